//! `cosim info`: what a recording holds (its case, nodes, couplings, windows, channels and
//! last balance), as text or as a JSON document.

use crate::record::{self, Recorded};
use crate::replay::{Decoded, case_of, decode_all};
use protocol::*;
use std::collections::BTreeMap;
use std::path::Path;

/// What `cosim info` reports on a recording (also its `--json` document).
#[derive(Debug, serde::Serialize)]
pub struct RunInfo {
    pub recording: String,
    pub bytes: u64,
    /// False when the writer stopped early (a killed coordinator).
    pub complete: bool,
    pub segments: Vec<String>,
    pub run: String,
    pub end_time: Option<f64>,
    pub window: Option<f64>,
    /// As the recorded case says; `None` where the recording holds no case.
    pub schedule: Option<String>,
    pub transport: Option<String>,
    pub nodes: Vec<NodeInfo>,
    pub couplings: Vec<CouplingInfo>,
    pub windows_completed: u64,
    pub messages: u64,
    pub channels: Vec<ChannelInfo>,
    /// The last `/cosim/balance` row as recorded, with the run's largest imbalance and
    /// residual beside it.
    pub balance: Option<serde_json::Value>,
    pub largest_momentum_imbalance: Option<f64>,
    pub largest_momentum_residual: Option<f64>,
    /// The balance as a user reads it first: the largest residuals against their scales and
    /// the case's `[run.balance]` thresholds, and the warnings they give.
    pub verdict: Option<Verdict>,
}

/// The run's largest residuals, their thresholds and the balance warnings (those of
/// `summary.json`, from the recording alone).
#[derive(Debug, serde::Serialize)]
pub struct Verdict {
    /// Largest momentum residual over the larger of the largest impulse and gross momentum
    /// (None for a recording made before the rows carried their scales).
    pub momentum_relative: Option<f64>,
    /// Largest energy residual (signed: created > 0) over the largest energy or work.
    pub energy_relative: f64,
    pub momentum_warning: f64,
    pub energy_warning: f64,
    pub warnings: Vec<String>,
}

#[derive(Debug, serde::Serialize)]
pub struct NodeInfo {
    pub name: String,
    pub model: String,
    pub couplings: usize,
}

#[derive(Debug, serde::Serialize)]
pub struct CouplingInfo {
    pub name: String,
    pub kind: String,
    pub from: String,
    pub to: String,
}

#[derive(Debug, serde::Serialize)]
pub struct ChannelInfo {
    pub topic: String,
    pub messages: u64,
    pub bytes: u64,
}

/// Everything `cosim info` says about a recording (and the segments restarts added to it).
pub fn run_info(path: &Path) -> anyhow::Result<RunInfo> {
    let (msgs, complete) = record::read_all(path)?;
    let bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    let segments = record::segments(path)
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    let dec = decode_all(&msgs);
    let case = CaseFacts::of(&msgs);
    let run = dec.first().map(|d| d.env.run.clone()).unwrap_or_default();
    let (nodes, couplings) = nodes_and_couplings(&dec);
    let windows_completed = dec
        .iter()
        .filter_map(|d| match &d.env.message {
            Message::Done(dn) => Some(dn.window),
            _ => None,
        })
        .max()
        .unwrap_or(0);
    let mut counts: BTreeMap<&str, (u64, u64)> = BTreeMap::new();
    for m in &msgs {
        let e = counts.entry(m.topic.as_str()).or_default();
        e.0 += 1;
        e.1 += m.data.len() as u64;
    }
    let rows: Vec<serde_json::Value> = msgs
        .iter()
        .filter(|m| m.topic == "/cosim/balance")
        .filter_map(|m| serde_json::from_slice(&m.data).ok())
        .collect();
    let largest = |key: &str| rows.iter().filter_map(|v| v[key].as_f64()).reduce(f64::max);
    let verdict = verdict(&rows, &case);
    Ok(RunInfo {
        verdict,
        recording: path.display().to_string(),
        bytes,
        complete,
        segments,
        run,
        end_time: case.end_time,
        window: case.window,
        schedule: case.schedule,
        transport: case.transport,
        nodes,
        couplings,
        windows_completed,
        messages: msgs.len() as u64,
        channels: counts
            .into_iter()
            .map(|(t, (n, b))| ChannelInfo {
                topic: t.to_string(),
                messages: n,
                bytes: b,
            })
            .collect(),
        largest_momentum_imbalance: largest("momentum_imbalance"),
        largest_momentum_residual: largest("momentum_residual"),
        balance: rows.last().cloned(),
    })
}

