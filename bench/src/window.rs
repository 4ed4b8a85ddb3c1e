//! Whole coupling windows through `cosim run` (the `window` kernel of `cosim bench`): what a
//! window costs a user end to end, with the coordinator, both nodes and the recorder in the
//! loop. Two tables: the participant round trip (the Rust `echo` node drives, the responder is
//! the same node in Rust, in Python on the `cosim` package, or in C on the participant
//! library; 1 KiB each way) and the split bar's window on each transport, in lockstep and
//! pipelined (`COSIM_WINDOWS_AHEAD` 1 and 2, and unset: the coordinator's choice), split into the nodes' compute and everything
//! beyond it, with a third table of where the window goes (the coordinator's phases from
//! `summary.json` `window_breakdown`, each node's compute, coupling wait and idle time).
//!
//! A window's time is the wall-clock spacing of `/cosim/balance` records in the recording
//! (their publish time: when the coordinator audited the window, every node having reported
//! it done), taken over blocks of 8 consecutive windows (the coordinator audits several at
//! a time when windows are short), so each sample is the mean window of a block; the first
//! tenth of each run's blocks is left out as warm-up.

use anyhow::{Context, anyhow, bail};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The Python echo participant and the C one, carried inside the binary so that the benchmark
/// needs no checkout.
const ECHO_PY: &str = include_str!("../echo/echo_node.py");
const ECHO_C: &str = include_str!("../echo/echo_node.c");
const HEADER: &str = include_str!("../../participant-c/include/cosim_participant.h");
/// The split bar as the README runs it.
const SPLIT_BAR: &str = include_str!("../../examples/split_bar.toml");

/// Windows per timed block: a sample is the mean window time over this many consecutive
/// windows.
const BLOCK: usize = 8;

/// The participant round trip moves this many bytes each way (128 points, one f64 each).
const ECHO_BYTES: usize = 1024;

/// One responder's (or one transport's) window times.
#[derive(Debug, Clone, Serialize)]
pub struct WindowRow {
    /// `participant` (echo pair) or `split-bar`.
    pub case: String,
    pub transport: String,
    /// The responder's language (participant rows) or `rust` (the split bar's built-in nodes).
    pub node: String,
    /// Bytes each way per window through the coupling (participant rows).
    pub bytes: Option<usize>,
    /// `cosim run`s measured (alternating with the other rows of the table).
    pub runs: usize,
    /// Windows whose time entered the statistics (all runs, warm-up left out; blocks of
    /// [`BLOCK`] windows, one sample each).
    pub windows: usize,
    pub median_us: f64,
    pub p10_us: f64,
    pub p90_us: f64,
    /// Median time over the Rust responder's (participant rows).
    pub ratio_to_rust: Option<f64>,
    /// Both nodes' compute per window (`summary.json`: Σ compute_s / windows, mean over runs).
    pub compute_us: Option<f64>,
    /// Window-loop time per window beyond both nodes' compute (`window_loop_s / windows` −
    /// compute; the serial schedule runs the nodes one after the other).
    pub beyond_compute_us: Option<f64>,
    /// Windows the coordinator lets run at once on split bar rows (`COSIM_WINDOWS_AHEAD`;
    /// 1 = lockstep); `None` on a split bar row: its own choice (the default; the mean it chose
    /// is the breakdown's `windows_in_flight`).
    pub windows_ahead: Option<u64>,
    /// Where the window's time goes, µs per window (mean over runs): the coordinator's
    /// phases (`summary.json` `window_breakdown`), then each node's compute, coupling wait
    /// and idle time; and the coordinator's allocations per window.
    pub breakdown: Vec<(String, f64)>,
}

/// A row that could not be measured here, and why.
pub struct Missing {
    pub what: String,
    pub reason: String,
}

/// How many windows and runs.
struct Size {
    echo_windows: usize,
    split_bar_windows: usize,
    runs: usize,
}

