//! Interface mapping on non-matching meshes (docs/architecture.md, "Mapping"): the interface power
//! `Σ f_d·v_d = Σ f_r·v_r` to round-off, total force preserved (rows of `W` sum to one), moment
//! preserved when the responder lies on a planar driver, and exact reproduction of linear fields
//! by the consistent map on line, triangle and (distorted) quad meshes.

use protocol::mapping::Mapping;
use protocol::{CellKind, Cells, InterfaceMesh};

/// splitmix64: deterministic test data without a dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.next()
    }
    fn vec(&mut self, n: usize) -> Vec<f64> {
        (0..n).map(|_| self.range(-1.0, 1.0)).collect()
    }
}

/// A surface patch over `(u, v) ∈ [0, 1]²`.
type Surface = fn(f64, f64) -> [f64; 3];

/// Tilted plane through (0.3, -0.2, 1) with unit in-plane axes (0.6, 0, 0.8), (0, 1, 0) scaled
/// to a 2 × 1.5 patch.
fn tilted_plane(u: f64, v: f64) -> [f64; 3] {
    [0.3 + 1.2 * u, -0.2 + 1.5 * v, 1.0 + 1.6 * u]
}

/// Curved: a cylinder sector (radius 1, 90°) with an added twist, so quads are warped.
fn curved(u: f64, v: f64) -> [f64; 3] {
    let th = 1.5 * u + 0.3 * u * v;
    [th.cos(), th.sin(), 2.0 * v + 0.2 * u * u]
}

/// Structured `nx × ny` mesh of the surface (`Quad`, split `Triangle`, or a `Line` along `v = 0`),
/// interior nodes jittered in `(u, v)` by up to `jitter` of a cell (boundary nodes stay on the
/// patch edges, so the mesh covers the whole patch).
fn driver_mesh(
    s: Surface,
    nx: usize,
    ny: usize,
    kind: CellKind,
    jitter: f64,
    rng: &mut Rng,
) -> InterfaceMesh {
    let mut x = Vec::new();
    let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut conn = Vec::new();
    if kind == CellKind::Line {
        for i in 0..=nx {
            let mut u = i as f64 / nx as f64;
            if i > 0 && i < nx {
                u += jitter * rng.range(-1.0, 1.0) / nx as f64;
            }
            x.push(s(u, 0.0));
        }
        for i in 0..nx {
            conn.extend_from_slice(&[i as u32, i as u32 + 1]);
        }
    } else {
        for j in 0..=ny {
            for i in 0..=nx {
                let (mut u, mut v) = (i as f64 / nx as f64, j as f64 / ny as f64);
                if i > 0 && i < nx && j > 0 && j < ny {
                    u += jitter * rng.range(-1.0, 1.0) / nx as f64;
                    v += jitter * rng.range(-1.0, 1.0) / ny as f64;
                }
                x.push(s(u, v));
            }
        }
        for j in 0..ny {
            for i in 0..nx {
                let q = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
                if kind == CellKind::Quad {
                    conn.extend_from_slice(&q);
                } else {
                    conn.extend_from_slice(&[q[0], q[1], q[2], q[0], q[2], q[3]]);
                }
            }
        }
    }
    let mut m = InterfaceMesh::points(x);
    m.cells = Some(Cells {
        kind,
        connectivity: conn,
    });
    m
}

/// `nx × ny` responder points on the surface over `[-margin, 1 + margin]²` (the margin puts
/// some outside the driver mesh), plus a small normal-ish offset noise.
fn responder_cloud(s: Surface, nx: usize, ny: usize, margin: f64, rng: &mut Rng) -> Vec<[f64; 3]> {
    let mut pts = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let u = -margin + (1.0 + 2.0 * margin) * i as f64 / (nx - 1) as f64;
            let v = -margin + (1.0 + 2.0 * margin) * j as f64 / (ny - 1) as f64;
            let p = s(u, v);
            pts.push([
                p[0] + 1e-3 * rng.range(-1.0, 1.0),
                p[1] + 1e-3 * rng.range(-1.0, 1.0),
                p[2] + 1e-3 * rng.range(-1.0, 1.0),
            ]);
        }
    }
    pts
}

/// Power on both sides for random `v_d`, `f_r` (3 components); returns the relative mismatch
/// `|P_d − P_r| / Σ_j |f_r,j|·|v_r,j|` and the relative total-force mismatch.
fn power_and_force(m: &Mapping, rng: &mut Rng) -> (f64, f64) {
    let (nd, nr) = (m.n_driver(), m.n_responder());
    let v_d = rng.vec(3 * nd);
    let f_r = rng.vec(3 * nr);
    let mut v_r = vec![0.0; 3 * nr];
    let mut f_d = vec![0.0; 3 * nd];
    m.map_motion(&v_d, 3, &mut v_r).unwrap();
    m.map_load(&f_r, 3, &mut f_d).unwrap();
    let p_d: f64 = f_d.iter().zip(&v_d).map(|(f, v)| f * v).sum();
    let p_r: f64 = f_r.iter().zip(&v_r).map(|(f, v)| f * v).sum();
    let scale: f64 = f_r.iter().zip(&v_r).map(|(f, v)| (f * v).abs()).sum();
    let mut force_err: f64 = 0.0;
    for c in 0..3 {
        let sd: f64 = f_d.iter().skip(c).step_by(3).sum();
        let sr: f64 = f_r.iter().skip(c).step_by(3).sum();
        let mag: f64 = f_r.iter().skip(c).step_by(3).map(|f| f.abs()).sum();
        force_err = force_err.max((sd - sr).abs() / mag);
    }
    ((p_d - p_r).abs() / scale, force_err)
}

