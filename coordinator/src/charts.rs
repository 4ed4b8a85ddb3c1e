//! The charts a run draws by default, chosen by what each reported quantity is rather than
//! one per quantity and node: the run's balance, every node's energies, one chart per
//! physical quantity with a line per node (or per probe, or per component where one node
//! reports it), and the method's own counters kept apart (`numerics.png` for step sizes and
//! mass scaling, `profile.png` for wall-clock counters). `cosim plot RUN --all` draws every
//! quantity of every node on its own instead.

use crate::plot::{Histories, Panel, Series, file_stem, grid_chart};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What a reported quantity is, for the default set of charts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// An energy or work term: the node's panel of `energy.png`.
    Energy,
    /// Wall-clock counters (`time_*`, `*_per_s`): `profile.png`.
    Timing,
    /// The method's own state (step sizes, mass scaling, the quasi-static ratio of kinetic
    /// to internal energy): `numerics.png`.
    Numerics,
    /// A node's momentum: the run's momentum residual is in `balance.png`; drawn per node
    /// only with `--all`.
    Momentum,
    /// Everything else: probes, displacements, forces, damage and fragment counts.
    Physics,
}

/// The kind of the quantity `key` (a node's report key, dotted names whole).
pub fn kind_of(key: &str) -> Kind {
    let k = key.rsplit('.').next().unwrap_or(key);
    if k.ends_with("_energy") || k.ends_with("_work") || k == "fracture_energy" {
        Kind::Energy
    } else if k.starts_with("time_") || k.ends_with("_per_s") || k.contains("wall") {
        Kind::Timing
    } else if k == "dt"
        || k.ends_with("_dt")
        || k.starts_with("added_mass")
        || k.starts_with("mass_scaling")
        || k == "kinetic_over_internal"
        || k.starts_with("cfl")
    {
        Kind::Numerics
    } else if k.starts_with("momentum") {
        Kind::Momentum
    } else {
        Kind::Physics
    }
}

/// One figure of the default set: its file name in `plots/`, its title and its panels.
#[derive(Debug, Clone)]
pub struct Chart {
    pub file: String,
    pub title: String,
    pub panels: Vec<Panel>,
}

/// `key` with every `_`- or `.`-separated part equal to the node's name replaced by `*`:
/// `force_j3_a` of node `j3` is `force_*_a`, the quantity every joint reports.
pub fn generic(key: &str, node: &str) -> String {
    let mut out = String::with_capacity(key.len());
    let mut part = String::new();
    let flush = |part: &mut String, out: &mut String| {
        out.push_str(if part == node { "*" } else { part });
        part.clear();
    };
    for c in key.chars() {
        if c == '_' || c == '.' {
            flush(&mut part, &mut out);
            out.push(c);
        } else {
            part.push(c);
        }
    }
    flush(&mut part, &mut out);
    out
}

/// Whether a history is worth a chart: some finite value, and not the same throughout.
fn varies(points: &[(f64, f64)]) -> bool {
    let mut finite = points.iter().map(|p| p.1).filter(|v| v.is_finite());
    match finite.next() {
        Some(first) => finite.any(|v| v != first),
        None => false,
    }
}

/// One line of a quantity within a node: the group it belongs to (vector components and
/// probes folded), its label within the node and whether it is a vector's component.
struct Line<'a> {
    group: String,
    label: String,
    component: Option<usize>,
    points: &'a [(f64, f64)],
}

