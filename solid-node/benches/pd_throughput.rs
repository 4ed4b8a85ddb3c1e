//! Throughput benchmark (issue #4, must-show 7): bond-updates per second for pd-bond and
//! pd-correspondence on a 31 × 31 × 31 cubic block (29,791 particles), δ = 3.015 Δx
//! (122-member interior families, 3,244,494 bonds), 100 full time steps (forces, damage
//! check, velocity-Verlet integration); pd-rk-ba (order 2) on the same block for reference.
//! Select models by naming them after `--`. Run with RAYON_NUM_THREADS=1 and 2:
//! `RAYON_NUM_THREADS=1 cargo bench -p solid-node --bench pd_throughput`.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use mechanics::damage::CriticalStretch;
use mechanics::j2::J2Material;
use solid_node::pd::bond::BondModel;
use solid_node::pd::correspondence::Correspondence;
use solid_node::pd::family::Bonds;
use solid_node::pd::geometry::cube_lattice;
use solid_node::pd::integrate::Body;
use solid_node::pd::model::{Dim, Kinematics, PdModel};
use solid_node::pd::rk_ba::RkBa;
use std::time::Instant;

fn block(model: &str) -> Body {
    let dx = 1e-3;
    let horizon = 3.015 * dx;
    let x0 = cube_lattice(31, dx);
    let vol = vec![dx * dx * dx; x0.len()];
    let bonds = Bonds::build(&x0, horizon);
    let k = Kinematics {
        x0: &x0,
        pos: &x0,
        vel: &x0,
        vol: &vol,
    };
    let (e, rho) = (200e9, 7850.0);
    let mat = J2Material {
        young: e,
        poisson: 0.3,
        yield_stress: 500e6,
        iso_hardening: 1e9,
        kin_hardening: 0.0,
    };
    let m: Box<dyn PdModel> = if model == "pd-rk-ba" {
        // Order 2 on the same families (δ = 3.015 Δx), bond-level J2 and stretch damage.
        Box::new(RkBa::new(
            Dim::Three,
            2,
            horizon,
            mat,
            CriticalStretch {
                critical_stretch: 0.01,
            },
            &bonds,
        ))
    } else if model == "pd-bond" {
        Box::new(BondModel::new(
            Dim::Three,
            e,
            horizon,
            1.0,
            Some(0.01),
            &k,
            &bonds,
        ))
    } else {
        Box::new(Correspondence::new(
            Dim::Three,
            mat,
            0.5,
            horizon,
            1.0,
            CriticalStretch {
                critical_stretch: 0.01,
            },
            &k,
            &bonds,
        ))
    };
    let mut b = Body::new(Dim::Three, dx, horizon, rho, x0, vol, bonds, m);
    // A smooth, non-trivial initial velocity field so every bond does real work.
    for i in 0..b.len() {
        let x = b.x0[i];
        b.vel[i] = [
            5.0 * (x[1] * 200.0).sin(),
            -3.0 * (x[2] * 150.0).cos(),
            2.0 * (x[0] * 300.0).sin(),
        ];
    }
    b
}

fn main() {
    let threads = rayon::current_num_threads();
    let which: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a.starts_with("pd-"))
        .collect();
    for model in ["pd-bond", "pd-correspondence", "pd-rk-ba"] {
        if !which.is_empty() && !which.iter().any(|w| w == model) {
            continue;
        }
        let mut b = block(model);
        let bonds = b.bonds.len();
        let dt = 0.5 * b.stable_dt();
        b.step(dt); // warm-up
        // pd-rk-ba (bond-level J2) is ~20× slower: fewer steps, same per-step measure.
        let steps = std::env::var("PD_BENCH_STEPS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(if model == "pd-rk-ba" { 10 } else { 100 });
        let t = Instant::now();
        for _ in 0..steps {
            b.step(dt);
        }
        let s = t.elapsed().as_secs_f64();
        let rate = bonds as f64 * steps as f64 / s;
        println!(
            "{model:>18}: {} particles, {bonds} bonds, {steps} steps in {s:.3} s at {threads} thread(s): {:.1} M bond-updates/s",
            b.len(),
            rate / 1e6
        );
    }
}
