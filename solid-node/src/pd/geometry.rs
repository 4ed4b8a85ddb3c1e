//! Particle generation on a cubic (3-D) or square (2-D) lattice from simple shapes: boxes,
//! discs/cylinders, hollow cylinders and hollow squares (seed 000 §3.1–3.3), with the
//! particle volume Δx³ (3-D) or Δx²·h (2-D, thickness h).
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use serde::Deserialize;

/// A region of space. In 2-D only x and y matter; in 3-D the round and square shapes are
/// prisms along z of the given `height` centred on `center[2]`.
#[derive(Debug, Clone, PartialEq, Deserialize, schemars::JsonSchema)]
#[serde(tag = "shape", rename_all = "snake_case", deny_unknown_fields)]
pub enum Shape {
    /// An axis-aligned box.
    Box {
        /// Lower corner (m).
        min: [f64; 3],
        /// Upper corner (m).
        max: [f64; 3],
    },
    /// A disc (2-D) or a round prism along z (3-D).
    Disc {
        /// Centre (m).
        center: [f64; 3],
        /// Radius (m).
        radius: f64,
        /// Length along z in 3-D (m).
        #[serde(default)]
        height: f64,
    },
    /// A ring (2-D) or a hollow cylinder along z (3-D).
    HollowCylinder {
        /// Centre (m).
        center: [f64; 3],
        /// Inner radius (m).
        inner_radius: f64,
        /// Outer radius (m).
        outer_radius: f64,
        /// Length along z in 3-D (m).
        #[serde(default)]
        height: f64,
    },
    /// A square with a square hole (2-D), or its prism along z (3-D).
    HollowSquare {
        /// Centre (m).
        center: [f64; 3],
        /// Half side of the hole (m).
        inner_half: f64,
        /// Half side of the outer square (m).
        outer_half: f64,
        /// Length along z in 3-D (m).
        #[serde(default)]
        height: f64,
    },
}

impl Shape {
    /// Whether `p` lies inside (in 2-D, z is ignored).
    pub fn contains(&self, p: &[f64; 3], three_d: bool) -> bool {
        let in_z = |c: &[f64; 3], h: f64| !three_d || (p[2] - c[2]).abs() <= 0.5 * h;
        match self {
            Shape::Box { min, max } => {
                let dims = if three_d { 3 } else { 2 };
                (0..dims).all(|d| p[d] >= min[d] && p[d] <= max[d])
            }
            Shape::Disc {
                center,
                radius,
                height,
            } => {
                let r2 = (p[0] - center[0]).powi(2) + (p[1] - center[1]).powi(2);
                r2 <= radius * radius && in_z(center, *height)
            }
            Shape::HollowCylinder {
                center,
                inner_radius,
                outer_radius,
                height,
            } => {
                let r2 = (p[0] - center[0]).powi(2) + (p[1] - center[1]).powi(2);
                r2 <= outer_radius * outer_radius
                    && r2 >= inner_radius * inner_radius
                    && in_z(center, *height)
            }
            Shape::HollowSquare {
                center,
                inner_half,
                outer_half,
                height,
            } => {
                let m = (p[0] - center[0]).abs().max((p[1] - center[1]).abs());
                m <= *outer_half && m >= *inner_half && in_z(center, *height)
            }
        }
    }

    /// Axis-aligned bounding box (lo, hi).
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        match self {
            Shape::Box { min, max } => (*min, *max),
            Shape::Disc {
                center,
                radius: r,
                height: h,
            }
            | Shape::HollowCylinder {
                center,
                outer_radius: r,
                height: h,
                ..
            }
            | Shape::HollowSquare {
                center,
                outer_half: r,
                height: h,
                ..
            } => (
                [center[0] - r, center[1] - r, center[2] - 0.5 * h],
                [center[0] + r, center[1] + r, center[2] + 0.5 * h],
            ),
        }
    }

    /// Checks the dimensions; on error returns the reason.
    pub fn check(&self, three_d: bool) -> Result<(), String> {
        let pos = |v: f64, what: &str| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("{what} must be > 0, got {v}"))
            }
        };
        let finite = |v: &[f64; 3], what: &str| {
            if v.iter().all(|x| x.is_finite()) {
                Ok(())
            } else {
                Err(format!("{what} must be finite, got {v:?}"))
            }
        };
        match self {
            Shape::Box { min, max } => finite(min, "min").and(finite(max, "max"))?,
            Shape::Disc { center, .. }
            | Shape::HollowCylinder { center, .. }
            | Shape::HollowSquare { center, .. } => finite(center, "center")?,
        }
        match self {
            Shape::Box { min, max } => {
                let dims = if three_d { 3 } else { 2 };
                for d in 0..dims {
                    if !(max[d] > min[d]) {
                        return Err(format!("box max[{d}] must exceed min[{d}]"));
                    }
                }
                Ok(())
            }
            Shape::Disc { radius, height, .. } => {
                pos(*radius, "radius")?;
                if three_d {
                    pos(*height, "height")
                } else {
                    Ok(())
                }
            }
            Shape::HollowCylinder {
                inner_radius,
                outer_radius,
                height,
                ..
            } => {
                pos(*outer_radius, "outer_radius")?;
                if !(*inner_radius >= 0.0 && inner_radius < outer_radius) {
                    return Err("inner_radius must be in [0, outer_radius)".into());
                }
                if three_d {
                    pos(*height, "height")
                } else {
                    Ok(())
                }
            }
            Shape::HollowSquare {
                inner_half,
                outer_half,
                height,
                ..
            } => {
                pos(*outer_half, "outer_half")?;
                if !(*inner_half >= 0.0 && inner_half < outer_half) {
                    return Err("inner_half must be in [0, outer_half)".into());
                }
                if three_d {
                    pos(*height, "height")
                } else {
                    Ok(())
                }
            }
        }
    }
}

