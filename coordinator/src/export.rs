//! `cosim export`: a run's per-window histories as arrays for analysis outside cosim — every
//! node's report (`/cosim/node/<name>`: energies, momentum, named scalars such as probe
//! pressures and displacements) and the balance (`/cosim/balance`), read from the recording.
//! `npz` holds one array per `NODE/KEY` (`balance/KEY`): 1-D float64 per window, (windows, 3)
//! for vectors, NaN where a window lacks the key; `csv` writes one table per node. The
//! coupling messages' interface fields go to `fields.npz` (`COUPLING/SENDER/FIELD` as
//! (messages, points, components), with `.window` and `.time` per message).

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

/// Whether `name` (`NODE/KEY`) is selected by `patterns` (`NODE/KEY` with `*` matching any
/// run of characters, or `NODE` alone for all its keys); no pattern selects everything.
pub fn selected(name: &str, patterns: &[String]) -> bool {
    patterns.is_empty()
        || patterns.iter().any(|p| {
            glob(p, name) || (!p.contains('/') && name.split('/').next() == Some(p.as_str()))
        })
}

/// `*`-only glob match of `text` against `pat`.
fn glob(pat: &str, text: &str) -> bool {
    let mut parts = pat.split('*');
    let first = parts.next().unwrap_or("");
    let Some(mut rest) = text.strip_prefix(first) else {
        return false;
    };
    let parts: Vec<&str> = parts.collect();
    let Some((last, middle)) = parts.split_last() else {
        return rest.is_empty();
    };
    for m in middle {
        match rest.find(m) {
            Some(i) => rest = &rest[i + m.len()..],
            None => return false,
        }
    }
    rest.len() >= last.len() && rest.ends_with(last)
}

/// Keeps in `tables` the columns `patterns` select (`window` and `time` stay with any
/// selected column of their table); an error names the patterns that selected nothing.
pub fn filter(tables: &mut BTreeMap<String, Table>, patterns: &[String]) -> anyhow::Result<()> {
    if patterns.is_empty() {
        return Ok(());
    }
    let unused: Vec<&String> = patterns
        .iter()
        .filter(|p| {
            !tables.iter().any(|(node, t)| {
                t.columns
                    .iter()
                    .any(|(k, _)| selected(&format!("{node}/{k}"), std::slice::from_ref(p)))
            })
        })
        .collect();
    if !unused.is_empty() {
        let known: Vec<String> = tables
            .iter()
            .flat_map(|(n, t)| t.columns.iter().map(move |(k, _)| format!("{n}/{k}")))
            .take(40)
            .collect();
        bail!(
            "--series {unused:?} selects nothing; series are NODE/KEY, e.g. {}",
            known.join(", ")
        );
    }
    for (node, t) in tables.iter_mut() {
        let keep: Vec<bool> = t
            .columns
            .iter()
            .map(|(k, _)| selected(&format!("{node}/{k}"), patterns))
            .collect();
        let any = keep.iter().any(|&k| k);
        let mut i = 0;
        t.columns.retain(|(k, _)| {
            let kept = keep[i] || (any && (k == "window" || k == "time"));
            i += 1;
            kept
        });
    }
    tables.retain(|_, t| !t.columns.is_empty());
    Ok(())
}

/// One interface field as sent by one node on one coupling, message after message.
#[derive(Debug, Default, Clone)]
pub struct FieldSeries {
    pub coupling: String,
    pub sender: String,
    pub field: String,
    pub components: usize,
    pub points: usize,
    /// Window and simulated time of each message holding the field (the set-up's is window 0).
    pub window: Vec<u64>,
    pub time: Vec<f64>,
    /// (messages, points, components), row-major.
    pub values: Vec<f64>,
}

impl FieldSeries {
    /// `COUPLING/SENDER/FIELD`.
    pub fn name(&self) -> String {
        format!("{}/{}/{}", self.coupling, self.sender, self.field)
    }
}

/// Every interface field of the recording's coupling messages, by `COUPLING/SENDER/FIELD`,
/// and the names of fields left out because their point count changes between messages (a
/// table cannot hold them; the recording still does). The sender is the last part of the
/// data topic (`cosim/<run>/<coupling>/<sender>`).
pub fn field_series(
    recording: &Path,
) -> anyhow::Result<(BTreeMap<String, FieldSeries>, Vec<String>)> {
    let (msgs, _complete) = record::read_all(recording)?;
    let mut out: BTreeMap<String, FieldSeries> = BTreeMap::new();
    let mut ragged = Vec::new();
    for m in msgs.iter().filter(|m| !m.json) {
        let Ok(env) = protocol::decode(&m.data) else {
            continue;
        };
        let protocol::Message::Fields(f) = env.message else {
            continue;
        };
        let sender = m.topic.rsplit('/').next().unwrap_or_default();
        for fld in &f.fields {
            let comps = (fld.components as usize).max(1);
            let points = fld.values.len() / comps;
            let name = format!("{}/{sender}/{}", f.coupling, fld.name);
            if ragged.contains(&name) {
                continue;
            }
            let s = out.entry(name.clone()).or_insert_with(|| FieldSeries {
                coupling: f.coupling.clone(),
                sender: sender.to_string(),
                field: fld.name.clone(),
                components: comps,
                points,
                ..Default::default()
            });
            if s.points != points || s.components != comps {
                out.remove(&name);
                ragged.push(name);
                continue;
            }
            s.window.push(f.window);
            s.time.push(f.time);
            s.values.extend_from_slice(&fld.values);
        }
    }
    Ok((out, ragged))
}

/// Writes each field series as `NAME` (messages, points, components), `NAME.window` and
/// `NAME.time` into a numpy `.npz` file; returns the number of series.
pub fn write_fields_npz(
    series: &BTreeMap<String, FieldSeries>,
    path: &Path,
) -> anyhow::Result<usize> {
    let file =
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let mut npz = ndarray_npy::NpzWriter::new(std::io::BufWriter::new(file));
    for (name, s) in series {
        // views of the series' own storage: no copy of the (possibly large) values
        let a =
            ndarray::ArrayView3::from_shape((s.window.len(), s.points, s.components), &s.values)?;
        npz.add_array(name.as_str(), &a)?;
        npz.add_array(
            format!("{name}.window").as_str(),
            &ndarray::ArrayView1::from(&s.window),
        )?;
        npz.add_array(
            format!("{name}.time").as_str(),
            &ndarray::ArrayView1::from(&s.time),
        )?;
    }
    npz.finish()
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(series.len())
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
