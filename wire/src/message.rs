//! The messages of the protocol (PROTOCOL.md). Every one travels inside an
//! [`crate::Envelope`]; the recorder stores the exact bytes, so these types are also the
//! recording's schema.

use serde::{Deserialize, Serialize};

/// Role a node plays in one coupling.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Role {
    /// Owns the interface motion (kinematic) and receives constraint forces.
    Driver,
    /// Follows the driver's motion and returns constraint forces.
    Responder,
}

/// The coupling kinds of docs/architecture.md.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CouplingKind {
    Kinematic,
    Immersed,
    Lagrange,
    Overlap,
}

impl CouplingKind {
    pub fn as_str(self) -> &'static str {
        match self {
            CouplingKind::Kinematic => "kinematic",
            CouplingKind::Immersed => "immersed",
            CouplingKind::Lagrange => "lagrange",
            CouplingKind::Overlap => "overlap",
        }
    }
}

/// One coupling as a node sees it: which of its interfaces, which peer, which role, which
/// fields go each way, and whether an input is used in the window it was produced in
/// (`lag = 0`) or in the next (`lag = 1`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Binding {
    /// Coupling name, unique in the run (the data topic is `cosim/<run>/<coupling>/<from>`).
    pub coupling: String,
    pub kind: CouplingKind,
    /// This node's interface.
    pub interface: String,
    pub role: Role,
    pub peer: String,
    pub peer_interface: String,
    /// Fields this node sends every window.
    pub sends: Vec<String>,
    /// Fields this node receives every window.
    pub receives: Vec<String>,
    /// 0: the input of window k is the peer's output of window k (serial dependency);
    /// 1: it is the peer's output of window k-1 (or of set-up for k = 1).
    pub input_lag: u64,
}

/// Node → coordinator, first message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Hello {
    pub protocol_version: u16,
    pub node: String,
    pub model: String,
    pub pid: u32,
    pub capabilities: Vec<String>,
    /// Token a remote node presents (docs/architecture.md); empty for launched nodes.
    pub token: String,
}

/// Coordinator → node: accepted, with everything the node needs to build its solver.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Welcome {
    pub run: String,
    pub model: String,
    /// The node's parameter table, as TOML text (validated by the node's own config types).
    pub params_toml: String,
    pub bindings: Vec<Binding>,
    /// Directory for the node's VTK and logs.
    pub output_dir: String,
    pub heartbeat_ms: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Reject {
    pub reason: String,
}

/// One interface a node offers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InterfaceDescription {
    pub name: String,
    /// Number of interface points.
    pub points: u64,
    /// Fields this interface can send.
    pub provides: Vec<String>,
    /// Fields this interface can take.
    pub accepts: Vec<String>,
}

/// Node → coordinator after `Welcome`: what the solver is and what it offers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Describe {
    pub model: String,
    pub interfaces: Vec<InterfaceDescription>,
    /// The solver's own stable time step, after set-up (s).
    pub stable_dt: f64,
    pub units: String,
    /// Conditions the user should know about that do not stop the run (a GPU without f64
    /// running in f32, ...): logged by the coordinator and listed in `summary.json`.
    pub warnings: Vec<String>,
}

/// Interface cell shapes for mapping (docs/architecture.md, "Mapping").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum CellKind {
    Line,
    Triangle,
    Quad,
}

impl CellKind {
    pub fn nodes(self) -> usize {
        match self {
            CellKind::Line => 2,
            CellKind::Triangle => 3,
            CellKind::Quad => 4,
        }
    }
}

/// An interface point set with optional cells, normals and weights.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct InterfaceMesh {
    pub ids: Vec<u64>,
    pub positions: Vec<[f64; 3]>,
    /// Cells over the points, all of one kind; `None` for a bare point cloud.
    pub cells: Option<Cells>,
    pub normals: Vec<[f64; 3]>,
    pub weights: Vec<f64>,
}

impl InterfaceMesh {
    pub fn points(positions: Vec<[f64; 3]>) -> Self {
        let ids = (0..positions.len() as u64).collect();
        InterfaceMesh {
            ids,
            positions,
            ..Default::default()
        }
    }
    pub fn len(&self) -> usize {
        self.positions.len()
    }
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Cells {
    pub kind: CellKind,
    /// `kind.nodes()` point indices per cell.
    pub connectivity: Vec<u32>,
}

/// Provider → peers: an interface mesh.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Mesh {
    pub coupling: String,
    pub interface: String,
    pub mesh: InterfaceMesh,
}

/// Coordinator → node: advance over `[t0, t1]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Advance {
    /// Windows count from 1; window 0 is set-up.
    pub window: u64,
    pub t0: f64,
    pub t1: f64,
    pub write_output: bool,
    pub checkpoint: bool,
}

/// A named per-point array, `components` values per point, stored flat.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Field {
    pub name: String,
    pub components: u32,
    /// Encoded as one block of little-endian bytes in binary formats, so a large field costs
    /// about a memcpy each way instead of a per-value encode; a plain list of numbers in
    /// human-readable ones (JSON).
    #[serde(with = "f64_bytes")]
    pub values: Vec<f64>,
}

