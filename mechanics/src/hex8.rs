//! Eight-node hexahedra for explicit dynamics: one-point (mean-gradient) integration with
//! hourglass control, J2 plasticity with isotropic and kinematic hardening in rate form
//! (Jaumann), lumped mass, central differences driven by the caller.
//!
//! **Integration.** Each element uses the mean strain rate over its volume: with
//! `B_I = ∫_e ∇N_I dV` (the derivative of the element's volume with respect to node I's
//! position, Flanagan & Belytschko 1981) the velocity gradient is `L = (1/V) Σ_I v_I ⊗ B_I`
//! and the internal force `f_I = −σ B_I`. `B_I` and `V` are integrated exactly by 2 × 2 × 2
//! Gauss points (their integrands are of degree ≤ 3 in each reference coordinate), so a
//! linear velocity field gives its exact gradient in any element shape and the interior
//! forces of a uniform stress cancel in any mesh: the patch test holds on distorted meshes.
//!
//! **Hourglass control.** The four hourglass shapes `h_α` (ξη, ηζ, ζξ, ξηζ at the corners)
//! are projected against the linear fields of the current geometry, `γ_αI = h_αI − (1/V)
//! Σ_k (h_α · x_k) B_Ik`, so `q̇_α = Σ_I γ_αI v_I` is blind to rigid and uniform motion. The
//! resisting generalised force `Q_α` (a vector per shape) grows by `K_α q̇_α Δt` and turns
//! with the element's spin; the nodes feel `f_I = −Σ_α Q_α γ_αI`. `K_α` acts in the
//! element's own axes and is chosen from the physics of the mode in a box-shaped element of
//! half-lengths `a_i` (`hourglass_rates`): a displacement `u_i = q h_α` along an axis `i`
//! that `h_α` varies along is a bending (or warping) field; it keeps the energy of its normal
//! strain `∂u_i/∂x_i` and drops its parasitic shear, as assumed-strain elements do. Two such
//! normal strains with the same linear profile (the bending strain and its Poisson
//! contraction across the width) share a plane-stress energy, so a beam bent in a box-shaped
//! mesh stores exactly `½ E κ² I` per length whatever the number of elements through its
//! depth: no shear locking and no Poisson stiffening. A displacement along an axis `h_α`
//! does not vary along is a twist, and keeps its shear energy. `hourglass` scales all of it
//! (1: as derived). The hourglass response stays elastic and its energy counts as internal
//! energy.

// Index loops mirror the tensor formulas; `!(x > 0.0)` rejects NaN on purpose.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use crate::j2::{self, J2Material, J2State, Sym};
use rayon::prelude::*;

/// Reference coordinates (ξ, η, ζ) of the corners, in the usual order: the bottom face
/// (ζ = −1) counter-clockwise seen from +ζ, then the top face.
pub const CORNERS: [[f64; 3]; 8] = [
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
];

/// The hourglass shapes at the corners: ξη, ηζ, ζξ, ξηζ (the tests check them against the
/// products of [`CORNERS`]).
const HG_SHAPES: [[f64; 8]; 4] = [
    [1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0],
    [1.0, 1.0, -1.0, -1.0, -1.0, -1.0, 1.0, 1.0],
    [1.0, -1.0, -1.0, 1.0, -1.0, 1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0, 1.0, 1.0, -1.0, 1.0, -1.0],
];

/// The volume of a trilinear hexahedron is a sum of triple products of its corners,
/// `V = Σ_IJK D_IJK x_I y_J z_K`, with `D_IJK = ∫ det[∇_ξ N_I, ∇_ξ N_J, ∇_ξ N_K] dξ` over
/// the reference cube (antisymmetric in I, J, K); so `B_I = ∂V/∂x_I = Σ_{J<K} D_IJK (x_J ×
/// x_K)`: nine cross products a corner, each weighted ±1/12 (Flanagan and Belytschko's
/// closed form). The table lists, per corner, those (J, K, 12 D_IJK); the tests check the
/// gradients it gives against 2 × 2 × 2 Gauss points (exact for the trilinear map).
const VOLUME_PAIRS: [[(usize, usize, f64); 9]; 8] = [
    [
        (1, 2, -1.0),
        (1, 3, -1.0),
        (1, 4, 1.0),
        (1, 5, 1.0),
        (2, 3, -1.0),
        (3, 4, -1.0),
        (3, 7, -1.0),
        (4, 5, -1.0),
        (4, 7, 1.0),
    ],
    [
        (0, 2, 1.0),
        (0, 3, 1.0),
        (0, 4, -1.0),
        (0, 5, -1.0),
        (2, 3, -1.0),
        (2, 5, 1.0),
        (2, 6, 1.0),
        (4, 5, -1.0),
        (5, 6, -1.0),
    ],
    [
        (0, 1, -1.0),
        (0, 3, 1.0),
        (1, 3, 1.0),
        (1, 5, -1.0),
        (1, 6, -1.0),
        (3, 6, 1.0),
        (3, 7, 1.0),
        (5, 6, -1.0),
        (6, 7, -1.0),
    ],
    [
        (0, 1, -1.0),
        (0, 2, -1.0),
        (0, 4, 1.0),
        (0, 7, 1.0),
        (1, 2, -1.0),
        (2, 6, -1.0),
        (2, 7, -1.0),
        (4, 7, 1.0),
        (6, 7, -1.0),
    ],
    [
        (0, 1, 1.0),
        (0, 3, -1.0),
        (0, 5, 1.0),
        (0, 7, -1.0),
        (1, 5, 1.0),
        (3, 7, -1.0),
        (5, 6, 1.0),
        (5, 7, 1.0),
        (6, 7, 1.0),
    ],
    [
        (0, 1, 1.0),
        (0, 4, -1.0),
        (1, 2, 1.0),
        (1, 4, -1.0),
        (1, 6, 1.0),
        (2, 6, 1.0),
        (4, 6, -1.0),
        (4, 7, -1.0),
        (6, 7, 1.0),
    ],
    [
        (1, 2, 1.0),
        (1, 5, -1.0),
        (2, 3, 1.0),
        (2, 5, -1.0),
        (2, 7, 1.0),
        (3, 7, 1.0),
        (4, 5, 1.0),
        (4, 7, -1.0),
        (5, 7, -1.0),
    ],
    [
        (0, 3, -1.0),
        (0, 4, 1.0),
        (2, 3, 1.0),
        (2, 6, -1.0),
        (3, 4, 1.0),
        (3, 6, -1.0),
        (4, 5, 1.0),
        (4, 6, 1.0),
        (5, 6, 1.0),
    ],
];

