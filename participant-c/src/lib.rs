//! C ABI of the participant runtime: a solver written in C, C++, Fortran (through
//! `bind(C)`) or anything else that can call C joins a run exactly as a built-in node. The
//! solver hands [`cosim_node_main`] a table of callbacks ([`CosimSolverVTable`]) and an opaque
//! `user` pointer; the Rust runtime does the rest (command line, transport, handshake,
//! heartbeats, interface mapping, clean failure).
//!
//! During a callback the solver talks back through the [`CosimCall`] handle it receives:
//! parameters (`cosim_param_*`), its description (`cosim_describe_*`), interface meshes
//! (`cosim_mesh_*`), coupling fields (`cosim_inbox_get`, `cosim_outbox_put`: pointers into the
//! runtime's own buffers, no copies), report scalars and errors. Nothing a C caller passes can
//! panic the runtime: every entry point checks its pointers and strings and catches unwinding.
//! The header `include/cosim_participant.h` is generated from this crate by cbindgen.

mod call;
mod params;
mod solver;

pub use call::*;

use protocol::participant::node_main_with;
use solver::{CSolver, UserPtr};
use std::ffi::{CStr, OsString, c_char, c_int, c_void};
use std::os::unix::ffi::OsStringExt;

/// Version of this ABI; a vtable built against another version is refused.
pub const COSIM_ABI_VERSION: u32 = 1;

/// Which side of a coupling this node is on (docs/architecture.md).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CosimRole {
    /// Owns the interface motion, receives constraint forces.
    Driver = 0,
    /// Follows the driver's motion, returns constraint forces.
    Responder = 1,
}

/// The coupling kinds of docs/architecture.md.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CosimCouplingKind {
    Kinematic = 0,
    Immersed = 1,
    Lagrange = 2,
    Overlap = 3,
}

/// What kind of failure a callback reports with `cosim_set_error`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CosimErrorKind {
    /// Anything else.
    Other = 0,
    /// A bad parameter; `key` is its key in the node's params (`elements`, `interfaces.root`).
    Config = 1,
    /// A coupling input missing or malformed; `key` is the interface.
    Interface = 2,
}

/// Cell shapes of an interface mesh.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CosimCellKind {
    Line = 0,
    Triangle = 1,
    Quad = 2,
}

/// One coupling window `[t0, t1]`; windows count from 1.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CosimWindow {
    pub index: u64,
    pub t0: f64,
    pub t1: f64,
    /// The coordinator asks for output (`write_output` follows the window).
    pub write_output: bool,
}

/// One coupling of this node, as `setup` sees it. The strings live until the callback
/// returns.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct CosimBinding {
    pub coupling: *const c_char,
    pub kind: CosimCouplingKind,
    /// This node's interface.
    pub interface: *const c_char,
    pub role: CosimRole,
    pub peer: *const c_char,
    pub peer_interface: *const c_char,
}

/// What `advance` reports (SI units; docs/architecture.md). The runtime zeroes it before each
/// call; named scalars go through `cosim_report_scalar`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CosimStepReport {
    pub kinetic_energy: f64,
    pub internal_energy: f64,
    /// Work of the node's own external loads (J).
    pub external_work: f64,
    /// Work done on the node through its coupling interfaces (J).
    pub interface_work: f64,
    /// Total linear momentum (kg m/s).
    pub momentum: [f64; 3],
    /// Σ m|v| (kg m/s), the scale of momentum sums that cancel; 0 if not known.
    pub momentum_gross: f64,
    /// Impulse of external loads and supports over the run so far (N s).
    pub external_impulse: [f64; 3],
    /// Magnitude of the impulse of prescribed loads so far, supports excluded (N s).
    pub applied_impulse: f64,
    /// Impulse received through coupling interfaces over the run so far (N s).
    pub interface_impulse: [f64; 3],
    /// Internal steps taken in the window.
    pub substeps: u64,
}

/// A callback's result: 0 for success; anything else is a failure, explained by
/// `cosim_set_error` (or reported with the code alone).
pub type CosimStatus = c_int;

