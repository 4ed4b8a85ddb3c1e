//! How the node constructs each peridynamic model from its parameters: one module per model
//! (`bond`, `correspondence`, `rk_ba`), each with its [`PdModelDef`] — its name, the keys it
//! refuses, its constructor and, where it has device kernels, its device path — and [`ALL`],
//! the list the node's model table and [`by_name`] read. The force laws themselves are the
//! modules of the same names one level up.

pub mod bond;
pub mod correspondence;
pub mod rk_ba;

use super::family::Bonds;
use super::gpu::DeviceBody;
use super::integrate::Body;
use super::model::{Dim, Kinematics, PdModel};
use super::params::{DamageParams, PdParams};
use mechanics::damage::{
    BrittleVonMises, CriticalStretch, DamageModel, DuctilePlasticStrain, FailureIndicator,
};
use mechanics::gpu::{GpuContext, GpuError};
use mechanics::j2::J2Material;
use protocol::{SolverError, SolverResult};
use std::sync::Arc;

/// Every peridynamic model of the node.
pub const ALL: &[&PdModelDef] = &[&bond::DEF, &correspondence::DEF, &rk_ba::DEF];

/// The model named `name` (as in a case's `model`).
pub fn by_name(name: &str) -> Option<&'static PdModelDef> {
    ALL.iter().copied().find(|d| d.name == name)
}

/// What constructing a model needs: its dimension, the node's parameters and the J2
/// material they give, the body's reference kinematics (at rest) and its bonds.
pub struct ModelInput<'a> {
    pub dim: Dim,
    pub p: &'a PdParams,
    pub material: J2Material,
    pub k: &'a Kinematics<'a>,
    pub bonds: &'a Bonds,
}

/// A peridynamic model as the node offers it.
pub struct PdModelDef {
    /// The name a case gives as the node's `model`.
    pub name: &'static str,
    /// Keys of the parameter table the model ignores, refused by name with the reason, so
    /// that a key meant for another model is never dropped silently.
    pub refuses: &'static [(&'static str, &'static str)],
    /// Whether it takes a plastic material (`yield_stress` with hardening).
    pub plastic: bool,
    /// The model, after the checks it alone makes of the parameters.
    pub build: fn(&ModelInput) -> SolverResult<Box<dyn PdModel>>,
    /// Its device kernels, if it has them.
    pub device: Option<DeviceDef>,
}

/// A model's device path.
pub struct DeviceDef {
    /// What its kernels cannot run, beyond what no device path supports (damage, pressure
    /// pulses): the reason, for `device = "gpu"`.
    pub refuses: fn(Dim, &PdParams) -> Option<String>,
    /// Whether its kernels break bonds at a critical stretch (`damage.kind =
    /// "critical_stretch"`); every other damage law stays on the CPU.
    pub critical_stretch: bool,
    /// The device copy of a freshly built `body` (`input` as the body's model was built
    /// with), gathering the particles `gather` to the host every window.
    pub open: OpenDevice,
}

/// [`DeviceDef::open`]: the context, the model's input, the body, the gathered particles.
pub type OpenDevice =
    fn(Arc<GpuContext>, &ModelInput, &Body, &[usize]) -> Result<DeviceBody, GpuError>;

/// A configuration error at parameter `key`.
pub(super) fn cfg<T>(key: &str, reason: impl Into<String>) -> SolverResult<T> {
    Err(SolverError::config(key, reason))
}

/// Calls `f` with the damage law the parameters give (none without `damage`): a model
/// generic over its damage law is built once per law.
pub(super) fn with_damage<R>(damage: &Option<DamageParams>, f: impl DamageVisitor<R>) -> R {
    match damage.clone().unwrap_or(DamageParams::None {}) {
        DamageParams::None {} => f.visit(mechanics::damage::NoDamage),
        DamageParams::CriticalStretch { critical_stretch } => {
            f.visit(CriticalStretch { critical_stretch })
        }
        DamageParams::VonMises { critical_stress } => f.visit(BrittleVonMises { critical_stress }),
        DamageParams::PlasticStrain {
            eps_threshold,
            eps_critical,
        } => f.visit(DuctilePlasticStrain {
            threshold: eps_threshold,
            critical: eps_critical,
        }),
        // the indicator is accumulated by the stress law (checked at set-up to be there)
        DamageParams::JohnsonCook { .. } => f.visit(FailureIndicator),
    }
}

/// What [`with_damage`] calls with the damage law, whatever its type.
pub(super) trait DamageVisitor<R> {
    fn visit<D: DamageModel + 'static>(self, damage: D) -> R;
}
