//! `kind = "lagrange"` through `cosim run` (seed 003 §4–§5): the split bar of
//! examples/split_bar_lagrange.toml, each half its own node with its own integrator and step,
//! the interface problem solved by the coordinator. Step ratio 1 reproduces the single-domain
//! bar; for m = 2 (implicit | implicit) and m = 4 (implicit | explicit) `gs4` is second order
//! and `gc` first order over three halvings of the system step, at the interface, the tip and
//! in λ, against a single-domain run of the same mesh with a 128 times smaller step; every
//! run agrees with the in-process library path (`solid_node::fixtures::split_bar`) to
//! round-off; the interface energy ΔE_Γ in summary.json shrinks at first order for gc and at
//! second for gs4; a replay of a lagrange side is bit-identical.

use cosim_tests::*;
use mechanics::time::{Design, Gs4};
use protocol::scheme::lagrange::Method;
use solid_node::fixtures::split_bar::{self, Half, Histories, Ramp};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

fn case() -> PathBuf {
    workspace_root().join("examples/split_bar_lagrange.toml")
}

fn newmark() -> Gs4 {
    Gs4::u0(Design {
        rho1: 1.0,
        rho2: 1.0,
        rho_s: 0.0,
    })
}

fn integrator(coef: Gs4) -> &'static str {
    if coef.explicit {
        "{ scheme = \"gs4\", design = \"U0(1,1,0)\", implicit = false }"
    } else {
        "{ scheme = \"gs4\", design = \"U0(1,1,0)\", implicit = true }"
    }
}

/// The `--set`s of a run: method, the halves' integrators and substeps, system step `dt`
/// and `windows` windows. Times are written in Rust's shortest round-trip form, so the nodes
/// see exactly the library's values.
fn sets(method: Method, left: Half, right: Half, dt: f64, windows: usize) -> Vec<String> {
    let m = match method {
        Method::Gs4 => "gs4",
        Method::Gc => "gc",
        Method::Ph => "ph",
    };
    vec![
        format!("couplings.mid.method={m}"),
        format!("run.window={dt:e}"),
        format!("run.end_time={:e}", dt * windows as f64),
        format!("left.integrator={}", integrator(left.coef)),
        format!("left.substeps={}", left.substeps),
        format!("right.integrator={}", integrator(right.coef)),
        format!("right.substeps={}", right.substeps),
        format!("right.ramp_time={:e}", split_bar::ramp_time()),
    ]
}

