//! The `CosimCall` handle and the functions a C solver calls through it during a callback:
//! parameters, description, interface mesh, bindings, coupling fields, report scalars,
//! state bytes and errors. Each checks its pointers and strings, catches unwinding, and
//! records what went wrong in the call (the first error sticks), so the runtime fails the
//! callback with that reason even if the solver ignores the returned code.

use crate::params::Params;
use crate::{CosimBinding, CosimCellKind, CosimCouplingKind, CosimErrorKind, CosimRole};
use protocol::{
    Binding, CellKind, Cells, CouplingKind, FieldSet, InterfaceInfo, InterfaceMesh,
    NodeDescription, Role, SolverError,
};
use std::ffi::{CStr, CString, c_char, c_int};
use std::panic::{AssertUnwindSafe, catch_unwind};

/// Success.
pub const COSIM_OK: c_int = 0;
/// A looked-up parameter or field is not there (not an error by itself).
pub const COSIM_MISSING: c_int = 1;
/// The call failed; the reason is recorded and the callback will fail with it.
pub const COSIM_ERROR: c_int = -1;

/// Largest number of values one field may have (2³¹), a guard against garbage sizes.
const MAX_FIELD_VALUES: usize = 1 << 31;

/// The strings of one binding, kept alive for the callback.
pub(crate) struct BindingStrings {
    coupling: CString,
    kind: CosimCouplingKind,
    interface: CString,
    role: CosimRole,
    peer: CString,
    peer_interface: CString,
}

/// Opaque handle passed to every callback; valid only until the callback returns.
pub struct CosimCall {
    /// Which callback this is (for messages).
    pub(crate) what: &'static str,
    pub(crate) params: Option<Params>,
    pub(crate) description: Option<NodeDescription>,
    pub(crate) mesh: Option<InterfaceMesh>,
    pub(crate) bindings: Vec<BindingStrings>,
    pub(crate) inbox: Option<*const FieldSet>,
    pub(crate) outbox: Option<*mut FieldSet>,
    pub(crate) scalars: Option<Vec<(String, f64)>>,
    pub(crate) state: Option<Vec<u8>>,
    pub(crate) warnings: Vec<String>,
    pub(crate) error: Option<SolverError>,
    /// Strings handed out to the solver, alive until the call ends.
    keep: Vec<CString>,
}

impl CosimCall {
    /// A call handle for `what` with nothing to read or write: what a callback gets that its
    /// kind of call does not allow (for tests of careless callers).
    pub fn bare(what: &'static str) -> Self {
        Self::new(what)
    }

    /// Lend `outbox` to the call, as `advance` does (for tests).
    ///
    /// # Safety
    /// `outbox` must outlive every use of the call.
    pub unsafe fn lend_outbox(&mut self, outbox: *mut FieldSet) {
        self.outbox = Some(outbox);
    }

    /// The call's outcome for a callback that returned `code` (for tests).
    pub fn outcome(&mut self, code: c_int) -> Result<(), SolverError> {
        self.finish(code)
    }

    pub(crate) fn new(what: &'static str) -> Self {
        CosimCall {
            what,
            params: None,
            description: None,
            mesh: None,
            bindings: Vec::new(),
            inbox: None,
            outbox: None,
            scalars: None,
            state: None,
            warnings: Vec::new(),
            error: None,
            keep: Vec::new(),
        }
    }

    pub(crate) fn with_bindings(mut self, bindings: &[Binding]) -> Result<Self, SolverError> {
        let s = |x: &str| {
            CString::new(x).map_err(|_| SolverError::Other(format!("name '{x}' holds a NUL byte")))
        };
        for b in bindings {
            self.bindings.push(BindingStrings {
                coupling: s(&b.coupling)?,
                kind: match b.kind {
                    CouplingKind::Kinematic => CosimCouplingKind::Kinematic,
                    CouplingKind::Immersed => CosimCouplingKind::Immersed,
                    CouplingKind::Lagrange => CosimCouplingKind::Lagrange,
                    CouplingKind::Overlap => CosimCouplingKind::Overlap,
                },
                interface: s(&b.interface)?,
                role: match b.role {
                    Role::Driver => CosimRole::Driver,
                    Role::Responder => CosimRole::Responder,
                },
                peer: s(&b.peer)?,
                peer_interface: s(&b.peer_interface)?,
            });
        }
        Ok(self)
    }

