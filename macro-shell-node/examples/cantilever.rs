//! Full-resolution frequency runs (issue #5 must-show 2 and 3):
//! `cargo run --release -p macro-shell-node --example cantilever -- [nx ny] [plate n]`
//! Steel cantilever strip 1 × 0.1 × 0.01 m kicked with v_z = v0 x/L: the first three bending
//! frequencies from a Blackman–Harris-windowed DFT of the tip velocity (1 s record) against
//! Euler–Bernoulli 8.382, 52.528, 147.081 Hz; then the simply supported 1 × 1 × 0.01 m plate
//! against Kirchhoff 49.329 Hz.
#![allow(clippy::needless_range_loop)]

use macro_shell_node::{ShellSolver, step};

const STEEL: &str = r#"
[material]
model = "elastic"
density = 7800.0
youngs_modulus = 210.0e9
poisson_ratio = 0.3
[section]
thickness = 0.01
integration_points = 3
"#;

fn window(u: f64) -> f64 {
    0.35875 - 0.48829 * u.cos() + 0.14128 * (2.0 * u).cos() - 0.01168 * (3.0 * u).cos()
}

fn mag(x: &[f64], dt: f64, f: f64) -> f64 {
    let n = x.len();
    let (mut re, mut im) = (0.0, 0.0);
    for (k, &v) in x.iter().enumerate() {
        let w = window(2.0 * std::f64::consts::PI * k as f64 / (n - 1) as f64);
        let (s, c) = (2.0 * std::f64::consts::PI * f * dt * k as f64).sin_cos();
        re += w * v * c;
        im -= w * v * s;
    }
    (re * re + im * im).sqrt()
}

/// Strongest `count` peaks in (lo, hi), leakage within 4/T of a stronger peak skipped.
fn peaks(x: &[f64], dt: f64, lo: f64, hi: f64, count: usize) -> Vec<f64> {
    let t = dt * x.len() as f64;
    let df = 0.25 / t;
    let nf = ((hi - lo) / df) as usize;
    let spec: Vec<f64> = (0..=nf).map(|k| mag(x, dt, lo + k as f64 * df)).collect();
    let mut c: Vec<(f64, f64)> = (1..nf)
        .filter(|&k| spec[k] > spec[k - 1] && spec[k] >= spec[k + 1])
        .map(|k| (spec[k], lo + k as f64 * df))
        .collect();
    c.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut kept: Vec<f64> = Vec::new();
    for (_, f) in c {
        if kept.iter().all(|k| (k - f).abs() > 4.0 / t) {
            kept.push(f);
        }
    }
    let mut out: Vec<f64> = kept
        .into_iter()
        .take(count)
        .map(|f| {
            let (mut a, mut b) = (f - df, f + df);
            let g = 0.5 * (5f64.sqrt() - 1.0);
            for _ in 0..60 {
                let (c, d) = (b - g * (b - a), a + g * (b - a));
                if mag(x, dt, c) > mag(x, dt, d) {
                    b = d;
                } else {
                    a = c;
                }
            }
            0.5 * (a + b)
        })
        .collect();
    out.sort_by(|a, b| a.total_cmp(b));
    out
}

fn build(toml: &str) -> ShellSolver {
    ShellSolver::from_toml_str(toml).unwrap_or_else(|e| panic!("{e}"))
}

fn record(s: &mut ShellSolver, probe: &[u32], t_end: f64, sample: f64) -> Vec<f64> {
    let m = &mut s.model;
    let dt_s = step::stable_dt(m);
    let sub = (sample / dt_s).ceil() as usize;
    let dt = sample / sub as f64;
    let mut h = Vec::new();
    for _ in 0..(t_end / sample) as usize {
        for _ in 0..sub {
            step::step(m, dt).unwrap_or_else(|e| panic!("{e}"));
        }
        h.push(probe.iter().map(|&i| m.v[i as usize][2]).sum::<f64>() / probe.len() as f64);
    }
    h
}

fn main() {
    let a: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|s| s.parse().ok())
        .collect();
    let (nx, ny) = (
        a.first().copied().unwrap_or(80),
        a.get(1).copied().unwrap_or(4),
    );
    let np = a.get(2).copied().unwrap_or(24);
    let t0 = std::time::Instant::now();
    let mut s = build(&format!(
        "[mesh]\nkind = \"plate\"\nlength = 1.0\nwidth = 0.1\nnx = {nx}\nny = {ny}\n{STEEL}\n[[fixed]]\nnode_set = \"x0\"\n"
    ));
    for i in 0..s.model.num_nodes() {
        if s.model.fix[i] == 0 {
            s.model.v[i][2] = 0.05 * s.model.x0[i][0];
            s.model.w[i][1] = -0.05;
        }
    }
    let tip = s.model.node_sets["x1"].clone();
    let h = record(&mut s, &tip, 1.0, 2.5e-4);
    let f = peaks(&h, 2.5e-4, 3.0, 250.0, 3);
    let exact = [8.382, 52.528, 147.081];
    println!(
        "cantilever {nx}x{ny} ({} steps, {:.1} s):",
        s.model.steps,
        t0.elapsed().as_secs_f64()
    );
    for k in 0..f.len().min(3) {
        println!(
            "  mode {}: {:8.3} Hz  (Euler–Bernoulli {:7.3}, error {:+.3} %)",
            k + 1,
            f[k],
            exact[k],
            100.0 * (f[k] - exact[k]) / exact[k]
        );
    }
    let t1 = std::time::Instant::now();
    let mut p = build(&format!(
        "[mesh]\nkind = \"plate\"\nlength = 1.0\nwidth = 1.0\nnx = {np}\nny = {np}\n{STEEL}\n\
         [[fixed]]\nnode_set = \"x0\"\ndofs = [\"z\"]\n[[fixed]]\nnode_set = \"x1\"\ndofs = [\"z\"]\n\
         [[fixed]]\nnode_set = \"y0\"\ndofs = [\"z\"]\n[[fixed]]\nnode_set = \"y1\"\ndofs = [\"z\"]\n"
    ));
    let pi = std::f64::consts::PI;
    let m = &mut p.model;
    for i in 0..m.num_nodes() {
        let [x, y, _] = m.x0[i];
        if m.fix[i] == 0 {
            m.v[i][2] = 0.01 * (pi * x).sin() * (pi * y).sin();
        }
        m.w[i][0] = 0.01 * pi * (pi * x).sin() * (pi * y).cos();
        m.w[i][1] = -0.01 * pi * (pi * x).cos() * (pi * y).sin();
    }
    let centre: Vec<u32> = (0..m.num_nodes() as u32)
        .filter(|&i| {
            let [x, y, _] = m.x0[i as usize];
            (x - 0.5).abs() < 1e-9 && (y - 0.5).abs() < 1e-9
        })
        .collect();
    let h = record(&mut p, &centre, 0.25, 2.5e-4);
    let f = peaks(&h, 2.5e-4, 10.0, 200.0, 1);
    println!(
        "simply supported plate {np}x{np} ({:.1} s): f1 = {:.3} Hz (Kirchhoff 49.329, error {:+.3} %)",
        t1.elapsed().as_secs_f64(),
        f[0],
        100.0 * (f[0] - 49.329) / 49.329
    );
}