/// A node's physical quantities as lines: a vector reported as `K_x`, `K_y`, `K_z` is the
/// group `K` (left out where the node also reports its magnitude `K_magnitude`), probes sharing a
/// quantity (`point1.pressure`, `point2.pressure`) the group `*.pressure`.
fn node_lines<'a>(q: &'a BTreeMap<String, Vec<(f64, f64)>>) -> Vec<Line<'a>> {
    let physics: Vec<(&String, &Vec<(f64, f64)>)> = q
        .iter()
        .filter(|(k, p)| kind_of(k) == Kind::Physics && varies(p))
        .collect();
    let component = |k: &str| {
        ["_x", "_y", "_z"]
            .iter()
            .enumerate()
            .find_map(|(i, c)| k.strip_suffix(c).map(|b| (b.to_string(), i)))
    };
    let is_vector = |base: &str| {
        ["_x", "_y", "_z"]
            .iter()
            .filter(|c| q.contains_key(&format!("{base}{c}")))
            .count()
            >= 2
    };
    let suffix_count = |suffix: &str| {
        physics
            .iter()
            .filter(|(k, _)| k.rsplit_once('.').is_some_and(|(_, s)| s == suffix))
            .count()
    };
    let mut out = Vec::new();
    for &(k, p) in &physics {
        if let Some((base, i)) = component(k).filter(|(b, _)| is_vector(b)) {
            if q.contains_key(&base) || q.contains_key(&format!("{base}_magnitude")) {
                continue; // the magnitude is reported: one line, not three
            }
            out.push(Line {
                group: base,
                label: ["x", "y", "z"][i].to_string(),
                component: Some(i),
                points: p,
            });
        } else if let Some((probe, suffix)) =
            k.rsplit_once('.').filter(|(_, s)| suffix_count(s) > 1)
        {
            out.push(Line {
                group: format!("*.{suffix}"),
                label: probe.to_string(),
                component: None,
                points: p,
            });
        } else {
            out.push(Line {
                group: k.clone(),
                label: String::new(),
                component: None,
                points: p,
            });
        }
    }
    out
}

/// The magnitude of a vector from its component lines (those of one node and group), at the
/// times all of them have.
fn magnitude(lines: &[&Line]) -> Vec<(f64, f64)> {
    let n = lines.iter().map(|l| l.points.len()).min().unwrap_or(0);
    (0..n)
        .map(|i| {
            let t = lines[0].points[i].0;
            let sq: f64 = lines.iter().map(|l| l.points[i].1 * l.points[i].1).sum();
            (t, sq.sqrt())
        })
        .collect()
}

/// The run's balance histories from its balance rows (`/cosim/balance`, summary.json's
/// `balance.per_window`): the total energy, the budget (initial energy plus external work),
/// the energy residual and the momentum residual.
pub fn balance_histories<'a>(
    rows: impl IntoIterator<Item = &'a serde_json::Value>,
) -> BTreeMap<&'static str, Vec<(f64, f64)>> {
    let mut out: BTreeMap<&'static str, Vec<(f64, f64)>> = BTreeMap::new();
    let mut e0 = None;
    for r in rows {
        let f = |k: &str| r[k].as_f64();
        let (Some(t), Some(e), Some(w), Some(res)) = (
            f("time"),
            f("energy"),
            f("external_work"),
            f("energy_residual"),
        ) else {
            continue;
        };
        let e0 = *e0.get_or_insert(e - w - res);
        out.entry("energy").or_default().push((t, e));
        out.entry("budget").or_default().push((t, e0 + w));
        out.entry("energy_residual").or_default().push((t, res));
        if let Some(p) = f("momentum_residual") {
            out.entry("momentum_residual").or_default().push((t, p));
        }
    }
    out
}

/// The default set of charts of a run's histories `h` and balance (`balance_histories`).
pub fn curated(h: &Histories, balance: &BTreeMap<&str, Vec<(f64, f64)>>) -> Vec<Chart> {
    let mut charts = Vec::new();
    if let Some(c) = balance_chart(balance) {
        charts.push(c);
    }
    let energy: Vec<Panel> = h
        .iter()
        .filter_map(|(node, q)| {
            let series: Vec<Series> = q
                .iter()
                .filter(|(k, p)| kind_of(k) == Kind::Energy && p.iter().any(|x| x.1 != 0.0))
                .map(|(k, p)| Series {
                    label: k.replace('_', " "),
                    points: p.clone(),
                })
                .collect();
            (!series.is_empty()).then(|| Panel {
                title: node.clone(),
                y_label: "energy".into(),
                series,
            })
        })
        .collect();
    if !energy.is_empty() {
        charts.push(Chart {
            file: "energy.png".into(),
            title: "energy of each node".into(),
            panels: energy,
        });
    }
    charts.extend(physics_charts(h));
    for (kind, file, title) in [
        (Kind::Numerics, "numerics.png", "the methods' own state"),
        (Kind::Timing, "profile.png", "where the wall time goes"),
    ] {
        let panels = counter_panels(h, kind);
        if !panels.is_empty() {
            charts.push(Chart {
                file: file.into(),
                title: title.into(),
                panels,
            });
        }
    }
    charts
}

