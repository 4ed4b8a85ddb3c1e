//! Helpers shared by the end-to-end tests: find the built binaries, write case files into a
//! scratch directory, run `cosim`, and read back what a run recorded.

/// The policy of tests that need something a machine may lack: skip with a message outside
/// CI, fail under `CI=true`.
pub use mechanics::gpu::skip_or_fail;
use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Mutex, Once};

/// `target/<profile>`: the directory of the running test binary's parent.
pub fn bin_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test binary path");
    let deps = exe.parent().expect("deps dir");
    deps.parent().expect("profile dir").to_path_buf()
}

/// Path of a workspace binary; the end-to-end tests need `cargo build --release --workspace`
/// first (`cargo test` does not build the binaries of other packages).
pub fn bin(name: &str) -> PathBuf {
    let p = bin_dir().join(name);
    assert!(
        p.is_file(),
        "{} not built: run `cargo build --release --workspace && cargo test --release --workspace`",
        p.display()
    );
    p
}

pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("workspace")
        .to_path_buf()
}

static COUNTER: AtomicU32 = AtomicU32::new(0);

/// Every scratch directory of this process, and those of the tests that failed (kept).
static SCRATCH: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
static KEEP: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
static CLEANUP: Once = Once::new();

thread_local! {
    /// The scratch directories the test running on this thread made.
    static MINE: RefCell<Vec<PathBuf>> = const { RefCell::new(Vec::new()) };
}

/// A fresh scratch directory and a unique run id for one test. When the test binary exits,
/// the directories of the tests that passed are removed (otherwise every run's recordings
/// and frames stay behind and pile up); those of a test that panicked are kept, for a look at
/// what it left (the panic message is followed by a line naming them).
pub fn scratch(tag: &str) -> (PathBuf, String) {
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let id = format!("t{}-{}-{}", std::process::id() % 100_000, n, tag);
    // Run ids are at most 32 characters: 24 here leaves tests room for a suffix of their
    // own (`{id}-serial`), however many tests the binary has counted.
    let id: String = id.chars().take(24).collect();
    let dir = std::env::temp_dir().join(format!("cosim-tests/{id}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    remove_at_exit(&dir);
    (dir, id)
}

/// Books `dir` for removal at exit unless the thread that made it panics.
fn remove_at_exit(dir: &Path) {
    CLEANUP.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            previous(info);
            let mine = MINE.with(|m| std::mem::take(&mut *m.borrow_mut()));
            if !mine.is_empty() {
                eprintln!("kept for inspection: {mine:?}");
                lock(&KEEP).extend(mine);
            }
        }));
        // SAFETY: `remove_scratch` is a plain `extern "C" fn` that takes no arguments and
        // returns. The C library runs it at exit, whether the test binary's `main` returns
        // (all passed) or libtest calls `std::process::exit` (a failure); a binary killed by
        // a signal leaves its folders.
        unsafe {
            libc::atexit(remove_scratch);
        }
    });
    lock(&SCRATCH).push(dir.to_path_buf());
    MINE.with(|m| m.borrow_mut().push(dir.to_path_buf()));
}

extern "C" fn remove_scratch() {
    let keep = lock(&KEEP).clone();
    for d in lock(&SCRATCH).iter().filter(|d| !keep.contains(d)) {
        let _ = std::fs::remove_dir_all(d);
    }
}

/// A lock that a panicking test cannot poison for the others.
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Run `cosim` with arguments.
pub fn cosim(args: &[&str]) -> Output {
    Command::new(bin("cosim"))
        .args(args)
        .env("COSIM_LOG", "warn")
        .output()
        .expect("cosim runs")
}

/// Run a case file; returns the output.
pub fn run_case(case: &Path, out: &Path, run_id: &str, extra: &[&str]) -> Output {
    let mut args = vec![
        "run",
        case.to_str().expect("utf-8 path"),
        "--output",
        out.to_str().expect("utf-8 path"),
        "--run-id",
        run_id,
        "--quiet",
    ];
    args.extend_from_slice(extra);
    cosim(&args)
}

