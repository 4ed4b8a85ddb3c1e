//! Each crate compiles once: `cargo build --release --workspace`, `cargo test` after it and
//! maturin's build of the Python package (`cargo rustc` of `cosim-python` alone) resolve
//! every shared dependency with the same features, so none of them compiles a registry crate
//! the others already built. Cargo picks features by the packages a command selects (and
//! leaves the dev-dependencies' wishes out of a plain build); `workspace-hack` asks for the
//! union. The first test asks `cargo tree` how each command resolves and fails, naming the
//! crate and both feature sets, when a new dependency breaks the agreement.
//!
//! `cargo tree` shows one feature set per package where the host (build scripts,
//! proc-macros) and the target differ: a host crate built with other features under maturin
//! (zenoh's macros reading serde_json) escaped it and made a clean clone compile zenoh twice.
//! The second test compares the compilation units themselves (`cargo build --unit-graph`:
//! package, features, host or target, profile, mode), which is where a second build shows.

use cosim_tests::workspace_root;
use std::collections::{BTreeMap, BTreeSet};
use std::process::Command;

/// Each package (`name vX.Y.Z`, with its path for workspace members) and the feature sets it
/// is built with, as `cargo tree` resolves the selection `args` (a package built for the
/// host and for the target can have two).
fn resolved(args: &[&str]) -> BTreeMap<String, BTreeSet<String>> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .current_dir(workspace_root())
        .args([
            "tree", "--frozen", "--prefix", "none", "--format", "{p}|{f}",
        ])
        .args(args)
        .output()
        .expect("cargo tree runs");
    assert!(
        out.status.success(),
        "cargo tree {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut map: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for line in String::from_utf8(out.stdout).unwrap().lines() {
        let line = line.trim_end_matches(" (*)");
        if let Some((pkg, features)) = line.split_once('|') {
            map.entry(pkg.trim().to_string())
                .or_default()
                .insert(features.trim().to_string());
        }
    }
    map
}

/// Every package `other` shares with `base` is built with feature sets `base` has.
fn differences(
    base: &BTreeMap<String, BTreeSet<String>>,
    other: &BTreeMap<String, BTreeSet<String>>,
) -> Vec<String> {
    let mut out = Vec::new();
    for (pkg, sets) in other {
        if let Some(have) = base.get(pkg) {
            for s in sets.difference(have) {
                out.push(format!("{pkg}: [{s}] (the workspace build has {have:?})"));
            }
        }
    }
    out
}

#[test]
fn the_build_the_tests_and_the_python_package_resolve_one_feature_set() {
    let build = resolved(&["--workspace", "--edges", "normal,build"]);
    let test = resolved(&["--workspace", "--edges", "normal,build,dev"]);
    let python = resolved(&["--package", "cosim-python", "--edges", "normal,build"]);
    println!(
        "{} packages in the build, {} with the tests, {} in the Python package",
        build.len(),
        test.len(),
        python.len()
    );
    // The selections are what they claim: zenoh is in both builds, the tests' proptest in
    // theirs; criterion (a benchmark harness behind fluid-node's `criterion-bench` feature)
    // is in none, so `cargo test` does not compile it.
    assert!(build.len() > 300 && python.len() > 250, "{}", build.len());
    assert!(build.keys().any(|p| p.starts_with("zenoh v")));
    assert!(python.keys().any(|p| p.starts_with("zenoh v")));
    assert!(test.keys().any(|p| p.starts_with("proptest v")));
    assert!(!build.keys().any(|p| p.starts_with("criterion v")));
    assert!(!test.keys().any(|p| p.starts_with("criterion v")));

    let tests_differ = differences(&build, &test);
    assert!(
        tests_differ.is_empty(),
        "`cargo test` would compile these again with other features; add them to \
         workspace-hack/Cargo.toml:\n{}",
        tests_differ.join("\n")
    );
    let python_differs = differences(&build, &python);
    assert!(
        python_differs.is_empty(),
        "maturin would compile these again with other features; add them to \
         workspace-hack/Cargo.toml:\n{}",
        python_differs.join("\n")
    );
}

