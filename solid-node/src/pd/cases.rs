//! Reference fracture set-ups shared by the examples and their coarse test variants
//! (the README's case sections "Solid node"): the Kalthoff–Winkler plate.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use super::bond::BondModel;
use super::family::Bonds;
use super::fracture::{CrackFit, crack_angle, critical_stretch_for_energy};
use super::geometry::{Shape, lattice};
use super::integrate::Body;
use super::model::{Dim, Kinematics};

/// Kalthoff–Winkler plate (Kalthoff & Winkler 1988; Silling 2003): maraging steel
/// E 191 GPa, ρ 8000 kg/m³, 2-D plane stress (bond-based, ν = 1/3), thickness 9 mm.
/// The plate is 100 mm wide (x, the notch direction) and 200 mm tall (y); two notches
/// 50 mm long, 1.5 mm wide, from the impacted edge x = 0 at y = 75 and 125 mm; the edge
/// between them is driven at `speed` (16 m/s: half the 32 m/s of the equal-impedance
/// projectile).
#[derive(Debug, Clone, Copy)]
pub struct KalthoffWinkler {
    pub dx: f64,
    pub speed: f64,
    /// Fracture energy G0 (J/m²); K_Ic ≈ 68 MPa√m gives K²/E ≈ 24 kJ/m².
    pub g0: f64,
    pub end_time: f64,
}

pub const KW_E: f64 = 191e9;
pub const KW_RHO: f64 = 8000.0;
pub const KW_H: f64 = 9e-3;
pub const KW_WIDTH: f64 = 0.1;
pub const KW_HEIGHT: f64 = 0.2;
pub const KW_NOTCH: f64 = 0.05;
pub const KW_NOTCH_W: f64 = 1.5e-3;
/// Notch centre lines.
pub const KW_Y: [f64; 2] = [0.075, 0.125];

impl Default for KalthoffWinkler {
    fn default() -> Self {
        KalthoffWinkler {
            dx: 1e-3,
            speed: 16.0,
            g0: 22.17e3,
            end_time: 90e-6,
        }
    }
}

impl KalthoffWinkler {
    /// The body at rest with the impact region prescribed, and the critical stretch used.
    pub fn build(&self) -> (Body, f64) {
        let dx = self.dx;
        let delta = 3.015 * dx;
        let bodies = [Shape::Box {
            min: [0.0; 3],
            max: [KW_WIDTH, KW_HEIGHT, KW_H],
        }];
        let holes: Vec<Shape> = KW_Y
            .iter()
            .map(|&y| Shape::Box {
                min: [-1.0, y - 0.5 * KW_NOTCH_W, -1.0],
                max: [KW_NOTCH, y + 0.5 * KW_NOTCH_W, 1.0],
            })
            .collect();
        let x0 = lattice(&bodies, &holes, dx, false);
        let vol = vec![dx * dx * KW_H; x0.len()];
        let bonds = Bonds::build(&x0, delta);
        let zero = vec![[0.0; 3]; x0.len()];
        let k = Kinematics {
            x0: &x0,
            pos: &x0,
            disp: &zero,
            vel: &zero,
            vol: &vol,
        };
        // s0 from G0 on this lattice with this influence function (the closed form
        // √(4πG0/(9Eδ)) belongs to ω = 1 and a continuum family): cut through the bulk
        // below the lower notch, away from the edges.
        let elastic = BondModel::new(Dim::PlaneStress, KW_E, delta, KW_H, None, &k, &bonds);
        let y_cut = (0.03 / dx).round() * dx;
        let s0 = critical_stretch_for_energy(
            self.g0,
            &x0,
            &vol,
            &bonds,
            &elastic.coef,
            y_cut,
            0.3 * KW_WIDTH,
            0.7 * KW_WIDTH,
            KW_H,
        );
        let model = BondModel::new(Dim::PlaneStress, KW_E, delta, KW_H, Some(s0), &k, &bonds);
        let mut b = Body::new(
            Dim::PlaneStress,
            dx,
            delta,
            KW_RHO,
            x0,
            vol,
            bonds,
            Box::new(model),
        );
        // Impact: the three columns at the edge between the notches.
        for i in 0..b.len() {
            let p = b.x0[i];
            if p[0] < 3.0 * dx && p[1] > KW_Y[0] && p[1] < KW_Y[1] {
                b.prescribed[i] = 1;
                b.vpres[i] = [self.speed, 0.0, 0.0];
                b.vel[i] = [self.speed, 0.0, 0.0];
            }
        }
        (b, s0)
    }