/// `cosim info`: [`run_info`] as text.
pub fn info(path: &Path) -> anyhow::Result<String> {
    use std::fmt::Write;
    let i = run_info(path)?;
    let mut s = String::new();
    writeln!(
        s,
        "recording  {} ({:.1} kB, {})",
        i.recording,
        i.bytes as f64 / 1e3,
        if i.complete {
            "complete"
        } else {
            "INCOMPLETE: writer stopped early"
        }
    )?;
    if let Some(v) = &i.verdict {
        write_verdict(&mut s, v)?;
    }
    if i.segments.len() > 1 {
        writeln!(
            s,
            "segments   {} (restarted {} times, read as one run)",
            i.segments.join(" + "),
            i.segments.len() - 1
        )?;
    }
    match (&i.schedule, &i.transport) {
        (Some(schedule), Some(transport)) => {
            let opt = |x: Option<f64>| x.map(plain).unwrap_or_default();
            writeln!(
                s,
                "case       end_time {} s, window {} s, schedule {schedule}, transport {transport}",
                opt(i.end_time),
                opt(i.window),
            )?
        }
        _ => writeln!(s, "case       not in the recording")?,
    }
    writeln!(s, "run        {}", i.run)?;
    write_parts(&mut s, &i)?;
    if let Some(v) = &i.balance {
        write_balance(&mut s, &i, v)?;
    }
    Ok(s)
}

/// The nodes, couplings, windows and channels lines of [`info`].
fn write_parts(s: &mut String, i: &RunInfo) -> std::fmt::Result {
    use std::fmt::Write;
    writeln!(s, "nodes")?;
    for n in &i.nodes {
        writeln!(
            s,
            "  {:<12} model {:<20} couplings {}",
            n.name, n.model, n.couplings
        )?;
    }
    writeln!(s, "couplings")?;
    for c in &i.couplings {
        writeln!(s, "  {:<12} {} {} → {}", c.name, c.kind, c.from, c.to)?;
    }
    writeln!(s, "windows    {} completed", i.windows_completed)?;
    writeln!(
        s,
        "messages   {} in {} channels",
        i.messages,
        i.channels.len()
    )?;
    for c in &i.channels {
        writeln!(
            s,
            "  {:<48} {:>8} msgs {:>12.1} kB",
            c.topic,
            c.messages,
            c.bytes as f64 / 1e3
        )?;
    }
    Ok(())
}

/// The run's settings the recorded case gives (what it leaves out is the default it ran
/// with); all None where the recording holds no case.
#[derive(Default)]
struct CaseFacts {
    end_time: Option<f64>,
    window: Option<f64>,
    schedule: Option<String>,
    transport: Option<String>,
    /// `[run.balance]` as recorded (None: the default).
    balance_momentum: Option<f64>,
    balance_energy: Option<f64>,
}

impl CaseFacts {
    fn of(msgs: &[Recorded]) -> CaseFacts {
        let Some(run) = case_of(msgs)
            .ok()
            .and_then(|(case, _)| case.get("run").and_then(|r| r.as_table()).cloned())
        else {
            return CaseFacts::default();
        };
        let num = |k: &str| {
            run.get(k)
                .and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
        };
        let text = |k: &str, default: &str| {
            Some(
                run.get(k)
                    .and_then(|v| v.as_str())
                    .unwrap_or(default)
                    .to_string(),
            )
        };
        let balance = |k: &str| {
            run.get("balance")
                .and_then(|b| b.get(k))
                .and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
        };
        CaseFacts {
            balance_momentum: balance("momentum"),
            balance_energy: balance("energy"),
            end_time: num("end_time"),
            window: num("window"),
            schedule: text("schedule", "serial"),
            transport: text("transport", "shm"),
        }
    }
}

/// The balance rows' verdict: the audit's largest residuals and scales rebuilt from the
/// recorded rows, judged by the case's thresholds as the run judged them.
fn verdict(rows: &[serde_json::Value], case: &CaseFacts) -> Option<Verdict> {
    let last = rows.last()?;
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64();
    let mut a = crate::engine::Audit::default();
    for r in rows {
        a.worst_resid = a.worst_resid.max(f(r, "momentum_residual").unwrap_or(0.0));
        let e = f(r, "energy_residual").unwrap_or(0.0);
        if e.abs() > a.worst_e_resid.abs() {
            a.worst_e_resid = e;
        }
    }
    let momentum_scale = f(last, "momentum_scale");
    a.momentum_scale = momentum_scale.unwrap_or(0.0);
    a.energy_scale = match f(last, "energy_scale") {
        Some(e) => e,
        // an older recording: the largest energy, external work or initial energy
        None => rows
            .iter()
            .flat_map(|r| {
                let (e, w) = (
                    f(r, "energy").unwrap_or(0.0),
                    f(r, "external_work").unwrap_or(0.0),
                );
                let e0 = e - w - f(r, "energy_residual").unwrap_or(0.0);
                [e.abs(), w.abs(), e0.abs()]
            })
            .fold(0.0, f64::max),
    };
    let (momentum_warning, energy_warning) = (
        case.balance_momentum
            .unwrap_or(crate::guard::MOMENTUM_WARNING),
        case.balance_energy.unwrap_or(crate::guard::ENERGY_WARNING),
    );
    Some(Verdict {
        momentum_relative: momentum_scale.map(|_| a.momentum_relative()),
        energy_relative: a.energy_relative(),
        momentum_warning,
        energy_warning,
        warnings: crate::engine::summary::balance_warnings(
            &a,
            if momentum_scale.is_some() {
                momentum_warning
            } else {
                f64::INFINITY
            },
            energy_warning,
        ),
    })
}

