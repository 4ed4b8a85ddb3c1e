//! Eight-node hexahedra for explicit dynamics: one-point (mean-gradient) integration with
//! hourglass control, J2 plasticity with isotropic and kinematic hardening in rate form
//! (Jaumann), lumped mass, central differences driven by the caller.
//!
//! **Integration.** Each element uses the mean strain rate over its volume: with
//! `B_I = ∫_e ∇N_I dV` (the derivative of the element's volume with respect to node I's
//! position, Flanagan & Belytschko 1981) the velocity gradient is `L = (1/V) Σ_I v_I ⊗ B_I`
//! and the internal force `f_I = −σ B_I`. `B_I` and `V` are exact for the trilinear map, in
//! Flanagan and Belytschko's closed form (sums of cross products of corner positions), so a
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
//!
//! **Speed.** The force kernel is written once over a [`Lane`] type and runs four elements
//! side by side (one per lane; in one AVX register per value where the CPU has AVX2), each
//! lane bit for bit what the element gives alone: about 1,200 instructions an element step
//! against 3,300 one at a time (callgrind, 20³ block, AVX2).

// Index loops mirror the tensor formulas; `!(x > 0.0)` rejects NaN on purpose.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use crate::j2::{J2Material, J2State};
use crate::lanes::{Lane, Lanes, unrolled};
use crate::simd::Simd;
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

/// Positions of `W` elements' corners, one element per lane: `[corner][axis]`.
type Corners<L> = [[L; 3]; 8];

/// A vector of `W` lanes.
type V3<L> = [L; 3];

