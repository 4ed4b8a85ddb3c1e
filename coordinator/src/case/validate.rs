//! What the values of a case mean and whether they fit together: ranges, names, the members
//! of each coupling, the scheme's rules (decoupling, the lagrange coupling's whole windows,
//! the parallel schedule), then what each node executable says of itself (`--describe`):
//! its parameters, interfaces, fields, point positions and stable steps. Every refusal
//! names the key it comes from.

use super::graph::required_fields;
use super::parse::{CaseFile, CouplingSection, NodeSection, PicturesName, RunSection};
use super::parse::{ScheduleName, TransportName};
use super::resolved::{Case, ConfigError, CouplingConfig, Decouple, NodeConfig, Pictures};
use super::resolved::{DEFAULT_POINT_TOLERANCE, RunConfig, Schedule, err};
use crate::launch::resolve_exe;
use protocol::CouplingKind;
use protocol::scheme;
use protocol::transport::TransportKind;
use std::collections::BTreeMap;
use std::path::Path;

/// The resolved case of a typed case file: every value checked, defaults filled in, params
/// files read (relative to `path`'s folder) and node executables found. Nothing is started.
pub(super) fn settle(file: CaseFile, path: &Path, text: &str) -> Result<Case, ConfigError> {
    let case_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    for name in file.variants.keys() {
        if !valid_name(name) {
            return Err(err(
                format!("variants.{name}"),
                "variant names are 1–32 characters of [A-Za-z0-9_-]",
            ));
        }
    }
    let run = settle_run(&file.run, &case_dir)?;
    if file.nodes.is_empty() {
        return Err(err("nodes", "a case needs at least one [nodes.<name>]"));
    }
    let nodes = file
        .nodes
        .iter()
        .map(|(name, n)| settle_node(name, n, &case_dir))
        .collect::<Result<Vec<_>, _>>()?;
    let mut couplings: Vec<CouplingConfig> = Vec::new();
    for (i, c) in file.couplings.iter().enumerate() {
        let c = settle_coupling(i, c, &nodes)?;
        if couplings.iter().any(|o| o.name == c.name) {
            return Err(err(
                format!("couplings[{i}].name"),
                format!("duplicate coupling name '{}'", c.name),
            ));
        }
        couplings.push(c);
    }
    super::graph::check_one_coupling_per_interface(&couplings)?;
    check_lagrange(&run, &nodes, &couplings)?;
    if run.schedule == Schedule::Parallel
        && let Some((i, why)) = couplings
            .iter()
            .enumerate()
            .find_map(|(i, c)| Some((i, scheme::of(c.kind).parallel_refusal()?)))
    {
        return Err(err(
            "run.schedule",
            format!("{why} couplings[{i}] (docs/architecture.md); use \"serial\""),
        ));
    }
    for (i, (node, _)) in run.print.iter().enumerate() {
        if !nodes.iter().any(|n| &n.name == node) {
            let names: Vec<&str> = nodes.iter().map(|n| n.name.as_str()).collect();
            return Err(err(
                format!("run.print[{i}]"),
                format!("no node '{node}' (the case has {})", names.join(", ")),
            ));
        }
    }
    Ok(Case {
        path: path.to_path_buf(),
        text: text.to_string(),
        run,
        nodes,
        couplings,
        variants: file.variants.keys().cloned().collect(),
        warnings: Vec::new(),
    })
}

