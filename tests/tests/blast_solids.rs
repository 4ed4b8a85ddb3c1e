//! Blast on fracturing solids end to end (seed 000 §3.2–3.3 and §4): the small
//! variants of `examples/brittle_cylinder.toml` (a brittle ring around a charge) and
//! `examples/ductile_square.toml` (a ductile hollow square around a charge), each a gas node
//! and a peridynamic node as real processes coupled by the immersed coupling, plus the square
//! decoupled from the gas at 75 µs (seed 000 Fig. 12). Checked: the momentum the gas gives up
//! is what the solid receives, window by window, to round-off; the published charge stays far
//! below failure (static Lamé estimate); the strong charge breaks the ring from its inner face
//! into fragments and cracks the square first at its re-entrant corners; after decoupling the
//! gas stops and the solid goes on as a free body. And the steel tube of
//! `examples/steel_tube.toml` (a JWL charge in a Johnson–Cook tube, seed 002 §5.5) at its
//! test size: fragments measured and tabled, the tube's energy under Gurney's bound. And the
//! underwater explosion near a held steel plate of `examples/underwater_plate.toml` (seed 002
//! §5.3) at its test size: the shock's arrival at point A against the seed's and the sound
//! speed's bounds, the plate pushed up, momentum to round-off.

use cosim_tests::*;
use std::path::PathBuf;
use std::sync::OnceLock;

fn run(case: &str, variant: &str, tag: &str) -> PathBuf {
    run_example(case, variant, tag)
}

fn ring() -> &'static PathBuf {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| run("brittle_cylinder.toml", "small", "ring"))
}

fn ring_published() -> &'static PathBuf {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| run("brittle_cylinder.toml", "small-published", "ringpub"))
}

fn square() -> &'static PathBuf {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| run("ductile_square.toml", "small", "square"))
}

fn square_decoupled() -> &'static PathBuf {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| run("ductile_square.toml", "small-decoupled", "squaredec"))
}

fn plate() -> &'static PathBuf {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| run("underwater_plate.toml", "small", "uwplate"))
}

fn taylor() -> &'static PathBuf {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| run("taylor_bar.toml", "small", "taylor"))
}

fn tube() -> &'static PathBuf {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| run("steel_tube.toml", "small", "tube"))
}

/// The run's momentum residual below 1e-12 and its energy residual below `energy` (both
/// relative, from `summary.json`); returns the energy residual.
fn balance_within(out: &std::path::Path, energy: f64) -> f64 {
    let s = summary(out);
    let b = &s["balance"];
    let residual = b["max_momentum_residual_relative"].as_f64().unwrap();
    assert!(residual < 1e-12, "momentum residual {residual}");
    let e = b["max_energy_residual_relative"].as_f64().unwrap();
    assert!(e.abs() < energy, "energy residual {e}");
    e
}

/// Largest value of a node scalar over the run.
fn peak(out: &std::path::Path, node: &str, key: &str) -> f64 {
    node_series(&out.join("run.mcap"), node, key)
        .iter()
        .map(|&(_, v)| v)
        .fold(f64::NEG_INFINITY, nan_max)
}

/// Last value of a node scalar.
fn last(out: &std::path::Path, node: &str, key: &str) -> f64 {
    node_series(&out.join("run.mcap"), node, key)
        .last()
        .map(|&(_, v)| v)
        .unwrap_or_else(|| panic!("{node}.{key} never reported"))
}

