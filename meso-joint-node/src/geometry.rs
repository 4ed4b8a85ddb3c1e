//! Particle sets: a cubic lattice filling a box, and the bolted joint of seed 004 §4.2 (two
//! 1 mm plates overlapping around a rigid bolt, plate material as SPG particles).

/// Particle positions, volumes and part ids; `rigid_parts` lists the parts that move rigidly.
/// Each particle sits at the centre of its lattice cell, of edge lengths `cell`.
#[derive(Debug, Clone, Default)]
pub struct ParticleSet {
    pub x: Vec<[f64; 3]>,
    pub vol: Vec<f64>,
    pub part: Vec<u32>,
    pub cell: Vec<[f64; 3]>,
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
                s.cell.push(hh);
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
        for ((p, v), c) in b.x.iter().zip(&b.vol).zip(&b.cell) {
            if !in_shank(p) {
                s.x.push(*p);
                s.vol.push(*v);
                s.part.push(part);
                s.cell.push(*c);
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
                    s.cell.push([h, h, hz]);
                }
            }
        }
    }
    s
}

/// A particle set split into SPG particles and hexahedra (`split_solid`).
#[derive(Debug, Clone, Default)]
pub struct SolidSplit {
    /// The particles: the corners of the core cells (with their share of those cells'
    /// volume) and the rigid parts' particles as they were.
    pub particles: ParticleSet,
    /// Each particle's weight in its neighbours' shape functions: a whole cell's volume
    /// (the largest core cell it touches), also on the core's boundary.
    pub kernel_vol: Vec<f64>,
    /// Positions and parts of the elements' nodes; `node_particle[k]` is the particle node
    /// k is (on the core's boundary), or `u32::MAX` for a node of elements only.
    pub nodes: Vec<[f64; 3]>,
    pub node_part: Vec<u32>,
    pub node_particle: Vec<u32>,
    /// Hexahedra on `nodes` (corner order of `mechanics::hex8::CORNERS`) and their parts.
    pub elements: Vec<[u32; 8]>,
    pub element_part: Vec<u32>,
}

/// Splits a lattice particle set: the cells of non-rigid parts whose centre `in_core` keeps
/// stay SPG material, every other such cell becomes a hexahedron. Both live on the cells'
/// corners, so the particles of the core move to the corners too: a corner node touching a
/// core cell is a particle, with an eighth of each core cell it touches as its volume; a
/// node touching only element cells belongs to the elements alone. Corners are merged
/// within a part, never across parts (the plates of a joint stay separate bodies).
pub fn split_solid(s: &ParticleSet, in_core: impl Fn(&[f64; 3]) -> bool) -> SolidSplit {
    use std::collections::HashMap;
    // corners keyed by part and position on a grid far finer than any cell
    let tol = 1e-9;
    let key = |part: u32, x: &[f64; 3]| (part, x.map(|c| (c / tol).round() as i64));
    let mut corner_id: HashMap<(u32, [i64; 3]), u32> = HashMap::new();
    let mut corners: Vec<([f64; 3], u32)> = Vec::new();
    let mut core_vol: Vec<f64> = Vec::new();
    let mut cell_vol: Vec<f64> = Vec::new();
    let mut in_element: Vec<bool> = Vec::new();
    let mut cells: Vec<([u32; 8], u32, bool)> = Vec::new();
    for i in 0..s.x.len() {
        if s.rigid_parts.contains(&s.part[i]) {
            continue;
        }
        let core = in_core(&s.x[i]);
        let ids: [u32; 8] = std::array::from_fn(|c| {
            let r = mechanics::hex8::CORNERS[c];
            let x: [f64; 3] = std::array::from_fn(|d| s.x[i][d] + 0.5 * r[d] * s.cell[i][d]);
            *corner_id.entry(key(s.part[i], &x)).or_insert_with(|| {
                corners.push((x, s.part[i]));
                core_vol.push(0.0);
                cell_vol.push(0.0);
                in_element.push(false);
                (corners.len() - 1) as u32
            })
        });
        for &k in &ids {
            if core {
                core_vol[k as usize] += 0.125 * s.vol[i];
                cell_vol[k as usize] = cell_vol[k as usize].max(s.vol[i]);
            } else {
                in_element[k as usize] = true;
            }
        }
        cells.push((ids, s.part[i], core));
    }
    let mut out = SolidSplit::default();
    // particles: core corners, then the rigid particles
    let mut particle_of = vec![u32::MAX; corners.len()];
    for (k, (x, part)) in corners.iter().enumerate() {
        if core_vol[k] > 0.0 {
            particle_of[k] = out.particles.x.len() as u32;
            out.particles.x.push(*x);
            out.particles.vol.push(core_vol[k]);
            out.particles.part.push(*part);
            out.particles.cell.push([0.0; 3]);
            out.kernel_vol.push(cell_vol[k]);
        }
    }
    for i in 0..s.x.len() {
        if s.rigid_parts.contains(&s.part[i]) {
            out.particles.x.push(s.x[i]);
            out.particles.vol.push(s.vol[i]);
            out.particles.part.push(s.part[i]);
            out.particles.cell.push(s.cell[i]);
            out.kernel_vol.push(s.vol[i]);
        }
    }
    out.particles.rigid_parts = s.rigid_parts.clone();
    // element nodes: every corner of an element cell
    let mut node_of = vec![u32::MAX; corners.len()];
    for (k, (x, part)) in corners.iter().enumerate() {
        if in_element[k] {
            node_of[k] = out.nodes.len() as u32;
            out.nodes.push(*x);
            out.node_part.push(*part);
            out.node_particle.push(particle_of[k]);
        }
    }
    for (ids, part, core) in cells {
        if !core {
            out.elements.push(ids.map(|k| node_of[k as usize]));
            out.element_part.push(part);
        }
    }
    out
}

