//! PNG line charts (plotters, docs/architecture.md): the plots `cosim run` writes next to the
//! recording (every node's energies and named scalars over time), and `cosim plot`, which
//! draws one series of several runs on one figure (e.g. a quantity at three resolutions).
//!
//! Text needs a TrueType font: the first of `COSIM_FONT`, DejaVu Sans or Liberation Sans
//! found on the machine (Debian: `fonts-dejavu-core`). Without one the charts are drawn
//! without captions, tick labels or legend, and a warning says so.

use crate::record::{self, Recorded};
use anyhow::{Context, bail};
use plotters::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// One line of a chart.
#[derive(Debug, Clone)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

const FONT_PATHS: [&str; 4] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
];

/// Registers a font under "sans-serif" once; false when none was found.
pub(crate) fn font_ready() -> bool {
    static READY: OnceLock<bool> = OnceLock::new();
    *READY.get_or_init(|| {
        let env = std::env::var("COSIM_FONT").ok();
        let candidates = env.iter().map(String::as_str).chain(FONT_PATHS);
        for p in candidates {
            if let Ok(bytes) = std::fs::read(p) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok()
                {
                    return true;
                }
            }
        }
        tracing::warn!(
            "no TrueType font found (set COSIM_FONT or install fonts-dejavu-core): plots have no text"
        );
        false
    })
}

/// Matplotlib's "tab10" cycle, the colours researchers know (ten joints of a crash tube
/// on one chart, each its own).
const COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Axis range of all finite values with a margin; a flat series gets a unit-free band.
fn range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = bounds(vals);
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let span = hi - lo;
    let pad = if span > 0.0 {
        0.05 * span
    } else {
        0.5 * lo.abs().max(1e-12)
    };
    (lo - pad, hi + pad)
}

/// Smallest and largest finite value (infinite when there is none).
fn bounds(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    (lo, hi)
}

/// The SI unit of a reported quantity, from its name (the nodes report SI, see
/// docs/user-guide.md): the last part of a dotted name, a vector component's `_x`/`_y`/`_z` aside;
/// `None` when the name does not say. Counts and ratios read "1".
pub fn unit_of(key: &str) -> Option<&'static str> {
    let k = key.rsplit('.').next().unwrap_or(key).to_ascii_lowercase();
    let base = ["_x", "_y", "_z"]
        .iter()
        .find_map(|c| k.strip_suffix(c))
        .unwrap_or(&k);
    let has = |w: &str| base.contains(w);
    let ends = |w: &str| base.ends_with(w);
    // a vector's component of a location; an edge line's first and last crossing (the
    // fluid's `NAME.first`, `NAME.last`)
    let located = base != k
        && ["first_damage", "centre", "center", "com", "crack_tip"].contains(&base)
        || ["first", "last"].contains(&base);
    Some(if ends("per_s") {
        "1/s"
    } else if base == "time"
        || base.starts_with("time_")
        || ends("_time")
        || ends("_s")
        || base == "dt"
        || ends("_dt")
    {
        "s"
    } else if has("energy") || has("work") {
        "J"
    } else if has("momentum") || has("impulse") {
        "N s"
    } else if has("pressure") || has("stress") || has("modulus") || has("mises") {
        "Pa"
    } else if has("velocity") || has("speed") || ["_vx", "_vy", "_vz"].iter().any(|w| ends(w)) {
        "m/s"
    } else if has("fraction") || has("ratio") || has("_over_") {
        "1"
    } else if has("density") {
        "kg/m³"
    } else if has("mass") {
        "kg"
    } else if has("temperature") {
        "K"
    } else if has("force") || has("lambda") {
        "N"
    } else if located
        || [
            "displacement",
            "position",
            "deflection",
            "gap",
            "width",
            "thickness",
            "radius",
            "extent",
        ]
        .iter()
        .any(|w| has(w))
        || has("distance")
        || has("length")
        || ["_ux", "_uy", "_uz"].iter().any(|w| ends(w))
        || ["ux", "uy", "uz"].contains(&base)
    {
        "m"
    } else if [
        "strain",
        "damage",
        "count",
        "particles",
        "nodes",
        "bonds",
        "fragments",
        "cells",
        "index",
    ]
    .iter()
    .any(|w| has(w))
    {
        "1"
    } else {
        return None;
    })
}

