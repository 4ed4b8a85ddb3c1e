//! `CSolver`: the `Solver` trait over a C callback table. Each trait call makes a fresh
//! `CosimCall` holding what that callback may touch (parameters, description, mesh, the
//! runtime's inbox and outbox), runs the callback, and turns a recorded error or a non-zero
//! code into a `SolverError`.

use crate::call::CosimCall;
use crate::params::Params;
use crate::{COSIM_ABI_VERSION, CosimSolverVTable, CosimStepReport, CosimWindow};
use protocol::{
    Binding, Inbox, InterfaceMesh, NodeDescription, Outbox, Solver, SolverError, SolverResult,
    StepReport, Window,
};
use std::ffi::{CString, c_void};
use std::path::Path;

/// The solver's `user` pointer. The runtime calls the solver from one thread at a time,
/// which is all a C solver can expect of us; moving the pointer between threads is the
/// caller's promise in `cosim_node_main`.
#[derive(Clone, Copy)]
pub(crate) struct UserPtr(pub *mut c_void);

// SAFETY: see above; the pointer is only passed back to the solver's own callbacks, one call
// at a time.
unsafe impl Send for UserPtr {}

/// Refuse a vtable of another ABI version or without a required callback.
pub(crate) fn check_vtable(vt: &CosimSolverVTable) -> Result<(), String> {
    if vt.abi_version != COSIM_ABI_VERSION {
        return Err(format!(
            "vtable of ABI version {}, this library is version {COSIM_ABI_VERSION} (rebuild against its cosim_participant.h)",
            vt.abi_version
        ));
    }
    let missing: Vec<&str> = [
        ("create", vt.create.is_none()),
        ("describe", vt.describe.is_none()),
        ("interface_mesh", vt.interface_mesh.is_none()),
        ("stable_dt", vt.stable_dt.is_none()),
        ("advance", vt.advance.is_none()),
    ]
    .iter()
    .filter(|(_, m)| *m)
    .map(|(n, _)| *n)
    .collect();
    if missing.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "vtable lacks required callbacks: {}",
            missing.join(", ")
        ))
    }
}

fn c_string(s: &str, what: &str) -> SolverResult<CString> {
    CString::new(s).map_err(|_| SolverError::Other(format!("{what} '{s}' holds a NUL byte")))
}

pub(crate) struct CSolver {
    vt: CosimSolverVTable,
    user: UserPtr,
    desc: NodeDescription,
    warnings: Vec<String>,
}

impl CSolver {
    /// `create`, then `describe` (cached: a description does not change during a run).
    pub(crate) fn create(
        vt: CosimSolverVTable,
        user: UserPtr,
        model: &str,
        params: &toml::Table,
    ) -> SolverResult<Box<dyn Solver>> {
        // From here on `destroy` runs when the solver is dropped, also after a failure below.
        let mut s = CSolver {
            vt,
            user,
            desc: NodeDescription {
                model: model.to_string(),
                interfaces: Vec::new(),
                units: "SI".into(),
            },
            warnings: Vec::new(),
        };
        let (Some(create), Some(describe)) = (vt.create, vt.describe) else {
            return Err(SolverError::Other("vtable lacks create or describe".into()));
        };
        let m = c_string(model, "model")?;
        let mut call = CosimCall::new("create");
        call.params = Some(Params::new(params.clone()));
        // SAFETY: a callback of the solver's own vtable, with its own user pointer and a
        // call handle that lives across the call.
        let rc = unsafe { create(user.0, m.as_ptr(), &mut call) };
        call.finish(rc)?;
        if let Some(p) = &call.params {
            p.check_all_read()?;
        }
        s.warnings.append(&mut call.warnings);
        let mut call = CosimCall::new("describe");
        call.description = Some(s.desc.clone());
        // SAFETY: as above.
        let rc = unsafe { describe(user.0, &mut call) };
        call.finish(rc)?;
        s.warnings.append(&mut call.warnings);
        if let Some(d) = call.description.take() {
            s.desc = d;
        }
        Ok(Box::new(s))
    }
}

impl Drop for CSolver {
    fn drop(&mut self) {
        if let Some(destroy) = self.vt.destroy {
            // SAFETY: the solver's own callback, called once.
            unsafe { destroy(self.user.0) };
        }
    }
}

impl Solver for CSolver {
    fn describe(&self) -> NodeDescription {
        self.desc.clone()
    }

    fn interface(&self, name: &str) -> SolverResult<InterfaceMesh> {
        let Some(f) = self.vt.interface_mesh else {
            return Err(SolverError::interface(
                name,
                "the solver has no interface_mesh",
            ));
        };
        let n = c_string(name, "interface")?;
        let mut call = CosimCall::new("interface_mesh");
        call.mesh = Some(InterfaceMesh::default());
        // SAFETY: as in `create`.
        let rc = unsafe { f(self.user.0, n.as_ptr(), &mut call) };
        call.finish(rc)?;
        let m = call.mesh.take().unwrap_or_default();
        check_mesh(name, &m)?;
        Ok(m)
    }

