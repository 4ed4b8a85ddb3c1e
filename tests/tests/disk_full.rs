//! A run whose output fills its disk (a small tmpfs mounted for the test): it exits non-zero
//! naming the file it could not write, writes what summary it can, and leaves no half-written
//! file behind — no truncated VTK frame (listed in a `.pvd` or not), no partial summary,
//! plot or temporary file.

use cosim_tests::*;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A tmpfs of `size` mounted at a fresh folder, unmounted when dropped.
struct Tmpfs(PathBuf);

impl Tmpfs {
    /// None (after [`skip_or_fail`]) where this machine cannot mount one (not root, no
    /// privilege in a container).
    fn mount(tag: &str, size: &str, test: &str) -> Option<Tmpfs> {
        let (dir, _) = scratch(tag);
        let at = dir.join("disk");
        std::fs::create_dir_all(&at).expect("mount point");
        let o = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(&at)
            .output();
        match o {
            Ok(o) if o.status.success() => Some(Tmpfs(at)),
            Ok(o) => {
                skip_or_fail(
                    test,
                    &format!(
                        "cannot mount a tmpfs: {}",
                        String::from_utf8_lossy(&o.stderr).trim()
                    ),
                );
                None
            }
            Err(e) => {
                skip_or_fail(test, &format!("cannot run mount: {e}"));
                None
            }
        }
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

/// No file under `dir` is half-written: no temporary (`.NAME.part…`) is left; every VTK frame
/// is a whole XML document; every frame a `.pvd` lists exists; `summary.json`, where there is
/// one, is JSON; no picture is empty.
fn assert_nothing_half_written(dir: &Path) {
    let files = files_under(dir, &[]);
    assert!(
        !files.is_empty(),
        "the run wrote nothing: the scenario is void"
    );
    for (f, bytes) in &files {
        let name = f.to_string_lossy();
        let base = f.file_name().unwrap_or_default().to_string_lossy();
        assert!(!base.contains(".part"), "a temporary file left: {name}");
        if name.ends_with(".vtu") {
            let text = String::from_utf8_lossy(bytes);
            assert!(
                text.trim_end().ends_with("</VTKFile>"),
                "a truncated frame: {name} ({} bytes)",
                bytes.len()
            );
        }
        if name.ends_with(".pvd") {
            let text = String::from_utf8_lossy(bytes);
            assert!(
                text.trim_end().ends_with("</VTKFile>"),
                "a truncated series: {name}"
            );
            let folder = f.parent().unwrap_or(Path::new(""));
            for listed in text.split("file=\"").skip(1) {
                let listed = listed.split('"').next().unwrap_or_default();
                assert!(
                    files.contains_key(&folder.join(listed)),
                    "{name} lists {listed}, which is not there"
                );
            }
        }
        if name.ends_with(".png") {
            assert!(bytes.len() > 8, "an empty picture: {name}");
        }
        if base == "summary.json" {
            let v: serde_json::Value =
                serde_json::from_slice(bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(v["status"], "failed", "{v}");
        }
    }
}

/// The split bar writing a frame of each half every window onto a 1 MiB disk: the frames fill
/// it within a few hundred windows.
#[test]
fn frames_filling_the_disk_end_the_run_naming_the_file() {
    let test = "frames_filling_the_disk_end_the_run_naming_the_file";
    let Some(disk) = Tmpfs::mount("full-frames", "1m", test) else {
        return;
    };
    let (dir, id) = scratch("full-frames-case");
    let case = split_bar_case(&dir, 20, 60, 0.5, "shm", 4.0);
    let out = disk.0.join("out");
    let o = run_case(&case, &out, &id, &["--set", "run.output_every=1"]);
    let err = String::from_utf8_lossy(&o.stderr);
    println!("{err}");
    assert_eq!(o.status.code(), Some(1), "{err}");
    // The frame a node could not write, or the summary after it: a file under the output.
    assert!(
        err.contains(&format!("cannot write {}", out.display()))
            && err.contains("No space left on device"),
        "no file that could not be written is named: {err}"
    );
    assert_nothing_half_written(&out);
    nothing_left(&id);
}

/// Frames only at the start and the end: the recording fills the disk first. The recorder
/// names its file at once (a warning; the run's physics goes on), and the run fails, naming
/// whatever it could not write last.
#[test]
fn a_recording_filling_the_disk_is_named_and_fails_the_run() {
    let test = "a_recording_filling_the_disk_is_named_and_fails_the_run";
    let Some(disk) = Tmpfs::mount("full-rec", "64k", test) else {
        return;
    };
    let (dir, id) = scratch("full-rec-case");
    let case = split_bar_case(&dir, 20, 60, 0.5, "shm", 4.0);
    let out = disk.0.join("out");
    let o = run_case(
        &case,
        &out,
        &id,
        &[
            "--set",
            "run.output_every=0",
            "--set",
            "run.pictures=\"none\"",
        ],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    println!("{err}");
    assert_eq!(o.status.code(), Some(1), "{err}");
    let mcap = out.join("run.mcap");
    assert!(
        err.contains(&format!("cannot write {}", mcap.display()))
            && err.contains("No space left on device"),
        "the recording that could not be written is not named: {err}"
    );
    assert_nothing_half_written(&out);
    nothing_left(&id);
}