/// What the gas gives the particles in window w is what the solid receives in window w + 1
/// (the coupling lag), to 1e-12 of the largest net impulse; returns (worst, scale).
fn impulse_mismatch(out: &std::path::Path, solid: &str) -> (f64, f64) {
    let gas = node_vectors(&out.join("run.mcap"), "gas", "interface_impulse");
    let sol = node_vectors(&out.join("run.mcap"), solid, "interface_impulse");
    assert!(
        gas.len() >= 50 && gas.len() <= sol.len(),
        "{} {}",
        gas.len(),
        sol.len()
    );
    let scale = gas
        .iter()
        .map(|(_, j)| j[0].abs().max(j[1].abs()))
        .fold(0.0f64, nan_max);
    let mut worst: f64 = 0.0;
    for w in 0..gas.len() - 1 {
        assert_eq!(gas[w].0 + 1, sol[w + 1].0);
        for d in 0..3 {
            worst = worst.max((gas[w].1[d] + sol[w + 1].1[d]).abs());
        }
    }
    (worst, scale)
}

#[test]
fn the_ring_receives_what_the_gas_gives_every_window() {
    let out = ring();
    let (worst, scale) = impulse_mismatch(out, "ring");
    // The small ring's charge sits 1 cm off the axis: the net impulse is physical, not
    // the round-off of a symmetric load.
    assert!(scale > 1.0, "net impulse on the ring only {scale:e} N s");
    println!("ring: largest per-window mismatch {worst:e} N s of {scale:e} N s");
    assert!(worst <= 1e-12 * scale, "{worst:e} vs {scale:e}");
    let r = summary(out)["balance"]["max_momentum_residual_relative"]
        .as_f64()
        .expect("residual in summary.json");
    println!("ring: largest momentum residual {r:e} of the largest impulse");
    assert!(r <= 1e-12, "momentum residual {r:e}");
    // The charge is on the +x side of the axis: the near wall takes the stronger blast, so
    // the ring's momentum points to +x; the set-up is symmetric about y = 0.15, which the
    // fragmenting ring keeps to the round-off its breaking amplifies (measured |p_y|/p_x
    // 2.7e-3 on pd-rk-ba).
    let p = node_vectors(&out.join("run.mcap"), "ring", "momentum");
    let (_, p) = p.last().copied().expect("ring reports");
    assert!(
        p[0] > 0.0 && p[1].abs() < 1e-2 * p[0],
        "ring momentum {p:?}"
    );
}

/// The published charge sits on the ring's axis: the net impulses are round-off, so the
/// residual is judged against the gross momentum Σ m|v| of the nodes (gas and ring).
#[test]
fn a_symmetric_blast_balances_momentum_against_the_gross_scale() {
    let out = ring_published();
    let b = &summary(out)["balance"];
    let get = |k: &str| {
        b[k].as_f64()
            .unwrap_or_else(|| panic!("balance.{k} in summary.json"))
    };
    let (resid, impulse, gross, rel) = (
        get("max_momentum_residual"),
        get("impulse_scale"),
        get("momentum_scale"),
        get("max_momentum_residual_relative"),
    );
    println!(
        "symmetric blast: residual {resid:.3e} N s, largest net impulse {impulse:.3e} N s, \
         gross momentum {gross:.3e} kg m/s, relative {rel:.3e}"
    );
    // The gas's gross momentum: at least the ring's outward momentum, which is physical.
    let ring_gross = node_series(&out.join("run.mcap"), "ring", "momentum_gross")
        .iter()
        .map(|&(_, v)| v)
        .fold(0.0f64, nan_max);
    assert!(
        ring_gross > 1e-3 && gross >= ring_gross,
        "{ring_gross:e} {gross:e}"
    );
    assert!(
        rel <= 1e-12 && (rel - resid / impulse.max(gross)).abs() <= 1e-15,
        "{rel:e}"
    );
}

