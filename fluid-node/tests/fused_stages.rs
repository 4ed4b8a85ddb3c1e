//! The fused RK stages (fluxes and update per block of rows, no flux array in memory) give
//! the unfused stages' results bit for bit: every conserved variable of
//! every cell, the boundary impulse and work, and, with an immersed body, the forces on the
//! particles and the node's report, after every window — on 2-D and 3-D grids, one and two
//! materials, every limiter, on 1 and 2 threads; and a step that breaks the state fails with
//! the same error either way.

use crate::common;
use common::{particle_block, solver, walled_blast_case};
use fluid_node::EulerSolver;
use protocol::{Field, Inbox, Outbox, Solver, Window, message::is_timing_scalar};

/// Bits of everything a step sequence produces that the next window depends on.
fn state_bits(s: &EulerSolver) -> Vec<u64> {
    let f = &s.fluid;
    let mut v: Vec<u64> = f.cons.iter().map(|x| x.to_bits()).collect();
    v.extend(f.boundary_impulse.iter().map(|x| x.to_bits()));
    v.push(f.boundary_work.to_bits());
    v.push(f.time.to_bits());
    v
}

fn in_pool<T: Send>(threads: usize, run: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool")
        .install(run)
}

/// `steps` steps of the case, fused or not; the state's bits.
fn steps(text: &str, fused: bool, steps: usize, threads: usize) -> Vec<u64> {
    in_pool(threads, || {
        let mut s = solver(text);
        s.fluid.fused = fused;
        for _ in 0..steps {
            fluid_node::step::step(&mut s.fluid, f64::INFINITY).expect("step");
        }
        state_bits(&s)
    })
}

fn assert_same(a: &[u64], b: &[u64], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    let differ = a.iter().zip(b).filter(|(x, y)| x != y).count();
    assert_eq!(differ, 0, "{what}: {differ} of {} values differ", a.len());
}

/// 12 steps of each walled blast case (cells, two materials, limiter), fused and unfused,
/// on 1 and 2 threads, compared bit for bit; the number of values compared.
fn fused_equals_unfused(cases: &[([usize; 3], bool, &str)]) -> usize {
    let mut compared = 0;
    for &(cells, two, limiter) in cases {
        let text = walled_blast_case(cells, two, limiter);
        for threads in [1, 2] {
            let a = steps(&text, false, 12, threads);
            let b = steps(&text, true, 12, threads);
            assert_same(
                &a,
                &b,
                &format!("{cells:?} two {two} {limiter} {threads} threads"),
            );
            compared += a.len();
        }
    }
    compared
}

#[test]
fn three_d_fused_stage_equals_the_unfused_one() {
    // 18 y lines: two full tiles of 8 and a partial one; 13 and 20 planes: one or several
    // blocks of planes per thread
    let cases = [
        ([20, 18, 13], true, "van_leer"),
        ([14, 12, 20], false, "minmod"),
        ([12, 17, 9], false, "mc"),
        // fewer y lines than a tile, an odd row length
        ([9, 5, 11], false, "van_leer"),
    ];
    let mut compared = fused_equals_unfused(&cases);
    // periodic in x and z, inflow and outflow in y
    let text = walled_blast_case([16, 14, 12], false, "van_leer").replace(
        "x_lower = \"wall\"\n        x_upper = \"outflow\"\n        y_lower = \"symmetry\"\n        y_upper = \"wall\"\n        z_lower = \"wall\"\n        z_upper = \"outflow\"",
        "x_lower = \"periodic\"\n        x_upper = \"periodic\"\n        y_lower = { kind = \"inflow\", material = \"air\", density = 1.2, pressure = 0.3, velocity = [0.0, 0.4, 0.0] }\n        y_upper = \"outflow\"\n        z_lower = \"periodic\"\n        z_upper = \"periodic\"",
    );
    assert!(
        text.contains("periodic"),
        "the boundary replacement applies"
    );
    let a = steps(&text, false, 12, 2);
    let b = steps(&text, true, 12, 2);
    assert_same(&a, &b, "periodic / inflow 3-D");
    compared += a.len();
    println!("3-D fused = unfused: {compared} values compared bit for bit");
}

#[test]
fn two_d_fused_stage_equals_the_unfused_one() {
    let cases = [
        ([40, 36, 1], true, "van_leer"),
        ([33, 20, 1], false, "minmod"),
        ([25, 31, 1], false, "mc"),
    ];
    let compared = fused_equals_unfused(&cases);
    println!("2-D fused = unfused: {compared} values compared bit for bit");
}

