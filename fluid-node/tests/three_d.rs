//! The 3-D path of the solver ("2-D and 3-D structured-grid Euler solver").
//!
//! 1. Sod along x, y and z of a 3-D grid (100 cells along the tube, 4×4 across, walls on
//!    the sides): the three runs and all 16 lines of each give the same tube profile to
//!    round-off (the kernels treat the three directions alike, the transverse fluxes of a
//!    transversely uniform state cancel), and its density L1 error against the exact Riemann
//!    solution is ≤ 1.5 % at 100 cells (the 1-D must-show is ≤ 1 % at 400 cells; at order
//!    ~0.9 that is ≈ 3.5 % at 100 cells, and the 3-D step is smaller — its CFL rate adds the
//!    transverse c/Δx — which only lowers the error).
//! 2. Spherical Sedov blast, γ 1.4, ρ0 1: energy E = α ρ0 R⁵/t² with α = 0.851072
//!    (the README's case sections; `common::sedov_alpha(3, 1.4)`) in the cells of [-h, h]³, so the shock
//!    should stand at R = 1 at t = 1.
//!    a. Full cube [-1.2, 1.2]³ at 24³ to t = 0.5: the eight octants are mirror images and
//!    the axes permutations of each other to round-off; mass, energy and (zero) momentum
//!    are conserved to round-off (the shock has not reached the outflow boundary).
//!    b. One octant [0, 1.1]³ at 28³ with symmetry planes, to t = 1: permutation symmetry to
//!    round-off, and the shock radius (outermost half-height crossing between ambient and
//!    peak density) on an axis and on the body diagonal within two cell widths (7.9 %) of
//!    1 — the resolution limit of a shock captured over 2–3 cells at 25 cells per radius.
//!    (The 3 % must-show is met by the 2-D cylindrical test at 40 cells per radius; a 3-D
//!    run at that resolution is an example-sized job. Measured at 32³ on [0, 1.2]³:
//!    +5.4 % on the axis, +3.9 % on the diagonal; 40³ full cube: +9.9 %, +3.9 %.)

use crate::common;
use common::{ExactRiemann, sedov_alpha, solver};
use fluid_node::diagnostics::{cell_prim, totals};

fn sod_case(cells: [usize; 3], axis: usize) -> String {
    let mut hi_box = [1.0, 1.0, 1.0];
    hi_box[axis] = 0.5;
    let names = ["x", "y", "z"];
    let mut bcs = String::new();
    for (d, nm) in names.iter().enumerate() {
        let kind = if d == axis { "outflow" } else { "wall" };
        bcs.push_str(&format!(
            "{nm}_lower = \"{kind}\"\n{nm}_upper = \"{kind}\"\n"
        ));
    }
    format!(
        r#"
        cfl = 0.5
        [grid]
        cells = [{}, {}, {}]
        lower = [0.0, 0.0, 0.0]
        upper = [1.0, 1.0, 1.0]
        [materials.gas]
        eos = "ideal"
        gamma = 1.4
        [[regions]]
        shape = "all"
        material = "gas"
        density = 0.125
        pressure = 0.1
        [[regions]]
        shape = "box"
        lower = [0.0, 0.0, 0.0]
        upper = [{}, {}, {}]
        material = "gas"
        density = 1.0
        pressure = 1.0
        [boundaries]
        {bcs}
    "#,
        cells[0], cells[1], cells[2], hi_box[0], hi_box[1], hi_box[2]
    )
}

/// (ρ, u_axis, p) along the tube through transverse cell (a, b), for every transverse cell.
fn tube_profiles(n: usize, m: usize, axis: usize) -> Vec<Vec<[f64; 3]>> {
    let mut cells = [m; 3];
    cells[axis] = n;
    let mut s = solver(&sod_case(cells, axis));
    s.advance_to(0.2).expect("run");
    let f = &s.fluid;
    let g = &f.grid;
    let mut out = Vec::new();
    for a in 0..m {
        for b in 0..m {
            let mut line = Vec::new();
            for t in 0..n {
                let mut idx = [a, b, 0];
                // place the tube index on `axis` and the two transverse indices elsewhere
                let tr: Vec<usize> = (0..3).filter(|&d| d != axis).collect();
                idx[axis] = t;
                idx[tr[0]] = a;
                idx[tr[1]] = b;
                let r = g.row(idx[1] + g.g[1], idx[2] + g.g[2]);
                let (rho, v, p, _) = cell_prim(f, r, idx[0] + g.g[0]);
                line.push([rho, v[axis], p]);
            }
            out.push(line);
        }
    }
    out
}

