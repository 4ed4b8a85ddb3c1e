//! `cosim export`: a run's per-window histories as arrays for analysis outside cosim — every
//! node's report (`/cosim/node/<name>`: energies, momentum, named scalars such as probe
//! pressures and displacements) and the balance (`/cosim/balance`), read from the recording.
//! `npz` holds one array per `NODE/KEY` (`balance/KEY`): 1-D float64 per window, (windows, 3)
//! for vectors, NaN where a window lacks the key; `csv` and `parquet` write one table per
//! node (vectors as `KEY_x`, `KEY_y`, `KEY_z`; empty or null where a window lacks the key). The
//! coupling messages' interface fields go to `fields.npz` (`COUPLING/SENDER/FIELD` as
//! (messages, points, components), with `.window` and `.time` per message). A node that wrote
//! a fragment table (`NODE/fragments.csv` in the run's folder) adds the table
//! `NODE_fragments`, one row per fragment of its last frame.

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
        fold_vectors(t);
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

/// One name for a vector everywhere: a node's scalars `K_x`, `K_y` (and `K_z`) become the
/// vector column `K` (2 or 3 components, as the recorded `momentum` is), so NPZ and Python
/// hold one (windows, n) array `K` and the flat tables (CSV, Parquet, pandas) its columns
/// `K_x`, `K_y`, `K_z` again. Left apart where the table already has a key `K` or keys
/// `K.…` (a nested probe's). The recorder
/// itself writes a vector as one key by the same rule (`engine::report`); this folds the
/// recordings made before it did.
fn fold_vectors(t: &mut Table) {
    let has = |t: &Table, k: &str| t.columns.iter().any(|(c, w)| c == k && *w == 1);
    let bases: Vec<String> = t
        .columns
        .iter()
        .filter_map(|(c, w)| (*w == 1).then(|| c.strip_suffix("_x"))?)
        .map(str::to_string)
        .collect();
    for base in bases {
        let comps: Vec<String> = ["x", "y", "z"]
            .iter()
            .map(|a| format!("{base}_{a}"))
            .take_while(|k| has(t, k))
            .collect();
        // the recorder's rule (`engine::report::vector`): `K` must not be a key already, nor
        // the object of nested names `K.…`
        let dotted = format!("{base}.");
        if comps.len() < 2
            || t.columns
                .iter()
                .any(|(c, _)| *c == base || c.starts_with(&dotted))
        {
            continue;
        }
        for row in &mut t.rows {
            let v: Vec<serde_json::Value> = comps
                .iter()
                .map(|k| row.remove(k).unwrap_or(serde_json::Value::Null))
                .collect();
            if v.iter().any(|x| !x.is_null()) {
                row.insert(base.clone(), serde_json::Value::Array(v));
            }
        }
        t.columns.retain(|(c, _)| !comps.contains(c));
        t.columns.push((base, comps.len()));
    }
}

/// The fragment tables the run's nodes wrote (`RUN/NODE/fragments.csv`: one row per fragment
/// of the last frame), as tables named `NODE_fragments`, one row per fragment, in node
/// order. A file that is not a table of numbers under one header is an error naming it.
pub fn fragment_tables(run_dir: &Path) -> anyhow::Result<BTreeMap<String, Table>> {
    let mut out = BTreeMap::new();
    let Ok(rd) = std::fs::read_dir(run_dir) else {
        return Ok(out);
    };
    let mut files: Vec<(String, PathBuf)> = rd
        .flatten()
        .map(|e| e.path())
        .filter(|d| d.join("fragments.csv").is_file())
        .map(|d| {
            let node = d
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            (node, d.join("fragments.csv"))
        })
        .collect();
    files.sort();
    for (node, file) in files {
        out.insert(format!("{node}_fragments"), read_table(&file)?);
    }
    Ok(out)
}

