//! A node that joins a run from outside (`remote = true`): `cosim` prints the command with the
//! run id, endpoint and token, waits, and the run completes with the same result as when it
//! launches the node itself. A node presenting a wrong token is rejected.

use cosim_tests::*;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Duration;

fn remote_case(tag: &str) -> (std::path::PathBuf, std::path::PathBuf, String) {
    let (dir, id) = scratch(tag);
    let case = split_bar_case(&dir, 50, 150, 0.5, "zenoh", 0.5);
    let text = std::fs::read_to_string(&case)
        .unwrap()
        .replace("[nodes.right]\n", "[nodes.right]\nremote = true\n");
    std::fs::write(&case, text).unwrap();
    (case, dir.join("out"), id)
}

#[test]
fn a_remote_node_joins_with_the_printed_command_and_token() {
    let (case, out, id) = remote_case("remote");
    let mut cosim = Command::new(bin("cosim"))
        .args([
            "run",
            case.to_str().unwrap(),
            "--output",
            out.to_str().unwrap(),
            "--run-id",
            &id,
            "--quiet",
        ])
        .env("COSIM_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(cosim.stderr.take().unwrap());
    let mut line = String::new();
    err.read_line(&mut line).unwrap();
    assert!(line.contains("waiting for remote node 'right'"), "{line}");
    let cmd: Vec<&str> = line
        .split(": ")
        .last()
        .unwrap()
        .split_whitespace()
        .collect();
    let arg = |k: &str| cmd[cmd.iter().position(|a| *a == k).unwrap() + 1].to_string();
    assert_eq!(arg("--run"), id);
    // A node with a wrong token is turned away ...
    let bad = Command::new(bin("solid-node"))
        .args([
            "--run",
            &id,
            "--node",
            "right",
            "--transport",
            "zenoh",
            "--connect",
            &arg("--connect"),
            "--token",
            "0000",
        ])
        .env("COSIM_LOG", "error")
        .output()
        .unwrap();
    assert_rejected(&bad);
    // ... the one with the printed token is let in and the run completes.
    let node = Command::new(bin("solid-node"))
        .args([
            "--run",
            &id,
            "--node",
            "right",
            "--transport",
            "zenoh",
            "--connect",
            &arg("--connect"),
            "--token",
            &arg("--token"),
        ])
        .env("COSIM_LOG", "error")
        .output()
        .unwrap();
    let status = cosim.wait().unwrap();
    let mut rest = String::new();
    let _ = std::io::Read::read_to_string(&mut err, &mut rest);
    assert!(
        node.status.success(),
        "node {:?}: {}; cosim: {rest}",
        node.status,
        String::from_utf8_lossy(&node.stderr)
    );
    assert!(status.success(), "cosim: {rest}");
    let remote = node_series(&out.join("run.mcap"), "right", "tip_displacement");
    // The same case with both nodes launched locally gives the same numbers, bit for bit.
    let (dir2, id2) = scratch("local");
    let local_case = split_bar_case(&dir2, 50, 150, 0.5, "zenoh", 0.5);
    let o = run_case(&local_case, &dir2.join("out"), &id2, &[]);
    assert!(o.status.success());
    let local = node_series(&dir2.join("out/run.mcap"), "right", "tip_displacement");
    assert_eq!(remote.len(), local.len());
    assert!(
        remote
            .iter()
            .zip(&local)
            .all(|(a, b)| a.1.to_bits() == b.1.to_bits())
    );
}

/// A node turned away at the door: exit 2, saying it was rejected.
fn assert_rejected(bad: &std::process::Output) {
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(bad.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("rejected"), "{stderr}");
}

/// The command `cosim` prints for the remote node `right` on its first stderr line, as words.
fn printed_command(err: &mut impl BufRead) -> Vec<String> {
    let mut line = String::new();
    err.read_line(&mut line).unwrap();
    assert!(line.contains("waiting for remote node 'right'"), "{line}");
    line.split(": ")
        .last()
        .unwrap()
        .split_whitespace()
        .map(str::to_string)
        .collect()
}

/// Runs `solid-node` as the remote node `right` with the printed command `cmd` (its first
/// word the executable), the token replaced by `token` when given.
fn join_with(cmd: &[String], token: Option<&str>) -> std::process::Output {
    let mut args: Vec<String> = cmd[1..].to_vec();
    if let (Some(t), Some(i)) = (token, args.iter().position(|a| a == "--token")) {
        args[i + 1] = t.to_string();
    }
    Command::new(bin("solid-node"))
        .args(&args)
        .env("COSIM_LOG", "error")
        .output()
        .unwrap()
}

/// The README's several-hosts flow with the remote node started
/// long after `cosim` printed its command: 6 s, six times both the heartbeat timeout and the
/// start timeout (1 s each; the 60 s scaled down with them; `COSIM_TEST_JOIN_DELAY=60`
/// runs it with the 60 s and the default timeouts). The local node waits,
/// `cosim` names who it waits for, a node with a wrong token is still turned away, and the
/// run completes with the printed command.
#[test]
fn a_remote_node_may_join_after_the_heartbeat_timeout() {
    let by_hand: Option<u64> = std::env::var("COSIM_TEST_JOIN_DELAY")
        .ok()
        .and_then(|s| s.parse().ok());
    let delay = Duration::from_secs(by_hand.unwrap_or(6));
    let (case, out, id) = remote_case("late");
    let timeouts = if by_hand.is_some() {
        ""
    } else {
        "\nheartbeat_ms = 100\nheartbeat_timeout = 1.0\nstart_timeout = 1.0"
    };
    let text = std::fs::read_to_string(&case)
        .unwrap()
        .replace("output = \"out\"", &format!("output = \"out\"{timeouts}"));
    std::fs::write(&case, text).unwrap();
    let mut cosim = spawn_cosim(&case, &out, &id);
    let mut err = BufReader::new(cosim.stderr.take().unwrap());
    let cmd = printed_command(&mut err);
    std::thread::sleep(delay);
    // The local node is still there, waiting.
    assert!(
        node_pid(&id, "left").is_some(),
        "the local node did not wait"
    );
    let bad = join_with(&cmd, Some("0000"));
    assert_rejected(&bad);
    let node = join_with(&cmd, None);
    let status = cosim.wait().unwrap();
    let mut rest = String::new();
    let _ = std::io::Read::read_to_string(&mut err, &mut rest);
    println!("{rest}");
    assert!(
        node.status.success(),
        "node {:?}: {}; cosim: {rest}",
        node.status,
        String::from_utf8_lossy(&node.stderr)
    );
    assert!(status.success(), "cosim: {rest}");
    assert!(
        rest.contains("still waiting for remote node(s) 'right'"),
        "no progress line naming 'right': {rest}"
    );
    assert!(rest.contains("remote node 'right' joined"), "{rest}");
    let s = summary(&out);
    assert_eq!(s["status"], "finished");
    assert!(!node_series(&out.join("run.mcap"), "right", "tip_displacement").is_empty());
    nothing_left(&id);
}

/// The field check for a node checked only when it joins: the remote node's executable
/// is not on this host, so `cosim` cannot describe it before the run; its `Describe` at the
/// handshake shows that its interface does not accept the field the coupling asks the
/// responder to take, and the run is refused before any window, naming the coupling, node,
/// interface and field, with no process or shared memory left and a readable recording.
#[test]
fn a_remote_node_lacking_a_coupling_field_is_refused_when_it_joins() {
    let (case, out, id) = remote_case("lacking");
    // `lagrange_operator`: the left bar provides it, no bar accepts it.
    let text = std::fs::read_to_string(&case)
        .unwrap()
        .replace(
            "remote = true\nsolver = \"solid-node\"",
            "remote = true\nsolver = \"solid-node-on-another-host\"",
        )
        .replace(
            "responder = \"right.root\"",
            "responder = \"right.root\"\ndriver_fields = [\"velocity\", \"lagrange_operator\"]",
        );
    assert!(text.contains("solid-node-on-another-host") && text.contains("driver_fields"));
    std::fs::write(&case, text).unwrap();
    let mut cosim = spawn_cosim(&case, &out, &id);
    let mut err = BufReader::new(cosim.stderr.take().unwrap());
    let cmd = printed_command(&mut err);
    assert_eq!(cmd[0], "solid-node-on-another-host");
    let node = join_with(&cmd, None);
    let status = cosim.wait().unwrap();
    let mut rest = String::new();
    let _ = std::io::Read::read_to_string(&mut err, &mut rest);
    assert!(!status.success(), "cosim: {rest}");
    assert!(!node.status.success(), "the refused node exited 0");
    for part in [
        "node 'right'",
        "couplings[0].driver_fields",
        "kinematic coupling 'mid'",
        "interface 'root'",
        "accept field 'lagrange_operator'",
    ] {
        assert!(rest.contains(part), "'{part}' not in: {rest}");
    }
    std::thread::sleep(Duration::from_millis(100));
    nothing_left(&id);
    let mcap = out.join("run.mcap");
    let (ok, text) = check_mcap(&mcap, "--recover");
    assert!(ok, "check_mcap --recover: {text}");
    assert!(balance_windows(&mcap).is_empty(), "a window ran");
    assert_eq!(summary(&out)["status"], "failed");
}