    fn setup(&mut self, bindings: &[Binding], inbox: &Inbox, out: &mut Outbox) -> SolverResult<()> {
        let Some(f) = self.vt.setup else {
            return Ok(());
        };
        let mut call = CosimCall::new("setup").with_bindings(bindings)?;
        call.inbox = Some(inbox as *const Inbox);
        call.outbox = Some(out as *mut Outbox);
        // SAFETY: as in `create`; the inbox and outbox outlive the call.
        let rc = unsafe { f(self.user.0, &mut call) };
        call.finish(rc)?;
        self.warnings.append(&mut call.warnings);
        Ok(())
    }

    fn stable_dt(&self) -> f64 {
        match self.vt.stable_dt {
            // SAFETY: as in `create`.
            Some(f) => unsafe { f(self.user.0) },
            None => f64::NAN,
        }
    }

    fn advance(&mut self, w: &Window, inbox: &Inbox, out: &mut Outbox) -> SolverResult<StepReport> {
        let Some(f) = self.vt.advance else {
            return Err(SolverError::Other("the solver has no advance".into()));
        };
        let cw = CosimWindow {
            index: w.index,
            t0: w.t0,
            t1: w.t1,
            write_output: w.write_output,
        };
        let mut r = CosimStepReport::default();
        let mut call = CosimCall::new("advance");
        call.inbox = Some(inbox as *const Inbox);
        call.outbox = Some(out as *mut Outbox);
        call.scalars = Some(Vec::new());
        // SAFETY: as in `setup`; the window and report live across the call.
        let rc = unsafe { f(self.user.0, &cw, &mut call, &mut r) };
        call.finish(rc)?;
        Ok(StepReport {
            kinetic_energy: r.kinetic_energy,
            internal_energy: r.internal_energy,
            external_work: r.external_work,
            interface_work: r.interface_work,
            momentum: r.momentum,
            momentum_gross: r.momentum_gross,
            external_impulse: r.external_impulse,
            applied_impulse: r.applied_impulse,
            interface_impulse: r.interface_impulse,
            substeps: r.substeps,
            scalars: call.scalars.take().unwrap_or_default(),
            ..Default::default()
        })
    }

    fn write_output(&self, t: f64, window: u64, dir: &Path) -> SolverResult<()> {
        let Some(f) = self.vt.write_output else {
            return Ok(());
        };
        let d = c_string(&dir.to_string_lossy(), "output directory")?;
        let mut call = CosimCall::new("write_output");
        // SAFETY: as in `create`.
        let rc = unsafe { f(self.user.0, t, window, d.as_ptr(), &mut call) };
        call.finish(rc)
    }

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        let Some(f) = self.vt.save_state else {
            return Err(SolverError::Other("this solver cannot checkpoint".into()));
        };
        let mut call = CosimCall::new("save_state");
        call.state = Some(Vec::new());
        // SAFETY: as in `create`.
        let rc = unsafe { f(self.user.0, &mut call) };
        call.finish(rc)?;
        Ok(call.state.take().unwrap_or_default())
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        let Some(f) = self.vt.load_state else {
            return Err(SolverError::Other("this solver cannot restart".into()));
        };
        let mut call = CosimCall::new("load_state");
        // SAFETY: as in `create`; the bytes outlive the call.
        let rc = unsafe { f(self.user.0, bytes.as_ptr(), bytes.len(), &mut call) };
        call.finish(rc)
    }

    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }
}

/// A mesh from C must be consistent before it goes on the wire.
fn check_mesh(name: &str, m: &InterfaceMesh) -> SolverResult<()> {
    let n = m.positions.len();
    let bad = |reason: String| Err(SolverError::interface(name, reason));
    if n == 0 {
        return bad("interface_mesh gave no points (cosim_mesh_points)".into());
    }
    if m.positions.iter().flatten().any(|x| !x.is_finite()) {
        return bad("a point coordinate is not finite".into());
    }
    if !m.normals.is_empty() && m.normals.len() != n {
        return bad(format!("{} normals for {n} points", m.normals.len()));
    }
    if !m.weights.is_empty() && m.weights.len() != n {
        return bad(format!("{} weights for {n} points", m.weights.len()));
    }
    if let Some(c) = &m.cells
        && let Some(i) = c.connectivity.iter().find(|&&i| i as usize >= n)
    {
        return bad(format!("a cell names point {i} of {n}"));
    }
    Ok(())
}
