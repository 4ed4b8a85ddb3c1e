//! A short run of every fuzz target in the test suite (2,000 inputs each; `FUZZ_CASES`
//! changes the count): no input panics, and the inputs reach past the first check (some are
//! accepted, some refused), so the targets are not fuzzing only the outer layer.

use cosim_fuzz::*;
use proptest::strategy::{Strategy, ValueTree};
use proptest::test_runner::{Config, TestRunner};

fn cases() -> u32 {
    std::env::var("FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2000)
}

/// Runs `target` over `cases()` inputs of `strategy`; returns (accepted, refused).
fn run<S: Strategy>(name: &str, strategy: S, target: impl Fn(&S::Value) -> bool) -> (u32, u32)
where
    S::Value: std::fmt::Debug,
{
    let mut runner = TestRunner::new(Config {
        cases: cases(),
        ..Config::default()
    });
    let (mut ok, mut err) = (0, 0);
    for _ in 0..cases() {
        let input = strategy
            .new_tree(&mut runner)
            .unwrap_or_else(|e| panic!("{name}: no input: {e}"))
            .current();
        match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| target(&input))) {
            Ok(true) => ok += 1,
            Ok(false) => err += 1,
            Err(_) => panic!("{name}: the input {input:?} panicked"),
        }
    }
    eprintln!("{name}: {} inputs, {ok} accepted, {err} refused", ok + err);
    assert_eq!(ok + err, cases(), "{name}: every input ran");
    (ok, err)
}

#[test]
fn the_message_decoder_never_panics() {
    let (ok, err) = run("wire", wire_input(), |b| wire_target(b));
    assert!(ok > 0 && err > 0, "wire: {ok} accepted, {err} refused");
}

#[test]
fn the_case_parser_with_overrides_never_panics() {
    if let Err(e) = coordinator::case::load_variant_text(
        CASE,
        std::path::Path::new("fuzz.toml"),
        None,
        &["left.elements=20".to_string()],
    ) {
        panic!("the seed case parses: {}: {}", e.key, e.reason);
    }
    let (ok, err) = run("case", case_input(), |(t, s)| case_target(t, s));
    assert!(ok > 0 && err > 0, "case: {ok} accepted, {err} refused");
}

#[test]
fn every_node_params_decoder_never_panics() {
    for m in MODELS.iter() {
        if let Err(e) = params_check(m, &base_table(m)) {
            panic!("{}: the seed table builds: {e}", m.name);
        }
    }
    // Per model, not pooled: every model's decoder must see inputs it accepts and inputs it
    // refuses, or its deeper checks went unfuzzed.
    let tally = std::cell::RefCell::new(vec![(0u32, 0u32); MODELS.len()]);
    let (ok, err) = run("params", params_input(), |(m, t)| {
        let accepted = params_target(&MODELS[*m], t);
        let mut tally = tally.borrow_mut();
        if accepted {
            tally[*m].0 += 1;
        } else {
            tally[*m].1 += 1;
        }
        accepted
    });
    assert!(ok > 0 && err > 0, "params: {ok} accepted, {err} refused");
    for (m, &(ok, err)) in MODELS.iter().zip(tally.borrow().iter()) {
        eprintln!("params {}: {ok} accepted, {err} refused", m.name);
        assert!(
            ok > 0 && err > 0,
            "params {}: {ok} accepted, {err} refused",
            m.name
        );
    }
}
