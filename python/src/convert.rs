//! Conversions between the runtime's Rust values and what a Python solver reads and returns:
//! parameters (TOML → dict), the description and report dictionaries (checked key by key,
//! an unknown key is refused), and Python exceptions (→ `SolverError`, with the traceback).

use protocol::{InterfaceInfo, InterfaceMesh, NodeDescription, SolverError, StepReport};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// A TOML value as the Python value a solver expects (tables are dicts).
pub fn toml_to_py<'py>(py: Python<'py>, v: &toml::Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        toml::Value::String(s) => s.into_pyobject(py)?.into_any(),
        toml::Value::Integer(i) => i.into_pyobject(py)?.into_any(),
        toml::Value::Float(x) => x.into_pyobject(py)?.into_any(),
        toml::Value::Boolean(b) => b.into_pyobject(py)?.to_owned().into_any(),
        toml::Value::Datetime(d) => d.to_string().into_pyobject(py)?.into_any(),
        toml::Value::Array(a) => {
            let l = PyList::empty(py);
            for x in a {
                l.append(toml_to_py(py, x)?)?;
            }
            l.into_any()
        }
        toml::Value::Table(t) => table_to_py(py, t)?.into_any(),
    })
}

pub fn table_to_py<'py>(py: Python<'py>, t: &toml::Table) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, v) in t {
        d.set_item(k, toml_to_py(py, v)?)?;
    }
    Ok(d)
}

/// A Python exception as the runtime's error: `cosim.ConfigError(key, reason)` and
/// `cosim.InterfaceError(interface, reason)` keep their key; anything else carries the
/// traceback, so the coordinator's message shows where the solver failed.
pub fn py_error(py: Python<'_>, e: PyErr, what: &str) -> SolverError {
    let kind = |name: &str| -> bool {
        py.import("cosim")
            .and_then(|m| m.getattr(name))
            .is_ok_and(|cls| e.get_type(py).is_subclass(&cls).unwrap_or(false))
    };
    let attr = |name: &str| -> String {
        e.value(py)
            .getattr(name)
            .and_then(|v| v.str().map(|s| s.to_string()))
            .unwrap_or_default()
    };
    if kind("ConfigError") {
        return SolverError::config(attr("key"), attr("reason"));
    }
    if kind("InterfaceError") {
        return SolverError::interface(attr("interface"), attr("reason"));
    }
    // The traceback lives in the error, not yet on the exception object.
    if let Some(tb) = e.traceback(py) {
        let _ = e.value(py).setattr("__traceback__", tb);
    }
    let tb = py
        .import("traceback")
        .and_then(|t| t.call_method1("format_exception", (e.value(py),)))
        .and_then(|l| l.extract::<Vec<String>>())
        .map(|l| l.concat())
        .unwrap_or_else(|_| e.to_string());
    SolverError::Other(format!("{what} raised {}", tb.trim_end()))
}

/// Item `key` of a dict, if present.
fn item<'py>(d: &Bound<'py, PyDict>, key: &str) -> PyResult<Option<Bound<'py, PyAny>>> {
    d.get_item(key)
}

/// Refuse a key of `d` that is not in `known`: a misspelt key must not pass silently.
fn only_known(d: &Bound<'_, PyDict>, what: &str, known: &[&str]) -> Result<(), String> {
    for k in d.keys() {
        let k: String = k
            .extract()
            .map_err(|_| format!("{what}: keys must be strings"))?;
        if !known.contains(&k.as_str()) {
            return Err(format!(
                "{what}: unknown key '{k}' (known: {})",
                known.join(", ")
            ));
        }
    }
    Ok(())
}

fn get<'py, T: FromPyObjectOwned<'py>>(
    d: &Bound<'py, PyDict>,
    key: &str,
    what: &str,
) -> Result<Option<T>, String> {
    match item(d, key).map_err(|e| e.to_string())? {
        None => Ok(None),
        Some(v) if v.is_none() => Ok(None),
        Some(v) => v.extract::<T>().map(Some).map_err(|e| {
            let e: PyErr = e.into();
            format!("{what}['{key}']: {e}")
        }),
    }
}

/// The dict `describe()` returns:
/// `{"model": str, "units": str, "interfaces": [{"name", "points", "provides", "accepts"}]}`.
pub fn description(v: &Bound<'_, PyAny>, model: &str) -> Result<NodeDescription, String> {
    let d = v
        .cast::<PyDict>()
        .map_err(|_| "describe() must return a dict".to_string())?;
    only_known(d, "describe()", &["model", "units", "interfaces"])?;
    let mut desc = NodeDescription {
        model: get::<String>(d, "model", "describe()")?.unwrap_or_else(|| model.to_string()),
        interfaces: Vec::new(),
        units: get::<String>(d, "units", "describe()")?.unwrap_or_else(|| "SI".into()),
    };
    let list = item(d, "interfaces")
        .map_err(|e| e.to_string())?
        .ok_or("describe(): no 'interfaces' list")?;
    for (i, x) in list
        .try_iter()
        .map_err(|_| "describe()['interfaces'] must be a list".to_string())?
        .enumerate()
    {
        let what = format!("describe()['interfaces'][{i}]");
        let x = x.map_err(|e| e.to_string())?;
        let e = x
            .cast::<PyDict>()
            .map_err(|_| format!("{what} must be a dict"))?;
        only_known(e, &what, &["name", "points", "provides", "accepts"])?;
        let name: String = get(e, "name", &what)?.ok_or(format!("{what}: no 'name'"))?;
        if desc.interfaces.iter().any(|f| f.name == name) {
            return Err(format!("describe(): interface '{name}' described twice"));
        }
        desc.interfaces.push(InterfaceInfo {
            points: get(e, "points", &what)?.ok_or(format!("{what}: no 'points'"))?,
            provides: get(e, "provides", &what)?.unwrap_or_default(),
            accepts: get(e, "accepts", &what)?.unwrap_or_default(),
            name,
        });
    }
    Ok(desc)
}