/// `balance.png`: the run's energy against its budget with the residual, and the momentum
/// residual.
fn balance_chart(b: &BTreeMap<&str, Vec<(f64, f64)>>) -> Option<Chart> {
    let line = |k: &str, label: &str| {
        b.get(k).map(|p| Series {
            label: label.into(),
            points: p.clone(),
        })
    };
    let energy: Vec<Series> = [
        line("energy", "total energy E"),
        line("budget", "E₀ + external work"),
        line("energy_residual", "residual E − E₀ − W"),
    ]
    .into_iter()
    .flatten()
    .collect();
    if energy.is_empty() {
        return None;
    }
    let mut panels = vec![Panel {
        title: "energy balance".into(),
        y_label: "energy".into(),
        series: energy,
    }];
    if let Some(s) = line("momentum_residual", "") {
        panels.push(Panel {
            title: "momentum residual".into(),
            y_label: "momentum residual".into(),
            series: vec![s],
        });
    }
    Some(Chart {
        file: "balance.png".into(),
        title: "balance of the run".into(),
        panels,
    })
}

/// One chart per physical quantity: a line per node where several report it (a vector as
/// its magnitude), per probe or component where one node does.
fn physics_charts(h: &Histories) -> Vec<Chart> {
    // generic group → [(node, lines)]
    let mut groups: BTreeMap<String, Vec<(&String, Vec<Line>)>> = BTreeMap::new();
    for (node, q) in h {
        let mut by_group: BTreeMap<String, Vec<Line>> = BTreeMap::new();
        for l in node_lines(q) {
            by_group.entry(l.group.clone()).or_default().push(l);
        }
        for (g, lines) in by_group {
            groups
                .entry(generic(&g, node))
                .or_default()
                .push((node, lines));
        }
    }
    groups
        .into_iter()
        .map(|(g, members)| match members.as_slice() {
            [(node, lines)] => one_node_chart(&g, node, lines),
            _ => several_nodes_chart(&g, &members),
        })
        .collect()
}

/// The chart of a quantity (generic group `g`) that one node reports: a line per probe or
/// component.
fn one_node_chart(g: &str, node: &str, lines: &[Line]) -> Chart {
    let quantity = g.strip_prefix("*.").unwrap_or(g).to_string();
    let series = lines
        .iter()
        .map(|l| Series {
            label: l.label.clone(),
            points: l.points.to_vec(),
        })
        .collect();
    let own = lines[0].group.strip_prefix("*.").unwrap_or(&lines[0].group);
    Chart {
        file: format!("{node}_{}.png", file_stem(own)),
        title: format!("{node}: {own}"),
        panels: vec![Panel {
            title: format!("{node}: {own}"),
            y_label: quantity,
            series,
        }],
    }
}

