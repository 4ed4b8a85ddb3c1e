//! Configuration and plumbing: bad input refused with the key named,
//! the case-file shape parsed through the node's factory, determinism across thread counts,
//! support reactions consistent with momentum, VTK and CSV output written.
#![allow(clippy::needless_range_loop)]

mod common;

use common::{STEEL, shell};
use macro_shell_node::{ShellSolver, factory, step};
use protocol::{Inbox, Outbox, Solver, Window};

fn refused(toml: &str) -> String {
    match ShellSolver::from_toml_str(toml) {
        Ok(_) => panic!("accepted a bad config"),
        Err(e) => e.to_string(),
    }
}

fn plate(extra: &str, section: &str) -> String {
    format!(
        r#"
[mesh]
kind = "plate"
length = 1.0
width = 0.1
nx = 4
ny = 2
{STEEL}
[section]
{section}
{extra}
"#
    )
}

#[test]
fn zero_or_negative_thickness_is_refused() {
    for t in ["0.0", "-0.01"] {
        let e = refused(&plate("", &format!("thickness = {t}")));
        assert!(e.starts_with("section.thickness:"), "{e}");
    }
}

#[test]
fn node_set_naming_missing_nodes_is_refused() {
    let e = refused(&plate(
        "[[node_sets]]\nname = \"tip\"\nids = [3, 99]\n",
        "thickness = 0.01",
    ));
    assert!(
        e.starts_with("node_sets[0].ids:") && e.contains("99"),
        "{e}"
    );
    // A boundary condition naming a set that does not exist.
    let e = refused(&plate(
        "[[fixed]]\nnode_set = \"nowhere\"\n",
        "thickness = 0.01",
    ));
    assert!(e.starts_with("fixed[0].node_set:"), "{e}");
}

#[test]
fn degenerate_element_is_refused() {
    let toml = format!(
        r#"
[mesh]
kind = "explicit"
nodes = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0],
         [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]]
elements = [[0, 1, 2, 3], [1, 4, 5, 4]]
{STEEL}
[section]
thickness = 0.01
"#
    );
    let e = refused(&toml);
    assert!(e.starts_with("mesh.elements[1]:"), "{e}");
    // Collinear nodes: zero area without repeated nodes.
    let e = refused(&toml.replace("[1, 4, 5, 4]", "[0, 1, 4, 5]"));
    assert!(e.starts_with("mesh.elements[1]:"), "{e}");
}

#[test]
fn poisson_ratio_at_or_above_half_is_refused() {
    for nu in ["0.5", "0.7"] {
        let t = plate("", "thickness = 0.01")
            .replace("poisson_ratio = 0.3", &format!("poisson_ratio = {nu}"));
        let e = refused(&t);
        assert!(e.starts_with("material.poisson_ratio:"), "{e}");
    }
}

#[test]
fn unknown_keys_and_bad_kinds_are_refused() {
    let e = refused(&plate("", "thickness = 0.01\nthicknes = 0.02"));
    assert!(e.contains("thicknes"), "{e}");
    let e = refused(&plate("", "thickness = 0.01").replace("kind = \"plate\"", "kind = \"disk\""));
    assert!(e.starts_with("mesh.kind:"), "{e}");
    let e = refused(&plate("", "thickness = 0.01\nintegration_points = 1"));
    assert!(e.starts_with("section.integration_points:"), "{e}");
}

#[test]
fn case_file_params_build_through_the_factory() {
    let case = r#"
[run]
name = "cantilever"
end_time = 0.5
window = 1.0e-4
transport = "shm"
output = "out/cantilever"
[nodes.shell]
solver = "macro-shell-node"
model = "blt-shell"
[nodes.shell.params]
mesh = { kind = "plate", length = 1.0, width = 0.1, nx = 10, ny = 1 }
material = { model = "elastic", density = 7800.0, youngs_modulus = 210.0e9, poisson_ratio = 0.3 }
section = { thickness = 0.01 }
fixed = [{ node_set = "x0" }]
output = { reaction_sets = ["x0"] }
"#;
    let t: toml::Table = toml::from_str(case).unwrap_or_else(|e| panic!("{e}"));
    let params = t["nodes"]["shell"]["params"]
        .as_table()
        .unwrap_or_else(|| panic!("no params"))
        .clone();
    let s = factory("blt-shell", &params).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.describe().model, "blt-shell");
    assert!(s.stable_dt() > 0.0);
    let e = factory("hex8", &params)
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(e.starts_with("model:"), "{e}");
}

