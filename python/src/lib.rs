//! The extension module `cosim._cosim` behind the Python package `cosim`: runs a solver
//! written in Python as a node on top of the Rust participant runtime (`protocol`). The user
//! writes a class; `cosim.run_node(Class)` parses the node command line, joins the run, builds
//! the solver from the coordinator's parameters and drives it window by window. Coupling
//! fields reach Python as numpy arrays that view the runtime's own buffers (no copies).
//! `cosim.open_run` reads a run's recording back (results.rs).

mod convert;
mod fields;
mod results;
mod solver;

use fields::{Inbox, Lease, Outbox};
use pyo3::prelude::*;
use solver::{Binding, PySolver, Window};

/// Run `factory` as a node: `argv` is the node command line (program first, as `sys.argv`).
/// `factory(model, params)` builds the solver once the coordinator has sent the parameters.
/// Returns the exit code (0 finished, 1 failed, 2 bad invocation, 3 aborted).
#[pyfunction]
fn run_node(py: Python<'_>, factory: Py<PyAny>, argv: Vec<String>) -> i32 {
    let binary = argv
        .first()
        .and_then(|a| std::path::Path::new(a).file_name())
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "python-node".to_string());
    // The runtime waits on the transport most of the time: let other Python threads run.
    py.detach(move || {
        let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            protocol::participant::node_main_with(
                &binary,
                argv,
                Box::new(
                    move |model: &str, params: &toml::Table, _: &protocol::BuildOptions| {
                        PySolver::create(factory, model, params)
                    },
                ),
            )
        }));
        run.unwrap_or_else(|p| {
            let text = p
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| p.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            eprintln!("{binary}: internal error: {text}");
            1
        })
    })
}

#[pymodule]
fn _cosim(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(run_node, m)?)?;
    m.add_function(wrap_pyfunction!(results::read_tables, m)?)?;
    m.add_function(wrap_pyfunction!(results::read_json_messages, m)?)?;
    m.add_function(wrap_pyfunction!(results::read_fields, m)?)?;
    m.add_class::<Inbox>()?;
    m.add_class::<Outbox>()?;
    m.add_class::<Lease>()?;
    m.add_class::<Window>()?;
    m.add_class::<Binding>()?;
    Ok(())
}
