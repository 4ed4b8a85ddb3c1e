//! The written contract is complete: `tools/wire_decode.py`, a decoder written from
//! PROTOCOL.md alone in plain Python, decodes every golden vector to the same JSON as the
//! Rust codec (and refuses every truncation of it). Needs `python3`: a failure under
//! `CI=true`, a skip with a message elsewhere.

use std::path::Path;
use std::process::Command;

/// `wire_decode.py --check DIR`, or None (after saying why) where python3 is missing
/// outside CI.
fn check(dir: &Path) -> Option<std::process::Output> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tools/wire_decode.py");
    match Command::new("python3")
        .arg(&script)
        .arg("--check")
        .arg(dir)
        .output()
    {
        Ok(o) => Some(o),
        Err(e) => {
            assert!(
                std::env::var("CI").as_deref() != Ok("true"),
                "python3 is needed under CI: {e}"
            );
            eprintln!("skipped: python3 cannot be started ({e})");
            None
        }
    }
}

#[test]
fn python_decoder_reads_every_golden_vector() {
    let golden = Path::new(env!("CARGO_MANIFEST_DIR")).join("golden");
    let Some(out) = check(&golden) else { return };
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "wire_decode.py:\n{stdout}\n{stderr}");
    let bins = std::fs::read_dir(&golden)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .is_ok_and(|e| e.path().extension().is_some_and(|x| x == "bin"))
        })
        .count();
    assert!(bins >= 20, "only {bins} golden vectors");
    let want = format!("{bins} of {bins} vectors match");
    assert!(
        stdout.lines().any(|l| l == want),
        "expected '{want}' from wire_decode.py, got:\n{stdout}"
    );
}

#[test]
fn python_decoder_notices_a_changed_byte() {
    // The heartbeat vector with substeps 301 instead of 300 (`fb 2c 01` → `fb 2d 01`) beside
    // the unchanged JSON: the check must fail, so a match above means something.
    let golden = Path::new(env!("CARGO_MANIFEST_DIR")).join("golden");
    let dir = std::env::temp_dir().join(format!("wire-decode-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut bin = std::fs::read(golden.join("09_heartbeat.bin")).unwrap();
    let at = bin
        .windows(3)
        .position(|w| w == [0xfb, 0x2c, 0x01])
        .unwrap();
    bin[at + 1] = 0x2d;
    std::fs::write(dir.join("09_heartbeat.bin"), &bin).unwrap();
    std::fs::copy(
        golden.join("09_heartbeat.json"),
        dir.join("09_heartbeat.json"),
    )
    .unwrap();
    let out = check(&dir);
    std::fs::remove_dir_all(&dir).unwrap();
    let Some(out) = out else { return };
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success(), "a changed byte passed:\n{stdout}");
    assert!(stdout.contains("0 of 1 vectors match"), "{stdout}");
}