/// A y-axis title: the quantity with its unit (`point2.pressure [Pa]`).
fn with_unit(label: &str) -> String {
    match unit_of(label) {
        Some(u) if !label.ends_with(']') => format!("{label} [{u}]"),
        _ => label.to_string(),
    }
}

/// Time axis scale: seconds shown in s, ms or µs so that the largest time reads 1–1000.
fn time_scale(t_max: f64) -> (f64, &'static str) {
    match t_max.abs() {
        t if t > 0.0 && t < 1e-3 => (1e6, "t [µs]"),
        t if t > 0.0 && t < 1.0 => (1e3, "t [ms]"),
        _ => (1.0, "t [s]"),
    }
}

/// Tick labels for an axis spanning `lo..hi`: fixed notation with as many decimals as the
/// tick spacing needs for magnitudes 1e-3 … 1e5, else scientific with as many digits as tell
/// the ticks apart; values within 1e-9 of the span from zero read 0 (no `-6.8e-21`).
pub(crate) fn tick_label(v: f64, lo: f64, hi: f64) -> String {
    let span = (hi - lo).abs();
    let step = if span > 0.0 {
        span / 10.0
    } else {
        lo.abs().max(1e-300)
    };
    if v.abs() <= 1e-9 * span {
        return "0".into();
    }
    let mag = lo.abs().max(hi.abs());
    if (1e-3..1e5).contains(&mag) {
        let decimals = (-step.log10()).ceil().clamp(0.0, 9.0) as usize;
        format!("{v:.decimals$}")
    } else {
        let unit = 10f64.powf(mag.log10().floor());
        let digits = (-(step / unit).log10()).ceil().clamp(0.0, 9.0) as usize;
        format!("{v:.digits$e}")
    }
}

/// Whether a series is zero at every point (not worth a chart of its own).
fn all_zero(points: &[(f64, f64)]) -> bool {
    points.iter().all(|p| p.1 == 0.0)
}

/// Draw `series` as lines into a PNG at `path` (800×500).
pub fn line_chart(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> anyhow::Result<()> {
    png_whole(path, |tmp| {
        line_chart_into(tmp, title, x_label, y_label, series)
    })
}

/// Draw a picture whole or not at all: `draw` writes it to a hidden file beside `path`
/// (ending `.png` too: the encoder picks the format by the extension), renamed over `path`
/// once written. On a full disk neither a truncated nor an empty picture is left, and the
/// error names `path`.
pub fn png_whole<T>(
    path: &Path,
    draw: impl FnOnce(&Path) -> anyhow::Result<T>,
) -> anyhow::Result<T> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.part.png"));
    let drawn = draw(&tmp).and_then(|v| {
        std::fs::rename(&tmp, path)?;
        Ok(v)
    });
    drawn.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        e.context(format!("cannot write {}", path.display()))
    })
}

