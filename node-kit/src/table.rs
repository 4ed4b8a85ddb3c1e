//! The history tables a node writes beside its VTK frames (`probes.csv`, `reactions.csv`,
//! `joint_force.csv`): a header row of column names, then one row per recorded time, written
//! whole or not at all. Every value is written as the shortest decimal that reads back to
//! the same f64 (`1.5e-3`), so a table holds exactly what the node reported. The same values
//! also reach the run's recording; `cosim export` gathers them across nodes.

use std::path::Path;

/// Writes `path` (its folder created): `header`, then each row of `rows`. A name holding a
/// comma or a quote is quoted as CSV requires.
pub fn write_csv<R>(
    path: &Path,
    header: &[String],
    rows: impl IntoIterator<Item = R>,
) -> std::io::Result<()>
where
    R: IntoIterator<Item = f64>,
{
    if let Some(d) = path.parent() {
        std::fs::create_dir_all(d)?;
    }
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(header)?;
    let mut row = Vec::with_capacity(header.len());
    for r in rows {
        row.clear();
        row.extend(r.into_iter().map(|x| format!("{x:e}")));
        w.write_record(&row)?;
    }
    let bytes = w.into_inner().map_err(|e| e.into_error())?;
    crate::whole::write(path, &bytes)
}

/// Writes `path` (its folder created) whole or not at all: `header`, then `rows` of text
/// cells (for a table whose columns are not all numbers), quoted as CSV requires.
pub fn write_text_csv(path: &Path, header: &[&str], rows: &[Vec<String>]) -> std::io::Result<()> {
    if let Some(d) = path.parent() {
        std::fs::create_dir_all(d)?;
    }
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(header)?;
    for r in rows {
        w.write_record(r)?;
    }
    let bytes = w.into_inner().map_err(|e| e.into_error())?;
    crate::whole::write(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values read back bit for bit; a name with a comma is quoted.
    #[test]
    fn a_table_reads_back_exactly() {
        let dir = std::env::temp_dir().join(format!("node-kit-table-{}", std::process::id()));
        let path = dir.join("t.csv");
        let values = [0.1 + 0.2, -1.0 / 3.0, 6.02214076e23, 5e-324, 0.0];
        let header = vec!["time".to_string(), "a,b".to_string()];
        let rows: Vec<[f64; 2]> = values.iter().map(|&v| [v, -v]).collect();
        write_csv(&path, &header, rows.iter().map(|r| r.iter().copied())).unwrap();
        let mut rd = csv::Reader::from_path(&path).unwrap();
        assert_eq!(rd.headers().unwrap(), vec!["time", "a,b"]);
        let mut n = 0;
        for (rec, want) in rd.records().zip(&rows) {
            let rec = rec.unwrap();
            let got: Vec<f64> = rec.iter().map(|s| s.parse().unwrap()).collect();
            assert_eq!(got.len(), 2);
            for (g, w) in got.iter().zip(want) {
                assert_eq!(g.to_bits(), w.to_bits(), "{g:e} against {w:e}");
            }
            n += 1;
        }
        assert_eq!(n, values.len());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
