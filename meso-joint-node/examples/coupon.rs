//! Seed 004 §4.1 single-scale coupon (all SPG): 24×8×4 mm, E 210 GPa, σy 1 GPa, E_t 1 GPa,
//! ρ 7.85e-3 g/mm³ (7850 kg/m³), 20 mm/s at both ends, ε_crit 0.5, mass scaling to the
//! seed's meso step 8.5e-6 s. Prints the force–elongation curve, the added mass and the
//! kinetic/internal energy ratio; writes VTK and the force CSV under `out/coupon`.
//! `cargo run --release -p meso-joint-node --example coupon -- [end_time_s]`

use protocol::{FieldSet, Window};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let end: f64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.05);
    let params: toml::Table = toml::from_str(
        r#"
        spacing = 0.5e-3
        kernel_support = 1.0e-3
        density = 7850.0
        young = 210e9
        poisson = 0.3
        yield_stress = 1e9
        tangent_modulus = 1e9
        eps_crit = 0.5
        mass_scaling_dt = 8.5e-6
        velocity_bc = [
          { name = "left", velocity = [-0.02, 0.0, 0.0], region = { lo = [-1.0, -1.0, -1.0], hi = [1.0e-3, 1.0, 1.0] } },
          { name = "right", velocity = [0.02, 0.0, 0.0], region = { lo = [23.0e-3, -1.0, -1.0], hi = [1.0, 1.0, 1.0] } },
        ]
        [geometry]
        kind = "block"
        origin = [0.0, 0.0, 0.0]
        size = [24e-3, 8e-3, 4e-3]
        "#,
    )?;
    let mut s = meso_joint_node::factory("mc-spg", &params)?;
    let window = 1.0e-4;
    let windows = (end / window).ceil() as u64;
    let out_dir = std::path::Path::new("out/coupon");
    println!("# time_s elongation_m force_right_N kinetic/internal substeps added_mass_kg");
    let (mut inbox, mut outbox) = (FieldSet::new(), FieldSet::new());
    inbox.clear();
    for k in 1..=windows {
        let w = Window {
            index: k,
            t0: (k - 1) as f64 * window,
            t1: k as f64 * window,
            write_output: k % 50 == 0,
        };
        let r = s.advance(&w, &inbox, &mut outbox)?;
        let get = |n: &str| {
            r.scalars
                .iter()
                .find(|(m, _)| m == n)
                .map(|(_, v)| *v)
                .unwrap_or(0.0)
        };
        if k % 10 == 0 {
            println!(
                "{:.4e} {:.4e} {:.4e} {:.3e} {} {:.3e}",
                w.t1,
                2.0 * 0.02 * w.t1,
                get("force_right_x"),
                get("kinetic_over_internal"),
                r.substeps,
                get("added_mass")
            );
        }
        if w.write_output {
            s.write_output(w.t1, k, out_dir)?;
        }
    }
    s.write_output(windows as f64 * window, windows, out_dir)?;
    Ok(())
}