/// The solver, as callbacks. `user` is the pointer given to `cosim_node_main`, passed back
/// unchanged. Callbacks marked optional may be NULL. The runtime calls them from one thread.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct CosimSolverVTable {
    /// `COSIM_ABI_VERSION` of the header the solver was compiled with.
    pub abi_version: u32,
    /// Build the solver for `model` from its parameters (`cosim_param_*`). Every parameter the
    /// solver understands must be read here: a key it never reads is refused as unknown.
    pub create: Option<
        unsafe extern "C" fn(
            user: *mut c_void,
            model: *const c_char,
            call: *mut CosimCall,
        ) -> CosimStatus,
    >,
    /// Describe the solver: `cosim_describe_model` and one `cosim_describe_interface` per
    /// interface. Called once, after `create`.
    pub describe:
        Option<unsafe extern "C" fn(user: *mut c_void, call: *mut CosimCall) -> CosimStatus>,
    /// The point set of interface `name` (`cosim_mesh_points`, optional cells, normals,
    /// weights).
    pub interface_mesh: Option<
        unsafe extern "C" fn(
            user: *mut c_void,
            name: *const c_char,
            call: *mut CosimCall,
        ) -> CosimStatus,
    >,
    /// Optional. Once before the first window: the couplings (`cosim_binding_*`), what peers
    /// sent at set-up (`cosim_inbox_get`), and set-up fields to send (`cosim_outbox_put`).
    pub setup: Option<unsafe extern "C" fn(user: *mut c_void, call: *mut CosimCall) -> CosimStatus>,
    /// The solver's stable time step now (s).
    pub stable_dt: Option<unsafe extern "C" fn(user: *mut c_void) -> f64>,
    /// Advance from `window->t0` to exactly `window->t1`, reading inputs with
    /// `cosim_inbox_get`, writing outputs with `cosim_outbox_put`, filling `report`.
    pub advance: Option<
        unsafe extern "C" fn(
            user: *mut c_void,
            window: *const CosimWindow,
            call: *mut CosimCall,
            report: *mut CosimStepReport,
        ) -> CosimStatus,
    >,
    /// Optional. Write output for ParaView under `dir` for the state at `t` after `window`.
    pub write_output: Option<
        unsafe extern "C" fn(
            user: *mut c_void,
            t: f64,
            window: u64,
            dir: *const c_char,
            call: *mut CosimCall,
        ) -> CosimStatus,
    >,
    /// Optional. Write the complete state with `cosim_state_write` (checkpoints).
    pub save_state:
        Option<unsafe extern "C" fn(user: *mut c_void, call: *mut CosimCall) -> CosimStatus>,
    /// Optional. Restore a state written by `save_state`.
    pub load_state: Option<
        unsafe extern "C" fn(
            user: *mut c_void,
            bytes: *const u8,
            len: usize,
            call: *mut CosimCall,
        ) -> CosimStatus,
    >,
    /// Optional. The solver is no longer needed (called once, at the end).
    pub destroy: Option<unsafe extern "C" fn(user: *mut c_void)>,
}

/// Run a node: parse `argv` as a node binary does (`--run`, `--node`, `--transport`, ...),
/// join the run, and drive the solver given by `vtable` and `user` until the coordinator
/// ends the run. Returns the process exit code: 0 finished, 1 failed, 2 bad invocation or
/// bad vtable, 3 aborted by the coordinator. The vtable is copied; `user` must stay valid
/// until the call returns.
///
/// # Safety
/// `argv` must hold `argc` NUL-terminated strings (or be NULL with `argc` 0); `vtable` must
/// point to a `CosimSolverVTable` or be NULL (refused).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_node_main(
    argc: c_int,
    argv: *const *const c_char,
    vtable: *const CosimSolverVTable,
    user: *mut c_void,
) -> c_int {
    let run = std::panic::catch_unwind(|| {
        // SAFETY: the caller promises argv holds argc C strings.
        let args = unsafe { collect_args(argc, argv) };
        if vtable.is_null() {
            eprintln!("cosim_node_main: vtable is NULL");
            return 2;
        }
        // SAFETY: non-null, and the caller promises it points to a vtable; copied by value.
        let vt = unsafe { *vtable };
        if let Err(e) = solver::check_vtable(&vt) {
            eprintln!("cosim_node_main: {e}");
            return 2;
        }
        let binary = args
            .first()
            .and_then(|a| std::path::Path::new(a).file_name())
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "c-node".to_string());
        let user = UserPtr(user);
        node_main_with(
            &binary,
            args,
            Box::new(
                move |model: &str, params: &toml::Table, _: &protocol::BuildOptions| {
                    CSolver::create(vt, user, model, params)
                },
            ),
        )
    });
    match run {
        Ok(code) => code,
        Err(p) => {
            eprintln!("cosim_node_main: internal error: {}", call::panic_text(&*p));
            1
        }
    }
}

/// The solver behind `vtable` and `user` as the runtime sees it, without a run: what
/// `cosim_node_main` builds after the coordinator's `Welcome`. For Rust hosts and tests that
/// drive a C solver in-process (as replay does with built-in solvers).
pub fn solver_from_vtable(
    vtable: CosimSolverVTable,
    user: *mut c_void,
    model: &str,
    params: &toml::Table,
) -> protocol::SolverResult<Box<dyn protocol::Solver>> {
    solver::check_vtable(&vtable).map_err(protocol::SolverError::Other)?;
    CSolver::create(vtable, UserPtr(user), model, params)
}

/// The C command line as OS strings (program name first).
unsafe fn collect_args(argc: c_int, argv: *const *const c_char) -> Vec<OsString> {
    if argv.is_null() || argc <= 0 {
        return Vec::new();
    }
    (0..argc as usize)
        .filter_map(|i| {
            // SAFETY: i < argc, and the caller promises argv holds argc entries.
            let p = unsafe { *argv.add(i) };
            // SAFETY: a non-null entry is a NUL-terminated string.
            (!p.is_null())
                .then(|| OsString::from_vec(unsafe { CStr::from_ptr(p) }.to_bytes().to_vec()))
        })
        .collect()
}
