//! Helpers shared by the integration tests: building a shell from TOML, and extracting
//! frequencies from a sampled history (Hann-windowed DFT, peak refined by golden section).
#![allow(clippy::needless_range_loop)]
#![allow(dead_code)]

use macro_shell_node::ShellSolver;

pub const STEEL: &str = r#"
[material]
model = "elastic"
density = 7800.0
youngs_modulus = 210.0e9
poisson_ratio = 0.3
"#;

pub fn shell(toml: &str) -> ShellSolver {
    match ShellSolver::from_toml_str(toml) {
        Ok(s) => s,
        Err(e) => panic!("config refused: {e}"),
    }
}

/// |Σ w_k x_k e^{−iωt_k}| with a 4-term Blackman–Harris window (side lobes below −92 dB, so
/// a weak mode is not hidden under a strong one's leakage).
pub fn dft_mag(x: &[f64], dt: f64, f: f64) -> f64 {
    let n = x.len();
    let (mut re, mut im) = (0.0, 0.0);
    let w = 2.0 * std::f64::consts::PI * f * dt;
    for (k, &v) in x.iter().enumerate() {
        let u = 2.0 * std::f64::consts::PI * k as f64 / (n - 1) as f64;
        let han =
            0.35875 - 0.48829 * u.cos() + 0.14128 * (2.0 * u).cos() - 0.01168 * (3.0 * u).cos();
        let (s, c) = (w * k as f64).sin_cos();
        re += han * v * c;
        im -= han * v * s;
    }
    (re * re + im * im).sqrt()
}

/// The `count` strongest spectral peaks of `x` (sampled every `dt`) in (f_lo, f_hi),
/// ascending in frequency, each refined to the maximum of the windowed DFT. A local maximum
/// within the main-lobe half width (4/T) of a stronger one is leakage and is skipped.
pub fn peaks(x: &[f64], dt: f64, f_lo: f64, f_hi: f64, count: usize) -> Vec<f64> {
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    let y: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let t = dt * x.len() as f64;
    let df = 0.25 / t;
    let nf = ((f_hi - f_lo) / df) as usize;
    let spec: Vec<f64> = (0..=nf)
        .map(|k| dft_mag(&y, dt, f_lo + k as f64 * df))
        .collect();
    let mut cands: Vec<(f64, f64)> = (1..nf)
        .filter(|&k| spec[k] > spec[k - 1] && spec[k] >= spec[k + 1])
        .map(|k| (spec[k], f_lo + k as f64 * df))
        .collect();
    cands.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut kept: Vec<(f64, f64)> = Vec::new();
    for c in cands {
        if kept.iter().all(|k| (k.1 - c.1).abs() > 4.0 / t) {
            kept.push(c);
        }
    }
    let mut out: Vec<f64> = kept
        .iter()
        .take(count)
        .map(|&(_, f)| {
            // Golden-section search for the maximum in [f − df, f + df].
            let (mut a, mut b) = (f - df, f + df);
            let g = 0.5 * (5f64.sqrt() - 1.0);
            for _ in 0..60 {
                let c = b - g * (b - a);
                let d = a + g * (b - a);
                if dft_mag(&y, dt, c) > dft_mag(&y, dt, d) {
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
