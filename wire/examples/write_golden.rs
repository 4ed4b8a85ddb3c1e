//! Writes the golden vectors of the wire contract into `wire/golden/`: for each hand-chosen
//! envelope, `NN_name.bin` (its exact bytes) and `NN_name.json` (the same envelope as JSON).
//! Run once, by hand, when the contract changes on purpose: `cargo run -p wire --example
//! write_golden`. The tests only read the files; they never write them.

use std::path::PathBuf;
use wire::codec::encode;
use wire::message::*;

const RUN: &str = "demo-1";

/// One vector: file stem, sender, sequence number, message.
type Vector = (&'static str, &'static str, u64, Message);

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

fn report() -> StepReport {
    StepReport {
        kinetic_energy: 1.25,
        internal_energy: 0.75,
        external_work: 2.0,
        interface_work: -0.5,
        momentum: [0.125, 0.0, -3.5],
        momentum_gross: 4.0,
        external_impulse: [0.0, 0.0, -1.0],
        applied_impulse: 1.0,
        interface_impulse: [0.25, 0.0, 0.0],
        substeps: 3,
        wall_s: 0.001953125,
        coupling_wait_s: 0.0,
        idle_s: 0.0009765625,
        scalars: vec![],
    }
}

fn vectors() -> Vec<Vector> {
    let reason_300: String = "window too long; ".repeat(18).chars().take(300).collect();
    vec![
        (
            "01_hello",
            "right",
            0,
            Message::Hello(Hello {
                protocol_version: wire::PROTOCOL_VERSION,
                node: "right".into(),
                model: String::new(),
                pid: 4242,
                capabilities: strings(&["solid-node"]),
                token: "9e3779b97f4a7c15".into(),
            }),
        ),
        (
            "02_welcome",
            "coordinator",
            1,
            Message::Welcome(Welcome {
                run: RUN.into(),
                model: "bar-1d".into(),
                params_toml: "length = 0.5\nelements = 300\n".into(),
                bindings: vec![
                    Binding {
                        coupling: "tip".into(),
                        kind: CouplingKind::Kinematic,
                        interface: "root".into(),
                        role: Role::Responder,
                        peer: "left".into(),
                        peer_interface: "tip".into(),
                        sends: strings(&["force", "mass", "stiffness"]),
                        receives: strings(&["velocity"]),
                        input_lag: 0,
                    },
                    Binding {
                        coupling: "wall".into(),
                        kind: CouplingKind::Lagrange,
                        interface: "end".into(),
                        role: Role::Driver,
                        peer: "coordinator".into(),
                        peer_interface: String::new(),
                        sends: strings(&["velocity", "lagrange_operator"]),
                        receives: strings(&["force"]),
                        input_lag: 0,
                    },
                ],
                output_dir: "out/split_bar/right".into(),
                heartbeat_ms: 200,
            }),
        ),
        (
            "03_reject",
            "coordinator",
            1,
            Message::Reject(Reject {
                reason: "wrong run token".into(),
            }),
        ),
        (
            "04_describe",
            "right",
            1,
            Message::Describe(Describe {
                model: "bar-1d".into(),
                interfaces: vec![InterfaceDescription {
                    name: "root".into(),
                    points: 1,
                    provides: strings(&["force", "mass", "stiffness"]),
                    accepts: strings(&["velocity"]),
                }],
                stable_dt: 4.956e-7 / 3.0,
                units: "SI".into(),
                warnings: vec![],
            }),
        ),
        (
            "05_mesh",
            "left",
            2,
            Message::Mesh(Mesh {
                coupling: "tip".into(),
                interface: "tip".into(),
                mesh: InterfaceMesh {
                    ids: vec![0, 1],
                    positions: vec![[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]],
                    cells: Some(Cells {
                        kind: CellKind::Line,
                        connectivity: vec![0, 1],
                    }),
                    normals: vec![],
                    weights: vec![],
                },
            }),
        ),
        (
            "06_advance",
            "coordinator",
            5,
            Message::Advance(Advance {
                window: 1,
                t0: 0.0,
                t1: 4.956e-7,
                write_output: false,
                checkpoint: false,
            }),
        ),
        (
            "07_fields",
            "left",
            4,
            Message::Fields(Fields {
                coupling: "tip".into(),
                window: 1,
                time: 4.956e-7,
                fields: vec![Field {
                    name: "velocity".into(),
                    components: 1,
                    values: vec![-0.25],
                }],
            }),
        ),
        (
            "08_done",
            "left",
            5,
            Message::Done(Done {
                window: 1,
                report: report(),
            }),
        ),
        (
            "09_heartbeat",
            "right",
            7,
            Message::Heartbeat(Heartbeat {
                window: 3,
                substeps: 300,
                waiting: true,
            }),
        ),
        (
            "10_finish",
            "coordinator",
            3201,
            Message::Finish(Finish {
                reason: "end time reached".into(),
            }),
        ),
        (
            "11_abort",
            "coordinator",
            40,
            Message::Abort(Abort {
                reason: "node 'right': was killed by signal 9 (SIGKILL) during window 12".into(),
            }),
        ),
        (
            "12_failed",
            "right",
            2,
            Message::Failed(Failed {
                reason: "nodes.right.params.young: must be > 0, got -1".into(),
            }),
        ),
        (
            "13_decouple",
            "coordinator",
            1210,
            Message::Decouple(Decouple {
                coupling: "blast".into(),
                window: 1200,
                reason: "t = 1.000000e-3 s reached decouple_at = 1e-3 s".into(),
            }),
        ),
        (
            "14_mesh_quad",
            "shell",
            3,
            Message::Mesh(Mesh {
                coupling: "skin".into(),
                interface: "outer".into(),
                mesh: InterfaceMesh {
                    ids: vec![10, 11, 12, 20, 21, 22],
                    positions: vec![
                        [0.0, 0.0, 0.0],
                        [0.1, 0.0, 0.0],
                        [0.2, 0.0, 0.0],
                        [0.0, 0.1, 0.0],
                        [0.1, 0.1, 0.0],
                        [0.2, 0.1, 0.0],
                    ],
                    cells: Some(Cells {
                        kind: CellKind::Quad,
                        connectivity: vec![0, 1, 4, 3, 1, 2, 5, 4],
                    }),
                    normals: vec![[0.0, 0.0, 1.0]; 6],
                    weights: vec![0.0025, 0.005, 0.0025, 0.0025, 0.005, 0.0025],
                },
            }),
        ),
        (
            "15_mesh_points",
            "joint",
            3,
            Message::Mesh(Mesh {
                coupling: "bolt".into(),
                interface: "head".into(),
                mesh: InterfaceMesh {
                    ids: vec![0, 1, 2],
                    positions: vec![[0.0, 0.0, 0.0], [0.0, 0.0, 0.01], [0.0, 0.0, 0.02]],
                    cells: None,
                    normals: vec![],
                    weights: vec![1.0, 1.0, 1.0],
                },
            }),
        ),
        (
            "16_fields_multi",
            "right",
            9,
            Message::Fields(Fields {
                coupling: "tip".into(),
                window: 0,
                time: 0.0,
                fields: vec![
                    Field {
                        name: "force".into(),
                        components: 3,
                        values: vec![
                            -0.0,
                            0.1 + 0.2,
                            1e-300,
                            f64::MAX,
                            f64::MIN_POSITIVE,
                            5e-324,
                            -1.5,
                            2.0f64.sqrt(),
                            std::f64::consts::PI,
                        ],
                    },
                    Field {
                        name: "mass".into(),
                        components: 1,
                        values: vec![7.85, 7.85, 3.925],
                    },
                    Field {
                        name: "stiffness".into(),
                        components: 1,
                        // 40 values: 320 bytes, so the byte string's length takes the u16 form.
                        values: (0..40).map(|i| 2.1e11 * (1.0 + i as f64 / 64.0)).collect(),
                    },
                ],
            }),
        ),
        (
            "17_describe_warnings",
            "fluid",
            1,
            Message::Describe(Describe {
                model: "euler-2d".into(),
                interfaces: vec![
                    InterfaceDescription {
                        name: "wall".into(),
                        points: 256,
                        provides: strings(&["force"]),
                        accepts: strings(&["position", "velocity"]),
                    },
                    InterfaceDescription {
                        name: "inlet".into(),
                        points: 0,
                        provides: vec![],
                        accepts: vec![],
                    },
                ],
                stable_dt: 2.5e-8,
                units: "SI".into(),
                warnings: strings(&[
                    "the GPU has no f64: running in f32",
                    "σ_y rounded to 3 digits",
                ]),
            }),
        ),
        (
            "18_done_scalars",
            "right",
            3300,
            Message::Done(Done {
                window: 3200,
                report: StepReport {
                    substeps: 70_000,
                    scalars: vec![
                        ("tip_displacement".into(), 1.25e-5),
                        ("probe_pressure".into(), 101325.0),
                    ],
                    ..report()
                },
            }),
        ),
        (
            "19_advance_varints",
            "coordinator",
            0x0102_0304_0506_0708,
            Message::Advance(Advance {
                window: 1 << 40,
                t0: 0.5,
                t1: 1.0,
                write_output: true,
                checkpoint: true,
            }),
        ),
        (
            "20_abort_long_reason",
            "coordinator",
            41,
            Message::Abort(Abort { reason: reason_300 }),
        ),
    ]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("golden");
    std::fs::create_dir_all(&dir)?;
    let vs = vectors();
    for (stem, sender, seq, message) in &vs {
        let bytes = encode(RUN, sender, *seq, message)?;
        let env = wire::Envelope {
            run: RUN.into(),
            sender: sender.to_string(),
            seq: *seq,
            message: message.clone(),
        };
        let json = serde_json::to_string_pretty(&env)? + "\n";
        std::fs::write(dir.join(format!("{stem}.bin")), &bytes)?;
        std::fs::write(dir.join(format!("{stem}.json")), json)?;
    }
    println!("{} vectors written to {}", vs.len(), dir.display());
    Ok(())
}