#[test]
fn the_published_charge_stays_far_below_failure() {
    // Lamé's thick ring (a = 7 cm, b = 10 cm) under an inner pressure p, plane strain
    // (σz = ν(σr + σθ)): at the inner face σr = −p, σθ = p(b² + a²)/(b² − a²), and the von
    // Mises stress is 3.42 p. A suddenly applied load at most doubles an elastic response,
    // and the face sees less than the charge's 6.75 MPa (the gas expands from r 3.5 cm).
    let (a, b, nu, p) = (0.07f64, 0.1f64, 0.29, 6.75e6);
    let (sr, st) = (-p, p * (b * b + a * a) / (b * b - a * a));
    let sz = nu * (sr + st);
    let vm = (0.5 * ((st - sr).powi(2) + (st - sz).powi(2) + (sz - sr).powi(2))).sqrt();
    let out = ring_published();
    let peak_vm = peak(out, "ring", "max_von_mises");
    let face = peak(out, "gas", "inner_face.pressure");
    println!(
        "published charge: peak von Mises {:.1} MPa (static Lamé with 6.75 MPa: {:.1} MPa; \
         thin-wall hoop p r / t = {:.1} MPa); peak gas pressure near the inner face {:.2} MPa; \
         σcr 3 GPa",
        peak_vm * 1e-6,
        vm * 1e-6,
        p * a / (b - a) * 1e-6,
        face * 1e-6
    );
    assert!(face < p, "face pressure {face:e}");
    assert!(
        peak_vm > 0.0 && peak_vm <= 2.0 * vm,
        "{peak_vm:e} vs {vm:e}"
    );
    assert_eq!(peak(out, "ring", "cracked_particles"), 0.0);
    assert_eq!(last(out, "ring", "fragments"), 1.0);
}

#[test]
fn the_strong_charge_breaks_the_ring_from_its_inner_face_into_fragments() {
    let out = ring();
    let dx = 5e-3;
    let damaged = last(out, "ring", "damaged_particles");
    let fragments = last(out, "ring", "fragments");
    let (r0, r1) = (
        last(out, "ring", "first_damage_radius_min"),
        last(out, "ring", "first_damage_radius_max"),
    );
    let t = last(out, "ring", "first_damage_time");
    println!(
        "ring: first damage at {:.1} µs between r = {:.1} and {:.1} mm (faces 70 / 100 mm); \
         {damaged} particles with damage ≥ 0.5, {fragments} fragments of ≥ 10 particles, \
         peak von Mises {:.2} GPa",
        t * 1e6,
        r0 * 1e3,
        r1 * 1e3,
        peak(out, "ring", "max_von_mises") * 1e-9
    );
    // The first cracks are on the inner face: the first layer (r < 70 mm + Δx) is among
    // them and none is in the outer half of the wall.
    assert!(r0 < 0.07 + dx, "first damage from r = {r0}");
    assert!(r1 < 0.085, "first damage out to r = {r1}");
    assert!(damaged > 0.0);
    assert!(fragments >= 2.0, "{fragments} fragments");
    // Irreversible: the damaged count never decreases.
    let s = node_series(&out.join("run.mcap"), "ring", "damaged_particles");
    assert!(s.windows(2).all(|w| w[1].1 >= w[0].1));
    let (ok, text) = check_mcap(&out.join("run.mcap"), "--require-json");
    assert!(ok, "check_mcap: {text}");
    let png = out.join("plots").join("ring_fragments.png");
    assert!(std::fs::metadata(&png).map(|m| m.len()).unwrap_or(0) > 1000);
}