/// The axes of a line chart of `series`: the scale of x and its label (time in s, ms or µs
/// where x is `t [s]`), and the spans of x (the data exactly: a run starts at t = 0) and of
/// y.
fn axes<'a>(series: &[Series], x_label: &'a str) -> (f64, &'a str, (f64, f64), (f64, f64)) {
    let (xs, x_label) = if x_label == "t [s]" {
        let (_, t_max) = bounds(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
        time_scale(t_max)
    } else {
        (1.0, x_label)
    };
    let xs_of = || {
        series
            .iter()
            .flat_map(move |s| s.points.iter().map(move |p| p.0 * xs))
    };
    let (mut x0, mut x1) = bounds(xs_of());
    if !(x0.is_finite() && x1 > x0) {
        (x0, x1) = range(xs_of());
    }
    let y = range(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    (xs, x_label, (x0, x1), y)
}

fn line_chart_into(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> anyhow::Result<()> {
    let panel = Panel {
        title: title.to_string(),
        y_label: y_label.to_string(),
        series: series.to_vec(),
    };
    grid_chart_into(path, "", x_label, std::slice::from_ref(&panel))
}

/// One chart of a figure: its title, its quantity (y) and its lines.
#[derive(Debug, Clone)]
pub struct Panel {
    pub title: String,
    pub y_label: String,
    pub series: Vec<Series>,
}

/// Draw `panels` into one PNG at `path`: a single chart is 800×500; several are laid out in
/// a grid of up to four columns, 600×380 each, under the figure's `title`.
pub fn grid_chart(path: &Path, title: &str, x_label: &str, panels: &[Panel]) -> anyhow::Result<()> {
    png_whole(path, |tmp| grid_chart_into(tmp, title, x_label, panels))
}

/// Columns and rows of a grid of `n` panels.
fn grid_of(n: usize) -> (usize, usize) {
    let cols = match n {
        0 | 1 => 1,
        2 | 4 => 2,
        3 | 5 | 6 | 9 => 3,
        _ => 4,
    };
    (cols, n.div_ceil(cols))
}

fn grid_chart_into(
    path: &Path,
    title: &str,
    x_label: &str,
    panels: &[Panel],
) -> anyhow::Result<()> {
    let drawn: Vec<&Panel> = panels
        .iter()
        .filter(|p| p.series.iter().any(|s| !s.points.is_empty()))
        .collect();
    if drawn.is_empty() {
        let what = panels.first().map_or(title, |p| p.title.as_str());
        bail!("{what}: nothing to plot");
    }
    let text = font_ready();
    let draw = |e: &dyn std::fmt::Display| anyhow::anyhow!("plot {}: {e}", path.display());
    let (cols, rows) = grid_of(drawn.len());
    let heading = if text && drawn.len() > 1 && !title.is_empty() {
        40
    } else {
        0
    };
    let size = if drawn.len() == 1 {
        (800, 500)
    } else {
        (600 * cols as u32, 380 * rows as u32 + heading)
    };
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(|e| draw(&e))?;
    let body = if heading > 0 {
        root.titled(title, ("sans-serif", 26))
            .map_err(|e| draw(&e))?
    } else {
        root.clone()
    };
    for (area, panel) in body.split_evenly((rows, cols)).iter().zip(&drawn) {
        draw_panel(area, panel, x_label, text).map_err(|e| draw(&e))?;
    }
    root.present().map_err(|e| draw(&e))?;
    Ok(())
}

/// One panel's axes, grid, lines and legend on `area`.
fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    panel: &Panel,
    x_label: &str,
    text: bool,
) -> Result<(), String> {
    let series = &panel.series;
    let (xs, x_label, (x0, x1), (y0, y1)) = axes(series, x_label);
    let y_label = with_unit(&panel.y_label);
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let mut builder = ChartBuilder::on(area);
    builder.margin(15);
    if text {
        builder
            .caption(&panel.title, ("sans-serif", 22))
            .x_label_area_size(45)
            .y_label_area_size(80);
    } else {
        builder.x_label_area_size(10).y_label_area_size(10);
    }
    let mut chart = builder
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|x| e(&x))?;
    let x_ticks = |v: &f64| tick_label(*v, x0, x1);
    let y_ticks = |v: &f64| tick_label(*v, y0, y1);
    let mut mesh = chart.configure_mesh();
    if text {
        mesh.x_desc(x_label)
            .y_desc(y_label.as_str())
            .x_label_formatter(&x_ticks)
            .y_label_formatter(&y_ticks)
            .label_style(("sans-serif", 13));
    } else {
        mesh.x_labels(0).y_labels(0);
    }
    mesh.draw().map_err(|x| e(&x))?;
    for (i, s) in series.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        let pts = s
            .points
            .iter()
            .map(|p| (p.0 * xs, p.1))
            .filter(|p| p.0.is_finite() && p.1.is_finite());
        let drawn = chart
            .draw_series(LineSeries::new(pts, colour.stroke_width(2)))
            .map_err(|x| e(&x))?;
        if text {
            drawn
                .label(s.label.clone())
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], colour));
        }
    }
    if text && (series.len() > 1 || series.first().is_some_and(|s| !s.label.is_empty())) {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .draw()
            .map_err(|x| e(&x))?;
    }
    Ok(())
}

