//! Seed 000 §3.2 brittle hollow cylinder, loaded by a prescribed
//! internal pressure pulse instead of the detonation gas: inner radius 7 cm, outer 10 cm,
//! E 200 GPa, ν 0.29, ρ 7870 kg/m³, brittle von Mises damage σ_cr = 3 GPa, pd-correspondence
//! in plane strain; the set-up is [`solid_node::pd::cases::HollowCylinder`], run through the
//! node's `Solver` interface with its `pressure_pulse` parameter. Writes VTK every 10 µs and
//! prints where the first bonds broke and the number of fragments (connected components over
//! unbroken bonds with at least 20 particles; smaller ones are counted as debris).
//! `cargo run --release -p solid-node --example hollow_cylinder [dx_mm] [peak_GPa] [end_us]`
use solid_node::pd::cases::HollowCylinder;

fn main() {
    let mut args = std::env::args().skip(1);
    let mut c = HollowCylinder::default();
    let num = |a: Option<String>| a.and_then(|s| s.parse::<f64>().ok());
    if let Some(dx) = num(args.next()) {
        c.dx = dx * 1e-3;
    }
    if let Some(p) = num(args.next()) {
        c.peak = p * 1e9;
    }
    let end = num(args.next()).unwrap_or(150.0) * 1e-6;
    let window = 1e-6;
    let windows = (end / window).round() as u64;
    let dir = std::env::temp_dir().join("hollow_cylinder");
    println!(
        "dx = {:.2} mm, pulse peak {:.2} GPa, rise {:.0} µs, duration {:.0} µs, {:.0} µs",
        c.dx * 1e3,
        c.peak * 1e-9,
        c.rise * 1e6,
        c.duration * 1e6,
        end * 1e6
    );
    let wall = std::time::Instant::now();
    match c.run(windows, window, 20, Some((&dir, 10))) {
        Ok((s, r)) => {
            println!(
                "{} particles, {:.1} s wall, VTK in {}",
                s.body.len(),
                wall.elapsed().as_secs_f64(),
                dir.display()
            );
            match &r.first_break {
                Some((t, radii)) => {
                    let (lo, hi) = radii
                        .iter()
                        .fold((f64::MAX, 0.0f64), |(a, b), &r| (a.min(r), b.max(r)));
                    println!(
                        "first bonds broke by t = {:.1} µs at {} particles, radii {:.1}–{:.1} mm (inner face 70 mm, outer 100 mm)",
                        t * 1e6,
                        radii.len(),
                        lo * 1e3,
                        hi * 1e3
                    );
                }
                None => println!("no bond broke"),
            }
            println!(
                "fragments (≥ 20 particles): {}; sizes {:?}; debris particles {}",
                r.fragments.len(),
                r.fragments,
                r.debris
            );
        }
        Err(e) => eprintln!("run failed: {e}"),
    }
}