/// Runs the case with `sets`; returns the output directory.
fn run(tag: &str, sets: &[String]) -> PathBuf {
    let (dir, id) = scratch(tag);
    let out = dir.join("out");
    let mut extra: Vec<&str> = Vec::new();
    for s in sets {
        extra.push("--set");
        extra.push(s);
    }
    let o = run_case(&case(), &out, &id, &extra);
    assert!(
        o.status.success(),
        "{tag}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    nothing_left(&id);
    out
}

/// The histories of a run, from its recording: u, v, a at the interface (the left half's
/// `tip`) and the right half's tip per window, λ from the `/cosim/lagrange/mid` channel, with
/// the state at t = 0 (at rest, no load) first, as the library samples them.
fn histories(out: &Path, dt: f64) -> Histories {
    let mcap = out.join("run.mcap");
    let series = |node: &str, key: &str| -> Vec<f64> {
        std::iter::once(0.0)
            .chain(node_series(&mcap, node, key).into_iter().map(|(_, v)| v))
            .collect()
    };
    let q = ["displacement", "velocity", "acceleration"];
    let (msgs, _) = coordinator::record::read_json(&mcap).expect("readable recording");
    let lambda: Vec<f64> = std::iter::once(0.0)
        .chain(
            msgs.iter()
                .filter(|m| m.topic == "/cosim/lagrange/mid")
                .filter_map(|m| {
                    let v: serde_json::Value = serde_json::from_slice(&m.data).ok()?;
                    v["lambda"][0].as_f64()
                }),
        )
        .collect();
    Histories {
        dt,
        interface: q.map(|k| series("left", &format!("tip_{k}"))),
        tip: q.map(|k| series("right", &format!("tip_{k}"))),
        lambda,
        interface_work: Vec::new(),
    }
}

/// Largest difference between two histories sampled alike, relative to `b`'s largest value,
/// over the seven quantities; and the samples compared.
fn agreement(a: &Histories, b: &Histories) -> (f64, usize) {
    let (e, n) = split_bar::errors(a, b);
    (e.iter().fold(0.0f64, |m, x| m.max(*x)), n)
}

const NAMES: [&str; 7] = ["u_Γ", "v_Γ", "a_Γ", "u_tip", "v_tip", "a_tip", "λ"];

#[test]
fn ratio_one_through_cosim_run_reproduces_the_single_domain_bar() {
    // Both halves central differences at a quarter of the left element's transit (within the
    // right half's limit), 400 windows into the septic ramp.
    let cd = Gs4::central_difference();
    let half = Half {
        coef: cd,
        substeps: 1,
    };
    let dt = split_bar::left_transit() / 4.0;
    let windows = 400;
    let out = run("lag-m1", &sets(Method::Gs4, half, half, dt, windows));
    let got = histories(&out, dt);
    for h in [&got.interface[0], &got.tip[0], &got.lambda] {
        assert_eq!(h.len(), windows + 1, "windows recorded");
    }
    let single = split_bar::single(Ramp::Septic, cd, dt, windows, 1);
    let (e, n) = split_bar::errors(&got, &single);
    println!("m = 1 through cosim vs single domain: {e:?} over {n} samples");
    assert_eq!(n, windows + 1);
    // u to 1e-12 of its amplitude (as the library test); v, a and λ are what round-off in u
    // becomes through the mesh's highest frequencies (see tests/lagrange_split_bar.rs).
    let tol = [1e-12, 1e-10, 1e-7, 1e-12, 1e-10, 1e-7, 1e-10];
    for k in 0..7 {
        assert!(e[k] < tol[k], "{}: {:e}", NAMES[k], e[k]);
    }
    let lib = split_bar::split(Ramp::Septic, Method::Gs4, half, half, dt, windows).unwrap();
    let (d, n) = agreement(&got, &lib);
    println!("m = 1 through cosim vs the library path: {d:e} over {n} samples");
    assert_eq!(n, windows + 1);
    assert!(d < 1e-14, "cosim and library differ by {d:e}");
    // bar-1d reports the end force's, the support's and the interface's impulses on the
    // lagrange path: the audit's momentum balance closes.
    let s = summary(&out);
    let b = &s["balance"];
    let (resid, scale) = (
        b["max_momentum_residual_relative"]
            .as_f64()
            .unwrap_or(f64::NAN),
        b["impulse_scale"].as_f64().unwrap_or(0.0),
    );
    println!("m = 1: momentum residual {resid:.3e} of the impulse scale {scale:.3e} N s");
    assert!(scale > 0.0, "impulses reported: {scale}");
    assert!(resid < 1e-9, "momentum residual {resid:e}");
    // The recording replays bit-identically, each side against the recorded multipliers.
    for node in ["left", "right"] {
        let w = assert_replays_bit_identically(&out.join("run.mcap"), node, "lag-replay");
        assert_eq!(w, windows as u64);
    }
}

/// System steps of the coarsest level (ΔT₀ = h_left/c) of the order study: to T, the end of
/// the ramp.
fn steps0() -> usize {
    (split_bar::ramp_time() / split_bar::left_transit()).round() as usize
}

fn reference() -> &'static Histories {
    static R: OnceLock<Histories> = OnceLock::new();
    R.get_or_init(|| {
        let dt = split_bar::left_transit() / 128.0;
        split_bar::single(Ramp::Septic, newmark(), dt, steps0() * 128, 1)
    })
}

/// Errors against the reference at ΔT₀ … ΔT₀/8 through `cosim run`, and ΔE_Γ from each
/// run's summary.json.
fn study(tag: &str, method: Method, left: Half, right: Half) -> (Vec<[f64; 7]>, Vec<f64>) {
    let mut errors = Vec::new();
    let mut energy = Vec::new();
    for level in 0..4 {
        let dt = split_bar::left_transit() / (1 << level) as f64;
        let windows = steps0() << level;
        let out = run(
            &format!("{tag}-{level}"),
            &sets(method, left, right, dt, windows),
        );
        let got = histories(&out, dt);
        let (e, n) = split_bar::errors(&got, reference());
        assert_eq!(n, windows + 1, "{tag} level {level}: samples compared");
        let lib = split_bar::split(Ramp::Septic, method, left, right, dt, windows).unwrap();
        let (d, n) = agreement(&got, &lib);
        println!("{tag} level {level}: cosim vs library {d:e} over {n} samples");
        assert_eq!(n, windows + 1);
        assert!(
            d < 1e-14,
            "{tag} level {level}: cosim and library differ by {d:e}"
        );
        let s = summary(&out);
        let de = s["couplings"][0]["interface_energy"]
            .as_f64()
            .expect("interface_energy in summary.json");
        errors.push(e);
        energy.push(de);
    }
    (errors, energy)
}

fn orders(e: &[[f64; 7]]) -> Vec<[f64; 7]> {
    (0..e.len() - 1)
        .map(|l| std::array::from_fn(|k| (e[l][k] / e[l + 1][k]).log2()))
        .collect()
}

