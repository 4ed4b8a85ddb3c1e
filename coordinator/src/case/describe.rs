//! Validation through the node executables: `NODE --describe --model M --node N` for every
//! node whose executable is on this host, all at once, each with a timeout. The answers name
//! a bad parameter's key (`nodes.N.params.<key>`) and list each node's interfaces; the
//! coordinator builds no solver itself (docs/architecture.md, PROTOCOL.md "Node command line").

use super::resolved::{ConfigError, NodeConfig};
use protocol::describe::{DescribeAnswer, NodeDescriptionJson, parse_answer};
use std::io::{Read, Write};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// How long one node may take to describe itself (it builds its model, as for a run).
pub const DESCRIBE_TIMEOUT: Duration = Duration::from_secs(120);

/// What became of one node's check.
#[derive(Debug, Clone)]
pub enum Checked {
    /// Its executable described it.
    Described(Box<NodeDescriptionJson>),
    /// A remote node whose executable is not on this host: it is checked when it joins.
    WhenItJoins,
}

/// Describe every node of `nodes` (executables resolved against `case_dir`) in parallel;
/// the first error in case order, or one answer per node.
pub fn describe_nodes(
    nodes: &[NodeConfig],
    case_dir: &Path,
    timeout: Duration,
) -> Result<Vec<Checked>, ConfigError> {
    let results: Vec<Result<Checked, ConfigError>> = std::thread::scope(|s| {
        let handles: Vec<_> = nodes
            .iter()
            .map(|n| {
                let exe = n
                    .exe
                    .clone()
                    .or_else(|| crate::launch::resolve_exe(&n.solver, case_dir));
                s.spawn(move || match exe {
                    Some(exe) => {
                        describe_one(&exe, &[], n, timeout).map(|d| Checked::Described(Box::new(d)))
                    }
                    None => Ok(Checked::WhenItJoins),
                })
            })
            .collect();
        handles
            .into_iter()
            .zip(nodes)
            .map(|(h, n)| {
                h.join().unwrap_or_else(|_| {
                    Err(ConfigError {
                        key: format!("nodes.{}", n.name),
                        reason: "the describe thread panicked".into(),
                    })
                })
            })
            .collect()
    });
    results.into_iter().collect()
}

/// `child` given `input` on its stdin and waited for at most `timeout`: its exit status,
/// stdout and stderr (both read while it works, so that neither fills up and blocks it). Err:
/// why there is no answer ("did not answer within 5 s"), the child killed.
fn answer(
    child: &mut std::process::Child,
    input: &[u8],
    timeout: Duration,
) -> Result<(std::process::ExitStatus, String, String), String> {
    let pipe = |r: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut s = String::new();
            if let Some(mut r) = r {
                let _ = r.read_to_string(&mut s);
            }
            s
        })
    };
    let out = pipe(
        child
            .stdout
            .take()
            .map(|p| Box::new(p) as Box<dyn Read + Send>),
    );
    let err = pipe(
        child
            .stderr
            .take()
            .map(|p| Box::new(p) as Box<dyn Read + Send>),
    );
    if let Some(mut stdin) = child.stdin.take() {
        // A node that exits without reading (a bad invocation) closes the pipe: its answer
        // says why, so a write error here is not the story.
        let _ = stdin.write_all(input);
    }
    let start = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(st)) => break st,
            Ok(None) if start.elapsed() > timeout => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(format!("did not answer within {} s", timeout.as_secs()));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(5)),
            Err(e) => return Err(format!("could not be waited for: {e}")),
        }
    };
    Ok((
        status,
        out.join().unwrap_or_default(),
        err.join().unwrap_or_default(),
    ))
}

/// Run `exe args… --describe` for node `n` (`args`: the command's own arguments, as
/// `cosim conformance` is given them), its params on stdin, and read its answer.
pub fn describe_one(
    exe: &Path,
    args: &[String],
    n: &NodeConfig,
    timeout: Duration,
) -> Result<NodeDescriptionJson, ConfigError> {
    let at = |k: &str| format!("nodes.{}.{k}", n.name);
    let fail = |reason: String| ConfigError {
        key: at("solver"),
        reason,
    };
    let params = toml::to_string(&n.params).map_err(|e| ConfigError {
        key: at("params"),
        reason: format!("cannot encode: {e}"),
    })?;
    let shown = exe.display();
    let mut child = Command::new(exe)
        .args(args)
        .args(["--describe", "--model", &n.model, "--node", &n.name])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| fail(format!("cannot start {shown}: {e}")))?;
    let (status, stdout, stderr) = answer(&mut child, params.as_bytes(), timeout)
        .map_err(|why| fail(format!("`{shown} --describe` {why}")))?;
    match parse_answer(&stdout) {
        Some(DescribeAnswer::Description(d)) if status.success() => Ok(d),
        Some(DescribeAnswer::Error(e)) => Err(ConfigError {
            key: e
                .key
                .map_or_else(|| format!("nodes.{}", n.name), |k| at(&k)),
            reason: e.reason,
        }),
        _ => {
            let last = stderr.lines().rev().find(|l| !l.trim().is_empty());
            Err(fail(format!(
                "`{shown} --describe` gave no description ({status}){}; every node executable must answer --describe (PROTOCOL.md, \"Node command line\")",
                last.map(|l| format!(": {}", l.trim())).unwrap_or_default()
            )))
        }
    }
}
