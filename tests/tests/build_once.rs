//! Each crate compiles once: `cargo build --release --workspace`, `cargo test` after it and
//! maturin's build of the Python package (`cargo rustc` of `cosim-python` alone) resolve
//! every shared dependency with the same features, so none of them compiles a registry crate
//! the others already built. Cargo picks features by the packages a command selects (and
//! leaves the dev-dependencies' wishes out of a plain build); `workspace-hack` asks for the
//! union. This test asks `cargo tree` how each command resolves and fails, naming the crate
//! and both feature sets, when a new dependency breaks the agreement.

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
    // The selections are what they claim: zenoh and criterion are where they belong.
    assert!(build.len() > 300 && python.len() > 250, "{}", build.len());
    assert!(build.keys().any(|p| p.starts_with("zenoh v")));
    assert!(python.keys().any(|p| p.starts_with("zenoh v")));
    assert!(!build.keys().any(|p| p.starts_with("criterion v")));
    assert!(test.keys().any(|p| p.starts_with("criterion v")));

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