    /// The callback's outcome: a recorded error wins, then a non-zero code.
    pub(crate) fn finish(&mut self, code: c_int) -> Result<(), SolverError> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        if code != COSIM_OK {
            return Err(SolverError::Other(format!(
                "{} returned {code} without a message (cosim_set_error)",
                self.what
            )));
        }
        Ok(())
    }

    fn fail(&mut self, e: SolverError) {
        if self.error.is_none() {
            self.error = Some(e);
        }
    }

    fn other(&self, reason: impl std::fmt::Display) -> SolverError {
        SolverError::Other(format!("{}: {reason}", self.what))
    }

    /// A C string handed out for the rest of the call.
    fn keep(&mut self, s: &str) -> Result<*const c_char, SolverError> {
        let c = CString::new(s).map_err(|_| self.other(format!("'{s}' holds a NUL byte")))?;
        let p = c.as_ptr();
        self.keep.push(c);
        Ok(p)
    }
}

/// Text of a caught panic.
pub(crate) fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic".to_string())
}

/// Run `f` on the call behind `call`: a NULL handle gives `fail`; an error is recorded in the
/// call and gives `fail`; a panic is caught, recorded and gives `fail`.
fn with_call<R: Copy>(
    call: *mut CosimCall,
    name: &str,
    fail: R,
    f: impl FnOnce(&mut CosimCall) -> Result<R, SolverError>,
) -> R {
    if call.is_null() {
        return fail;
    }
    let r = catch_unwind(AssertUnwindSafe(|| {
        // SAFETY: non-null; the runtime made it for this callback and nothing else holds it.
        let c = unsafe { &mut *call };
        f(c)
    }));
    // SAFETY: as above; the closure's borrow has ended.
    let c = unsafe { &mut *call };
    match r {
        Ok(Ok(v)) => v,
        Ok(Err(e)) => {
            c.fail(e);
            fail
        }
        Err(p) => {
            c.fail(SolverError::Other(format!(
                "{name}: internal error: {}",
                panic_text(&*p)
            )));
            fail
        }
    }
}

/// A C string argument as UTF-8.
fn text<'a>(c: &CosimCall, p: *const c_char, arg: &str) -> Result<&'a str, SolverError> {
    if p.is_null() {
        return Err(c.other(format!("{arg} is NULL")));
    }
    // SAFETY: non-null, and the C caller promises a NUL-terminated string that outlives the call.
    unsafe { CStr::from_ptr(p) }
        .to_str()
        .map_err(|_| c.other(format!("{arg} is not UTF-8")))
}

/// `n` values at `p` (NULL allowed only for n = 0).
fn values<'a, T>(c: &CosimCall, p: *const T, n: usize, arg: &str) -> Result<&'a [T], SolverError> {
    if n == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return Err(c.other(format!("{arg} is NULL")));
    }
    if n > MAX_FIELD_VALUES {
        return Err(c.other(format!("{arg}: {n} values is too many")));
    }
    // SAFETY: non-null, and the C caller promises `n` readable values.
    Ok(unsafe { std::slice::from_raw_parts(p, n) })
}

/// Report a failure from the solver: `kind` says what `key` names (a parameter key for
/// `Config`, an interface for `Interface`, nothing for `Other`: may be NULL). The callback
/// then fails with this reason, whatever it returns. The first error of a call is kept.
///
/// # Safety
/// `call` is the handle of the running callback; `key` and `message` are NULL or C strings.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_set_error(
    call: *mut CosimCall,
    kind: CosimErrorKind,
    key: *const c_char,
    message: *const c_char,
) {
    with_call(call, "cosim_set_error", (), |c| {
        let message = if message.is_null() {
            "(no message)"
        } else {
            text(c, message, "message")?
        };
        let key = if key.is_null() {
            ""
        } else {
            text(c, key, "key")?
        };
        Err(match kind {
            CosimErrorKind::Config => SolverError::config(key, message),
            CosimErrorKind::Interface => SolverError::interface(key, message),
            CosimErrorKind::Other => c.other(message),
        })
    })
}

