//! The 1-D elastic bar (`bar-1d`): a lumped-mass spring chain advanced by central
//! differences. For a one-spacing horizon this is also the peridynamic bar operator of
//! seed 001 §5.2 (eq. 196–201). Either end may be fixed, loaded by a step force, or be a
//! coupling interface (ARCHITECTURE §5, kinematic: driver or responder).
//!
//! Time stepping (central difference, velocities at half steps):
//! `a_n = M⁻¹ (f_int(u_n) + f_ext + f_coupling)`, `v_{n+1/2} = v_{n-1/2} + Δt a_n`,
//! `u_{n+1} = u_n + Δt v_{n+1/2}`.

use protocol::{
    Binding, InterfaceMesh, Role, Solver, SolverError, SolverResult, StepReport, Window,
};
use protocol::{Inbox, InterfaceInfo, NodeDescription, Outbox};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Parameters of `bar-1d`, as in the case file's `[nodes.<name>.params]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BarParams {
    /// Bar length (m).
    pub length: f64,
    /// Position of the left end (m); interface positions are reported from it.
    #[serde(default)]
    pub x0: f64,
    pub elements: usize,
    /// Young's modulus (Pa).
    pub young: f64,
    /// Density (kg/m³).
    pub density: f64,
    /// Cross-section (m²).
    pub area: f64,
    /// Which end is fixed: "left", "right" or "none".
    #[serde(default = "default_fixed")]
    pub fixed: String,
    /// Step force (N) applied from t = 0 at `load_end`.
    #[serde(default)]
    pub tip_force: f64,
    /// "left", "right" or "none".
    #[serde(default = "default_load_end")]
    pub load_end: String,
    /// Fraction of the critical step used (≤ 1).
    #[serde(default = "default_courant")]
    pub courant: f64,
    /// Interface names → end ("left" | "right").
    #[serde(default)]
    pub interfaces: BTreeMap<String, String>,
}

/// Most elements a bar takes (its arrays must fit in memory).
pub const MAX_ELEMENTS: usize = 100_000_000;

fn default_fixed() -> String {
    "left".into()
}
fn default_load_end() -> String {
    "right".into()
}
fn default_courant() -> f64 {
    0.9
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum End {
    Left,
    Right,
}

fn parse_end(key: &str, s: &str, allow_none: bool) -> SolverResult<Option<End>> {
    match s {
        "left" => Ok(Some(End::Left)),
        "right" => Ok(Some(End::Right)),
        "none" if allow_none => Ok(None),
        other => Err(SolverError::config(
            key,
            format!(
                "must be \"left\", \"right\"{}, got \"{other}\"",
                if allow_none { " or \"none\"" } else { "" }
            ),
        )),
    }
}

fn check_positive(key: &str, v: f64) -> SolverResult<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(SolverError::config(key, format!("must be > 0, got {v}")))
    }
}

/// What the bar does at one coupled end.
#[derive(Debug, Clone)]
struct Coupled {
    interface: String,
    end: End,
    role: Role,
    /// Driver: the responder's constraint force at the last sync time (N).
    force: f64,
    /// Driver: interface mass and stiffness bound received at set-up.
    added_mass: f64,
    added_stiffness: f64,
}

/// The bar's complete state (what `save_state` writes).
#[derive(Debug, Clone, Serialize, Deserialize)]
struct BarState {
    u: Vec<f64>,
    v: Vec<f64>,
    time: f64,
    external_work: f64,
    interface_work: f64,
    external_impulse: f64,
    applied_impulse: f64,
    interface_impulse: f64,
    coupling_force: Vec<f64>,
}

pub struct Bar {
    p: BarParams,
    fixed: Option<End>,
    load: Option<End>,
    h: f64,
    k: f64,
    /// Lumped masses, with the interface mass of responders added at driven ends.
    m: Vec<f64>,
    /// Internal force buffer (no allocation per step).
    f: Vec<f64>,
    s: BarState,
    coupled: Vec<Coupled>,
}

impl Bar {
    pub fn from_params(params: &toml::Table) -> SolverResult<Self> {
        Self::new(protocol::params::decode(params)?)
    }

