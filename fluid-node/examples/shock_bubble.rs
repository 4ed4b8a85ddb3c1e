//! Shock–helium-bubble interaction at full resolution (seed 002 §5.1). Loads
//! the case file (first argument, default `examples/shock_bubble.toml`), builds the fluid
//! node from `[nodes.gas.params]` through `fluid_node::factory`'s model, runs it in-process
//! window by window, tracks the bubble's upstream and downstream edges on the symmetry axis
//! (helium volume fraction 0.5) and prints their speeds against Haas & Sturtevant's
//! 230 m/s (upstream edge / jet) and 145 m/s (downstream edge).
//! Optional second argument: a directory for VTK output and the edge history CSV.

use anyhow::{Context, Result, bail};
use fluid_node::EulerSolver;
use fluid_node::diagnostics::cell_prim;
use protocol::{Inbox, Outbox, Solver, Window};
use std::fmt::Write as _;

/// Edges of the helium region on the axis row: (leftmost, rightmost) x where α_He ≥ 0.5.
fn edges(s: &EulerSolver, he: usize) -> Option<(f64, f64)> {
    let f = &s.fluid;
    let g = &f.grid;
    let r = g.row(g.g[1], g.g[2]);
    let mut prev: Option<(f64, f64)> = None;
    let (mut lo, mut hi) = (None, None);
    for i in g.irange() {
        let x = g.centre(i, g.g[1], g.g[2])[0];
        let a = cell_prim(f, r, i).3[he];
        if let Some((xp, ap)) = prev {
            let cross = |t: f64| xp + (t - ap) / (a - ap) * (x - xp);
            if ap < 0.5 && a >= 0.5 && lo.is_none() {
                lo = Some(cross(0.5));
            }
            if ap >= 0.5 && a < 0.5 {
                hi = Some(cross(0.5));
            }
        }
        prev = Some((x, a));
    }
    Some((lo?, hi?))
}

/// Least-squares slope of (t, x) samples.
fn slope(p: &[(f64, f64)]) -> f64 {
    let n = p.len() as f64;
    let (st, sx) = p.iter().fold((0.0, 0.0), |a, q| (a.0 + q.0, a.1 + q.1));
    let (mt, mx) = (st / n, sx / n);
    let num: f64 = p.iter().map(|q| (q.0 - mt) * (q.1 - mx)).sum();
    let den: f64 = p.iter().map(|q| (q.0 - mt).powi(2)).sum();
    num / den
}

fn main() -> Result<()> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "examples/shock_bubble.toml".into());
    let outdir = std::env::args().nth(2);
    let text = std::fs::read_to_string(&path).with_context(|| format!("reading {path}"))?;
    let case: toml::Table = text.parse().with_context(|| format!("parsing {path}"))?;
    let run = case
        .get("run")
        .and_then(|v| v.as_table())
        .context("[run] missing")?;
    let end = run
        .get("end_time")
        .and_then(|v| v.as_float())
        .context("run.end_time")?;
    let window = run
        .get("window")
        .and_then(|v| v.as_float())
        .context("run.window")?;
    let node = case
        .get("nodes")
        .and_then(|v| v.get("gas"))
        .and_then(|v| v.as_table())
        .context("[nodes.gas] missing")?;
    let model = node
        .get("model")
        .and_then(|v| v.as_str())
        .unwrap_or("euler");
    let params = node
        .get("params")
        .and_then(|v| v.as_table())
        .context("[nodes.gas.params] missing")?;
    // the factory is the node's registry; build through it to check the model name, then
    // keep a concrete solver to read its fields
    fluid_node::factory(model, params).map_err(|e| anyhow::anyhow!("nodes.gas.params.{e}"))?;
    let mut s = EulerSolver::new(params).map_err(|e| anyhow::anyhow!("nodes.gas.params.{e}"))?;
    let he = s
        .fluid
        .material_names
        .iter()
        .position(|n| n == "helium")
        .context("the case needs a material named 'helium'")?;
    println!(
        "shock-bubble: {} x {} cells, {} windows of {window:e} s",
        s.fluid.grid.n[0],
        s.fluid.grid.n[1],
        (end / window).round()
    );
    let (inbox, mut out) = (Inbox::new(), Outbox::new());
    let nwin = (end / window).round() as u64;
    let mut hist: Vec<(f64, f64, f64)> = Vec::new();
    let (x0_lo, x0_hi) = edges(&s, he).context("no helium on the axis")?;
    hist.push((0.0, x0_lo, x0_hi));
    let wall = std::time::Instant::now();
    for k in 1..=nwin {
        let w = Window {
            index: k,
            t0: (k - 1) as f64 * window,
            t1: k as f64 * window,
            write_output: false,
        };
        s.advance(&w, &inbox, &mut out)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        if let Some((lo, hi)) = edges(&s, he) {
            hist.push((w.t1, lo, hi));
        }
        if let Some(d) = &outdir
            && k % 20 == 0
        {
            s.write_output(w.t1, k, std::path::Path::new(d))
                .map_err(|e| anyhow::anyhow!("{e}"))?;
        }
    }
    println!("run took {:.1} s wall", wall.elapsed().as_secs_f64());
    // an edge "moves" once it is 0.5 mm from where it started
    let moving = |sel: fn(&(f64, f64, f64)) -> f64, x0: f64| -> Vec<(f64, f64)> {
        hist.iter()
            .filter(|h| (sel(h) - x0).abs() > 5e-4)
            .map(|h| (h.0, sel(h)))
            .collect()
    };
    let up = moving(|h| h.2, x0_hi);
    let down = moving(|h| h.1, x0_lo);
    if up.len() < 4 || down.len() < 4 {
        bail!("edges did not move enough to measure speeds (run longer)");
    }
    // speeds over the whole time each edge is moving (straight x-t lines, seed 002 Fig. 8)
    let vu = -slope(&up);
    let vd = -slope(&down);
    println!(
        "upstream edge (jet):  {vu:7.1} m/s  (Haas & Sturtevant 230 m/s, {:+.1} %), fitted over t = {:.0}..{:.0} µs",
        100.0 * (vu / 230.0 - 1.0),
        up[0].0 * 1e6,
        up[up.len() - 1].0 * 1e6
    );
    println!(
        "downstream edge:      {vd:7.1} m/s  (Haas & Sturtevant 145 m/s, {:+.1} %), fitted over t = {:.0}..{:.0} µs",
        100.0 * (vd / 145.0 - 1.0),
        down[0].0 * 1e6,
        down[down.len() - 1].0 * 1e6
    );
    if let Some(d) = &outdir {
        let mut csv = String::from("time_s,downstream_edge_m,upstream_edge_m\n");
        for (t, lo, hi) in &hist {
            let _ = writeln!(csv, "{t:e},{lo:e},{hi:e}");
        }
        std::fs::write(std::path::Path::new(d).join("edges.csv"), csv)?;
    }
    Ok(())
}