#[test]
fn mapping_interface_power_and_force_are_preserved_on_non_matching_meshes() {
    let mut rng = Rng(2026);
    let mut worst_power: f64 = 0.0;
    let mut worst_force: f64 = 0.0;
    for (name, s) in [
        ("tilted plane", tilted_plane as Surface),
        ("curved", curved as Surface),
    ] {
        let cloud = responder_cloud(s, 13, 9, 0.05, &mut rng);
        for kind in [CellKind::Quad, CellKind::Triangle, CellKind::Line] {
            let driver = driver_mesh(s, 7, 5, kind, 0.25, &mut rng);
            for (how, m) in [
                ("consistent", Mapping::consistent(&driver, &cloud).unwrap()),
                ("nearest", Mapping::nearest(&driver, &cloud).unwrap()),
            ] {
                assert_eq!((m.n_driver(), m.n_responder()), (driver.len(), 13 * 9));
                let defect = m.max_row_sum_defect();
                assert!(
                    defect <= 4.0 * f64::EPSILON,
                    "{name} {kind:?} {how}: rows {defect:e}"
                );
                let (p, f) = power_and_force(&m, &mut rng);
                eprintln!(
                    "{name:12} {kind:8?} {how:10}: |ΔP|/P = {p:.2e}, |ΔF|/F = {f:.2e}, row-sum defect {defect:.1e}"
                );
                assert!(p < 1e-13, "{name} {kind:?} {how}: power mismatch {p:e}");
                assert!(f < 1e-13, "{name} {kind:?} {how}: force mismatch {f:e}");
                worst_power = worst_power.max(p);
                worst_force = worst_force.max(f);
            }
        }
    }
    eprintln!("worst relative power mismatch {worst_power:.2e}, force {worst_force:.2e}");
}

#[test]
fn mapping_moment_is_preserved_when_the_responder_lies_on_a_planar_driver() {
    // Responder strictly inside a jittered planar quad mesh: W x_d = x_r, hence
    // Σ x_d × f_d = Σ x_r × f_r.
    let mut rng = Rng(99);
    let driver = driver_mesh(tilted_plane, 7, 5, CellKind::Quad, 0.3, &mut rng);
    let cloud: Vec<[f64; 3]> = (0..117)
        .map(|_| tilted_plane(rng.range(0.0, 1.0), rng.range(0.0, 1.0)))
        .collect();
    let m = Mapping::consistent(&driver, &cloud).unwrap();
    let f_r = rng.vec(3 * cloud.len());
    let mut f_d = vec![0.0; 3 * driver.len()];
    m.map_load(&f_r, 3, &mut f_d).unwrap();
    let moment = |x: &[[f64; 3]], f: &[f64]| {
        let mut mo = [0.0; 3];
        for (p, f) in x.iter().zip(f.chunks_exact(3)) {
            mo[0] += p[1] * f[2] - p[2] * f[1];
            mo[1] += p[2] * f[0] - p[0] * f[2];
            mo[2] += p[0] * f[1] - p[1] * f[0];
        }
        mo
    };
    let (md, mr) = (moment(&driver.positions, &f_d), moment(&cloud, &f_r));
    let scale: f64 = f_r.iter().map(|f| f.abs()).sum::<f64>() * 3.0;
    let err = (0..3).map(|c| (md[c] - mr[c]).abs()).fold(0.0, f64::max) / scale;
    eprintln!("moment mismatch (relative to Σ|x||f|) {err:.2e}");
    assert!(err < 1e-14, "moment mismatch {err:e}");
}

/// Maps `f(x) = a + b·x` from the driver nodes to the responder points and returns the largest
/// error relative to max |f|.
fn linear_error(driver: &InterfaceMesh, pts: &[[f64; 3]]) -> f64 {
    let field = |x: &[f64; 3]| 0.7 - 1.3 * x[0] + 2.1 * x[1] + 0.4 * x[2];
    let f_d: Vec<f64> = driver.positions.iter().map(field).collect();
    let m = Mapping::consistent(driver, pts).unwrap();
    let mut f_r = vec![0.0; pts.len()];
    m.map_motion(&f_d, 1, &mut f_r).unwrap();
    let fmax = f_d.iter().fold(0.0f64, |a, f| a.max(f.abs()));
    pts.iter()
        .zip(&f_r)
        .map(|(x, f)| (f - field(x)).abs() / fmax)
        .fold(0.0, f64::max)
}

