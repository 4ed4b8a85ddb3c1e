//! `cosim validate` and `cosim conformance`: a case checked without starting anything, and a
//! node executable checked against the protocol.

use crate::case::{self, load_variant};
use serde_json::json;
use std::path::PathBuf;

/// `cosim validate`'s command line.
#[derive(Debug, clap::Args)]
pub struct ValidateArgs {
    pub case: PathBuf,
    /// Check with these overrides (NODE.KEY=VALUE, run.KEY=VALUE, couplings.NAME.KEY=VALUE).
    #[arg(long = "set")]
    pub sets: Vec<String>,
    /// Check only this variant.
    #[arg(long)]
    pub variant: Option<String>,
    /// Print the result as one JSON document on stdout: `{"ok": true, "nodes": [...],
    /// "variants": [...]}` or `{"ok": false, "key": "nodes.gas.params...", "reason": ...}`
    /// (the exit codes are the same).
    #[arg(long)]
    pub json: bool,
}

/// `cosim validate`: the case (and every variant when neither a variant nor overrides are
/// given) checked without starting anything; exit 2 naming the key of the first error.
pub(super) fn validate(a: &ValidateArgs) -> i32 {
    let variant = a.variant.as_deref();
    let c = match load_variant(&a.case, variant, &a.sets) {
        Ok(c) => c,
        Err(e) => return refuse(a, &e, variant),
    };
    let order = case::window_order(&c).unwrap_or_default();
    let mut doc = json!({
        "ok": true, "case": a.case, "variant": variant, "nodes": [], "variants": [],
        "couplings": c.couplings.len(), "windows": windows(&c), "order": order,
        "window": c.run.window, "end_time": c.run.end_time, "output": c.run.output,
        "warnings": c.warnings,
    });
    if !a.json {
        println!(
            "{}: ok — {} nodes, {} couplings, {} windows, order {}",
            a.case.display(),
            c.nodes.len(),
            c.couplings.len(),
            windows(&c),
            order.join(" → ")
        );
        for w in &c.warnings {
            println!("  warning: {w}");
        }
    }
    for n in &c.nodes {
        if let Some(list) = doc["nodes"].as_array_mut() {
            list.push(node_doc(n));
        }
        if !a.json {
            println!("{}", node_line(n));
        }
    }
    // Every variant must build too.
    if variant.is_none() && a.sets.is_empty() {
        for v in &c.variants {
            match load_variant(&a.case, Some(v), &[]) {
                Ok(cv) => {
                    let entry =
                        json!({ "name": v, "windows": windows(&cv), "output": cv.run.output });
                    if let Some(list) = doc["variants"].as_array_mut() {
                        list.push(entry);
                    }
                    if !a.json {
                        println!(
                            "  variant {v}: ok — {} windows, output {}",
                            windows(&cv),
                            cv.run.output.display()
                        );
                    }
                }
                Err(e) => return refuse(a, &e, Some(v)),
            }
        }
    }
    if a.json {
        println!("{doc}");
    }
    0
}

/// The windows a case runs.
fn windows(c: &case::Case) -> f64 {
    ((c.run.end_time / c.run.window) - 1e-9).ceil()
}

/// A refused case (or variant) on stdout as JSON or on stderr as a line; exit code 2.
fn refuse(a: &ValidateArgs, e: &case::ConfigError, variant: Option<&str>) -> i32 {
    if a.json {
        println!(
            "{}",
            json!({ "ok": false, "case": a.case, "variant": variant, "key": e.key, "reason": e.reason })
        );
    } else {
        match variant {
            Some(v) => eprintln!("cosim: {} (variant {v}): {e}", a.case.display()),
            None => eprintln!("cosim: {}: {e}", a.case.display()),
        }
    }
    2
}

/// A node of a valid case as `--json` lists it.
fn node_doc(n: &case::NodeConfig) -> serde_json::Value {
    json!({
        "name": n.name, "solver": n.solver, "model": n.model,
        "remote": n.interfaces.is_none(), "interfaces": n.interfaces,
    })
}

/// A node of a valid case as the text listing shows it.
fn node_line(n: &case::NodeConfig) -> String {
    match &n.interfaces {
        Some(i) => format!(
            "  node {}: {} {} described by its executable — interfaces {}",
            n.name,
            n.solver,
            n.model,
            if i.is_empty() {
                "none".to_string()
            } else {
                i.join(", ")
            }
        ),
        None => format!(
            "  node {}: remote, '{}' is not on this host — its parameters are checked when it joins",
            n.name, n.solver
        ),
    }
}