/// Time histories per node and quantity: node → quantity → (t, value).
pub type Histories = BTreeMap<String, BTreeMap<String, Vec<(f64, f64)>>>;

/// Add one window's node report (the JSON of a `/cosim/node/<node>` message) to `h`: the
/// energies, the momentum components and the node's scalars, at the report's `time`.
pub fn add_report(h: &mut Histories, node: &str, v: &serde_json::Value) {
    let Some(obj) = v.as_object() else { return };
    let Some(t) = obj.get("time").and_then(|t| t.as_f64()) else {
        return;
    };
    let q = h.entry(node.to_string()).or_default();
    for (k, val) in obj {
        match (k.as_str(), val) {
            (k, _) if SKIPPED.contains(&k) => {}
            (_, serde_json::Value::Number(n)) => {
                if let Some(x) = n.as_f64() {
                    q.entry(k.clone()).or_default().push((t, x));
                }
            }
            // a vector (`momentum`, or a node's `K_x`, `K_y`, `K_z` recorded as one `K`) is
            // plotted by component, `K_x`; the impulses, which a live run does not plot, stay
            // out
            (k, serde_json::Value::Array(a))
                if k != "external_impulse" && k != "interface_impulse" =>
            {
                for (d, c) in a.iter().enumerate().take(3) {
                    if let Some(x) = c.as_f64() {
                        q.entry(format!("{k}_{}", ["x", "y", "z"][d]))
                            .or_default()
                            .push((t, x));
                    }
                }
            }
            _ => {}
        }
    }
}

/// [`add_report`] straight from a node's report of the window ending at `t` (as the
/// coordinator records it, see `run::NodeReportDoc`), without building its JSON: each series
/// is reserved for `windows` points when it first appears, so a run adds them without
/// allocating.
pub fn add_node_report(
    h: &mut Histories,
    node: &str,
    t: f64,
    r: &protocol::StepReport,
    windows: usize,
) {
    if !h.contains_key(node) {
        h.insert(node.to_string(), BTreeMap::new());
    }
    let Some(q) = h.get_mut(node) else { return };
    let mut push = |k: &str, x: f64| {
        // a NaN or infinite value is recorded as null, which add_report skips
        if !x.is_finite() || SKIPPED.contains(&k) {
            return;
        }
        match q.get_mut(k) {
            Some(v) => v.push((t, x)),
            None => {
                let mut v = Vec::with_capacity(windows.max(1));
                v.push((t, x));
                q.insert(k.to_string(), v);
            }
        }
    };
    let shadowed = |k: &str| r.scalars.iter().any(|(n, _)| n == k);
    for (k, x) in [
        ("kinetic_energy", r.kinetic_energy),
        ("internal_energy", r.internal_energy),
        ("external_work", r.external_work),
        ("interface_work", r.interface_work),
        ("momentum_gross", r.momentum_gross),
    ] {
        if !shadowed(k) {
            push(k, x);
        }
    }
    if !shadowed("momentum") {
        for (d, axis) in ["momentum_x", "momentum_y", "momentum_z"]
            .iter()
            .enumerate()
        {
            push(axis, r.momentum[d]);
        }
    }
    for (k, x) in &r.scalars {
        push(k, *x);
    }
}

/// Keys of a node report that are not plotted.
const SKIPPED: [&str; 6] = [
    "time",
    "window",
    "substeps",
    "wall_s",
    "coupling_wait_s",
    "idle_s",
];