/// The compilation units of the registry crates a cargo command (`args`) would build, without
/// building anything: package, features, host or target, profile name and opt level, mode and
/// target name. `--unit-graph` is unstable in cargo; RUSTC_BOOTSTRAP lets the stable cargo
/// print it, and only here. A scratch target directory keeps the call off the lock of the
/// `cargo test` running this test.
fn units(args: &[&str]) -> BTreeSet<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let scratch = std::env::temp_dir().join(format!("cosim-unit-graph-{}", std::process::id()));
    let out = Command::new(cargo)
        .current_dir(workspace_root())
        .env("RUSTC_BOOTSTRAP", "1")
        .env("CARGO_TARGET_DIR", &scratch)
        .args(args)
        .args([
            "--release",
            "--frozen",
            "--unit-graph",
            "-Z",
            "unstable-options",
        ])
        .output()
        .expect("cargo runs");
    let _ = std::fs::remove_dir_all(&scratch);
    assert!(
        out.status.success(),
        "cargo {args:?} --unit-graph: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let graph: serde_json::Value = serde_json::from_slice(&out.stdout).expect("a unit graph");
    assert_eq!(graph["version"], 1, "a unit graph of another version");
    let mut set = BTreeSet::new();
    for u in graph["units"].as_array().expect("units") {
        let id = u["pkg_id"].as_str().unwrap_or_default();
        if !id.starts_with("registry+") {
            continue;
        }
        let package = id.rsplit('#').next().unwrap_or(id);
        let features: Vec<&str> = u["features"]
            .as_array()
            .map(|f| f.iter().filter_map(|x| x.as_str()).collect())
            .unwrap_or_default();
        let side = u["platform"].as_str().unwrap_or("host-or-target");
        set.insert(format!(
            "{package} [{}] {side} {} opt {} {} {}",
            features.join(","),
            u["profile"]["name"],
            u["profile"]["opt_level"],
            u["mode"],
            u["target"]["name"]
        ));
    }
    set
}

/// Every registry unit maturin's build of the Python package compiles is one the workspace
/// build compiles too, and every unit `cargo test` compiles of a package the build has is one
/// the build compiled (the test adds any dev-dependency the build does not have).
#[test]
fn the_build_compiles_every_unit_the_python_package_and_the_tests_reuse() {
    let build = units(&["build", "--workspace"]);
    let python = units(&["build", "-p", "cosim-python", "--lib"]);
    let test = units(&["test", "--workspace", "--no-run"]);
    println!(
        "{} registry units in the build, {} in the Python package, {} with the tests",
        build.len(),
        python.len(),
        test.len()
    );
    assert!(build.len() > 500 && python.len() > 500, "{}", build.len());
    // (the tests add no registry crate of their own since criterion went behind a feature,
    // and leave out the Python package's pyo3)
    assert!(test.len() > 500, "{}", test.len());
    let python_only: Vec<&String> = python.difference(&build).collect();
    assert!(
        python_only.is_empty(),
        "the build after `pip install ./python` would compile these again (pin their \
         features in workspace-hack/Cargo.toml, host crates under [build-dependencies]):\n{}",
        python_only
            .iter()
            .map(|s| s.as_str())
            .collect::<Vec<_>>()
            .join("\n")
    );
    let packages: BTreeSet<&str> = build.iter().filter_map(|u| u.split(' ').next()).collect();
    let test_again: Vec<&String> = test
        .difference(&build)
        .filter(|u| u.split(' ').next().is_some_and(|p| packages.contains(p)))
        .collect();
    assert!(
        test_again.is_empty(),
        "`cargo test` after the build would compile these again (pin their features in \
         workspace-hack/Cargo.toml):\n{}",
        test_again
            .iter()
            .map(|s| s.as_str())
            .collect::<Vec<_>>()
            .join("\n")
    );
}