/// Run both tables. `rows` gets every measured row; `missing` the responders this machine
/// cannot run (no Python package, no C compiler); an `Err` is a failure of the benchmark.
pub fn run(quick: bool) -> anyhow::Result<(Vec<WindowRow>, Vec<Missing>)> {
    let size = if quick {
        Size {
            echo_windows: 200,
            split_bar_windows: 200,
            runs: 1,
        }
    } else {
        Size {
            echo_windows: 5000,
            split_bar_windows: 3200,
            runs: 3,
        }
    };
    let exe = std::env::current_exe().context("the benchmark's own path")?;
    let bin = exe
        .parent()
        .ok_or_else(|| anyhow!("{} has no directory", exe.display()))?
        .to_path_buf();
    let cosim = bin.join("cosim");
    if !cosim.is_file() {
        bail!(
            "{} not found: build the workspace (cargo build --release --workspace)",
            cosim.display()
        );
    }
    let dir = std::env::temp_dir().join(format!("cosim-bench-window-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let out = measure(&cosim, &bin, &dir, &size);
    let _ = std::fs::remove_dir_all(&dir);
    out
}

fn measure(
    cosim: &Path,
    bin: &Path,
    dir: &Path,
    size: &Size,
) -> anyhow::Result<(Vec<WindowRow>, Vec<Missing>)> {
    let mut missing = Vec::new();
    let rust = bin.join("cosim-echo-node");
    if !rust.is_file() {
        bail!(
            "{} not found: build the workspace (cargo build --release --workspace)",
            rust.display()
        );
    }
    let mut responders: Vec<(&str, PathBuf)> = vec![("rust", rust.clone())];
    match python_echo(dir) {
        Ok(p) => responders.push(("python", p)),
        Err(e) => missing.push(Missing {
            what: "python".into(),
            reason: format!("{e:#}"),
        }),
    }
    match c_echo(dir, bin) {
        Ok(p) => responders.push(("c", p)),
        Err(e) => missing.push(Missing {
            what: "c".into(),
            reason: format!("{e:#}"),
        }),
    }
    // Runs alternate between the responders so that a burst of load hits them all.
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); responders.len()];
    for r in 0..size.runs {
        for (i, (name, exe)) in responders.iter().enumerate() {
            let case = dir.join(format!("echo-{name}-{r}.toml"));
            std::fs::write(&case, echo_case(&rust, exe, size.echo_windows))?;
            let out = dir.join(format!("out-echo-{name}-{r}"));
            let (dts, _) = run_case(cosim, &case, &out, &[], &[], size.echo_windows)
                .with_context(|| format!("participant window, {name} responder"))?;
            times[i].extend(dts);
        }
    }
    let mut rows = Vec::new();
    for ((name, _), dts) in responders.iter().zip(&mut times) {
        let (median, p10, p90) = quantiles(dts);
        rows.push(WindowRow {
            case: "participant".into(),
            transport: "shm".into(),
            node: name.to_string(),
            bytes: Some(ECHO_BYTES),
            runs: size.runs,
            windows: dts.len() * BLOCK,
            median_us: median * 1e6,
            p10_us: p10 * 1e6,
            p90_us: p90 * 1e6,
            ratio_to_rust: None,
            compute_us: None,
            beyond_compute_us: None,
            windows_ahead: None,
            breakdown: Vec::new(),
        });
    }
    let base = rows[0].median_us;
    for r in &mut rows {
        r.ratio_to_rust = Some(r.median_us / base);
    }
    // The split bar on each transport, shortened in quick mode.
    let split = dir.join("split_bar.toml");
    std::fs::write(&split, SPLIT_BAR)?;
    let window = split_bar_window()?;
    let end = format!("run.end_time={:e}", window * size.split_bar_windows as f64);
    // Each transport in lockstep (each Advance after the last window's audit, as the loop first did), with two windows in flight, and as the coordinator chooses (`None`, the
    // default: up to 8 in flight, sent in batches).
    let transports = [
        ("shm", Some(1u64)),
        ("shm", Some(2)),
        ("shm", None),
        ("zenoh", Some(1)),
        ("zenoh", Some(2)),
        ("zenoh", None),
    ];
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); transports.len()];
    let mut compute = vec![0.0; transports.len()];
    let mut beyond = vec![0.0; transports.len()];
    let mut parts: Vec<Vec<(String, f64)>> = vec![Vec::new(); transports.len()];
    for r in 0..size.runs {
        for (i, (t, ahead)) in transports.iter().enumerate() {
            let label = ahead.map_or("auto".to_string(), |a| a.to_string());
            let out = dir.join(format!("out-split-{t}-{label}-{r}"));
            let tr = format!("run.transport=\"{t}\"");
            let ahead_env = [("COSIM_WINDOWS_AHEAD", label.as_str())];
            let (dts, summary) = run_case(
                cosim,
                &split,
                &out,
                &["--set", &end, "--set", &tr],
                if ahead.is_some() { &ahead_env } else { &[] },
                size.split_bar_windows,
            )
            .with_context(|| format!("split bar on {t}, windows in flight: {label}"))?;
            times[i].extend(dts);
            let (c, b) = compute_split(&summary)?;
            compute[i] += c / size.runs as f64;
            beyond[i] += b / size.runs as f64;
            for (k, v) in breakdown(&summary)? {
                match parts[i].iter_mut().find(|(n, _)| *n == k) {
                    Some(p) => p.1 += v / size.runs as f64,
                    None => parts[i].push((k, v / size.runs as f64)),
                }
            }
        }
    }
    for (i, (t, ahead)) in transports.iter().enumerate() {
        let (median, p10, p90) = quantiles(&mut times[i]);
        rows.push(WindowRow {
            case: "split-bar".into(),
            transport: t.to_string(),
            node: "rust".into(),
            bytes: None,
            runs: size.runs,
            windows: times[i].len() * BLOCK,
            median_us: median * 1e6,
            p10_us: p10 * 1e6,
            p90_us: p90 * 1e6,
            ratio_to_rust: None,
            compute_us: Some(compute[i] * 1e6),
            beyond_compute_us: Some(beyond[i] * 1e6),
            windows_ahead: *ahead,
            breakdown: std::mem::take(&mut parts[i]),
        });
    }
    Ok((rows, missing))
}