/// Steps four times too long (CFL 4) break the state in a later RK stage, whose primitives
/// the fused stages recover while updating the stage before: fused and unfused stop with the
/// same error (cell, variable, stage) at the same state, in 2-D and 3-D.
#[test]
fn a_diverging_stage_fails_alike_fused_and_unfused() {
    for cells in [[30, 26, 1], [12, 11, 10]] {
        let text = walled_blast_case(cells, false, "van_leer");
        let run = |fused: bool| {
            in_pool(1, || {
                let mut s = solver(&text);
                s.fluid.fused = fused;
                s.fluid.cfl = 4.0;
                let mut err = None;
                for _ in 0..20 {
                    if let Err(e) = fluid_node::step::step(&mut s.fluid, f64::INFINITY) {
                        err = Some(e.to_string());
                        break;
                    }
                }
                (err, state_bits(&s))
            })
        };
        let (ea, sa) = run(false);
        let (eb, sb) = run(true);
        let ea = ea.unwrap_or_else(|| panic!("{cells:?}: CFL 4 ran 20 steps"));
        println!("{cells:?}: {ea}");
        assert!(
            ea.contains("RK stage 2") || ea.contains("RK stage 3"),
            "{cells:?}: fails in a later stage: {ea}"
        );
        assert_eq!(Some(ea), eb, "{cells:?}: the same error");
        assert_same(&sa, &sb, &format!("{cells:?}: state at the error"));
    }
}

/// A blast next to a block of particles that moves through the gas, fed window by window
/// through the `Solver` interface as a solid node would: per window the bits of the state,
/// the forces on the particles and the report (timings left out).
fn immersed_run(cells: [usize; 3], fused: bool, threads: usize) -> Vec<Vec<u64>> {
    let nd = if cells[2] > 1 { 3 } else { 2 };
    let mut text = walled_blast_case(cells, false, "van_leer");
    text.push_str("\n[immersed]\ninterface = \"particles\"\n");
    in_pool(threads, || {
        let mut s = solver(&text);
        s.fluid.fused = fused;
        let dx = s.fluid.grid.dx;
        // particles half a cell apart in the block [0.55, 0.75] × [0.3, 0.6] (× [0.2, 0.6])
        let sp = [0.5 * dx[0], 0.5 * dx[1], 0.5 * dx[2]];
        let (lo, hi) = ([0.55, 0.3, 0.2], [0.75, 0.6, 0.6]);
        let x0 = particle_block(dx, nd, lo, hi);
        let n = x0.len() / 3;
        let u = [0.4, -0.3, if nd == 3 { 0.2 } else { 0.0 }];
        let vol = sp[0] * sp[1] * if nd == 3 { sp[2] } else { dx[2] };
        let field = |name: &str, c: u32, v: Vec<f64>| Field {
            name: name.into(),
            components: c,
            values: v,
        };
        let win = 0.01;
        let mut out = Outbox::new();
        let mut per_window = Vec::new();
        for k in 1..=12u64 {
            let t0 = (k - 1) as f64 * win;
            let pos: Vec<f64> = x0
                .iter()
                .enumerate()
                .map(|(i, x)| x + u[i % 3] * t0)
                .collect();
            let vel: Vec<f64> = (0..3 * n).map(|i| u[i % 3]).collect();
            let mut inbox = Inbox::new();
            inbox.insert("particles", field("position", 3, pos));
            inbox.insert("particles", field("velocity", 3, vel));
            inbox.insert("particles", field("volume", 1, vec![vol; n]));
            let w = Window {
                index: k,
                t0,
                t1: k as f64 * win,
                write_output: false,
            };
            let rep = s.advance(&w, &inbox, &mut out).expect("window");
            let mut bits = state_bits(&s);
            let forces = &out.get("particles", "force").expect("forces sent").values;
            assert_eq!(forces.len(), 3 * n);
            bits.extend(forces.iter().map(|x| x.to_bits()));
            for x in rep.momentum.iter().chain(&rep.interface_impulse) {
                bits.push(x.to_bits());
            }
            bits.extend(
                [rep.kinetic_energy, rep.internal_energy, rep.interface_work].map(f64::to_bits),
            );
            for (name, x) in &rep.scalars {
                if !is_timing_scalar(name) {
                    bits.push(x.to_bits());
                }
            }
            per_window.push(bits);
        }
        let im = s.immersed().expect("immersed");
        assert!(
            !im.walls.is_empty(),
            "the body has wall faces, so the wall fluxes are exercised"
        );
        per_window
    })
}

#[test]
fn immersed_fused_stage_equals_the_unfused_one() {
    let mut compared = 0;
    for (cells, threads) in [
        ([40, 36, 1], 1),
        ([40, 36, 1], 2),
        ([18, 17, 14], 1),
        ([18, 17, 14], 2),
    ] {
        let a = immersed_run(cells, false, threads);
        let b = immersed_run(cells, true, threads);
        assert_eq!(a.len(), 12, "windows run");
        assert_eq!(a.len(), b.len());
        for (w, (x, y)) in a.iter().zip(&b).enumerate() {
            assert_same(
                x,
                y,
                &format!("{cells:?} {threads} threads, window {}", w + 1),
            );
            compared += x.len();
        }
    }
    println!("immersed fused = unfused: {compared} values compared bit for bit over 48 windows");
}