/// `cosim conformance`'s command line.
#[derive(Debug, clap::Args)]
pub struct ConformanceArgs {
    /// The model inside the executable, as in a case's `nodes.NAME.model`.
    #[arg(long)]
    model: String,
    /// The node's parameters: a TOML file holding the body of `[nodes.NAME.params]`.
    #[arg(long)]
    params: Option<PathBuf>,
    /// The interface to couple (default: the first the node describes).
    #[arg(long)]
    interface: Option<String>,
    /// The coupling kind: kinematic, immersed or lagrange (cosim then solves the interface
    /// problem against a rigid side of its own; --role does not apply).
    #[arg(long, default_value = "kinematic")]
    kind: String,
    /// The node's role, driver or responder; cosim plays the other.
    #[arg(long, default_value = "responder")]
    role: String,
    /// Windows to run after the set-up (a checkpoint is asked in the one before the last).
    #[arg(long, default_value_t = 4)]
    windows: u64,
    /// The window (s); default: the node's stable step.
    #[arg(long)]
    window: Option<f64>,
    /// Directory for the node's log, output and checkpoint (default: a fresh one under
    /// the system's temporary directory).
    #[arg(long, short)]
    output: Option<PathBuf>,
    /// The node's command: an executable (a path, or a name beside cosim) and its own
    /// arguments.
    #[arg(required = true, last = true)]
    command: Vec<String>,
}

/// `cosim conformance`: check the node, print a line per rule; returns the exit code.
pub(super) fn conformance(a: ConformanceArgs) -> i32 {
    use crate::conformance::{self, Outcome};
    let (kind, role) = (a.kind.clone(), a.role.clone());
    let o = match conformance_options(a) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("cosim conformance: {e}");
            return 2;
        }
    };
    let what = if kind == "lagrange" {
        "a lagrange side".to_string()
    } else {
        format!("the {kind} {role} node")
    };
    println!(
        "cosim conformance: `{}` (model {}) as {what}, {} windows; its log: {}",
        o.command.join(" "),
        o.model,
        o.windows,
        o.output.join("node.log").display()
    );
    match conformance::check(&o) {
        Ok(verdicts) => {
            for v in &verdicts {
                println!("{v}");
            }
            let passed = verdicts
                .iter()
                .filter(|v| v.outcome == Outcome::Pass)
                .count();
            println!("{passed} of {} rules pass", verdicts.len());
            if conformance::all_pass(&verdicts) {
                0
            } else {
                1
            }
        }
        Err(e) => {
            eprintln!("cosim conformance: {e:#}");
            1
        }
    }
}

/// The checker's options from the command line, or what is wrong with it.
fn conformance_options(a: ConformanceArgs) -> Result<crate::conformance::Options, String> {
    use protocol::{CouplingKind, Role};
    let kind = match a.kind.as_str() {
        "kinematic" => CouplingKind::Kinematic,
        "immersed" => CouplingKind::Immersed,
        "lagrange" => CouplingKind::Lagrange,
        k => return Err(format!("--kind {k}: kinematic, immersed or lagrange")),
    };
    let role = match a.role.as_str() {
        "driver" => Role::Driver,
        "responder" => Role::Responder,
        r => return Err(format!("--role {r}: driver or responder")),
    };
    let params = match &a.params {
        None => toml::Table::new(),
        Some(p) => std::fs::read_to_string(p)
            .map_err(|e| e.to_string())
            .and_then(|t| toml::from_str::<toml::Table>(&t).map_err(|e| e.to_string()))
            .map_err(|e| format!("--params {}: {e}", p.display()))?,
    };
    if a.windows < 2 {
        return Err("--windows must be at least 2 (one holds the checkpoint)".into());
    }
    let output = a.output.unwrap_or_else(|| {
        std::env::temp_dir().join(crate::launch::pick_run_id("cosim-conformance"))
    });
    Ok(crate::conformance::Options {
        command: a.command,
        model: a.model,
        params,
        interface: a.interface,
        kind,
        role,
        windows: a.windows,
        window: a.window,
        output,
    })
}
