//! `cosim replay` and `cosim info` (ARCHITECTURE §7). Replay rebuilds one node in-process from
//! its recorded `Welcome`, feeds it the recorded peer inputs window by window (open loop),
//! and compares its outputs with the recorded ones, field by field and window by window.

use crate::config;
use crate::record::{self, Recorded};
use anyhow::{Context, bail};
use protocol::participant::{NodeEngine, is_motion};
use protocol::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Largest differences of one field in one window.
#[derive(Debug, Clone, Default)]
pub struct Diff {
    pub max_abs: f64,
    pub max_rel: f64,
    pub identical: bool,
}

fn diff(a: &[f64], b: &[f64]) -> Diff {
    if a.len() != b.len() {
        return Diff {
            max_abs: f64::INFINITY,
            max_rel: f64::INFINITY,
            identical: false,
        };
    }
    let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let mut d = Diff {
        identical: true,
        ..Default::default()
    };
    for (x, y) in a.iter().zip(b) {
        if x.to_bits() != y.to_bits() {
            d.identical = false;
        }
        let e = (x - y).abs();
        d.max_abs = d.max_abs.max(e);
    }
    d.max_rel = if scale > 0.0 {
        d.max_abs / scale
    } else {
        d.max_abs
    };
    d
}

/// Result of a replay.
#[derive(Debug, Clone, Default)]
pub struct ReplayReport {
    pub windows: u64,
    pub fields_compared: u64,
    pub bit_identical: bool,
    /// (window, coupling, field) → difference, for every compared field.
    pub rows: Vec<(u64, String, String, Diff)>,
    /// Report scalars (e.g. tip displacement): (window, name, replayed, recorded).
    pub scalars: Vec<(u64, String, f64, f64)>,
    /// End time of each replayed window: (window, t1).
    pub times: Vec<(u64, f64)>,
    /// First window where the node's interface motion drifted past the tolerance.
    pub drift: Option<(u64, String, f64)>,
}

struct Decoded {
    topic: String,
    env: Envelope,
}

fn decode_all(msgs: &[Recorded]) -> Vec<Decoded> {
    msgs.iter()
        .filter(|m| !m.json)
        .filter_map(|m| {
            codec::decode(&m.data).ok().map(|env| Decoded {
                topic: m.topic.clone(),
                env,
            })
        })
        .collect()
}

fn case_of(msgs: &[Recorded]) -> anyhow::Result<toml::Table> {
    let m = msgs
        .iter()
        .find(|m| m.topic == "/cosim/case")
        .context("the recording has no /cosim/case channel")?;
    let v: serde_json::Value = serde_json::from_slice(&m.data)?;
    let text = v["toml"].as_str().context("/cosim/case has no toml")?;
    Ok(toml::from_str(text)?)
}