    pub fn new(p: BarParams) -> SolverResult<Self> {
        check_positive("length", p.length)?;
        check_positive("young", p.young)?;
        check_positive("density", p.density)?;
        check_positive("area", p.area)?;
        if p.elements == 0 || p.elements > MAX_ELEMENTS {
            return Err(SolverError::config(
                "elements",
                format!("must be in 1..={MAX_ELEMENTS}, got {}", p.elements),
            ));
        }
        if !(p.courant > 0.0 && p.courant <= 1.0) {
            return Err(SolverError::config(
                "courant",
                format!("must be in (0, 1], got {}", p.courant),
            ));
        }
        if !p.tip_force.is_finite() {
            return Err(SolverError::config("tip_force", "must be finite"));
        }
        let fixed = parse_end("fixed", &p.fixed, true)?;
        let load = parse_end("load_end", &p.load_end, true)?;
        if load.is_none() && p.tip_force != 0.0 {
            return Err(SolverError::config(
                "tip_force",
                "does not apply with load_end = \"none\" (no end carries it)",
            ));
        }
        for (name, end) in &p.interfaces {
            parse_end(&format!("interfaces.{name}"), end, false)?;
        }
        let n = p.elements + 1;
        let h = p.length / p.elements as f64;
        let k = p.young * p.area / h;
        let me = p.density * p.area * h;
        let mut m = vec![me; n];
        m[0] = me / 2.0;
        m[n - 1] = me / 2.0;
        Ok(Bar {
            fixed,
            load,
            h,
            k,
            m,
            f: vec![0.0; n],
            s: BarState {
                u: vec![0.0; n],
                v: vec![0.0; n],
                time: 0.0,
                external_work: 0.0,
                interface_work: 0.0,
                external_impulse: 0.0,
                applied_impulse: 0.0,
                interface_impulse: 0.0,
                coupling_force: Vec::new(),
            },
            coupled: Vec::new(),
            p,
        })
    }

    fn node(&self, end: End) -> usize {
        match end {
            End::Left => 0,
            End::Right => self.p.elements,
        }
    }

    fn end_of(&self, interface: &str) -> SolverResult<End> {
        let s = self.p.interfaces.get(interface).ok_or_else(|| {
            SolverError::interface(
                interface,
                "no such interface on this bar (see params.interfaces)",
            )
        })?;
        parse_end(&format!("interfaces.{interface}"), s, false)?
            .ok_or_else(|| SolverError::interface(interface, "not an end"))
    }

    /// Spring-chain internal force on every node, into `self.f`.
    fn internal_force(&mut self) {
        let (u, f, k) = (&self.s.u, &mut self.f, self.k);
        f.fill(0.0);
        for i in 0..u.len() - 1 {
            let d = k * (u[i + 1] - u[i]);
            f[i] += d;
            f[i + 1] -= d;
        }
    }

    fn is_prescribed(&self, i: usize) -> bool {
        self.fixed.is_some_and(|e| self.node(e) == i)
            || self
                .coupled
                .iter()
                .any(|c| c.role == Role::Responder && self.node(c.end) == i)
    }

    /// Critical step of the chain: Gershgorin bound on the highest frequency,
    /// ω² ≤ max_i 2 Σ_adjacent k / m_i, which is exact for a uniform chain (Δt = h/c);
    /// a driven end counts the responder's mass and stiffness bound.
    fn critical_dt(&self) -> f64 {
        let n = self.m.len();
        let mut w2: f64 = 0.0;
        for i in 0..n {
            let mut ksum = if i == 0 || i == n - 1 {
                self.k
            } else {
                2.0 * self.k
            };
            if n == 1 {
                ksum = 0.0;
            }
            for c in &self.coupled {
                if c.role == Role::Driver && self.node(c.end) == i {
                    ksum += c.added_stiffness;
                }
            }
            w2 = w2.max(2.0 * ksum / self.m[i]);
        }
        2.0 / w2.sqrt()
    }

    fn energies(&self) -> (f64, f64, f64) {
        let s = &self.s;
        let mut ke = 0.0;
        let mut p = 0.0;
        for i in 0..s.u.len() {
            if !self.is_prescribed(i) {
                ke += 0.5 * self.m[i] * s.v[i] * s.v[i];
                p += self.m[i] * s.v[i];
            }
        }
        let mut ie = 0.0;
        for i in 0..s.u.len() - 1 {
            let d = s.u[i + 1] - s.u[i];
            ie += 0.5 * self.k * d * d;
        }
        (ke, ie, p)
    }
}

impl Solver for Bar {
    fn describe(&self) -> NodeDescription {
        NodeDescription {
            model: "bar-1d".into(),
            interfaces: self
                .p
                .interfaces
                .keys()
                .map(|name| InterfaceInfo {
                    name: name.clone(),
                    points: 1,
                    provides: vec![
                        "position".into(),
                        "velocity".into(),
                        "force".into(),
                        "mass".into(),
                        "stiffness".into(),
                    ],
                    accepts: vec![
                        "position".into(),
                        "velocity".into(),
                        "force".into(),
                        "mass".into(),
                        "stiffness".into(),
                    ],
                })
                .collect(),
            units: "SI".into(),
        }
    }

