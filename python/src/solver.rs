//! `PySolver`: the `Solver` trait over a Python object. The runtime thread attaches to the
//! interpreter for each call, hands the solver `Window`, `Binding`, `Inbox` and `Outbox`
//! objects, closes them when the call returns, and turns an exception into a `SolverError`
//! carrying its traceback (the node then fails cleanly with that text).

use crate::convert::{self, py_error};
use crate::fields::{Inbox, Outbox};
use protocol::{
    Binding as RtBinding, Inbox as RtInbox, InterfaceMesh, NodeDescription, Outbox as RtOutbox,
    Role, Solver, SolverError, SolverResult, StepReport, Window as RtWindow,
};
use pyo3::intern;
use pyo3::prelude::*;
use std::path::Path;

/// One coupling window `[t0, t1]` (windows count from 1).
#[pyclass(frozen, get_all, module = "cosim")]
pub struct Window {
    pub index: u64,
    pub t0: f64,
    pub t1: f64,
    /// The coordinator asks for output after this window (`write_output` follows).
    pub write_output: bool,
}

#[pymethods]
impl Window {
    fn __repr__(&self) -> String {
        format!(
            "Window(index={}, t0={:e}, t1={:e}, write_output={})",
            self.index,
            self.t0,
            self.t1,
            if self.write_output { "True" } else { "False" }
        )
    }
}

/// One coupling of this node, as `setup` sees it.
#[pyclass(frozen, get_all, module = "cosim")]
pub struct Binding {
    pub coupling: String,
    /// "kinematic", "immersed", "lagrange" or "overlap".
    pub kind: String,
    /// This node's interface.
    pub interface: String,
    /// "driver" or "responder".
    pub role: String,
    pub peer: String,
    pub peer_interface: String,
    /// Fields this node sends every window.
    pub sends: Vec<String>,
    /// Fields this node receives every window.
    pub receives: Vec<String>,
}

#[pymethods]
impl Binding {
    fn __repr__(&self) -> String {
        format!(
            "Binding(coupling='{}', interface='{}', role='{}', peer='{}.{}')",
            self.coupling, self.interface, self.role, self.peer, self.peer_interface
        )
    }
}

/// Which optional methods the solver has.
struct Optional {
    setup: bool,
    report: bool,
    write_output: bool,
    save_state: bool,
    load_state: bool,
}

pub struct PySolver {
    obj: Py<PyAny>,
    desc: NodeDescription,
    has: Optional,
}

fn other(e: impl std::fmt::Display) -> SolverError {
    SolverError::Other(e.to_string())
}

impl PySolver {
    /// `factory(model, params)`, then `describe()` (kept: a description does not change).
    pub fn create(
        factory: Py<PyAny>,
        model: &str,
        params: &toml::Table,
    ) -> SolverResult<Box<dyn Solver>> {
        Python::attach(|py| {
            let p = convert::table_to_py(py, params).map_err(other)?;
            let obj = factory
                .call1(py, (model, p))
                .map_err(|e| py_error(py, e, "the solver's constructor"))?;
            let b = obj.bind(py);
            for m in ["describe", "interface", "stable_dt", "advance"] {
                if !b.hasattr(m).unwrap_or(false) {
                    return Err(SolverError::Other(format!(
                        "the solver object has no {m}() method"
                    )));
                }
            }
            let has = |m: &str| b.hasattr(m).unwrap_or(false);
            let has = Optional {
                setup: has("setup"),
                report: has("report"),
                write_output: has("write_output"),
                save_state: has("save_state"),
                load_state: has("load_state"),
            };
            let d = b
                .call_method0(intern!(py, "describe"))
                .map_err(|e| py_error(py, e, "describe()"))?;
            let desc = convert::description(&d, model).map_err(SolverError::Other)?;
            Ok(Box::new(PySolver {
                obj: obj.clone_ref(py),
                desc,
                has,
            }) as Box<dyn Solver>)
        })
    }
}

/// Close the call's inbox and outbox; a view kept past the call is an error.
fn close(
    py: Python<'_>,
    what: &str,
    i: &Bound<'_, Inbox>,
    o: &Bound<'_, Outbox>,
) -> SolverResult<()> {
    let a = i.borrow().close(py, what);
    let b = o.borrow().close(py, what);
    a.and(b).map_err(SolverError::Other)
}

impl Solver for PySolver {
    fn describe(&self) -> NodeDescription {
        self.desc.clone()
    }