/// Replay node `node` of the recording at `path`; `sets` override its parameters.
pub fn replay(
    path: &Path,
    node: &str,
    sets: &[String],
    tolerance: f64,
) -> anyhow::Result<ReplayReport> {
    let (msgs, complete) = record::read_all(path)?;
    if !complete {
        eprintln!(
            "cosim replay: the recording is incomplete (its writer was stopped); replaying the windows it holds"
        );
    }
    let case = case_of(&msgs)?;
    let solver = case
        .get("nodes")
        .and_then(|n| n.get(node))
        .and_then(|n| n.get("solver"))
        .and_then(|s| s.as_str())
        .with_context(|| format!("node '{node}' is not in the recorded case"))?
        .to_string();
    let factory = config::builtin_factory(&solver).with_context(|| {
        format!("solver '{solver}' is not built into cosim; replay needs a built-in solver")
    })?;
    let dec = decode_all(&msgs);
    let run = dec
        .first()
        .map(|d| d.env.run.clone())
        .context("the recording holds no protocol message")?;
    let down = topic::down(&run, node);
    let welcome = dec
        .iter()
        .find_map(|d| match &d.env.message {
            Message::Welcome(w) if d.topic == down => Some(w.clone()),
            _ => None,
        })
        .with_context(|| format!("no Welcome to node '{node}' in the recording"))?;
    let mut params: toml::Table = toml::from_str(&welcome.params_toml)?;
    let mut model = welcome.model.clone();
    let mut param_sets = Vec::new();
    for s in sets {
        if let Some(m) = s.strip_prefix("model=") {
            model = m.trim_matches('"').to_string();
        } else {
            param_sets.push(s.clone());
        }
    }
    config::apply_sets(&mut params, &param_sets).map_err(|e| anyhow::anyhow!("{e}"))?;
    let solver = factory(&model, &params).map_err(|e| anyhow::anyhow!("nodes.{node}: {e}"))?;
    let mut engine = NodeEngine::new(solver, &welcome.bindings);
    // Topics: peer → node inputs, node → peer recorded outputs.
    let inputs: Vec<String> = welcome
        .bindings
        .iter()
        .map(|b| topic::data(&run, &b.coupling, &b.peer))
        .collect();
    let outputs: Vec<String> = welcome
        .bindings
        .iter()
        .map(|b| topic::data(&run, &b.coupling, node))
        .collect();
    let up = topic::up(&run, node);
    let mut recorded_out: BTreeMap<(u64, String), Fields> = BTreeMap::new();
    let mut recorded_done: BTreeMap<u64, StepReport> = BTreeMap::new();
    let mut advances = Vec::new();
    let mut decouples: Vec<Decouple> = Vec::new();
    let mut peer_fields: Vec<Fields> = Vec::new();
    for d in &dec {
        match &d.env.message {
            Message::Mesh(m) if inputs.contains(&d.topic) => engine.peer_mesh(m)?,
            Message::Fields(f) if inputs.contains(&d.topic) => peer_fields.push(f.clone()),
            Message::Fields(f) if outputs.contains(&d.topic) => {
                recorded_out.insert((f.window, f.coupling.clone()), f.clone());
            }
            Message::Advance(a) if d.topic == down && a.window > 0 => advances.push(*a),
            Message::Decouple(x) if d.topic == down => decouples.push(x.clone()),
            Message::Done(dn) if d.topic == up => {
                recorded_done.insert(dn.window, dn.report.clone());
            }
            _ => {}
        }
    }
    let mut rep = ReplayReport {
        bit_identical: true,
        ..Default::default()
    };
    let mut fed = 0usize;
    let mut feed_upto = |engine: &mut NodeEngine, k: u64| -> anyhow::Result<()> {
        while fed < peer_fields.len() && peer_fields[fed].window <= k {
            engine.receive(peer_fields[fed].clone())?;
            fed += 1;
        }
        Ok(())
    };
    let compare = |rep: &mut ReplayReport, k: u64, out: &[Fields]| {
        for f in out {
            let Some(r) = recorded_out.get(&(k, f.coupling.clone())) else {
                continue;
            };
            for field in &f.fields {
                let Some(rf) = r.get(&field.name) else {
                    continue;
                };
                let d = diff(&field.values, &rf.values);
                rep.fields_compared += 1;
                if !d.identical {
                    rep.bit_identical = false;
                }
                if is_motion(&field.name) && d.max_rel > tolerance && rep.drift.is_none() {
                    rep.drift = Some((k, format!("{}/{}", f.coupling, field.name), d.max_rel));
                }
                rep.rows
                    .push((k, f.coupling.clone(), field.name.clone(), d));
            }
        }
    };
    feed_upto(&mut engine, 0)?;
    let setup_out = engine.setup()?;
    compare(&mut rep, 0, &setup_out);
    for a in &advances {
        if !recorded_done.contains_key(&a.window) {
            eprintln!(
                "cosim replay: window {} was not completed in the recording; stopping there",
                a.window
            );
            break;
        }
        for x in decouples.iter().filter(|x| x.window == a.window) {
            engine.decouple(&x.coupling, x.window)?;
        }
        feed_upto(&mut engine, a.window)?;
        if !engine.ready(a.window) {
            eprintln!(
                "cosim replay: the recording lacks inputs of window {} ({}); stopping there",
                a.window,
                engine.missing(a.window).join(", ")
            );
            break;
        }
        let w = Window {
            index: a.window,
            t0: a.t0,
            t1: a.t1,
            write_output: false,
        };
        let (report, out) = engine.advance(&w)?;
        compare(&mut rep, a.window, &out);
        if let Some(rr) = recorded_done.get(&a.window) {
            for (name, v) in &report.scalars {
                if let Some((_, r)) = rr.scalars.iter().find(|(n, _)| n == name) {
                    if v.to_bits() != r.to_bits() {
                        rep.bit_identical = false;
                    }
                    rep.scalars.push((a.window, name.clone(), *v, *r));
                }
            }
        }
        rep.times.push((a.window, a.t1));
        rep.windows += 1;
    }
    if rep.windows == 0 && advances.is_empty() {
        bail!("the recording holds no window of node '{node}'");
    }
    Ok(rep)
}

/// One PNG per reported quantity of the replayed node in `dir`: the recorded and the
/// replayed history on one chart (e.g. a bar's displacement under two solid models).
pub fn plot(rep: &ReplayReport, node: &str, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    use crate::plot::{Series, line_chart};
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let time: BTreeMap<u64, f64> = rep.times.iter().copied().collect();
    let mut names: Vec<&str> = rep.scalars.iter().map(|s| s.1.as_str()).collect();
    names.sort_unstable();
    names.dedup();
    let mut files = Vec::new();
    for name in names {
        let pick = |replayed: bool| -> Vec<(f64, f64)> {
            rep.scalars
                .iter()
                .filter(|s| s.1 == name)
                .filter_map(|s| Some((*time.get(&s.0)?, if replayed { s.2 } else { s.3 })))
                .collect()
        };
        let p = dir.join(format!(
            "replay_{node}_{}.png",
            crate::plot::file_stem(name)
        ));
        let series = [
            Series {
                label: "recorded".into(),
                points: pick(false),
            },
            Series {
                label: "replayed".into(),
                points: pick(true),
            },
        ];
        line_chart(&p, &format!("{node}: {name}"), "t [s]", name, &series)?;
        files.push(p);
    }
    Ok(files)
}

