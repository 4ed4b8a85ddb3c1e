//! `pd-correspondence`: the non-ordinary state-based correspondence model with J2 plasticity
//! and zero-energy stabilization (its force law: `pd/correspondence.rs`).

use super::{DamageVisitor, DeviceDef, ModelInput, PdModelDef, with_damage};
use crate::pd::correspondence::Correspondence;
use crate::pd::gpu::DeviceBody;
use crate::pd::integrate::Body;
use crate::pd::model::{Dim, PdModel};
use mechanics::damage::{DamageModel, NoDamage};
use mechanics::gpu::{GpuContext, GpuError};
use protocol::SolverResult;
use std::sync::Arc;

pub const DEF: PdModelDef = PdModelDef {
    name: "pd-correspondence",
    refuses: &[(
        "rk_order",
        "does not apply to pd-correspondence (only pd-rk-ba has an RK gradient order)",
    )],
    plastic: true,
    build,
    device: Some(DeviceDef {
        refuses: |dim, _| {
            (dim == Dim::PlaneStress).then(|| {
                "\"gpu\" does not support dimension = \"plane_stress\" for pd-correspondence (its through-thickness iteration has no device kernel): use plane_strain or 3d, or use device = \"cpu\"".to_string()
            })
        },
        open,
    }),
};

/// The model with the damage law the parameters give.
fn build(m: &ModelInput) -> SolverResult<Box<dyn PdModel>> {
    struct Make<'a, 'b>(&'a ModelInput<'b>);
    impl DamageVisitor<Box<dyn PdModel>> for Make<'_, '_> {
        fn visit<D: DamageModel + 'static>(self, damage: D) -> Box<dyn PdModel> {
            Box::new(model(self.0, damage))
        }
    }
    Ok(with_damage(&m.p.damage, Make(m)))
}

fn model<D: DamageModel>(m: &ModelInput, damage: D) -> Correspondence<D> {
    let p = m.p;
    Correspondence::new(
        m.dim,
        m.material,
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
    DeviceBody::corr(ctx, body, model(m, NoDamage), gather)
}
