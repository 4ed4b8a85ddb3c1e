//! The run's joint report: every joint of every node that writes one (`NODE/joint_report.csv`:
//! the meso-joint node, one row per joint with its peak force and its failure), joined into
//! one table in the run's folder (`joint_report.csv`, the node first) and printed at the end
//! of a run, as crash analysts read joint forces. The joint's own columns are the node's:
//! name, peak force (N) and its time (s), failure time (s, empty if none) and mode
//! (the meso-joint node's `pull-out`, `interfacial`, `rupture`, or `none`; another node may
//! name its own), then whatever the node adds.

use std::path::Path;

/// One joint's row of the report.
#[derive(Debug, Clone, PartialEq)]
pub struct JointRow {
    pub node: String,
    pub joint: String,
    /// Peak force (N) and its time (s).
    pub peak: f64,
    pub peak_time: f64,
    /// Failure time (s) and mode (`pull-out`, `interfacial`, `rupture`, ...), if it failed.
    pub failure: Option<(f64, String)>,
}

/// Reads every `NODE/joint_report.csv` of the run in `dir` (nodes in name order), writes the
/// joined table to `dir/joint_report.csv` (whole or not at all) and returns its rows;
/// `Ok(empty)` when no node wrote one. A row that does not parse is an error naming the file
/// and line.
pub fn collect(dir: &Path) -> Result<Vec<JointRow>, String> {
    let mut nodes: Vec<(String, std::path::PathBuf)> = std::fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|e| e.ok())
        .filter(|e| e.path().join("joint_report.csv").is_file())
        .map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            (name, e.path().join("joint_report.csv"))
        })
        .collect();
    nodes.sort();
    let mut rows = Vec::new();
    let mut joined = csv::Writer::from_writer(Vec::new());
    let mut header_written = false;
    for (node, path) in &nodes {
        let mut r = csv::Reader::from_path(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let header = r
            .headers()
            .map_err(|e| format!("{}: {e}", path.display()))?
            .clone();
        if !header_written {
            let mut h = vec!["node"];
            h.extend(header.iter());
            joined.write_record(&h).map_err(|e| e.to_string())?;
            header_written = true;
        }
        for (k, rec) in r.records().enumerate() {
            let where_ = format!("{} line {}", path.display(), k + 2);
            let rec = rec.map_err(|e| format!("{where_}: {e}"))?;
            let bad = |what: &str| format!("{where_}: {what}: {rec:?}");
            if rec.len() != header.len() || rec.len() < 5 {
                return Err(bad("wrong number of fields"));
            }
            let num = |s: &str| s.parse::<f64>().map_err(|_| bad("not a number"));
            let failure = match (&rec[3], &rec[4]) {
                ("", "none") => None,
                (t, mode) if !t.is_empty() && !mode.is_empty() && mode != "none" => {
                    Some((num(t)?, mode.to_string()))
                }
                _ => return Err(bad("failure time and mode do not agree")),
            };
            rows.push(JointRow {
                node: node.clone(),
                joint: rec[0].to_string(),
                peak: num(&rec[1])?,
                peak_time: num(&rec[2])?,
                failure,
            });
            let mut out = vec![node.as_str()];
            out.extend(rec.iter());
            joined.write_record(&out).map_err(|e| e.to_string())?;
        }
    }
    if !rows.is_empty() {
        let out = dir.join("joint_report.csv");
        let bytes = joined.into_inner().map_err(|e| e.to_string())?;
        node_kit::whole::write(&out, &bytes).map_err(|e| e.to_string())?;
    }
    Ok(rows)
}

/// The report as lines for a terminal: node/joint, peak force and when, failure.
pub fn lines(rows: &[JointRow]) -> Vec<String> {
    let width = rows
        .iter()
        .map(|r| r.node.len() + r.joint.len() + 1)
        .max()
        .unwrap_or(0);
    rows.iter()
        .map(|r| {
            let who = format!("{}/{}", r.node, r.joint);
            let failure = match &r.failure {
                Some((t, mode)) => format!("failed at {:.4} ms ({mode})", t * 1e3),
                None => "not failed".to_string(),
            };
            format!(
                "{who:<width$}  peak {:>10.4} kN at {:.4} ms, {failure}",
                r.peak * 1e-3,
                r.peak_time * 1e3
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nodes_tables_are_joined_with_the_node_first() {
        let dir = std::env::temp_dir().join(format!("cosim-joints-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let header = "joint,peak_force_N,peak_time_s,failure_time_s,failure_mode,broken_bonds_material,broken_bonds_interface";
        for (node, body) in [
            ("j2", "j2,1500,0.01,,none,0,0"),
            (
                "grouped",
                "\"a,b\",8520.5,0.0798,0.0986,pull-out,3154,904\nc,200,0.02,0.03,interfacial,2,10",
            ),
        ] {
            std::fs::create_dir_all(dir.join(node)).unwrap();
            std::fs::write(
                dir.join(node).join("joint_report.csv"),
                format!("{header}\n{body}\n"),
            )
            .unwrap();
        }
        std::fs::create_dir_all(dir.join("tube")).unwrap();
        let rows = collect(&dir).unwrap();
        assert_eq!(rows.len(), 3);
        assert_eq!(
            rows[0],
            JointRow {
                node: "grouped".into(),
                joint: "a,b".into(),
                peak: 8520.5,
                peak_time: 0.0798,
                failure: Some((0.0986, "pull-out".into())),
            }
        );
        assert_eq!(rows[1].failure, Some((0.03, "interfacial".into())));
        assert_eq!(
            (rows[2].node.as_str(), rows[2].failure.as_ref()),
            ("j2", None)
        );
        let joined = std::fs::read_to_string(dir.join("joint_report.csv")).unwrap();
        assert!(joined.starts_with(&format!("node,{header}\ngrouped,\"a,b\",8520.5,")));
        assert_eq!(joined.lines().count(), 4);
        let l = lines(&rows);
        assert!(
            l[0].contains("peak     8.5205 kN at 79.8000 ms, failed at 98.6000 ms (pull-out)"),
            "{}",
            l[0]
        );
        assert!(l[2].ends_with("not failed"), "{}", l[2]);
        // a node's own mode is kept; a mode without a time, or a time without one, is refused
        std::fs::write(
            dir.join("j2/joint_report.csv"),
            format!("{header}\nj2,1500,0.01,0.02,rupture,7,0\n"),
        )
        .unwrap();
        let rows = collect(&dir).unwrap();
        assert_eq!(rows[2].failure, Some((0.02, "rupture".into())));
        for body in ["j2,1500,0.01,,rupture,0,0", "j2,1500,0.01,0.02,none,0,0"] {
            std::fs::write(
                dir.join("j2/joint_report.csv"),
                format!("{header}\n{body}\n"),
            )
            .unwrap();
            let e = collect(&dir).unwrap_err();
            assert!(e.contains("failure time and mode do not agree"), "{e}");
        }
        // a damaged table is an error naming its file and line
        std::fs::write(
            dir.join("j2/joint_report.csv"),
            format!("{header}\nj2,x,0.01,,none,0,0\n"),
        )
        .unwrap();
        let e = collect(&dir).unwrap_err();
        assert!(
            e.contains("j2/joint_report.csv line 2: not a number"),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