/// Run `examples/<file>` with `--variant <variant>` into a scratch folder of `tag`; the run
/// must finish (exit 0). Returns the output folder.
pub fn run_example(file: &str, variant: &str, tag: &str) -> PathBuf {
    let (dir, id) = scratch(tag);
    let out = dir.join("out");
    let case = workspace_root().join("examples").join(file);
    run_case_ok(&case, &out, &id, &["--variant", variant]);
    out
}

/// [`run_case`], which must finish (exit 0); its stdout and stderr are the message if not.
pub fn run_case_ok(case: &Path, out: &Path, run_id: &str, extra: &[&str]) {
    let o = run_case(case, out, run_id, extra);
    assert!(
        o.status.success(),
        "{} {extra:?}: {}{}",
        case.display(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Run one of the independent checks in `tools/` (Python, the official readers) with
/// `args`; returns (passed, its stdout + stderr).
fn python_tool(script: &str, args: &[&std::ffi::OsStr]) -> (bool, String) {
    let o = Command::new("python3")
        .arg(workspace_root().join("tools").join(script))
        .args(args)
        .output()
        .expect("python3 runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    (o.status.success(), text)
}

/// Run the independent MCAP check (`tools/check_mcap.py`, the official Python reader) with
/// `flag` (`--require-json` or `--recover`); returns (passed, its stdout + stderr).
pub fn check_mcap(mcap: &Path, flag: &str) -> (bool, String) {
    python_tool("check_mcap.py", &[mcap.as_os_str(), flag.as_ref()])
}

/// Open every VTK file (.vtu, .vtk) under `dir` with meshio, the independent reader
/// (`tools/check_vtk.py`), requiring the named arrays in each; (passed, its output).
pub fn check_vtk(dir: &Path, require: &[&str]) -> (bool, String) {
    let mut args = vec![dir.as_os_str()];
    for r in require {
        args.extend_from_slice(&["--require".as_ref(), r.as_ref()]);
    }
    python_tool("check_vtk.py", &args)
}

/// Per-window 3-vector `key` of a node's report (e.g. `interface_impulse`), from the
/// `/cosim/node/<node>` channel: (window, [x, y, z]).
pub fn node_vectors(mcap: &Path, node: &str, key: &str) -> Vec<(u64, [f64; 3])> {
    let (msgs, _) = coordinator::record::read_json(mcap).expect("readable recording");
    let topic = format!("/cosim/node/{node}");
    msgs.iter()
        .filter(|m| m.topic == topic)
        .filter_map(|m| {
            let v: serde_json::Value = serde_json::from_slice(&m.data).ok()?;
            let a = v[key].as_array()?;
            Some((
                v["window"].as_u64()?,
                [
                    a.first()?.as_f64()?,
                    a.get(1)?.as_f64()?,
                    a.get(2)?.as_f64()?,
                ],
            ))
        })
        .collect()
}

/// Per-window values of a node's report scalar (e.g. `tip_displacement`), from the
/// `/cosim/node/<node>` channel of a recording: (time, value). A vector's component `K_x`
/// (`_y`, `_z`) is read from the vector `K` the recording holds.
pub fn node_series(mcap: &Path, node: &str, key: &str) -> Vec<(f64, f64)> {
    let (msgs, _) = coordinator::record::read_json(mcap).expect("readable recording");
    let topic = format!("/cosim/node/{node}");
    let component = ["_x", "_y", "_z"]
        .iter()
        .position(|a| key.ends_with(a))
        .map(|d| (&key[..key.len() - 2], d));
    msgs.iter()
        .filter(|m| m.topic == topic)
        .filter_map(|m| {
            let v: serde_json::Value = serde_json::from_slice(&m.data).ok()?;
            let x = match (v.get(key), component) {
                (Some(x), _) => x.as_f64()?,
                (None, Some((base, d))) => v.get(base)?.get(d)?.as_f64()?,
                (None, None) => return None,
            };
            Some((v["time"].as_f64()?, x))
        })
        .collect()
}

pub fn summary(out: &Path) -> serde_json::Value {
    let s = std::fs::read_to_string(out.join("summary.json")).expect("summary.json");
    serde_json::from_str(&s).expect("summary is JSON")
}

/// The split-bar case with the given left/right element counts and transport.
pub fn split_bar_case(
    dir: &Path,
    n_left: usize,
    n_right: usize,
    right_courant: f64,
    transport: &str,
    periods: f64,
) -> PathBuf {
    let c = (200e9f64 / 7860.0).sqrt();
    let h = 0.5 / n_left as f64;
    let window = 0.5 * h / c;
    let end = periods * 4.0 / c;
    let text = format!(
        r#"
[run]
name = "split-bar"
end_time = {end:e}
window = {window:e}
transport = "{transport}"
output = "out"

[nodes.left]
solver = "solid-node"
model = "bar-1d"
[nodes.left.params]
length = 0.5
elements = {n_left}
young = 200e9
density = 7860.0
area = 1e-4
fixed = "left"
load_end = "none"
courant = 1.0
interfaces = {{ tip = "right" }}

[nodes.right]
solver = "solid-node"
model = "bar-1d"
[nodes.right.params]
length = 0.5
x0 = 0.5
elements = {n_right}
young = 200e9
density = 7860.0
area = 1e-4
fixed = "none"
tip_force = 1000.0
load_end = "right"
courant = {right_courant}
interfaces = {{ root = "left" }}

[[couplings]]
name = "mid"
kind = "kinematic"
driver = "left.tip"
responder = "right.root"
"#
    );
    let p = dir.join("split.toml");
    std::fs::write(&p, text).expect("write case");
    p
}

/// Exact tip displacement of the bar under a step end load: a triangle wave between 0 and
/// 2FL/(EA) with period 4L/c.
pub fn exact_tip(t: f64) -> f64 {
    let (e, rho, a, l, f) = (200e9f64, 7860.0f64, 1e-4, 1.0, 1e3);
    let c = (e / rho).sqrt();
    let amp = 2.0 * f * l / (e * a);
    let period = 4.0 * l / c;
    let ph = (t % period) / period;
    amp * if ph < 0.5 { 2.0 * ph } else { 2.0 * (1.0 - ph) }
}

pub fn amplitude() -> f64 {
    2.0 * 1e3 * 1.0 / (200e9 * 1e-4)
}

/// A NaN-keeping maximum for error and peak folds (`.fold(0.0, nan_max)`).
pub use solid_node::fixtures::nan_max;

/// Largest |tip − exact| / amplitude over a series (NaN if any sample is).
pub fn tip_error(series: &[(f64, f64)]) -> f64 {
    assert!(!series.is_empty(), "no tip displacement was recorded");
    series
        .iter()
        .map(|&(t, u)| (u - exact_tip(t)).abs() / amplitude())
        .fold(0.0, nan_max)
}

/// Files in /dev/shm whose name contains `needle`.
pub fn shm_files(needle: &str) -> Vec<String> {
    std::fs::read_dir("/dev/shm")
        .map(|d| {
            d.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().to_string())
                .filter(|n| n.contains(needle))
                .collect()
        })
        .unwrap_or_default()
}

/// Processes whose command line contains `needle` (excluding this one).
pub fn processes_with(needle: &str) -> Vec<u32> {
    let me = std::process::id();
    let mut v = Vec::new();
    if let Ok(d) = std::fs::read_dir("/proc") {
        for e in d.flatten() {
            let Ok(pid) = e.file_name().to_string_lossy().parse::<u32>() else {
                continue;
            };
            if pid == me {
                continue;
            }
            if let Ok(cmd) = std::fs::read(format!("/proc/{pid}/cmdline")) {
                let cmd = String::from_utf8_lossy(&cmd).replace('\0', " ");
                // A zombie has an empty cmdline and is not a survivor.
                if cmd.contains(needle) {
                    v.push(pid);
                }
            }
        }
    }
    v
}

/// The counts of the report's first line: (compared windows, recorded windows, fields,
/// values, report values).
pub fn replay_counts(stdout: &str) -> (u64, u64, u64, u64, u64) {
    let line = stdout
        .lines()
        .find(|l| l.starts_with("replayed node"))
        .unwrap_or_else(|| panic!("no report line in: {stdout}"));
    let tail = line.rsplit_once(": ").map_or(line, |t| t.1);
    let nums: Vec<u64> = tail
        .split(|c: char| !c.is_ascii_digit())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    assert_eq!(nums.len(), 5, "{line}");
    (nums[0], nums[1], nums[2], nums[3], nums[4])
}

/// Windows of `node` in a recording, counted from its per-window report channel.
pub fn recorded_windows(mcap: &Path, node: &str) -> u64 {
    node_series(mcap, node, "kinetic_energy").len() as u64
}

pub fn replay_node(
    mcap: &Path,
    node: &str,
    run_id: &str,
    extra: &[&str],
) -> (bool, String, String) {
    let (code, out, err) = replay_status(mcap, node, run_id, extra);
    (code == Some(0), out, err)
}

/// `cosim replay` of `node`: (exit code, stdout, stderr).
pub fn replay_status(
    mcap: &Path,
    node: &str,
    run_id: &str,
    extra: &[&str],
) -> (Option<i32>, String, String) {
    let mut args = vec![
        "replay",
        mcap.to_str().unwrap(),
        "--node",
        node,
        "--run-id",
        run_id,
    ];
    args.extend_from_slice(extra);
    let o = cosim(&args);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).to_string(),
        String::from_utf8_lossy(&o.stderr).to_string(),
    )
}

/// Nothing of run `id` is left: no live process on its command line, no shared memory.
pub fn nothing_left(id: &str) {
    let alive = live_processes(id);
    assert!(alive.is_empty(), "surviving node processes: {alive:?}");
    assert!(
        shm_files(id).is_empty(),
        "left in /dev/shm: {:?}",
        shm_files(id)
    );
}

/// `cosim replay`: replay `node` of `mcap` with its recorded executable and require bit-identity over every
/// recorded window; returns the window count.
pub fn assert_replays_bit_identically(mcap: &Path, node: &str, tag: &str) -> u64 {
    let (_, id) = scratch(tag);
    let (ok, out, err) = replay_node(mcap, node, &id, &[]);
    println!("{node}: {out}{err}");
    assert!(ok, "{node}: {err}");
    assert!(out.contains("bit-identical"), "{node}: {out}");
    let (compared, recorded, fields, values, report) = replay_counts(&out);
    let expected = recorded_windows(mcap, node);
    assert!(expected > 0, "{node}: no window in the recording");
    assert_eq!(recorded, expected, "{node}: recorded windows");
    assert_eq!(compared, expected, "{node}: compared windows");
    assert!(
        fields >= compared && values >= fields && report >= compared,
        "{out}"
    );
    nothing_left(&id);
    compared
}

/// A split bar long enough to be interrupted (many short windows), with a short heartbeat
/// timeout; returns (case file, output directory, run id).
pub fn long_split_bar(tag: &str, transport: &str) -> (PathBuf, PathBuf, String) {
    let (dir, id) = scratch(tag);
    let case = split_bar_case(&dir, 100, 300, 0.5, transport, 400.0);
    let text = std::fs::read_to_string(&case).expect("case").replace(
        "output = \"out\"",
        "output = \"out\"\nheartbeat_ms = 100\nheartbeat_timeout = 1.0",
    );
    std::fs::write(&case, text).expect("write case");
    (case, dir.join("out"), id)
}

/// `cosim run` in the background, stdout and stderr piped.
pub fn spawn_cosim(case: &Path, out: &Path, run_id: &str) -> std::process::Child {
    spawn_cosim_with(case, out, run_id, &[])
}

/// `cosim run` in the background with further arguments (`--variant`, `--set`), stdout and
/// stderr piped.
pub fn spawn_cosim_with(
    case: &Path,
    out: &Path,
    run_id: &str,
    extra: &[&str],
) -> std::process::Child {
    Command::new(bin("cosim"))
        .args([
            "run",
            case.to_str().expect("utf-8 path"),
            "--output",
            out.to_str().expect("utf-8 path"),
            "--run-id",
            run_id,
            "--quiet",
        ])
        .args(extra)
        .env("COSIM_LOG", "warn")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("cosim starts")
}

/// The pid of node `node` of run `id`, if it runs.
pub fn node_pid(id: &str, node: &str) -> Option<u32> {
    processes_with(&format!("--run {id} --node {node}"))
        .first()
        .copied()
}

/// Processes of run `id` that are alive (a zombie waiting to be reaped is not).
pub fn live_processes(id: &str) -> Vec<u32> {
    processes_with(&format!("--run {id}"))
        .into_iter()
        .filter(|pid| {
            std::fs::read_to_string(format!("/proc/{pid}/stat"))
                .map(|s| !s.contains(") Z"))
                .unwrap_or(false)
        })
        .collect()
}

/// Wait up to `limit` for `child` to exit.
pub fn wait_exit(
    child: &mut std::process::Child,
    limit: std::time::Duration,
) -> Option<std::process::ExitStatus> {
    let start = std::time::Instant::now();
    loop {
        if let Ok(Some(s)) = child.try_wait() {
            return Some(s);
        }
        if start.elapsed() > limit {
            return None;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

/// The windows of a recording's `/cosim/balance` channel, in file order (a damaged file: those
/// of its complete chunks).
pub fn balance_windows(mcap: &Path) -> Vec<u64> {
    let (msgs, _) = coordinator::record::read_json(mcap).expect("readable recording");
    msgs.iter()
        .filter(|m| m.topic == "/cosim/balance")
        .filter_map(|m| {
            serde_json::from_slice::<serde_json::Value>(&m.data).ok()?["window"].as_u64()
        })
        .collect()
}

/// A PNG's size and RGB pixels, row by row (read with the `image` crate).
pub fn png_pixels(path: &Path) -> (u32, u32, Vec<[u8; 3]>) {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8();
    let (w, h) = img.dimensions();
    (w, h, img.pixels().map(|p| p.0).collect())
}

/// A small pseudo-random sequence (xorshift) for fault campaigns, seeded from the clock or
/// from `COSIM_TEST_SEED`; tests print the seed so a failing draw can be repeated.
pub struct Draw(pub u64);

impl Draw {
    /// Seeded from `COSIM_TEST_SEED` when set, else from the clock; never zero.
    pub fn seeded() -> Draw {
        let seed = std::env::var("COSIM_TEST_SEED")
            .ok()
            .and_then(|s| s.parse::<u64>().ok())
            .unwrap_or_else(|| {
                std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map(|d| d.as_nanos() as u64)
                    .unwrap_or(1)
            });
        Draw(seed | 1)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Run the independent series check (`tools/check_pvd.py`: Python's XML parser and meshio)
/// on every `.pvd` under `dir`, requiring `series` of them, each opening with a t = 0 frame,
/// every frame once; `displacement` zero in each first frame. (passed, its output).
pub fn check_pvd(dir: &Path, series: usize) -> (bool, String) {
    let n = series.to_string();
    python_tool(
        "check_pvd.py",
        &[
            dir.as_os_str(),
            "--series".as_ref(),
            n.as_ref(),
            "--zero-at-t0".as_ref(),
            "displacement".as_ref(),
        ],
    )
}

/// Whether `what` is available; if not, the shared policy applies: a skip with `hint`
/// outside CI, a failure under `CI=true`.
fn need(ok: bool, what: &str, hint: &str) -> bool {
    if !ok {
        skip_or_fail(what, &format!("missing ({hint})"));
    }
    ok
}

/// Whether Python module `module` imports (the PyPI package `package`); if not, skipped
/// outside CI and a failure under `CI=true`.
pub fn python_module_or_skip(module: &str, package: &str) -> bool {
    python_imports_or_skip(
        module,
        &format!("the Python module `{module}`"),
        &format!("python3 -m pip install {package}"),
    )
}

/// Whether `import {modules}` succeeds; `what` and `hint` name it in the skip or failure.
fn python_imports_or_skip(modules: &str, what: &str, hint: &str) -> bool {
    let ok = Command::new("python3")
        .args(["-c", &format!("import {modules}")])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    need(ok, what, hint)
}

/// Whether the Python participant package `cosim` (with numpy) imports; if not, skipped
/// outside CI and a failure under `CI=true`.
pub fn python_package_or_skip() -> bool {
    python_imports_or_skip(
        "cosim, numpy",
        "the Python package `cosim` (with numpy)",
        "python3 -m pip install ./python",
    )
}

/// Build the C bar (`examples/external/bar.c`) into `exe` against the participant library in
/// target/release, as its Makefile does; None (skipped outside CI) without library or compiler.
pub fn build_c_bar(exe: &Path) -> Option<PathBuf> {
    let lib = bin_dir();
    if !need(
        lib.join("libcosim_participant.so").is_file(),
        "target/release/libcosim_participant.so",
        "cargo build --release --workspace",
    ) {
        return None;
    }
    let root = workspace_root();
    // built beside it and renamed over it: tests build the same file side by side, and one
    // may be running the old one (a rename keeps its inode alive; writing in place would not)
    static BUILDS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let k = BUILDS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = exe.with_extension(format!("building-{}-{k}", std::process::id()));
    let status = Command::new("cc")
        .args(["-O2", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(root.join("participant-c/include"))
        .arg("-o")
        .arg(&tmp)
        .arg(root.join("examples/external/bar.c"))
        .arg("-L")
        .arg(&lib)
        .arg("-lcosim_participant")
        .arg(format!("-Wl,-rpath,{}", lib.display()))
        .arg("-lm")
        .status();
    if !need(status.is_ok(), "a C compiler (cc)", "apt-get install gcc") {
        return None;
    }
    assert!(status.is_ok_and(|s| s.success()), "bar.c does not compile");
    std::fs::rename(&tmp, exe).expect("the built C node renamed into place");
    Some(exe.to_path_buf())
}

/// Wait until the recording of the live run `child` shows `n` windows in its balance channel
/// (its chunks reach the disk at window boundaries): an event on recorded progress, not a
/// fixed sleep. Panics if the run exits first or `limit` passes; returns the windows seen.
pub fn wait_for_windows(
    mcap: &Path,
    n: usize,
    limit: std::time::Duration,
    child: &mut std::process::Child,
) -> usize {
    let start = std::time::Instant::now();
    loop {
        if let Ok(Some(s)) = child.try_wait() {
            panic!("the run exited ({s}) before its recording showed {n} windows");
        }
        // A file still being written may not be readable yet: ask again.
        let seen = coordinator::record::read_json(mcap)
            .map(|(msgs, _)| msgs.iter().filter(|m| m.topic == "/cosim/balance").count())
            .unwrap_or(0);
        if seen >= n {
            return seen;
        }
        assert!(
            start.elapsed() < limit,
            "{}: {seen} of {n} windows after {limit:?}",
            mcap.display()
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// Send signal `sig` to our own child process.
pub fn signal_child(child: &std::process::Child, sig: i32) {
    // SAFETY: kill with the pid of our own child and a valid signal number.
    let rc = unsafe { libc::kill(child.id() as i32, sig) };
    assert_eq!(rc, 0, "kill failed");
}

/// Every file under `dir` (recursively) with its bytes, by path relative to `dir`, but for
/// the names in `except`.
pub fn files_under(dir: &Path, except: &[&str]) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).expect("a readable folder").flatten() {
            let p = e.path();
            if except.iter().any(|x| e.file_name() == *x) {
                continue;
            }
            if p.is_dir() {
                todo.push(p);
            } else {
                let rel = p.strip_prefix(dir).expect("under dir").to_path_buf();
                match std::fs::read(&p) {
                    Ok(bytes) => {
                        out.insert(rel, bytes);
                    }
                    // Gone since the listing: a live run's file written under a temporary
                    // name and renamed.
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                    Err(e) => panic!("{}: {e}", p.display()),
                }
            }
        }
    }
    out
}

/// SIGKILL the `cosim` of run `id`, as the OOM killer would, and wait until its nodes, which
/// watch their parent, are gone too.
pub fn kill_cosim(child: &mut std::process::Child, id: &str) {
    signal_child(child, libc::SIGKILL);
    let _ = child.wait();
    let t = std::time::Instant::now();
    while !live_processes(id).is_empty() && t.elapsed() < std::time::Duration::from_secs(10) {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert!(
        live_processes(id).is_empty(),
        "the killed run's nodes live on"
    );
}

/// `cosim render`'s picture of the run in `out` (one node's `field` chosen, `NODE.FIELD`, or
/// the defaults) drawn as a figure for a paper, into `out/paper_<field>.png`: a length scale,
/// and a colour bar per field drawn, each captioned with its node, field and unit (a tensor
/// with the measure drawn of it). Returns what it drew.
pub fn paper_picture(out: &Path, field: Option<&str>) -> coordinator::fields::Picture {
    let choice = field.map(|f| coordinator::fields::Choice::parse(f).expect("NODE.FIELD"));
    let png = out.join(format!("paper_{}.png", field.unwrap_or("default")));
    let p = coordinator::fields::render(out, None, &png, choice, None, Default::default())
        .expect("a picture");
    println!(
        "{}: length scale {:?}, colour bars {:?}",
        png.display(),
        p.length_scale,
        p.scales.iter().map(|s| &s.label).collect::<Vec<_>>()
    );
    assert!(
        p.length_scale.is_some(),
        "{}: no length scale",
        png.display()
    );
    assert!(!p.scales.is_empty(), "{}: no colour bar", png.display());
    for s in &p.scales {
        assert!(
            s.label.contains(": ") && s.label.ends_with(']') && s.hi > s.lo,
            "{}: colour bar '{}' over {}..{}",
            png.display(),
            s.label,
            s.lo,
            s.hi
        );
    }
    p
}

/// The inline piece of an unstructured-grid VTK file (`.vtu`), as the nodes write them.
pub fn vtu_piece(vtu: &Path) -> vtkio::model::UnstructuredGridPiece {
    use vtkio::model::{DataSet, Piece, Vtk};
    let vtk = Vtk::import(vtu).unwrap_or_else(|e| panic!("{}: {e}", vtu.display()));
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("{}: not an unstructured grid", vtu.display())
    };
    let Some(Piece::Inline(p)) = pieces.into_iter().next() else {
        panic!("{}: no inline piece", vtu.display())
    };
    *p
}

/// The data array `name` among `attrs` (a piece's point or cell data), as f64s.
pub fn vtu_array(attrs: Vec<vtkio::model::Attribute>, name: &str) -> Option<Vec<f64>> {
    attrs.into_iter().find_map(|a| match a {
        vtkio::model::Attribute::DataArray(d) if d.name == name => d.data.cast_into::<f64>(),
        _ => None,
    })
}