/// Index of the corner pair (j, k), j < k, among the 28.
const fn pair(j: usize, k: usize) -> usize {
    j * (15 - j) / 2 + k - j - 1
}

/// The mean gradient of an element: `B_I = ∫ ∇N_I dV` and the volume `V` (closed form,
/// `VOLUME_PAIRS`), exact for the trilinear map; positions are taken relative to the first
/// corner, so an element far from the origin keeps its digits. `None` when the volume is
/// not positive or not finite (a folded or inverted element).
pub fn mean_gradient(x: &[[f64; 3]; 8]) -> Option<([[f64; 3]; 8], f64)> {
    let o = x[0];
    let r: [[f64; 3]; 8] =
        std::array::from_fn(|i| [x[i][0] - o[0], x[i][1] - o[1], x[i][2] - o[2]]);
    // the corners' cross products, once each (those with corner 0, at the origin, vanish)
    let mut cr = [[0.0; 3]; 28];
    for j in 1..8 {
        for k in j + 1..8 {
            let (a, c) = (r[j], r[k]);
            cr[pair(j, k)] = [
                a[1] * c[2] - a[2] * c[1],
                a[2] * c[0] - a[0] * c[2],
                a[0] * c[1] - a[1] * c[0],
            ];
        }
    }
    let mut b = [[0.0; 3]; 8];
    let mut vol = 0.0;
    for i in 0..8 {
        let mut s = [0.0; 3];
        for &(j, k, w) in &VOLUME_PAIRS[i] {
            if j > 0 {
                let c = &cr[pair(j, k)];
                for d in 0..3 {
                    s[d] += w * c[d];
                }
            }
        }
        let s = s.map(|c| c / 12.0);
        vol += s[0] * r[i][0] + s[1] * r[i][1] + s[2] * r[i][2];
        b[i] = s;
    }
    // Σ_I B_I · x_I = 3 V (V is homogeneous of degree 3 in the positions)
    vol /= 3.0;
    if !(vol > 0.0) || !vol.is_finite() {
        return None;
    }
    Some((b, vol))
}

/// The element's own axes (orthonormal, from the centre Jacobian's columns by Gram–Schmidt)
/// and half-lengths along its reference directions.
fn axes(x: &[[f64; 3]; 8]) -> ([[f64; 3]; 3], [f64; 3]) {
    let mut col = [[0.0; 3]; 3];
    for i in 0..8 {
        for k in 0..3 {
            for r in 0..3 {
                col[k][r] += 0.125 * CORNERS[i][k] * x[i][r];
            }
        }
    }
    let half = col.map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt());
    let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let unit = |a: [f64; 3]| {
        let n = 1.0 / dot(&a, &a).sqrt();
        a.map(|c| c * n)
    };
    let e0 = unit(col[0]);
    let d1 = dot(&col[1], &e0);
    let e1 = unit(std::array::from_fn(|r| col[1][r] - d1 * e0[r]));
    let e2 = [
        e0[1] * e1[2] - e0[2] * e1[1],
        e0[2] * e1[0] - e0[0] * e1[2],
        e0[0] * e1[1] - e0[1] * e1[0],
    ];
    ([e0, e1, e2], half)
}

/// The pairs of hourglass entries (shape, axis) whose normal strains share one linear
/// profile: (x, ξη) and (z, ηζ) both strain along η, (y, ξη) and (z, ζξ) along ξ, (x, ζξ)
/// and (y, ηζ) along ζ. Their energy couples through Poisson's ratio.
const HG_PAIRS: [[(usize, usize); 2]; 3] = [[(0, 0), (1, 2)], [(0, 1), (2, 2)], [(2, 0), (1, 1)]];

/// The hourglass force rates `Q̇` (in the element's axes) for the projected generalised
/// velocities `ql` (in the element's axes; `q̇ = 8 ×` the mode's amplitude rate in a box).
///
/// Normal-strain entries of the two-variable shapes are paired (`HG_PAIRS`): strain rates
/// `Ȧ`, `Ċ` of one linear profile store `E/(1−ν²) (A² + C² + 2ν A C) ⟨η²⟩ V / 2`, which is
/// `E A² ⟨η²⟩ V / 2` — uniaxial bending, exact — when the lateral one is free (`C = −νA`).
/// The three-variable shape's normal strains are uncoupled (modulus E); the entries a shape
/// does not vary along keep their shear energy (modulus G).
fn hourglass_rates(
    m: &J2Material,
    vol: f64,
    half: &[f64; 3],
    scale: f64,
    ql: &[[f64; 3]; 4],
) -> [[f64; 3]; 4] {
    let (e, g, nu) = (m.young, m.shear_modulus(), m.poisson);
    let c = scale * vol / 64.0;
    // 1/a_i and 1/a_i² (the rates below take no other division)
    let ih = half.map(|h| 1.0 / h);
    let ih2 = ih.map(|x| x * x);
    let mut r = [[0.0; 3]; 4];
    // shear-only entries of the two-variable shapes: (z, ξη), (x, ηζ), (y, ζξ)
    let cg = c * g / 3.0;
    r[0][2] = cg * (ih2[0] + ih2[1]) * ql[0][2];
    r[1][0] = cg * (ih2[1] + ih2[2]) * ql[1][0];
    r[2][1] = cg * (ih2[2] + ih2[0]) * ql[2][1];
    // normal-strain pairs of the two-variable shapes
    let cep = c * e / (3.0 * (1.0 - nu * nu));
    for [(a1, i1), (a2, i2)] in HG_PAIRS {
        let (s1, s2) = (ql[a1][i1] * ih[i1], ql[a2][i2] * ih[i2]);
        r[a1][i1] = cep * (s1 + nu * s2) * ih[i1];
        r[a2][i2] = cep * (s2 + nu * s1) * ih[i2];
    }
    // the three-variable shape
    let ce = c * e / 9.0;
    for i in 0..3 {
        r[3][i] = ce * ih2[i] * ql[3][i];
    }
    r
}

