//! A node whose log cannot be written (its stderr on a full disk) still exits with its own
//! code, not with a panic of the message it could not print: `/dev/full` fails every write
//! with ENOSPC, as a log file on a full disk does.

use cosim_tests::*;
use std::process::{Command, Stdio};

/// A bad invocation (an unknown transport) is exit code 1 with its message, and still 1 with
/// stderr on `/dev/full` (`eprintln!` would panic there: exit code 101).
#[test]
fn a_node_with_its_stderr_on_a_full_disk_exits_with_its_own_code() {
    for node in ["solid-node", "fluid-node"] {
        let args = [
            "--run",
            "full-stderr",
            "--node",
            "n",
            "--transport",
            "bogus",
        ];
        let plain = Command::new(bin(node)).args(args).output().expect("starts");
        let err = String::from_utf8_lossy(&plain.stderr);
        assert_eq!(plain.status.code(), Some(1), "{node}: {err}");
        assert!(err.contains("unknown transport 'bogus'"), "{node}: {err}");
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .expect("/dev/full");
        let st = Command::new(bin(node))
            .args(args)
            .stdout(Stdio::null())
            .stderr(Stdio::from(full))
            .status()
            .expect("starts");
        assert_eq!(st.code(), Some(1), "{node} with stderr on /dev/full: {st}");
    }
}
