//! The coupled step's ghost fill: after the solid-cell fills, only the
//! rows whose x ghosts copy a cell the body changed are filled again
//! (`immersed::refill_x_ghosts`). On bodies that move into and out of reach of the x ends of
//! the domain (wall, outflow and periodic ends, 2-D and 3-D), the primitives with every ghost
//! cell equal those of refilling every row (`boundary::fill_ghosts`) bit for bit.

use crate::common;
use common::{particle_block, solver, walled_blast_case};
use fluid_node::boundary::{fill_ghosts, fill_ghosts_yz};
use fluid_node::immersed;
use fluid_node::step;

/// Counts of what the comparison saw.
#[derive(Default)]
struct Seen {
    /// Fills compared bit for bit.
    fills: usize,
    /// Fills that refilled some rows.
    with_rows: usize,
    /// Fills that refilled none.
    without_rows: usize,
    /// Fills where leaving the x ghosts as `prim_all` left them would have been wrong.
    stale: usize,
}

/// Windows of a body on the case `text`: a block starting at the lower x end moving up and a
/// block moving into the upper x end; in each window a few steps, and before each step the
/// fill of the step's first stage both ways.
fn compare(text: &str, seen: &mut Seen) {
    let mut text = text.to_string();
    text.push_str("\n[immersed]\ninterface = \"particles\"\n");
    let mut s = solver(&text);
    let f = &mut s.fluid;
    let nd = f.grid.nd;
    let dx = f.grid.dx;
    let (zlo, zhi) = (0.2, 0.6);
    let mut x0 = particle_block(dx, nd, [0.005, 0.3, zlo], [0.205, 0.6, zhi]);
    let first_right = x0.len() / 3;
    x0.extend(particle_block(dx, nd, [0.55, 0.35, zlo], [0.75, 0.55, zhi]));
    let n = x0.len() / 3;
    // the left block leaves the ends' reach after two windows, the right one reaches the
    // upper end after about seven
    let (ul, ur) = (4.0, 3.0);
    let win = 0.01;
    let vol = vec![0.25 * dx[0] * dx[1] * if nd == 3 { 0.5 * dx[2] } else { dx[2] }; n];
    for k in 0..10 {
        let t0 = k as f64 * win;
        let mut pos = Vec::with_capacity(3 * n);
        let mut vel = Vec::with_capacity(3 * n);
        for (p, x) in x0.chunks_exact(3).enumerate() {
            let u = if p < first_right { ul } else { ur };
            pos.extend_from_slice(&[x[0] + u * t0, x[1] - 0.5 * t0, x[2]]);
            vel.extend_from_slice(&[u, -0.5, 0.0]);
        }
        let mut im = f.immersed.take().expect("immersed body");
        im.set_particles(f, &pos, &vel, &vol);
        f.immersed = Some(im);
        for _ in 0..3 {
            // primitives and every row's x ghosts, as the stage's `prim_all`
            step::stable_dt(f).expect("stable dt");
            let im = f.immersed.take().expect("immersed body");
            immersed::fill_solid_prims(f, &im);
            let vel0 = f.vel0();
            let mut every_row = f.prim.clone();
            fill_ghosts(&f.grid, &mut every_row, f.nv, vel0, &f.bc);
            let mut untouched = f.prim.clone();
            fill_ghosts_yz(&f.grid, &mut untouched, f.nv, vel0, &f.bc);
            let rows = immersed::refill_x_ghosts(f, &im);
            fill_ghosts_yz(&f.grid, &mut f.prim, f.nv, vel0, &f.bc);
            let differ = f
                .prim
                .iter()
                .zip(&every_row)
                .filter(|(a, b)| a.to_bits() != b.to_bits())
                .count();
            assert_eq!(
                differ,
                0,
                "window {k}: {differ} of {} primitives differ from refilling every row",
                f.prim.len()
            );
            seen.fills += 1;
            if rows > 0 {
                seen.with_rows += 1;
            } else {
                seen.without_rows += 1;
            }
            if untouched
                .iter()
                .zip(&every_row)
                .any(|(a, b)| a.to_bits() != b.to_bits())
            {
                seen.stale += 1;
            }
            f.immersed = Some(im);
            step::step(f, f64::INFINITY).expect("step");
        }
    }
}

#[test]
fn refilling_the_rows_the_body_reaches_equals_refilling_every_row() {
    let mut seen = Seen::default();
    for cells in [[40, 36, 1], [18, 17, 14]] {
        let walled = walled_blast_case(cells, false, "van_leer");
        compare(&walled, &mut seen);
        let periodic = walled
            .replace("x_lower = \"wall\"", "x_lower = \"periodic\"")
            .replace("x_upper = \"outflow\"", "x_upper = \"periodic\"");
        assert_ne!(periodic, walled, "the x ends became periodic");
        compare(&periodic, &mut seen);
    }
    assert_eq!(seen.fills, 4 * 10 * 3, "fills compared");
    assert!(
        seen.with_rows >= 4 && seen.without_rows >= 4,
        "the body both reaches and leaves the x ends: {} fills with rows refilled, {} without",
        seen.with_rows,
        seen.without_rows
    );
    assert!(
        seen.stale >= 4,
        "the refill matters: in {} fills the x ghosts `prim_all` left were out of date",
        seen.stale
    );
    println!(
        "{} fills equal bit for bit ({} refilled some rows, {} none; {} needed the refill)",
        seen.fills, seen.with_rows, seen.without_rows, seen.stale
    );
}