/// Material and numerical parameters of a hexahedral part.
#[derive(Debug, Clone, Copy)]
pub struct HexParams {
    pub material: J2Material,
    pub density: f64,
    /// Scale of the hourglass stiffness (1: the physical stiffness of the module docs).
    pub hourglass: f64,
}

/// A block of hexahedra: nodes and elements (corner order of [`CORNERS`]).
#[derive(Debug, Clone, Default)]
pub struct HexMesh {
    pub nodes: Vec<[f64; 3]>,
    pub elements: Vec<[u32; 8]>,
}

impl HexMesh {
    /// A structured block of `n[0] × n[1] × n[2]` elements filling `[origin, origin + size]`.
    pub fn block(origin: [f64; 3], size: [f64; 3], n: [usize; 3]) -> HexMesh {
        let n = n.map(|k| k.max(1));
        let id = |i: usize, j: usize, k: usize| (i + (n[0] + 1) * (j + (n[1] + 1) * k)) as u32;
        let mut m = HexMesh::default();
        for k in 0..=n[2] {
            for j in 0..=n[1] {
                for i in 0..=n[0] {
                    let s = [i, j, k];
                    m.nodes.push(std::array::from_fn(|d| {
                        origin[d] + size[d] * s[d] as f64 / n[d] as f64
                    }));
                }
            }
        }
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    m.elements.push([
                        id(i, j, k),
                        id(i + 1, j, k),
                        id(i + 1, j + 1, k),
                        id(i, j + 1, k),
                        id(i, j, k + 1),
                        id(i + 1, j, k + 1),
                        id(i + 1, j + 1, k + 1),
                        id(i, j + 1, k + 1),
                    ]);
                }
            }
        }
        m
    }
}

/// Per-element state and what the last force evaluation left in it.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct HexState {
    pub mat: J2State,
    /// Hourglass generalised forces, one vector per shape (N).
    pub hg: [[f64; 3]; 4],
    /// Stress work and hourglass energy since the start (J), plastic work (J).
    pub work: f64,
    pub hg_energy: f64,
    pub plastic_work: f64,
    /// Volume now (m³).
    pub volume: f64,
}

/// Elements on a node array the caller owns (positions, half-step velocities, forces):
/// connectivity, per-element state, and the scratch of a force evaluation. The nodes may be
/// shared with another discretisation (the meso-joint node's particles are the nodes of its
/// hexahedra); `add_forces` adds to what the caller's force array already holds.
#[derive(Debug, Clone)]
pub struct HexPart {
    pub p: HexParams,
    pub elements: Vec<[u32; 8]>,
    pub state: Vec<HexState>,
    /// Each element's density over the material's (1; more under mass scaling).
    pub density_scale: Vec<f64>,
    /// Each element's nodal forces from the last evaluation (scratch, gathered into `f`).
    elem_f: Vec<[[f64; 3]; 8]>,
    /// Elements around each node: CSR offsets into `adj` of (element, corner).
    adj_start: Vec<u32>,
    adj: Vec<(u32, u8)>,
}

