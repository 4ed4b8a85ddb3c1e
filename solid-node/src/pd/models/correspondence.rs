//! `pd-correspondence`: the non-ordinary state-based correspondence model with zero-energy
//! stabilization (its force law: `pd/correspondence.rs`), with J2 plasticity or, given
//! `johnson_cook`, the blast solid (Johnson–Cook strength, an equation of state, Johnson–Cook
//! failure; `mechanics::blast_solid`).

use super::{DamageVisitor, DeviceDef, ModelInput, PdModelDef, cfg, with_damage};
use crate::pd::correspondence::Correspondence;
use crate::pd::gpu::DeviceBody;
use crate::pd::integrate::Body;
use crate::pd::model::{Dim, PdModel};
use mechanics::damage::{DamageModel, NoDamage};
use mechanics::gpu::{GpuContext, GpuError};
use mechanics::stress_law::StressLaw;
use protocol::SolverResult;
use std::sync::Arc;

pub const DEF: PdModelDef = PdModelDef {
    name: "pd-correspondence",
    refuses: &[
        (
            "rk_order",
            "does not apply to pd-correspondence (only pd-rk-ba has an RK gradient order)",
        ),
        (
            "rk_condition_floor",
            "does not apply to pd-correspondence (only pd-rk-ba has an RK gradient whose order falls back)",
        ),
        (
            "bond_associative",
            "does not apply to pd-correspondence (only pd-rk-ba has a bond-associative switch; this model is stabilized by `stabilization`)",
        ),
    ],
    plastic: true,
    build,
    device: Some(DeviceDef {
        refuses: |dim, p| {
            if p.johnson_cook.is_some() {
                return Some("\"gpu\" does not support johnson_cook (the device kernels integrate J2 plasticity only): use device = \"cpu\"".to_string());
            }
            (dim == Dim::PlaneStress).then(|| {
                "\"gpu\" does not support dimension = \"plane_stress\" for pd-correspondence (its through-thickness iteration has no device kernel): use plane_strain or 3d, or use device = \"cpu\"".to_string()
            })
        },
        critical_stretch: false,
        open,
    }),
};

/// The model with the stress and damage laws the parameters give.
fn build(m: &ModelInput) -> SolverResult<Box<dyn PdModel>> {
    let solid = m.p.blast_solid().or_else(|(k, r)| cfg(&k, r))?;
    if solid.is_some() && m.dim == Dim::PlaneStress {
        return cfg(
            "johnson_cook",
            "is integrated in 3d and plane_strain (plane stress's through-thickness iteration is J2's alone)",
        );
    }
    struct Make<'a, 'b, L>(&'a ModelInput<'b>, L);
    impl<L: StressLaw> DamageVisitor<Box<dyn PdModel>> for Make<'_, '_, L> {
        fn visit<D: DamageModel + 'static>(self, damage: D) -> Box<dyn PdModel> {
            Box::new(model(self.0, self.1, damage))
        }
    }
    Ok(match solid {
        Some(s) => with_damage(&m.p.damage, Make(m, s)),
        None => with_damage(&m.p.damage, Make(m, m.material)),
    })
}

fn model<D: DamageModel, L: StressLaw>(m: &ModelInput, law: L, damage: D) -> Correspondence<D, L> {
    let p = m.p;
    Correspondence::new(
        m.dim,
        law,
        p.stabilization,
        p.horizon,
        p.thickness,
        damage,
        m.k,
        m.bonds,
    )
}

/// The device body, with an undamaged twin of the body's model.
fn open(
    ctx: Arc<GpuContext>,
    m: &ModelInput,
    body: &Body,
    gather: &[usize],
) -> Result<DeviceBody, GpuError> {
    DeviceBody::corr(ctx, body, model(m, m.material, NoDamage), gather)
}
