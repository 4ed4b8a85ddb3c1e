//! `cosim export`: a run's per-window histories as arrays for analysis outside cosim — every
//! node's report (`/cosim/node/<name>`: energies, momentum, named scalars such as probe
//! pressures and displacements) and the balance (`/cosim/balance`), read from the recording.
//! `npz` holds one array per `NODE/KEY` (`balance/KEY`): 1-D float64 per window, (windows, 3)
//! for vectors, NaN where a window lacks the key; `csv` writes one table per node.

use crate::record;
use anyhow::{Context, bail};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One channel's history: the keys in first-seen order and one row per recorded window.
#[derive(Debug, Default)]
pub struct Table {
    /// Key → number of components (1 for a scalar, 3 for a vector).
    pub columns: Vec<(String, usize)>,
    pub rows: Vec<serde_json::Map<String, serde_json::Value>>,
}

impl Table {
    /// The column `key` as `width` values per row, NaN where a row lacks it.
    pub fn column(&self, key: &str, width: usize) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.rows.len() * width);
        for r in &self.rows {
            match r.get(key) {
                Some(serde_json::Value::Array(a)) => out.extend(
                    (0..width).map(|i| a.get(i).and_then(|x| x.as_f64()).unwrap_or(f64::NAN)),
                ),
                Some(v) => {
                    out.push(v.as_f64().unwrap_or(f64::NAN));
                    out.extend(std::iter::repeat_n(f64::NAN, width - 1));
                }
                None => out.extend(std::iter::repeat_n(f64::NAN, width)),
            }
        }
        out
    }
}

/// The histories of a recording: `balance` and each node, in name order.
pub fn tables(recording: &Path) -> anyhow::Result<BTreeMap<String, Table>> {
    let (msgs, _complete) = record::read_json(recording)?;
    let mut out: BTreeMap<String, Table> = BTreeMap::new();
    for m in &msgs {
        let name = if m.topic == "/cosim/balance" {
            "balance"
        } else if let Some(n) = m.topic.strip_prefix("/cosim/node/") {
            n
        } else {
            continue;
        };
        let Ok(serde_json::Value::Object(row)) = serde_json::from_slice(&m.data) else {
            bail!(
                "{}: a message on {} is not a JSON object",
                recording.display(),
                m.topic
            );
        };
        let t = out.entry(name.to_string()).or_default();
        for (k, v) in &row {
            let width = match v {
                serde_json::Value::Number(_) | serde_json::Value::Null => 1,
                serde_json::Value::Array(a) if a.iter().all(|x| x.is_number() || x.is_null()) => {
                    a.len()
                }
                _ => continue,
            };
            match t.columns.iter_mut().find(|(c, _)| c == k) {
                Some((_, w)) => *w = (*w).max(width),
                None => t.columns.push((k.clone(), width)),
            }
        }
        t.rows.push(row);
    }
    for t in out.values_mut() {
        // window and time first, the rest in name order
        t.columns
            .sort_by_key(|(k, _)| (k != "window", k != "time", k.clone()));
    }
    if out.is_empty() {
        bail!(
            "{}: no node reports or balance rows recorded",
            recording.display()
        );
    }
    Ok(out)
}

/// Writes `NODE/KEY` arrays into a numpy `.npz` file; returns the number of arrays.
pub fn write_npz(tables: &BTreeMap<String, Table>, path: &Path) -> anyhow::Result<usize> {
    let file =
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut npz = ndarray_npy::NpzWriter::new(std::io::BufWriter::new(file));
    let mut n = 0;
    for (node, t) in tables {
        for (key, width) in &t.columns {
            let data = t.column(key, *width);
            let name = format!("{node}/{key}");
            if *width == 1 {
                npz.add_array(name.as_str(), &ndarray::Array1::from(data))?;
            } else {
                let a = ndarray::Array2::from_shape_vec((t.rows.len(), *width), data)?;
                npz.add_array(name.as_str(), &a)?;
            }
            n += 1;
        }
    }
    npz.finish()
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(n)
}

/// Writes `DIR/NODE.csv` per table (vectors as KEY_x, KEY_y, KEY_z; empty where missing);
/// returns the files written.
pub fn write_csv(tables: &BTreeMap<String, Table>, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut files = Vec::new();
    for (node, t) in tables {
        let path = dir.join(format!("{node}.csv"));
        let mut w = csv::Writer::from_path(&path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        let mut head = Vec::new();
        let mut cols = Vec::new();
        for (key, width) in &t.columns {
            match *width {
                1 => head.push(key.clone()),
                3 => head.extend(["x", "y", "z"].map(|a| format!("{key}_{a}"))),
                _ => head.extend((0..*width).map(|i| format!("{key}_{i}"))),
            }
            cols.push((t.column(key, *width), *width));
        }
        w.write_record(&head)?;
        let mut line = Vec::with_capacity(head.len());
        for r in 0..t.rows.len() {
            line.clear();
            for (c, width) in &cols {
                for v in &c[r * width..(r + 1) * width] {
                    line.push(if v.is_nan() {
                        String::new()
                    } else if v.fract() == 0.0 && v.abs() < 1e15 {
                        format!("{}", *v as i64)
                    } else {
                        format!("{v:e}")
                    });
                }
            }
            w.write_record(&line)?;
        }
        w.flush()
            .with_context(|| format!("cannot write {}", path.display()))?;
        files.push(path);
    }
    Ok(files)
}