impl HexPart {
    /// The elements on nodes `x` (their reference positions); refuses a node index out of
    /// range and a folded or inverted element.
    pub fn new(elements: Vec<[u32; 8]>, x: &[[f64; 3]], p: HexParams) -> Result<HexPart, String> {
        let n = x.len();
        let mut state = vec![HexState::default(); elements.len()];
        for (e, el) in elements.iter().enumerate() {
            if let Some(&bad) = el.iter().find(|&&i| i as usize >= n) {
                return Err(format!("element {e} names node {bad} of {n}"));
            }
            let xe = el.map(|i| x[i as usize]);
            let (_, vol) = mean_gradient(&xe)
                .ok_or_else(|| format!("element {e} is folded or inverted (det J ≤ 0)"))?;
            state[e].volume = vol;
        }
        let mut start = vec![0u32; n + 1];
        for el in &elements {
            for &i in el {
                start[i as usize + 1] += 1;
            }
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut adj = vec![(0u32, 0u8); start[n] as usize];
        let mut fill = start.clone();
        for (e, el) in elements.iter().enumerate() {
            for (c, &i) in el.iter().enumerate() {
                adj[fill[i as usize] as usize] = (e as u32, c as u8);
                fill[i as usize] += 1;
            }
        }
        Ok(HexPart {
            p,
            density_scale: vec![1.0; elements.len()],
            elem_f: vec![[[0.0; 3]; 8]; elements.len()],
            elements,
            state,
            adj_start: start,
            adj,
        })
    }

    /// Whether node `i` belongs to an element.
    pub fn has_node(&self, i: usize) -> bool {
        self.adj_start[i + 1] > self.adj_start[i]
    }

    /// Lumped mass: an eighth of each element's mass to each of its nodes (kg, per node).
    pub fn lumped_mass(&self) -> Vec<f64> {
        let mut m = vec![0.0; self.adj_start.len() - 1];
        for ((el, s), k) in self
            .elements
            .iter()
            .zip(&self.state)
            .zip(&self.density_scale)
        {
            for &i in el {
                m[i as usize] += 0.125 * self.p.density * k * s.volume;
            }
        }
        m
    }

    /// The elements' physical mass (kg, without mass scaling).
    pub fn physical_mass(&self) -> f64 {
        self.p.density * self.state.iter().map(|s| s.volume).sum::<f64>()
    }

    /// Mass scaling: raises the density of every element whose stable step (`factor` times
    /// [`HexPart::stable_dt`]'s bound) is below `target` until it reaches it. Returns the
    /// mass added to each node (kg).
    pub fn mass_scale(&mut self, x: &[[f64; 3]], target: f64, factor: f64) -> Vec<f64> {
        let mut add = vec![0.0; self.adj_start.len() - 1];
        for e in 0..self.elements.len() {
            let dt = factor * self.element_dt(x, e);
            if dt > 0.0 && dt < target {
                let grow = (target / dt).powi(2);
                let extra =
                    self.p.density * self.density_scale[e] * (grow - 1.0) * self.state[e].volume;
                self.density_scale[e] *= grow;
                for &i in &self.elements[e] {
                    add[i as usize] += 0.125 * extra;
                }
            }
        }
        add
    }

    /// Element `e`'s bound `2 / ω_max` (s; 0 for a folded element).
    fn element_dt(&self, x: &[[f64; 3]], e: usize) -> f64 {
        let m = &self.p.material;
        let c2 = (m.bulk_modulus() + 4.0 / 3.0 * m.shear_modulus())
            / (self.p.density * self.density_scale[e]);
        let xe = self.elements[e].map(|i| x[i as usize]);
        match mean_gradient(&xe) {
            Some((b, vol)) => {
                let bb: f64 = b.iter().flatten().map(|c| c * c).sum();
                vol / (2.0 * c2 * bb).sqrt()
            }
            None => 0.0,
        }
    }

    /// Largest stable step of central differences, `2 / ω_max` with Flanagan and
    /// Belytschko's bound on an element's highest frequency, `ω² ≤ 8 (λ + 2μ) Σ B_iI² /
    /// (ρ V²)` (0.577 h / c for a cube of side h). The usual `V / A_max` estimate (h / c) is
    /// above what a lumped corner node of a compressible-enough material takes: it let a
    /// cantilever with ν = 0.45 fold at its free corner. Folded elements give 0.
    pub fn stable_dt(&self, x: &[[f64; 3]]) -> f64 {
        (0..self.elements.len())
            .into_par_iter()
            .map(|e| self.element_dt(x, e))
            .reduce(|| f64::INFINITY, f64::min)
    }

    /// Adds the internal forces at positions `x` to `f`, the stresses first advanced over
    /// `dt` with the velocities `v` (the half-step velocities of central differences; `dt =
    /// 0` evaluates the forces of the present state). Fails on a folded element, naming it.
    pub fn add_forces(
        &mut self,
        x: &[[f64; 3]],
        v: &[[f64; 3]],
        dt: f64,
        f: &mut [[f64; 3]],
    ) -> Result<(), String> {
        let p = &self.p;
        let folded = self
            .elements
            .par_iter()
            .zip(self.state.par_iter_mut())
            .zip(self.elem_f.par_iter_mut())
            .enumerate()
            .filter_map(|(e, ((el, s), out))| {
                let xe = el.map(|i| x[i as usize]);
                let ve = el.map(|i| v[i as usize]);
                element(&xe, &ve, p, s, out, dt).err().map(|_| e)
            })
            .min();
        if let Some(e) = folded {
            return Err(format!(
                "hexahedron {e} folded (det J ≤ 0) at {:?}",
                self.elements[e].map(|i| x[i as usize])
            ));
        }
        let (start, adj, ef) = (&self.adj_start, &self.adj, &self.elem_f);
        f.par_iter_mut().enumerate().for_each(|(i, f)| {
            for &(e, c) in &adj[start[i] as usize..start[i + 1] as usize] {
                let fe = ef[e as usize][c as usize];
                for d in 0..3 {
                    f[d] += fe[d];
                }
            }
        });
        Ok(())
    }

    /// Stress work, hourglass energy and plastic work of all elements (J).
    pub fn energies(&self) -> (f64, f64, f64) {
        self.state.iter().fold((0.0, 0.0, 0.0), |a, s| {
            (a.0 + s.work, a.1 + s.hg_energy, a.2 + s.plastic_work)
        })
    }
}

/// A part of hexahedra with its own nodes (reference, current position, half-step
/// velocity, internal force, lumped mass), for a caller that steps it alone.
#[derive(Debug, Clone)]
pub struct HexModel {
    pub part: HexPart,
    pub x0: Vec<[f64; 3]>,
    pub x: Vec<[f64; 3]>,
    pub v: Vec<[f64; 3]>,
    /// Internal force at `x` (N).
    pub f: Vec<[f64; 3]>,
    pub mass: Vec<f64>,
}

impl HexModel {
    /// The part at rest in its reference configuration.
    pub fn new(mesh: HexMesh, p: HexParams) -> Result<HexModel, String> {
        let part = HexPart::new(mesh.elements, &mesh.nodes, p)?;
        let n = mesh.nodes.len();
        Ok(HexModel {
            mass: part.lumped_mass(),
            part,
            x0: mesh.nodes.clone(),
            x: mesh.nodes,
            v: vec![[0.0; 3]; n],
            f: vec![[0.0; 3]; n],
        })
    }

    pub fn nodes(&self) -> usize {
        self.x.len()
    }

    pub fn stable_dt(&self) -> f64 {
        self.part.stable_dt(&self.x)
    }

