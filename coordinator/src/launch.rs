//! Starting node processes, shared by `cosim run` and `cosim replay`: finding a solver's
//! executable, choosing run ids and ports, spawning a node with its log and its death tied
//! to the coordinator's, and saying why one ended.

use anyhow::Context;
use protocol::transport::TransportKind;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

/// Where a node executable is: a path (relative to the case file), or a name beside `cosim`.
pub fn resolve_exe(solver: &str, case_dir: &Path) -> Option<PathBuf> {
    let p = Path::new(solver);
    if solver.contains('/') {
        let p = if p.is_absolute() {
            p.to_path_buf()
        } else {
            case_dir.join(p)
        };
        return p.is_file().then_some(p);
    }
    let here = std::env::current_exe().ok()?;
    let cand = here.parent()?.join(solver);
    cand.is_file().then_some(cand)
}

/// A run id: the run's name, this process and the time (at most 32 characters, the end kept).
pub(crate) fn pick_run_id(name: &str) -> String {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_millis() % 1_000_000)
        .unwrap_or(0);
    let mut s = format!("{}-{}-{t}", name, std::process::id());
    if s.len() > 32 {
        s = s[s.len() - 32..].to_string();
    }
    s
}

/// A free TCP port on this host (for a zenoh endpoint written with port 0).
pub(crate) fn free_port() -> anyhow::Result<u16> {
    let l = std::net::TcpListener::bind("127.0.0.1:0")?;
    Ok(l.local_addr()?.port())
}

/// Kill the child when the coordinator dies, whatever the cause (Linux).
fn die_with_parent(cmd: &mut Command) {
    use std::os::unix::process::CommandExt;
    // SAFETY: prctl is async-signal-safe; nothing else runs between fork and exec here.
    unsafe {
        cmd.pre_exec(|| {
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
            Ok(())
        });
    }
}

/// Append to a node's log the line that marks where a restart from the checkpoint of
/// `window` begins (the killed run's lines above it are kept).
pub(crate) fn mark_restart(log: &Path, window: u64, segment: &Path) -> anyhow::Result<()> {
    use std::io::Write;
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(log)
        .with_context(|| format!("cannot open {}", log.display()))?;
    writeln!(
        f,
        "---- cosim restart from the checkpoint of window {window}; recording {} ----",
        segment.file_name().unwrap_or_default().to_string_lossy()
    )
    .with_context(|| format!("cannot write {}", log.display()))
}

/// Start node `name` of run `run` from its executable, as `cosim run`, `cosim replay` and
/// `cosim conformance` do: `exe args… --run …` (`args`: the command's own arguments, e.g. a
/// script an interpreter runs); its stdout and stderr are appended to `log`, and it dies with
/// this process. `connect` is the zenoh endpoint to join, where the transport needs one.
pub(crate) fn spawn_node(
    exe: &Path,
    args: &[String],
    run: &str,
    name: &str,
    kind: TransportKind,
    connect: Option<&str>,
    log: &Path,
) -> Result<Child, String> {
    let out = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(log)
        .map_err(|e| format!("cannot open its log {}: {e}", log.display()))?;
    let err = out.try_clone().map_err(|e| e.to_string())?;
    let mut cmd = Command::new(exe);
    cmd.args(args);
    cmd.args(["--run", run, "--node", name, "--transport", kind.as_str()]);
    if let Some(endpoint) = connect {
        cmd.args(["--connect", endpoint]);
    }
    cmd.stdin(Stdio::null()).stdout(out).stderr(err);
    // A node built on the participant runtime turns this into SIGTERM for itself, so it can
    // remove its shared memory; another executable is killed with us.
    cmd.env(
        protocol::watchdog::PARENT_ENV,
        std::process::id().to_string(),
    );
    die_with_parent(&mut cmd);
    cmd.spawn()
        .map_err(|e| format!("cannot start {}: {e}", exe.display()))
}

/// What the log of a node that exited says last: its path and its last lines (at most 12,
/// from its last 8 KiB), indented, for the fault message.
pub(crate) fn log_note(log: &Path) -> String {
    use std::io::{Read, Seek, SeekFrom};
    let mut text = String::new();
    if let Ok(mut f) = std::fs::File::open(log) {
        let len = f.metadata().map(|m| m.len()).unwrap_or(0);
        let mut buf = Vec::new();
        if f.seek(SeekFrom::Start(len.saturating_sub(8192))).is_ok()
            && f.read_to_end(&mut buf).is_ok()
        {
            text = String::from_utf8_lossy(&buf).into_owned();
        }
    }
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    if lines.is_empty() {
        return format!(" (its log, {}, is empty)", log.display());
    }
    let tail = &lines[lines.len().saturating_sub(12)..];
    let mut s = format!("; its log, {}, ends:", log.display());
    for l in tail {
        s.push_str("\n    ");
        s.push_str(l);
    }
    s
}

/// How a node process ended, in words.
pub(crate) fn describe_status(s: std::process::ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (s.code(), s.signal()) {
        (Some(c), _) => format!("exited with status {c}"),
        (None, Some(sig)) => format!(
            "was killed by signal {sig}{}",
            match sig {
                9 => " (SIGKILL)",
                11 => " (SIGSEGV)",
                15 => " (SIGTERM)",
                6 => " (SIGABRT)",
                _ => "",
            }
        ),
        _ => "ended".into(),
    }
}