/// The benchmark blocks' model parameters at spacing `h`.
fn benchmark_params(h: f64) -> crate::model::ModelParams {
    use crate::config::Smoothing;
    use crate::model::ModelParams;
    ModelParams {
        blast: None,
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
    }
}

/// The benchmark block: `n³` particles of 1 mm steel (J2 with kinematic hardening,
/// support 2 h, consistent smoothing, re-anchoring every 100 steps), pulled apart at 1 m/s by
/// its top and bottom two layers, initial forces computed. Shared by the crate's benchmark
/// and `cosim bench`.
pub fn benchmark_block(n: usize) -> Result<crate::model::Model, String> {
    use crate::model::Model;
    let h = 1e-3;
    let s = block([0.0; 3], [n as f64 * h; 3], h);
    let p = benchmark_params(h);
    let mut m = Model::new(p, s.x, s.vol, s.part, &s.rigid_parts)?;
    let top = n as f64 * h;
    m.add_velocity_bc("bottom", [0.0, 0.0, -1.0], 0.0, |x| x[2] < 2.0 * h);
    m.add_velocity_bc("top", [0.0, 0.0, 1.0], 0.0, |x| x[2] > top - 2.0 * h);
    m.initial_forces();
    Ok(m)
}

/// The benchmark block with solid elements (`solid`): the same `n³` cells, pulled the same
/// way, as hexahedra around a central SPG core of a third of the side (a 27th of the
/// cells), the core's particles on the cells' corners.
pub fn benchmark_block_solid(n: usize) -> Result<crate::model::Model, String> {
    use crate::model::Model;
    let h = 1e-3;
    let s = block([0.0; 3], [n as f64 * h; 3], h);
    let side = n as f64 * h;
    let (lo, hi) = (side / 3.0, 2.0 * side / 3.0);
    let split = split_solid(&s, |x| (0..3).all(|d| x[d] > lo && x[d] < hi));
    let p = benchmark_params(h);
    let hp = mechanics::hex8::HexParams {
        material: p.material,
        density: p.density,
        hourglass: 1.0,
    };
    let solid = crate::solid::Solid::new(
        split.nodes,
        split.node_particle,
        split.elements,
        split.element_part,
        hp,
    )?;
    let ps = split.particles;
    let mut m = Model::with_solid(
        p,
        ps.x,
        ps.vol,
        ps.part,
        &ps.rigid_parts,
        Some(solid),
        Some(split.kernel_vol),
    )?;
    m.add_velocity_bc("bottom", [0.0, 0.0, -1.0], 0.0, |x| x[2] < 1.5 * h);
    m.add_velocity_bc("top", [0.0, 0.0, 1.0], 0.0, |x| x[2] > side - 1.5 * h);
    m.initial_forces();
    Ok(m)
}