#[inline(always)]
fn dot<L: Lane>(a: &V3<L>, b: &V3<L>) -> L {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn cross<L: Lane>(a: &V3<L>, c: &V3<L>) -> V3<L> {
    [
        a[1] * c[2] - a[2] * c[1],
        a[2] * c[0] - a[0] * c[2],
        a[0] * c[1] - a[1] * c[0],
    ]
}

/// The mean gradient of an element: `B_I = ∫ ∇N_I dV` and the volume `V` (closed form,
/// `VOLUME_PAIRS`), exact for the trilinear map; positions are taken relative to the first
/// corner, so an element far from the origin keeps its digits. `None` when the volume is
/// not positive or not finite (a folded or inverted element).
pub fn mean_gradient(x: &[[f64; 3]; 8]) -> Option<([[f64; 3]; 8], f64)> {
    let r: Corners<f64> = std::array::from_fn(|i| std::array::from_fn(|d| x[i][d] - x[0][d]));
    let (b, vol) = mean_gradient_rel(&r);
    if !(vol > 0.0) || !vol.is_finite() {
        return None;
    }
    Some((b, vol))
}

/// [`mean_gradient`] of `W` elements at once from corner positions `r` relative to each
/// element's first corner (`r[0] = 0`); the volume is not checked.
#[inline(always)]
fn mean_gradient_rel<L: Lane>(r: &Corners<L>) -> (Corners<L>, L) {
    // the corners' cross products, once each, in the order of `pair` (those with corner 0,
    // at the origin, vanish and are left out)
    let cr: [V3<L>; 21] = [
        cross(&r[1], &r[2]),
        cross(&r[1], &r[3]),
        cross(&r[1], &r[4]),
        cross(&r[1], &r[5]),
        cross(&r[1], &r[6]),
        cross(&r[1], &r[7]),
        cross(&r[2], &r[3]),
        cross(&r[2], &r[4]),
        cross(&r[2], &r[5]),
        cross(&r[2], &r[6]),
        cross(&r[2], &r[7]),
        cross(&r[3], &r[4]),
        cross(&r[3], &r[5]),
        cross(&r[3], &r[6]),
        cross(&r[3], &r[7]),
        cross(&r[4], &r[5]),
        cross(&r[4], &r[6]),
        cross(&r[4], &r[7]),
        cross(&r[5], &r[6]),
        cross(&r[5], &r[7]),
        cross(&r[6], &r[7]),
    ];
    let b: Corners<L> = unrolled!(i in [0, 1, 2, 3, 4, 5, 6, 7] => corner_gradient(&cr, i));
    // Σ_I B_I · x_I = 3 V (V is homogeneous of degree 3 in the positions)
    let mut vol = dot(&b[1], &r[1]);
    for i in 2..8 {
        vol += dot(&b[i], &r[i]);
    }
    (b, vol / 3.0)
}

/// `B_i` from the corners' cross products (`VOLUME_PAIRS`; the weights are ±1).
#[inline(always)]
fn corner_gradient<L: Lane>(cr: &[V3<L>; 21], i: usize) -> V3<L> {
    let mut s = [L::zero(); 3];
    for &(j, k, w) in &VOLUME_PAIRS[i] {
        if j > 0 {
            let c = &cr[pair(j, k) - 7];
            for d in 0..3 {
                if w > 0.0 {
                    s[d] += c[d];
                } else {
                    s[d] -= c[d];
                }
            }
        }
    }
    // a product, not a quotient (24 divisions an element were about a tenth of the kernel)
    let w = 1.0 / 12.0;
    [s[0] * w, s[1] * w, s[2] * w]
}

/// `Σ_I s_I r_Id` over corners `from..8` for a table of signs `s` (±1); `from = 1` for
/// positions relative to corner 0 (at the origin).
#[inline(always)]
fn signed_sum<L: Lane>(s: &[f64; 8], r: &Corners<L>, d: usize, from: usize) -> L {
    let mut a = if s[from] > 0.0 {
        r[from][d]
    } else {
        -r[from][d]
    };
    for i in from + 1..8 {
        if s[i] > 0.0 {
            a += r[i][d];
        } else {
            a -= r[i][d];
        }
    }
    a
}

/// The element's own axes (orthonormal, from the centre Jacobian's columns by Gram–Schmidt)
/// and half-lengths along its reference directions, from corner positions relative to the
/// first corner.
#[inline(always)]
fn axes_rel<L: Lane>(r: &Corners<L>) -> ([V3<L>; 3], V3<L>) {
    let col: [V3<L>; 3] = unrolled!(k in [0, 1, 2] => {
        let s = CORNER_SIGNS[k];
        unrolled!(d in [0, 1, 2] => signed_sum(&s, r, d, 1) * 0.125)
    });
    let half = unrolled!(k in [0, 1, 2] => dot(&col[k], &col[k]).sqrt());
    let n0 = half[0].recip();
    let e0 = unrolled!(d in [0, 1, 2] => col[0][d] * n0);
    let d1 = dot(&col[1], &e0);
    let t1 = unrolled!(d in [0, 1, 2] => col[1][d] - d1 * e0[d]);
    let n1 = dot(&t1, &t1).sqrt().recip();
    let e1 = unrolled!(d in [0, 1, 2] => t1[d] * n1);
    let e2 = cross(&e0, &e1);
    ([e0, e1, e2], half)
}

/// The corners' reference coordinates by axis: `CORNER_SIGNS[k][i] = CORNERS[i][k]`.
const CORNER_SIGNS: [[f64; 8]; 3] = {
    let mut s = [[0.0; 8]; 3];
    let mut i = 0;
    while i < 8 {
        let mut k = 0;
        while k < 3 {
            s[k][i] = CORNERS[i][k];
            k += 1;
        }
        i += 1;
    }
    s
};

/// The hourglass force rates `Q̇` (in the element's axes) for the projected generalised
/// velocities `ql` (in the element's axes; `q̇ = 8 ×` the mode's amplitude rate in a box).
///
/// Normal-strain entries of the two-variable shapes (shape, axis) are paired when they share
/// one linear profile: (ξη, x) and (ηζ, z) both strain along η, (ξη, y) and (ζξ, z) along ξ,
/// (ζξ, x) and (ηζ, y) along ζ. Strain rates `Ȧ`, `Ċ` of one profile store
/// `E/(1−ν²) (A² + C² + 2ν A C) ⟨η²⟩ V / 2`, which is `E A² ⟨η²⟩ V / 2` — uniaxial bending,
/// exact — when the lateral one is free (`C = −νA`). The three-variable shape's normal
/// strains are uncoupled (modulus E); the entries a shape does not vary along keep their
/// shear energy (modulus G).
#[inline(always)]
fn hourglass_rates<L: Lane>(
    m: &J2Material,
    vol: L,
    half: &V3<L>,
    scale: f64,
    ql: &[V3<L>; 4],
) -> [V3<L>; 4] {
    let (e, g, nu) = (m.young, m.shear_modulus(), m.poisson);
    let c = vol * (scale / 64.0);
    // 1/a_i and 1/a_i² (the rates below take no other division)
    let ih = unrolled!(i in [0, 1, 2] => half[i].recip());
    let ih2 = unrolled!(i in [0, 1, 2] => ih[i] * ih[i]);
    // shear-only entries of the two-variable shapes: (ξη, z), (ηζ, x), (ζξ, y)
    let cg = c * (g / 3.0);
    // normal-strain pairs of the two-variable shapes
    let cep = c * (e / (3.0 * (1.0 - nu * nu)));
    let s = |a: usize, i: usize| ql[a][i] * ih[i];
    let paired = |(a1, i1): (usize, usize), (a2, i2): (usize, usize)| {
        cep * (s(a1, i1) + s(a2, i2) * nu) * ih[i1]
    };
    // the three-variable shape
    let ce = c * (e / 9.0);
    [
        [
            paired((0, 0), (1, 2)),
            paired((0, 1), (2, 2)),
            cg * (ih2[0] + ih2[1]) * ql[0][2],
        ],
        [
            cg * (ih2[1] + ih2[2]) * ql[1][0],
            paired((1, 1), (2, 0)),
            paired((1, 2), (0, 0)),
        ],
        [
            paired((2, 0), (1, 1)),
            cg * (ih2[2] + ih2[0]) * ql[2][1],
            paired((2, 2), (0, 1)),
        ],
        unrolled!(i in [0, 1, 2] => ce * ih2[i] * ql[3][i]),
    ]
}

/// Elements computed side by side, one per lane of the force kernel where the CPU has no
/// AVX2 (where it has, four in one AVX register).
const LANES: usize = 4;

/// Elements per parallel task of the force evaluation.
const BLOCK: usize = 256;

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

/// Values of a [`HexState`]: stress (6), back stress (6), equivalent plastic strain,
/// hourglass forces (12), stress work, hourglass energy, plastic work, volume.
const NSTATE: usize = 29;

/// [`BLOCK`] elements' states, value by value (`v[q][k]`: value `q` of the block's element
/// `k`), so that the force kernel loads and stores each value of its lanes at once.
#[derive(Debug, Clone)]
struct StateBlock {
    v: [[f64; BLOCK]; NSTATE],
}

impl StateBlock {
    fn get(&self, k: usize) -> HexState {
        HexState::from_values(&std::array::from_fn(|q| self.v[q][k]))
    }

    fn set(&mut self, k: usize, s: &HexState) {
        for (q, x) in s.values().into_iter().enumerate() {
            self.v[q][k] = x;
        }
    }
}

/// The values of an element's state in the order of [`StateBlock`]: stress, back stress,
/// equivalent plastic strain, hourglass forces, then stress work, hourglass energy, plastic
/// work and volume (`ends`).
#[inline(always)]
fn state_layout<T: Copy>(
    stress: &[T; 6],
    back: &[T; 6],
    eqp: T,
    hg: &[[T; 3]; 4],
    ends: [T; 4],
) -> [T; NSTATE] {
    let mut v = [eqp; NSTATE];
    v[..6].copy_from_slice(stress);
    v[6..12].copy_from_slice(back);
    for a in 0..4 {
        v[13 + 3 * a..16 + 3 * a].copy_from_slice(&hg[a]);
    }
    v[25..].copy_from_slice(&ends);
    v
}

impl HexState {
    /// The values in the order of [`StateBlock`] (see [`NSTATE`]).
    fn values(&self) -> [f64; NSTATE] {
        let m = &self.mat;
        let ends = [self.work, self.hg_energy, self.plastic_work, self.volume];
        state_layout(
            &m.stress,
            &m.back_stress,
            m.eq_plastic_strain,
            &self.hg,
            ends,
        )
    }

    /// The state of values in the order of [`StateBlock`].
    fn from_values(v: &[f64; NSTATE]) -> HexState {
        HexState {
            mat: J2State {
                stress: [v[0], v[1], v[2], v[3], v[4], v[5]],
                back_stress: [v[6], v[7], v[8], v[9], v[10], v[11]],
                eq_plastic_strain: v[12],
            },
            hg: [
                [v[13], v[14], v[15]],
                [v[16], v[17], v[18]],
                [v[19], v[20], v[21]],
                [v[22], v[23], v[24]],
            ],
            work: v[25],
            hg_energy: v[26],
            plastic_work: v[27],
            volume: v[28],
        }
    }
}

/// The states of a part's elements, stored in blocks of [`BLOCK`] value by value (what the
/// force kernel reads); read and written here one element at a time as [`HexState`].
#[derive(Debug, Clone, Default)]
pub struct HexStates {
    blocks: Vec<StateBlock>,
    len: usize,
}

impl HexStates {
    /// `n` elements in the default state.
    pub fn new(n: usize) -> HexStates {
        let block = StateBlock {
            v: [[0.0; BLOCK]; NSTATE],
        };
        HexStates {
            blocks: vec![block; n.div_ceil(BLOCK)],
            len: n,
        }
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Element `e`'s state.
    pub fn get(&self, e: usize) -> HexState {
        assert!(e < self.len, "element {e} of {}", self.len);
        self.blocks[e / BLOCK].get(e % BLOCK)
    }

    /// Sets element `e`'s state.
    pub fn set(&mut self, e: usize, s: &HexState) {
        assert!(e < self.len, "element {e} of {}", self.len);
        self.blocks[e / BLOCK].set(e % BLOCK, s);
    }

    /// Every element's state, in order.
    pub fn iter(&self) -> impl Iterator<Item = HexState> + '_ {
        (0..self.len).map(|e| self.get(e))
    }

    /// Every element's state as a vector (for a checkpoint).
    pub fn to_vec(&self) -> Vec<HexState> {
        self.iter().collect()
    }

    /// The states of `s`, one per element.
    pub fn from_slice(s: &[HexState]) -> HexStates {
        let mut h = HexStates::new(s.len());
        for (e, st) in s.iter().enumerate() {
            h.set(e, st);
        }
        h
    }
}

/// Elements on a node array the caller owns (positions, half-step velocities, forces):
/// connectivity, per-element state, and the scratch of a force evaluation. The nodes may be
/// shared with another discretisation (the meso-joint node's particles are the nodes of its
/// hexahedra); `add_forces` adds to what the caller's force array already holds.
#[derive(Debug, Clone)]
pub struct HexPart {
    pub p: HexParams,
    pub elements: Vec<[u32; 8]>,
    pub state: HexStates,
    /// Each element's density over the material's (1; more under mass scaling).
    pub density_scale: Vec<f64>,
    /// The widest instruction set the force evaluation may use (the CPU's widest unless
    /// set; every choice gives the same forces bit for bit).
    pub simd: Simd,
    /// Each element's nodal forces from the last evaluation (scratch, gathered into `f`).
    elem_f: Vec<f64>,
    /// Elements around each node: CSR offsets into `adj` of where in `elem_f` the force of
    /// each (element, corner) is (x, y and z side by side: the gather reads one cache line).
    adj_start: Vec<u32>,
    adj: Vec<u32>,
}

impl HexPart {
    /// The elements on nodes `x` (their reference positions); refuses a node index out of
    /// range and a folded or inverted element.
    pub fn new(elements: Vec<[u32; 8]>, x: &[[f64; 3]], p: HexParams) -> Result<HexPart, String> {
        let n = x.len();
        let mut state = HexStates::new(elements.len());
        for (e, el) in elements.iter().enumerate() {
            if let Some(&bad) = el.iter().find(|&&i| i as usize >= n) {
                return Err(format!("element {e} names node {bad} of {n}"));
            }
            let xe = el.map(|i| x[i as usize]);
            let (_, vol) = mean_gradient(&xe)
                .ok_or_else(|| format!("element {e} is folded or inverted (det J ≤ 0)"))?;
            state.set(
                e,
                &HexState {
                    volume: vol,
                    ..Default::default()
                },
            );
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
        let mut adj = vec![0u32; start[n] as usize];
        let mut fill = start.clone();
        for (e, el) in elements.iter().enumerate() {
            for (c, &i) in el.iter().enumerate() {
                adj[fill[i as usize] as usize] = force_slot(e, c, 0) as u32;
                fill[i as usize] += 1;
            }
        }
        Ok(HexPart {
            p,
            density_scale: vec![1.0; elements.len()],
            simd: Simd::detect(),
            elem_f: vec![0.0; elements.len().div_ceil(BLOCK) * 24 * BLOCK],
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
            .zip(self.state.iter())
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
                let extra = self.p.density
                    * self.density_scale[e]
                    * (grow - 1.0)
                    * self.state.get(e).volume;
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
        let (p, simd) = (&self.p, self.simd);
        let folded = self
            .elements
            .par_chunks(BLOCK)
            .zip(self.state.blocks.par_iter_mut())
            .zip(self.elem_f.par_chunks_mut(24 * BLOCK))
            .enumerate()
            .filter_map(|(c, ((els, st), out))| {
                let b = Block {
                    x,
                    v,
                    p,
                    els,
                    st,
                    out,
                    dt,
                };
                element_block(simd, b).map(|k| c * BLOCK + k)
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
            for &a in &adj[start[i] as usize..start[i + 1] as usize] {
                let a = a as usize;
                f[0] += ef[a];
                f[1] += ef[a + 1];
                f[2] += ef[a + 2];
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

/// The state of `W` elements, one per lane: what [`element`] reads and writes of
/// [`HexState`].
struct StateLanes<L: Lane> {
    stress: [L; 6],
    back: [L; 6],
    eqp: L,
    hg: [V3<L>; 4],
    work: L,
    hg_energy: L,
    plastic_work: L,
    volume: L,
}

impl<L: Lane> StateLanes<L> {
    /// The states of the block's elements `o..o + W`.
    #[inline(always)]
    fn load(b: &StateBlock, o: usize) -> Self {
        let v = |q: usize| L::load(&b.v[q][o..]);
        StateLanes {
            stress: unrolled!(c in [0, 1, 2, 3, 4, 5] => v(c)),
            back: unrolled!(c in [0, 1, 2, 3, 4, 5] => v(6 + c)),
            eqp: v(12),
            hg: unrolled!(a in [0, 1, 2, 3] => unrolled!(d in [0, 1, 2] => v(13 + 3 * a + d))),
            work: v(25),
            hg_energy: v(26),
            plastic_work: v(27),
            volume: v(28),
        }
    }

    /// Into the block's elements `o..o + W` (those beyond the block's last element are
    /// padding, never read as elements).
    #[inline(always)]
    fn store(&self, b: &mut StateBlock, o: usize) {
        let ends = [self.work, self.hg_energy, self.plastic_work, self.volume];
        let lanes = state_layout(&self.stress, &self.back, self.eqp, &self.hg, ends);
        for (q, l) in lanes.into_iter().enumerate() {
            l.store(&mut b.v[q][o..]);
        }
    }
}

/// `a : b` of symmetric tensors (Voigt order, tensor shear).
#[inline(always)]
fn ddot<L: Lane>(a: &[L; 6], b: &[L; 6]) -> L {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + (a[3] * b[3] + a[4] * b[4] + a[5] * b[5]) * 2.0
}

/// `s += dt (W s − s W)` for the skew spin with upper entries `w01, w02, w12` (the rotation
/// of `j2::jaumann_rotate_skew`).
#[inline(always)]
fn rotate<L: Lane>(s: &mut [L; 6], w: &[L; 3], dt: f64) {
    let [w01, w02, w12] = *w;
    let [sxx, syy, szz, syz, sxz, sxy] = *s;
    let p00 = w01 * sxy + w02 * sxz;
    let p01 = w01 * syy + w02 * syz;
    let p02 = w01 * syz + w02 * szz;
    let p10 = w12 * sxz - w01 * sxx;
    let p11 = w12 * syz - w01 * sxy;
    let p12 = w12 * szz - w01 * sxz;
    let p20 = -(w02 * sxx) - w12 * sxy;
    let p21 = -(w02 * sxy) - w12 * syy;
    let p22 = -(w02 * sxz) - w12 * syz;
    let dt2 = 2.0 * dt;
    s[0] += p00 * dt2;
    s[1] += p11 * dt2;
    s[2] += p22 * dt2;
    s[3] += (p12 + p21) * dt;
    s[4] += (p02 + p20) * dt;
    s[5] += (p01 + p10) * dt;
}

/// The elastic predictor and radial return of [`J2Material::update`] lane by lane (a lane
/// that does not yield keeps its trial stress); returns Δε̄ᵖ and adds the plastic work
/// density `σ : Δεᵖ` of [`j2::plastic_work`] times `vol` to `s.plastic_work`.
#[inline(always)]
fn j2_update<L: Lane>(m: &J2Material, s: &mut StateLanes<L>, de: &[L; 6], vol: L) {
    let mu = m.shear_modulus();
    let two_mu = 2.0 * mu;
    let lambda = m.bulk_modulus() - 2.0 / 3.0 * mu;
    let tr = (de[0] + de[1] + de[2]) * lambda;
    for k in 0..3 {
        s.stress[k] += tr + de[k] * two_mu;
    }
    for k in 3..6 {
        s.stress[k] += de[k] * two_mu;
    }
    let mean = (s.stress[0] + s.stress[1] + s.stress[2]) / 3.0;
    let mut dev = s.stress;
    for c in &mut dev[..3] {
        *c -= mean;
    }
    let mut xi = dev;
    for k in 0..6 {
        xi[k] -= s.back[k];
    }
    let norm = ddot(&xi, &xi).sqrt();
    let sqrt23 = (2.0f64 / 3.0).sqrt();
    let radius = (s.eqp * m.iso_hardening + m.yield_stress) * sqrt23;
    let f = norm - radius;
    // f > 0 also means norm > 0; NaN yields nowhere
    let zero = L::zero();
    let dgamma = f.where_positive(
        f / (two_mu + 2.0 / 3.0 * (m.iso_hardening + m.kin_hardening)),
        zero,
    );
    let inv = f.where_positive(norm.recip(), zero);
    let ds = dgamma * two_mu;
    let da = dgamma * (2.0 / 3.0 * m.kin_hardening);
    let mut dev_after = dev;
    for k in 0..6 {
        let n = xi[k] * inv;
        s.stress[k] -= ds * n;
        dev_after[k] -= ds * n;
        s.back[k] += da * n;
    }
    let dp = dgamma * sqrt23;
    s.eqp += dp;
    // σ : Δεᵖ = √(3/2) Δε̄ᵖ (dev σ : n) with the returned stress; n is the return's direction
    let work = dp * 1.5f64.sqrt() * ddot(&dev_after, &xi) * inv;
    s.plastic_work += vol * work;
}

/// `W` elements, one per lane: the stress and hourglass forces advanced over `dt` with the
/// nodal velocities `v` at the positions `x`; returns the nodal forces. A folded element's
/// lane gets a volume that is not positive (checked by the caller).
#[inline(always)]
fn element<L: Lane>(
    x: &Corners<L>,
    v: &Corners<L>,
    p: &HexParams,
    s: &mut StateLanes<L>,
    dt: f64,
) -> Corners<L> {
    let r: Corners<L> =
        unrolled!(i in [0, 1, 2, 3, 4, 5, 6, 7] => unrolled!(d in [0, 1, 2] => x[i][d] - x[0][d]));
    let (b, vol) = mean_gradient_rel(&r);
    s.volume = vol;
    let inv = vol.recip();
    // mean velocity gradient L_dc = (1/V) Σ_I v_Id B_Ic
    let l: [V3<L>; 3] = unrolled!(d in [0, 1, 2] => {
        unrolled!(c in [0, 1, 2] => {
            let mut a = v[0][d] * b[0][c];
            for i in 1..8 {
                a += v[i][d] * b[i][c];
            }
            a * inv
        })
    });
    // the spin's upper entries and the strain increment (`j2::spin_and_strain_step`)
    let spin = [
        (l[0][1] - l[1][0]) * 0.5,
        (l[0][2] - l[2][0]) * 0.5,
        (l[1][2] - l[2][1]) * 0.5,
    ];
    let de = [
        l[0][0] * dt,
        l[1][1] * dt,
        l[2][2] * dt,
        (l[1][2] + l[2][1]) * 0.5 * dt,
        (l[0][2] + l[2][0]) * 0.5 * dt,
        (l[0][1] + l[1][0]) * 0.5 * dt,
    ];
    let before = s.stress;
    rotate(&mut s.stress, &spin, dt);
    rotate(&mut s.back, &spin, dt);
    j2_update(&p.material, s, &de, vol);
    // stress work with the mean of the stress before and after over the strain increment
    let mid = unrolled!(k in [0, 1, 2, 3, 4, 5] => (before[k] + s.stress[k]) * 0.5);
    s.work += vol * ddot(&mid, &de);
    let [sxx, syy, szz, syz, sxz, sxy] = s.stress;
    let sig = [[sxx, sxy, sxz], [sxy, syy, syz], [sxz, syz, szz]];
    let mut out: Corners<L> = unrolled!(i in [0, 1, 2, 3, 4, 5, 6, 7] => unrolled!(d in [0, 1, 2] => -dot(&sig[d], &b[i])));
    if p.hourglass > 0.0 {
        // With γ_αI = h_αI − (1/V) Σ_k hx_αk B_Ik (hx_α = Σ_I h_αI x_I): q̇_α = hv_α − L hx_α
        // (hv_α = Σ_I h_αI v_I), and −Σ_α Q_α γ_αI = −Σ_α Q_α h_αI + (1/V) M B_I with
        // M = Σ_α Q_α ⊗ hx_α — no γ is formed. The shapes' entries are ±1.
        let (e_axes, half) = axes_rel(&r);
        let hx: [V3<L>; 4] = unrolled!(a in [0, 1, 2, 3] => {
            unrolled!(d in [0, 1, 2] => signed_sum(&HG_SHAPES[a], &r, d, 1))
        });
        let qdot: [V3<L>; 4] = unrolled!(a in [0, 1, 2, 3] => {
            unrolled!(d in [0, 1, 2] => signed_sum(&HG_SHAPES[a], v, d, 0) - dot(&l[d], &hx[a]))
        });
        let ql: [V3<L>; 4] = unrolled!(a in [0, 1, 2, 3] => {
            unrolled!(ax in [0, 1, 2] => dot(&e_axes[ax], &qdot[a]))
        });
        let rate = hourglass_rates(&p.material, vol, &half, p.hourglass, &ql);
        let [w01, w02, w12] = spin;
        // turn with the element (dQ = W Q dt) and grow by the rate in its axes
        let q: [V3<L>; 4] = unrolled!(a in [0, 1, 2, 3] => {
            let old = s.hg[a];
            let wq = [
                w01 * old[1] + w02 * old[2],
                w12 * old[2] - w01 * old[0],
                -(w02 * old[0]) - w12 * old[1],
            ];
            unrolled!(d in [0, 1, 2] => {
                let kq = rate[a][0] * e_axes[0][d]
                    + rate[a][1] * e_axes[1][d]
                    + rate[a][2] * e_axes[2][d];
                old[d] + (wq[d] + kq) * dt
            })
        });
        let half_dt = 0.5 * dt;
        for a in 0..4 {
            let sum = unrolled!(d in [0, 1, 2] => s.hg[a][d] + q[a][d]);
            s.hg_energy += dot(&sum, &qdot[a]) * half_dt;
        }
        s.hg = q;
        let m: [V3<L>; 3] = unrolled!(d in [0, 1, 2] => {
            unrolled!(k in [0, 1, 2] => {
                q[0][d] * hx[0][k] + q[1][d] * hx[1][k] + q[2][d] * hx[2][k] + q[3][d] * hx[3][k]
            })
        });
        for i in 0..8 {
            for d in 0..3 {
                let mut f = out[i][d] + inv * dot(&m[d], &b[i]);
                for a in 0..4 {
                    if HG_SHAPES[a][i] > 0.0 {
                        f -= q[a][d];
                    } else {
                        f += q[a][d];
                    }
                }
                out[i][d] = f;
            }
        }
    }
    out
}

/// The positions (or velocities) `a` of the corners of elements `els` in the first lanes;
/// the last element's in the lanes beyond.
#[inline(always)]
fn gather_corners<L: Lane>(a: &[[f64; 3]], els: &[[u32; 8]]) -> Corners<L> {
    let n = els.len();
    unrolled!(i in [0, 1, 2, 3, 4, 5, 6, 7] => {
        unrolled!(d in [0, 1, 2] => {
            L::from_lanes(|k| a[els[k.min(n - 1)][i] as usize][d])
        })
    })
}

/// Elements `els` (their states `st`, their nodal forces into `out`) `W` at a time; the
/// first folded one, if any (its index in `els`).
#[inline(always)]
fn element_block_body<L: Lane>(b: Block) -> Option<usize> {
    let Block {
        x,
        v,
        p,
        els,
        st,
        out,
        dt,
    } = b;
    let mut folded = None;
    for (c, els) in els.chunks(L::W).enumerate() {
        let o = c * L::W;
        let (xl, vl) = (gather_corners::<L>(x, els), gather_corners::<L>(v, els));
        let mut sl = StateLanes::load(st, o);
        let ol = element(&xl, &vl, p, &mut sl, dt);
        sl.store(st, o);
        // each element's 24 forces side by side (where the node gather reads them)
        let mut buf = [[0.0; 8]; 24];
        for i in 0..8 {
            for d in 0..3 {
                ol[i][d].store(&mut buf[3 * i + d]);
            }
        }
        for k in 0..els.len() {
            let e = &mut out[24 * (o + k)..24 * (o + k + 1)];
            for (q, e) in e.iter_mut().enumerate() {
                *e = buf[q][k];
            }
        }
        for k in 0..els.len() {
            let vol = sl.volume.lane(k);
            if !(vol > 0.0) || !vol.is_finite() {
                folded = Some(o + k);
                break;
            }
        }
        if folded.is_some() {
            break;
        }
    }
    folded
}

/// A block of elements to step: positions and velocities of the nodes, the elements, their
/// states and the scratch for their nodal forces.
struct Block<'a> {
    x: &'a [[f64; 3]],
    v: &'a [[f64; 3]],
    p: &'a HexParams,
    /// At most [`BLOCK`] elements.
    els: &'a [[u32; 8]],
    st: &'a mut StateBlock,
    /// The block's nodal forces: `out[24 k + 3 i + d]` is component `d` at corner `i` of the
    /// block's element `k` (what [`force_slot`] addresses).
    out: &'a mut [f64],
    dt: f64,
}

/// Where in a part's nodal forces (24 values an element, in element order) component `d`
/// of corner `c`'s force of element `e` is.
const fn force_slot(e: usize, c: usize, d: usize) -> usize {
    24 * e + 3 * c + d
}

/// [`element_block_body`] eight elements side by side in one AVX-512 register each value, or
/// four in an AVX register, as `simd` allows and the CPU has, else four in the portable
/// lanes; bit for bit the same.
fn element_block(simd: Simd, b: Block) -> Option<usize> {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx2,avx")]
        fn avx2(b: Block) -> Option<usize> {
            element_block_body::<crate::lanes::Avx4>(b)
        }
        #[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,avx")]
        fn avx512(b: Block) -> Option<usize> {
            element_block_body::<crate::lanes::Avx8>(b)
        }
        if simd == Simd::Avx512 && crate::simd::has_avx512() {
            // SAFETY: the CPU has AVX-512 F, DQ and VL (checked just above), what `avx512`
            // and the `Avx8` values made in it require.
            return unsafe { avx512(b) };
        }
        if matches!(simd, Simd::Avx2 | Simd::Avx512) && crate::simd::has_avx2() {
            // SAFETY: the CPU has AVX2 (checked just above), what `avx2` and the `Avx4`
            // values made in it require.
            return unsafe { avx2(b) };
        }
    }
    let _ = simd;
    element_block_body::<Lanes<LANES>>(b)
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

    /// The force kernel runs `LANES` elements side by side: every lane, at every instruction
    /// set the CPU has, gives bit for bit what the kernel gives that element alone (`W = 1`),
    /// for a distorted mesh whose element count is not a multiple of the lanes, with some
    /// elements yielding and others elastic, over steps that carry stress and hourglass state.
    #[test]
    fn elements_side_by_side_give_each_element_alone_bit_for_bit() {
        let mesh = distorted(0.01);
        let n_el = mesh.elements.len();
        assert_eq!(n_el % LANES, 27 % LANES);
        assert_ne!(n_el % LANES, 0);
        // a velocity field with shear, spin and hourglass content, strong enough that some
        // elements yield in the first steps (σy 200 MPa)
        let v: Vec<[f64; 3]> = mesh
            .nodes
            .iter()
            .enumerate()
            .map(|(k, x)| {
                let w = [
                    (k % 7) as f64 - 3.0,
                    (k % 4) as f64 - 1.5,
                    (k % 3) as f64 - 1.0,
                ];
                // strongest at x = 0.01, where the elements yield; elastic near x = 0
                let a = (x[0] / 0.01).powi(3);
                [
                    a * (30.0 * x[1] / 0.01 + 0.8 * w[0]),
                    a * (-20.0 * x[2] / 0.01 + 0.8 * w[1]),
                    a * (25.0 * x[0] / 0.01 + 0.8 * w[2]),
                ]
            })
            .collect();
        let p = steel(200e6);
        let dt = 2e-7;
        let run = |f: &dyn Fn(Block) -> Option<usize>| {
            let mut x = mesh.nodes.clone();
            let mut states = HexStates::new(n_el);
            let mut out = vec![0.0; 24 * BLOCK];
            let mut forces = Vec::new();
            for _ in 0..5 {
                for (x, v) in x.iter_mut().zip(&v) {
                    for d in 0..3 {
                        x[d] += dt * v[d];
                    }
                }
                let b = Block {
                    x: &x,
                    v: &v,
                    p: &p,
                    els: &mesh.elements,
                    st: &mut states.blocks[0],
                    out: &mut out,
                    dt,
                };
                assert_eq!(f(b), None);
                forces.extend(out[..24 * n_el].iter().copied());
            }
            (forces, states.to_vec())
        };
        let (alone, st_alone) = run(&|b| element_block_body::<f64>(b));
        let yielded = st_alone.iter().filter(|s| s.plastic_work > 0.0).count();
        assert!(yielded > 0 && yielded < n_el, "{yielded} of {n_el} yielded");
        assert!(st_alone.iter().all(|s| s.hg_energy != 0.0));
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let state_bits = |s: &[HexState]| {
            let mut b = Vec::new();
            for s in s {
                b.extend(
                    s.mat
                        .stress
                        .iter()
                        .chain(&s.mat.back_stress)
                        .map(|x| x.to_bits()),
                );
                b.extend(s.hg.iter().flatten().map(|x| x.to_bits()));
                for x in [
                    s.mat.eq_plastic_strain,
                    s.work,
                    s.hg_energy,
                    s.plastic_work,
                    s.volume,
                ] {
                    b.push(x.to_bits());
                }
            }
            b
        };
        for simd in Simd::available() {
            let (side, st_side) = run(&|b| element_block(simd, b));
            assert_eq!(side.len(), alone.len());
            assert!(bits(&side) == bits(&alone), "{simd:?}: forces differ");
            assert!(
                state_bits(&st_side) == state_bits(&st_alone),
                "{simd:?}: states differ"
            );
        }
    }

    /// A part of several blocks of elements, the last one partly filled, gives the same
    /// forces and states at every instruction set over steps that carry state.
    #[test]
    fn every_instruction_set_steps_a_part_of_several_blocks_alike() {
        let n = 9; // 729 elements: two whole blocks and a partial one
        let mut runs = Vec::new();
        for simd in Simd::available() {
            let mut m = HexModel::new(HexMesh::block([0.0; 3], [0.01; 3], [n, n, n]), steel(200e6))
                .unwrap();
            let ne = m.part.elements.len();
            assert!(ne > 2 * BLOCK && !ne.is_multiple_of(BLOCK));
            m.part.simd = simd;
            for (k, v) in m.v.iter_mut().enumerate() {
                *v = [
                    (k % 7) as f64 - 3.0,
                    (k % 5) as f64 - 2.0,
                    (k % 3) as f64 - 1.0,
                ];
            }
            let dt = 2e-8;
            for _ in 0..4 {
                for (x, v) in m.x.iter_mut().zip(&m.v) {
                    for d in 0..3 {
                        x[d] += dt * v[d];
                    }
                }
                m.update_forces(dt).unwrap();
            }
            let bits: Vec<u64> =
                m.f.iter()
                    .flatten()
                    .chain(
                        m.part
                            .state
                            .iter()
                            .flat_map(|s| s.mat.stress)
                            .collect::<Vec<_>>()
                            .iter(),
                    )
                    .map(|x| x.to_bits())
                    .collect();
            runs.push((simd, bits));
        }
        // one instruction set alone compares nothing: a CPU without AVX2 fails under CI
        if runs.len() < 2 {
            assert!(
                std::env::var("CI").is_err(),
                "only {:?} here: nothing to compare",
                runs[0].0
            );
            println!(
                "skipped: this CPU has one instruction set ({:?})",
                runs[0].0
            );
        }
        for (simd, bits) in &runs[1..] {
            assert!(*bits == runs[0].1, "{simd:?} differs from {:?}", runs[0].0);
        }
    }

    /// A folded element is reported by its index, whichever lane it is in.
    #[test]
    fn a_folded_element_is_named_from_any_lane() {
        let mut mesh = HexMesh::block([0.0; 3], [0.01; 3], [3, 2, 1]);
        let n_el = mesh.elements.len();
        // element 4 inside out: its top face given as its bottom
        let el = mesh.elements[4];
        mesh.elements[4] = std::array::from_fn(|c| el[(c + 4) % 8]);
        let v = vec![[0.0; 3]; mesh.nodes.len()];
        let mut st = HexStates::new(n_el);
        let mut out = vec![0.0; 24 * BLOCK];
        let p = steel(1e9);
        for simd in Simd::available() {
            let b = Block {
                x: &mesh.nodes,
                v: &v,
                p: &p,
                els: &mesh.elements,
                st: &mut st.blocks[0],
                out: &mut out,
                dt: 0.0,
            };
            assert_eq!(element_block(simd, b), Some(4), "{simd:?}");
        }
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
        let (_, de) = crate::j2::spin_and_strain_step(&l, dt);
        let want = m.part.p.material.elastic_increment(&de);
        let scale = want.iter().fold(0.0f64, |a, s| a.max(s.abs()));
        for s in m.part.state.iter() {
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
        let s = &m.part.state.get(0);
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