    /// Internal forces at `x` after advancing the stresses over `dt` with `v`.
    pub fn update_forces(&mut self, dt: f64) -> Result<(), String> {
        self.f.fill([0.0; 3]);
        self.part.add_forces(&self.x, &self.v, dt, &mut self.f)
    }

    /// Stress work, hourglass energy and plastic work (J).
    pub fn energies(&self) -> (f64, f64, f64) {
        self.part.energies()
    }

    /// Kinetic energy and linear momentum of the nodes (half-step velocities).
    pub fn motion(&self) -> (f64, [f64; 3]) {
        let mut ke = 0.0;
        let mut p = [0.0; 3];
        for (m, v) in self.mass.iter().zip(&self.v) {
            ke += 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            for d in 0..3 {
                p[d] += m * v[d];
            }
        }
        (ke, p)
    }
}

/// One element: the stress and hourglass forces advanced over `dt` with the nodal
/// velocities `v` at the positions `x`, and the nodal forces into `out`.
fn element(
    x: &[[f64; 3]; 8],
    v: &[[f64; 3]; 8],
    p: &HexParams,
    s: &mut HexState,
    out: &mut [[f64; 3]; 8],
    dt: f64,
) -> Result<(), ()> {
    let (b, vol) = mean_gradient(x).ok_or(())?;
    s.volume = vol;
    let inv = 1.0 / vol;
    // mean velocity gradient L_rc = (1/V) Σ_I v_Ir B_Ic
    let mut l = [[0.0; 3]; 3];
    for i in 0..8 {
        for r in 0..3 {
            for c in 0..3 {
                l[r][c] += v[i][r] * b[i][c];
            }
        }
    }
    for row in &mut l {
        for c in row.iter_mut() {
            *c *= inv;
        }
    }
    let (spin, de) = j2::spin_and_strain_step(&l, dt);
    let before = s.mat.stress;
    j2::jaumann_rotate_skew(&mut s.mat.stress, &spin, dt);
    j2::jaumann_rotate_skew(&mut s.mat.back_stress, &spin, dt);
    let deqp = p.material.update(&mut s.mat, &de);
    // stress work with the mean of the stress before and after over the strain increment
    let mid: Sym = std::array::from_fn(|k| 0.5 * (before[k] + s.mat.stress[k]));
    s.work += vol * j2::ddot(&mid, &de);
    s.plastic_work += vol * j2::plastic_work(&s.mat, deqp);
    let sig = j2::to_matrix(&s.mat.stress);
    for i in 0..8 {
        for r in 0..3 {
            out[i][r] = -(sig[r][0] * b[i][0] + sig[r][1] * b[i][1] + sig[r][2] * b[i][2]);
        }
    }
    if p.hourglass > 0.0 {
        // With γ_αI = h_αI − (1/V) Σ_k hx_αk B_Ik (hx_α = Σ_I h_αI x_I): q̇_α = hv_α − L hx_α
        // (hv_α = Σ_I h_αI v_I), and −Σ_α Q_α γ_αI = −Σ_α Q_α h_αI + (1/V) M B_I with
        // M = Σ_α Q_α ⊗ hx_α — no γ is formed.
        let (e_axes, half) = axes(x);
        let o = x[0];
        let mut hx = [[0.0; 3]; 4];
        let mut qdot = [[0.0; 3]; 4];
        let mut ql = [[0.0; 3]; 4];
        for a in 0..4 {
            let h = &HG_SHAPES[a];
            let mut hv = [0.0; 3];
            for i in 0..8 {
                for r in 0..3 {
                    hx[a][r] += h[i] * (x[i][r] - o[r]);
                    hv[r] += h[i] * v[i][r];
                }
            }
            for r in 0..3 {
                qdot[a][r] = hv[r] - (l[r][0] * hx[a][0] + l[r][1] * hx[a][1] + l[r][2] * hx[a][2]);
            }
            for ax in 0..3 {
                let e = &e_axes[ax];
                ql[a][ax] = e[0] * qdot[a][0] + e[1] * qdot[a][1] + e[2] * qdot[a][2];
            }
        }
        let rate = hourglass_rates(&p.material, vol, &half, p.hourglass, &ql);
        let mut m = [[0.0; 3]; 3];
        for a in 0..4 {
            let q = &mut s.hg[a];
            let old = *q;
            // turn with the element (dQ = W Q dt) and grow by the rate in its axes
            for r in 0..3 {
                let wq = spin[r][0] * old[0] + spin[r][1] * old[1] + spin[r][2] * old[2];
                let kq = rate[a][0] * e_axes[0][r]
                    + rate[a][1] * e_axes[1][r]
                    + rate[a][2] * e_axes[2][r];
                q[r] = old[r] + dt * (wq + kq);
            }
            s.hg_energy += dt
                * 0.5
                * ((old[0] + q[0]) * qdot[a][0]
                    + (old[1] + q[1]) * qdot[a][1]
                    + (old[2] + q[2]) * qdot[a][2]);
            let h = &HG_SHAPES[a];
            for i in 0..8 {
                for r in 0..3 {
                    out[i][r] -= q[r] * h[i];
                }
            }
            for r in 0..3 {
                for k in 0..3 {
                    m[r][k] += q[r] * hx[a][k];
                }
            }
        }
        for i in 0..8 {
            for r in 0..3 {
                out[i][r] += inv * (m[r][0] * b[i][0] + m[r][1] * b[i][1] + m[r][2] * b[i][2]);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cofactor matrix of a 3 × 3 matrix (`cof[r][k]` = signed minor of entry (r, k)).
    fn cofactors(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
        [
            [
                m[1][1] * m[2][2] - m[1][2] * m[2][1],
                m[1][2] * m[2][0] - m[1][0] * m[2][2],
                m[1][0] * m[2][1] - m[1][1] * m[2][0],
            ],
            [
                m[0][2] * m[2][1] - m[0][1] * m[2][2],
                m[0][0] * m[2][2] - m[0][2] * m[2][0],
                m[0][1] * m[2][0] - m[0][0] * m[2][1],
            ],
            [
                m[0][1] * m[1][2] - m[0][2] * m[1][1],
                m[0][2] * m[1][0] - m[0][0] * m[1][2],
                m[0][0] * m[1][1] - m[0][1] * m[1][0],
            ],
        ]
    }

    /// The mean gradient by 2 × 2 × 2 Gauss points (exact for the trilinear map): the
    /// reference the closed form is checked against.
    fn gauss_mean_gradient(x: &[[f64; 3]; 8]) -> Option<([[f64; 3]; 8], f64)> {
        let g = 1.0 / 3f64.sqrt();
        let mut b = [[0.0; 3]; 8];
        let mut vol = 0.0;
        for gp in 0..8 {
            let p = [CORNERS[gp][0] * g, CORNERS[gp][1] * g, CORNERS[gp][2] * g];
            // dN_I/dξ_k at p
            let mut dn = [[0.0; 3]; 8];
            for i in 0..8 {
                let c = CORNERS[i];
                let f = [1.0 + c[0] * p[0], 1.0 + c[1] * p[1], 1.0 + c[2] * p[2]];
                dn[i] = [
                    0.125 * c[0] * f[1] * f[2],
                    0.125 * c[1] * f[0] * f[2],
                    0.125 * c[2] * f[0] * f[1],
                ];
            }
            // J_ik = ∂x_i/∂ξ_k
            let mut jac = [[0.0; 3]; 3];
            for i in 0..8 {
                for r in 0..3 {
                    for k in 0..3 {
                        jac[r][k] += x[i][r] * dn[i][k];
                    }
                }
            }
            let cof = cofactors(&jac);
            let det = jac[0][0] * cof[0][0] + jac[0][1] * cof[0][1] + jac[0][2] * cof[0][2];
            if !(det > 0.0) || !det.is_finite() {
                return None;
            }
            vol += det;
            // ∇N_I det J = cof(J) dN_I/dξ (cof(J) = det J · J⁻ᵀ), unit Gauss weights
            for i in 0..8 {
                for r in 0..3 {
                    b[i][r] += cof[r][0] * dn[i][0] + cof[r][1] * dn[i][1] + cof[r][2] * dn[i][2];
                }
            }
        }
        Some((b, vol))
    }

    /// Which reference coordinates each hourglass shape varies along: ξη, ηζ, ζξ, ξηζ.
    const HG_VARS: [[bool; 3]; 4] = [
        [true, true, false],
        [false, true, true],
        [true, false, true],
        [true, true, true],
    ];

    /// The hourglass shapes are the products of the corners' reference coordinates.
    #[test]
    fn the_hourglass_shapes_are_the_coordinate_products() {
        for a in 0..4 {
            for i in 0..8 {
                let want: f64 = (0..3)
                    .filter(|&k| HG_VARS[a][k])
                    .map(|k| CORNERS[i][k])
                    .product();
                assert_eq!(HG_SHAPES[a][i], want, "shape {a}, corner {i}");
            }
        }
    }

    fn steel(yield_stress: f64) -> HexParams {
        HexParams {
            material: J2Material {
                young: 210e9,
                poisson: 0.3,
                yield_stress,
                iso_hardening: 0.0,
                kin_hardening: 1e9,
            },
            density: 7850.0,
            hourglass: 1.0,
        }
    }

    /// A 3 × 3 × 3 block whose interior nodes are moved off the lattice (every element a
    /// general hexahedron).
    fn distorted(size: f64) -> HexMesh {
        let mut m = HexMesh::block([0.0; 3], [size; 3], [3, 3, 3]);
        let h = size / 3.0;
        for (k, x) in m.nodes.iter_mut().enumerate() {
            let interior = x.iter().all(|&c| c > 1e-12 && c < size - 1e-12);
            if interior {
                let s = [0.23, -0.17, 0.11];
                let t = [(k % 3) as f64 - 1.0, (k % 5) as f64 / 2.0 - 1.0, 0.5];
                for d in 0..3 {
                    x[d] += h * s[d] * t[(d + k) % 3];
                }
            }
        }
        m
    }

    /// The mean gradient integrates exactly: `Σ_I B_I ⊗ x_I = V I` and `Σ_I B_I = 0` for a
    /// general hexahedron, and the volume of a box is its volume.
    #[test]
    fn the_mean_gradient_reproduces_linear_fields_in_a_general_hexahedron() {
        let mut x = CORNERS.map(|c| c.map(|v| 0.5 + 0.5 * v));
        x[6] = [1.3, 1.1, 1.2];
        x[1] = [0.9, -0.1, 0.05];
        let (b, vol) = mean_gradient(&x).expect("a valid element");
        let (bg, vg) = gauss_mean_gradient(&x).expect("a valid element");
        assert!(
            (vol - vg).abs() < 1e-14 * vg,
            "volume {vol} against Gauss {vg}"
        );
        for i in 0..8 {
            for r in 0..3 {
                assert!(
                    (b[i][r] - bg[i][r]).abs() < 1e-14,
                    "B[{i}][{r}] {} against Gauss {}",
                    b[i][r],
                    bg[i][r]
                );
            }
        }
        for r in 0..3 {
            let sum: f64 = (0..8).map(|i| b[i][r]).sum();
            assert!(sum.abs() < 1e-14, "Σ B_{r} = {sum}");
            for c in 0..3 {
                let m: f64 = (0..8).map(|i| b[i][r] * x[i][c]).sum();
                let want = if r == c { vol } else { 0.0 };
                assert!(
                    (m - want).abs() < 1e-14 * vol.max(1.0),
                    "({r},{c}): {m} vs {want}"
                );
            }
        }
        let boxed = CORNERS.map(|c| [c[0] * 1.5, c[1] * 0.5, c[2] * 0.25]);
        let (_, v) = mean_gradient(&boxed).unwrap();
        assert!((v - 3.0 * 1.0 * 0.5).abs() < 1e-15, "box volume {v}");
        // an inverted element is refused
        let mut inv = boxed;
        inv.swap(0, 6);
        assert!(mean_gradient(&inv).is_none());
    }

    /// Patch test: a uniform velocity gradient applied to a distorted mesh gives every
    /// element the exact stress of the strain, no hourglass force, and no net force on any
    /// interior node.
    #[test]
    fn a_uniform_strain_gives_the_exact_stress_and_no_interior_force_on_a_distorted_mesh() {
        let size = 0.03;
        let mesh = distorted(size);
        let mut m = HexModel::new(mesh, steel(1e12)).unwrap();
        // L: stretch, shear and rotation together, small enough to stay linear
        let l = [
            [2e-3, 1e-3, -0.5e-3],
            [0.3e-3, -1e-3, 0.8e-3],
            [0.7e-3, 0.2e-3, 0.5e-3],
        ];
        for (v, x) in m.v.iter_mut().zip(&m.x) {
            *v = std::array::from_fn(|r| (0..3).map(|c| l[r][c] * x[c]).sum());
        }
        let dt = 1e-3;
        m.update_forces(dt).unwrap();
        // the strain increment of L (its own unit test checks the split)
        let (_, de) = j2::spin_and_strain_step(&l, dt);
        let want = m.part.p.material.elastic_increment(&de);
        let scale = want.iter().fold(0.0f64, |a, s| a.max(s.abs()));
        for s in &m.part.state {
            for k in 0..6 {
                assert!(
                    (s.mat.stress[k] - want[k]).abs() < 1e-12 * scale,
                    "stress {k}: {} vs {}",
                    s.mat.stress[k],
                    want[k]
                );
            }
            for q in &s.hg {
                assert!(q.iter().all(|c| c.abs() < 1e-12 * scale * size * size));
            }
        }
        let fscale = scale * size * size;
        let mut interior = 0;
        for (x, f) in m.x.iter().zip(&m.f) {
            if x.iter().all(|&c| c > 1e-12 && c < size - 1e-12) {
                interior += 1;
                let n = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
                assert!(
                    n < 1e-12 * fscale,
                    "interior force {n} N against {fscale} N"
                );
            }
        }
        assert_eq!(interior, 8);
    }

    /// A box-shaped element bent by Saint-Venant's pure bending field (`u_x = −κ x y`, the
    /// lateral strains free) on a box of half-lengths a, b, c stores the exact bending
    /// energy `½ E κ² b² V / 3`: its centre strain is zero, so all of it is the hourglass's.
    #[test]
    fn a_box_bent_by_its_hourglass_mode_stores_the_exact_bending_energy() {
        let (a, b, c) = (0.02, 0.005, 0.003);
        let mesh = HexMesh {
            nodes: CORNERS.map(|k| [a * k[0], b * k[1], c * k[2]]).to_vec(),
            elements: vec![std::array::from_fn(|i| i as u32)],
        };
        let p = steel(1e12);
        let mut m = HexModel::new(mesh, p).unwrap();
        let kappa = 0.1;
        // velocities that reach u in one step of dt
        let dt = 1.0;
        for (v, x) in m.v.iter_mut().zip(&m.x0) {
            // Saint-Venant's pure bending: σ_xx = −E κ y, the lateral strains free
            let nu = p.material.poisson;
            *v = [
                -kappa * x[0] * x[1] / dt,
                0.5 * kappa * (x[0] * x[0] + nu * (x[1] * x[1] - x[2] * x[2])) / dt,
                nu * kappa * x[1] * x[2] / dt,
            ];
        }
        m.update_forces(dt).unwrap();
        let vol = 8.0 * a * b * c;
        let exact = 0.5 * p.material.young * kappa * kappa * b * b * vol / 3.0;
        // the centre strain of pure bending is zero: all of the energy is the hourglass's
        let s = &m.part.state[0];
        assert!(
            s.mat
                .stress
                .iter()
                .all(|x| x.abs() < 1e-6 * p.material.young * kappa * b)
        );
        let (_, hg, _) = m.energies();
        // one step from zero: trapezoidal energy ½ K q̇² dt² equals the stored ½ K q²
        assert!((hg - exact).abs() < 1e-12 * exact, "{hg} against {exact}");
    }

    /// Rigid motion (a translation and a spin) strains nothing and makes no force.
    #[test]
    fn rigid_motion_makes_no_force() {
        let mut m = HexModel::new(distorted(0.03), steel(1e12)).unwrap();
        let w = [0.0, -3.0, 2.0];
        for (v, x) in m.v.iter_mut().zip(&m.x) {
            let r = [x[0] - 0.01, x[1] - 0.02, x[2]];
            *v = [
                1.0 + w[1] * r[2] - w[2] * r[1],
                -2.0 + w[2] * r[0] - w[0] * r[2],
                0.5 + w[0] * r[1] - w[1] * r[0],
            ];
        }
        m.update_forces(1e-7).unwrap();
        let fmax = m.f.iter().flatten().fold(0.0f64, |a, f| a.max(f.abs()));
        // a strain of 1e-7 would give forces near E × 1e-7 × h² ≈ 2 N
        assert!(fmax < 1e-6, "largest force {fmax} N");
    }

    /// The tip deflection of a steel cantilever 100 × 10 × 10 mm (20 × 2 × 2 elements) under
    /// a 100 N tip load, brought to rest by mass-proportional damping, and beam theory's:
    /// Euler–Bernoulli's `P L³ / 3EI` plus Timoshenko's shear part `P L / κGA` (κ = 5/6).
    /// The root is held as beam theory holds it: every root node along the axis, the root's
    /// mid-lines across it, so the root section stays plane and contracts freely.
    fn cantilever(poisson: f64) -> (f64, f64) {
        let (len, h, w) = (0.1, 0.01, 0.01);
        let mut p = steel(1e12);
        p.material.poisson = poisson;
        let mut m = HexModel::new(HexMesh::block([0.0; 3], [len, h, w], [20, 2, 2]), p).unwrap();
        let held: Vec<[bool; 3]> =
            m.x0.iter()
                .map(|x| {
                    let root = x[0] < 1e-12;
                    [
                        root,
                        root && (x[1] - h / 2.0).abs() < 1e-9,
                        root && (x[2] - w / 2.0).abs() < 1e-9,
                    ]
                })
                .collect();
        let tip: Vec<usize> = (0..m.nodes())
            .filter(|&i| m.x0[i][0] > len - 1e-12)
            .collect();
        assert_eq!(tip.len(), 9);
        let load = 100.0;
        let dt = 0.9 * m.stable_dt();
        let damping = 10000.0; // 1/s, about critical for the first bending mode (5,250 rad/s)
        let steps = (0.006 / dt) as usize;
        let deflection =
            |m: &HexModel| -tip.iter().map(|&i| m.x[i][1] - m.x0[i][1]).sum::<f64>() / 9.0;
        m.update_forces(0.0).unwrap();
        let mut last = 0.0;
        for step in 0..steps {
            for i in 0..m.nodes() {
                let mut f = m.f[i];
                if tip.contains(&i) {
                    f[1] -= load / 9.0;
                }
                for d in (0..3).filter(|&d| !held[i][d]) {
                    m.v[i][d] = (m.v[i][d] * (1.0 - 0.5 * damping * dt) + dt * f[d] / m.mass[i])
                        / (1.0 + 0.5 * damping * dt);
                }
            }
            for i in 0..m.nodes() {
                for d in 0..3 {
                    m.x[i][d] += dt * m.v[i][d];
                }
            }
            m.update_forces(dt).unwrap();
            if step + 100 == steps {
                last = deflection(&m);
            }
        }
        let tip_u = deflection(&m);
        assert!(
            (tip_u - last).abs() < 1e-6 * tip_u,
            "not at rest: {last} → {tip_u}"
        );
        let mat = p.material;
        let inertia = w * h.powi(3) / 12.0;
        let bending = load * len.powi(3) / (3.0 * mat.young * inertia);
        let shear = load * len / (5.0 / 6.0 * mat.shear_modulus() * w * h);
        (tip_u, bending + shear)
    }

    /// With two elements through the depth the beam bends as beam theory says, for a common
    /// and a nearly incompressible Poisson's ratio (measured −0.14 % and −0.20 %; a root
    /// held fully, which stops its Poisson contraction, reads 1.4 % and 3.4 % stiffer).
    #[test]
    fn a_cantilever_of_two_elements_through_its_depth_bends_as_a_beam() {
        for nu in [0.3, 0.45] {
            let (tip, beam) = cantilever(nu);
            let err = (tip - beam) / beam;
            println!(
                "ν = {nu}: tip deflection {tip:.6e} m, beam theory {beam:.6e} m, {:+.3} %",
                100.0 * err
            );
            assert!(
                err.abs() < 0.005,
                "ν = {nu}: {:+.3} % off beam theory",
                100.0 * err
            );
        }
    }

    /// A free distorted block set moving with scattered velocities: the internal forces sum
    /// to zero (momentum to round-off) and kinetic plus stored energy stays within 1e-4 of
    /// the start (measured 7.3e-6 over 2,000 steps) while the block vibrates elastically,
    /// through hourglass and constant-strain modes alike.
    #[test]
    fn a_free_block_keeps_its_momentum_and_energy() {
        let mut m = HexModel::new(distorted(0.03), steel(1e12)).unwrap();
        let mut seed = 12345u64;
        let mut rand = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for v in m.v.iter_mut() {
            *v = [rand(), rand(), rand()];
        }
        let dt = 0.5 * m.stable_dt();
        m.update_forces(0.0).unwrap();
        let (_, p0) = m.motion();
        // kinetic energy at a whole step: ½ m v⁻ · v⁺ of the half steps around it
        let step = |m: &mut HexModel| {
            let mut ke = 0.0;
            for i in 0..m.nodes() {
                let before = m.v[i];
                for d in 0..3 {
                    m.v[i][d] += dt * m.f[i][d] / m.mass[i];
                    ke += 0.5 * m.mass[i] * before[d] * m.v[i][d];
                    m.x[i][d] += dt * m.v[i][d];
                }
            }
            ke
        };
        let ke0 = step(&mut m);
        m.update_forces(dt).unwrap();
        let (mut largest, mut drift) = (0.0f64, 0.0f64);
        let steps = 2000;
        for _ in 1..steps {
            let (work, hg, _) = m.energies();
            let ke = step(&mut m);
            m.update_forces(dt).unwrap();
            largest = largest.max(work + hg);
            drift = drift.max((ke + work + hg - ke0).abs() / ke0);
        }
        let (_, p) = m.motion();
        let pscale: f64 = m.mass.iter().sum::<f64>() * 0.5;
        for d in 0..3 {
            assert!(
                (p[d] - p0[d]).abs() < 1e-13 * pscale,
                "momentum {d}: {} → {}",
                p0[d],
                p[d]
            );
        }
        assert_eq!(m.energies().2, 0.0, "plastic work");
        // the stored energy took a good share of the motion's
        assert!(largest > 0.1 * ke0, "stored at most {largest} J of {ke0} J");
        println!(
            "largest stored {largest:.4e} J of {ke0:.4e} J; energy off by at most {:.3e}",
            drift
        );
        assert!(
            drift < 1e-3,
            "energy off by {:+.3} % over {steps} steps",
            100.0 * drift
        );
    }
}
