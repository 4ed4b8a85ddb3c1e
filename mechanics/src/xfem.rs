//! A crack in a mesh of bilinear quads (seed 001 eqs. 67–70): the polyline, the side of it a
//! point lies on, and how it cuts each element — not at all, through (the element splits in
//! two parts, each carrying its own copy of the displacement field), or only into it (it holds
//! a crack tip, and stays whole). `fem2d::Model::cracked` builds the enriched model from it.
//!
//! The approximation is the shifted-Heaviside enrichment of seed 001 eq. (67)–(70) written in
//! the phantom-node basis (Hansbo & Hansbo 2004; Song, Areias & Belytschko 2006): both span
//! the same functions, but here every degree of freedom is a displacement — a node's own, or
//! the other side's field continued to it (its phantom) — so the lumped mass stays diagonal.
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use crate::fem2d::Fem2dError;

fn config(key: &str, reason: impl Into<String>) -> Fem2dError {
    Fem2dError::Config {
        key: key.into(),
        reason: reason.into(),
    }
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

fn lerp(a: [f64; 2], b: [f64; 2], t: f64) -> [f64; 2] {
    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
}

/// A crack: a polyline of at least two points. Its positive side is the left of its direction
/// (from the first point to the last).
#[derive(Debug, Clone, PartialEq)]
pub struct Crack {
    points: Vec<[f64; 2]>,
}

impl Crack {
    /// Refuses fewer than two points, a non-finite coordinate or a segment of zero length;
    /// `key` names the polyline in errors.
    pub fn new(key: &str, points: Vec<[f64; 2]>) -> Result<Self, Fem2dError> {
        if points.len() < 2 {
            return Err(config(
                key,
                format!("needs at least two points, got {}", points.len()),
            ));
        }
        if let Some(k) = points
            .iter()
            .position(|p| !(p[0].is_finite() && p[1].is_finite()))
        {
            return Err(config(&format!("{key}[{k}]"), "must be finite"));
        }
        if let Some(k) = points.windows(2).position(|w| w[0] == w[1]) {
            return Err(config(
                &format!("{key}[{}]", k + 1),
                "repeats the point before it (a segment of zero length)",
            ));
        }
        Ok(Crack { points })
    }

    pub fn points(&self) -> &[[f64; 2]] {
        &self.points
    }

    /// The two ends (first, last).
    pub fn ends(&self) -> [[f64; 2]; 2] {
        [self.points[0], self.points[self.points.len() - 1]]
    }

    /// Total length (m).
    pub fn length(&self) -> f64 {
        self.points
            .windows(2)
            .map(|w| dot(sub(w[1], w[0]), sub(w[1], w[0])).sqrt())
            .sum()
    }

    /// Distance from `p` to the polyline and the side `p` lies on: +1 left of it, −1 right.
    /// The side is taken from the nearest point; where that is a vertex shared by two
    /// segments, from the bisector of their directions.
    pub fn locate(&self, p: [f64; 2]) -> (f64, f64) {
        let mut best = (f64::INFINITY, 1.0);
        for (k, w) in self.points.windows(2).enumerate() {
            let (a, b) = (w[0], w[1]);
            let d = sub(b, a);
            let t = (dot(sub(p, a), d) / dot(d, d)).clamp(0.0, 1.0);
            let q = lerp(a, b, t);
            let dist = dot(sub(p, q), sub(p, q)).sqrt();
            if dist < best.0 {
                let mut dir = d;
                let last = self.points.len() - 2;
                // At an interior vertex, the bisector of the two directions.
                if t == 1.0 && k < last {
                    let e = sub(self.points[k + 2], b);
                    let (ld, le) = (dot(d, d).sqrt(), dot(e, e).sqrt());
                    dir = [d[0] / ld + e[0] / le, d[1] / ld + e[1] / le];
                } else if t == 0.0 && k > 0 {
                    let e = sub(a, self.points[k - 1]);
                    let (ld, le) = (dot(d, d).sqrt(), dot(e, e).sqrt());
                    dir = [d[0] / ld + e[0] / le, d[1] / ld + e[1] / le];
                }
                let side = if cross(dir, sub(p, q)) >= 0.0 {
                    1.0
                } else {
                    -1.0
                };
                best = (dist, side);
            }
        }
        best
    }

    /// The side of `p`: +1 left of the crack, −1 right of it.
    pub fn side(&self, p: [f64; 2]) -> f64 {
        self.locate(p).1
    }

    /// The parameters t ∈ [0, 1] along the segment a → b where the polyline crosses it,
    /// in increasing order.
    pub fn crossings(&self, a: [f64; 2], b: [f64; 2]) -> Vec<f64> {
        let mut out = Vec::new();
        let r = sub(b, a);
        for w in self.points.windows(2) {
            let s = sub(w[1], w[0]);
            let den = cross(r, s);
            if den == 0.0 {
                continue;
            }
            let qp = sub(w[0], a);
            let t = cross(qp, s) / den;
            let u = cross(qp, r) / den;
            if (0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u) {
                out.push(t);
            }
        }
        out.sort_by(f64::total_cmp);
        out
    }

    /// How the crack meets the convex, counter-clockwise quad `xy`, given which of its ends
    /// are tips (ends inside the body; an end on the boundary or outside it is a mouth). An
    /// element the crack crosses from edge to edge is cut even when a tip lies on its exit
    /// edge; the element beyond, holding that tip on its boundary, is a tip element.
    pub fn cut(&self, xy: &[[f64; 2]; 4], tips: [bool; 2]) -> Result<Cut, String> {
        let holds_tip = self
            .ends()
            .iter()
            .zip(tips)
            .any(|(end, tip)| tip && inside_closed(xy, *end));
        // The polyline clipped to the quad, segment by segment (Cyrus–Beck); the pieces must
        // join into one chain from where the crack enters to where it leaves.
        let mut chain: Vec<[f64; 2]> = Vec::new();
        for w in self.points.windows(2) {
            let Some((t0, t1)) = clip(xy, w[0], w[1]) else {
                continue;
            };
            let (p0, p1) = (lerp(w[0], w[1], t0), lerp(w[0], w[1], t1));
            if close(p0, p1, xy) {
                continue;
            }
            match chain.last() {
                Some(&e) if close(e, p0, xy) => {}
                Some(_) => return Err("the crack crosses this element twice".into()),
                None => chain.push(p0),
            }
            chain.push(p1);
        }
        let untouched = if holds_tip { Cut::Tip } else { Cut::None };
        if chain.len() < 2 {
            return Ok(untouched);
        }
        let (entry, exit) = (chain[0], chain[chain.len() - 1]);
        let (Some(ce), Some(cx)) = (perimeter(xy, entry), perimeter(xy, exit)) else {
            // It ends inside: at a tip, or (a mouth inside the body cannot be) an error.
            return if holds_tip {
                Ok(Cut::Tip)
            } else {
                Err("the crack ends inside this element".into())
            };
        };
        if close(entry, exit, xy) {
            return Ok(untouched);
        }
        // The part left of the crack, counter-clockwise: the chain, then the boundary from
        // the exit on to the entry.
        let walk = |from: f64, to: f64, poly: &mut Vec<[f64; 2]>| {
            let end = if to > from { to } else { to + 4.0 };
            let mut corner = from.floor() + 1.0;
            while corner < end {
                poly.push(xy[(corner as usize) % 4]);
                corner += 1.0;
            }
        };
        let mut minus: Vec<[f64; 2]> = chain.iter().rev().copied().collect();
        walk(ce, cx, &mut minus);
        let mut plus = chain;
        walk(cx, ce, &mut plus);
        let area = polygon_area(&plus);
        let total = polygon_area(&xy[..]);
        Ok(Cut::Through {
            plus,
            minus,
            fraction: (area / total).clamp(0.0, 1.0),
        })
    }
}

/// How a crack meets one element.
#[derive(Debug, Clone, PartialEq)]
pub enum Cut {
    /// Not at all (or it only touches a corner or an edge).
    None,
    /// It holds a crack tip: the element stays whole.
    Tip,
    /// It crosses the element: `plus` is the part left of the crack and `minus` the part
    /// right of it (counter-clockwise polygons), `fraction` the left part's share of the
    /// element's area.
    Through {
        plus: Vec<[f64; 2]>,
        minus: Vec<[f64; 2]>,
        fraction: f64,
    },
}

/// Signed area of a polygon (positive counter-clockwise).
pub fn polygon_area(p: &[[f64; 2]]) -> f64 {
    let n = p.len();
    0.5 * (0..n).map(|i| cross(p[i], p[(i + 1) % n])).sum::<f64>()
}

fn scale(xy: &[[f64; 2]; 4]) -> f64 {
    let d = sub(xy[2], xy[0]);
    dot(d, d).sqrt()
}

fn close(a: [f64; 2], b: [f64; 2], xy: &[[f64; 2]; 4]) -> bool {
    let d = sub(a, b);
    dot(d, d).sqrt() <= 1e-12 * scale(xy)
}

/// Whether `p` is in the closed convex counter-clockwise quad `xy` (within round-off of
/// its size).
pub fn quad_contains(xy: &[[f64; 2]; 4], p: [f64; 2]) -> bool {
    inside_closed(xy, p)
}

/// Distance from `p` to the segment a → b.
pub fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let d = sub(b, a);
    let t = (dot(sub(p, a), d) / dot(d, d)).clamp(0.0, 1.0);
    let q = lerp(a, b, t);
    dot(sub(p, q), sub(p, q)).sqrt()
}