/// `[run]`, checked and with its defaults.
/// `[run]`, its `output` relative to the case file's folder (`case_dir`), as every path a case
/// file names is.
fn settle_run(r: &RunSection, case_dir: &Path) -> Result<RunConfig, ConfigError> {
    let name = r.name.clone().unwrap_or_else(|| "run".into());
    if !valid_name(&name) {
        return Err(err(
            "run.name",
            format!("must be 1–32 characters of [A-Za-z0-9_-], got '{name}'"),
        ));
    }
    let (end_time, window) = run_times(r)?;
    let (heartbeat_ms, heartbeat_timeout, stall_timeout) = run_liveness(r)?;
    let (energy_bound, energy_floor) = run_energy_guard(r)?;
    let (balance_momentum, balance_energy) = run_balance(r)?;
    let positive = |key: &str, v: Option<f64>, default: f64| {
        let v = v.unwrap_or(default);
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(err(format!("run.{key}"), format!("must be > 0 s, got {v}")))
        }
    };
    Ok(RunConfig {
        name,
        end_time,
        window,
        schedule: match r.schedule {
            None | Some(ScheduleName::Serial) => Schedule::Serial,
            Some(ScheduleName::Parallel) => Schedule::Parallel,
        },
        transport: match r.transport {
            None | Some(TransportName::Shm) => TransportKind::Shm,
            Some(TransportName::Zenoh) => TransportKind::Zenoh,
        },
        output: case_dir.join(r.output.as_deref().unwrap_or("out")),
        output_every: r.output_every.unwrap_or(0),
        heartbeat_ms,
        heartbeat_timeout,
        stall_timeout,
        listen: r.listen.clone().unwrap_or_else(|| "tcp/127.0.0.1:0".into()),
        join_timeout: positive("join_timeout", r.join_timeout, 300.0)?,
        start_timeout: positive("start_timeout", r.start_timeout, 60.0)?,
        record_every: r.record_every.unwrap_or(1).max(1),
        checkpoint_every: r.checkpoint_every.unwrap_or(0),
        pictures: match r.pictures {
            None | Some(PicturesName::End) => Pictures::End,
            Some(PicturesName::Frames) => Pictures::Frames,
            Some(PicturesName::None) => Pictures::None,
        },
        energy_bound,
        energy_floor,
        balance_momentum,
        balance_energy,
        print: run_print(r)?,
    })
}

/// `[run.balance]`: both thresholds > 0 (and finite), with their defaults.
fn run_balance(r: &RunSection) -> Result<(f64, f64), ConfigError> {
    let b = r.balance.clone().unwrap_or_default();
    let share = |key: &str, v: Option<f64>, default: f64| {
        let v = v.unwrap_or(default);
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(err(
                format!("run.balance.{key}"),
                format!("must be > 0 (a share of the residual's scale), got {v}"),
            ))
        }
    };
    Ok((
        share("momentum", b.momentum, crate::guard::MOMENTUM_WARNING)?,
        share("energy", b.energy, crate::guard::ENERGY_WARNING)?,
    ))
}

/// `run.print`: each entry "NODE.SCALAR" (the node checked once the nodes are known).
fn run_print(r: &RunSection) -> Result<Vec<(String, String)>, ConfigError> {
    let mut out = Vec::new();
    for (i, e) in r.print.iter().flatten().enumerate() {
        match e.split_once('.') {
            Some((node, scalar)) if !node.is_empty() && !scalar.is_empty() => {
                out.push((node.to_string(), scalar.to_string()));
            }
            _ => {
                return Err(err(
                    format!("run.print[{i}]"),
                    format!("must be \"NODE.SCALAR\" (e.g. \"gas.max_pressure\"), got '{e}'"),
                ));
            }
        }
    }
    Ok(out)
}

/// `run.end_time` and `run.window`: positive, a window no longer than the run, at most 1e9
/// windows.
fn run_times(r: &RunSection) -> Result<(f64, f64), ConfigError> {
    let end_time = r.end_time;
    if !(end_time.is_finite() && end_time > 0.0) {
        return Err(err("run.end_time", format!("must be > 0, got {end_time}")));
    }
    let window = r.window;
    if !(window.is_finite() && window > 0.0 && window <= end_time) {
        return Err(err(
            "run.window",
            format!("must be > 0 and ≤ run.end_time ({end_time}), got {window}"),
        ));
    }
    if end_time / window > 1e9 {
        return Err(err(
            "run.window",
            format!("gives {:.3e} windows; at most 1e9", end_time / window),
        ));
    }
    Ok((end_time, window))
}

