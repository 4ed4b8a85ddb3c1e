//! Immersed coupling in-process (seed 002 §3 eq. 31–35): a heavy rigid wall of
//! particles at rest, fed window by window through the `Solver` interface as a solid node
//! would, reflects an incident Ms 1.5 shock with p5/p1 within 5 % of the rigid-wall value
//! 5.4253, and every window the momentum the gas loses equals the impulse the particles
//! receive (Σ force · window) plus the impulse of the domain boundaries, to round-off.

use crate::common;
use common::solver;
use fluid_node::diagnostics::x_line;
use fluid_node::immersed::{INTERFACE, SOLID};
use protocol::{Field, Inbox, Outbox, Solver, Window};

const G: f64 = 1.4;

#[test]
fn particle_wall_reflects_shock_and_conserves_momentum() {
    let ms: f64 = 1.5;
    let w = ms * G.sqrt();
    let r2 = (G + 1.0) * ms * ms / ((G - 1.0) * ms * ms + 2.0);
    let p2 = 1.0 + 2.0 * G / (G + 1.0) * (ms * ms - 1.0);
    let u2 = w * (1.0 - 1.0 / r2);
    let p52 = ((3.0 * G - 1.0) * p2 - (G - 1.0)) / ((G - 1.0) * p2 + (G + 1.0));
    let r52 = (1.0 + (G + 1.0) / (G - 1.0) * p52) / ((G + 1.0) / (G - 1.0) + p52);
    let wr = r2 * u2 / (r52 * r2 - r2);
    let (nx, ny) = (240, 4);
    let h = 1.2 / nx as f64;
    let mut s = solver(&format!(
        r#"
        cfl = 0.5
        [grid]
        cells = [{nx}, {ny}, 1]
        lower = [0.0, 0.0, 0.0]
        upper = [1.2, {ly}, 1.0]
        [materials.air]
        eos = "ideal"
        gamma = 1.4
        [[regions]]
        shape = "all"
        material = "air"
        density = 1.0
        pressure = 1.0
        [[regions]]
        shape = "half_space"
        point = [0.5, 0.0, 0.0]
        normal = [-1.0, 0.0, 0.0]
        material = "air"
        density = {r2}
        pressure = {p2}
        velocity = [{u2}, 0.0, 0.0]
        [boundaries]
        x_lower = {{ kind = "inflow", material = "air", density = {r2}, pressure = {p2}, velocity = [{u2}, 0.0, 0.0] }}
        x_upper = "wall"
        y_lower = "wall"
        y_upper = "wall"
        [immersed]
        interface = "particles"
    "#,
        ly = ny as f64 * h
    ));
    // particle wall: x in [1.0, 1.1], two particles per cell and direction, at rest
    let mut pos = Vec::new();
    let sp = 0.5 * h;
    let (npx, npy) = ((0.1 / sp).round() as usize, 2 * ny);
    for a in 0..npx {
        for b in 0..npy {
            pos.extend_from_slice(&[1.0 + (a as f64 + 0.5) * sp, (b as f64 + 0.5) * sp, 0.5]);
        }
    }
    let n = pos.len() / 3;
    let mut inbox = Inbox::new();
    let f = |name: &str, c: u32, v: Vec<f64>| Field {
        name: name.into(),
        components: c,
        values: v,
    };
    inbox.insert("particles", f("position", 3, pos));
    inbox.insert("particles", f("velocity", 3, vec![0.0; 3 * n]));
    inbox.insert("particles", f("volume", 1, vec![sp * sp; n]));
    let mut out = Outbox::new();
    let win = 0.01;
    let t_end = 0.5 / w + 0.15 / wr;
    let windows = (t_end / win).ceil() as u64;
    type Snapshot = ([f64; 3], [f64; 3], [f64; 3], f64);
    let mut prev: Option<Snapshot> = None;
    let mut worst = 0.0_f64;
    // impulse of the ambient pressure on the wall's cross-section over one window
    let pscale = 1.0 * (ny as f64 * h) * win;
    for k in 1..=windows {
        let wdw = Window {
            index: k,
            t0: (k - 1) as f64 * win,
            t1: k as f64 * win,
            write_output: false,
        };
        let rep = s.advance(&wdw, &inbox, &mut out).expect("window");
        let forces = out
            .require("particles", "force", 3 * n)
            .expect("force output");
        let impulse_x: f64 = forces.iter().step_by(3).sum::<f64>() * win;
        let im = s.immersed().expect("immersed");
        let reclass = im.reclass_momentum[0];
        if k == 1 {
            let ni = im.cell_kind.iter().filter(|&&c| c == INTERFACE).count();
            let ns = im.cell_kind.iter().filter(|&&c| c == SOLID).count();
            assert_eq!(ni, 2 * ny, "two interface columns");
            assert_eq!(ns, 18 * ny, "solid interior");
        }
        if let Some((p0, b0, i0, rc0)) = prev {
            let dp = rep.momentum[0] - p0[0];
            let db = rep.external_impulse[0] - b0[0];
            let di = rep.interface_impulse[0] - i0[0];
            // the particles' impulse is what the interface took from the gas
            assert!(
                (impulse_x + di).abs() <= 1e-12 * pscale,
                "force·window {impulse_x} vs {di}"
            );
            let resid = dp - (db - impulse_x + (reclass - rc0));
            let scale = dp.abs() + db.abs() + impulse_x.abs() + pscale;
            worst = worst.max(resid.abs() / scale);
        }
        prev = Some((
            rep.momentum,
            rep.external_impulse,
            rep.interface_impulse,
            reclass,
        ));
    }
    let line = x_line(&s.fluid, 1, 0);
    let pr: Vec<f64> = line
        .iter()
        .filter(|c| c.0 > 0.88 && c.0 < 0.98)
        .map(|c| c.3)
        .collect();
    let p5 = pr.iter().sum::<f64>() / pr.len() as f64;
    println!(
        "immersed particle wall: p5/p1 = {p5:.4} (rigid wall 5.4253, error {:.2} %); worst relative momentum residual per window {worst:.3e}",
        100.0 * (p5 / 5.4253 - 1.0)
    );
    assert!((p5 / 5.4253 - 1.0).abs() < 0.05, "p5/p1 {p5}");
    assert!(worst < 1e-10, "momentum residual {worst}");
}