    fn interface(&self, name: &str) -> SolverResult<InterfaceMesh> {
        Python::attach(|py| {
            let v = self
                .obj
                .call_method1(py, intern!(py, "interface"), (name,))
                .map_err(|e| py_error(py, e, &format!("interface('{name}')")))?;
            convert::mesh(py, v.bind(py), name).map_err(|r| SolverError::interface(name, r))
        })
    }

    fn setup(
        &mut self,
        bindings: &[RtBinding],
        inbox: &RtInbox,
        out: &mut RtOutbox,
    ) -> SolverResult<()> {
        if !self.has.setup {
            return Ok(());
        }
        Python::attach(|py| {
            let list = bindings
                .iter()
                .map(|b| {
                    Py::new(
                        py,
                        Binding {
                            coupling: b.coupling.clone(),
                            kind: b.kind.as_str().to_string(),
                            interface: b.interface.clone(),
                            role: match b.role {
                                Role::Driver => "driver".into(),
                                Role::Responder => "responder".into(),
                            },
                            peer: b.peer.clone(),
                            peer_interface: b.peer_interface.clone(),
                            sends: b.sends.clone(),
                            receives: b.receives.clone(),
                        },
                    )
                })
                .collect::<PyResult<Vec<_>>>()
                .map_err(other)?;
            let i = Bound::new(py, Inbox::new(inbox)).map_err(other)?;
            let o = Bound::new(py, Outbox::new(out)).map_err(other)?;
            let r = self
                .obj
                .call_method1(py, intern!(py, "setup"), (list, &i, &o));
            let r = r.map_err(|e| py_error(py, e, "setup()"));
            close(py, "setup()", &i, &o)?;
            r.map(|_| ())
        })
    }

    fn stable_dt(&self) -> f64 {
        // The trait has no error here: a failing stable_dt() reads as NaN, which the
        // coordinator refuses as a step.
        Python::attach(|py| {
            self.obj
                .call_method0(py, intern!(py, "stable_dt"))
                .and_then(|v| v.extract::<f64>(py))
                .unwrap_or_else(|e| {
                    let msg = py_error(py, e, "stable_dt()");
                    eprintln!("{msg}");
                    f64::NAN
                })
        })
    }

    fn advance(
        &mut self,
        w: &RtWindow,
        inbox: &RtInbox,
        out: &mut RtOutbox,
    ) -> SolverResult<StepReport> {
        Python::attach(|py| {
            let win = Window {
                index: w.index,
                t0: w.t0,
                t1: w.t1,
                write_output: w.write_output,
            };
            let i = Bound::new(py, Inbox::new(inbox)).map_err(other)?;
            let o = Bound::new(py, Outbox::new(out)).map_err(other)?;
            let r = self
                .obj
                .call_method1(py, intern!(py, "advance"), (win, &i, &o));
            let r = r.map_err(|e| py_error(py, e, "advance()"));
            close(py, "advance()", &i, &o)?;
            let mut r = r?.into_bound(py);
            if r.is_none() {
                if !self.has.report {
                    return Err(SolverError::Other(
                        "advance() returned None and the solver has no report()".into(),
                    ));
                }
                r = self
                    .obj
                    .call_method0(py, intern!(py, "report"))
                    .map_err(|e| py_error(py, e, "report()"))?
                    .into_bound(py);
            }
            convert::report(&r).map_err(SolverError::Other)
        })
    }

    fn write_output(&self, t: f64, window: u64, dir: &Path) -> SolverResult<()> {
        if !self.has.write_output {
            return Ok(());
        }
        Python::attach(|py| {
            self.obj
                .call_method1(
                    py,
                    intern!(py, "write_output"),
                    (t, window, dir.to_string_lossy()),
                )
                .map(|_| ())
                .map_err(|e| py_error(py, e, "write_output()"))
        })
    }

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        if !self.has.save_state {
            return Err(SolverError::Other("this solver cannot checkpoint".into()));
        }
        Python::attach(|py| {
            let v = self
                .obj
                .call_method0(py, intern!(py, "save_state"))
                .map_err(|e| py_error(py, e, "save_state()"))?;
            v.extract::<Vec<u8>>(py)
                .map_err(|_| SolverError::Other("save_state() must return bytes".into()))
        })
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        if !self.has.load_state {
            return Err(SolverError::Other("this solver cannot restart".into()));
        }
        Python::attach(|py| {
            let b = pyo3::types::PyBytes::new(py, bytes);
            self.obj
                .call_method1(py, intern!(py, "load_state"), (b,))
                .map(|_| ())
                .map_err(|e| py_error(py, e, "load_state()"))
        })
    }
}
