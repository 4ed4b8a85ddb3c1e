//! The checked-in C header is exactly what cbindgen generates from this crate's source, so a
//! change to the ABI cannot ship with a stale header. cbindgen runs as its command-line tool
//! (`cargo install cbindgen --version 0.29.4 --locked`, which `.ci/run` does) rather than as
//! a dependency: as a crate it would change the features of the workspace's shared
//! dependencies and rebuild them all. `COSIM_BLESS=1` rewrites the header.

use std::path::Path;
use std::process::Command;

#[test]
fn the_checked_in_header_is_what_cbindgen_generates_from_the_source() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("cosim_participant-{}.h", std::process::id()));
    let run = Command::new("cbindgen")
        .arg("--config")
        .arg(dir.join("cbindgen.toml"))
        .arg("--output")
        .arg(&out)
        .arg(dir.join("src/lib.rs"))
        .output();
    let Ok(run) = run else {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "cbindgen is missing under CI: cargo install cbindgen --version 0.29.4 --locked"
        );
        eprintln!(
            "skipped: cbindgen is not installed (cargo install cbindgen --version 0.29.4 --locked)"
        );
        return;
    };
    assert!(
        run.status.success(),
        "cbindgen failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let generated = std::fs::read(&out).expect("cbindgen wrote the header");
    let _ = std::fs::remove_file(&out);
    let path = dir.join("include/cosim_participant.h");
    if std::env::var_os("COSIM_BLESS").is_some() {
        std::fs::write(&path, &generated).expect("write the header");
    }
    let text = String::from_utf8_lossy(&generated);
    for f in [
        "cosim_node_main",
        "cosim_inbox_get",
        "cosim_outbox_put",
        "cosim_set_error",
        "COSIM_ABI_VERSION",
        "CosimSolverVTable",
    ] {
        assert!(text.contains(f), "the generated header lacks {f}");
    }
    let checked_in = std::fs::read(&path).unwrap_or_default();
    assert!(
        checked_in == generated,
        "include/cosim_participant.h differs from what cbindgen generates: regenerate it with \
         `COSIM_BLESS=1 cargo test --release -p participant-c --test header`"
    );
}
