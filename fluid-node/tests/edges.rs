//! Edge lines (docs/physics.md §3.6): a helium slab carried by air at a uniform 100 m/s
//! and 1 atm keeps its width and moves at the flow's speed, so its two edges along the
//! flow must be where the slab is and move at 100 m/s; along a line the other way, the
//! first and last edges swap and the speeds change sign.

use crate::common;
use common::solver;
use protocol::{Inbox, Outbox, Solver, Window};

#[test]
fn the_edges_of_a_carried_slab_move_with_the_flow() {
    let u = 100.0;
    let mut s = solver(&format!(
        r#"
        cfl = 0.5
        [grid]
        cells = [400, 1, 1]
        lower = [0.0, 0.0, 0.0]
        upper = [1.0, 1.0, 1.0]
        [materials.air]
        eos = "ideal"
        gamma = 1.4
        [materials.helium]
        eos = "ideal"
        gamma = 1.67
        [[regions]]
        shape = "all"
        material = "air"
        density = 1.2
        pressure = 1.0e5
        velocity = [{u}, 0.0, 0.0]
        [[regions]]
        shape = "box"
        lower = [0.2, 0.0, 0.0]
        upper = [0.4, 1.0, 1.0]
        material = "helium"
        density = 0.17
        pressure = 1.0e5
        velocity = [{u}, 0.0, 0.0]
        [[edges]]
        name = "along"
        material = "helium"
        from = [0.0, 0.5, 0.5]
        to = [1.0, 0.5, 0.5]
        [[edges]]
        name = "back"
        material = "helium"
        from = [1.0, 0.5, 0.5]
        to = [0.0, 0.5, 0.5]
        [boundaries]
        x_lower = {{ kind = "inflow", material = "air", density = 1.2, pressure = 1.0e5, velocity = [{u}, 0.0, 0.0] }}
        x_upper = "outflow"
    "#
    ));
    let (inbox, mut out) = (Inbox::new(), Outbox::new());
    let window = 1.0e-4;
    let mut report = None;
    for k in 1..=30u64 {
        let w = Window {
            index: k,
            t0: (k - 1) as f64 * window,
            t1: k as f64 * window,
            write_output: false,
        };
        report = Some(s.advance(&w, &inbox, &mut out).expect("window"));
    }
    let r = report.expect("a report");
    let get = |n: &str| {
        r.scalars
            .iter()
            .find(|(k, _)| k == n)
            .unwrap_or_else(|| panic!("no {n}"))
            .1
    };
    let t = 30.0 * window;
    let (first, last) = (get("along.first"), get("along.last"));
    let (v1, v2) = (get("along.first_speed"), get("along.last_speed"));
    println!(
        "slab after {t} s: edges at {first:.5} and {last:.5} m (exact {:.5}, {:.5}); speeds {v1:.3}, {v2:.3} m/s (exact {u}); \
         the other way {:.5}, {:.5} m, {:.3}, {:.3} m/s; {} entries in the history",
        0.2 + u * t,
        0.4 + u * t,
        get("back.first"),
        get("back.last"),
        get("back.first_speed"),
        get("back.last_speed"),
        s.edge_history.len()
    );
    assert_eq!(s.edge_history.len(), 31, "t = 0 and every window");
    let h = 1.0 / 400.0;
    assert!((first - (0.2 + u * t)).abs() < 0.5 * h, "{first}");
    assert!((last - (0.4 + u * t)).abs() < 0.5 * h, "{last}");
    assert!(
        (v1 / u - 1.0).abs() < 0.01 && (v2 / u - 1.0).abs() < 0.01,
        "{v1} {v2}"
    );
    // from the other end: the first edge met is the slab's right one, moving toward the start
    assert!((get("back.first") - (1.0 - last)).abs() < 1e-9);
    assert!((get("back.last") - (1.0 - first)).abs() < 1e-9);
    assert!((get("back.first_speed") + v2).abs() < 1e-6 * u);
    assert!((get("back.last_speed") + v1).abs() < 1e-6 * u);
}