/// The chart of a quantity (generic group `g`) that several nodes report: a line per node
/// (a vector as its magnitude) and per probe of a node.
fn several_nodes_chart(g: &str, members: &[(&String, Vec<Line>)]) -> Chart {
    let quantity = g.strip_prefix("*.").unwrap_or(g).to_string();
    let mut series = Vec::new();
    for (node, lines) in members {
        let comps: Vec<&Line> = lines.iter().filter(|l| l.component.is_some()).collect();
        if !comps.is_empty() {
            series.push(Series {
                label: node.to_string(),
                points: magnitude(&comps),
            });
        }
        for l in lines.iter().filter(|l| l.component.is_none()) {
            series.push(Series {
                label: if l.label.is_empty() {
                    node.to_string()
                } else {
                    format!("{node} {}", l.label)
                },
                points: l.points.to_vec(),
            });
        }
    }
    let vector = members
        .iter()
        .any(|(_, ls)| ls.iter().any(|l| l.component.is_some()));
    let title = if vector {
        format!("|{quantity}|")
    } else {
        quantity.clone()
    };
    let stem = file_stem(&g.replace('*', ""))
        .split('_')
        .filter(|p| !p.is_empty())
        .collect::<Vec<_>>()
        .join("_");
    Chart {
        file: format!("{stem}.png"),
        title: title.clone(),
        panels: vec![Panel {
            title,
            y_label: quantity,
            series,
        }],
    }
}

/// A panel per counter of `kind` (node names folded: every joint's `mass_scaling_dt` on
/// one panel), a line per node.
fn counter_panels(h: &Histories, kind: Kind) -> Vec<Panel> {
    let mut by: BTreeMap<String, Vec<Series>> = BTreeMap::new();
    for (node, q) in h {
        for (k, p) in q
            .iter()
            .filter(|(k, p)| kind_of(k) == kind && p.iter().any(|x| x.1.is_finite()))
        {
            by.entry(generic(k, node)).or_default().push(Series {
                label: node.clone(),
                points: p.clone(),
            });
        }
    }
    by.into_iter()
        .map(|(k, series)| Panel {
            title: k.clone(),
            y_label: k,
            series,
        })
        .collect()
}

/// Draw `charts` into `dir`; returns the files.
pub fn draw(charts: &[Chart], dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))?;
    let mut written = Vec::new();
    for c in charts {
        let p = dir.join(&c.file);
        grid_chart(&p, &c.title, "t [s]", &c.panels)?;
        written.push(p);
    }
    Ok(written)
}

/// The default set of charts of a run (an output directory or a recording), as `cosim run`
/// drew them when it ended.
pub fn default_charts(run: &Path) -> anyhow::Result<Vec<Chart>> {
    let msgs = crate::plot::run_messages(run)?;
    let rows: Vec<serde_json::Value> = msgs
        .iter()
        .filter(|m| m.topic == "/cosim/balance")
        .filter_map(|m| serde_json::from_slice(&m.data).ok())
        .collect();
    let b = balance_histories(&rows);
    Ok(curated(&crate::plot::node_histories(&msgs), &b))
}

