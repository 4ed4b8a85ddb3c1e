//! `cosim conformance -- NODE_COMMAND`: a node is driven through a short run against the peer
//! cosim plays and held to each rule of PROTOCOL.md (section 9). The built-in bar, the Python
//! bar and the C bar pass every rule; the built-in bar with one fault (`cosim-faulty`) fails
//! exactly the rule its fault breaks, and the exit status says so.
//!
//! The Python and C bars need the Python package and a C compiler: under `CI=true` a missing
//! one is a failure, elsewhere the test is skipped with a message.

use cosim_tests::*;
use std::collections::BTreeMap;

/// The rules PROTOCOL.md section 9 lists, by name.
const RULES: [&str; 13] = [
    "describe",
    "hello",
    "welcome-describe",
    "mesh",
    "set-up",
    "fields-match-binding",
    "finite-values",
    "books-match-fields",
    "windows-in-order",
    "heartbeat",
    "checkpoint",
    "finish",
    "cleanup",
];

/// The rules PROTOCOL.md section 9 lists for a lagrange side, by name.
const LAGRANGE_RULES: [&str; 12] = [
    "describe",
    "hello",
    "welcome-describe",
    "mesh",
    "lagrange-set-up",
    "lagrange-steps",
    "lagrange-correction",
    "windows-in-order",
    "heartbeat",
    "checkpoint",
    "finish",
    "cleanup",
];

/// The parameters of the right half of examples/split_bar.toml, coupled at its `root`.
const RIGHT_HALF: &str = "length = 0.5\nx0 = 0.5\nelements = 300\nyoung = 200e9\n\
    density = 7860.0\narea = 1e-4\nfixed = \"none\"\ntip_force = 1000.0\n\
    load_end = \"right\"\ncourant = 0.5\ninterfaces = { root = \"left\" }\n";

/// The parameters of its left half, which drives the coupling at its `tip`.
const LEFT_HALF: &str = "length = 0.5\nelements = 100\nyoung = 200e9\ndensity = 7860.0\n\
    area = 1e-4\nfixed = \"left\"\nload_end = \"none\"\ncourant = 1.0\n\
    interfaces = { tip = \"right\" }\n";

/// `cosim conformance` of `command` as the bar's right half, its parameters with `extra`
/// lines; returns the exit code, each rule's tag (PASS, FAIL or ----) and reason, and the
/// whole output.
fn conformance(
    tag: &str,
    extra: &str,
    command: &[&str],
) -> (Option<i32>, BTreeMap<String, (String, String)>, String) {
    conformance_as(
        tag,
        "bar-1d",
        &format!("{RIGHT_HALF}{extra}\n"),
        &[],
        command,
    )
}

/// `cosim conformance` of `command` as model `model` with the parameters `params` and the
/// options `options`.
fn conformance_as(
    tag: &str,
    model: &str,
    params: &str,
    options: &[&str],
    command: &[&str],
) -> (Option<i32>, BTreeMap<String, (String, String)>, String) {
    let (dir, _) = scratch(tag);
    let params_file = dir.join("params.toml");
    std::fs::write(&params_file, params).expect("write params");
    let out = dir.join("out");
    let mut args = vec![
        "conformance",
        "--model",
        model,
        "--params",
        params_file.to_str().unwrap(),
        "--output",
        out.to_str().unwrap(),
    ];
    args.extend(options);
    args.push("--");
    args.extend(command);
    let o = cosim(&args);
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    println!("{text}");
    let mut rules = BTreeMap::new();
    for line in text.lines() {
        let Some((tag, rest)) = line.split_once("  ") else {
            continue;
        };
        if !["PASS", "FAIL", "----"].contains(&tag) {
            continue;
        }
        // `§… rule: reason`: the rule is the word before the first ": ".
        let (head, reason) = rest.split_once(": ").expect("rule: reason");
        let rule = head.split_whitespace().last().expect("a rule name");
        rules.insert(rule.to_string(), (tag.to_string(), reason.to_string()));
    }
    let names: Vec<&str> = rules.keys().map(String::as_str).collect();
    let mut want = if options.contains(&"lagrange") {
        LAGRANGE_RULES.to_vec()
    } else {
        RULES.to_vec()
    };
    want.sort();
    assert_eq!(names, want, "{text}");
    (o.status.code(), rules, text)
}