#[test]
fn sod_along_each_axis_of_a_3d_grid() {
    let (n, m) = (100, 4);
    let px = tube_profiles(n, m, 0);
    let py = tube_profiles(n, m, 1);
    let pz = tube_profiles(n, m, 2);
    // every line of every run against line 0 of the run along x
    let reference = px[0].clone();
    let mut worst = 0.0_f64;
    for prof in [&px, &py, &pz] {
        for line in prof.iter() {
            for (c, r) in line.iter().zip(&reference) {
                for q in 0..3 {
                    let scale = r[q].abs().max(1.0);
                    worst = worst.max((c[q] - r[q]).abs() / scale);
                }
            }
        }
    }
    // density L1 error of the tube against the exact solution (cell averages)
    let ex = ExactRiemann::new(1.4, (1.0, 0.0, 1.0), (0.125, 0.0, 0.1));
    let dx = 1.0 / n as f64;
    let (mut err, mut norm) = (0.0, 0.0);
    for (t, c) in reference.iter().enumerate() {
        let x = (t as f64 + 0.5) * dx;
        let mut r_ex = 0.0;
        for q in 0..16 {
            let xq = x + ((q as f64 + 0.5) / 16.0 - 0.5) * dx;
            r_ex += ex.sample((xq - 0.5) / 0.2).0 / 16.0;
        }
        err += (c[0] - r_ex).abs() * dx;
        norm += r_ex * dx;
    }
    let l1 = err / norm;
    println!(
        "3-D Sod {n}x{m}x{m} along x, y, z: largest difference between axes and lines {worst:.3e}; density L1 error {l1:.4e}"
    );
    assert!(worst < 1e-13, "axes differ: {worst}");
    assert!(l1 < 0.015, "L1 {l1}");
}

/// Spherical Sedov set-up on the cube [lo, hi]³ with n³ cells: ambient ρ 1, p 1e-6, and the
/// energy α (R = 1 at t = 1) of the full sphere put into the cells of [-h, h]³ inside the
/// domain (8 cells on a full cube, the corner cell of an octant).
fn sedov_case(n: usize, lo: f64, hi: f64, octant: bool) -> String {
    let h = (hi - lo) / n as f64;
    let alpha = sedov_alpha(3, 1.4);
    let p_in = 0.4 * alpha / (8.0 * h * h * h);
    let lower_bc = if octant { "symmetry" } else { "outflow" };
    format!(
        r#"
        cfl = 0.5
        [grid]
        cells = [{n}, {n}, {n}]
        lower = [{lo}, {lo}, {lo}]
        upper = [{hi}, {hi}, {hi}]
        [materials.gas]
        eos = "ideal"
        gamma = 1.4
        [[regions]]
        shape = "all"
        material = "gas"
        density = 1.0
        pressure = 1.0e-6
        [[regions]]
        shape = "box"
        lower = [{m}, {m}, {m}]
        upper = [{h}, {h}, {h}]
        material = "gas"
        density = 1.0
        pressure = {p_in}
        [boundaries]
        x_lower = "{lower_bc}"
        x_upper = "outflow"
        y_lower = "{lower_bc}"
        y_upper = "outflow"
        z_lower = "{lower_bc}"
        z_upper = "outflow"
    "#,
        m = -h
    )
}

/// A map of cell indices (i, j, k) of an n³ grid onto their mirror or permuted image.
type IndexMap = fn(usize, [usize; 3]) -> [usize; 3];

/// Largest relative density difference between each cell of the n³ grid and its images under
/// the given index maps.
fn asymmetry(s: &fluid_node::EulerSolver, maps: &[IndexMap]) -> f64 {
    let f = &s.fluid;
    let g = &f.grid;
    let n = g.n[0];
    let rho = |c: [usize; 3]| cell_prim(f, g.row(c[1] + g.g[1], c[2] + g.g[2]), c[0] + g.g[0]).0;
    let mut asym = 0.0_f64;
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r = rho([i, j, k]);
                for m in maps {
                    asym = asym.max((r - rho(m(n, [i, j, k]))).abs() / r);
                }
            }
        }
    }
    asym
}