/// `run.heartbeat_ms`, `run.heartbeat_timeout` (more than two beats) and `run.stall_timeout`
/// (more than the heartbeat timeout), with their defaults.
fn run_liveness(r: &RunSection) -> Result<(u64, f64, f64), ConfigError> {
    let heartbeat_ms = r.heartbeat_ms.unwrap_or(200);
    if !(10..=60_000).contains(&heartbeat_ms) {
        return Err(err(
            "run.heartbeat_ms",
            format!("must be in 10..=60000, got {heartbeat_ms}"),
        ));
    }
    let heartbeat_timeout = r.heartbeat_timeout.unwrap_or(3.0);
    if !(heartbeat_timeout.is_finite() && heartbeat_timeout * 1000.0 > 2.0 * heartbeat_ms as f64) {
        return Err(err(
            "run.heartbeat_timeout",
            format!(
                "must exceed two heartbeats ({} s), got {heartbeat_timeout}",
                2.0 * heartbeat_ms as f64 / 1000.0
            ),
        ));
    }
    let stall_timeout = r.stall_timeout.unwrap_or(30.0);
    if !(stall_timeout.is_finite() && stall_timeout > heartbeat_timeout) {
        return Err(err(
            "run.stall_timeout",
            format!(
                "must exceed run.heartbeat_timeout ({heartbeat_timeout} s), got {stall_timeout}"
            ),
        ));
    }
    Ok((heartbeat_ms, heartbeat_timeout, stall_timeout))
}

/// `run.energy_bound` (> 1, or 0 for none) and `run.energy_floor` (≥ 0 J), with their
/// defaults.
fn run_energy_guard(r: &RunSection) -> Result<(f64, f64), ConfigError> {
    let energy_bound = r.energy_bound.unwrap_or(crate::guard::DEFAULT_FACTOR);
    if !(energy_bound == 0.0 || energy_bound.is_finite() && energy_bound > 1.0) {
        return Err(err(
            "run.energy_bound",
            format!(
                "must be > 1 (a multiple of the initial energy plus the external work), or 0 to turn the bound off, got {energy_bound}"
            ),
        ));
    }
    let energy_floor = r.energy_floor.unwrap_or(crate::guard::DEFAULT_FLOOR);
    if !(energy_floor.is_finite() && energy_floor >= 0.0) {
        return Err(err(
            "run.energy_floor",
            format!("must be ≥ 0 J, got {energy_floor}"),
        ));
    }
    Ok((energy_bound, energy_floor))
}

/// `[nodes.NAME]`: its name, its parameters (a table, or a file relative to `case_dir`), and
/// its executable on this host unless it is remote.
fn settle_node(name: &str, n: &NodeSection, case_dir: &Path) -> Result<NodeConfig, ConfigError> {
    let p = format!("nodes.{name}.");
    if !valid_name(name) || name == "coordinator" {
        return Err(err(
            format!("nodes.{name}"),
            "node names are 1–32 characters of [A-Za-z0-9_-] and not 'coordinator'",
        ));
    }
    let params = match &n.params {
        None => toml::Table::new(),
        Some(toml::Value::Table(t)) => t.clone(),
        Some(toml::Value::String(f)) => read_params_file(&case_dir.join(f), &format!("{p}params"))?,
        Some(_) => return Err(err(format!("{p}params"), "must be a table or a file name")),
    };
    let remote = n.remote.unwrap_or(false);
    let exe = if remote {
        None
    } else {
        Some(resolve_exe(&n.solver, case_dir).ok_or_else(|| {
            err(
                format!("{p}solver"),
                format!(
                    "no executable '{}' beside cosim or at that path (build it: cargo build --release --workspace)",
                    n.solver
                ),
            )
        })?)
    };
    Ok(NodeConfig {
        name: name.to_string(),
        solver: n.solver.clone(),
        exe,
        model: n.model.clone(),
        params,
        remote,
        interfaces: None,
        fields: Vec::new(),
        points: Vec::new(),
        window_limits: Vec::new(),
        positions: BTreeMap::new(),
    })
}

/// A node's `params = "FILE"`: the table in `file`; errors name `key`.
pub(super) fn read_params_file(file: &Path, key: &str) -> Result<toml::Table, ConfigError> {
    let s = std::fs::read_to_string(file)
        .map_err(|e| err(key, format!("cannot read {}: {e}", file.display())))?;
    toml::from_str(&s).map_err(|e| err(key, format!("{}: {}", file.display(), e.message())))
}