/// The node histories of a recording (its `/cosim/node/<n>` channels).
pub fn node_histories(msgs: &[Recorded]) -> Histories {
    let mut out = Histories::new();
    for m in msgs {
        let Some(node) = m.topic.strip_prefix("/cosim/node/") else {
            continue;
        };
        if let Ok(v) = serde_json::from_slice::<serde_json::Value>(&m.data) {
            add_report(&mut out, node, &v);
        }
    }
    out
}

/// File-name-safe form of a quantity name.
pub fn file_stem(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Every quantity of a run on its own (`cosim plot RUN --all`), written to `plots`: per node
/// an energy chart and one chart per other quantity (none for one that is zero throughout).
/// Returns the files.
pub fn every_quantity(hist: &Histories, plots: &Path) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(plots).with_context(|| format!("cannot create {}", plots.display()))?;
    let mut written = Vec::new();
    for (node, q) in hist {
        // every energy and work term of the node on one chart, those zero throughout left out
        let energies: Vec<Series> = q
            .iter()
            .filter(|(k, p)| {
                (k.ends_with("_energy") || *k == "interface_work" || *k == "external_work")
                    && !all_zero(p)
            })
            .map(|(k, p)| Series {
                label: k.replace('_', " "),
                points: p.clone(),
            })
            .collect();
        if !energies.is_empty() {
            let p = plots.join(format!("{node}_energy.png"));
            line_chart(&p, &format!("{node}: energy"), "t [s]", "energy", &energies)?;
            written.push(p);
        }
        for (k, pts) in q {
            if k.ends_with("_energy")
                || k == "interface_work"
                || k == "external_work"
                || all_zero(pts)
            {
                continue;
            }
            let p = plots.join(format!("{node}_{}.png", file_stem(k)));
            let s = [Series {
                label: String::new(),
                points: pts.clone(),
            }];
            line_chart(&p, &format!("{node}: {k}"), "t [s]", k, &s)?;
            written.push(p);
        }
    }
    Ok(written)
}