fn permutations() -> Vec<IndexMap> {
    vec![|_, [i, j, k]| [j, i, k], |_, [i, j, k]| [k, j, i], |_,
                                                              [
        i,
        j,
        k,
    ]| {
        [i, k, j]
    }]
}

#[test]
fn spherical_blast_full_cube_octant_symmetry_and_conservation() {
    // 24³ on [-1.2, 1.2]³ to t = 0.5 (R = 0.5^0.4 = 0.76: the shock stays off the boundary)
    let mut s = solver(&sedov_case(24, -1.2, 1.2, false));
    let t0 = totals(&mut s.fluid).expect("totals");
    s.advance_to(0.5).expect("run");
    let t1 = totals(&mut s.fluid).expect("totals");
    let mut maps = permutations();
    maps.push(|n, [i, j, k]| [n - 1 - i, j, k]);
    maps.push(|n, [i, j, k]| [i, n - 1 - j, k]);
    maps.push(|n, [i, j, k]| [i, j, n - 1 - k]);
    let asym = asymmetry(&s, &maps);
    let (e0, e1) = (t0.kinetic + t0.internal, t1.kinetic + t1.internal);
    let dm = (t1.mass - t0.mass).abs() / t0.mass;
    let de = (e1 - e0).abs() / e0;
    let mom = t1.momentum.iter().map(|m| m.abs()).fold(0.0, f64::max);
    println!(
        "spherical blast 24^3, t 0.5: octant/permutation asymmetry {asym:.3e}; mass drift {dm:.3e}, energy drift {de:.3e}, |momentum| {mom:.3e}"
    );
    assert!(asym < 1e-12, "asymmetry {asym}");
    assert!(dm < 1e-13, "mass drift {dm}");
    assert!(de < 1e-13, "energy drift {de}");
    // momentum: zero by symmetry; round-off relative to the mass times a typical speed
    assert!(mom < 1e-12 * t1.mass, "net momentum {mom}");
}

#[test]
fn spherical_sedov_octant_radius() {
    // one octant [0, 1.1]³ at 28³ (h = 0.039, 25 cells across the radius), symmetry planes
    // at the lower faces
    let n = 28;
    let h = 1.1 / n as f64;
    let mut s = solver(&sedov_case(n, 0.0, 1.1, true));
    s.advance_to(1.0).expect("run");
    let asym = asymmetry(&s, &permutations());
    let f = &s.fluid;
    let g = &f.grid;
    let rho =
        |i: usize, j: usize, k: usize| cell_prim(f, g.row(j + g.g[1], k + g.g[2]), i + g.g[0]).0;
    // shock radius: outermost crossing of (1 + ρ_peak)/2 along a ray
    let radius = |pts: Vec<(f64, f64)>| -> f64 {
        let peak = pts.iter().map(|p| p.1).fold(0.0, f64::max);
        let half = 0.5 * (1.0 + peak);
        let mut r = 0.0;
        for w in pts.windows(2) {
            if w[0].1 >= half && w[1].1 < half {
                r = w[0].0 + (half - w[0].1) / (w[1].1 - w[0].1) * (w[1].0 - w[0].0);
            }
        }
        r
    };
    let x = |i: usize| (i as f64 + 0.5) * h;
    let axis: Vec<(f64, f64)> = (0..n)
        .map(|i| ((x(i).powi(2) + 2.0 * x(0).powi(2)).sqrt(), rho(i, 0, 0)))
        .collect();
    let diag: Vec<(f64, f64)> = (0..n).map(|i| (x(i) * 3f64.sqrt(), rho(i, i, i))).collect();
    let (ra, rd) = (radius(axis), radius(diag));
    println!(
        "Sedov spherical, octant {n}^3: shock radius axis {ra:.4}, body diagonal {rd:.4} (exact 1.0); permutation asymmetry {asym:.3e}"
    );
    assert!(asym < 1e-12, "asymmetry {asym}");
    // the captured shock is spread over 2–3 cells: locate it within two cell widths
    let tol = 2.0 * h;
    assert!((ra - 1.0).abs() < tol, "axis radius {ra}, tolerance {tol}");
    assert!(
        (rd - 1.0).abs() < tol,
        "diagonal radius {rd}, tolerance {tol}"
    );
}