#[test]
fn the_square_cracks_first_at_its_reentrant_corners() {
    let out = square();
    let dx = 5e-3;
    let d = last(out, "square", "first_damage_corner_distance");
    let (x, y) = (
        last(out, "square", "first_damage_x"),
        last(out, "square", "first_damage_y"),
    );
    let n = last(out, "square", "first_damage_particles");
    println!(
        "square: first damage at {:.1} µs, {n} particles, all within {:.1} mm of an inner \
         corner (most damaged at ({:.1}, {:.1}) mm from the centre; the corners are at \
         (±50, ±50) mm, the mid-sides 50 mm from them); {} damaged, {} fragments",
        last(out, "square", "first_damage_time") * 1e6,
        d * 1e3,
        (x - 0.2) * 1e3,
        (y - 0.2) * 1e3,
        last(out, "square", "damaged_particles"),
        last(out, "square", "fragments"),
    );
    // Within a horizon (3.015 Δx = 15 mm) of a corner, far from the mid-sides 50 mm away. At
    // this size (six particles across the wall) pd-rk-ba first damages the inner face next to
    // the corner (measured 12.7 mm from it); at the case's D1–D4 the first damaged particles
    // lie within 2.5–5.1 mm of the corners (the case file's header).
    assert!(
        d <= 3.015 * dx,
        "first damage {d} m from the nearest inner corner"
    );
    assert!(last(out, "square", "damaged_particles") > 0.0);
    assert!(peak(out, "square", "max_plastic_strain") >= 0.18);
    let (worst, _) = impulse_mismatch(out, "square");
    // The load is symmetric: the net impulse is round-off; compare with the momentum the
    // square's particles carry, √(2 M K) ≥ Σ m|v| (Cauchy–Schwarz).
    let mass = 7870.0 * (0.16f64 * 0.16 - 0.1 * 0.1) * 0.01;
    let k = peak(out, "square", "kinetic_energy");
    let scale = (2.0 * mass * k).sqrt();
    println!("square: largest per-window mismatch {worst:e} N s of Σ m|v| ≤ {scale:e} N s");
    assert!(worst <= 1e-12 * scale, "{worst:e} vs {scale:e}");
    let (ok, text) = check_mcap(&out.join("run.mcap"), "--require-json");
    assert!(ok, "check_mcap: {text}");
}

#[test]
fn after_decoupling_the_gas_stops_and_the_square_goes_on_alone() {
    let out = square_decoupled();
    let t_dec = 75e-6;
    let gas = node_series(&out.join("run.mcap"), "gas", "max_pressure");
    let sq = node_series(&out.join("run.mcap"), "square", "kinetic_energy");
    let t_gas = gas.last().map(|g| g.0).expect("gas reports");
    let t_sq = sq.last().map(|g| g.0).expect("square reports");
    assert!(
        (t_gas - t_dec).abs() <= 1e-9,
        "gas last reported at {t_gas}"
    );
    assert!(
        (t_sq - 1.5e-4).abs() <= 1e-9,
        "square last reported at {t_sq}"
    );
    // 75 µs is the end of window 75 of 1 µs: the coupling ends before window 76.
    let s = summary(out);
    assert_eq!(
        s["couplings"][0]["decoupled"]["before_window"].as_u64(),
        Some(76),
        "{}",
        s["couplings"]
    );
    assert_eq!(
        s["nodes"]["gas"]["finished_after_window"].as_u64(),
        Some(75)
    );
    // No force after the gas's last window has been applied: the square is a free body,
    // its momentum and received impulse constant to round-off.
    let p = node_vectors(&out.join("run.mcap"), "square", "momentum");
    let j = node_vectors(&out.join("run.mcap"), "square", "interface_impulse");
    let k_max = sq.iter().map(|s| s.1).fold(0.0, nan_max);
    let mass = 7870.0 * (0.16f64 * 0.16 - 0.1 * 0.1) * 0.01;
    let scale = (2.0 * mass * k_max).sqrt();
    let after: Vec<usize> = (0..p.len()).filter(|&w| sq[w].0 > t_dec + 2.0e-6).collect();
    assert!(after.len() > 50);
    // Everything the gas gave up before it stopped — the last window's impulse, in flight
    // across the one-window lag, included — reached the square.
    let gas_j = node_vectors(&out.join("run.mcap"), "gas", "interface_impulse");
    let (_, jg) = gas_j.last().copied().expect("gas reports");
    let (_, js) = j.last().copied().expect("square reports");
    for d in 0..3 {
        assert!((jg[d] + js[d]).abs() <= 1e-12 * scale, "{jg:?} vs {js:?}");
    }
    for w in &after[1..] {
        for d in 0..3 {
            assert!((p[*w].1[d] - p[after[0]].1[d]).abs() <= 1e-12 * scale);
            assert_eq!(j[*w].1[d], j[after[0]].1[d]);
        }
    }
    let with = last(square(), "square", "damaged_particles");
    let without = last(out, "square", "damaged_particles");
    println!(
        "damaged particles (φ ≥ 0.5) at 150 µs: coupled throughout {with}, decoupled at 75 µs \
         {without}; cracked (φ > 0): {} / {}",
        last(square(), "square", "cracked_particles"),
        last(out, "square", "cracked_particles"),
    );
    assert!(without > 0.0);
    let (ok, text) = check_mcap(&out.join("run.mcap"), "--require-json");
    assert!(ok, "check_mcap: {text}");
}