/// `cosim info`: nodes, couplings, windows, message counts and the energy balance.
pub fn info(path: &Path) -> anyhow::Result<String> {
    use std::fmt::Write;
    let (msgs, complete) = record::read_all(path)?;
    let mut s = String::new();
    let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    writeln!(
        s,
        "recording  {} ({:.1} kB, {})",
        path.display(),
        size as f64 / 1e3,
        if complete {
            "complete"
        } else {
            "INCOMPLETE: writer stopped early"
        }
    )?;
    let dec = decode_all(&msgs);
    if let Ok(case) = case_of(&msgs)
        && let Some(run) = case.get("run").and_then(|r| r.as_table())
    {
        writeln!(
            s,
            "case       end_time {} s, window {} s, schedule {}, transport {}",
            run.get("end_time")
                .map(|v| v.to_string())
                .unwrap_or_default(),
            run.get("window").map(|v| v.to_string()).unwrap_or_default(),
            run.get("schedule")
                .and_then(|v| v.as_str())
                .unwrap_or("serial"),
            run.get("transport")
                .and_then(|v| v.as_str())
                .unwrap_or("shm"),
        )?;
    }
    let run = dec.first().map(|d| d.env.run.clone()).unwrap_or_default();
    writeln!(s, "run        {run}")?;
    writeln!(s, "nodes")?;
    let mut couplings = BTreeMap::new();
    for d in &dec {
        if let Message::Welcome(w) = &d.env.message {
            let node = d.topic.rsplit('/').nth(1).unwrap_or("?");
            writeln!(
                s,
                "  {node:<12} model {:<20} couplings {}",
                w.model,
                w.bindings.len()
            )?;
            for b in &w.bindings {
                if b.role == Role::Driver {
                    couplings.insert(
                        b.coupling.clone(),
                        format!(
                            "{} {node}.{} → {}.{}",
                            b.kind.as_str(),
                            b.interface,
                            b.peer,
                            b.peer_interface
                        ),
                    );
                }
            }
        }
    }
    writeln!(s, "couplings")?;
    for (name, c) in &couplings {
        writeln!(s, "  {name:<12} {c}")?;
    }
    let windows = dec
        .iter()
        .filter_map(|d| match &d.env.message {
            Message::Done(dn) => Some(dn.window),
            _ => None,
        })
        .max()
        .unwrap_or(0);
    writeln!(s, "windows    {windows} completed")?;
    let mut counts: BTreeMap<&str, (u64, u64)> = BTreeMap::new();
    for m in &msgs {
        let e = counts.entry(m.topic.as_str()).or_default();
        e.0 += 1;
        e.1 += m.data.len() as u64;
    }
    writeln!(s, "messages   {} in {} channels", msgs.len(), counts.len())?;
    for (t, (n, b)) in &counts {
        writeln!(s, "  {t:<48} {n:>8} msgs {:>12.1} kB", *b as f64 / 1e3)?;
    }
    if let Some(last) = msgs.iter().rev().find(|m| m.topic == "/cosim/balance") {
        let v: serde_json::Value = serde_json::from_slice(&last.data)?;
        writeln!(s, "balance at window {} (t = {} s)", v["window"], v["time"])?;
        writeln!(
            s,
            "  energy {:.6e} J, external work {:.6e} J, residual {:.3e} J, interface work sum {:.3e} J",
            v["energy"].as_f64().unwrap_or(0.0),
            v["external_work"].as_f64().unwrap_or(0.0),
            v["energy_residual"].as_f64().unwrap_or(0.0),
            v["interface_work_sum"].as_f64().unwrap_or(0.0)
        )?;
        writeln!(
            s,
            "  momentum {:.6e}, external impulse {:.6e}, imbalance {:.3e} N s",
            v["momentum"].as_f64().unwrap_or(0.0),
            v["external_impulse"].as_f64().unwrap_or(0.0),
            v["momentum_imbalance"].as_f64().unwrap_or(0.0)
        )?;
        let worst = msgs
            .iter()
            .filter(|m| m.topic == "/cosim/balance")
            .filter_map(|m| serde_json::from_slice::<serde_json::Value>(&m.data).ok())
            .filter_map(|v| v["momentum_imbalance"].as_f64())
            .fold(0.0f64, f64::max);
        let applied = v["applied_impulse"].as_f64().unwrap_or(0.0);
        if applied > 0.0 {
            writeln!(
                s,
                "  largest momentum imbalance {:.3e} N s = {:.3e} of the applied impulse {:.3e} N s",
                worst,
                worst / applied,
                applied
            )?;
        }
        let resid = msgs
            .iter()
            .filter(|m| m.topic == "/cosim/balance")
            .filter_map(|m| serde_json::from_slice::<serde_json::Value>(&m.data).ok())
            .filter_map(|v| v["momentum_residual"].as_f64())
            .fold(0.0f64, f64::max);
        writeln!(
            s,
            "  largest momentum residual (external and in-flight coupling impulse accounted) {resid:.3e} N s"
        )?;
    }
    Ok(s)
}