#[test]
fn mapping_consistent_map_reproduces_linear_fields_exactly() {
    let mut rng = Rng(31);
    for kind in [CellKind::Line, CellKind::Triangle, CellKind::Quad] {
        let driver = driver_mesh(tilted_plane, 7, 5, kind, 0.35, &mut rng);
        let pts: Vec<[f64; 3]> = (0..300)
            .map(|_| {
                let v = if kind == CellKind::Line {
                    0.0
                } else {
                    rng.range(0.0, 1.0)
                };
                tilted_plane(rng.range(0.0, 1.0), v)
            })
            .collect();
        let err = linear_error(&driver, &pts);
        eprintln!("linear field, {kind:?} mesh: max relative error {err:.2e}");
        assert!(err < 1e-14, "{kind:?}: {err:e}");
    }

    // One strongly distorted quad (a general convex quadrilateral, no two sides parallel) in
    // 3D; points sampled over its bilinear image.
    let x = vec![
        [0.0, 0.0, 0.0],
        [3.0, 0.4, 1.2],
        [2.2, 2.5, 0.88],
        [-0.4, 1.3, -0.16],
    ];
    // All four lie on the plane z = 0.4 x (a tilt), so linear reproduction is exact.
    let mut quad = InterfaceMesh::points(x.clone());
    quad.cells = Some(Cells {
        kind: CellKind::Quad,
        connectivity: vec![0, 1, 2, 3],
    });
    let pts: Vec<[f64; 3]> = (0..300)
        .map(|_| {
            let (xi, eta) = (rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
            let n = [
                0.25 * (1.0 - xi) * (1.0 - eta),
                0.25 * (1.0 + xi) * (1.0 - eta),
                0.25 * (1.0 + xi) * (1.0 + eta),
                0.25 * (1.0 - xi) * (1.0 + eta),
            ];
            let mut p = [0.0; 3];
            for k in 0..4 {
                for d in 0..3 {
                    p[d] += n[k] * x[k][d];
                }
            }
            p
        })
        .collect();
    let err = linear_error(&quad, &pts);
    eprintln!("linear field, single distorted quad: max relative error {err:.2e}");
    assert!(err < 1e-14, "distorted quad: {err:e}");
}

#[test]
fn mapping_nearest_neighbour_transfers_node_values_on_refined_copy() {
    // Responder = driver nodes shuffled and displaced by less than half the spacing: each
    // responder point must take exactly its source node's value and the load map must return
    // each force to that node.
    let mut rng = Rng(4);
    let driver = driver_mesh(curved, 7, 5, CellKind::Quad, 0.0, &mut rng);
    let n = driver.len();
    let perm: Vec<usize> = (0..n).map(|k| (k * 17 + 5) % n).collect();
    let pts: Vec<[f64; 3]> = perm
        .iter()
        .map(|&i| {
            let p = driver.positions[i];
            [
                p[0] + 0.01 * rng.range(-1.0, 1.0),
                p[1],
                p[2] - 0.01 * rng.range(-1.0, 1.0),
            ]
        })
        .collect();
    let m = Mapping::nearest(&driver, &pts).unwrap();
    let v_d: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let mut v_r = vec![0.0; n];
    m.map_motion(&v_d, 1, &mut v_r).unwrap();
    let expected: Vec<f64> = perm.iter().map(|&i| i as f64).collect();
    assert_eq!(v_r, expected);
    let mut back = vec![0.0; n];
    m.map_load(&v_r, 1, &mut back).unwrap();
    assert_eq!(back, v_d);
}

/// Construction cost at scale (prints timings, asserts only correctness): run with
/// `cargo test --release -p protocol --test mapping_power -- --ignored --nocapture`.
#[test]
#[ignore]
fn mapping_large_mesh_construction() {
    let mut rng = Rng(1);
    let driver = driver_mesh(curved, 300, 200, CellKind::Quad, 0.2, &mut rng);
    let cloud = responder_cloud(curved, 450, 300, 0.01, &mut rng);
    let t = std::time::Instant::now();
    let m = Mapping::consistent(&driver, &cloud).unwrap();
    let tc = t.elapsed();
    let t = std::time::Instant::now();
    let mn = Mapping::nearest(&driver, &cloud).unwrap();
    let tn = t.elapsed();
    let mut v_r = vec![0.0; 3 * cloud.len()];
    let v_d = rng.vec(3 * driver.len());
    let t = std::time::Instant::now();
    m.map_motion(&v_d, 3, &mut v_r).unwrap();
    let ta = t.elapsed();
    eprintln!(
        "driver {} quads / {} nodes, responder {} points: consistent {tc:?}, nearest {tn:?}, map_motion(3) {ta:?}",
        300 * 200,
        driver.len(),
        cloud.len()
    );
    let (p, f) = power_and_force(&m, &mut rng);
    let (pn, fn_) = power_and_force(&mn, &mut rng);
    eprintln!("power {p:.2e} / {pn:.2e}, force {f:.2e} / {fn_:.2e}");
    assert!(p < 1e-12 && f < 1e-12 && pn < 1e-12 && fn_ < 1e-12);
}
