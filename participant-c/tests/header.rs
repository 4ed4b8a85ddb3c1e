//! The checked-in C header is exactly what cbindgen generates from this crate's source (the
//! build script writes it into `OUT_DIR`), so a change to the ABI cannot ship with a stale
//! header. `COSIM_BLESS=1` rewrites the checked-in header.

use std::path::Path;

#[test]
fn the_checked_in_header_is_what_cbindgen_generates_from_the_source() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = Path::new(env!("OUT_DIR")).join("cosim_participant.h");
    let generated = std::fs::read(&out).unwrap_or_else(|e| {
        panic!(
            "the build script wrote no header ({}: {e}); its warning says why",
            out.display()
        )
    });
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
