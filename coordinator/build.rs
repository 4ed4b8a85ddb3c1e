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
    if git.is_dir() {
        println!("cargo:rerun-if-changed=../.git/HEAD");
        println!("cargo:rerun-if-changed=../.git/refs/heads");
        println!("cargo:rerun-if-changed=../.git/packed-refs");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
