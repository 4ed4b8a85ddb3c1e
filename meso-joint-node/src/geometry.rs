//! Particle sets: a cubic lattice filling a box, and the bolted joint of seed 004 §4.2 (two
//! 1 mm plates overlapping around a rigid bolt, plate material as SPG particles).

/// Particle positions, volumes and part ids; `rigid_parts` lists the parts that move rigidly.
#[derive(Debug, Clone, Default)]
pub struct ParticleSet {
    pub x: Vec<[f64; 3]>,
    pub vol: Vec<f64>,
    pub part: Vec<u32>,
    pub rigid_parts: Vec<u32>,
}

/// Cell-centred cubic lattice of spacing `h` in `[origin, origin + size]`
/// (`round(size/h)` particles per direction, at least one).
pub fn block(origin: [f64; 3], size: [f64; 3], h: f64) -> ParticleSet {
    let n: [usize; 3] = std::array::from_fn(|d| ((size[d] / h).round() as usize).max(1));
    let hh: [f64; 3] = std::array::from_fn(|d| size[d] / n[d] as f64);
    let mut s = ParticleSet::default();
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                s.x.push([
                    origin[0] + (i as f64 + 0.5) * hh[0],
                    origin[1] + (j as f64 + 0.5) * hh[1],
                    origin[2] + (k as f64 + 0.5) * hh[2],
                ]);
                s.vol.push(hh[0] * hh[1] * hh[2]);
                s.part.push(0);
            }
        }
    }
    s
}

/// Seed 004 §4.2 joint: plate 0 spans x ∈ [0, length], z ∈ [0, t]; plate 1 spans
/// x ∈ [length − overlap, 2 length − overlap], z ∈ [t, 2t]; both y ∈ [−width/2, width/2].
/// The bolt (part 2, rigid) is a cylinder of `bolt_radius` through both plates at the centre
/// of the overlap, with heads of `head_radius` and `head_height` above and below. Plate
/// particles inside the shank are removed.
#[allow(clippy::too_many_arguments)]
pub fn bolted_plates(
    thickness: f64,
    width: f64,
    length: f64,
    overlap: f64,
    bolt_radius: f64,
    head_radius: f64,
    head_height: f64,
    h: f64,
) -> ParticleSet {
    let xc = length - 0.5 * overlap;
    let in_shank = |p: &[f64; 3]| (p[0] - xc).powi(2) + p[1].powi(2) < bolt_radius * bolt_radius;
    let mut s = ParticleSet {
        rigid_parts: vec![2],
        ..Default::default()
    };
    for (part, x0, z0) in [(0u32, 0.0, 0.0), (1u32, length - overlap, thickness)] {
        let b = block([x0, -0.5 * width, z0], [length, width, thickness], h);
        for (p, v) in b.x.iter().zip(&b.vol) {
            if !in_shank(p) {
                s.x.push(*p);
                s.vol.push(*v);
                s.part.push(part);
            }
        }
    }
    // Bolt: shank through both plates plus heads; particles on the same lattice spacing.
    let z_lo = -head_height;
    let z_hi = 2.0 * thickness + head_height;
    let nz = ((z_hi - z_lo) / h).round().max(1.0) as usize;
    let hz = (z_hi - z_lo) / nz as f64;
    let nr = (head_radius / h).ceil() as i64;
    for k in 0..nz {
        let z = z_lo + (k as f64 + 0.5) * hz;
        let r = if (0.0..=2.0 * thickness).contains(&z) {
            bolt_radius
        } else {
            head_radius
        };
        for j in -nr..=nr {
            for i in -nr..=nr {
                let dx = (i as f64) * h;
                let dy = (j as f64) * h;
                if dx * dx + dy * dy < r * r {
                    s.x.push([xc + dx, dy, z]);
                    s.vol.push(h * h * hz);
                    s.part.push(2);
                }
            }
        }
    }
    s
}

/// The benchmark block: `n³` particles of 1 mm steel (J2 with kinematic hardening,
/// support 2 h, consistent smoothing, re-anchoring every 100 steps), pulled apart at 1 m/s by
/// its top and bottom two layers, initial forces computed. Shared by the crate's benchmark
/// and `cosim bench`.
pub fn benchmark_block(n: usize) -> Result<crate::model::Model, String> {
    use crate::config::Smoothing;
    use crate::model::{Model, ModelParams};
    let h = 1e-3;
    let s = block([0.0; 3], [n as f64 * h; 3], h);
    let p = ModelParams {
        material: mechanics::j2::J2Material {
            young: 210e9,
            poisson: 0.3,
            yield_stress: 0.2e9,
            iso_hardening: 0.0,
            kin_hardening: 22e9,
        },
        density: 7850.0,
        spacing: h,
        support: 2.0 * h,
        eps_crit: 0.1,
        e_crit: 1.0,
        // The default rate: one re-anchoring per 100 steps (amortised in a long run).
        reanchor_every: 100,
        smoothing: Smoothing::Consistent,
        cfl: 0.4,
        bearing: None,
    };
    let mut m = Model::new(p, s.x, s.vol, s.part, &s.rigid_parts)?;
    let top = n as f64 * h;
    m.add_velocity_bc("bottom", [0.0, 0.0, -1.0], 0.0, |x| x[2] < 2.0 * h);
    m.add_velocity_bc("top", [0.0, 0.0, 1.0], 0.0, |x| x[2] > top - 2.0 * h);
    m.initial_forces();
    Ok(m)
}