/// `couplings[i]`: its members among `nodes`, name, decoupling rule, tolerance and fields.
fn settle_coupling(
    i: usize,
    c: &CouplingSection,
    nodes: &[NodeConfig],
) -> Result<CouplingConfig, ConfigError> {
    let p = format!("couplings[{i}].");
    let kind = c.kind;
    let (sides, method, driver, responder) = settle_members(c, &p, nodes)?;
    if driver.0 == responder.0 {
        return Err(err(
            format!("{p}responder"),
            "a node cannot couple to itself",
        ));
    }
    let name = c
        .name
        .clone()
        .unwrap_or_else(|| format!("{}-{}", driver.0, responder.0));
    if !valid_name(&name) {
        return Err(err(
            format!("{p}name"),
            format!("must be 1–32 characters of [A-Za-z0-9_-], got '{name}'"),
        ));
    }
    let decouple = settle_decouple(c, &p, nodes)?;
    let point_tolerance = c.point_tolerance.unwrap_or(DEFAULT_POINT_TOLERANCE);
    if !(point_tolerance.is_finite() && point_tolerance > 0.0) {
        return Err(err(
            format!("{p}point_tolerance"),
            format!("must be a number > 0, got {point_tolerance}"),
        ));
    }
    let (df, rf) = default_fields(kind);
    Ok(CouplingConfig {
        point_tolerance,
        sides,
        method,
        decouple,
        name,
        kind,
        driver,
        responder,
        driver_fields: c.driver_fields.clone().unwrap_or(df),
        responder_fields: c.responder_fields.clone().unwrap_or(rf),
    })
}

/// A coupling's members as `("node", "interface")` pairs: a lagrange coupling's `sides` and
/// `method` (its first two sides standing for driver and responder), any other's `driver`
/// and `responder` (and neither `sides` nor `method`). `p`: the coupling's key path.
#[allow(clippy::type_complexity)]
fn settle_members(
    c: &CouplingSection,
    p: &str,
    nodes: &[NodeConfig],
) -> Result<
    (
        Vec<(String, String)>,
        Option<protocol::scheme::lagrange::Method>,
        (String, String),
        (String, String),
    ),
    ConfigError,
> {
    let member = |key: &str, s: &str| -> Result<(String, String), ConfigError> {
        let (n, i) = s
            .split_once('.')
            .ok_or_else(|| err(key, format!("must be \"node.interface\", got \"{s}\"")))?;
        if !nodes.iter().any(|x| x.name == n) {
            let known = nodes.iter().map(|x| x.name.as_str());
            return Err(err(key, super::resolved::unknown("node", n, known)));
        }
        Ok((n.to_string(), i.to_string()))
    };
    let split = |key: &str, v: &Option<String>| -> Result<(String, String), ConfigError> {
        let v = v
            .as_deref()
            .ok_or_else(|| err(format!("{p}{key}"), "missing"))?;
        member(&format!("{p}{key}"), v)
    };
    let (sides, method) = if scheme::of(c.kind).coordinator_solved() {
        lagrange_sides(c, p, &member)?
    } else {
        for (k, given) in [("sides", c.sides.is_some()), ("method", c.method.is_some())] {
            if given {
                return Err(err(
                    format!("{p}{k}"),
                    "only a lagrange coupling takes it (kind = \"lagrange\")",
                ));
            }
        }
        (Vec::new(), None)
    };
    let (driver, responder) = match sides.as_slice() {
        [a, b, ..] => (a.clone(), b.clone()),
        _ => (
            split("driver", &c.driver)?,
            split("responder", &c.responder)?,
        ),
    };
    Ok((sides, method, driver, responder))
}