/// A kicked, point-loaded cantilever run for some steps inside a rayon pool of `threads`.
fn run_in_pool(threads: usize) -> (Vec<[f64; 3]>, Vec<f64>) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap_or_else(|e| panic!("{e}"));
    pool.install(|| {
        let mut s = shell(&plate(
            "[[fixed]]\nnode_set = \"x0\"\n[[point_loads]]\nnode_set = \"x1\"\nforce = [0.0, 10.0, -50.0]\n",
            "thickness = 0.01",
        ));
        let m = &mut s.model;
        let dt = step::stable_dt(m);
        for _ in 0..300 {
            step::step(m, dt).unwrap_or_else(|e| panic!("{e}"));
        }
        (m.x.clone(), m.stress.clone())
    })
}

#[test]
fn results_are_bit_identical_for_1_and_2_threads() {
    let (x1, s1) = run_in_pool(1);
    let (x2, s2) = run_in_pool(2);
    assert!(
        x1.iter()
            .zip(&x2)
            .all(|(a, b)| a.iter().zip(b).all(|(p, q)| p.to_bits() == q.to_bits()))
    );
    assert!(s1.iter().zip(&s2).all(|(a, b)| a.to_bits() == b.to_bits()));
}

#[test]
fn momentum_equals_impulse_of_loads_and_supports() {
    // Tip load on a clamped strip: Σ m v = ∫ (F_load + R_support) dt to round-off, so the
    // reaction forces written to CSV are the ones that act.
    let mut s = shell(&plate(
        "[[fixed]]\nnode_set = \"x0\"\n[[point_loads]]\nnode_set = \"x1\"\nforce = [5.0, 10.0, -50.0]\n[output]\nreaction_sets = [\"x0\"]\n",
        "thickness = 0.01",
    ));
    let dt = s.stable_dt();
    let mut out = Outbox::new();
    let mut total_reaction_impulse = [0.0; 3];
    for k in 0..200 {
        let w = Window {
            index: k + 1,
            t0: k as f64 * 5.0 * dt,
            t1: (k + 1) as f64 * 5.0 * dt,
            write_output: false,
        };
        let r = s
            .advance(&w, &Inbox::new(), &mut out)
            .unwrap_or_else(|e| panic!("{e}"));
        for d in 0..3 {
            total_reaction_impulse[d] = r.external_impulse[d] - s.model.load_impulse[d];
        }
        let p = r.momentum;
        let scale = s
            .model
            .load_impulse
            .iter()
            .map(|v| v.abs())
            .fold(0.0, f64::max);
        for d in 0..3 {
            assert!(
                (p[d] - r.external_impulse[d]).abs() < 1e-12 * scale,
                "window {k}: {p:?} vs {:?}",
                r.external_impulse
            );
        }
    }
    // The supports took part: without their impulse the balance would be off.
    let load_z = s.model.load_impulse[2].abs();
    println!(
        "reaction impulse {:?}, load impulse {:?}",
        total_reaction_impulse, s.model.load_impulse
    );
    assert!(total_reaction_impulse[2].abs() > 1e-3 * load_z);
    assert_eq!(s.history.rows.len(), 200);
    assert_eq!(s.history.header.len(), 7);
}