#[test]
fn gs4_is_second_order_and_gc_first_through_cosim_run() {
    // (tag, left, right, whether ΔE_Γ is checked): over this horizon (to the end of the
    // ramp) gc's interface energy with the explicit right half is not yet of one sign at the
    // coarsest step (measured −2.7e-6, 1.9e-6, 3.3e-6, 2.2e-6 J); the library test follows it
    // to 2T (solid-node/tests/lagrange_split_bar.rs).
    let pairs = [
        (
            "lag-nm2",
            Half {
                coef: newmark(),
                substeps: 1,
            },
            Half {
                coef: newmark(),
                substeps: 2,
            },
            true,
        ),
        (
            "lag-cd4",
            Half {
                coef: newmark(),
                substeps: 1,
            },
            Half {
                coef: Gs4::central_difference(),
                substeps: 4,
            },
            false,
        ),
    ];
    let mut measured = 0;
    let mut energies = 0;
    for (tag, left, right, energy) in pairs {
        let (gs4, gs4_energy) = study(&format!("{tag}-gs4"), Method::Gs4, left, right);
        let (gc, gc_energy) = study(&format!("{tag}-gc"), Method::Gc, left, right);
        for (l, o) in orders(&gs4).iter().enumerate() {
            for k in 0..7 {
                println!("{tag} gs4 halving {l}: {} order {:.3}", NAMES[k], o[k]);
                assert!(
                    o[k] >= 1.9,
                    "{tag} gs4 halving {l}: {} order {:.3}",
                    NAMES[k],
                    o[k]
                );
                measured += 1;
            }
        }
        let last = orders(&gc)[2];
        for k in [0, 1, 3, 4, 6] {
            println!("{tag} gc: {} order {:.3}", NAMES[k], last[k]);
            assert!(
                (0.7..=1.3).contains(&last[k]),
                "{tag} gc: {} order {:.3}",
                NAMES[k],
                last[k]
            );
            measured += 1;
        }
        // ΔE_Γ: gc dissipates and halves it with the step, gs4's falls four
        // times per halving.
        println!("{tag}: ΔE_Γ gc {gc_energy:?}, gs4 {gs4_energy:?}");
        if !energy {
            continue;
        }
        energies += 1;
        assert!(
            gc_energy.iter().all(|&e| e > 0.0),
            "{tag}: gc ΔE_Γ {gc_energy:?}"
        );
        let gc_ratio = gc_energy[2] / gc_energy[3];
        let gs4_ratio = gs4_energy[2] / gs4_energy[3];
        assert!(
            (1.6..=2.4).contains(&gc_ratio),
            "{tag}: gc ΔE_Γ ratio {gc_ratio}"
        );
        assert!(
            (3.2..=4.8).contains(&gs4_ratio),
            "{tag}: gs4 ΔE_Γ ratio {gs4_ratio}"
        );
    }
    assert_eq!(measured, 2 * (3 * 7 + 5));
    assert_eq!(energies, 1);
}

/// an explicit–implicit pair with the explicit side exactly at its
/// Courant limit (right half central differences, 3 substeps of h_left/c: Δt = h_right/c)
/// runs stable through `cosim run` to the end of the ramp, for gs4 and gc, and stays close to
/// the single-domain reference (gs4 closer than gc); the gc run's explicit side replays
/// bit-identically.
#[test]
fn explicit_side_at_its_courant_limit_is_stable() {
    let left = Half {
        coef: newmark(),
        substeps: 1,
    };
    let right = Half {
        coef: Gs4::central_difference(),
        substeps: 3,
    };
    let dt = split_bar::left_transit();
    let windows = steps0();
    let mut worst = Vec::new();
    for method in [Method::Gs4, Method::Gc] {
        let tag = format!("lag-courant-{method:?}");
        let out = run(&tag, &sets(method, left, right, dt, windows));
        let got = histories(&out, dt);
        let (e, n) = split_bar::errors(&got, reference());
        assert_eq!(n, windows + 1, "{tag}: samples compared");
        println!("{tag}: errors against the reference {e:?}");
        let lib = split_bar::split(Ramp::Septic, method, left, right, dt, windows).unwrap();
        let (d, _) = agreement(&got, &lib);
        assert!(d < 1e-14, "{tag}: cosim and library differ by {d:e}");
        // Measured: gs4 ≤ 4.5e-5 in all seven; gc 5.1e-4 in u_tip (0.16 in a_tip).
        let (quantities, bound): (&[usize], f64) = match method {
            Method::Gs4 => (&[0, 1, 2, 3, 4, 5, 6], 1e-4),
            _ => (&[0, 3, 6], 2e-3),
        };
        for &k in quantities {
            assert!(e[k] < bound, "{tag}: {} error {:e}", NAMES[k], e[k]);
        }
        worst.push(e.iter().fold(0.0f64, |m, x| m.max(*x)));
        if method == Method::Gc {
            // gc exchanges once per substep of the right half (three per window): its
            // replay meets every one of them.
            let w = assert_replays_bit_identically(&out.join("run.mcap"), "right", "lag-gc-replay");
            assert_eq!(w, windows as u64);
        }
    }
    assert!(worst[0] < worst[1], "gs4 {:e}, gc {:e}", worst[0], worst[1]);
}