    /// Runs to `end_time` at 0.8 of the stable step.
    pub fn run(&self, b: &mut Body) -> usize {
        let dt = 0.8 * b.stable_dt();
        let steps = (self.end_time / dt).ceil() as usize;
        for _ in 0..steps {
            b.step(dt);
        }
        steps
    }

    /// Crack angles from the upper and lower notch tips: damaged particles (φ ≥ 0.35)
    /// between 3δ and `r_max` from the tip, line fit through the tip (see
    /// [`crack_angle`]); the lower crack is mirrored so both report the angle to +x.
    pub fn measure(&self, x0: &[[f64; 3]], damage: &[f64], r_max: f64) -> [Option<CrackFit>; 2] {
        let r_min = 3.0 * 3.015 * self.dx;
        [
            crack_angle(x0, damage, [KW_NOTCH, KW_Y[1]], 1.0, 0.35, r_min, r_max),
            crack_angle(x0, damage, [KW_NOTCH, KW_Y[0]], -1.0, 0.35, r_min, r_max),
        ]
    }
}

/// Seed 000 §3.2 brittle hollow cylinder, loaded by a prescribed internal pressure pulse
/// instead of the detonation gas: inner radius 7 cm, outer 10 cm, E 200 GPa, ν 0.29,
/// ρ 7870 kg/m³, brittle von Mises bond breaking at σ_cr = 3 GPa (App. C), pd-correspondence
/// in plane strain (unit thickness), δ = 3.015 Δx.
#[derive(Debug, Clone, Copy)]
pub struct HollowCylinder {
    pub dx: f64,
    /// Pulse peak pressure (Pa), rise and total duration (s).
    pub peak: f64,
    pub rise: f64,
    pub duration: f64,
}

impl Default for HollowCylinder {
    fn default() -> Self {
        HollowCylinder {
            dx: 1e-3,
            peak: 2e9,
            rise: 5e-6,
            duration: 60e-6,
        }
    }
}

/// What a hollow-cylinder run reports.
#[derive(Debug, Clone)]
pub struct CylinderReport {
    /// Time of the first bond break (s) and the reference radii of the particles damaged
    /// in that first window.
    pub first_break: Option<(f64, Vec<f64>)>,
    /// Fragment sizes (components of ≥ `min_size` particles) at the end.
    pub fragments: Vec<usize>,
    /// Particles in components smaller than `min_size` (debris).
    pub debris: usize,
    pub windows: u64,
}

impl HollowCylinder {
    /// The node parameter table (what a case file's `[nodes.X.params]` holds).
    pub fn params(&self) -> String {
        format!(
            r#"dimension = "plane_strain"
thickness = 1.0
spacing = {dx:e}
horizon = {h:e}
density = 7870.0
young = 200e9
poisson = 0.29
damage = {{ kind = "von_mises", critical_stress = 3e9 }}
bodies = [{{ shape = "hollow_cylinder", center = [0.0, 0.0, 0.0], inner_radius = 0.07, outer_radius = 0.1 }}]
pressure_pulse = {{ surface = "inner", center = [0.0, 0.0, 0.0], inner_radius = 0.07, peak = {p:e}, rise = {r:e}, duration = {d:e} }}
"#,
            dx = self.dx,
            h = 3.015 * self.dx,
            p = self.peak,
            r = self.rise,
            d = self.duration,
        )
    }

    /// Runs the node through `windows` windows of `window` seconds (output directory: VTK
    /// every `vtk_every` windows when given) and counts fragments of ≥ `min_size` particles.
    pub fn run(
        &self,
        windows: u64,
        window: f64,
        min_size: usize,
        vtk: Option<(&std::path::Path, u64)>,
    ) -> Result<(super::solver::PdSolver, CylinderReport), protocol::SolverError> {
        use protocol::{Inbox, Outbox, Solver, Window};
        let table: toml::Table = toml::from_str(&self.params())
            .map_err(|e| protocol::SolverError::config("params", e.to_string()))?;
        let mut s = super::solver::PdSolver::from_table("pd-correspondence", &table)?;
        s.setup(&[], &Inbox::new(), &mut Outbox::new())?;
        let (inbox, mut out) = (Inbox::new(), Outbox::new());
        let mut first_break = None;
        for w in 0..windows {
            let win = Window {
                index: w + 1,
                t0: w as f64 * window,
                t1: (w + 1) as f64 * window,
                write_output: false,
            };
            s.advance(&win, &inbox, &mut out)?;
            if first_break.is_none() {
                let d = s.body.damage();
                let radii: Vec<f64> = (0..d.len())
                    .filter(|&i| d[i] > 0.0)
                    .map(|i| s.body.x0[i][0].hypot(s.body.x0[i][1]))
                    .collect();
                if !radii.is_empty() {
                    first_break = Some((win.t1, radii));
                }
            }
            if let Some((dir, every)) = vtk
                && (w + 1) % every == 0
            {
                s.write_output(win.t1, w + 1, dir)?;
            }
        }
        let (fragments, debris) = s.fragments(min_size);
        Ok((
            s,
            CylinderReport {
                first_break,
                fragments,
                debris,
                windows,
            },
        ))
    }
}