#[test]
fn vtk_and_csv_output_are_written() {
    let mut s = shell(&plate(
        "[[fixed]]\nnode_set = \"x0\"\n[[point_loads]]\nnode_set = \"x1\"\nforce = [0.0, 0.0, -50.0]\n[output]\nreaction_sets = [\"x0\"]\n",
        "thickness = 0.01",
    ));
    let dt = s.stable_dt();
    let mut out = Outbox::new();
    let w = Window {
        index: 1,
        t0: 0.0,
        t1: 10.0 * dt,
        write_output: true,
    };
    s.advance(&w, &Inbox::new(), &mut out)
        .unwrap_or_else(|e| panic!("{e}"));
    let dir = std::env::temp_dir().join(format!("shell-out-{}", std::process::id()));
    s.write_output(w.t1, 1, &dir)
        .unwrap_or_else(|e| panic!("{e}"));
    let vtu = std::fs::read_to_string(dir.join("shell_000001.vtu")).unwrap_or_default();
    for name in [
        "displacement",
        "velocity",
        "stress_mid",
        "plastic_strain",
        "thickness",
    ] {
        assert!(vtu.contains(name), "{name} missing");
    }
    assert!(
        std::fs::read_to_string(dir.join("shell.pvd"))
            .unwrap_or_default()
            .contains("shell_000001.vtu")
    );
    let csv = std::fs::read_to_string(dir.join("reactions.csv")).unwrap_or_default();
    assert!(csv.starts_with("time,x0_fx,x0_fy,x0_fz"));
    assert_eq!(csv.lines().count(), 2);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The meshes and sets the coupled examples use: several separate plates (`kind =
/// "plates"`), element sets from several boxes, a tube with two seams; bad input named.
#[test]
fn plates_boxes_and_two_seams_build_with_the_expected_counts() {
    let s = ShellSolver::from_toml_str(&format!(
        r#"
[mesh]
kind = "plates"
plates = [
  {{ origin = [0.0, 0.0, 2e-3], length = 6e-3, width = 8e-3, nx = 6, ny = 8 }},
  {{ origin = [18e-3, 0.0, 2e-3], length = 6e-3, width = 8e-3, nx = 3, ny = 4 }},
]
{STEEL}
[section]
thickness = 4e-3
[[element_sets]]
name = "ends"
boxes = [[4.9e-3, -1.0, -1.0, 6.1e-3, 1.0, 1.0], [17.9e-3, -1.0, -1.0, 20.1e-3, 1.0, 1.0]]
[[interfaces]]
name = "ends"
element_set = "ends"
"#
    ))
    .unwrap_or_else(|e| panic!("{e}"));
    let m = &s.model;
    // 7 × 9 + 4 × 5 nodes, 48 + 12 elements, no shared nodes.
    assert_eq!(m.num_nodes(), 63 + 20);
    assert_eq!(m.num_elements(), 60);
    // The last column of plate 0 (8 elements) and the first of plate 1 (4).
    assert_eq!(m.element_sets["ends"].len(), 12);
    assert_eq!(s.interfaces[0].cells.len(), 12);
    assert_eq!(m.element_sets["plate1"].len(), 12);
    // Mass: ρ h A of both plates.
    let mass = 7800.0 * 4e-3 * (48e-6 + 48e-6);
    assert!((m.total_mass() / mass - 1.0).abs() < 1e-12);

    let tube = |seams: &str| {
        ShellSolver::from_toml_str(&format!(
            r#"
[mesh]
kind = "tube"
side = 0.05
length = 0.2
n_side = 8
n_length = 32
overlap = 0.0125
gap = 0.001
{seams}
{STEEL}
[section]
thickness = 1e-3
"#
        ))
    };
    let one = tube("").unwrap_or_else(|e| panic!("{e}"));
    let two = tube("seams = 2").unwrap_or_else(|e| panic!("{e}"));
    // Each seam adds a strip of 2 × 32 elements (12.5 mm of a 6.25 mm mesh).
    assert_eq!(two.model.num_elements(), one.model.num_elements() + 2 * 32);
    assert_eq!(two.model.element_sets["seam2_outer"].len(), 64);
    assert_eq!(two.model.element_sets["seam2_inner"].len(), 64);
    // The second strip is 1 mm outside the face y = +h.
    let e = two.model.element_sets["seam2_outer"][0] as usize;
    let y = two.model.conn[e]
        .iter()
        .map(|&n| two.model.x0[n as usize][1])
        .sum::<f64>()
        / 4.0;
    assert!((y - 0.026).abs() < 1e-12, "{y}");
    match tube("seams = 3") {
        Ok(_) => panic!("three seams accepted"),
        Err(e) => assert!(e.to_string().starts_with("mesh.seams:"), "{e}"),
    }
    let e = refused(&format!(
        "[mesh]\nkind = \"plates\"\nplates = [{{ length = 1.0, width = -1.0, nx = 1, ny = 1 }}]\n{STEEL}\n[section]\nthickness = 0.01\n"
    ));
    assert!(e.starts_with("mesh.plates[0].width:"), "{e}");
}