/// Serde adapter: a `Vec<f64>` as one byte string of little-endian values for binary formats
/// (bincode: the length in bytes, then the bytes), as a sequence of numbers for
/// human-readable ones (`is_human_readable`), so the golden vectors' JSON shows the values.
pub mod f64_bytes {
    use serde::de::{Error, Visitor};
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
        if s.is_human_readable() {
            return s.collect_seq(v);
        }
        #[cfg(target_endian = "little")]
        {
            // SAFETY: f64 has no padding and every byte of it is initialised; the slice
            // covers exactly the vector's storage and lives as long as `v`.
            let bytes = unsafe {
                std::slice::from_raw_parts(v.as_ptr().cast::<u8>(), std::mem::size_of_val(v))
            };
            s.serialize_bytes(bytes)
        }
        #[cfg(not(target_endian = "little"))]
        {
            let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
            s.serialize_bytes(&bytes)
        }
    }

    struct V;

    impl<'de> Visitor<'de> for V {
        type Value = Vec<f64>;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("a byte string of little-endian f64 values")
        }
        fn visit_bytes<E: Error>(self, b: &[u8]) -> Result<Vec<f64>, E> {
            if !b.len().is_multiple_of(8) {
                return Err(E::custom(format!(
                    "{} bytes is not a whole number of f64 values",
                    b.len()
                )));
            }
            Ok(b.chunks_exact(8)
                .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
                .collect())
        }
        fn visit_borrowed_bytes<E: Error>(self, b: &'de [u8]) -> Result<Vec<f64>, E> {
            self.visit_bytes(b)
        }
        fn visit_byte_buf<E: Error>(self, b: Vec<u8>) -> Result<Vec<f64>, E> {
            self.visit_bytes(&b)
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        if d.is_human_readable() {
            return Vec::<f64>::deserialize(d);
        }
        d.deserialize_bytes(V)
    }
}

/// Node → peer: the fields of one coupling produced at the end of `window`
/// (window 0: at set-up).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fields {
    pub coupling: String,
    pub window: u64,
    pub time: f64,
    pub fields: Vec<Field>,
}

impl Fields {
    pub fn get(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }
}

/// What a node reports after each window (docs/architecture.md).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StepReport {
    pub kinetic_energy: f64,
    pub internal_energy: f64,
    /// Work of the node's own external loads (J).
    pub external_work: f64,
    /// Work done on the node through its coupling interfaces (J).
    pub interface_work: f64,
    /// Total linear momentum of the node (kg m/s).
    pub momentum: [f64; 3],
    /// Gross momentum of the node, Σ m|v| (kg m/s): the scale of momentum sums that cancel
    /// (a symmetric blast pushes a ring outward with a net momentum of round-off). 0 when
    /// the node does not report it.
    pub momentum_gross: f64,
    /// Impulse of the node's own external loads and supports over the run so far (N s).
    pub external_impulse: [f64; 3],
    /// Magnitude of the impulse of the node's prescribed loads so far, supports excluded
    /// (N s): the scale against which momentum balances are judged.
    pub applied_impulse: f64,
    /// Impulse received through coupling interfaces over the run so far (N s).
    pub interface_impulse: [f64; 3],
    pub substeps: u64,
    pub wall_s: f64,
    /// Time the node spent blocked on its peers' coupling data in this window, with the
    /// window's command in hand (s): load imbalance plus transport latency.
    pub coupling_wait_s: f64,
    /// Time the node waited for the coordinator's next command before this window (s): the
    /// slowest node of the previous window finishing, plus the round trip.
    pub idle_s: f64,
    /// Named extra scalars (probes, tip displacement, ...), for plots and replay reports.
    pub scalars: Vec<(String, f64)>,
}

/// Names of the `StepReport.scalars` that carry energy a node has dissipated (J, summed
/// from the start of the run, ≥ 0): the work of plastic flow and the energy released by
/// broken bonds. Reported beside the elastic `internal_energy` rather than inside it, and
/// counted by the coordinator's energy balance (as scalars, they change no byte of a message:
/// a node that does not dissipate, or does not separate it, simply leaves them out).
pub const DISSIPATED_SCALARS: [&str; 2] = ["plastic_work", "fracture_energy"];

/// Whether a `StepReport.scalars` name is a timing: wall-clock seconds (`time_…`) or a rate
/// (`…_per_s`). Timings differ from run to run, so replay does not compare them.
pub fn is_timing_scalar(name: &str) -> bool {
    name.starts_with("time_") || name.ends_with("_per_s")
}

impl StepReport {
    /// The energy the node reports as dissipated (J): the sum of its [`DISSIPATED_SCALARS`].
    pub fn dissipated(&self) -> f64 {
        self.scalars
            .iter()
            .filter(|(n, _)| DISSIPATED_SCALARS.contains(&n.as_str()))
            .map(|(_, v)| *v)
            .sum()
    }

