//! The 1-D elastic bar (`bar-1d`): a lumped-mass spring chain advanced by central
//! differences. For a one-spacing horizon this is also the peridynamic bar operator of
//! seed 001 §5.2 (eq. 196–201). Either end may be fixed, loaded by a step force, or be a
//! coupling interface (kinematic: driver or responder). In a lagrange coupling one interface
//! may join both ends ("left+right"): the bar is then a middle subdomain of a chain.
//!
//! Time stepping (central difference, velocities at half steps):
//! `a_n = M⁻¹ (f_int(u_n) + f_ext + f_coupling)`, `v_{n+1/2} = v_{n-1/2} + Δt a_n`,
//! `u_{n+1} = u_n + Δt v_{n+1/2}`.

use crate::lagrange::{SubdomainSide, resonance_limit, resonance_warning};
use mechanics::time::{CouplingMethod, InterfaceDof, Subdomain};
use mechanics::time::{Gs4, Gs4Error, IntegratorSpec, LinearSystem, State, Stepper};
use protocol::scheme::lagrange::{LagrangeSide, Method, wire as lwire};
use protocol::scheme::{self, kinematic};
use protocol::{Binding, InterfaceMesh, Solver, SolverError, SolverResult, StepReport, Window};
use protocol::{
    Inbox, InterfaceInfo, LimitApplies, LimitKind, NodeDescription, Outbox, WindowLimit,
};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Parameters of `bar-1d`, as in the case file's `[nodes.<name>.params]`.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BarParams {
    /// Bar length (m).
    pub length: f64,
    /// Position of the left end (m); interface positions are reported from it.
    #[serde(default)]
    pub x0: f64,
    /// Number of elements (linear, equal length).
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
    /// End force (N) at `load_end`: from t = 0 (`ramp = "step"`), or reached over
    /// `ramp_time` along a smooth ramp.
    #[serde(default)]
    pub tip_force: f64,
    /// How the end force starts: "step" (at once), "sin2" (F sin²(πt/2T)) or "septic"
    /// (F (35x⁴ − 84x⁵ + 70x⁶ − 20x⁷), x = t/T: C³, for second-order studies), over T =
    /// `ramp_time`, then held.
    #[serde(default)]
    pub ramp: Ramp,
    /// T of the ramp (s).
    #[serde(default)]
    pub ramp_time: f64,
    /// Steps per window in a lagrange coupling (its ratio m to the system step). Absent:
    /// as many as the stable step needs.
    #[serde(default)]
    pub substeps: Option<usize>,
    /// "left", "right" or "none".
    #[serde(default = "default_load_end")]
    pub load_end: String,
    /// Fraction of the critical step used (≤ 1).
    #[serde(default = "default_courant")]
    pub courant: f64,
    /// Interface names → end ("left" | "right"), or both ends in one interface
    /// ("left+right": the middle subdomain of a chain in a lagrange coupling, its points
    /// in that order).
    #[serde(default)]
    pub interfaces: BTreeMap<String, String>,
    /// Time integrator. Absent: central differences with half-step velocities (above).
    /// `{ scheme = "gs4", design = "U0(1,1,0)", rho_inf = 1.0, implicit = false }`: a GS4-II
    /// member (seed 003 §4; `mechanics::time::gs4`) over the chain's linear system, for bars
    /// without kinematic couplings.
    #[serde(default)]
    pub integrator: Option<IntegratorSpec>,
}

pub use mechanics::time::Ramp;

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

/// An interface's ends: "left", "right", or both joined with "+" (each at most once).
fn parse_ends(key: &str, s: &str) -> SolverResult<Vec<End>> {
    let mut ends = Vec::with_capacity(2);
    for part in s.split('+') {
        let Some(end) = parse_end(key, part.trim(), false)? else {
            continue;
        };
        if ends.contains(&end) {
            return Err(SolverError::config(
                key,
                format!("names the {part} end twice, got \"{s}\""),
            ));
        }
        ends.push(end);
    }
    Ok(ends)
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
    /// Whether the end follows its peer's motion (a sync-force responder, as the scheme
    /// says) rather than sending its motion and taking the peer's force (the driver).
    follows: bool,
    /// Driver: the responder's constraint force at the last sync time (N).
    force: f64,
    /// Driver: interface mass and stiffness bound received at set-up.
    added_mass: f64,
    added_stiffness: f64,
}