/// A condition the user should know about that does not stop the run (logged by the
/// coordinator, listed in `summary.json`). From `create`, `describe` or `setup`.
///
/// # Safety
/// `call` is the handle of the running callback; `message` a C string.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_warn(call: *mut CosimCall, message: *const c_char) -> c_int {
    with_call(call, "cosim_warn", COSIM_ERROR, |c| {
        let m = text(c, message, "message")?.to_string();
        c.warnings.push(m);
        Ok(COSIM_OK)
    })
}

fn params(c: &mut CosimCall, key: *const c_char) -> Result<(&mut Params, String), SolverError> {
    let k = text(c, key, "key")?.to_string();
    let what = c.what;
    match c.params.as_mut() {
        Some(p) => Ok((p, k)),
        None => Err(SolverError::Other(format!(
            "{what}: parameters are read in create only"
        ))),
    }
}

/// Parameter `key` (dotted for nested tables: `interfaces.root`) as a number (an integer is
/// taken too). `COSIM_OK` with `*out` set, `COSIM_MISSING` (out untouched), or `COSIM_ERROR`
/// (wrong type: the call fails naming the key). In `create` only.
///
/// # Safety
/// `call` is the handle of the running callback; `key` a C string; `out` writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_param_f64(
    call: *mut CosimCall,
    key: *const c_char,
    out: *mut f64,
) -> c_int {
    with_call(call, "cosim_param_f64", COSIM_ERROR, |c| {
        let (p, k) = params(c, key)?;
        match p.f64(&k)? {
            Some(v) => {
                // SAFETY: the caller promises `out` is writable (checked for NULL).
                unsafe { write(out, v, "out")? };
                Ok(COSIM_OK)
            }
            None => Ok(COSIM_MISSING),
        }
    })
}

/// Parameter `key` as an integer; see `cosim_param_f64`.
///
/// # Safety
/// As `cosim_param_f64`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_param_i64(
    call: *mut CosimCall,
    key: *const c_char,
    out: *mut i64,
) -> c_int {
    with_call(call, "cosim_param_i64", COSIM_ERROR, |c| {
        let (p, k) = params(c, key)?;
        match p.i64(&k)? {
            Some(v) => {
                // SAFETY: as in cosim_param_f64.
                unsafe { write(out, v, "out")? };
                Ok(COSIM_OK)
            }
            None => Ok(COSIM_MISSING),
        }
    })
}

/// Parameter `key` as a boolean; see `cosim_param_f64`.
///
/// # Safety
/// As `cosim_param_f64`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_param_bool(
    call: *mut CosimCall,
    key: *const c_char,
    out: *mut bool,
) -> c_int {
    with_call(call, "cosim_param_bool", COSIM_ERROR, |c| {
        let (p, k) = params(c, key)?;
        match p.bool(&k)? {
            Some(v) => {
                // SAFETY: as in cosim_param_f64.
                unsafe { write(out, v, "out")? };
                Ok(COSIM_OK)
            }
            None => Ok(COSIM_MISSING),
        }
    })
}

/// Parameter `key` as a string, valid until the callback returns; see `cosim_param_f64`.
///
/// # Safety
/// As `cosim_param_f64`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_param_str(
    call: *mut CosimCall,
    key: *const c_char,
    out: *mut *const c_char,
) -> c_int {
    with_call(call, "cosim_param_str", COSIM_ERROR, |c| {
        let (p, k) = params(c, key)?;
        match p.str(&k)? {
            Some(v) => {
                let s = c.keep(&v)?;
                // SAFETY: as in cosim_param_f64.
                unsafe { write(out, s, "out")? };
                Ok(COSIM_OK)
            }
            None => Ok(COSIM_MISSING),
        }
    })
}

