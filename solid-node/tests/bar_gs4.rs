//! `bar-1d` with a GS4-II integrator: the `integrator` table is decoded strictly
//! and refused with its key path, and a fixed–free bar under a step end load F oscillates
//! about the static solution FL/EA with amplitude FL/EA (the exact triangle wave between 0
//! and 2FL/EA, period 4L/c).

use protocol::{Inbox, Outbox, Solver, Window};
use solid_node::bar::Bar;

fn params(integrator: &str) -> toml::Table {
    let text = format!(
        "length = 1.0\nelements = 100\nyoung = 200e9\ndensity = 7860.0\narea = 1e-4\n\
         fixed = \"left\"\ntip_force = 1000.0\nload_end = \"right\"\ncourant = 0.5\n{integrator}"
    );
    match text.parse::<toml::Table>() {
        Ok(t) => t,
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn bad_integrators_are_refused_with_their_key() {
    for (table, key) in [
        (
            "integrator = { scheme = \"gs4\", design = \"wbz\" }",
            "integrator.rho_inf",
        ),
        ("integrator = { scheme = \"rk4\" }", "integrator.scheme"),
        (
            "integrator = { scheme = \"gs4\", design = \"U0(1,1,2)\" }",
            "integrator.design",
        ),
        (
            "integrator = { scheme = \"gs4\", design = \"hht\", rho_inf = 0.9 }",
            "integrator.implicit",
        ),
    ] {
        let e = Bar::from_params(&params(table))
            .err()
            .map(|e| e.to_string());
        let e = e.unwrap_or_default();
        assert!(e.starts_with(&format!("{key}:")), "{table}: {e}");
    }
    let e = Bar::from_params(&params("integrator = { scheme = \"gs4\", rho = 1.0 }"));
    let e = e.err().map(|e| e.to_string()).unwrap_or_default();
    assert!(
        e.starts_with("integrator.rho:") && e.contains("unknown"),
        "{e}"
    );
}

#[test]
fn step_loaded_bar_oscillates_about_the_static_solution() {
    let (f, l, ea) = (1000.0, 1.0, 200e9 * 1e-4);
    let c = (200e9f64 / 7860.0).sqrt();
    let period = 4.0 * l / c;
    for integrator in [
        "integrator = { scheme = \"gs4\", design = \"U0(1,1,0)\", implicit = true }",
        "integrator = { scheme = \"gs4\", design = \"U0(1,1,0)\", implicit = false }",
    ] {
        let mut bar = match Bar::from_params(&params(integrator)) {
            Ok(b) => b,
            Err(e) => panic!("{integrator}: {e}"),
        };
        let mut out = Outbox::new();
        if let Err(e) = bar.setup(&[], &Inbox::new(), &mut out) {
            panic!("{e}");
        }
        let windows = 400;
        let (mut sum, mut peak) = (0.0, 0.0f64);
        for w in 0..windows {
            let win = Window {
                index: w,
                t0: w as f64 * 2.0 * period / windows as f64,
                t1: (w + 1) as f64 * 2.0 * period / windows as f64,
                write_output: false,
            };
            let r = match bar.advance(&win, &Inbox::new(), &mut out) {
                Ok(r) => r,
                Err(e) => panic!("{e}"),
            };
            let tip = r
                .scalars
                .iter()
                .find(|(n, _)| n == "tip_displacement")
                .map(|s| s.1)
                .unwrap_or(f64::NAN);
            sum += tip;
            peak = peak.max(tip);
        }
        let mean = sum / windows as f64;
        let stat = f * l / ea;
        assert!(
            (mean / stat - 1.0).abs() < 0.01,
            "{integrator}: mean {mean:e}, FL/EA {stat:e}"
        );
        assert!(
            (peak / (2.0 * stat) - 1.0).abs() < 0.05,
            "{integrator}: peak {peak:e}"
        );
    }
}
