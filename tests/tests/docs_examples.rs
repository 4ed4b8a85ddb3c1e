//! Every code example of the README, PROTOCOL.md and docs/*.md holds up: the shell commands
//! run (a `cosim run` cut to its first windows), the Python reads back what those runs wrote,
//! the TOML is a case fragment whose every key the case schema knows, the C names what the
//! participant header declares, the JSON parses. Blocks without a language (outputs,
//! diagrams) and `text` (formulas) are not code.

use cosim_tests::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A fenced code block: its document, first line, language and text.
struct Block {
    doc: String,
    line: usize,
    lang: String,
    text: String,
}

/// The documents a user reads.
fn documents() -> Vec<PathBuf> {
    let root = workspace_root();
    let mut docs = vec![root.join("README.md"), root.join("PROTOCOL.md")];
    let mut more: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .expect("docs/")
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    more.sort();
    docs.extend(more);
    docs
}

/// The fenced blocks of every document, in order.
fn blocks() -> Vec<Block> {
    let root = workspace_root();
    let mut out = Vec::new();
    for d in documents() {
        let text = std::fs::read_to_string(&d).expect("a readable document");
        let doc = d.strip_prefix(&root).unwrap().display().to_string();
        let mut open: Option<Block> = None;
        for (i, line) in text.lines().enumerate() {
            match (open.take(), line.trim_start().strip_prefix("```")) {
                (None, Some(lang)) => {
                    open = Some(Block {
                        doc: doc.clone(),
                        line: i + 1,
                        lang: lang.trim().to_string(),
                        text: String::new(),
                    })
                }
                (Some(b), Some(_)) => out.push(b),
                (Some(mut b), None) => {
                    b.text.push_str(line);
                    b.text.push('\n');
                    open = Some(b);
                }
                (None, None) => {}
            }
        }
    }
    out
}

/// The commands of a shell block: continuation lines joined, comments and blank lines left
/// out, `a && b` as two commands.
fn commands(text: &str) -> Vec<String> {
    let joined = text.replace("\\\n", " ");
    joined
        .lines()
        .map(|l| l.split(" #").next().unwrap_or("").trim())
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .flat_map(|l| l.split("&&").map(|c| c.trim().to_string()))
        .collect()
}