/// `n × 3` values from any array-like of points (numpy array, list of triples).
fn triples(py: Python<'_>, v: &Bound<'_, PyAny>, what: &str) -> Result<Vec<[f64; 3]>, String> {
    let flat: Vec<f64> = py
        .import("numpy")
        .and_then(|np| np.call_method1("asarray", (v, "float64")))
        .and_then(|a| a.call_method0("ravel"))
        .and_then(|a| a.call_method0("tolist"))
        .and_then(|l| l.extract())
        .map_err(|e| format!("{what}: {e}"))?;
    if !flat.len().is_multiple_of(3) {
        return Err(format!(
            "{what}: {} values is not a list of 3-D points",
            flat.len()
        ));
    }
    Ok(flat.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect())
}

/// What `interface(name)` returns: the points as an (n, 3) array-like, or a dict with
/// `positions` and optional `normals` and `weights`.
pub fn mesh(py: Python<'_>, v: &Bound<'_, PyAny>, name: &str) -> Result<InterfaceMesh, String> {
    let what = format!("interface('{name}')");
    let mut m = match v.cast::<PyDict>() {
        Ok(d) => {
            only_known(d, &what, &["positions", "normals", "weights"])?;
            let p = item(d, "positions")
                .map_err(|e| e.to_string())?
                .ok_or(format!("{what}: no 'positions'"))?;
            let mut m = InterfaceMesh::points(triples(py, &p, &what)?);
            if let Some(n) = item(d, "normals").map_err(|e| e.to_string())? {
                m.normals = triples(py, &n, &format!("{what}['normals']"))?;
            }
            if let Some(w) = item(d, "weights").map_err(|e| e.to_string())? {
                m.weights = py
                    .import("numpy")
                    .and_then(|np| np.call_method1("asarray", (w, "float64")))
                    .and_then(|a| a.call_method0("ravel"))
                    .and_then(|a| a.call_method0("tolist"))
                    .and_then(|l| l.extract())
                    .map_err(|e| format!("{what}['weights']: {e}"))?;
            }
            m
        }
        Err(_) => InterfaceMesh::points(triples(py, v, &what)?),
    };
    let n = m.positions.len();
    if n == 0 {
        return Err(format!("{what}: no points"));
    }
    if m.positions.iter().flatten().any(|x| !x.is_finite()) {
        return Err(format!("{what}: a coordinate is not finite"));
    }
    if !m.normals.is_empty() && m.normals.len() != n {
        return Err(format!(
            "{what}: {} normals for {n} points",
            m.normals.len()
        ));
    }
    if !m.weights.is_empty() && m.weights.len() != n {
        return Err(format!(
            "{what}: {} weights for {n} points",
            m.weights.len()
        ));
    }
    m.ids = (0..n as u64).collect();
    Ok(m)
}

const REPORT_KEYS: &[&str] = &[
    "kinetic_energy",
    "internal_energy",
    "external_work",
    "interface_work",
    "momentum",
    "momentum_gross",
    "external_impulse",
    "applied_impulse",
    "interface_impulse",
    "substeps",
    "scalars",
];

/// A 3-vector given as a sequence of three numbers.
fn vec3(d: &Bound<'_, PyDict>, key: &str) -> Result<[f64; 3], String> {
    Ok(get::<Vec<f64>>(d, key, "report")?
        .map(|v| {
            <[f64; 3]>::try_from(v.as_slice())
                .map_err(|_| format!("report['{key}'] must hold 3 numbers, got {}", v.len()))
        })
        .transpose()?
        .unwrap_or_default())
}

/// The report dict of a window (keys as `StepReport`; `scalars` a dict of named numbers).
pub fn report(v: &Bound<'_, PyAny>) -> Result<StepReport, String> {
    let d = v
        .cast::<PyDict>()
        .map_err(|_| "the report must be a dict".to_string())?;
    only_known(d, "report", REPORT_KEYS)?;
    let f = |k: &str| get::<f64>(d, k, "report").map(Option::unwrap_or_default);
    let mut scalars = Vec::new();
    if let Some(s) = item(d, "scalars").map_err(|e| e.to_string())? {
        let s = s
            .cast::<PyDict>()
            .map_err(|_| "report['scalars'] must be a dict of numbers".to_string())?;
        for (k, v) in s.iter() {
            let k: String = k
                .extract()
                .map_err(|_| "report['scalars']: names must be strings".to_string())?;
            let v: f64 = v
                .extract()
                .map_err(|_| format!("report['scalars']['{k}'] must be a number"))?;
            scalars.push((k, v));
        }
    }
    Ok(StepReport {
        kinetic_energy: f("kinetic_energy")?,
        internal_energy: f("internal_energy")?,
        external_work: f("external_work")?,
        interface_work: f("interface_work")?,
        momentum: vec3(d, "momentum")?,
        momentum_gross: f("momentum_gross")?,
        external_impulse: vec3(d, "external_impulse")?,
        applied_impulse: f("applied_impulse")?,
        interface_impulse: vec3(d, "interface_impulse")?,
        substeps: get::<u64>(d, "substeps", "report")?.unwrap_or_default(),
        scalars,
        ..Default::default()
    })
}