/// A coupling's `decouple_at` and `decouple_when`, which only a scheme that decouples takes.
fn settle_decouple(
    c: &CouplingSection,
    p: &str,
    nodes: &[NodeConfig],
) -> Result<Decouple, ConfigError> {
    let mut decouple = Decouple {
        at: c.decouple_at,
        when: None,
    };
    if let Some(at) = decouple.at
        && !(at.is_finite() && at > 0.0)
    {
        return Err(err(
            format!("{p}decouple_at"),
            format!("must be a time > 0, got {at}"),
        ));
    }
    if let Some(w) = &c.decouple_when {
        decouple.when =
            Some(parse_when(w, nodes).map_err(|r| err(format!("{p}decouple_when"), r))?);
    }
    if decouple.is_set() && !scheme::of(c.kind).decouples() {
        let key = if decouple.at.is_some() {
            "decouple_at"
        } else {
            "decouple_when"
        };
        return Err(err(
            format!("{p}{key}"),
            "only an immersed coupling can be decoupled (the solid goes on alone, seed 000 §4)",
        ));
    }
    Ok(decouple)
}

/// The lagrange coupling's rules across the case: whole windows (each window is a system
/// step), no side on the GPU, and a node a side of one lagrange coupling at most.
fn check_lagrange(
    run: &RunConfig,
    nodes: &[NodeConfig],
    couplings: &[CouplingConfig],
) -> Result<(), ConfigError> {
    for (i, c) in couplings.iter().enumerate() {
        if !scheme::of(c.kind).coordinator_solved() {
            continue;
        }
        let w = run.end_time / run.window;
        if (w - w.round()).abs() > 1e-9 * w.max(1.0) {
            return Err(err(
                "run.end_time",
                format!(
                    "must be a whole number of windows for the lagrange coupling couplings[{i}] (each window is a system step), got {w} windows"
                ),
            ));
        }
        for (k, (node, _)) in c.sides.iter().enumerate() {
            // The device path has no lagrange side (its state lives on the device between
            // windows): refused here rather than once the nodes are set up.
            let params = nodes.iter().find(|n| &n.name == node);
            if params
                .and_then(|n| n.params.get("device"))
                .and_then(|d| d.as_str())
                == Some("gpu")
            {
                return Err(err(
                    format!("nodes.{node}.params.device"),
                    format!(
                        "node '{node}' is a side of the lagrange coupling couplings[{i}], which runs on the cpu: use device = \"cpu\""
                    ),
                ));
            }
            if let Some(j) = couplings[..i].iter().position(|o| {
                scheme::of(o.kind).coordinator_solved() && o.sides.iter().any(|s| &s.0 == node)
            }) {
                return Err(err(
                    format!("couplings[{i}].sides[{k}]"),
                    format!(
                        "node '{node}' is already a side of the lagrange coupling couplings[{j}] (a node takes one)"
                    ),
                ));
            }
        }
    }
    Ok(())
}

pub(super) fn valid_name(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 32
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

/// Default fields of a coupling kind, as its scheme declares them: (driver sends,
/// responder sends).
pub fn default_fields(kind: CouplingKind) -> (Vec<String>, Vec<String>) {
    let v = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let (d, r) = scheme::of(kind).default_fields();
    (v(d), v(r))
}

/// Share of its largest stable step from which an explicit step is warned of.
const NEAR_LIMIT: f64 = 0.95;

/// Refuse a window at which a lagrange side's explicit integrator, whose steps per window are
/// fixed, would step beyond its largest stable step (it would blow up within a few windows),
/// naming `run.window`, the largest window that works and the substeps that would; warn of
/// one within 5 % of it. A node that sub-cycles at its own stable step states no limit.
fn check_stability(case: &Case) -> Result<Vec<String>, ConfigError> {
    use protocol::LimitApplies;
    let window = case.run.window;
    let mut warnings = Vec::new();
    for (i, c) in case.couplings.iter().enumerate() {
        if !scheme::of(c.kind).coordinator_solved() {
            continue;
        }
        let gs4_or_ph = c.method != Some(scheme::lagrange::Method::Gc);
        for (node, _) in &c.sides {
            let Some(n) = case.nodes.iter().find(|n| &n.name == node) else {
                continue;
            };
            for l in &n.window_limits {
                let holds = match l.applies {
                    LimitApplies::LagrangeSide => true,
                    LimitApplies::LagrangeSideGs4OrPh => gs4_or_ph,
                };
                // A limit without a positive step (NaN included) states nothing to check.
                if !holds || l.max_step.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                    continue;
                }
                let step = window / l.substeps.max(1) as f64;
                let ratio = step / l.max_step;
                if l.kind == protocol::LimitKind::Resonance {
                    if ratio > 1.0 + 1e-12 {
                        warnings.push(resonance_warning(node, i, &c.name, l, window, step));
                    }
                    continue;
                }
                let what = format!(
                    "node '{node}' (a side of the lagrange coupling couplings[{i}] '{}') steps {} {} time{} per window: at run.window = {window:e} s a step is {step:.4e} s, {ratio:.3} × its largest stable step {:.4e} s",
                    c.name,
                    l.integrator,
                    l.substeps,
                    if l.substeps == 1 { "" } else { "s" },
                    l.max_step,
                );
                if ratio > 1.0 + 1e-12 {
                    let fix = match &l.key {
                        Some(k) => format!(
                            "; or set nodes.{node}.{k} = {}",
                            (window / l.max_step - 1e-9).ceil().max(1.0)
                        ),
                        None => String::new(),
                    };
                    return Err(err(
                        "run.window",
                        format!(
                            "{what}: unstable. The largest run.window that works is {:.6e} s{fix}",
                            l.max_window()
                        ),
                    ));
                }
                if ratio > NEAR_LIMIT {
                    warnings.push(format!(
                        "{what}: within {:.0} % of the limit, stable only while nothing stiffens it",
                        (1.0 - NEAR_LIMIT) * 100.0
                    ));
                }
            }
        }
    }
    Ok(warnings)
}