/// Words of a command, single-quoted words kept whole.
fn words(cmd: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut quoted = false;
    for c in cmd.chars() {
        match c {
            '\'' => quoted = !quoted,
            ' ' if !quoted => {
                if !cur.is_empty() {
                    out.push(std::mem::take(&mut cur));
                }
            }
            _ => cur.push(c),
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

/// Commands that set up the environment: CI runs them before the tests (`.ci/run`), so
/// here they are only recognised.
fn environment(cmd: &str) -> bool {
    [
        "cargo ",
        "python3 -m venv",
        ". .venv/bin/activate",
        "python3 -m pip install",
    ]
    .iter()
    .any(|p| cmd.starts_with(p))
}

/// What `cosim validate --json` says of a case (and variant): its window, end time and
/// output folder.
fn case_facts(dir: &Path, args: &[String]) -> (f64, f64, String) {
    let case = &args[0];
    let mut v = vec!["validate".to_string(), case.clone(), "--json".into()];
    if let Some(i) = args.iter().position(|a| a == "--variant") {
        v.extend(["--variant".into(), args[i + 1].clone()]);
    }
    let o = Command::new(bin("cosim"))
        .args(&v)
        .current_dir(dir)
        .output()
        .expect("cosim validate");
    let j: serde_json::Value = serde_json::from_slice(&o.stdout)
        .unwrap_or_else(|_| panic!("{v:?}: {}", String::from_utf8_lossy(&o.stderr)));
    (
        j["window"].as_f64().expect("window"),
        j["end_time"].as_f64().expect("end_time"),
        j["output"].as_str().expect("output").to_string(),
    )
}

/// Runs the shell blocks in `dir` (a copy of the examples and the build reachable from it as
/// from the repository's root). A `cosim run` is cut to 4 windows more than the last run into the same
/// folder (so a restart reaches a later time); in a block that restarts, runs checkpoint
/// every window, and a folder no run has written yet is first written by the block's own
/// `cosim run … --restart FOLDER`, without the restart. Returns how many commands ran and
/// how many were the environment's.
fn run_shell(dir: &Path, blocks: &[&Block]) -> (usize, usize) {
    let cosim = bin("cosim");
    // how many runs have written each output folder
    let mut runs: BTreeMap<String, usize> = BTreeMap::new();
    let (mut ran, mut env) = (0, 0);
    for b in blocks {
        let cmds = commands(&b.text);
        let checkpoints = b.text.contains("restart");
        for c in &cmds {
            if environment(c) {
                env += 1;
                continue;
            }
            let w = words(c);
            let program = match w[0].as_str() {
                "cosim" | "./target/release/cosim" => cosim.clone(),
                "make" => PathBuf::from("make"),
                _ => panic!(
                    "{}:{}: a command this test does not know: {c}",
                    b.doc, b.line
                ),
            };
            let mut args = w[1..].to_vec();
            match (program == cosim, args.first().map(String::as_str)) {
                (true, Some("run")) => {
                    let (window, end, output) = case_facts(dir, &args[1..]);
                    let folder = flag(&args, "--restart").unwrap_or(output);
                    let k = bump(&mut runs, &folder);
                    args.extend(cut(k, window, end, checkpoints));
                }
                (true, Some("restart")) => {
                    let folder = args[1].clone();
                    if !runs.contains_key(&folder) {
                        start(dir, &cmds, &folder, b, &mut runs);
                    }
                    let window = summary(&dir.join(&folder))["window"]
                        .as_f64()
                        .expect("the run's window");
                    let k = bump(&mut runs, &folder);
                    args.extend(cut(k, window, f64::INFINITY, false));
                }
                _ => {}
            }
            run_ok(dir, &program, &args, b, c);
            ran += 1;
        }
    }
    (ran, env)
}

/// The value after `name` among `args`.
fn flag(args: &[String], name: &str) -> Option<String> {
    let i = args.iter().position(|a| a == name)?;
    args.get(i + 1).cloned()
}

/// One more run into `folder`: how many there have been with it.
fn bump(runs: &mut BTreeMap<String, usize>, folder: &str) -> usize {
    let k = runs.entry(folder.to_string()).or_insert(0);
    *k += 1;
    *k
}

/// The settings that cut the `k`-th run into a folder to 4k windows (at most the case's
/// end), checkpointing every window if asked.
fn cut(k: usize, window: f64, end: f64, checkpoints: bool) -> Vec<String> {
    let t = (4.0 * k as f64 * window).min(end);
    let mut out = vec!["--set".to_string(), format!("run.end_time={t:e}")];
    if checkpoints {
        out.extend(["--set".into(), "run.checkpoint_every=1".into()]);
    }
    out
}

/// The run that a block's `cosim restart FOLDER` continues: its `cosim run … --restart
/// FOLDER` without the restart, into FOLDER.
fn start(dir: &Path, cmds: &[String], folder: &str, b: &Block, runs: &mut BTreeMap<String, usize>) {
    let first = cmds
        .iter()
        .map(|c| words(c))
        .find(|w| w.len() > 2 && w[1] == "run" && w.iter().any(|x| x == folder))
        .unwrap_or_else(|| panic!("{}:{}: no run of {folder} to restart", b.doc, b.line));
    let mut args: Vec<String> = first[1..]
        .iter()
        .take_while(|x| *x != "--restart")
        .cloned()
        .collect();
    let (window, end, _) = case_facts(dir, &args[1..]);
    let k = bump(runs, folder);
    args.extend(cut(k, window, end, true));
    args.extend(["--output".into(), folder.to_string()]);
    let what = format!("(the run to restart) cosim {}", args.join(" "));
    run_ok(dir, &bin("cosim"), &args, b, &what);
}

/// Runs `program args` in `dir`; the test fails, naming the block and the command, unless it
/// exits 0.
fn run_ok(dir: &Path, program: &Path, args: &[String], b: &Block, what: &str) {
    let started = std::time::Instant::now();
    let o = Command::new(program)
        .args(args)
        .current_dir(dir)
        .env("PATH", path_with_cosim())
        .output()
        .expect("the command starts");
    println!(
        "{}:{}: {what} ({:.1} s)",
        b.doc,
        b.line,
        started.elapsed().as_secs_f64()
    );
    assert!(
        o.status.success(),
        "{}:{}: `{what}` ({program:?} {args:?}) failed:\n{}{}",
        b.doc,
        b.line,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// PATH with the build's binaries first (`cosim` and the nodes).
fn path_with_cosim() -> String {
    format!(
        "{}:{}",
        bin_dir().display(),
        std::env::var("PATH").unwrap_or_default()
    )
}

/// The key paths of a TOML value (`run.balance.energy`, `couplings[].kind`), params tables
/// left whole (a model's parameters are the node's to check).
fn key_paths(prefix: &str, v: &toml::Value, out: &mut Vec<String>) {
    match v {
        toml::Value::Table(t) => {
            for (k, x) in t {
                let p = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                out.push(p.clone());
                if k != "params" {
                    key_paths(&p, x, out);
                }
            }
        }
        toml::Value::Array(a) if a.iter().all(|x| x.is_table()) => {
            for x in a {
                key_paths(&format!("{prefix}[]"), x, out);
            }
        }
        _ => {}
    }
}

/// The schema object a key path of the case file names, following `$ref`s, `properties`,
/// `additionalProperties` (a node or variant by name) and `items`; None where the schema
/// does not know it.
fn schema_at<'a>(root: &'a serde_json::Value, path: &str) -> Option<&'a serde_json::Value> {
    let resolve = |mut s: &'a serde_json::Value| {
        for _ in 0..8 {
            if let Some(r) = s["$ref"].as_str() {
                s = root.pointer(r.trim_start_matches('#'))?;
            } else if let Some(any) = s["anyOf"].as_array() {
                s = any
                    .iter()
                    .find(|x| x["type"].as_str().is_none_or(|t| t != "null"))?;
            } else {
                return Some(s);
            }
        }
        None
    };
    let mut s = resolve(root)?;
    let mut by_name = false;
    for p in path.split('.') {
        let (key, item) = match p.strip_suffix("[]") {
            Some(k) => (k, true),
            None => (p, false),
        };
        s = if by_name {
            by_name = false;
            resolve(&s["additionalProperties"])?
        } else {
            let next = resolve(s["properties"].get(key)?)?;
            if next["additionalProperties"].is_object() && !next["properties"].is_object() {
                by_name = true; // `nodes.NAME`, `variants.NAME`
            }
            next
        };
        if item {
            s = resolve(&s["items"])?;
        }
    }
    Some(s)
}

#[test]
fn every_code_example_of_the_documents_runs_or_checks() {
    let all = blocks();
    let code: Vec<&Block> = all
        .iter()
        .filter(|b| ["sh", "python", "toml", "c", "json"].contains(&b.lang.as_str()))
        .collect();
    let count = |lang: &str| code.iter().filter(|b| b.lang == lang).count();
    println!(
        "{} code blocks: {} sh, {} python, {} toml, {} c, {} json",
        code.len(),
        count("sh"),
        count("python"),
        count("toml"),
        count("c"),
        count("json")
    );
    // Unknown languages would pass unchecked: every block is one of these, or output.
    for b in &all {
        assert!(
            ["", "sh", "python", "toml", "c", "json", "text"].contains(&b.lang.as_str()),
            "{}:{}: a ```{} block this test does not check",
            b.doc,
            b.line,
            b.lang
        );
    }

    // TOML: a case fragment whose every key the case schema knows; a model's parameter
    // table (no case section at its top) parses.
    let schema: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(workspace_root().join("docs/schema/case.json")).unwrap(),
    )
    .unwrap();
    let mut keys_checked = 0;
    for b in code.iter().filter(|b| b.lang == "toml") {
        let v: toml::Value = toml::from_str(&b.text)
            .unwrap_or_else(|e| panic!("{}:{}: not TOML: {e}", b.doc, b.line));
        let top: Vec<&String> = v.as_table().unwrap().keys().collect();
        if !top
            .iter()
            .all(|k| ["run", "nodes", "couplings", "variants"].contains(&k.as_str()))
        {
            continue;
        }
        let mut paths = Vec::new();
        key_paths("", &v, &mut paths);
        for p in paths {
            assert!(
                schema_at(&schema, &p).is_some(),
                "{}:{}: the case file has no key {p}",
                b.doc,
                b.line
            );
            keys_checked += 1;
        }
    }
    println!("{keys_checked} keys of the TOML examples found in the case schema");
    assert!(keys_checked >= 20, "{keys_checked} keys checked");
    // The walk tells a key the schema lacks from one it has, at every level.
    for (known, unknown) in [
        ("run.window", "run.windw"),
        ("run.balance.energy", "run.balance.enrgy"),
        ("nodes.left.solver", "nodes.left.solvr"),
        ("couplings[].decouple_when", "couplings[].decouple_whn"),
        ("variants.fine.set", "variants.fine.sett"),
    ] {
        assert!(schema_at(&schema, known).is_some(), "{known}");
        assert!(schema_at(&schema, unknown).is_none(), "{unknown}");
    }

    // JSON: parses.
    for b in code.iter().filter(|b| b.lang == "json") {
        serde_json::from_str::<serde_json::Value>(&b.text)
            .unwrap_or_else(|e| panic!("{}:{}: not JSON: {e}", b.doc, b.line));
    }

    // C: an excerpt of a node; every cosim name it uses is declared by the header.
    let header =
        std::fs::read_to_string(workspace_root().join("participant-c/include/cosim_participant.h"))
            .unwrap();
    for b in code.iter().filter(|b| b.lang == "c") {
        let mut names = 0;
        for w in b
            .text
            .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        {
            let lower = w.to_ascii_lowercase();
            if lower.starts_with("cosim") && w.len() > 5 {
                assert!(
                    header.contains(w),
                    "{}:{}: {w} is not in cosim_participant.h",
                    b.doc,
                    b.line
                );
                names += 1;
            }
        }
        assert!(names >= 5, "{}:{}: {names} names", b.doc, b.line);
    }

    // Shell: run, in a folder of their own holding a copy of the examples (runs write
    // beside their case file: examples/out/...) and the build at hand.
    let (dir, _id) = scratch("docs-examples");
    let copied = Command::new("cp")
        .args(["-r", workspace_root().join("examples").to_str().unwrap()])
        .arg(dir.join("examples"))
        .status()
        .expect("cp");
    assert!(copied.success());
    let _ = std::fs::remove_dir_all(dir.join("examples/out"));
    // the C node the split bar's `c` variant names (validating the case checks every
    // variant's executable), built into the copy: other tests build the tree's own
    assert!(build_c_bar(&dir.join("examples/external/bar-c")).is_some());
    // the build, and the C participant's header the external example's Makefile finds
    for link in ["target", "participant-c"] {
        std::os::unix::fs::symlink(workspace_root().join(link), dir.join(link)).unwrap();
    }
    let shell: Vec<&Block> = code.iter().copied().filter(|b| b.lang == "sh").collect();
    let (ran, env) = run_shell(&dir, &shell);
    println!("{ran} commands run, {env} of the environment's recognised");
    assert!(ran >= 12, "{ran} commands");

    // Python: a node script compiles (it runs when cosim launches it: the external
    // examples' tests); the rest runs in that folder, on what the commands wrote.
    if !python_package_or_skip() || !python_module_or_skip("pandas", "pandas") {
        return;
    }
    for (k, b) in code.iter().filter(|b| b.lang == "python").enumerate() {
        let file = dir.join(format!("example_{k}.py"));
        std::fs::write(&file, &b.text).unwrap();
        let args: Vec<&str> = if b.text.contains("run_node") {
            vec!["-m", "py_compile", file.to_str().unwrap()]
        } else {
            vec![file.to_str().unwrap()]
        };
        let o = Command::new("python3")
            .args(&args)
            .current_dir(&dir)
            .output()
            .expect("python3");
        assert!(
            o.status.success(),
            "{}:{}: {}",
            b.doc,
            b.line,
            String::from_utf8_lossy(&o.stderr)
        );
    }
}