/// A CSV file of numbers under one header line as a [`Table`] (a column per header field).
pub fn read_table(file: &Path) -> anyhow::Result<Table> {
    let mut r =
        csv::Reader::from_path(file).with_context(|| format!("cannot read {}", file.display()))?;
    let header: Vec<String> = r
        .headers()
        .with_context(|| format!("{}: no header line", file.display()))?
        .iter()
        .map(str::to_string)
        .collect();
    let mut t = Table {
        columns: header.iter().map(|h| (h.clone(), 1)).collect(),
        rows: Vec::new(),
    };
    for (line, rec) in r.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: row {}", file.display(), line + 1))?;
        let mut row = serde_json::Map::new();
        for (h, v) in header.iter().zip(rec.iter()) {
            let x: f64 = v.trim().parse().with_context(|| {
                format!(
                    "{}: row {}, column {h}: '{v}' is not a number",
                    file.display(),
                    line + 1
                )
            })?;
            row.insert(h.clone(), serde_json::json!(x));
        }
        t.rows.push(row);
    }
    Ok(t)
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
pub fn glob(pat: &str, text: &str) -> bool {
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

/// A table's columns flattened to scalars: vectors as `KEY_x`, `KEY_y` (and `KEY_z`; wider
/// ones `KEY_0`, …), one value per row, NaN where a row lacks the key.
fn flat_columns(t: &Table) -> Vec<(String, Vec<f64>)> {
    let mut out = Vec::new();
    for (key, width) in &t.columns {
        let c = t.column(key, *width);
        if *width == 1 {
            out.push((key.clone(), c));
            continue;
        }
        for i in 0..*width {
            let name = match (*width, i) {
                (2 | 3, _) => format!("{key}_{}", ["x", "y", "z"][i]),
                _ => format!("{key}_{i}"),
            };
            out.push((name, c.iter().skip(i).step_by(*width).copied().collect()));
        }
    }
    out
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
        let cols = flat_columns(t);
        w.write_record(cols.iter().map(|(name, _)| name))?;
        let mut line = Vec::with_capacity(cols.len());
        for r in 0..t.rows.len() {
            line.clear();
            for (_, c) in &cols {
                let v = c[r];
                line.push(if v.is_nan() {
                    String::new()
                } else if v.fract() == 0.0 && v.abs() < 1e15 {
                    format!("{}", v as i64)
                } else {
                    format!("{v:e}")
                });
            }
            w.write_record(&line)?;
        }
        w.flush()
            .with_context(|| format!("cannot write {}", path.display()))?;
        files.push(path);
    }
    Ok(files)
}

/// Writes `DIR/NODE.parquet` per table: the CSV's columns as optional float64 columns (null
/// where a window lacks the key), one row per window, one row group; returns the files.
pub fn write_parquet(tables: &BTreeMap<String, Table>, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    use parquet::basic::{Repetition, Type as Physical};
    use parquet::data_type::DoubleType;
    use parquet::file::writer::SerializedFileWriter;
    use parquet::schema::types::Type;
    use std::sync::Arc;

    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut files = Vec::new();
    for (node, t) in tables {
        let path = dir.join(format!("{node}.parquet"));
        let cols = flat_columns(t);
        let fields = cols
            .iter()
            .map(|(name, _)| {
                Type::primitive_type_builder(name, Physical::DOUBLE)
                    .with_repetition(Repetition::OPTIONAL)
                    .build()
                    .map(Arc::new)
            })
            .collect::<Result<Vec<_>, _>>()?;
        let schema = Arc::new(
            Type::group_type_builder("cosim_history")
                .with_fields(fields)
                .build()?,
        );
        let file = std::fs::File::create(&path)
            .with_context(|| format!("cannot create {}", path.display()))?;
        let mut w = SerializedFileWriter::new(file, schema, Default::default())?;
        let mut group = w.next_row_group()?;
        let mut values = Vec::with_capacity(t.rows.len());
        let mut defined = Vec::with_capacity(t.rows.len());
        for (_, c) in &cols {
            let Some(mut col) = group.next_column()? else {
                bail!("{}: the writer ran out of columns", path.display());
            };
            values.clear();
            defined.clear();
            for &v in c {
                defined.push(i16::from(!v.is_nan()));
                if !v.is_nan() {
                    values.push(v);
                }
            }
            col.typed::<DoubleType>()
                .write_batch(&values, Some(&defined), None)?;
            col.close()?;
        }
        group.close()?;
        w.close()
            .with_context(|| format!("cannot write {}", path.display()))?;
        files.push(path);
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The readers fold a vector by the recorder's rule: `K_x`, `K_y` (`K_z`) become `K`,
    /// except where `K` or a nested `K.…` is a column already.
    #[test]
    fn components_fold_into_a_vector_by_the_recorders_rule() {
        let row = serde_json::json!({
            "f_x": 1.0, "f_y": 2.0, "f_z": 3.0,
            "probe.pressure": 4.0, "probe_x": 5.0, "probe_y": 6.0,
            "lone_x": 7.0, "twice": 8.0, "twice_x": 9.0, "twice_y": 10.0,
        });
        let serde_json::Value::Object(row) = row else {
            unreachable!()
        };
        let mut t = Table {
            columns: row.keys().map(|k| (k.clone(), 1)).collect(),
            rows: vec![row],
        };
        fold_vectors(&mut t);
        let has = |k: &str, w: usize| t.columns.iter().any(|(c, n)| c == k && *n == w);
        assert!(has("f", 3) && !has("f_x", 1), "{:?}", t.columns);
        assert_eq!(t.column("f", 3), vec![1.0, 2.0, 3.0]);
        for k in [
            "probe.pressure",
            "probe_x",
            "probe_y",
            "lone_x",
            "twice",
            "twice_x",
            "twice_y",
        ] {
            assert!(has(k, 1), "{k}: {:?}", t.columns);
        }
        assert!(!has("probe", 2));
    }
}