    fn interface(&self, name: &str) -> SolverResult<InterfaceMesh> {
        let end = self.end_of(name)?;
        let x = match end {
            End::Left => self.p.x0,
            End::Right => self.p.x0 + self.p.length,
        };
        Ok(InterfaceMesh::points(vec![[x, 0.0, 0.0]]))
    }

    fn setup(&mut self, bindings: &[Binding], inbox: &Inbox, out: &mut Outbox) -> SolverResult<()> {
        self.coupled.clear();
        for b in bindings {
            let end = self.end_of(&b.interface)?;
            if self.fixed == Some(end) {
                return Err(SolverError::interface(
                    &b.interface,
                    "is the fixed end and cannot be coupled",
                ));
            }
            self.coupled.push(Coupled {
                interface: b.interface.clone(),
                end,
                role: b.role,
                force: 0.0,
                added_mass: 0.0,
                added_stiffness: 0.0,
            });
        }
        self.internal_force();
        for c in 0..self.coupled.len() {
            let (name, end, role) = {
                let c = &self.coupled[c];
                (c.interface.clone(), c.end, c.role)
            };
            let i = self.node(end);
            match role {
                Role::Responder => {
                    out.put(&name, "mass", 1, 1)[0] = self.m[i];
                    out.put(&name, "stiffness", 1, 1)[0] = self.k;
                    let f = out.put(&name, "force", 3, 1);
                    f.copy_from_slice(&[self.f[i], 0.0, 0.0]);
                }
                Role::Driver => {
                    let m = inbox.require(&name, "mass", 1)?[0];
                    let k = inbox.require(&name, "stiffness", 1)?[0];
                    let f = inbox.require(&name, "force", 3)?[0];
                    if !(m >= 0.0 && k >= 0.0 && m.is_finite() && k.is_finite()) {
                        return Err(SolverError::interface(
                            &name,
                            format!("bad set-up mass {m} or stiffness {k}"),
                        ));
                    }
                    self.m[i] += m;
                    let c = &mut self.coupled[c];
                    c.added_mass = m;
                    c.added_stiffness = k;
                    c.force = f;
                }
            }
        }
        Ok(())
    }

    fn stable_dt(&self) -> f64 {
        self.p.courant * self.critical_dt()
    }