/// `cosim plot RUN...` without `--series`: each run's default set of charts (`all`: every
/// quantity of every node on its own), into `out_dir` (`out_dir/<run>/` for several runs).
pub fn run_sets(runs: &[PathBuf], all: bool, out_dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for r in runs {
        let dir = if runs.len() > 1 {
            out_dir.join(crate::plot::run_label(r))
        } else {
            out_dir.to_path_buf()
        };
        if all {
            written.extend(crate::plot::every_quantity(
                &crate::plot::node_histories(&crate::plot::run_messages(r)?),
                &dir,
            )?);
        } else {
            written.extend(draw(&default_charts(r)?, &dir)?);
        }
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn h(node: &str, keys: &[(&str, &[f64])]) -> Histories {
        let mut q = BTreeMap::new();
        for (k, v) in keys {
            let p: Vec<(f64, f64)> = v.iter().enumerate().map(|(i, x)| (i as f64, *x)).collect();
            q.insert(k.to_string(), p);
        }
        let mut h = Histories::new();
        h.insert(node.to_string(), q);
        h
    }

    #[test]
    fn a_node_name_inside_a_key_is_folded_only_as_a_whole_part() {
        assert_eq!(generic("force_j3_a", "j3"), "force_*_a");
        assert_eq!(generic("force_j3p_a_x", "j3p"), "force_*_a_x");
        assert_eq!(generic("force_j3p_a", "j3"), "force_j3p_a");
        assert_eq!(generic("gas.point1.pressure", "gas"), "*.point1.pressure");
        assert_eq!(generic("max_pressure", "gas"), "max_pressure");
    }

    #[test]
    fn quantities_are_sorted_by_what_they_are() {
        for (k, kind) in [
            ("kinetic_energy", Kind::Energy),
            ("plastic_work", Kind::Energy),
            ("time_ghost_fills_s", Kind::Timing),
            ("cell_updates_per_s", Kind::Timing),
            ("mass_scaling_dt", Kind::Numerics),
            ("dt", Kind::Numerics),
            ("added_mass_fraction", Kind::Numerics),
            ("kinetic_over_internal", Kind::Numerics),
            ("momentum_x", Kind::Momentum),
            ("point1.pressure", Kind::Physics),
            ("force_top_x", Kind::Physics),
            ("mass", Kind::Physics),
        ] {
            assert_eq!(kind_of(k), kind, "{k}");
        }
    }

    #[test]
    fn vectors_probes_and_nodes_fold_into_one_chart_each() {
        let ramp: &[f64] = &[0.0, 1.0, 2.0];
        let flat: &[f64] = &[3.0, 3.0, 3.0];
        // One node: a vector with one component flat zero, two probes of one quantity, a
        // constant (left out), energies and a timer.
        let mut hist = h(
            "gas",
            &[
                ("com_displacement_x", ramp),
                ("com_displacement_y", &[0.0, -1.0, -3.0]),
                ("com_displacement_z", &[0.0, 0.0, 0.0]),
                ("point1.pressure", ramp),
                ("point2.pressure", &[1.0, 0.0, 1.0]),
                ("point1.density", ramp),
                ("mass", flat),
                ("kinetic_energy", ramp),
                ("internal_energy", flat),
                ("time_steps_s", ramp),
                ("momentum_x", ramp),
            ],
        );
        // Two joints reporting their own named force (magnitude and components).
        for j in ["j1", "j2"] {
            let f = format!("force_{j}_a");
            let (fx, fy, fz) = (format!("{f}_x"), format!("{f}_y"), format!("{f}_z"));
            let m = format!("{f}_magnitude");
            hist.extend(h(
                j,
                &[
                    (m.as_str(), ramp),
                    (fx.as_str(), ramp),
                    (fy.as_str(), ramp),
                    (fz.as_str(), ramp),
                    ("mass_scaling_dt", flat),
                ],
            ));
        }
        let charts = curated(&hist, &BTreeMap::new());
        let mut files: Vec<&str> = charts.iter().map(|c| c.file.as_str()).collect();
        files.sort();
        assert_eq!(
            files,
            [
                "energy.png",
                "force_a_magnitude.png",
                "gas_com_displacement.png",
                "gas_point1_density.png",
                "gas_pressure.png",
                "numerics.png",
                "profile.png"
            ]
        );
        let by = |f: &str| charts.iter().find(|c| c.file == f).unwrap();
        let labels = |f: &str| -> Vec<String> {
            by(f).panels[0]
                .series
                .iter()
                .map(|s| s.label.clone())
                .collect()
        };
        // the all-zero component is not drawn
        assert_eq!(labels("gas_com_displacement.png"), ["x", "y"]);
        assert_eq!(labels("gas_pressure.png"), ["point1", "point2"]);
        // the joints' magnitudes, one line each (their components are left out)
        assert_eq!(labels("force_a_magnitude.png"), ["j1", "j2"]);
        assert_eq!(by("numerics.png").panels[0].title, "mass_scaling_dt");
        assert_eq!(by("energy.png").panels.len(), 1);
        // every axis of the set carries a unit
        for c in &charts {
            for p in &c.panels {
                assert!(
                    crate::plot::unit_of(&p.y_label).is_some(),
                    "{}: {}",
                    c.file,
                    p.y_label
                );
            }
        }
    }
}
