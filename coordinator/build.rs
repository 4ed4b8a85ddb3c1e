//! Build script: the git commit the coordinator is built from (`COSIM_GIT_COMMIT`, empty
//! outside a git checkout), written into every recording's metadata.

use std::process::Command;

fn main() {
    let commit = Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    println!("cargo:rustc-env=COSIM_GIT_COMMIT={commit}");
    // Rebuild when HEAD moves (a commit, a checkout); in a worktree .git is a file.
    let git = std::path::Path::new("../.git");
    // Only files that exist: cargo counts a missing one as changed and would run this script,
    // and compile the coordinator, on every build (a clone without packed refs).
    if git.is_dir() {
        for f in ["HEAD", "refs/heads", "packed-refs"] {
            if git.join(f).exists() {
                println!("cargo:rerun-if-changed=../.git/{f}");
            }
        }
    }
    println!("cargo:rerun-if-changed=build.rs");
}