    /// A named scalar, when the node reported it.
    pub fn scalar(&self, name: &str) -> Option<f64> {
        self.scalars
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| *v)
    }
}

/// Node → coordinator: the window is finished.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Done {
    pub window: u64,
    pub report: StepReport,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Heartbeat {
    /// Last window the node finished.
    pub window: u64,
    pub substeps: u64,
    /// The node has a window to run but is blocked on a peer's input (a deadlock shows as
    /// every node waiting).
    pub waiting: bool,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Finish {
    pub reason: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Abort {
    pub reason: String,
}

/// Coordinator → node: coupling `coupling` ends before window `window` (seed 000 §4: the
/// solid goes on alone once enough impulse is delivered). Inputs produced by the peer before
/// `window` are still consumed; nothing more is sent or expected on that coupling.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Decouple {
    pub coupling: String,
    pub window: u64,
    pub reason: String,
}

/// Node → coordinator: the node failed and says why (it then exits non-zero).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Failed {
    pub reason: String,
}

/// Every message of the protocol.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Message {
    Hello(Hello),
    Welcome(Welcome),
    Reject(Reject),
    Describe(Describe),
    Mesh(Mesh),
    Advance(Advance),
    Fields(Fields),
    Done(Done),
    Heartbeat(Heartbeat),
    Finish(Finish),
    Abort(Abort),
    Failed(Failed),
    Decouple(Decouple),
}

impl Message {
    /// Stable numeric kind carried in the envelope header.
    pub fn kind(&self) -> u8 {
        match self {
            Message::Hello(_) => 1,
            Message::Welcome(_) => 2,
            Message::Reject(_) => 3,
            Message::Describe(_) => 4,
            Message::Mesh(_) => 5,
            Message::Advance(_) => 6,
            Message::Fields(_) => 7,
            Message::Done(_) => 8,
            Message::Heartbeat(_) => 9,
            Message::Finish(_) => 10,
            Message::Abort(_) => 11,
            Message::Failed(_) => 12,
            Message::Decouple(_) => 13,
        }
    }

    /// Rust type name, used as the MCAP schema name.
    pub fn type_name(&self) -> &'static str {
        kind_name(self.kind())
    }
}

/// Schema name of a message kind.
pub fn kind_name(kind: u8) -> &'static str {
    match kind {
        1 => "cosim.Hello",
        2 => "cosim.Welcome",
        3 => "cosim.Reject",
        4 => "cosim.Describe",
        5 => "cosim.Mesh",
        6 => "cosim.Advance",
        7 => "cosim.Fields",
        8 => "cosim.Done",
        9 => "cosim.Heartbeat",
        10 => "cosim.Finish",
        11 => "cosim.Abort",
        12 => "cosim.Failed",
        13 => "cosim.Decouple",
        _ => "cosim.Unknown",
    }
}

/// Topic names (PROTOCOL.md §3).
pub mod topic {
    /// Control topic of a node, node → coordinator.
    pub fn up(run: &str, node: &str) -> String {
        format!("cosim/{run}/{node}/ctrl")
    }
    /// Control topic of a node, coordinator → node.
    pub fn down(run: &str, node: &str) -> String {
        format!("cosim/{run}/{node}/cmd")
    }
    /// Data topic of one coupling, written by `from`.
    pub fn data(run: &str, coupling: &str, from: &str) -> String {
        format!("cosim/{run}/{coupling}/{from}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bits(v: &[f64]) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    #[test]
    fn field_values_are_numbers_in_json_and_one_byte_string_in_bincode() {
        let values = vec![1.5, -0.0, 0.1 + 0.2, 5e-324, f64::MAX];
        let f = Field {
            name: "v".into(),
            components: 1,
            values: values.clone(),
        };
        let json = serde_json::to_string(&f).unwrap();
        assert_eq!(
            json,
            r#"{"name":"v","components":1,"values":[1.5,-0.0,0.30000000000000004,5e-324,1.7976931348623157e+308]}"#
        );
        let back: Field = serde_json::from_str(&json).unwrap();
        assert_eq!(bits(&back.values), bits(&values));

        let bytes = bincode::serde::encode_to_vec(&f, bincode::config::standard()).unwrap();
        // name (length 1, "v"), components 1, then the byte string: 40 bytes of f64 LE.
        let mut want = vec![1, b'v', 1, 40];
        for x in &values {
            want.extend_from_slice(&x.to_le_bytes());
        }
        assert_eq!(bytes, want);
        let (back, used): (Field, usize) =
            bincode::serde::decode_from_slice(&bytes, bincode::config::standard()).unwrap();
        assert_eq!(used, bytes.len());
        assert_eq!(bits(&back.values), bits(&values));
    }

    #[test]
    fn json_field_values_must_be_numbers() {
        for bad in [r#""AAAAAAAA8D8=""#, r#"[1.0, "2"]"#, "null"] {
            let text = format!(r#"{{"name":"v","components":1,"values":{bad}}}"#);
            assert!(
                serde_json::from_str::<Field>(&text).is_err(),
                "accepted {text}"
            );
        }
    }
}
