//! Recording and `cosim info` on a real split-bar run (docs/architecture.md); replay is in
//! `replay.rs`.

use cosim_tests::*;
use std::sync::OnceLock;

/// One recorded run shared by the tests of this file.
fn recorded() -> &'static std::path::PathBuf {
    static OUT: OnceLock<std::path::PathBuf> = OnceLock::new();
    OUT.get_or_init(|| {
        let (dir, id) = scratch("rec");
        let case = split_bar_case(&dir, 100, 300, 0.5, "shm", 0.5);
        let out = dir.join("out");
        let o = run_case(&case, &out, &id, &[]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out.join("run.mcap")
    })
}

#[test]
fn recording_passes_the_official_reader() {
    let (ok, s) = check_mcap(recorded(), "--require-json");
    println!("{s}");
    assert!(ok, "check_mcap failed: {s}");
    assert!(s.contains("/cosim/balance"));
}

#[test]
fn info_summarises_the_run() {
    let o = cosim(&["info", recorded().to_str().unwrap()]);
    let s = String::from_utf8_lossy(&o.stdout);
    println!("{s}");
    assert!(o.status.success());
    for needle in [
        "left",
        "right",
        "kinematic",
        "windows",
        "messages",
        "energy",
        "momentum",
    ] {
        assert!(s.contains(needle), "info lacks '{needle}'");
    }
}

#[test]
fn nodes_write_paraview_output_at_the_end() {
    let out = recorded().parent().unwrap();
    for (node, points) in [("left", 101), ("right", 301)] {
        let pvd = std::fs::read_to_string(out.join(node).join("bar.pvd")).expect("a .pvd series");
        let file = pvd
            .split("file=\"")
            .nth(1)
            .and_then(|s| s.split('"').next())
            .expect("the series names a file");
        let vtu = std::fs::read_to_string(out.join(node).join(file)).expect("the .vtu it names");
        assert!(
            vtu.contains(&format!("NumberOfPoints=\"{points}\"")),
            "{node}: {file}"
        );
        assert!(vtu.contains("Name=\"displacement\""));
    }
}

/// Every field and variant name of every recorded protocol message, as serde names them.
fn names(v: &serde_json::Value, out: &mut std::collections::BTreeSet<String>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                out.insert(k.clone());
                names(x, out);
            }
        }
        serde_json::Value::Array(a) => a.iter().for_each(|x| names(x, out)),
        // a unit variant is serialised as its CamelCase name (other strings are data)
        serde_json::Value::String(s)
            if s.chars().all(|c| c.is_ascii_alphanumeric())
                && s.chars().next().is_some_and(|c| c.is_ascii_uppercase())
                && s.chars().nth(1).is_some_and(|c| c.is_ascii_lowercase()) =>
        {
            out.insert(s.clone());
        }
        _ => {}
    }
}

/// The schema of the bincode channels names every field of every recorded message, the JSON
/// channels' schemas list every key (checked by the official reader's script above), and
/// the log time is the simulated time: Foxglove's timeline is the simulation's.
#[test]
fn schemas_name_every_field_and_log_time_is_simulated_time() {
    let (msgs, complete) = coordinator::record::read_all(recorded()).expect("readable");
    assert!(complete);
    let schema = coordinator::record::ENVELOPE_SCHEMA;
    let word = |k: &str| {
        schema.match_indices(k).any(|(i, _)| {
            let before = schema[..i].chars().next_back();
            let after = schema[i + k.len()..].chars().next();
            let ident = |c: Option<char>| c.is_some_and(|c| c.is_alphanumeric() || c == '_');
            !ident(before) && !ident(after)
        })
    };
    let mut seen = std::collections::BTreeSet::new();
    let mut binary = 0;
    for m in msgs.iter().filter(|m| !m.json) {
        let env = protocol::decode(&m.data).expect("a recorded message decodes");
        let v = serde_json::json!({ "run": env.run, "sender": env.sender, "message": env.message });
        names(&v, &mut seen);
        binary += 1;
    }
    println!(
        "{binary} binary messages, {} field and variant names, all in the schema",
        seen.len()
    );
    // handshake, set-up, Advance, Done, Fields, Stop, ... of a two-node run
    assert!(binary > 2000, "{binary} binary messages");
    assert!(seen.len() >= 30, "only {} names: {seen:?}", seen.len());
    let missing: Vec<_> = seen.iter().filter(|k| !word(k)).collect();
    assert!(missing.is_empty(), "the schema lacks {missing:?}");

    let balance: Vec<_> = msgs
        .iter()
        .filter(|m| m.topic == "/cosim/balance")
        .collect();
    let windows = summary(recorded().parent().unwrap())["windows"]
        .as_u64()
        .unwrap();
    assert!(windows >= 800, "{windows} windows");
    assert_eq!(balance.len() as u64, windows);
    for m in &balance {
        let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
        let t = v["time"].as_f64().unwrap();
        assert_eq!(
            m.log_time,
            (t * 1e9).round() as u64,
            "window {}",
            v["window"]
        );
    }
}