fn inside_closed(xy: &[[f64; 2]; 4], p: [f64; 2]) -> bool {
    let tol = 1e-12 * scale(xy) * scale(xy);
    (0..4).all(|k| cross(sub(xy[(k + 1) % 4], xy[k]), sub(p, xy[k])) >= -tol)
}

/// The parameter interval of a → b inside the convex counter-clockwise quad, if any.
fn clip(xy: &[[f64; 2]; 4], a: [f64; 2], b: [f64; 2]) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    let d = sub(b, a);
    for k in 0..4 {
        let e = sub(xy[(k + 1) % 4], xy[k]);
        // Inside: cross(e, p − x_k) ≥ 0.
        let num = cross(e, sub(a, xy[k]));
        let den = cross(e, d);
        if den == 0.0 {
            if num < 0.0 {
                return None;
            }
        } else {
            let t = -num / den;
            if den > 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

/// Where `p` lies on the boundary of the quad, as k + s (edge k from corner k to k + 1, at
/// fraction s along it); None if it is not on the boundary.
fn perimeter(xy: &[[f64; 2]; 4], p: [f64; 2]) -> Option<f64> {
    let h = scale(xy);
    let mut best: Option<(f64, f64)> = None;
    for k in 0..4 {
        let (a, b) = (xy[k], xy[(k + 1) % 4]);
        let e = sub(b, a);
        let s = (dot(sub(p, a), e) / dot(e, e)).clamp(0.0, 1.0);
        let q = lerp(a, b, s);
        let dist = dot(sub(p, q), sub(p, q)).sqrt();
        if best.is_none_or(|(d, _)| dist < d) {
            best = Some((dist, k as f64 + s.min(1.0 - 1e-15)));
        }
    }
    best.filter(|(d, _)| *d <= 1e-9 * h).map(|(_, c)| c)
}

/// Degree-2 rule on a triangle: barycentric points and weights (sum 1).
pub const TRIANGLE_RULE: [([f64; 3], f64); 3] = [
    ([2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0], 1.0 / 3.0),
    ([1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0], 1.0 / 3.0),
    ([1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0], 1.0 / 3.0),
];

/// Quadrature points of a simple polygon: a fan of signed triangles from its first vertex,
/// each with [`TRIANGLE_RULE`]: (point, weight = signed area share). Exact for quadratics
/// over any simple polygon, convex or not (the signed fan sums to the polygon).
pub fn polygon_rule(p: &[[f64; 2]]) -> Vec<([f64; 2], f64)> {
    let mut out = Vec::with_capacity(3 * p.len());
    for i in 1..p.len().saturating_sub(1) {
        let (a, b, c) = (p[0], p[i], p[i + 1]);
        let area = 0.5 * cross(sub(b, a), sub(c, a));
        for (l, w) in TRIANGLE_RULE {
            let x = [
                l[0] * a[0] + l[1] * b[0] + l[2] * c[0],
                l[0] * a[1] + l[1] * b[1] + l[2] * c[1],
            ];
            out.push((x, w * area));
        }
    }
    out
}

/// The parent coordinates (ξ, η) of the physical point `p` in the bilinear quad `xy`
/// (Newton's method; the point may lie slightly outside).
pub fn parent_coordinates(xy: &[[f64; 2]; 4], p: [f64; 2]) -> [f64; 2] {
    const C: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    let (mut xi, mut eta) = (0.0, 0.0);
    let h = scale(xy);
    for _ in 0..30 {
        let mut x = [0.0; 2];
        let mut j = [[0.0; 2]; 2];
        for a in 0..4 {
            let [ca, da] = C[a];
            let n = 0.25 * (1.0 + xi * ca) * (1.0 + eta * da);
            let dxi = 0.25 * ca * (1.0 + eta * da);
            let deta = 0.25 * da * (1.0 + xi * ca);
            for c in 0..2 {
                x[c] += n * xy[a][c];
                j[c][0] += dxi * xy[a][c];
                j[c][1] += deta * xy[a][c];
            }
        }
        let r = sub(p, x);
        let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
        let dxi = (j[1][1] * r[0] - j[0][1] * r[1]) / det;
        let deta = (-j[1][0] * r[0] + j[0][0] * r[1]) / det;
        xi += dxi;
        eta += deta;
        if dot(r, r).sqrt() <= 1e-15 * h {
            break;
        }
    }
    [xi, eta]
}

#[cfg(test)]
mod tests {
    use super::*;

    const SQUARE: [[f64; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];

    /// The two parts and the left one's share, of the unit square crossed by `c`.
    fn through(c: &Crack) -> (Vec<[f64; 2]>, Vec<[f64; 2]>, f64) {
        match c.cut(&SQUARE, [false, false]) {
            Ok(Cut::Through {
                plus,
                minus,
                fraction,
            }) => (plus, minus, fraction),
            other => panic!("not cut: {other:?}"),
        }
    }

    #[test]
    fn a_straight_crack_splits_the_square_by_area() {
        let c = Crack::new("crack", vec![[-1.0, 0.25], [2.0, 0.25]]).unwrap();
        let (plus, minus, fraction) = through(&c);
        // Left of a crack running in +x is above it.
        assert!((fraction - 0.75).abs() < 1e-15, "{fraction}");
        assert!((polygon_area(&plus) - 0.75).abs() < 1e-15);
        assert!((polygon_area(&minus) - 0.25).abs() < 1e-15);
        assert_eq!(c.side([0.5, 0.9]), 1.0);
        assert_eq!(c.side([0.5, 0.1]), -1.0);
    }

    #[test]
    fn a_kinked_crack_gives_the_exact_area_and_a_quadratic_integral() {
        // Entry (0, 0.5), kink (0.5, 0.8), exit (1, 0.5): the part above has area
        // 0.5 − 0.15 = 0.35.
        let c = Crack::new("crack", vec![[-0.5, 0.2], [0.5, 0.8], [1.5, 0.2]]).unwrap();
        let (plus, minus, fraction) = through(&c);
        assert!((fraction - 0.35).abs() < 1e-14, "{fraction}");
        assert!((polygon_area(&minus) - 0.65).abs() < 1e-14);
        // ∫ y² over the part above, against the difference of ∫ y² over the square (1/3)
        // and over the part below (two trapezoids under the tent, computed by hand):
        // below = ∫0^0.5 (0.5 + 0.6x)³/3 dx · 2 = 2 · [(0.8⁴ − 0.5⁴)/(4 · 3 · 0.6)].
        let below = 2.0 * (0.8f64.powi(4) - 0.5f64.powi(4)) / (12.0 * 0.6);
        let above: f64 = polygon_rule(&plus)
            .iter()
            .map(|(x, w)| w * x[1] * x[1])
            .sum();
        assert!((above - (1.0 / 3.0 - below)).abs() < 1e-14, "{above}");
    }

    #[test]
    fn an_element_holding_a_tip_stays_whole_and_a_far_one_is_not_cut() {
        let c = Crack::new("crack", vec![[-1.0, 0.5], [0.5, 0.5]]).unwrap();
        assert_eq!(c.cut(&SQUARE, [false, true]).unwrap(), Cut::Tip);
        let far = SQUARE.map(|p| [p[0] + 3.0, p[1]]);
        assert_eq!(c.cut(&far, [false, true]).unwrap(), Cut::None);
    }

    #[test]
    fn the_parent_map_inverts_a_distorted_quad() {
        let xy = [[0.0, 0.0], [2.0, 0.1], [2.3, 1.7], [-0.2, 1.2]];
        for (xi, eta) in [(0.3, -0.7), (-0.9, 0.9), (0.0, 0.0)] {
            let c = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
            let mut p = [0.0; 2];
            for a in 0..4 {
                let n = 0.25 * (1.0 + xi * c[a][0]) * (1.0 + eta * c[a][1]);
                p[0] += n * xy[a][0];
                p[1] += n * xy[a][1];
            }
            let q = parent_coordinates(&xy, p);
            assert!(
                (q[0] - xi).abs() < 1e-13 && (q[1] - eta).abs() < 1e-13,
                "{q:?}"
            );
        }
    }

    #[test]
    fn bad_polylines_name_their_key() {
        assert!(matches!(
            Crack::new("crack", vec![[0.0, 0.0]]),
            Err(Fem2dError::Config { key, .. }) if key == "crack"
        ));
        assert!(matches!(
            Crack::new("crack", vec![[0.0, 0.0], [0.0, 0.0]]),
            Err(Fem2dError::Config { key, .. }) if key == "crack[1]"
        ));
        assert!(matches!(
            Crack::new("crack", vec![[0.0, 0.0], [f64::NAN, 0.0]]),
            Err(Fem2dError::Config { key, .. }) if key == "crack[1]"
        ));
    }

    // --- The cracked model (`fem2d::Model::cracked`) ---

    use crate::fem2d::{Edge, Material, Mesh, Model, Plane};
    use crate::time::{Gs4, State, Stepper};

    fn glass() -> Material {
        Material {
            young: 74e9,
            poisson: 0.22,
            density: 2480.0,
            thickness: 1e-3,
            plane: Plane::Stress,
        }
    }

    /// A 90 mm square plate of `n` × `n` elements, the bottom edge held, cracked along `crack`.
    fn plate(n: usize, crack: Option<Vec<[f64; 2]>>) -> Model {
        let mesh = Mesh::rectangle([0.0, 0.0], 0.09, 0.09, n, n).unwrap();
        let fixed: Vec<usize> = mesh
            .edge(Edge::Bottom)
            .iter()
            .flat_map(|&i| [2 * i, 2 * i + 1])
            .collect();
        let crack = crack.map(|c| Crack::new("crack", c).unwrap());
        Model::cracked(mesh, glass(), &fixed, crack).unwrap()
    }

    /// Whether all-dof `i` belongs to the field above the crack (side +1).
    fn above(m: &Model, i: usize) -> bool {
        let en = m.crack.as_ref().unwrap();
        let nn = m.mesh.nodes.len();
        if i < 2 * nn {
            en.side[i / 2] > 0.0
        } else {
            let k = (i - 2 * nn) / 2;
            let node = en.phantom.iter().position(|p| *p == Some(k)).unwrap();
            en.side[node] < 0.0
        }
    }

    #[test]
    fn a_crack_across_the_whole_plate_lets_no_force_through() {
        // Crack along y = 45 mm (the middle of element row 4 of 9), beyond both edges: the
        // plate is two bodies. The top edge is pulled up by a step load: the lower body must
        // stay at rest, and the upper one move as a free body, its centre of mass at
        // ½ (F / m) t² with m its own mass (central differences integrate a constant
        // acceleration exactly).
        let m = plate(9, Some(vec![[-0.01, 0.045], [0.1, 0.045]]));
        let en = m.crack.as_ref().unwrap();
        assert_eq!(
            en.phantoms(),
            20,
            "both node rows of the cut elements are enriched"
        );
        let q = 1e5; // N/m on the top edge
        let f_all = m.edge_load(&m.mesh.edge(Edge::Top), [0.0, q]);
        let sys = m.system();
        let mut f = vec![0.0; sys.len()];
        m.restrict(&f_all, &mut f);
        let dt = 0.9 * sys.critical_step_bound();
        let mut st = State::zeros(sys.len());
        sys.acceleration(&st.u.clone(), &st.v.clone(), &f, &mut st.a);
        let mut stepper = Stepper::new(Gs4::central_difference(), dt, &sys).unwrap();
        let steps = 400;
        for _ in 0..steps {
            stepper.step(&sys, &mut st, &f);
        }
        let t = steps as f64 * dt;
        let mut full = vec![0.0; m.dof.len()];
        m.expand(&st.u, &mut full);
        let scale = full.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let (mut below, mut counted) = (0.0f64, 0);
        let (mut mass, mut first) = (0.0, 0.0);
        for (i, x) in full.iter().enumerate() {
            if above(&m, i) {
                if i % 2 == 1 {
                    mass += m.mass[i];
                    first += m.mass[i] * x;
                }
            } else {
                below = below.max(x.abs());
                counted += 1;
            }
        }
        assert_eq!(
            counted,
            2 * (5 * 10 + 10),
            "lower body's dofs: 5 rows and the phantoms"
        );
        assert!(
            below <= 1e-12 * scale,
            "lower body moved {below:e} (scale {scale:e})"
        );
        let rho_t = glass().density * glass().thickness;
        assert!(
            (mass - rho_t * 0.09 * 0.045).abs() <= 1e-12 * mass,
            "upper mass {mass}"
        );
        let expected = 0.5 * (q * 0.09 / mass) * t * t;
        let com = first / mass;
        assert!(
            (com - expected).abs() <= 1e-9 * expected,
            "centre of mass {com:e}, free body {expected:e}"
        );
    }

    #[test]
    fn a_uniform_stress_along_an_inclined_crack_is_in_equilibrium() {
        // σ uniaxial along the crack's direction loads no crack face: the displacement of
        // that uniform strain, the same on both sides, must leave every interior dof (and
        // every phantom) without force.
        let dir = [30f64.to_radians().cos(), 30f64.to_radians().sin()];
        let start = [0.02, 0.0171];
        let crack = vec![start, [start[0] + 0.05 * dir[0], start[1] + 0.05 * dir[1]]];
        let m = plate(6, Some(crack));
        let en = m.crack.as_ref().unwrap();
        assert!(en.phantoms() > 0 && en.tips == [true, true]);
        let (e, nu, sigma) = (74e9, 0.22, 1e8);
        let n = [-dir[1], dir[0]];
        // ε = (σ/E) t⊗t − (νσ/E) n⊗n.
        let eps = |i: usize, j: usize| sigma / e * (dir[i] * dir[j] - nu * n[i] * n[j]);
        let nn = m.mesh.nodes.len();
        let mut u = vec![0.0; m.dof.len()];
        for (k, p) in m.mesh.nodes.iter().enumerate() {
            let val = [0, 1].map(|i| eps(i, 0) * p[0] + eps(i, 1) * p[1]);
            u[2 * k] = val[0];
            u[2 * k + 1] = val[1];
            if let Some(ph) = en.phantom[k] {
                u[2 * nn + 2 * ph] = val[0];
                u[2 * nn + 2 * ph + 1] = val[1];
            }
        }
        let mut f = vec![0.0; u.len()];
        m.stiffness.mul(&u, &mut f);
        let b = m.mesh.bounds();
        let h = 0.09 / 6.0;
        let interior = |k: usize| {
            let p = m.mesh.nodes[k];
            p[0] > b[0] && p[0] < b[2] && p[1] > b[1] && p[1] < b[3]
        };
        let scale = sigma * h * glass().thickness;
        let mut checked = 0;
        for (i, fi) in f.iter().enumerate() {
            let node = if i < 2 * nn {
                i / 2
            } else {
                en.phantom
                    .iter()
                    .position(|p| *p == Some((i - 2 * nn) / 2))
                    .unwrap()
            };
            if interior(node) {
                assert!(
                    fi.abs() <= 1e-10 * scale,
                    "dof {i}: force {fi:e} of {scale:e}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 2 * 25 + 2 * en.phantoms());
        // The crack-face check has teeth: a stress across the crack does load the faces.
        let cross_eps = |i: usize, j: usize| sigma / e * (n[i] * n[j] - nu * dir[i] * dir[j]);
        let mut u2 = vec![0.0; m.dof.len()];
        for (k, p) in m.mesh.nodes.iter().enumerate() {
            let val = [0, 1].map(|i| cross_eps(i, 0) * p[0] + cross_eps(i, 1) * p[1]);
            u2[2 * k] = val[0];
            u2[2 * k + 1] = val[1];
            if let Some(ph) = en.phantom[k] {
                u2[2 * nn + 2 * ph] = val[0];
                u2[2 * nn + 2 * ph + 1] = val[1];
            }
        }
        m.stiffness.mul(&u2, &mut f);
        let largest = (2 * nn..f.len()).map(|i| f[i].abs()).fold(0.0, f64::max);
        assert!(largest > 1e-2 * scale, "{largest:e}");
    }

    /// ω²_max of M⁻¹K over the free dofs, by power iteration (independent of the Gershgorin
    /// bound the model steps with).
    fn omega2(m: &Model) -> f64 {
        let sys = m.system();
        let n = sys.len();
        let mut x: Vec<f64> = (0..n).map(|i| 1.0 + ((i * 7919) % 13) as f64).collect();
        let mut y = vec![0.0; n];
        let mut lambda = 0.0;
        for _ in 0..3000 {
            sys.stiffness.mul(&x, &mut y);
            for (yi, m) in y.iter_mut().zip(&sys.mass) {
                *yi /= m;
            }
            let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
            lambda = norm / x.iter().map(|v| v * v).sum::<f64>().sqrt();
            for (xi, yi) in x.iter_mut().zip(&y) {
                *xi = yi / norm;
            }
        }
        lambda
    }

    #[test]
    fn the_crack_keeps_the_stable_step() {
        // Each side's lumped mass is its share of the element's area, and its stiffness is
        // integrated over the same share: a sliver part is light and soft together, so the
        // critical step of central differences stays that of the uncut mesh, wherever the
        // crack cuts (horizontal: at 1/2 down to 1/1000 of an element's height from a node
        // row; inclined: at 20° through a row, from several offsets): measured 0.977–0.996 of
        // it. The bound the node steps with stays below the true critical step, and within
        // 6 % of the uncut mesh's bound (measured 0.945–1.0).
        let plain = plate(6, None);
        let (w2_plain, bound_plain) = (omega2(&plain), plain.critical_step_bound());
        assert_eq!(
            bound_plain,
            plain.system().critical_step_bound(),
            "an uncut mesh keeps the bound it always had"
        );
        let mut cases = Vec::new();
        for frac in [0.5, 0.2, 0.05, 0.01, 1e-3] {
            let y = 0.03 + frac * 0.015;
            cases.push(vec![[-0.01, y], [0.1, y]]);
        }
        let slope = 20f64.to_radians().tan();
        for y0 in [0.0301, 0.0333, 0.0377] {
            cases.push(vec![[-0.01, y0 - 0.01 * slope], [0.1, y0 + 0.1 * slope]]);
        }
        let mut worst: f64 = 1.0;
        for crack in &cases {
            let m = plate(6, Some(crack.clone()));
            assert!(m.crack.as_ref().unwrap().phantoms() > 0);
            let w2 = omega2(&m);
            let critical = 2.0 / w2.sqrt();
            let bound = m.critical_step_bound();
            let ratio = (w2_plain / w2).sqrt();
            eprintln!(
                "crack {crack:?}: critical step / uncut {ratio:.4}, bound / critical \
                 {:.4}, bound / uncut bound {:.4}",
                bound / critical,
                bound / bound_plain
            );
            assert!(bound <= critical, "the bound must be safe");
            assert!(
                bound >= 0.94 * bound_plain,
                "{bound:e} against {bound_plain:e}"
            );

            worst = worst.min(ratio);
        }
        assert!(
            worst >= 0.95,
            "critical step down to {worst} of the uncut mesh's"
        );
    }

    #[test]
    fn an_edge_crack_opens_across_the_elements_it_crosses_and_its_mouth_splits_the_load() {
        // Seed 001's plate: 9 × 9 elements of 10 mm, a 20 mm crack from the middle of the
        // left edge. Elements 0 and 1 of row 4 are crossed; the tip sits on the edge x = 20
        // mm, whose nodes stay whole (the element beyond holds the tip), so 4 nodes carry a
        // phantom: x = 0 and 10 mm at y = 40 and 50 mm.
        let m = plate(9, Some(vec![[0.0, 0.045], [0.02, 0.045]]));
        let en = m.crack.as_ref().unwrap();
        assert_eq!(en.tips, [false, true]);
        let through: Vec<usize> = (0..81)
            .filter(|&e| matches!(en.cuts[e], Cut::Through { .. }))
            .collect();
        assert_eq!(through, [36, 37]);
        assert_eq!(en.cuts[38], Cut::Tip);
        let enriched: Vec<[f64; 2]> = (0..100)
            .filter(|&i| en.phantom[i].is_some())
            .map(|i| m.mesh.nodes[i].map(|x| (x * 1e3).round()))
            .collect();
        assert_eq!(
            enriched,
            [[0.0, 40.0], [10.0, 40.0], [0.0, 50.0], [10.0, 50.0]]
        );
        // A load on the left edge: the segment the mouth cuts sends each half to its side's
        // field, and the resultant stays q L.
        let q = [2e5, -3e5];
        let f = m.edge_load(&m.mesh.edge(Edge::Left), q);
        for (c, qc) in q.iter().enumerate() {
            let total: f64 = f.iter().skip(c).step_by(2).sum();
            assert!((total - qc * 0.09).abs() <= 1e-12 * (qc * 0.09).abs());
        }
        let nn = m.mesh.nodes.len();
        let phantom_load: f64 = f[2 * nn..].iter().map(|x| x.abs()).sum();
        // On the cut segment (10 mm, mouth at its middle), each node's phantom takes
        // ∫ N over the far half: L/8 of the load, both components.
        let expected = 2.0 * 0.01 / 8.0 * (q[0].abs() + q[1].abs());
        assert!(
            (phantom_load - expected).abs() <= 1e-12 * expected,
            "{phantom_load}"
        );
    }
}