/// The `index`-th key (in file order) of the table parameter `key`, e.g. the interface
/// names of `interfaces = { root = "left" }`; `COSIM_MISSING` past the last one.
///
/// # Safety
/// As `cosim_param_f64`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_param_table_key(
    call: *mut CosimCall,
    key: *const c_char,
    index: usize,
    out: *mut *const c_char,
) -> c_int {
    with_call(call, "cosim_param_table_key", COSIM_ERROR, |c| {
        let (p, k) = params(c, key)?;
        match p.table_key(&k, index)? {
            Some(v) => {
                let s = c.keep(&v)?;
                // SAFETY: as in cosim_param_f64.
                unsafe { write(out, s, "out")? };
                Ok(COSIM_OK)
            }
            None => Ok(COSIM_MISSING),
        }
    })
}

/// Write through an out pointer, refusing NULL.
unsafe fn write<T>(out: *mut T, v: T, arg: &str) -> Result<(), SolverError> {
    if out.is_null() {
        return Err(SolverError::Other(format!("{arg} is NULL")));
    }
    // SAFETY: non-null; the caller of the exported function promises it is writable.
    unsafe { out.write(v) };
    Ok(())
}

/// Split a comma-separated list of field names.
fn names(s: &str) -> Vec<String> {
    s.split(',')
        .map(str::trim)
        .filter(|x| !x.is_empty())
        .map(str::to_string)
        .collect()
}

/// The solver's model name and units (`"SI"` unless set). In `describe` only.
///
/// # Safety
/// `call` is the handle of the running callback; `model` a C string; `units` NULL or a C
/// string.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_describe_model(
    call: *mut CosimCall,
    model: *const c_char,
    units: *const c_char,
) -> c_int {
    with_call(call, "cosim_describe_model", COSIM_ERROR, |c| {
        let model = text(c, model, "model")?.to_string();
        let units = if units.is_null() {
            None
        } else {
            Some(text(c, units, "units")?.to_string())
        };
        let d = c
            .description
            .as_mut()
            .ok_or_else(|| SolverError::Other("cosim_describe_model: in describe only".into()))?;
        d.model = model;
        if let Some(u) = units {
            d.units = u;
        }
        Ok(COSIM_OK)
    })
}

/// One interface the solver offers: its name, number of points, and the fields it provides
/// and accepts as comma-separated names (`"position,velocity,force"`). In `describe` only.
///
/// # Safety
/// `call` is the handle of the running callback; the strings are C strings.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_describe_interface(
    call: *mut CosimCall,
    name: *const c_char,
    points: usize,
    provides: *const c_char,
    accepts: *const c_char,
) -> c_int {
    with_call(call, "cosim_describe_interface", COSIM_ERROR, |c| {
        let name = text(c, name, "name")?.to_string();
        let provides = names(text(c, provides, "provides")?);
        let accepts = names(text(c, accepts, "accepts")?);
        let d = c.description.as_mut().ok_or_else(|| {
            SolverError::Other("cosim_describe_interface: in describe only".into())
        })?;
        if d.interfaces.iter().any(|i| i.name == name) {
            return Err(SolverError::Other(format!(
                "describe: interface '{name}' described twice"
            )));
        }
        d.interfaces.push(InterfaceInfo {
            name,
            points,
            provides,
            accepts,
        });
        Ok(COSIM_OK)
    })
}

fn mesh<'a>(c: &'a mut CosimCall, name: &str) -> Result<&'a mut InterfaceMesh, SolverError> {
    c.mesh
        .as_mut()
        .ok_or_else(|| SolverError::Other(format!("{name}: in interface_mesh only")))
}