/// The steel tube of `examples/steel_tube.toml` at its test size (fluid 2 mm, tube 1 mm, to
/// 30 µs), a JWL charge in a Johnson–Cook tube. Checked: momentum to round-off; energy within
/// 5 % (the refill conserves); the gas never negative in any window; the tube in fragments
/// whose table adds up (rows, particles, masses against the lattice's, the reported means); the tube's kinetic energy below Gurney's bound
/// for a cylinder, ½M·2E/(M/C + ½) with the charge's whole detonation energy E (4.29 MJ/kg:
/// no tube gets more; with TNT's measured Gurney energy, √2E = 2.44 km/s, a tube gets 0.69
/// of it once fully driven) and above 0.4 of it (at 30 µs the products still push); and the
/// table reaches `cosim export` and `cosim plot --fragments`.
#[test]
fn the_steel_tube_breaks_into_measured_fragments_below_gurneys_bound() {
    let out = tube();
    let mcap = out.join("run.mcap");
    // the conservative refill creates and loses no gas: the balance closes within 5 % of
    // the largest energy (measured +1.1 %; with the seed's mean-state refill this variant
    // misses 13.8 %, and on the base case a refill that took freed cells' gas from their
    // neighbours missed 28 %)
    balance_within(out, 0.05);
    for key in ["min_pressure", "min_density"] {
        let v = node_series(&mcap, "gas", key);
        assert_eq!(v.len(), 150, "{key}: {} windows", v.len());
        let low = v.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
        assert!(low > 0.0, "{key} {low}");
    }
    // the fragment table of the last frame
    let table = std::fs::read_to_string(out.join("tube/fragments.csv")).unwrap();
    let mut rows = table.lines();
    let header: Vec<&str> = rows.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<f64>> = rows
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    let fragments = last(out, "tube", "fragments");
    assert_eq!(rows.len() as f64, fragments);
    assert!(fragments >= 6.0, "{fragments} fragments");
    let (h, t, rho) = (1e-3, 0.01, 7830.0);
    let particles: f64 = rows.iter().map(|r| r[col("particles")]).sum();
    let mass: f64 = rows.iter().map(|r| r[col("mass")]).sum();
    assert!((mass - particles * rho * h * h * t).abs() < 1e-12 * mass);
    let all = particles + last(out, "tube", "debris_particles");
    let lattice = std::f64::consts::PI * (0.034f64.powi(2) - 0.03f64.powi(2)) / (h * h);
    assert!(
        (all / lattice - 1.0).abs() < 0.03,
        "{all} particles, ring area {lattice}"
    );
    let mean = |c: usize| rows.iter().map(|r| r[c]).sum::<f64>() / rows.len() as f64;
    let width = last(out, "tube", "fragment_mean_width");
    let thickness = last(out, "tube", "fragment_mean_thickness");
    assert!((mean(col("width")) - width).abs() < 1e-12 * width);
    assert!((mean(col("thickness")) - thickness).abs() < 1e-12 * thickness);
    // every piece is at least a spacing thick and no wider than the tube's circumference
    for r in &rows {
        assert!(r[col("thickness")] >= h && r[col("width")] < 2.0 * std::f64::consts::PI * 0.1);
    }
    // Gurney's bound (open-faced cylinder) with the whole detonation energy
    let m_tube = all * rho * h * h * t;
    let m_charge = 1630.0 * std::f64::consts::PI * 0.03f64.powi(2) * t;
    let v_g2 = 2.0 * 4.29e6 / (m_tube / m_charge + 0.5);
    let bound = 0.5 * m_tube * v_g2;
    let ke = last(out, "tube", "kinetic_energy");
    println!(
        "steel tube (small): {fragments} fragments, mean width {:.2} mm, thickness {:.2} mm, \
         fastest {:.0} m/s; tube kinetic energy {ke:.4e} J = {:.3} of Gurney's bound \
         {bound:.4e} J (speed {:.0} m/s)",
        width * 1e3,
        thickness * 1e3,
        last(out, "tube", "fragment_max_speed"),
        ke / bound,
        v_g2.sqrt()
    );
    assert!(ke < bound && ke > 0.4 * bound, "{ke} against {bound}");
    // the table through cosim export and cosim plot
    let o = cosim(&["export", out.to_str().unwrap(), "--format", "csv"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let exported = std::fs::read_to_string(out.join("history/tube_fragments.csv")).unwrap();
    assert_eq!(exported.lines().count(), rows.len() + 1);
    let plots = out.join("hist");
    let o = cosim(&[
        "plot",
        out.to_str().unwrap(),
        "--fragments",
        "-o",
        plots.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let png = std::fs::read(plots.join("out_tube_fragments.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
}

/// The Taylor bar of `examples/taylor_bar.toml` at its test size (10 particles across): a
/// Johnson–Cook 4340 steel cylinder, 25.4 mm long, strikes a rigid anvil at 208 m/s.
/// Checked against the test (Johnson & Cook 1983): the recovered length within 3 % of its
/// 22.48 mm (measured −0.8 %); the face spread past the bar's 7.62 mm but not past the
/// test's 11.1 mm (9.13 mm measured: the case file says why it falls short). And the
/// anvil's books: the bar's momentum is the start's plus the anvil's impulse to round-off,
/// the anvil only ever pushes, the bar leaves it (no force in the last 10 windows) no faster
/// than an elastic release can throw it, and the energy closes within 1 % (measured 0.4 %).
#[test]
fn the_taylor_bar_shortens_as_the_test_did_and_the_anvil_keeps_the_books() {
    let out = taylor();
    let mcap = out.join("run.mcap");
    let energy = balance_within(out, 0.01);
    let force = node_series(&mcap, "bar", "wall_force_z");
    assert_eq!(force.len(), 40, "{} windows", force.len());
    assert!(force.iter().all(|&(_, f)| f >= 0.0), "the anvil pulled");
    assert!(force[..5].iter().all(|&(_, f)| f > 0.0), "no impact");
    assert!(
        force[30..].iter().all(|&(_, f)| f == 0.0),
        "still on the anvil"
    );
    let mass = 7830.0 * 2640.0 * 7.62e-4f64.powi(3);
    let pz = last(out, "bar", "momentum_z");
    let impulse = last(out, "bar", "external_impulse_z");
    assert!(
        (pz - (-mass * 208.0 + impulse)).abs() < 1e-12 * mass * 208.0,
        "momentum {pz} against −208 m · {mass} kg + {impulse}"
    );
    // It springs back off the anvil, no faster than an elastic release from the largest
    // stress it carried gives a bar, σ/(ρc₀): Johnson–Cook at this variant's largest plastic
    // strain (0.22) and a strain rate of 1e5/s, 1.32 GPa, over ρc₀ = 7830 · √(205e9/7830).
    let rebound = pz / mass;
    let release = 1.32e9 / (7830.0 * (205e9f64 / 7830.0).sqrt());
    assert!(
        rebound > 0.0 && rebound < release,
        "rebound {rebound} m/s, bound {release}"
    );
    let length = last(out, "bar", "extent_z");
    let diameter = last(out, "bar", "extent_radial");
    println!(
        "Taylor bar (small): length {:.2} mm (test 22.48), face {:.2} mm (test 11.1), rebound {rebound:.1} m/s, energy residual {energy:.1e}",
        length * 1e3,
        diameter * 1e3
    );
    assert!((length / 22.48e-3 - 1.0).abs() < 0.03, "length {length}");
    assert!(
        diameter > 7.62e-3 * 1.1 && diameter < 11.1e-3,
        "diameter {diameter}"
    );
}

/// Seed 002 §5.3 at the test size: a 6 GPa gas sphere of radius 0.25 m in water, a steel
/// plate 2.0 m above its centre, held at its edge. The shock crosses 1.74 m of water to point
/// A (just below the plate's wet face), no slower than the water's sound speed,
/// c0 = √(γ (p + p∞)/ρ) = √(4.4 · 6.001e8 / 1000) = 1625 m/s, and no faster than a shock
/// driven by the charge's whole 6 GPa, U = c0 √(1 + (γ + 1)/(2γ) · 6e9/6.001e8) = 4340 m/s: it
/// arrives between 0.40 and 1.07 ms (the seed: 0.6 ms; this file's `seed` variant on a GPU:
/// 0.70 ms). The reflection on the plate lifts A's pressure past 1 kbar, below the charge's
/// 6 GPa; the plate goes up; and the momentum of water and plate balances to round-off with
/// the outflow sides' and the held edge's impulse (the coupling's force on held particles and
/// the step's mean internal force on them included).
#[test]
fn the_underwater_charge_lifts_the_held_plate_with_the_seeds_arrival_time() {
    let out = plate();
    let mcap = out.join("run.mcap");
    let a = node_series(&mcap, "water", "A.pressure");
    assert!(a.len() >= 90, "{} probe values", a.len());
    // arrival: the first window in which A's pressure passes 10 bar (the water is at 1 bar)
    let arrival = a
        .iter()
        .find(|&&(_, p)| p > 1.0e6)
        .map(|&(t, _)| t)
        .expect("the shock reaches A");
    let (peak_t, peak_p) =
        a.iter().copied().fold(
            (0.0, f64::NEG_INFINITY),
            |m, (t, p)| if p > m.1 { (t, p) } else { m },
        );
    println!(
        "plate: shock at A at {:.3} ms (seed 0.6 ms), peak {:.3e} Pa at {:.3} ms (seed 0.82 GPa at 0.63 ms)",
        arrival * 1e3,
        peak_p,
        peak_t * 1e3
    );
    let c0 = (4.4_f64 * (1.0e5 + 6.0e8) / 1000.0).sqrt();
    let fastest = c0 * (1.0_f64 + 5.4 / 8.8 * 6.0e9 / 6.001e8).sqrt();
    assert!(
        arrival <= 1.74 / c0 && arrival >= 1.74 / fastest,
        "arrival {arrival:e} s, not between {:e} and {:e} s",
        1.74 / fastest,
        1.74 / c0
    );
    // the reflected wave builds on the plate: A's pressure passes 1 kbar, below the charge's
    assert!(peak_p > 1.0e8 && peak_p < 6.0e9, "peak {peak_p:e} Pa");
    // the plate goes up, held at its edge
    let uz = last(out, "plate", "centre_uz");
    let p = node_vectors(&mcap, "plate", "momentum");
    let j = node_vectors(&mcap, "plate", "external_impulse");
    let (pz, jz) = (
        p.last().expect("momentum").1[2],
        j.last().expect("impulse").1[2],
    );
    println!(
        "plate: centre lifted {uz:.3e} m, momentum {pz:.3e} N s, supports' impulse {jz:.3e} N s"
    );
    assert!(
        uz > 0.0 && pz > 0.0,
        "the plate must move up: {uz:e} m, {pz:e} N s"
    );
    let r = summary(out)["balance"]["max_momentum_residual_relative"]
        .as_f64()
        .expect("residual");
    println!("plate: largest momentum residual {r:e}");
    assert!(r <= 1e-12, "momentum residual {r:e}");
}
