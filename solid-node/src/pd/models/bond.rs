//! `pd-bond`: the bond-based model, elastic-brittle (its force law: `pd/bond.rs`).

use super::{DeviceDef, ModelInput, PdModelDef, cfg};
use crate::pd::bond::{BondModel, implied_poisson};
use crate::pd::gpu::DeviceBody;
use crate::pd::integrate::Body;
use crate::pd::model::PdModel;
use crate::pd::params::DamageParams;
use mechanics::gpu::{GpuContext, GpuError};
use protocol::SolverResult;
use std::sync::Arc;

pub const DEF: PdModelDef = PdModelDef {
    name: "pd-bond",
    refuses: &[
        (
            "stabilization",
            "does not apply to pd-bond (the bond-based model has no zero-energy modes; it is pd-correspondence's)",
        ),
        (
            "rk_order",
            "does not apply to pd-bond (only pd-rk-ba has an RK gradient order)",
        ),
        (
            "rk_condition_floor",
            "does not apply to pd-bond (only pd-rk-ba has an RK gradient whose order falls back)",
        ),
        (
            "bond_associative",
            "does not apply to pd-bond (only pd-rk-ba has a bond-associative switch)",
        ),
        (
            "iso_hardening",
            "does not apply to pd-bond (elastic-brittle; use pd-correspondence or pd-rk-ba for plasticity)",
        ),
        (
            "kin_hardening",
            "does not apply to pd-bond (elastic-brittle; use pd-correspondence or pd-rk-ba for plasticity)",
        ),
        (
            "johnson_cook",
            "does not apply to pd-bond (elastic-brittle; pd-correspondence and pd-rk-ba run the Johnson–Cook solid)",
        ),
        (
            "eos",
            "does not apply to pd-bond (only the Johnson–Cook solid of pd-correspondence and pd-rk-ba takes an equation of state)",
        ),
    ],
    plastic: false,
    build,
    device: Some(DeviceDef {
        refuses: |_, _| None,
        critical_stretch: true,
        open,
    }),
};

/// The bond-based model: its Poisson ratio is the one the dimension implies, it is elastic,
/// and it breaks bonds by critical stretch only.
fn build(m: &ModelInput) -> SolverResult<Box<dyn PdModel>> {
    let p = m.p;
    let nu = implied_poisson(m.dim);
    if (p.poisson - nu).abs() > 1e-9 {
        return cfg(
            "poisson",
            format!(
                "pd-bond in {} fixes ν = {nu:.6}, got {}",
                p.dimension, p.poisson
            ),
        );
    }
    if p.yield_stress.is_some() {
        return cfg(
            "yield_stress",
            "pd-bond is elastic-brittle; use pd-correspondence for plasticity",
        );
    }
    let s0 = match &p.damage {
        None | Some(DamageParams::None {}) => None,
        Some(DamageParams::CriticalStretch { critical_stretch }) => Some(*critical_stretch),
        Some(_) => {
            return cfg(
                "damage.kind",
                "pd-bond supports \"critical_stretch\" or \"none\"",
            );
        }
    };
    Ok(Box::new(model(m, s0)))
}

fn model(m: &ModelInput, s0: Option<f64>) -> BondModel {
    let p = m.p;
    BondModel::new(m.dim, p.young, p.horizon, p.thickness, s0, m.k, m.bonds)
}

/// The device body, with a twin of the body's model, breaking bonds at the critical stretch.
fn open(
    ctx: Arc<GpuContext>,
    m: &ModelInput,
    body: &Body,
    gather: &[usize],
) -> Result<DeviceBody, GpuError> {
    let s0 = match &m.p.damage {
        Some(DamageParams::CriticalStretch { critical_stretch }) => Some(*critical_stretch),
        _ => None,
    };
    DeviceBody::bond(ctx, body, model(m, s0), s0, gather)
}