/// The benchmark block of `cosim bench`: an `n³` cubic lattice, Δx 1 mm,
/// δ = 3.015 Δx (122-member interior families), steel (E 200 GPa, ρ 7850, J2 σy 500 MPa,
/// H 1 GPa for the correspondence models), critical stretch 0.01 so the damage check runs,
/// and a smooth non-trivial velocity field so every bond does real work.
pub struct BenchmarkBlock {
    pub body: Body,
    /// The bond model itself for `pd-bond` (what the GPU body is built from).
    pub bond: Option<BondModel>,
    /// Bytes of the model's own arrays (bond coefficients, or the correspondence model's
    /// per-particle kinematics and state and per-bond data); `None` for `pd-rk-ba`.
    pub model_bytes: Option<usize>,
}

/// See [`BenchmarkBlock`]; `model` is `pd-bond`, `pd-correspondence` or `pd-rk-ba` (order 2).
pub fn benchmark_block(n: usize, model: &str) -> Result<BenchmarkBlock, String> {
    use super::correspondence::Correspondence;
    use super::geometry::cube_lattice;
    use super::model::PdModel;
    use super::rk_ba::RkBa;
    use mechanics::damage::CriticalStretch;
    use mechanics::j2::J2Material;
    let dx = 1e-3;
    let horizon = 3.015 * dx;
    let x0 = cube_lattice(n, dx);
    let vol = vec![dx * dx * dx; x0.len()];
    let bonds = Bonds::build(&x0, horizon);
    let v0 = vec![[0.0; 3]; x0.len()];
    let k = Kinematics {
        x0: &x0,
        pos: &x0,
        disp: &v0,
        vel: &v0,
        vol: &vol,
    };
    let (e, rho) = (200e9, 7850.0);
    let mat = J2Material {
        young: e,
        poisson: 0.3,
        yield_stress: 500e6,
        iso_hardening: 1e9,
        kin_hardening: 0.0,
    };
    let stretch = CriticalStretch {
        critical_stretch: 0.01,
    };
    let (m, bond, model_bytes): (Box<dyn PdModel>, _, _) = match model {
        "pd-bond" => {
            let m = BondModel::new(Dim::Three, e, horizon, 1.0, Some(0.01), &k, &bonds);
            let bytes = std::mem::size_of_val(&m.coef[..]);
            (Box::new(m.clone()), Some(m), Some(bytes))
        }
        "pd-correspondence" => {
            let m = Correspondence::new(Dim::Three, mat, 0.5, horizon, 1.0, stretch, &k, &bonds);
            let bytes = std::mem::size_of_val(&m.state[..])
                + std::mem::size_of_val(&m.kin[..])
                + std::mem::size_of_val(&m.side[..]);
            (Box::new(m), None, Some(bytes))
        }
        "pd-rk-ba" => (
            Box::new(RkBa::new(Dim::Three, 2, horizon, mat, stretch, &bonds)),
            None,
            None,
        ),
        o => return Err(format!("no benchmark block for model '{o}'")),
    };
    let mut body = Body::new(Dim::Three, dx, horizon, rho, x0, vol, bonds, m);
    for i in 0..body.len() {
        let x = body.x0[i];
        body.vel[i] = [
            5.0 * (x[1] * 200.0).sin(),
            -3.0 * (x[2] * 150.0).cos(),
            2.0 * (x[0] * 300.0).sin(),
        ];
    }
    Ok(BenchmarkBlock {
        body,
        bond,
        model_bytes,
    })
}