/// The warning for a lagrange side whose steps pass its resonance limit: where it stands,
/// what it costs, and the ways out (a window that clears it, a dissipative design).
fn resonance_warning(
    node: &str,
    i: usize,
    coupling: &str,
    l: &protocol::WindowLimit,
    window: f64,
    step: f64,
) -> String {
    format!(
        "node '{node}' (a side of the lagrange coupling couplings[{i}] '{coupling}') steps {} {} \
         times per window: at run.window = {window:e} s a step is {step:.4e} s, past {:.4e} s, \
         where a mode of its mesh turns whole periods in one window and the window-end \
         constraint of gs4 and ph cannot hold it: the multipliers may lose accuracy. Clear of \
         it: run.window ≤ {:.6e} s at these substeps, or a dissipative design on this side \
         (\"Sub-cycling resonance\" in docs/architecture.md gives the limit at other \
         substeps)",
        l.integrator,
        l.substeps,
        l.max_step,
        l.max_window(),
    )
}

/// The length the distance between matched points is judged against: the interface's mean
/// point spacing along its extent (the diagonal of the bounding box of both sides' points
/// over their count less one), or 1 m for a single point, which has no extent.
pub fn point_spacing(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let n = a.len().max(b.len());
    if n < 2 {
        return 1.0;
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for x in a.iter().chain(b) {
        for d in 0..3 {
            lo[d] = lo[d].min(x[d]);
            hi[d] = hi[d].max(x[d]);
        }
    }
    let diagonal = (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt();
    diagonal / (n - 1) as f64
}

/// Refuse a kinematic coupling whose sides hold as many points each (a point-to-point
/// binding) but a responder point lies farther from its nearest driver point (the point the
/// runtime's nearest-point mapping would tie it to) than `point_tolerance` of the interface's
/// point spacing: the coupling would tie points that are not the same (a shifted node or
/// mesh). Checked where both nodes gave their positions; sides of different counts are
/// non-matching meshes, mapped by design.
fn check_coincident(case: &Case) -> Result<(), ConfigError> {
    for (i, c) in case.couplings.iter().enumerate() {
        if !scheme::of(c.kind).ties_points() {
            continue;
        }
        let at = |(node, iface): &(String, String)| {
            case.nodes
                .iter()
                .find(|n| &n.name == node)
                .and_then(|n| n.positions.get(iface))
        };
        let (Some(d), Some(r)) = (at(&c.driver), at(&c.responder)) else {
            continue;
        };
        if d.len() != r.len() || d.is_empty() {
            continue;
        }
        let limit = c.point_tolerance * point_spacing(d, r);
        let dist =
            |p: &[f64; 3], q: &[f64; 3]| (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt();
        for (k, q) in r.iter().enumerate() {
            // The nearest driver point; a NaN distance is never within the limit.
            let (j, gap) = d.iter().map(|p| dist(p, q)).enumerate().fold(
                (0, f64::INFINITY),
                |best, (j, g)| {
                    if g < best.1 || g.is_nan() {
                        (j, g)
                    } else {
                        best
                    }
                },
            );
            if gap.is_nan() || gap > limit {
                return Err(err(
                    format!("couplings[{i}]"),
                    format!(
                        "coupling '{}': point {k} of {}.{} at {q:?} is {gap:.4e} m from the nearest point ({j}) of {}.{} at {:?}, more than point_tolerance = {} × the interface's point spacing = {limit:.4e} m: the two sides do not coincide (a shifted node or mesh?)",
                        c.name,
                        c.responder.0,
                        c.responder.1,
                        c.driver.0,
                        c.driver.1,
                        d[j],
                        c.point_tolerance
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Ask every node executable found on this host to describe itself (in parallel): its own
/// validation names a bad parameter, and its interfaces let us check the couplings before
/// anything is launched. A remote node not on this host is checked when it joins.
pub(super) fn describe(case: &mut Case) -> Result<(), ConfigError> {
    let case_dir = case
        .path
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let checked =
        super::describe::describe_nodes(&case.nodes, &case_dir, super::describe::DESCRIBE_TIMEOUT)?;
    for (n, c) in case.nodes.iter_mut().zip(checked) {
        if let super::describe::Checked::Described(d) = c {
            n.fields = d
                .interfaces
                .iter()
                .map(|i| (i.provides.clone(), i.accepts.clone()))
                .collect();
            n.points = d.interfaces.iter().map(|i| i.points).collect();
            n.interfaces = Some(d.interfaces.into_iter().map(|i| i.name).collect());
            n.window_limits = d.window_limits;
            n.positions = d.positions;
        }
    }
    check_coincident(case)?;
    case.warnings = check_stability(case)?;
    check_interfaces(case, |node| {
        case.nodes
            .iter()
            .find(|n| n.name == node)
            .and_then(|n| n.interfaces.clone())
    })?;
    check_fields(case, |node, iface| {
        let cfg = case.nodes.iter().find(|x| x.name == node)?;
        let pos = cfg.interfaces.as_ref()?.iter().position(|x| x == iface)?;
        cfg.fields
            .get(pos)
            .map(|(p, a)| (p.as_slice(), a.as_slice()))
    })
}

/// Check remote node `node`, which was not described before the run, by the interfaces of
/// its `Describe` at the handshake: every coupling it is a member of
/// must find its interface and the fields the scheme needs, refused as before the run.
pub fn check_joined(
    case: &Case,
    node: &str,
    described: &[protocol::message::InterfaceDescription],
) -> Result<(), ConfigError> {
    let only = |n: &str| n == node;
    check_interfaces(case, |n| {
        only(n).then(|| described.iter().map(|i| i.name.clone()).collect())
    })?;
    check_fields(case, |n, iface| {
        let d = described.iter().find(|i| only(n) && i.name == iface)?;
        Some((d.provides.as_slice(), d.accepts.as_slice()))
    })
}

/// Refuse a coupling member naming an interface its node does not offer; `offered` gives a
/// node's interfaces (None: not known yet, a remote node checked when it joins).
fn check_interfaces(
    case: &Case,
    offered: impl Fn(&str) -> Option<Vec<String>>,
) -> Result<(), ConfigError> {
    for (i, c) in case.couplings.iter().enumerate() {
        for (key, (node, iface)) in c.keyed_members() {
            if let Some(list) = offered(node)
                && !list.iter().any(|x| x == iface)
            {
                return Err(err(
                    format!("couplings[{i}].{key}"),
                    format!(
                        "node '{node}' has no interface '{iface}' (it offers: {})",
                        if list.is_empty() {
                            "none".to_string()
                        } else {
                            list.join(", ")
                        }
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Refuse a coupling whose node does not provide or accept a field its scheme needs, by the
/// node's own description: the key, the coupling, the node, the field.
/// `fields` gives what a node's interface provides and accepts (None: not known yet, a remote
/// node checked when it joins).
fn check_fields<'d>(
    case: &Case,
    fields: impl Fn(&str, &str) -> Option<(&'d [String], &'d [String])>,
) -> Result<(), ConfigError> {
    for (i, c) in case.couplings.iter().enumerate() {
        for n in required_fields(c) {
            let (node, iface) = n.member;
            let Some((provides, accepts)) = fields(node, iface) else {
                continue;
            };
            let (have, verb) = if n.provide {
                (provides, "provide")
            } else {
                (accepts, "accept")
            };
            if let Some(f) = n.fields.iter().find(|f| !have.contains(f)) {
                return Err(err(
                    format!("couplings[{i}].{}", n.key),
                    format!(
                        "the {} coupling '{}' needs node '{node}' (interface '{iface}') to {verb} field '{f}'; it {verb}s: {}",
                        c.kind.as_str(),
                        c.name,
                        if have.is_empty() {
                            "none".to_string()
                        } else {
                            have.join(", ")
                        }
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// `"node.quantity >= level"` (or `>`): a scalar a node reports every window.
fn parse_when(s: &str, nodes: &[NodeConfig]) -> Result<(String, String, f64), String> {
    let form = "must read \"NODE.QUANTITY >= LEVEL\" (a quantity the node reports)";
    let (lhs, rhs) = s
        .split_once(">=")
        .or_else(|| s.split_once('>'))
        .ok_or_else(|| format!("{form}, got \"{s}\""))?;
    let (node, q) = lhs
        .trim()
        .split_once('.')
        .ok_or_else(|| format!("{form}, got \"{s}\""))?;
    if !nodes.iter().any(|n| n.name == node) {
        let known = nodes.iter().map(|n| n.name.as_str());
        return Err(super::resolved::unknown("node", node, known));
    }
    if q.is_empty() {
        return Err(format!("{form}, got \"{s}\""));
    }
    let level: f64 = rhs
        .trim()
        .parse()
        .map_err(|_| format!("level '{}' is not a number", rhs.trim()))?;
    if !level.is_finite() {
        return Err(format!("level must be finite, got {level}"));
    }
    Ok((node.to_string(), q.to_string(), level))
}

/// The sides and method of the lagrange coupling at `p` (`couplings[i].`): N ≥ 2 sides
/// "node.interface", each node once (one interface per node and coupling), and no
/// driver/responder keys.
#[allow(clippy::type_complexity)]
fn lagrange_sides(
    c: &CouplingSection,
    p: &str,
    member: &dyn Fn(&str, &str) -> Result<(String, String), ConfigError>,
) -> Result<
    (
        Vec<(String, String)>,
        Option<protocol::scheme::lagrange::Method>,
    ),
    ConfigError,
> {
    for (k, given) in [
        ("driver", c.driver.is_some()),
        ("responder", c.responder.is_some()),
        ("driver_fields", c.driver_fields.is_some()),
        ("responder_fields", c.responder_fields.is_some()),
    ] {
        if given {
            return Err(err(
                format!("{p}{k}"),
                "a lagrange coupling names its subdomains in `sides` (no driver or responder)",
            ));
        }
    }
    let list = c.sides.as_ref().ok_or_else(|| {
        err(
            format!("{p}sides"),
            "missing (e.g. [\"left.tip\", \"right.root\"])",
        )
    })?;
    if list.len() < 2 {
        return Err(err(
            format!("{p}sides"),
            format!("needs at least two subdomains, got {}", list.len()),
        ));
    }
    let mut sides: Vec<(String, String)> = Vec::new();
    for (k, s) in list.iter().enumerate() {
        let side = member(&format!("{p}sides[{k}]"), s)?;
        if sides.iter().any(|x| x.0 == side.0) {
            return Err(err(
                format!("{p}sides[{k}]"),
                format!(
                    "node '{}' is already a side of this coupling (one interface per node)",
                    side.0
                ),
            ));
        }
        sides.push(side);
    }
    let method = match &c.method {
        None => protocol::scheme::lagrange::Method::Gs4,
        Some(m) => m
            .parse()
            .map_err(|e: String| err(format!("{p}method"), e))?,
    };
    Ok((sides, Some(method)))
}