/// Lattice points (cell centres of a grid of spacing `dx` anchored at the body's bounding-box
/// corner) inside any of `bodies` and outside all `holes`. Deterministic order: z, y, x.
pub fn lattice(bodies: &[Shape], holes: &[Shape], dx: f64, three_d: bool) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    each_lattice_point(bodies, holes, dx, three_d, |p| out.push(p));
    out
}

/// How many points [`lattice`] gives, without storing them (the size check before a body
/// is built).
pub fn lattice_count(bodies: &[Shape], holes: &[Shape], dx: f64, three_d: bool) -> usize {
    let mut n = 0;
    each_lattice_point(bodies, holes, dx, three_d, |_| n += 1);
    n
}

/// Calls `f` on each point of [`lattice`], in its order.
fn each_lattice_point(
    bodies: &[Shape],
    holes: &[Shape],
    dx: f64,
    three_d: bool,
    mut f: impl FnMut([f64; 3]),
) {
    for body in bodies {
        let (lo, hi) = body.bounds();
        let n = |d: usize| ((hi[d] - lo[d]) / dx + 1e-9).floor().max(0.0) as usize;
        let (nx, ny) = (n(0), n(1));
        let nz = if three_d { n(2) } else { 1 };
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let p = [
                        lo[0] + (i as f64 + 0.5) * dx,
                        lo[1] + (j as f64 + 0.5) * dx,
                        if three_d {
                            lo[2] + (k as f64 + 0.5) * dx
                        } else {
                            0.0
                        },
                    ];
                    if body.contains(&p, three_d) && !holes.iter().any(|h| h.contains(&p, three_d))
                    {
                        f(p);
                    }
                }
            }
        }
    }
}

/// The 31³-style benchmark block: `n` particles a side, spacing `dx`, origin at 0.
pub fn cube_lattice(n: usize, dx: f64) -> Vec<[f64; 3]> {
    let mut out = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                out.push([i as f64 * dx, j as f64 * dx, k as f64 * dx]);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_lattice_counts_and_volume() {
        let b = Shape::Box {
            min: [0.0; 3],
            max: [1.0, 0.5, 0.25],
        };
        let p = lattice(&[b], &[], 0.05, true);
        assert_eq!(p.len(), 20 * 10 * 5);
        // Total volume equals the box volume exactly on a matching lattice.
        let v: f64 = p.len() as f64 * 0.05f64.powi(3);
        assert!((v - 0.125).abs() < 1e-12);
    }

    #[test]
    fn hollow_cylinder_area_converges() {
        let s = Shape::HollowCylinder {
            center: [0.0; 3],
            inner_radius: 0.07,
            outer_radius: 0.1,
            height: 0.0,
        };
        let dx = 0.001;
        let p = lattice(&[s], &[], dx, false);
        let area = p.len() as f64 * dx * dx;
        let exact = std::f64::consts::PI * (0.1f64.powi(2) - 0.07f64.powi(2));
        assert!((area - exact).abs() / exact < 0.01, "{area} vs {exact}");
    }

    /// Every generator in 2-D and 3-D: the particles lie inside their shape and outside the
    /// holes, and count × cell volume converges to the analytic measure (1 % at these
    /// resolutions, the lattice's staircase error on curved faces).
    #[test]
    fn every_shape_fills_its_measure_in_2d_and_3d() {
        use std::f64::consts::PI;
        let c = [0.01, -0.02, 0.005];
        let (dx, h) = (0.002, 0.04);
        let cases: Vec<(Shape, f64)> = vec![
            (
                Shape::Disc {
                    center: c,
                    radius: 0.1,
                    height: h,
                },
                PI * 0.01,
            ),
            (
                Shape::HollowCylinder {
                    center: c,
                    inner_radius: 0.05,
                    outer_radius: 0.1,
                    height: h,
                },
                PI * (0.01 - 0.0025),
            ),
            (
                Shape::HollowSquare {
                    center: c,
                    inner_half: 0.03,
                    outer_half: 0.1,
                    height: h,
                },
                4.0 * (0.01 - 0.0009),
            ),
        ];
        let hole = Shape::Box {
            min: [0.05, -0.2, -1.0],
            max: [0.2, 0.2, 1.0],
        };
        for (shape, area) in cases {
            for three_d in [false, true] {
                let p = lattice(std::slice::from_ref(&shape), &[], dx, three_d);
                assert!(p.iter().all(|q| shape.contains(q, three_d)), "{shape:?}");
                let (cell, exact) = if three_d {
                    (dx * dx * dx, area * h)
                } else {
                    (dx * dx, area)
                };
                let measure = p.len() as f64 * cell;
                assert!(
                    (measure - exact).abs() / exact < 0.01,
                    "{shape:?} 3-D {three_d}: {measure} vs {exact}"
                );
                // a hole removes its particles and nothing else
                let cut = lattice(
                    std::slice::from_ref(&shape),
                    std::slice::from_ref(&hole),
                    dx,
                    three_d,
                );
                let kept = p.iter().filter(|q| !hole.contains(q, three_d)).count();
                assert!(cut.len() == kept && kept < p.len(), "{shape:?}: the hole");
            }
        }
    }
}