/// The interface's points: `n` points as `3n` coordinates (x0, y0, z0, x1, ...), copied.
/// In `interface_mesh` only.
///
/// # Safety
/// `call` is the handle of the running callback; `xyz` holds `3n` readable values.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_mesh_points(
    call: *mut CosimCall,
    xyz: *const f64,
    n: usize,
) -> c_int {
    with_call(call, "cosim_mesh_points", COSIM_ERROR, |c| {
        let v = values(c, xyz, n.saturating_mul(3), "xyz")?;
        let pts: Vec<[f64; 3]> = v.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
        let m = mesh(c, "cosim_mesh_points")?;
        m.ids = (0..n as u64).collect();
        m.positions = pts;
        Ok(COSIM_OK)
    })
}

/// Optional unit normals at the points (`3n` values, after `cosim_mesh_points`).
///
/// # Safety
/// As `cosim_mesh_points`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_mesh_normals(
    call: *mut CosimCall,
    xyz: *const f64,
    n: usize,
) -> c_int {
    with_call(call, "cosim_mesh_normals", COSIM_ERROR, |c| {
        let v = values(c, xyz, n.saturating_mul(3), "xyz")?;
        let normals: Vec<[f64; 3]> = v.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
        mesh(c, "cosim_mesh_normals")?.normals = normals;
        Ok(COSIM_OK)
    })
}

/// Optional weights (areas, lumped masses) at the points (`n` values).
///
/// # Safety
/// As `cosim_mesh_points`, with `n` values.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_mesh_weights(
    call: *mut CosimCall,
    w: *const f64,
    n: usize,
) -> c_int {
    with_call(call, "cosim_mesh_weights", COSIM_ERROR, |c| {
        let v = values(c, w, n, "w")?.to_vec();
        mesh(c, "cosim_mesh_weights")?.weights = v;
        Ok(COSIM_OK)
    })
}

/// Optional cells over the points, all of `kind`: `cells × (2, 3 or 4)` point indices.
///
/// # Safety
/// As `cosim_mesh_points`, with `cells × nodes-per-cell` readable indices.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_mesh_cells(
    call: *mut CosimCall,
    kind: CosimCellKind,
    connectivity: *const u32,
    cells: usize,
) -> c_int {
    with_call(call, "cosim_mesh_cells", COSIM_ERROR, |c| {
        let kind = match kind {
            CosimCellKind::Line => CellKind::Line,
            CosimCellKind::Triangle => CellKind::Triangle,
            CosimCellKind::Quad => CellKind::Quad,
        };
        let v = values(
            c,
            connectivity,
            cells.saturating_mul(kind.nodes()),
            "connectivity",
        )?
        .to_vec();
        mesh(c, "cosim_mesh_cells")?.cells = Some(Cells {
            kind,
            connectivity: v,
        });
        Ok(COSIM_OK)
    })
}

/// Number of couplings of this node (in `setup`; 0 elsewhere).
///
/// # Safety
/// `call` is the handle of the running callback.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_binding_count(call: *mut CosimCall) -> usize {
    with_call(call, "cosim_binding_count", 0, |c| Ok(c.bindings.len()))
}

/// The `index`-th coupling of this node; its strings live until the callback returns.
///
/// # Safety
/// `call` is the handle of the running callback; `out` writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_binding_get(
    call: *mut CosimCall,
    index: usize,
    out: *mut CosimBinding,
) -> c_int {
    with_call(call, "cosim_binding_get", COSIM_ERROR, |c| {
        let Some(b) = c.bindings.get(index) else {
            return Ok(COSIM_MISSING);
        };
        let v = CosimBinding {
            coupling: b.coupling.as_ptr(),
            kind: b.kind,
            interface: b.interface.as_ptr(),
            role: b.role,
            peer: b.peer.as_ptr(),
            peer_interface: b.peer_interface.as_ptr(),
        };
        // SAFETY: the caller promises `out` is writable (checked for NULL).
        unsafe { write(out, v, "out")? };
        Ok(COSIM_OK)
    })
}