fn assert_all_pass(code: Option<i32>, rules: &BTreeMap<String, (String, String)>, text: &str) {
    for (rule, (tag, reason)) in rules {
        assert_eq!(tag, "PASS", "{rule}: {reason}");
    }
    assert!(text.contains("13 of 13 rules pass"), "{text}");
    assert_eq!(code, Some(0), "{text}");
}

/// Every rule but `broken` passes or, after it ended the drive, was not reached; `broken`
/// fails with a reason holding `why`; the exit status is 1.
fn assert_fails_only(
    code: Option<i32>,
    rules: &BTreeMap<String, (String, String)>,
    broken: &str,
    why: &str,
) {
    assert_eq!(code, Some(1));
    let (tag, reason) = &rules[broken];
    assert_eq!(tag, "FAIL", "{broken}: {reason}");
    assert!(reason.contains(why), "{broken}: {reason}");
    for (rule, (tag, reason)) in rules.iter().filter(|r| r.0 != broken) {
        assert_ne!(tag, "FAIL", "{rule} should not fail: {reason}");
    }
    // The handshake comes before any fault a test node has.
    for rule in ["describe", "hello", "welcome-describe", "mesh", "set-up"] {
        assert_eq!(rules[rule].0, "PASS", "{rule}: {}", rules[rule].1);
    }
}

#[test]
fn the_built_in_bar_passes_every_rule() {
    let (code, rules, text) = conformance("conf-builtin", "", &["solid-node"]);
    assert_all_pass(code, &rules, &text);
    // The checkpoint rule read the node's file back: of window 3 (the one before the last).
    assert!(rules["checkpoint"].1.contains("window 3 saved"), "{text}");
    assert_books_judged(&rules, &text);
}

/// The booking rule judged a responder bar's force against its books: pushed at 1 mm/s from
/// the first window, its interface impulse is above round-off in each of the 4.
fn assert_books_judged(rules: &BTreeMap<String, (String, String)>, text: &str) {
    assert!(
        rules["books-match-fields"].1.contains(
            "over 4 window(s) its booked interface impulse and the force it sent agree in sign"
        ),
        "{text}"
    );
}

#[test]
fn the_built_in_bar_passes_every_rule_as_the_driver() {
    let (code, rules, text) = conformance_as(
        "conf-driver",
        "bar-1d",
        LEFT_HALF,
        &["--role", "driver"],
        &["solid-node"],
    );
    assert_all_pass(code, &rules, &text);
    assert!(text.contains("as the kinematic driver node"), "{text}");
    // Coupled at the left half's tip, whose one point the peer's mesh copies.
    assert!(
        rules["describe"].1.contains("interface 'tip' of 1 points"),
        "{text}"
    );
}

#[test]
fn a_peridynamic_body_passes_every_rule_as_the_immersed_driver() {
    // The steel bar of examples/chamber_detonation.toml: 60 × 30 particles, all coupled.
    let params = "dimension = \"plane_strain\"\nthickness = 0.0035\n\
        spacing = 3.3333333333333335e-3\nhorizon = 1.005e-2\ndensity = 7870.0\nyoung = 200e9\n\
        poisson = 0.29\nyield_stress = 0.4e9\niso_hardening = 0.1e9\n\
        bodies = [{ shape = \"box\", min = [0.1, 0.15, 0.0], max = [0.3, 0.25, 0.0035] }]\n\
        interfaces = [{ name = \"particles\", select = \"all\" }]\n";
    let (code, rules, text) = conformance_as(
        "conf-immersed",
        "pd-correspondence",
        params,
        &["--kind", "immersed", "--role", "driver"],
        &["solid-node"],
    );
    assert_all_pass(code, &rules, &text);
    assert!(rules["mesh"].1.contains("1800 points"), "{text}");
}