/// The window of the embedded split bar (`run.window`).
fn split_bar_window() -> anyhow::Result<f64> {
    let t: toml::Table = toml::from_str(SPLIT_BAR).context("the embedded split bar")?;
    t.get("run")
        .and_then(|r| r.get("window"))
        .and_then(|w| w.as_float())
        .ok_or_else(|| anyhow!("the embedded split bar has no run.window"))
}

/// The two-node echo case: the Rust node drives, `responder` answers.
fn echo_case(rust: &Path, responder: &Path, windows: usize) -> String {
    format!(
        r#"[run]
name = "bench-participant"
end_time = {end:e}
window = 1e-3
transport = "shm"
output = "out"

[nodes.a]
solver = {rust:?}
model = "echo"
[nodes.a.params]
points = {points}

[nodes.b]
solver = {responder:?}
model = "echo"
[nodes.b.params]
points = {points}

[[couplings]]
name = "echo"
kind = "immersed"
driver = "a.port"
responder = "b.port"
driver_fields = ["signal"]
responder_fields = ["echo"]
"#,
        end = windows as f64 * 1e-3,
        rust = rust.display().to_string(),
        responder = responder.display().to_string(),
        points = ECHO_BYTES / 8,
    )
}

/// The Python echo node, if `python3` imports the `cosim` package here.
fn python_echo(dir: &Path) -> anyhow::Result<PathBuf> {
    let ok = Command::new("python3")
        .args(["-c", "import cosim"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        bail!("python3 cannot import the `cosim` package (python3 -m pip install ./python)");
    }
    let p = dir.join("echo_node.py");
    std::fs::write(&p, ECHO_PY)?;
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755))?;
    Ok(p)
}