/// A field received on `interface` (in this solver's point layout): a pointer to its values
/// in the runtime's buffer (no copy), valid until the callback returns, with
/// `*components` per point and `*len` values in all. NULL when absent (not an error; a
/// field the solver needs and misses should be reported with `cosim_set_error`).
/// In `setup` and `advance`.
///
/// # Safety
/// `call` is the handle of the running callback; the strings are C strings; `components`
/// and `len` are NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_inbox_get(
    call: *mut CosimCall,
    interface: *const c_char,
    name: *const c_char,
    components: *mut u32,
    len: *mut usize,
) -> *const f64 {
    with_call(call, "cosim_inbox_get", std::ptr::null(), |c| {
        let i = text(c, interface, "interface")?;
        let n = text(c, name, "name")?;
        let inbox = c.inbox.ok_or_else(|| {
            SolverError::Other("cosim_inbox_get: in setup and advance only".into())
        })?;
        // SAFETY: the runtime set this pointer from a live `&FieldSet` for this callback.
        let Some(f) = unsafe { &*inbox }.get(i, n) else {
            return Ok(std::ptr::null());
        };
        if !components.is_null() {
            // SAFETY: non-null; the caller promises it is writable.
            unsafe { components.write(f.components) };
        }
        if !len.is_null() {
            // SAFETY: as above.
            unsafe { len.write(f.values.len()) };
        }
        Ok(f.values.as_ptr())
    })
}

/// A writable buffer of `points × components` values for field `name` on `interface`, in
/// the runtime's outbox (no copy): fill it before the callback returns. It holds the
/// previous window's values when the field was sent before with the same size. NULL on
/// error (recorded). In `setup` and `advance`.
///
/// # Safety
/// `call` is the handle of the running callback; the strings are C strings. The pointer is
/// valid until the callback returns or the same field is put again with another size.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_outbox_put(
    call: *mut CosimCall,
    interface: *const c_char,
    name: *const c_char,
    components: u32,
    points: usize,
) -> *mut f64 {
    with_call(call, "cosim_outbox_put", std::ptr::null_mut(), |c| {
        let i = text(c, interface, "interface")?;
        let n = text(c, name, "name")?;
        if components == 0 {
            return Err(c.other(format!("field '{n}': components must be ≥ 1")));
        }
        if points.saturating_mul(components as usize) > MAX_FIELD_VALUES {
            return Err(c.other(format!("field '{n}': {points} points is too many")));
        }
        let outbox = c.outbox.ok_or_else(|| {
            SolverError::Other("cosim_outbox_put: in setup and advance only".into())
        })?;
        // SAFETY: the runtime set this pointer from a live `&mut FieldSet` for this callback,
        // and no other reference to it is used while the callback runs.
        let buf = unsafe { &mut *outbox }.put(i, n, components, points);
        Ok(buf.as_mut_ptr())
    })
}

/// A named scalar of this window's report (a probe such as `tip_displacement`). In
/// `advance` only.
///
/// # Safety
/// `call` is the handle of the running callback; `name` a C string.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_report_scalar(
    call: *mut CosimCall,
    name: *const c_char,
    value: f64,
) -> c_int {
    with_call(call, "cosim_report_scalar", COSIM_ERROR, |c| {
        let n = text(c, name, "name")?.to_string();
        let s = c
            .scalars
            .as_mut()
            .ok_or_else(|| SolverError::Other("cosim_report_scalar: in advance only".into()))?;
        s.push((n, value));
        Ok(COSIM_OK)
    })
}

/// Append `len` bytes to the state being saved. In `save_state` only.
///
/// # Safety
/// `call` is the handle of the running callback; `bytes` holds `len` readable bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn cosim_state_write(
    call: *mut CosimCall,
    bytes: *const u8,
    len: usize,
) -> c_int {
    with_call(call, "cosim_state_write", COSIM_ERROR, |c| {
        let b = values(c, bytes, len, "bytes")?;
        let s = c
            .state
            .as_mut()
            .ok_or_else(|| SolverError::Other("cosim_state_write: in save_state only".into()))?;
        s.extend_from_slice(b);
        Ok(COSIM_OK)
    })
}
