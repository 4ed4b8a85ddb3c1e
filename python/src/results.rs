//! Reading a finished (or interrupted) run back into Python: the per-window tables of
//! `cosim export` and the interface fields of the coupling messages, decoded here in Rust
//! with the coordinator's own reader (restart segments and truncated files included), handed
//! to Python as raw little-endian bytes that `cosim.results` wraps in numpy arrays.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use std::path::{Path, PathBuf};

fn bytes_of(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn err(e: anyhow::Error) -> PyErr {
    PyValueError::new_err(format!("{e:#}"))
}

/// The recording of `path`: a run's output folder (its `run.mcap`) or a recording.
fn recording(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.join("run.mcap")
    } else {
        path.to_path_buf()
    }
}

/// `{table: {key: (width, bytes)}}` for `balance` and each node (`cosim export`'s columns:
/// float64, NaN where a window lacks the key), and whether the recording is complete.
#[pyfunction]
pub fn read_tables<'py>(py: Python<'py>, path: PathBuf) -> PyResult<(Bound<'py, PyDict>, bool)> {
    let rec = recording(&path);
    let (_, complete) = coordinator::record::read_json(&rec).map_err(err)?;
    let tables = coordinator::export::tables(&rec).map_err(err)?;
    let out = PyDict::new(py);
    for (name, t) in &tables {
        let cols = PyDict::new(py);
        for (key, width) in &t.columns {
            let data = bytes_of(&t.column(key, *width));
            cols.set_item(key, (*width, PyBytes::new(py, &data)))?;
        }
        out.set_item(name, cols)?;
    }
    Ok((out, complete))
}

/// Every JSON message of the recording as `(topic, log time in ns, text)` in file order
/// (restart segments read as one run).
#[pyfunction]
pub fn read_json_messages<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyList>> {
    let (msgs, _) = coordinator::record::read_json(&recording(&path)).map_err(err)?;
    let out = PyList::empty(py);
    for m in &msgs {
        let text = String::from_utf8_lossy(&m.data);
        out.append((m.topic.as_str(), m.log_time, text.as_ref()))?;
    }
    Ok(out)
}

/// The interface fields: `[(coupling, sender, field, components, points, window bytes (u64),
/// time bytes, value bytes)]`, and the names left out because their point count changes.
#[pyfunction]
pub fn read_fields<'py>(
    py: Python<'py>,
    path: PathBuf,
) -> PyResult<(Bound<'py, PyList>, Vec<String>)> {
    let (series, ragged) = coordinator::export::field_series(&recording(&path)).map_err(err)?;
    let out = PyList::empty(py);
    for s in series.values() {
        let windows: Vec<u8> = s.window.iter().flat_map(|w| w.to_le_bytes()).collect();
        out.append((
            s.coupling.as_str(),
            s.sender.as_str(),
            s.field.as_str(),
            s.components,
            s.points,
            PyBytes::new(py, &windows),
            PyBytes::new(py, &bytes_of(&s.time)),
            PyBytes::new(py, &bytes_of(&s.values)),
        ))?;
    }
    Ok((out, ragged))
}
