//! Peridynamic solid models (seed 000 App. A–C, seed 001 ch. 4): particles and families,
//! the model family behind one trait (`model`), one file per model, the velocity-Verlet
//! body, VTK output and the `Solver` implementation with its coupling sides.
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
pub mod checkpoint;
pub mod correspondence;
pub mod family;
pub mod fracture;
pub mod geometry;
pub mod gpu;
pub mod integrate;
pub mod lagrange;
pub mod model;
pub mod rk_ba;
pub mod solver;

use protocol::{BuildOptions, Solver, SolverResult};

/// The peridynamic models of this node by config name, for a run; `None` when `model` is
/// not one.
pub fn factory(model: &str, params: &toml::Table) -> Option<SolverResult<Box<dyn Solver>>> {
    build(model, params, &BuildOptions::RUN)
}

/// As `factory`, as `opts` asks (describe-only opens no GPU).
pub fn build(
    model: &str,
    params: &toml::Table,
    opts: &BuildOptions,
) -> Option<SolverResult<Box<dyn Solver>>> {
    match model {
        "pd-bond" | "pd-correspondence" | "pd-rk-ba" => Some(
            protocol::params::decode(params)
                .and_then(|p| {
                    refuse_inapplicable(model, params)?;
                    solver::PdSolver::build(model, p, opts)
                })
                .map(|s| Box::new(s) as Box<dyn Solver>),
        ),
        _ => None,
    }
}

/// Keys of the parameter table that the chosen model or dimension ignores are refused by
/// name, so a key meant for another model is not silently dropped: the J2 keys and
/// `stabilization` (pd-correspondence's zero-energy control) on the elastic bond model,
/// `rk_order` outside pd-rk-ba, `stabilization` on pd-rk-ba (its bond-associative
/// stabilization has no constant), hardening without `yield_stress`, `thickness` in 3-D.
fn refuse_inapplicable(model: &str, params: &toml::Table) -> protocol::SolverResult<()> {
    use protocol::SolverError;
    let has = |k: &str| params.contains_key(k);
    let only = |key: &str, why: &str| Err(SolverError::config(key, why.to_string()));
    let per_model: &[(&str, &str)] = match model {
        "pd-bond" => &[
            (
                "stabilization",
                "does not apply to pd-bond (the bond-based model has no zero-energy modes; it is pd-correspondence's)",
            ),
            (
                "rk_order",
                "does not apply to pd-bond (only pd-rk-ba has an RK gradient order)",
            ),
            (
                "iso_hardening",
                "does not apply to pd-bond (elastic-brittle; use pd-correspondence or pd-rk-ba for plasticity)",
            ),
            (
                "kin_hardening",
                "does not apply to pd-bond (elastic-brittle; use pd-correspondence or pd-rk-ba for plasticity)",
            ),
        ],
        "pd-correspondence" => &[(
            "rk_order",
            "does not apply to pd-correspondence (only pd-rk-ba has an RK gradient order)",
        )],
        _ => &[(
            "stabilization",
            "does not apply to pd-rk-ba (its bond-associative stabilization takes no constant; G is pd-correspondence's)",
        )],
    };
    for (k, why) in per_model {
        if has(k) {
            return only(k, why);
        }
    }
    if !has("yield_stress") && model != "pd-bond" {
        for k in ["iso_hardening", "kin_hardening"] {
            if has(k) {
                return only(
                    k,
                    "applies only with yield_stress (without it the material is elastic)",
                );
            }
        }
    }
    if has("thickness") && params.get("dimension").and_then(|d| d.as_str()) == Some("3d") {
        return only(
            "thickness",
            "applies to 2-D dimensions only (\"plane_stress\", \"plane_strain\")",
        );
    }
    Ok(())
}
