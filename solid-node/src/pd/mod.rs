//! Peridynamic solid models (seed 000 App. A–C, seed 001 ch. 4): particles and families,
//! the model family behind one trait (`model`), one file per model's force law and one per
//! model's construction from its parameters (`models/`), the velocity-Verlet body, VTK
//! output and the `Solver` implementation with its coupling sides.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

#[cfg(target_arch = "x86_64")]
mod avx512;
pub mod bond;
pub mod cases;
pub mod correspondence;
pub mod family;
pub mod fracture;
pub mod geometry;
pub mod gpu;
pub mod integrate;
pub mod lagrange;
pub mod model;
pub mod models;
pub mod params;
pub mod rk_ba;
pub mod solver;

use protocol::{BuildOptions, Solver, SolverResult};

/// The peridynamic model named `model` for a run; `None` when `model` is not one.
pub fn factory(model: &str, params: &toml::Table) -> Option<SolverResult<Box<dyn Solver>>> {
    let def = models::by_name(model)?;
    Some(build(def, params, &BuildOptions::RUN))
}

/// Model `def` from its parameter table, as `opts` asks (describe-only opens no GPU).
pub fn build(
    def: &models::PdModelDef,
    params: &toml::Table,
    opts: &BuildOptions,
) -> SolverResult<Box<dyn Solver>> {
    protocol::params::decode(params)
        .and_then(|p| {
            refuse_inapplicable(def, params)?;
            solver::PdSolver::build_model(def, p, opts)
        })
        .map(|s| Box::new(s) as Box<dyn Solver>)
}

/// Keys of the parameter table that the chosen model or dimension ignores are refused by
/// name, so a key meant for another model is not silently dropped: each model's own list
/// (`PdModelDef::refuses`: the J2 keys and `stabilization` on the elastic bond model,
/// `rk_order`, `rk_condition_floor` and `bond_associative` outside pd-rk-ba, `stabilization` on pd-rk-ba, `johnson_cook` and `eos`
/// outside pd-correspondence), hardening without `yield_stress`, J2 hardening with
/// `johnson_cook`, `eos` without it, `thickness` in 3-D.
fn refuse_inapplicable(def: &models::PdModelDef, params: &toml::Table) -> SolverResult<()> {
    use protocol::SolverError;
    let has = |k: &str| params.contains_key(k);
    let only = |key: &str, why: &str| Err(SolverError::config(key, why.to_string()));
    for (k, why) in def.refuses {
        if has(k) {
            return only(k, why);
        }
    }
    if !has("yield_stress") && def.plastic {
        for k in ["iso_hardening", "kin_hardening"] {
            if has(k) {
                return only(
                    k,
                    "applies only with yield_stress (without it the material is elastic)",
                );
            }
        }
    }
    if has("johnson_cook") {
        for k in ["iso_hardening", "kin_hardening"] {
            if has(k) {
                return only(
                    k,
                    "is J2's linear hardening; with johnson_cook the hardening is its B and n",
                );
            }
        }
    } else if has("eos") {
        return only(
            "eos",
            "applies only with johnson_cook (the J2 material's pressure follows its bulk modulus)",
        );
    }
    if has("thickness") && params.get("dimension").and_then(|d| d.as_str()) == Some("3d") {
        return only(
            "thickness",
            "applies to 2-D dimensions only (\"plane_stress\", \"plane_strain\")",
        );
    }
    Ok(())
}