/// The bar's complete state (what `save_state` writes).
#[derive(Debug, Clone, Serialize, Deserialize, schemars::JsonSchema)]
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
    /// Nodal accelerations of a GS4-II integrator (empty for central differences; the
    /// checkpoint encoding is bincode, which writes every field, so none may be skipped).
    a: Vec<f64>,
}

/// A bar advanced by a GS4-II member: its linear system over the free nodes and the stepper,
/// refactorised only when the step changes.
struct Gs4Path {
    coef: Gs4,
    sys: LinearSystem,
    dof: Vec<Option<usize>>,
    state: State,
    stepper: Option<Stepper>,
    f: Vec<f64>,
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
    /// The following ends' path through the window (sync-force responder side).
    follow: kinematic::Follow,
    gs4: Option<Gs4Path>,
    lagrange: Option<LagrangeBar>,
    /// What the user should know that does not stop the run (given at set-up).
    warnings: Vec<String>,
}

/// The bar as one subdomain of a lagrange coupling: the runtime steps it.
struct LagrangeBar {
    interface: String,
    /// The interface's ends, in the order of its points and multipliers.
    ends: Vec<End>,
    side: SubdomainSide,
    dof: Vec<Option<usize>>,
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
        if p.ramp != Ramp::Step {
            check_positive("ramp_time", p.ramp_time)?;
        }
        if p.substeps == Some(0) {
            return Err(SolverError::config("substeps", "must be ≥ 1, got 0"));
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
            parse_ends(&format!("interfaces.{name}"), end)?;
        }
        let coef = match &p.integrator {
            Some(spec) => Some(
                Gs4::from_spec("integrator", spec)
                    .map_err(|Gs4Error::Config { key, reason }| SolverError::config(key, reason))?,
            ),
            None => None,
        };
        let n = p.elements + 1;
        let h = p.length / p.elements as f64;
        let k = p.young * p.area / h;
        let me = p.density * p.area * h;
        let mut m = vec![me; n];
        m[0] = me / 2.0;
        m[n - 1] = me / 2.0;
        let mut bar = Bar {
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
                a: Vec::new(),
            },
            coupled: Vec::new(),
            follow: kinematic::Follow::default(),
            gs4: None,
            warnings: Vec::new(),
            lagrange: None,
            p,
        };
        if let Some(coef) = coef {
            let (sys, dof) = bar.linear_system();
            let n = sys.len();
            bar.s.a = vec![0.0; bar.s.u.len()];
            bar.gs4 = Some(Gs4Path {
                coef,
                state: State::zeros(n),
                f: vec![0.0; n],
                sys,
                dof,
                stepper: None,
            });
        }
        Ok(bar)
    }

    fn node(&self, end: End) -> usize {
        match end {
            End::Left => 0,
            End::Right => self.p.elements,
        }
    }

    /// The ends an interface joins, in the order its case names them.
    fn ends_of(&self, interface: &str) -> SolverResult<Vec<End>> {
        let s = self.p.interfaces.get(interface).ok_or_else(|| {
            SolverError::interface(
                interface,
                "no such interface on this bar (see params.interfaces)",
            )
        })?;
        parse_ends(&format!("interfaces.{interface}"), s)
    }

    /// The one end of an interface a kinematic coupling drives.
    fn end_of(&self, interface: &str) -> SolverResult<End> {
        match self.ends_of(interface)?.as_slice() {
            [end] => Ok(*end),
            _ => Err(SolverError::interface(
                interface,
                "joins both ends, which only a lagrange coupling takes (a middle subdomain)",
            )),
        }
    }

    fn end_position(&self, end: End) -> f64 {
        match end {
            End::Left => self.p.x0,
            End::Right => self.p.x0 + self.p.length,
        }
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
                .any(|c| c.follows && self.node(c.end) == i)
    }

    /// The integrator a lagrange subdomain of this bar takes, and its name.
    fn lagrange_integrator(&self) -> (Gs4, String) {
        match (&self.gs4, &self.p.integrator) {
            (Some(g), Some(spec)) if !g.coef.explicit => {
                (g.coef, format!("implicit {}", spec.design))
            }
            (Some(g), _) => (g.coef, "central differences".into()),
            (None, _) => (Gs4::central_difference(), "central differences".into()),
        }
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
                if !c.follows && self.node(c.end) == i {
                    ksum += c.added_stiffness;
                }
            }
            w2 = w2.max(2.0 * ksum / self.m[i]);
        }
        2.0 / w2.sqrt()
    }

    /// Σ m|v| over the free nodes: the scale of momentum sums that cancel.
    fn momentum_gross(&self) -> f64 {
        (0..self.s.v.len())
            .filter(|&i| !self.is_prescribed(i))
            .map(|i| self.m[i] * self.s.v[i].abs())
            .sum()
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
                .iter()
                .map(|(name, ends)| InterfaceInfo {
                    name: name.clone(),
                    points: ends.split('+').count(),
                    provides: vec![
                        "position".into(),
                        "velocity".into(),
                        "force".into(),
                        "mass".into(),
                        "stiffness".into(),
                        // a lagrange side (seed 003 §4): its condensed interface operator
                        "lagrange_operator".into(),
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
        Ok(InterfaceMesh::points(
            self.ends_of(name)?
                .into_iter()
                .map(|e| [self.end_position(e), 0.0, 0.0])
                .collect(),
        ))
    }

    fn setup(&mut self, bindings: &[Binding], inbox: &Inbox, out: &mut Outbox) -> SolverResult<()> {
        self.coupled.clear();
        let (lagrange, bindings): (Vec<&Binding>, Vec<&Binding>) = bindings
            .iter()
            .partition(|b| scheme::of(b.kind).coordinator_solved());
        if self.gs4.is_some() && !bindings.is_empty() {
            return Err(SolverError::config(
                "integrator",
                "the GS4-II integrators do not drive kinematic couplings; remove `integrator` \
                 or couple with kind = \"lagrange\"",
            ));
        }
        match (lagrange.as_slice(), bindings.is_empty()) {
            ([], _) => {}
            ([b], true) => self.setup_lagrange(b, inbox)?,
            _ => {
                return Err(SolverError::interface(
                    &lagrange[0].interface,
                    "a bar in a lagrange coupling takes no other coupling (a middle bar of a \
                     chain joins both ends in one interface, \"left+right\")",
                ));
            }
        }
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
                follows: scheme::of(b.kind).follows(b.role),
                force: 0.0,
                added_mass: 0.0,
                added_stiffness: 0.0,
            });
        }
        self.internal_force();
        for c in 0..self.coupled.len() {
            let (name, end, follows) = {
                let c = &self.coupled[c];
                (c.interface.clone(), c.end, c.follows)
            };
            let i = self.node(end);
            if follows {
                out.put(&name, "mass", 1, 1)[0] = self.m[i];
                out.put(&name, "stiffness", 1, 1)[0] = self.k;
                let f = out.put(&name, "force", 3, 1);
                f.copy_from_slice(&[self.f[i], 0.0, 0.0]);
            } else {
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
        let n = self.coupled.iter().filter(|c| c.follows).count();
        self.follow = kinematic::Follow::new(kinematic::Path::Held, n, 1);
        Ok(())
    }

    fn stable_dt(&self) -> f64 {
        self.p.courant * self.critical_dt()
    }

    fn window_limits(&self) -> Vec<WindowLimit> {
        // A lagrange side with its substeps given steps window / substeps, whatever its
        // stable step; an implicit integrator has no stability limit. Either may resonate.
        let Some(n) = self.p.substeps else {
            return Vec::new();
        };
        let (coef, name) = self.lagrange_integrator();
        let mut limits = Vec::new();
        if coef.explicit {
            limits.push(WindowLimit {
                applies: LimitApplies::LagrangeSide,
                integrator: name.clone(),
                substeps: n as u64,
                max_step: self.critical_dt(),
                key: Some("params.substeps".into()),
                kind: LimitKind::Stability,
            });
        }
        limits.extend(resonance_limit(&coef, &name, n, self.critical_dt()));
        limits
    }

    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    fn lagrange_side(&mut self, interface: &str) -> Option<&mut dyn LagrangeSide> {
        match self.lagrange.as_mut() {
            Some(l) if l.interface == interface => Some(&mut l.side),
            _ => None,
        }
    }

    fn advance(&mut self, w: &Window, inbox: &Inbox, out: &mut Outbox) -> SolverResult<StepReport> {
        let span = w.t1 - w.t0;
        if span.is_nan() || span <= 0.0 {
            return Err(SolverError::Other(format!(
                "empty window [{}, {}]",
                w.t0, w.t1
            )));
        }
        if self.lagrange.is_some() {
            return self.report_lagrange(w);
        }
        let nsub = (span / self.stable_dt() - 1e-9).ceil().max(1.0) as u64;
        let dt = span / nsub as f64;
        // Inputs of this window. Following ends: displacement at t0 and the driver's
        // velocity, held over the window.
        let mut q = 0;
        for c in self.coupled.iter_mut() {
            let i = match c.end {
                End::Left => 0,
                End::Right => self.p.elements,
            };
            if c.follows {
                let vel = inbox.require(&c.interface, "velocity", 3)?[0];
                if !vel.is_finite() {
                    return Err(SolverError::interface(
                        &c.interface,
                        "non-finite velocity received",
                    ));
                }
                self.follow.set_start(q, &[self.s.u[i]]);
                self.follow.set_end(q, &[vel]);
                q += 1;
            } else {
                c.force = inbox.require(&c.interface, "force", 3)?[0];
            }
        }
        let fixed = self.fixed.map(|e| self.node(e));
        let load = self.load.map(|e| (self.node(e), self.p.tip_force));
        let (ramp, ramp_time) = (self.p.ramp, self.p.ramp_time);
        let central_steps = if self.gs4.is_some() {
            self.step_gs4(w.t0, nsub, dt)?;
            0
        } else {
            nsub
        };
        for step in 0..central_steps {
            self.internal_force();
            if let Some(i) = fixed {
                // Support reaction holds the node: its impulse enters the balance.
                self.s.external_impulse += -self.f[i] * dt;
            }
            for c in &self.coupled {
                let i = self.node(c.end);
                if c.follows {
                    // The chain feels −f on the prescribed node's spring.
                    self.s.interface_impulse += -self.f[i] * dt;
                } else {
                    self.f[i] += c.force;
                    self.s.interface_impulse += c.force * dt;
                }
            }
            if let Some((i, f0)) = load {
                let fl = f0 * ramp.factor(w.t0 + step as f64 * dt, ramp_time);
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
            for (q, c) in self.coupled.iter().filter(|c| c.follows).enumerate() {
                let i = self.node(c.end);
                self.s.v[i] = self.follow.velocity(q, 0, self.s.u[i], step, nsub, dt);
            }
            // Work of loads and interface forces over this step's displacement increment.
            for c in &self.coupled {
                let i = self.node(c.end);
                let du = dt * self.s.v[i];
                self.s.interface_work += if c.follows {
                    -self.f[i] * du
                } else {
                    c.force * du
                };
            }
            if let Some((i, f0)) = load {
                let fl = f0 * ramp.factor(w.t0 + step as f64 * dt, ramp_time);
                self.s.external_work += fl * dt * self.s.v[i];
            }
            for i in 0..n {
                self.s.u[i] += dt * self.s.v[i];
            }
            for (q, c) in self.coupled.iter().filter(|c| c.follows).enumerate() {
                // Along the driver's motion (seed 004 eq. 31: interpolated in time).
                let i = self.node(c.end);
                self.s.u[i] = self.follow.position(q, 0, step, nsub, dt);
            }
        }
        self.s.time = w.t1;
        // Outputs at t1.
        self.internal_force();
        for c in &self.coupled {
            let i = self.node(c.end);
            let x_ref = self.end_position(c.end);
            if c.follows {
                out.put(&c.interface, "force", 3, 1)
                    .copy_from_slice(&[self.f[i], 0.0, 0.0]);
            } else {
                out.put(&c.interface, "position", 3, 1).copy_from_slice(&[
                    x_ref + self.s.u[i],
                    0.0,
                    0.0,
                ]);
                out.put(&c.interface, "velocity", 3, 1)
                    .copy_from_slice(&[self.s.v[i], 0.0, 0.0]);
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
            momentum_gross: self.momentum_gross(),
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
        let frame = node_kit::vtk::Frame {
            dir,
            stem: "bar",
            window,
            time: t,
        };
        node_kit::vtk::write_vtu(&frame, node_kit::vtk::point_cloud(&points, data))?;
        Ok(())
    }

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        // In a lagrange coupling the runtime saves the subdomain beside this (its
        // `LagrangeSide::save_state`).
        let mut s = self.s.clone();
        s.coupling_force = self.coupled.iter().map(|c| c.force).collect();
        protocol::checkpoint::encode_state(&s)
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        use protocol::checkpoint::check_len;
        let s: BarState = protocol::checkpoint::decode_state(bytes)?;
        check_len("u", s.u.len(), self.s.u.len())?;
        check_len("v", s.v.len(), self.s.v.len())?;
        check_len("coupling_force", s.coupling_force.len(), self.coupled.len())?;
        for (c, f) in self.coupled.iter_mut().zip(&s.coupling_force) {
            c.force = *f;
        }
        if let Some(g) = self.gs4.as_mut() {
            if s.a.len() != s.u.len() {
                return Err(SolverError::Other(
                    "state has no accelerations for the GS4-II integrator".into(),
                ));
            }
            for (i, d) in g.dof.iter().enumerate() {
                if let Some(d) = *d {
                    (g.state.u[d], g.state.v[d], g.state.a[d]) = (s.u[i], s.v[i], s.a[i]);
                }
            }
        }
        self.s = s;
        Ok(())
    }
}

/// The bar's discretisation (the spring chain above: k = EA/h per element, lumped mass
/// ρAh/2 per element end) as a linear system M ü + K u = f over the nodes not in `fixed`,
/// for the GS4-II integrators (`mechanics::time`). `x` are the node positions (m), strictly
/// increasing. Returns the system and each node's degree of freedom (None where fixed).
pub fn chain_system(
    x: &[f64],
    young: f64,
    density: f64,
    area: f64,
    fixed: &[usize],
) -> (mechanics::time::LinearSystem, Vec<Option<usize>>) {
    let n = x.len();
    let mut dof = vec![None; n];
    let mut count = 0;
    for (i, d) in dof.iter_mut().enumerate() {
        if !fixed.contains(&i) {
            *d = Some(count);
            count += 1;
        }
    }
    let mut mass = vec![0.0; count];
    let mut t = Vec::with_capacity(4 * n);
    for e in 0..n.saturating_sub(1) {
        let h = x[e + 1] - x[e];
        let k = young * area / h;
        let me = density * area * h;
        let (a, b) = (dof[e], dof[e + 1]);
        for (i, j, s) in [(a, a, k), (b, b, k), (a, b, -k), (b, a, -k)] {
            if let (Some(i), Some(j)) = (i, j) {
                t.push((i, j, s));
            }
        }
        for d in [a, b].into_iter().flatten() {
            mass[d] += 0.5 * me;
        }
    }
    let sys = mechanics::time::LinearSystem {
        damping: vec![0.0; count],
        stiffness: mechanics::time::Csr::from_triplets(count, t),
        mass,
    };
    (sys, dof)
}

impl Bar {
    /// `nsub` steps of `dt` with the GS4-II member (constant end load), then the node arrays
    /// from the free degrees of freedom.
    fn step_gs4(&mut self, t0: f64, nsub: u64, dt: f64) -> SolverResult<()> {
        let load = self.load.map(|e| (self.node(e), self.p.tip_force));
        let (ramp, ramp_time) = (self.p.ramp, self.p.ramp_time);
        let fixed = self.fixed.map(|e| self.node(e));
        let Bar { gs4, s, k, .. } = self;
        let Some(g) = gs4.as_mut() else {
            return Ok(());
        };
        let load_dof = load.and_then(|(i, f)| g.dof[i].map(|d| (d, f)));
        g.f.fill(0.0);
        if let Some((d, f)) = load_dof {
            g.f[d] = f * ramp.factor(t0, ramp_time);
        }
        if g.stepper.is_none() {
            // First step: the acceleration in equilibrium with the load at t = 0.
            let st = &mut g.state;
            g.sys.acceleration(&st.u, &st.v, &g.f, &mut st.a);
        }
        if g.stepper.as_ref().is_none_or(|st| st.dt != dt) {
            g.stepper = Some(
                Stepper::new(g.coef, dt, &g.sys)
                    .map_err(|e| SolverError::config("integrator", e.to_string()))?,
            );
        }
        let Some(st) = g.stepper.as_mut() else {
            return Ok(());
        };
        // The node next to the support, whose spring carries the reaction.
        let beside = fixed.map(|i| if i == 0 { 1 } else { i - 1 });
        for n in 0..nsub {
            // seed 003 §4: the load at the algorithmic time t_n + W₁Δt.
            let t = t0 + n as f64 * dt;
            let g_n = (1.0 - g.coef.w1) * ramp.factor(t, ramp_time)
                + g.coef.w1 * ramp.factor(t + dt, ramp_time);
            if let Some((d, f)) = load_dof {
                g.f[d] = f * g_n;
            }
            if let Some(d) = beside.and_then(|j| g.dof[j]) {
                // The support's reaction is −k u of the neighbour, at either end.
                s.external_impulse += -*k * g.state.u[d] * dt;
            }
            let before = load_dof.map(|(d, _)| g.state.u[d]);
            st.step(&g.sys, &mut g.state, &g.f);
            if let (Some((d, _)), Some(u0)) = (load_dof, before) {
                let f = g.f[d];
                s.external_work += f * (g.state.u[d] - u0);
                s.external_impulse += f * dt;
                s.applied_impulse += f.abs() * dt;
            }
        }
        for (i, d) in g.dof.iter().enumerate() {
            let (u, v, a) = match *d {
                Some(d) => (g.state.u[d], g.state.v[d], g.state.a[d]),
                None => (0.0, 0.0, 0.0),
            };
            (s.u[i], s.v[i], s.a[i]) = (u, v, a);
        }
        Ok(())
    }

    /// This bar as a linear system over its free nodes (see [`chain_system`]).
    pub fn linear_system(&self) -> (mechanics::time::LinearSystem, Vec<Option<usize>>) {
        let x: Vec<f64> = (0..=self.p.elements)
            .map(|i| self.p.x0 + i as f64 * self.h)
            .collect();
        let fixed: Vec<usize> = self.fixed.map(|e| self.node(e)).into_iter().collect();
        chain_system(&x, self.p.young, self.p.density, self.p.area, &fixed)
    }
}

impl Bar {
    /// This bar as one subdomain of a lagrange coupling (seed 003 §4.1) at the system step
    /// `window`, taking `substeps` steps of its own integrator (central differences when none
    /// is given) per system step: one multiplier per end of `interface` (in the order the
    /// interface names them, the first `first_lambda`), with sign `sign` in B. The subdomain
    /// keeps ∫ R dt of the support's reaction (its probe 0).
    pub fn subdomain(
        &self,
        interface: &str,
        sign: f64,
        first_lambda: usize,
        window: f64,
        substeps: usize,
        method: CouplingMethod,
    ) -> SolverResult<Subdomain> {
        let ends = self.ends_of(interface)?;
        let (sys, dof) = self.linear_system();
        let mut iface = Vec::with_capacity(ends.len());
        for (k, &end) in ends.iter().enumerate() {
            let d = match dof[self.node(end)] {
                Some(d) if self.fixed != Some(end) => d,
                _ => {
                    return Err(SolverError::interface(
                        interface,
                        "is the fixed end and cannot be coupled",
                    ));
                }
            };
            iface.push(InterfaceDof {
                dof: d,
                sign,
                lambda: first_lambda + k,
            });
        }
        let coef = match self.gs4.as_ref() {
            Some(g) => g.coef,
            None => Gs4::central_difference(),
        };
        let mut shape = vec![0.0; sys.len()];
        if let Some(dl) = self.load.and_then(|e| dof[self.node(e)]) {
            shape[dl] = 1.0;
        }
        let (f0, ramp, time) = (self.p.tip_force, self.p.ramp, self.p.ramp_time);
        // The support's reaction on the bar, R = −k u of the fixed node's neighbour (a probe:
        // the subdomain keeps ∫ R dt over its corrected substeps).
        let mut reaction = vec![0.0; sys.len()];
        if let Some(f) = self.fixed.map(|e| self.node(e)) {
            let next = if f == 0 { 1 } else { f - 1 };
            if let Some(dn) = dof.get(next).copied().flatten() {
                reaction[dn] = -self.k;
            }
        }
        Subdomain::new(
            sys,
            coef,
            window,
            substeps,
            method,
            iface,
            shape,
            Box::new(move |t| f0 * ramp.factor(t, time)),
        )
        .and_then(|s| s.with_probes(reaction))
        .map_err(|e| SolverError::config("integrator", e.to_string()))
    }

    /// Builds the bar's subdomain for the lagrange coupling `b` (seed 003 §4): the system
    /// step and method from the coordinator's request, `substeps` per system step (as many
    /// as the stable step needs when absent).
    fn setup_lagrange(&mut self, b: &Binding, inbox: &Inbox) -> SolverResult<()> {
        let (method, window) = lwire::request(inbox, &b.interface)?;
        let substeps = match self.p.substeps {
            Some(m) => m,
            None => (window / self.stable_dt() - 1e-9).ceil().max(1.0) as usize,
        };
        if self.p.substeps.is_none() && method != Method::Gc {
            let (coef, name) = self.lagrange_integrator();
            self.warnings.extend(resonance_warning(
                &coef,
                &name,
                substeps,
                window,
                self.critical_dt(),
            ));
        }
        let method = match method {
            Method::Gs4 => CouplingMethod::Gs4,
            Method::Gc => CouplingMethod::Gc,
            Method::Ph => CouplingMethod::Ph,
        };
        let sub = self.subdomain(&b.interface, 1.0, 0, window, substeps, method)?;
        self.s.a = vec![0.0; self.s.u.len()];
        self.lagrange = Some(LagrangeBar {
            interface: b.interface.clone(),
            ends: self.ends_of(&b.interface)?,
            side: SubdomainSide(sub),
            dof: self.linear_system().1,
        });
        Ok(())
    }

    /// The report of a window the runtime has stepped through the lagrange side: the node
    /// arrays from the subdomain, energies, the end and interface histories.
    fn report_lagrange(&mut self, w: &Window) -> SolverResult<StepReport> {
        let Some(l) = self.lagrange.as_ref() else {
            return Err(SolverError::Other("no lagrange side".into()));
        };
        let sub = &l.side.0;
        let load = self.load.map(|e| self.node(e));
        let u_before = load.map(|i| self.s.u[i]);
        for (i, d) in l.dof.iter().enumerate() {
            (self.s.u[i], self.s.v[i], self.s.a[i]) = match *d {
                Some(d) => (sub.state.u[d], sub.state.v[d], sub.state.a[d]),
                None => (0.0, 0.0, 0.0),
            };
        }
        if let (Some(i), Some(u0)) = (load, u_before) {
            // Trapezoidal work of the end force over the window.
            let f = |t: f64| self.p.tip_force * self.p.ramp.factor(t, self.p.ramp_time);
            self.s.external_work += 0.5 * (f(w.t0) + f(w.t1)) * (self.s.u[i] - u0);
        }
        self.s.interface_work = sub.interface_work;
        // Impulses as the subdomain summed them over its corrected substeps (trapezoidal:
        // exactly the momentum central differences and average acceleration give): the end
        // force, the support's reaction and the interface force.
        let load_impulse = if load.is_some() {
            sub.load_integral
        } else {
            0.0
        };
        self.s.external_impulse = load_impulse + sub.probe_integral.first().unwrap_or(&0.0);
        self.s.applied_impulse = load_impulse.abs();
        // Along x at every end: the interface's impulse is their sum.
        self.s.interface_impulse = sub.interface_impulse.iter().sum();
        self.s.time = w.t1;
        let substeps = sub.substeps() as u64;
        let (ke, ie, p) = self.energies();
        let mut scalars = Vec::new();
        let mut push = |name: &str, i: usize, s: &BarState| {
            scalars.push((format!("{name}_displacement"), s.u[i]));
            scalars.push((format!("{name}_velocity"), s.v[i]));
            scalars.push((format!("{name}_acceleration"), s.a[i]));
        };
        if let Some(i) = load {
            push("tip", i, &self.s);
        }
        match l.ends.as_slice() {
            [end] => push(&l.interface, self.node(*end), &self.s),
            ends => {
                for &end in ends {
                    let side = match end {
                        End::Left => "left",
                        End::Right => "right",
                    };
                    push(&format!("{}_{side}", l.interface), self.node(end), &self.s);
                }
            }
        }
        Ok(StepReport {
            kinetic_energy: ke,
            internal_energy: ie,
            external_work: self.s.external_work,
            interface_work: self.s.interface_work,
            momentum: [p, 0.0, 0.0],
            momentum_gross: self.momentum_gross(),
            external_impulse: [self.s.external_impulse, 0.0, 0.0],
            applied_impulse: self.s.applied_impulse,
            interface_impulse: [self.s.interface_impulse, 0.0, 0.0],
            substeps,
            scalars,
            ..Default::default()
        })
    }
}
