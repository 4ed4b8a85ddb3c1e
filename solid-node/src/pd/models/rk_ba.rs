//! `pd-rk-ba`: the bond-associative model with reproducing-kernel gradients (its force law:
//! `pd/rk_ba.rs`), or with `bond_associative = false` the same gradients without the
//! stabilization; J2 plasticity at the bonds or, given `johnson_cook`, the blast solid
//! (Johnson–Cook strength, an equation of state, Johnson–Cook failure). It has no device
//! kernels.

use super::{DamageVisitor, ModelInput, PdModelDef, cfg, with_damage};
use crate::pd::model::{Dim, PdModel};
use crate::pd::rk_ba::{BondLaw, RkBa};
use mechanics::damage::DamageModel;
use protocol::SolverResult;

pub const DEF: PdModelDef = PdModelDef {
    name: "pd-rk-ba",
    refuses: &[(
        "stabilization",
        "does not apply to pd-rk-ba (its bond-associative stabilization takes no constant; G is pd-correspondence's)",
    )],
    plastic: true,
    build,
    device: None,
};

/// The model with the damage law the parameters give, in 3-D or plane strain, refused (key
/// `horizon`) when a moment matrix of the reference configuration is singular; the check
/// runs in the model's own buffers.
fn build(m: &ModelInput) -> SolverResult<Box<dyn PdModel>> {
    if m.dim == Dim::PlaneStress {
        return cfg("dimension", "pd-rk-ba supports \"3d\" and \"plane_strain\"");
    }
    let order = m.p.rk_order;
    if !(order == 1 || order == 2) {
        return cfg("rk_order", format!("must be 1 or 2, got {order}"));
    }
    let floor = m.p.rk_condition_floor;
    if !(floor > 0.0 && floor < 1.0) {
        return cfg(
            "rk_condition_floor",
            format!(
                "must lie strictly between 0 and 1 (a share of the reference determinant), got {floor}"
            ),
        );
    }
    if !m.p.bond_associative && m.p.damage.is_some() {
        return cfg(
            "bond_associative",
            "false takes no `damage`: pd-rk-ba's damage acts on the bond-level stress, which the unstabilized model does not have",
        );
    }
    let solid = m.p.blast_solid().or_else(|(k, r)| cfg(&k, r))?;
    struct Make<'a, 'b, L>(&'a ModelInput<'b>, L);
    impl<L: BondLaw> DamageVisitor<SolverResult<Box<dyn PdModel>>> for Make<'_, '_, L> {
        fn visit<D: DamageModel + 'static>(self, damage: D) -> SolverResult<Box<dyn PdModel>> {
            let m = self.0;
            let order = m.p.rk_order;
            let mut model = RkBa::new(m.dim, order, m.p.horizon, self.1, damage, m.bonds);
            model.set_bond_associative(m.p.bond_associative);
            model.set_condition_floor(m.p.rk_condition_floor);
            if let Some(i) = model.singular_particle(m.k, m.bonds) {
                return cfg(
                    "horizon",
                    format!(
                        "too small for rk_order = {order}: the moment matrix is singular at particle {i} (use δ ≥ {}·Δx)",
                        order + 1
                    ),
                );
            }
            Ok(Box::new(model))
        }
    }
    match solid {
        Some(s) => with_damage(&m.p.damage, Make(m, s)),
        None => with_damage(&m.p.damage, Make(m, m.material)),
    }
}