/// The C echo node, compiled here with `cc` against the participant library beside `cosim`.
fn c_echo(dir: &Path, bin: &Path) -> anyhow::Result<PathBuf> {
    if !bin.join("libcosim_participant.so").is_file() {
        bail!(
            "{} not built (cargo build --release --workspace)",
            bin.join("libcosim_participant.so").display()
        );
    }
    let inc = dir.join("include");
    std::fs::create_dir_all(&inc)?;
    std::fs::write(inc.join("cosim_participant.h"), HEADER)?;
    let src = dir.join("echo_node.c");
    std::fs::write(&src, ECHO_C)?;
    let exe = dir.join("echo-node-c");
    let o = Command::new("cc")
        .args(["-O2", "-I"])
        .arg(&inc)
        .arg("-o")
        .arg(&exe)
        .arg(&src)
        .arg("-L")
        .arg(bin)
        .arg("-lcosim_participant")
        .arg(format!("-Wl,-rpath,{}", bin.display()))
        .output()
        .map_err(|e| anyhow!("no C compiler (cc): {e}"))?;
    if !o.status.success() {
        bail!(
            "cc could not build the C echo node: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    // Executable bits set here, not left to the linker, and the file synced; then the node
    // must start (its usage answer is enough), retried for up to 2 s. On the 2-core VM the
    // first `cosim run` of this node was twice refused by exec (EACCES) in one afternoon,
    // a cause we have not found; these steps rule out an unfinished file.
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&exe, std::fs::Permissions::from_mode(0o755))?;
    std::fs::File::open(&exe)?.sync_all()?;
    let mut tries = 0;
    loop {
        match Command::new(&exe)
            .arg("--help")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
        {
            Ok(_) => break,
            Err(e) if tries < 20 => {
                tries += 1;
                eprintln!("cosim bench: the C echo node did not start ({e}); retrying");
                std::thread::sleep(std::time::Duration::from_millis(100));
            }
            Err(e) => bail!("the C echo node does not start: {e}"),
        }
    }
    Ok(exe)
}

/// `cosim run CASE --output OUT --quiet [extra]`: the window times (warm-up left out) and the
/// run's `summary.json`; exactly `windows` windows must have been recorded.
fn run_case(
    cosim: &Path,
    case: &Path,
    out: &Path,
    extra: &[&str],
    env: &[(&str, &str)],
    windows: usize,
) -> anyhow::Result<(Vec<f64>, serde_json::Value)> {
    let o = Command::new(cosim)
        .arg("run")
        .arg(case)
        .arg("--output")
        .arg(out)
        .arg("--quiet")
        .args(extra)
        // The schedule is the row's: a setting of the caller's shell does not leak in.
        .env_remove("COSIM_WINDOWS_AHEAD")
        .envs(env.iter().copied())
        .env("COSIM_LOG", "warn")
        .stdout(Stdio::null())
        .output()
        .with_context(|| format!("starting {}", cosim.display()))?;
    if !o.status.success() {
        bail!(
            "cosim run {} failed ({}): {}",
            case.display(),
            o.status,
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let mut t = balance_times(&out.join("run.mcap"))?;
    if t.len() != windows {
        bail!(
            "{} windows recorded, expected {windows}",
            t.len(),
            windows = windows
        );
    }
    t.sort_unstable();
    // The coordinator audits windows in batches (several in flight, woken every second
    // window), so one spacing says little: each sample is the mean of a block of BLOCK.
    let dts: Vec<f64> = t
        .windows(BLOCK + 1)
        .step_by(BLOCK)
        .map(|w| (w[BLOCK] - w[0]) as f64 * 1e-9 / BLOCK as f64)
        .collect();
    let skip = dts.len() / 10;
    let summary = std::fs::read(out.join("summary.json"))
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok())
        .ok_or_else(|| anyhow!("{}: no readable summary.json", out.display()))?;
    Ok((dts[skip..].to_vec(), summary))
}

/// The publish times (ns, wall clock) of the recording's `/cosim/balance` records.
fn balance_times(mcap: &Path) -> anyhow::Result<Vec<u64>> {
    let buf = std::fs::read(mcap).with_context(|| format!("reading {}", mcap.display()))?;
    let mut t = Vec::new();
    for m in mcap::MessageStream::new(&buf).context("not an MCAP file")? {
        let m = m.with_context(|| format!("{}: unreadable message", mcap.display()))?;
        if m.channel.topic == "/cosim/balance" {
            t.push(m.publish_time);
        }
    }
    Ok(t)
}

/// The summary's number `key`.
fn number(summary: &serde_json::Value, key: &str) -> anyhow::Result<f64> {
    summary[key]
        .as_f64()
        .ok_or_else(|| anyhow!("summary.json has no {key}"))
}

/// The summary's nodes.
fn nodes(
    summary: &serde_json::Value,
) -> anyhow::Result<&serde_json::Map<String, serde_json::Value>> {
    summary["nodes"]
        .as_object()
        .ok_or_else(|| anyhow!("summary.json has no nodes"))
}

/// (Both nodes' compute per window, window-loop time per window beyond it), in seconds.
fn compute_split(summary: &serde_json::Value) -> anyhow::Result<(f64, f64)> {
    let windows = number(summary, "windows")?;
    let lp = number(summary, "window_loop_s")?;
    let nodes = nodes(summary)?;
    let mut c = 0.0;
    for (name, n) in nodes {
        c += n["compute_s"]
            .as_f64()
            .ok_or_else(|| anyhow!("summary.json: nodes.{name} has no compute_s"))?;
    }
    Ok((c / windows, (lp - c) / windows))
}

/// Where a window's time goes (µs per window): the coordinator's phases from the summary's
/// `window_breakdown`, then each node's compute, coupling wait and idle time per window.
fn breakdown(summary: &serde_json::Value) -> anyhow::Result<Vec<(String, f64)>> {
    let b = summary["window_breakdown"]
        .as_object()
        .ok_or_else(|| anyhow!("summary.json has no window_breakdown"))?;
    let mut out = Vec::new();
    for (k, v) in b {
        if k == "windows" {
            continue;
        }
        let name = k.strip_suffix("_us").unwrap_or(k).to_string();
        // allocations are absent (null) where the counting allocator is not installed
        if let Some(x) = v.as_f64() {
            out.push((name, x));
        }
    }
    let windows = number(summary, "windows")?;
    for (name, n) in nodes(summary)? {
        for (key, label) in [
            ("compute_s", "compute"),
            ("coupling_wait_s", "coupling wait"),
            ("idle_s", "idle"),
        ] {
            let s = n[key]
                .as_f64()
                .ok_or_else(|| anyhow!("summary.json: nodes.{name} has no {key}"))?;
            out.push((format!("{name} {label}"), s / windows * 1e6));
        }
    }
    Ok(out)
}

/// (median, p10, p90) of `x` (sorted in place); NaN when empty.
fn quantiles(x: &mut [f64]) -> (f64, f64, f64) {
    if x.is_empty() {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    x.sort_unstable_by(f64::total_cmp);
    let q = |p: f64| x[((x.len() - 1) as f64 * p).round() as usize];
    (q(0.5), q(0.1), q(0.9))
}

/// The two tables in Markdown; `round_trip_1k` is the raw transport round trip at 1 KiB per
/// transport from the same `cosim bench` run, when it ran.
pub fn table(rows: &[WindowRow], missing: &[Missing], round_trip_1k: &[(String, f64)]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Participant window round trip through `cosim run` (the Rust echo node drives; {ECHO_BYTES} B each way on shm; recording on):\n\n\
         | responder | runs | windows | median µs | p10 µs | p90 µs | ratio to Rust |\n|---|---:|---:|---:|---:|---:|---:|"
    );
    for r in rows.iter().filter(|r| r.case == "participant") {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.2} |",
            r.node,
            r.runs,
            r.windows,
            r.median_us,
            r.p10_us,
            r.p90_us,
            r.ratio_to_rust.unwrap_or(f64::NAN)
        );
    }
    for m in missing {
        let _ = writeln!(
            s,
            "| {} | – | – | – | – | – | not run: {} |",
            m.what, m.reason
        );
    }
    let _ = writeln!(
        s,
        "\nSplit bar window (examples/split_bar.toml, both nodes, serial, recording on):\n\n\
         | transport | windows ahead | runs | windows | median µs | p10 µs | p90 µs | compute µs/window | beyond compute µs/window | raw round trip 1 KiB µs | beyond / (2 round trips) |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for r in rows.iter().filter(|r| r.case == "split-bar") {
        let rt = round_trip_1k
            .iter()
            .find(|(t, _)| *t == r.transport)
            .map(|(_, us)| *us);
        let beyond = r.beyond_compute_us.unwrap_or(f64::NAN);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {} |",
            r.transport,
            r.windows_ahead.map_or("auto".into(), |a| a.to_string()),
            r.runs,
            r.windows,
            r.median_us,
            r.p10_us,
            r.p90_us,
            r.compute_us.unwrap_or(f64::NAN),
            beyond,
            rt.map_or("–".into(), |v| format!("{v:.1}")),
            rt.map_or("–".into(), |v| format!("{:.2}", beyond / (2.0 * v))),
        );
    }
    let split: Vec<&WindowRow> = rows.iter().filter(|r| r.case == "split-bar").collect();
    if let Some(first) = split.first() {
        let _ = writeln!(
            s,
            "\nWhere a split bar window goes (columns: transport × windows in flight, 1 = lockstep, \
             auto = the coordinator's choice, its mean in the row windows in flight; \
             µs per window, mean over runs; the coordinator's phases, \
             then each node's compute, coupling wait and idle time; the serial chain overlaps \
             them, so they do not add up to the window):\n"
        );
        let mut head = "| part |".to_string();
        let mut rule = "|---|".to_string();
        for r in &split {
            let _ = write!(
                head,
                " {} × {} |",
                r.transport,
                r.windows_ahead.map_or("auto".into(), |a| a.to_string())
            );
            rule.push_str("---:|");
        }
        let _ = writeln!(s, "{head}\n{rule}");
        for (name, _) in &first.breakdown {
            let mut line = format!("| {} |", name.replace('_', " "));
            for r in &split {
                let v = r.breakdown.iter().find(|(n, _)| n == name).map(|p| p.1);
                let _ = write!(line, " {} |", v.map_or("–".into(), |v| format!("{v:.1}")));
            }
            let _ = writeln!(s, "{line}");
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_of_a_known_sample() {
        let mut x: Vec<f64> = (0..=100).rev().map(f64::from).collect();
        assert_eq!(quantiles(&mut x), (50.0, 10.0, 90.0));
        assert!(quantiles(&mut []).0.is_nan());
    }

    #[test]
    fn the_embedded_split_bar_has_its_window() {
        let w = split_bar_window().expect("window");
        assert!((w - 4.956056900399753e-7).abs() < 1e-20, "{w}");
    }

    #[test]
    fn compute_split_reads_the_summary() {
        let s: serde_json::Value = serde_json::from_str(
            r#"{"windows": 4, "window_loop_s": 1.0,
                "nodes": {"a": {"compute_s": 0.25}, "b": {"compute_s": 0.5}}}"#,
        )
        .expect("json");
        assert_eq!(compute_split(&s).expect("split"), (0.1875, 0.0625));
        let bad: serde_json::Value = serde_json::from_str(r#"{"windows": 4}"#).expect("json");
        assert!(compute_split(&bad).is_err());
    }
}