#[test]
fn a_bad_role_is_a_command_line_error() {
    let o = cosim(&[
        "conformance",
        "--model",
        "bar-1d",
        "--role",
        "sideways",
        "--",
        "solid-node",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--role sideways: driver or responder"));
}

#[test]
fn the_python_bar_passes_every_rule() {
    if !python_package_or_skip() {
        return;
    }
    let bar = workspace_root().join("examples/external/bar.py");
    let (code, rules, text) = conformance("conf-python", "", &[bar.to_str().unwrap()]);
    assert_all_pass(code, &rules, &text);
    assert_books_judged(&rules, &text);
}

#[test]
fn the_c_bar_passes_every_rule() {
    let Some(bar) = build_c_bar(&workspace_root().join("examples/external/bar-c")) else {
        return;
    };
    let (code, rules, text) = conformance("conf-c", "", &[bar.to_str().unwrap()]);
    assert_all_pass(code, &rules, &text);
    assert_books_judged(&rules, &text);
}

fn faulty(tag: &str, fault: &str) -> (Option<i32>, BTreeMap<String, (String, String)>) {
    let exe = bin("cosim-faulty");
    let (code, rules, _) = conformance(
        tag,
        &format!("fault = \"{fault}\""),
        &[exe.to_str().unwrap()],
    );
    (code, rules)
}

#[test]
fn a_force_of_one_component_fails_the_binding_rule() {
    let (code, rules) = faulty("conf-components", "components");
    assert_fails_only(
        code,
        &rules,
        "fields-match-binding",
        "field 'force' has 1 components per point, expected 3",
    );
    // The drive went on to the end: the other rules were all checked.
    assert!(rules.values().all(|r| r.0 != "----"), "{rules:?}");
}

#[test]
fn a_misnamed_field_fails_the_binding_rule() {
    let (code, rules) = faulty("conf-misnamed", "misnamed");
    assert_fails_only(
        code,
        &rules,
        "fields-match-binding",
        "field 'forse' is not one its binding sends",
    );
}

#[test]
fn a_set_up_without_the_force_fails_the_binding_rule() {
    let (code, rules) = faulty("conf-no-setup-force", "no_setup_force");
    assert_fails_only(
        code,
        &rules,
        "fields-match-binding",
        "set-up (window 0) on coupling 'conformance' break its binding (kinematic responder; PROTOCOL.md 4.2, 5.3): field 'force' missing",
    );
}

#[test]
fn a_node_that_stops_beating_fails_the_heartbeat_rule() {
    let (code, rules) = faulty("conf-silent", "silent");
    assert_fails_only(code, &rules, "heartbeat", "no heartbeat for 3");
    assert!(
        rules["heartbeat"].1.contains("during window 2"),
        "{rules:?}"
    );
}

#[test]
fn a_node_that_exits_before_finish_fails_the_finish_rule() {
    let (code, rules) = faulty("conf-early-exit", "early_exit");
    assert_fails_only(
        code,
        &rules,
        "finish",
        "ended before Finish: node 'node': exited with status 0 during window 2",
    );
}

#[test]
fn a_reversed_force_fails_the_booking_rule() {
    let (code, rules) = faulty("conf-reversed", "reversed");
    assert_fails_only(
        code,
        &rules,
        "books-match-fields",
        "breaks the booking rule (PROTOCOL.md 4.7",
    );
    // Named within the drive's 4 windows: at the third of opposite signs (in the first, the
    // bar's books hold only part of its force, which builds up over its substeps).
    let why = &rules["books-match-fields"].1;
    assert!(
        why.contains("(window 3)") || why.contains("(window 4)"),
        "{rules:?}"
    );
    // Its shape is right: only the booking rule sees the fault.
    assert_eq!(rules["fields-match-binding"].0, "PASS", "{rules:?}");
}

/// The sides of `examples/split_bar_lagrange.toml` and `examples/seed003_notch.toml` as
/// lagrange sides, each alone against cosim's rigid side: the bar's left half (average
/// acceleration), its right half (central differences, 8 steps per window), a `fem-2d`
/// cantilever part and a `pd-correspondence` body; every rule passes, the correction judged
/// in the 3 windows after the first.
#[test]
fn every_built_in_lagrange_side_passes_every_rule() {
    let left = format!(
        "{LEFT_HALF}substeps = 1\nintegrator = {{ scheme = \"gs4\", design = \"U0(1,1,0)\", \
         implicit = true }}\n"
    );
    let right = format!(
        "{}substeps = 8\nintegrator = {{ scheme = \"gs4\", design = \"U0(1,1,0)\", \
         implicit = false }}\n",
        RIGHT_HALF.replace("courant = 0.5\n", "")
    );
    let fem = "origin = [0.0, 0.0]\nlength = 4.0\nheight = 1.0\nnx = 8\nny = 2\n\
        young = 72e9\npoisson = 0.3\ndensity = 2700.0\nplane = \"stress\"\n\
        fixed = [\"left\"]\nsubsteps = 1\ninterfaces = { cut = \"right\" }\n\
        integrator = { scheme = \"gs4\", design = \"U0(1,1,0)\", implicit = true }\n";
    let pd = "dimension = \"plane_stress\"\nthickness = 1.0\nspacing = 0.2\nhorizon = 0.603\n\
        density = 2700.0\nyoung = 70e9\npoisson = 0.3\n\
        bodies = [{ shape = \"box\", min = [3.9, -0.1, 0.0], max = [7.1, 2.1, 0.0] }]\n\
        interfaces = [{ name = \"cut\", select = \"all\", region = { shape = \"box\", \
        min = [3.95, -0.5, 0.0], max = [4.05, 2.5, 0.0] } }]\n";
    // (tag, model, parameters, the window (s): the system step of its case, unknowns).
    let window = "9.912113800799505e-7";
    let sides = [
        ("conf-lag-left", "bar-1d", left.as_str(), window, 1),
        ("conf-lag-right", "bar-1d", right.as_str(), window, 1),
        ("conf-lag-fem", "fem-2d", fem, "1e-4", 6),
        ("conf-lag-pd", "pd-correspondence", pd, "1.6e-5", 22),
    ];
    for (tag, model, params, window, unknowns) in sides {
        let (code, rules, text) = conformance_as(
            tag,
            model,
            params,
            &["--kind", "lagrange", "--window", window],
            &["solid-node"],
        );
        for (rule, (tag, reason)) in &rules {
            assert_eq!(tag, "PASS", "{model} {rule}: {reason}");
        }
        assert!(text.contains("12 of 12 rules pass"), "{text}");
        assert_eq!(code, Some(0), "{text}");
        assert!(text.contains("as a lagrange side"), "{text}");
        assert!(
            rules["lagrange-set-up"]
                .1
                .starts_with(&format!("{unknowns} unknowns")),
            "{text}"
        );
        assert!(
            rules["lagrange-correction"].1.contains("in 3 window(s)"),
            "{text}"
        );
    }
}

/// A side that states twice its true operator is solved for half the multipliers it needs:
/// pulled toward the rigid side's 1 mm/s, its interface gets half way, and the rule that
/// compares its corrected velocity with what its stated operator predicts fails, alone.
#[test]
fn a_lagrange_side_that_misstates_its_operator_fails_the_correction_rule() {
    let params = format!(
        "{LEFT_HALF}substeps = 1\nintegrator = {{ scheme = \"gs4\", design = \"U0(1,1,0)\", \
         implicit = true }}\nfault = \"operator\"\n"
    );
    let (code, rules, text) = conformance_as(
        "conf-lag-lie",
        "bar-1d",
        &params,
        &["--kind", "lagrange", "--window", "9.912113800799505e-7"],
        &["cosim-faulty"],
    );
    assert_eq!(code, Some(1), "{text}");
    let (tag, reason) = &rules["lagrange-correction"];
    assert_eq!(tag, "FAIL", "{reason}");
    assert!(
        reason.starts_with("window 2 starts from interface velocities farther by 5.000e-4 m/s"),
        "{reason}"
    );
    for (rule, (tag, reason)) in rules.iter().filter(|r| r.0 != "lagrange-correction") {
        assert_eq!(tag, "PASS", "{rule}: {reason}");
    }
}
