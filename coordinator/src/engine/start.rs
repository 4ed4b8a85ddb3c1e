//! A run's start: the local nodes launched (the remote ones told how to join), every node's
//! `Hello`, the `Welcome` with its bindings, its `Describe`, the lagrange hubs' requests, and
//! the set-up (window 0).

use super::coord::*;
use crate::case::{self};
use crate::launch::spawn_node;
use protocol::transport::TransportKind;
use protocol::*;
use std::path::Path;
use std::time::{Duration, Instant};

/// Launch the local nodes, each with its log in `out`; print how to start the remote ones
/// (`listen`: the endpoint they connect to).
pub(super) fn launch(
    c: &mut Coord,
    out: &Path,
    listen: &str,
    opts: &RunOptions,
) -> Result<(), Fault> {
    let case = c.case;
    for (i, n) in case.nodes.iter().enumerate() {
        if n.remote {
            eprintln!(
                "cosim: waiting for remote node '{}': {} --run {} --node {} --transport {} --connect {} --token {}",
                n.name,
                n.solver,
                c.run,
                n.name,
                case.run.transport.as_str(),
                listen,
                c.token
            );
            if let Some(st) = &opts.restart {
                eprintln!(
                    "cosim: remote node '{}' resumes from its checkpoint of window {}, on its own host: start it there as before (with the same --output DIR if it had one)",
                    n.name, st.window
                );
            }
            continue;
        }
        let Some(exe) = &n.exe else { continue };
        let connect = (case.run.transport == TransportKind::Zenoh).then_some(listen);
        let log = out.join(format!("{}.log", n.name));
        let child = spawn_node(exe, &[], &c.run, &n.name, case.run.transport, connect, &log)
            .map_err(|e| fault(&n.name, e))?;
        c.nodes[i].child = Some(child);
        c.nodes[i].log = Some(log);
        c.nodes[i].last_seen = Instant::now();
    }
    Ok(())
}

/// Every node's `Hello` (the remote ones as they join), then its `Welcome` and `Describe`.
pub(super) fn hand_shake(c: &mut Coord, out: &Path) -> Result<(), Fault> {
    let case = c.case;
    let all: Vec<usize> = (0..c.nodes.len()).collect();
    let local: Vec<usize> = all
        .iter()
        .copied()
        .filter(|&i| !case.nodes[i].remote)
        .collect();
    let remote: Vec<usize> = all
        .iter()
        .copied()
        .filter(|&i| case.nodes[i].remote)
        .collect();
    let start = Duration::from_secs_f64(case.run.start_timeout);
    c.wait_all(
        &local,
        "Hello",
        Some((
            start,
            "the node is running but has not joined (a slow start? raise run.start_timeout)",
        )),
        |n| n.hello,
    )?;
    wait_for_joins(c, &remote)?;
    // Every node's silence so far was spent waiting for the others: the heartbeat clock
    // starts with the Welcome (nodes beat from then on), and so does the coordinator's own.
    for n in &mut c.nodes {
        n.last_seen = Instant::now();
    }
    c.own.restart();
    for (i, n) in case.nodes.iter().enumerate() {
        let w = Message::Welcome(Welcome {
            run: c.run.clone(),
            model: n.model.clone(),
            params_toml: toml::to_string(&n.params).map_err(|e| fault(&n.name, e.to_string()))?,
            bindings: case::bindings_of(case, &n.name),
            output_dir: out.join(&n.name).display().to_string(),
            heartbeat_ms: case.run.heartbeat_ms,
        });
        c.send(i, &w)?;
    }
    c.wait_all(
        &all,
        "Describe",
        Some((
            Duration::from_secs(60),
            "the node did not finish building its solver",
        )),
        |n| n.described >= 1,
    )?;
    Ok(())
}

/// The lagrange hubs' requests once every side listens, then the set-up window (0) of every
/// node, on disk before the first window.
pub(super) fn set_up(c: &mut Coord) -> Result<(), Fault> {
    let all: Vec<usize> = (0..c.nodes.len()).collect();
    // Lagrange couplings: every side subscribed before its Describe; once shared memory
    // shows them connected, each gets the coupling's request (system step, method).
    for h in 0..c.hubs.len() {
        let tp = topic::data(
            &c.run,
            &c.hubs[h].0.coupling,
            protocol::scheme::lagrange::wire::PEER,
        );
        let want = c.hubs[h].0.sides.len();
        let since = Instant::now();
        while c.t.readers(&tp).is_some_and(|r| r < want) {
            if since.elapsed() > Duration::from_secs(60) {
                return Err(fault(
                    &c.hubs[h].0.sides[0],
                    format!(
                        "the sides of coupling {} never subscribed to {tp}",
                        c.hubs[h].0.coupling
                    ),
                ));
            }
            c.pump_one(Duration::from_millis(5))?;
        }
        let req = c.hubs[h].0.request();
        c.publish_lagrange(h, req)?;
    }
    // Set-up (window 0).
    for i in 0..c.nodes.len() {
        c.send(
            i,
            &Message::Advance(Advance {
                window: 0,
                t0: 0.0,
                t1: 0.0,
                write_output: false,
                checkpoint: false,
            }),
        )?;
    }
    c.wait_all(&all, "set-up", None, |n| n.done == Some(0))?;
    // The hand-shake and set-up reach the disk before the first window.
    c.rec
        .flush()
        .map_err(|e| fault("coordinator", format!("recording: {e:#}")))?;
    Ok(())
}

/// Wait for the remote nodes to join (docs/architecture.md): as long as a person needs, up to
/// `run.join_timeout`, naming who is still missing every few seconds. The local nodes wait
/// meanwhile (they are alive; only their exit or lost connection is a fault).
pub(super) fn wait_for_joins(c: &mut Coord, remote: &[usize]) -> Result<(), Fault> {
    const NOTE_EVERY: Duration = Duration::from_secs(5);
    let limit = c.case.run.join_timeout;
    let start = Instant::now();
    let mut next_note = start + NOTE_EVERY;
    loop {
        let missing: Vec<usize> = remote
            .iter()
            .copied()
            .filter(|&i| !c.nodes[i].hello)
            .collect();
        let Some(&first) = missing.first() else {
            return Ok(());
        };
        let names = missing
            .iter()
            .map(|&i| format!("'{}'", c.nodes[i].name))
            .collect::<Vec<_>>()
            .join(", ");
        c.stop_now()?;
        c.check_health(&[])?;
        let waited = start.elapsed().as_secs_f64();
        if waited > limit {
            return Err(Fault {
                node: c.nodes[first].name.clone(),
                reason: format!(
                    "remote node(s) {names} did not join within run.join_timeout = {limit} s"
                ),
            });
        }
        if Instant::now() >= next_note {
            eprintln!(
                "cosim: still waiting for remote node(s) {names}: {waited:.0} s of run.join_timeout = {limit} s"
            );
            next_note += NOTE_EVERY;
        }
        c.pump_one(Duration::from_millis(50))?;
        for &i in &missing {
            if c.nodes[i].hello {
                eprintln!("cosim: remote node '{}' joined", c.nodes[i].name);
            }
        }
    }
}