    fn advance(&mut self, w: &Window, inbox: &Inbox, out: &mut Outbox) -> SolverResult<StepReport> {
        let span = w.t1 - w.t0;
        if span.is_nan() || span <= 0.0 {
            return Err(SolverError::Other(format!(
                "empty window [{}, {}]",
                w.t0, w.t1
            )));
        }
        let nsub = (span / self.stable_dt() - 1e-9).ceil().max(1.0) as u64;
        let dt = span / nsub as f64;
        // Inputs of this window.
        // Responder ends: node, displacement at t0, driver velocity over the window.
        let mut prescribed: Vec<(usize, f64, f64)> = Vec::new();
        for c in self.coupled.iter_mut() {
            let i = match c.end {
                End::Left => 0,
                End::Right => self.p.elements,
            };
            match c.role {
                Role::Driver => {
                    c.force = inbox.require(&c.interface, "force", 3)?[0];
                }
                Role::Responder => {
                    let vel = inbox.require(&c.interface, "velocity", 3)?[0];
                    if !vel.is_finite() {
                        return Err(SolverError::interface(
                            &c.interface,
                            "non-finite velocity received",
                        ));
                    }
                    prescribed.push((i, self.s.u[i], vel));
                }
            }
        }
        let fixed = self.fixed.map(|e| self.node(e));
        let load = self.load.map(|e| (self.node(e), self.p.tip_force));
        for step in 0..nsub {
            self.internal_force();
            if let Some(i) = fixed {
                // Support reaction holds the node: its impulse enters the balance.
                self.s.external_impulse += -self.f[i] * dt;
            }
            for c in &self.coupled {
                let i = self.node(c.end);
                match c.role {
                    Role::Driver => {
                        self.f[i] += c.force;
                        self.s.interface_impulse += c.force * dt;
                    }
                    Role::Responder => {
                        // The chain feels −f on the prescribed node's spring.
                        self.s.interface_impulse += -self.f[i] * dt;
                    }
                }
            }
            if let Some((i, fl)) = load {
                self.f[i] += fl;
                self.s.external_impulse += fl * dt;
                self.s.applied_impulse += fl.abs() * dt;
            }
            let n = self.s.u.len();
            for i in 0..n {
                let a = self.f[i] / self.m[i];
                self.s.v[i] += dt * a;
            }
            if let Some(i) = fixed {
                self.s.v[i] = 0.0;
            }
            for &(i, _, vel) in &prescribed {
                self.s.v[i] = vel;
            }
            // Work of loads and interface forces over this step's displacement increment.
            for c in &self.coupled {
                let i = self.node(c.end);
                let du = dt * self.s.v[i];
                match c.role {
                    Role::Driver => self.s.interface_work += c.force * du,
                    Role::Responder => self.s.interface_work += -self.f[i] * du,
                }
            }
            if let Some((i, fl)) = load {
                self.s.external_work += fl * dt * self.s.v[i];
            }
            for i in 0..n {
                self.s.u[i] += dt * self.s.v[i];
            }
            for &(i, u0, vel) in &prescribed {
                // Along the driver's motion (seed 004 eq. 31: interpolated in time). Integrated
                // from the window start rather than accumulated, so no drift builds up.
                self.s.u[i] = u0 + (step + 1) as f64 * dt * vel;
            }
        }
        self.s.time = w.t1;
        // Outputs at t1.
        self.internal_force();
        for c in &self.coupled {
            let i = self.node(c.end);
            let x_ref = match c.end {
                End::Left => self.p.x0,
                End::Right => self.p.x0 + self.p.length,
            };
            match c.role {
                Role::Driver => {
                    out.put(&c.interface, "position", 3, 1).copy_from_slice(&[
                        x_ref + self.s.u[i],
                        0.0,
                        0.0,
                    ]);
                    out.put(&c.interface, "velocity", 3, 1).copy_from_slice(&[
                        self.s.v[i],
                        0.0,
                        0.0,
                    ]);
                }
                Role::Responder => {
                    out.put(&c.interface, "force", 3, 1)
                        .copy_from_slice(&[self.f[i], 0.0, 0.0]);
                }
            }
        }
        let (ke, ie, p) = self.energies();
        let mut scalars = Vec::new();
        if let Some((i, _)) = load {
            scalars.push(("tip_displacement".to_string(), self.s.u[i]));
        }
        for c in &self.coupled {
            let i = self.node(c.end);
            scalars.push((format!("{}_displacement", c.interface), self.s.u[i]));
        }
        Ok(StepReport {
            kinetic_energy: ke,
            internal_energy: ie,
            external_work: self.s.external_work,
            interface_work: self.s.interface_work,
            momentum: [p, 0.0, 0.0],
            momentum_gross: (0..self.s.v.len())
                .filter(|&i| !self.is_prescribed(i))
                .map(|i| self.m[i] * self.s.v[i].abs())
                .sum(),
            external_impulse: [self.s.external_impulse, 0.0, 0.0],
            applied_impulse: self.s.applied_impulse,
            interface_impulse: [self.s.interface_impulse, 0.0, 0.0],
            substeps: nsub,
            scalars,
            ..Default::default()
        })
    }

    fn write_output(&self, t: f64, window: u64, dir: &std::path::Path) -> SolverResult<()> {
        // The nodes as VTK points (ParaView: `bar.pvd`), with displacement and velocity.
        let n = self.s.u.len();
        let points: Vec<[f64; 3]> = (0..n)
            .map(|i| [self.p.x0 + i as f64 * self.h, 0.0, 0.0])
            .collect();
        let vec3 = |a: &[f64]| a.iter().flat_map(|&x| [x, 0.0, 0.0]).collect::<Vec<f64>>();
        let data = vec![
            ("displacement", 3, vec3(&self.s.u)),
            ("velocity", 3, vec3(&self.s.v)),
        ];
        crate::pd::output::write_vtu(dir, "bar", window, t, &points, data)?;
        Ok(())
    }

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        let mut s = self.s.clone();
        s.coupling_force = self.coupled.iter().map(|c| c.force).collect();
        serde_json::to_vec(&s).map_err(|e| SolverError::Other(e.to_string()))
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        let s: BarState =
            serde_json::from_slice(bytes).map_err(|e| SolverError::Other(e.to_string()))?;
        if s.u.len() != self.s.u.len() || s.v.len() != self.s.v.len() {
            return Err(SolverError::Other(
                "state has another number of nodes".into(),
            ));
        }
        for (c, f) in self.coupled.iter_mut().zip(&s.coupling_force) {
            c.force = *f;
        }
        self.s = s;
        Ok(())
    }
}