/// The nodes the recording welcomed, and the couplings their drivers' bindings name.
fn nodes_and_couplings(dec: &[Decoded]) -> (Vec<NodeInfo>, Vec<CouplingInfo>) {
    let mut nodes = Vec::new();
    let mut couplings = BTreeMap::new();
    for d in dec {
        let Message::Welcome(w) = &d.env.message else {
            continue;
        };
        let node = d.topic.rsplit('/').nth(1).unwrap_or("?").to_string();
        for b in w.bindings.iter().filter(|b| b.role == Role::Driver) {
            couplings.insert(
                b.coupling.clone(),
                CouplingInfo {
                    name: b.coupling.clone(),
                    kind: b.kind.as_str().to_string(),
                    from: format!("{node}.{}", b.interface),
                    to: format!("{}.{}", b.peer, b.peer_interface),
                },
            );
        }
        nodes.push(NodeInfo {
            name: node,
            model: w.model.clone(),
            couplings: w.bindings.len(),
        });
    }
    (nodes, couplings.into_values().collect())
}

/// A number as a person reads it: plain from 1e-3 to 1e6, otherwise in scientific notation
/// (`4.956056900399753e-7`, not `0.0000004956056900399753`).
fn plain(x: f64) -> String {
    if x == 0.0 || (1e-3..1e6).contains(&x.abs()) {
        x.to_string()
    } else {
        format!("{x:e}")
    }
}

/// The balance a user reads first: "ok" or "WARNING", the largest residuals against their
/// thresholds, and each warning.
fn write_verdict(s: &mut String, v: &Verdict) -> std::fmt::Result {
    use std::fmt::Write;
    let momentum = match v.momentum_relative {
        Some(p) => format!(
            "momentum residual {p:.1e} (warn above {:e})",
            v.momentum_warning
        ),
        None => "momentum residual not judged (recorded without its scale)".to_string(),
    };
    writeln!(
        s,
        "balance    {}: {momentum}, energy residual {:+.2} % (warn above {} %)",
        if v.warnings.is_empty() {
            "ok"
        } else {
            "WARNING"
        },
        v.energy_relative * 100.0,
        v.energy_warning * 100.0
    )?;
    for w in &v.warnings {
        writeln!(s, "  {w}")?;
    }
    Ok(())
}

/// The last balance row `v` of the run `i`, as text.
fn write_balance(s: &mut String, i: &RunInfo, v: &serde_json::Value) -> std::fmt::Result {
    use std::fmt::Write;
    let f = |k: &str| v[k].as_f64().unwrap_or(0.0);
    let t = v["time"].as_f64().map(plain).unwrap_or_default();
    writeln!(s, "balance at window {} (t = {t} s)", v["window"])?;
    writeln!(
        s,
        "  energy {:.6e} J, external work {:.6e} J, residual {:.3e} J, interface work sum {:.3e} J",
        f("energy"),
        f("external_work"),
        f("energy_residual"),
        f("interface_work_sum")
    )?;
    writeln!(
        s,
        "  momentum {:.6e}, external impulse {:.6e}, imbalance {:.3e} N s",
        f("momentum"),
        f("external_impulse"),
        f("momentum_imbalance")
    )?;
    let applied = f("applied_impulse");
    let worst = i.largest_momentum_imbalance.unwrap_or(0.0);
    if applied > 0.0 {
        writeln!(
            s,
            "  largest momentum imbalance {:.3e} N s = {:.3e} of the applied impulse {:.3e} N s",
            worst,
            worst / applied,
            applied
        )?;
    }
    writeln!(
        s,
        "  largest momentum residual (external and in-flight coupling impulse accounted) {:.3e} N s",
        i.largest_momentum_residual.unwrap_or(0.0)
    )?;
    Ok(())
}