/// `NODE.QUANTITY` of one run's histories; `*.QUANTITY` is the one node that reports it.
fn lookup<'a>(h: &'a Histories, label: &str, spec: &str) -> anyhow::Result<&'a [(f64, f64)]> {
    let (node, q) = spec
        .split_once('.')
        .with_context(|| format!("{spec}: must be NODE.QUANTITY (or *.QUANTITY)"))?;
    if node == "*" {
        let hits: Vec<(&String, &Vec<(f64, f64)>)> = h
            .iter()
            .filter_map(|(n, m)| m.get(q).map(|p| (n, p)))
            .collect();
        return match hits.as_slice() {
            [(_, p)] => Ok(p.as_slice()),
            [] => bail!("run '{label}': no node reports {q}"),
            many => bail!(
                "run '{label}': several nodes report {q} ({}); name one",
                many.iter()
                    .map(|(n, _)| n.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        };
    }
    match h.get(node).and_then(|m| m.get(q)) {
        Some(p) => Ok(p.as_slice()),
        None => {
            let known: Vec<&String> = h.get(node).map(|m| m.keys().collect()).unwrap_or_default();
            match h.get(node) {
                None => bail!(
                    "run '{label}' has no node {node} (its nodes: {})",
                    h.keys().cloned().collect::<Vec<_>>().join(", ")
                ),
                Some(_) => bail!(
                    "run '{label}' has no {node}.{q}{} (it has: {known:?})",
                    protocol::params::did_you_mean(q, known.iter().map(|k| k.as_str()))
                        .map(|m| format!("; did you mean {node}.{m}?"))
                        .unwrap_or_default()
                ),
            }
        }
    }
}

/// The series of one run a `--series` names: `NODE.QUANTITY` itself, or where the quantity
/// (or the node) holds a `*`, every match in name order (`gas.point*.pressure`).
fn expand(h: &Histories, label: &str, spec: &str) -> anyhow::Result<Vec<String>> {
    let (node, q) = spec
        .split_once('.')
        .with_context(|| format!("{spec}: must be NODE.QUANTITY (or *.QUANTITY)"))?;
    if !q.contains('*') && (node == "*" || !node.contains('*')) {
        lookup(h, label, spec)?;
        return Ok(vec![spec.to_string()]);
    }
    let hits: Vec<String> = h
        .iter()
        .filter(|(n, _)| crate::export::glob(node, n))
        .flat_map(|(n, m)| {
            m.keys()
                .filter(|k| crate::export::glob(q, k))
                .map(move |k| format!("{n}.{k}"))
        })
        .collect();
    if hits.is_empty() {
        bail!("run '{label}': nothing matches {spec}");
    }
    Ok(hits)
}

/// Pair two histories of one run by time (same window ends): (x(t), y(t)).
fn pair(x: &[(f64, f64)], y: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(y.len());
    let mut i = 0;
    for &(t, v) in y {
        while i < x.len() && x[i].0 < t * (1.0 - 1e-12) {
            i += 1;
        }
        if i < x.len() && (x[i].0 - t).abs() <= 1e-12 * t.abs().max(1e-300) {
            out.push((x[i].1, v));
        }
    }
    out
}

/// `cosim plot`: the `series` of several `runs` (output directories holding `run.mcap`, or
/// recordings; a line per run and series, runs labelled by their directory's name) against
/// time or against another reported quantity `x` (e.g. force against displacement). Series
/// that share a unit share a figure (`--series gas.point1.pressure --series
/// gas.point2.pressure`: one chart); a `*` in the quantity takes every match
/// (`gas.point*.pressure`); a node named `*` is whichever node of each run reports the
/// quantity (runs whose nodes are named differently, e.g. a two-scale and a single-scale
/// model of one coupon). Returns the files, one per unit.
pub fn compare(
    runs: &[PathBuf],
    series: &[String],
    x: Option<&str>,
    out_dir: &Path,
) -> anyhow::Result<Vec<PathBuf>> {
    let data = load_runs(runs)?;
    std::fs::create_dir_all(out_dir)
        .with_context(|| format!("cannot create {}", out_dir.display()))?;
    // (unit, specs in order, lines)
    let mut figures: Vec<(Option<&str>, Vec<&str>, Vec<Series>)> = Vec::new();
    for s in series {
        let q = s.split_once('.').map_or(s.as_str(), |(_, q)| q);
        let unit = unit_of(q);
        let lines = series_lines(&data, s, x, series.len() > 1)?;
        match figures.iter_mut().find(|f| f.0 == unit) {
            Some(f) => {
                f.1.push(s);
                f.2.extend(lines);
            }
            None => figures.push((unit, vec![s.as_str()], lines)),
        }
    }
    let mut written = Vec::new();
    for (_, specs, lines) in figures {
        let stems: Vec<String> = specs.iter().map(|s| file_stem(s)).collect();
        let mut stem = stems.join("+");
        if stem.len() > 120 {
            stem = format!("{}+{}_more", stems[0], stems.len() - 1);
        }
        let q: Vec<&str> = specs
            .iter()
            .map(|s| s.split_once('.').map_or(*s, |(_, q)| q))
            .collect();
        let (stem, x_label) = match x {
            None => (stem, "t [s]".to_string()),
            Some(xs) => (
                format!("{stem}_vs_{}", file_stem(xs)),
                with_unit(xs.split_once('.').map_or(xs, |(_, q)| q)),
            ),
        };
        let title = specs.join(", ");
        let p = out_dir.join(format!("{stem}.png"));
        line_chart(&p, &title, &x_label, &q.join(", "), &lines)?;
        written.push(p);
    }
    Ok(written)
}

/// The lines of one `--series` spec `s` over the runs `data` (against time, or against `x`):
/// a line names its run where there are several, and its series where the spec matched
/// several or shares the figure with others (`shared`).
fn series_lines(
    data: &[(String, Histories)],
    s: &str,
    x: Option<&str>,
    shared: bool,
) -> anyhow::Result<Vec<Series>> {
    let mut lines = Vec::new();
    for (label, h) in data {
        let names = expand(h, label, s).with_context(|| format!("--series {s}"))?;
        for name in &names {
            let ys = lookup(h, label, name).with_context(|| format!("--series {s}"))?;
            let points = match x {
                None => ys.to_vec(),
                Some(xs) => pair(
                    lookup(h, label, xs).with_context(|| format!("--x {xs}"))?,
                    ys,
                ),
            };
            lines.push((label.clone(), name.clone(), points));
        }
    }
    let many_names = shared || lines.iter().any(|l| l.1 != lines[0].1);
    Ok(lines
        .into_iter()
        .map(|(run, name, points)| Series {
            label: match (data.len() > 1, many_names) {
                (true, true) => format!("{run}: {name}"),
                (true, false) => run,
                (false, _) => name,
            },
            points,
        })
        .collect())
}

/// The JSON messages of a run: an output directory (its `run.mcap`) or a recording.
pub(crate) fn run_messages(r: &Path) -> anyhow::Result<Vec<Recorded>> {
    let mcap = if r.is_dir() {
        r.join("run.mcap")
    } else {
        r.to_path_buf()
    };
    Ok(record::read_json(&mcap)?.0)
}

/// Each run's label (its directory's name) and node histories.
fn load_runs(runs: &[PathBuf]) -> anyhow::Result<Vec<(String, Histories)>> {
    runs.iter()
        .map(|r| Ok((run_label(r), node_histories(&run_messages(r)?))))
        .collect()
}

/// A run's label: the name of its output directory (a recording's folder).
pub(crate) fn run_label(r: &Path) -> String {
    if r.is_dir() {
        r.file_name()
    } else {
        r.parent().and_then(|p| p.file_name())
    }
    .map(|s| s.to_string_lossy().into_owned())
    .unwrap_or_else(|| r.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quantity_is_paired_with_another_by_time_and_found_by_wildcard() {
        // Displacement reported at every window, force from the second one on.
        let disp: Vec<(f64, f64)> = (1..=4).map(|k| (k as f64 * 0.1, k as f64 * 2.0)).collect();
        let force = vec![(0.2, 10.0), (0.30000000000000004, 15.0), (0.4, 12.0)];
        assert_eq!(
            pair(&disp, &force),
            vec![(4.0, 10.0), (6.0, 15.0), (8.0, 12.0)]
        );
        let mut h = Histories::new();
        h.entry("coupon".into())
            .or_default()
            .insert("force".into(), force.clone());
        h.entry("shell".into())
            .or_default()
            .insert("kinetic_energy".into(), disp.clone());
        assert_eq!(lookup(&h, "run", "*.force").unwrap(), force.as_slice());
        assert_eq!(lookup(&h, "run", "coupon.force").unwrap(), force.as_slice());
        assert!(lookup(&h, "run", "*.nothing").is_err());
        h.entry("shell".into())
            .or_default()
            .insert("force".into(), force.clone());
        let e = lookup(&h, "run", "*.force").unwrap_err().to_string();
        assert!(e.contains("several") && e.contains("shell"), "{e}");
        assert!(lookup(&h, "run", "force").is_err());
    }

    #[test]
    fn ticks_read_plainly_and_axes_carry_units() {
        // a pressure axis 1.0e5 … 3.5e5 Pa: scientific with the digits the ticks need
        assert_eq!(tick_label(2.5e5, 1.0e5, 3.5e5), "2.5e5");
        // a displacement of millimetres: fixed notation, enough decimals for the spacing
        assert_eq!(tick_label(0.0015, 0.0, 0.004), "0.0015");
        assert_eq!(tick_label(20.0, 0.0, 100.0), "20");
        assert_eq!(tick_label(-4.231e-18, -5e-18, 5e-18), "-4e-18");
        // a time axis starting at a float's round-off of zero reads 0, not -6.8e-21
        assert_eq!(tick_label(-6.8e-21, -6.8e-21, 1.6), "0");
        // a 1.6 ms run is drawn in ms, a 0.4 ms one in µs, a 2 s one in s
        assert_eq!(time_scale(1.6e-3), (1e3, "t [ms]"));
        assert_eq!(time_scale(4e-4), (1e6, "t [µs]"));
        assert_eq!(time_scale(2.0), (1.0, "t [s]"));
        assert_eq!(with_unit("point2.pressure"), "point2.pressure [Pa]");
        assert_eq!(with_unit("com_displacement_x"), "com_displacement_x [m]");
        assert_eq!(with_unit("momentum_x"), "momentum_x [N s]");
        assert_eq!(with_unit("plastic_work"), "plastic_work [J]");
        assert_eq!(with_unit("broken_bonds"), "broken_bonds [1]");
        assert_eq!(with_unit("energy [J]"), "energy [J]");
        // a time step is not a mass, a counter per second not a time
        for (key, unit) in [
            ("mass_scaling_dt", "s"),
            ("cell_updates_per_s", "1/s"),
            ("time_ghost_fills_s", "s"),
            ("added_mass", "kg"),
            ("added_mass_fraction", "1"),
            ("kinetic_over_internal", "1"),
            ("first_damage_x", "m"),
            ("first_damage_particles", "1"),
            ("A_ux", "m"),
            ("bubble.first", "m"),
            ("max_failure_index", "1"),
            ("fragment_mean_width", "m"),
            ("bubble.first_speed", "m/s"),
            ("min_density", "kg/m³"),
            ("max_von_mises", "Pa"),
            ("crack_tip_x", "m"),
            ("crack_length", "m"),
            ("contact_nodes", "1"),
            ("contact_energy", "J"),
            ("extent_radial", "m"),
            ("extent_z", "m"),
            ("wall_force_z", "N"),
        ] {
            assert_eq!(unit_of(key), Some(unit), "{key}");
        }
    }

    #[test]
    fn every_quantity_draws_no_chart_for_a_quantity_that_stays_zero() {
        let dir = std::env::temp_dir().join(format!("cosim-plot-zero-{}", std::process::id()));
        let mut h = Histories::new();
        let q = h.entry("bar".into()).or_default();
        let t: Vec<f64> = (0..50).map(|i| i as f64 * 1e-5).collect();
        q.insert(
            "tip_displacement".into(),
            t.iter().map(|&t| (t, t * 2.0)).collect(),
        );
        q.insert("momentum_z".into(), t.iter().map(|&t| (t, 0.0)).collect());
        q.insert("kinetic_energy".into(), t.iter().map(|&t| (t, t)).collect());
        q.insert(
            "fracture_energy".into(),
            t.iter().map(|&t| (t, 0.0)).collect(),
        );
        let files = every_quantity(&h, &dir).expect("plots");
        let names: Vec<String> = files
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["bar_energy.png", "bar_tip_displacement.png"]);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_chart_is_a_png_of_the_requested_size() {
        let dir = std::env::temp_dir().join(format!("cosim-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("tmp dir");
        let p = dir.join("sine.png");
        let s = [
            Series {
                label: "sin".into(),
                points: (0..200)
                    .map(|i| (i as f64 * 0.05, (i as f64 * 0.05).sin()))
                    .collect(),
            },
            Series {
                label: "flat".into(),
                points: vec![(0.0, 0.25), (10.0, 0.25)],
            },
        ];
        line_chart(&p, "test", "x", "y", &s).expect("chart");
        let bytes = std::fs::read(&p).expect("png written");
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        // IHDR: width and height, big-endian, right after the signature and chunk header.
        let w = u32::from_be_bytes([bytes[16], bytes[17], bytes[18], bytes[19]]);
        let h = u32::from_be_bytes([bytes[20], bytes[21], bytes[22], bytes[23]]);
        assert_eq!((w, h), (800, 500));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn an_empty_chart_is_an_error_not_an_empty_file() {
        let p = std::env::temp_dir().join("cosim-plot-empty.png");
        let s = [Series {
            label: "none".into(),
            points: vec![],
        }];
        assert!(line_chart(&p, "t", "x", "y", &s).is_err());
    }
}
