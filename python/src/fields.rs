//! `Inbox` and `Outbox`: a window's coupling fields as numpy arrays that view the runtime's
//! own buffers, through the buffer protocol of a small `Lease` object (no copies). A view is
//! only valid during the call that received it: when the call returns the runtime closes the
//! inbox, outbox and every lease, and refuses to go on if a view is still alive (kept in
//! `self`, say), because the memory it points to is reused in the next window.

use protocol::FieldSet;
use pyo3::buffer::PyBuffer;
use pyo3::exceptions::{PyBufferError, PyKeyError, PyRuntimeError, PyValueError};
use pyo3::ffi;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use std::cell::{Cell, RefCell};
use std::ffi::{c_char, c_int, c_void};

/// Largest field a solver may put (values), a guard against garbage shapes.
const MAX_FIELD_VALUES: usize = 1 << 31;

/// A numpy function, looked up once.
fn numpy<'py>(
    py: Python<'py>,
    cell: &'static PyOnceLock<Py<PyAny>>,
    name: &str,
) -> PyResult<&'py Bound<'py, PyAny>> {
    cell.get_or_try_init(py, || {
        Ok::<_, PyErr>(py.import("numpy")?.getattr(name)?.unbind())
    })
    .map(|f| f.bind(py))
}

fn asarray(py: Python<'_>) -> PyResult<&Bound<'_, PyAny>> {
    static F: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
    numpy(py, &F, "asarray")
}

fn ascontiguousarray(py: Python<'_>) -> PyResult<&Bound<'_, PyAny>> {
    static F: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
    numpy(py, &F, "ascontiguousarray")
}

/// A window of memory lent to numpy: `len` f64 values at `ptr` in the runtime's buffers.
#[pyclass(unsendable, module = "cosim")]
pub struct Lease {
    ptr: *mut f64,
    len: usize,
    shape: [ffi::Py_ssize_t; 2],
    strides: [ffi::Py_ssize_t; 2],
    ndim: c_int,
    readonly: bool,
    valid: Cell<bool>,
    exports: Cell<usize>,
}

#[pymethods]
impl Lease {
    /// # Safety
    /// Called by Python with a `Py_buffer` to fill.
    unsafe fn __getbuffer__(
        slf: Bound<'_, Self>,
        view: *mut ffi::Py_buffer,
        flags: c_int,
    ) -> PyResult<()> {
        if view.is_null() {
            return Err(PyBufferError::new_err("null view"));
        }
        let me = slf.borrow();
        if !me.valid.get() {
            return Err(PyBufferError::new_err(
                "this field belongs to a finished call: copy what you keep (numpy.array(x))",
            ));
        }
        if me.readonly && (flags & ffi::PyBUF_WRITABLE) == ffi::PyBUF_WRITABLE {
            return Err(PyBufferError::new_err("received fields are read-only"));
        }
        // SAFETY: `view` is non-null and Python's to fill; shape and strides point into this
        // object, which the view keeps alive through `obj`; the format is a static string.
        unsafe {
            (*view).obj = slf.clone().into_any().into_ptr();
            (*view).buf = me.ptr.cast::<c_void>();
            (*view).len = (me.len * 8) as ffi::Py_ssize_t;
            (*view).readonly = c_int::from(me.readonly);
            (*view).itemsize = 8;
            (*view).format = if (flags & ffi::PyBUF_FORMAT) == ffi::PyBUF_FORMAT {
                c"d".as_ptr() as *mut c_char
            } else {
                std::ptr::null_mut()
            };
            (*view).ndim = me.ndim;
            (*view).shape = if (flags & ffi::PyBUF_ND) == ffi::PyBUF_ND {
                me.shape.as_ptr() as *mut ffi::Py_ssize_t
            } else {
                std::ptr::null_mut()
            };
            (*view).strides = if (flags & ffi::PyBUF_STRIDES) == ffi::PyBUF_STRIDES {
                me.strides.as_ptr() as *mut ffi::Py_ssize_t
            } else {
                std::ptr::null_mut()
            };
            (*view).suboffsets = std::ptr::null_mut();
            (*view).internal = std::ptr::null_mut();
        }
        me.exports.set(me.exports.get() + 1);
        Ok(())
    }

    /// # Safety
    /// Called by Python when a view is released.
    unsafe fn __releasebuffer__(&self, _view: *mut ffi::Py_buffer) {
        self.exports.set(self.exports.get().saturating_sub(1));
    }
}

/// The leases of one call, named for error messages.
#[derive(Default)]
struct Leases(RefCell<Vec<(String, Py<Lease>)>>);

impl Leases {
    /// A numpy array over `len` values at `ptr`: 1-D for one component, else (points, c).
    fn view<'py>(
        &self,
        py: Python<'py>,
        label: String,
        ptr: *mut f64,
        len: usize,
        components: usize,
        readonly: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let c = components.max(1);
        let points = len / c;
        let (ndim, shape, strides) = if c == 1 {
            (1, [points as isize, 0], [8, 0])
        } else {
            (2, [points as isize, c as isize], [8 * c as isize, 8])
        };
        let lease = Py::new(
            py,
            Lease {
                ptr,
                len: points * c,
                shape,
                strides,
                ndim,
                readonly,
                valid: Cell::new(true),
                exports: Cell::new(0),
            },
        )?;
        let arr = asarray(py)?.call1((lease.bind(py),))?;
        self.0.borrow_mut().push((label, lease));
        Ok(arr)
    }

    /// End the call: no lease lends memory any more; a view still alive is an error.
    fn close(&self, py: Python<'_>, what: &str) -> Result<(), String> {
        let leases = self.0.take();
        for (_, l) in &leases {
            l.borrow(py).valid.set(false);
        }
        let alive = |ls: &[(String, Py<Lease>)]| -> Vec<String> {
            ls.iter()
                .filter(|(_, l)| l.borrow(py).exports.get() > 0)
                .map(|(n, _)| n.clone())
                .collect()
        };
        if alive(&leases).is_empty() {
            return Ok(());
        }
        // A view caught in a reference cycle is not kept on purpose: collect and look again.
        if let Ok(gc) = py.import("gc") {
            let _ = gc.call_method0("collect");
        }
        let still = alive(&leases);
        if still.is_empty() {
            return Ok(());
        }
        Err(format!(
            "{what} kept a numpy view of {} after returning; that memory is reused in the next \
             window: keep a copy instead (numpy.array(x) or x.copy())",
            still.join(", ")
        ))
    }
}

/// The fields received for this call, by interface and name (read-only arrays).
#[pyclass(unsendable, module = "cosim")]
pub struct Inbox {
    set: *const FieldSet,
    open: Cell<bool>,
    leases: Leases,
}

impl Inbox {
    pub(crate) fn new(set: &FieldSet) -> Self {
        Inbox {
            set: set as *const FieldSet,
            open: Cell::new(true),
            leases: Leases::default(),
        }
    }

    fn set(&self) -> PyResult<&FieldSet> {
        if !self.open.get() {
            return Err(PyRuntimeError::new_err(
                "this inbox belongs to a finished call",
            ));
        }
        // SAFETY: the runtime made this inbox from a live `&FieldSet` for the call, and marks
        // it closed before that borrow ends.
        Ok(unsafe { &*self.set })
    }

    pub(crate) fn close(&self, py: Python<'_>, what: &str) -> Result<(), String> {
        self.open.set(false);
        self.leases.close(py, what)
    }
}

#[pymethods]
impl Inbox {
    /// `inbox[interface, name]`: the field as a read-only array; KeyError when absent.
    fn __getitem__<'py>(
        &self,
        py: Python<'py>,
        key: (String, String),
    ) -> PyResult<Bound<'py, PyAny>> {
        let (i, n) = key;
        match self.get(py, &i, &n)? {
            Some(a) => Ok(a),
            None => Err(PyKeyError::new_err(format!(
                "no field '{n}' received on interface '{i}'"
            ))),
        }
    }

    /// The field `name` of `interface` as a read-only array, or None.
    fn get<'py>(
        &self,
        py: Python<'py>,
        interface: &str,
        name: &str,
    ) -> PyResult<Option<Bound<'py, PyAny>>> {
        let Some(f) = self.set()?.get(interface, name) else {
            return Ok(None);
        };
        let a = self.leases.view(
            py,
            format!("inbox['{interface}', '{name}']"),
            f.values.as_ptr() as *mut f64,
            f.values.len(),
            f.components as usize,
            true,
        )?;
        Ok(Some(a))
    }

    fn __contains__(&self, key: (String, String)) -> PyResult<bool> {
        Ok(self.set()?.get(&key.0, &key.1).is_some())
    }

    /// Every (interface, name) received.
    fn keys(&self) -> PyResult<Vec<(String, String)>> {
        Ok(self
            .set()?
            .iter()
            .map(|(i, f)| (i.to_string(), f.name.clone()))
            .collect())
    }

    fn __repr__(&self) -> String {
        match self.keys() {
            Ok(k) => format!("Inbox({k:?})"),
            Err(_) => "Inbox(closed)".into(),
        }
    }
}

/// The fields this call sends, by interface and name (writable arrays in the runtime's
/// buffers).
#[pyclass(unsendable, module = "cosim")]
pub struct Outbox {
    set: *mut FieldSet,
    open: Cell<bool>,
    leases: Leases,
    /// (interface, name, values) put during this call: a second put must keep the size.
    sizes: RefCell<Vec<(String, String, usize)>>,
}

impl Outbox {
    pub(crate) fn new(set: &mut FieldSet) -> Self {
        Outbox {
            set: set as *mut FieldSet,
            open: Cell::new(true),
            leases: Leases::default(),
            sizes: RefCell::new(Vec::new()),
        }
    }

    pub(crate) fn close(&self, py: Python<'_>, what: &str) -> Result<(), String> {
        self.open.set(false);
        self.leases.close(py, what)
    }

    /// The buffer of (interface, name) with `points × components` values.
    fn buffer(
        &self,
        interface: &str,
        name: &str,
        points: usize,
        components: usize,
    ) -> PyResult<(*mut f64, usize)> {
        if !self.open.get() {
            return Err(PyRuntimeError::new_err(
                "this outbox belongs to a finished call",
            ));
        }
        if components == 0 || components > u32::MAX as usize {
            return Err(PyValueError::new_err(format!(
                "field '{name}': components must be ≥ 1, got {components}"
            )));
        }
        let n = points
            .checked_mul(components)
            .filter(|&n| n <= MAX_FIELD_VALUES)
            .ok_or_else(|| PyValueError::new_err(format!("field '{name}': too many values")))?;
        let mut sizes = self.sizes.borrow_mut();
        match sizes.iter().find(|(i, f, _)| i == interface && f == name) {
            Some((_, _, m)) if *m != n => {
                return Err(PyValueError::new_err(format!(
                    "field '{name}' on '{interface}' was put with {m} values in this call, now {n}"
                )));
            }
            Some(_) => {}
            None => sizes.push((interface.to_string(), name.to_string(), n)),
        }
        // SAFETY: the runtime made this outbox from a live `&mut FieldSet` for the call and
        // marks it closed before that borrow ends; the size check above keeps every buffer
        // lent in this call from being reallocated.
        let buf = unsafe { &mut *self.set }.put(interface, name, components as u32, points);
        Ok((buf.as_mut_ptr(), n))
    }
}

/// `shape`: `points` (one component per point) or `(points, components)`.
fn parse_shape(shape: &Bound<'_, PyAny>) -> PyResult<(usize, usize, bool)> {
    if let Ok(n) = shape.extract::<usize>() {
        return Ok((n, 1, true));
    }
    match shape.extract::<(usize, usize)>() {
        Ok((n, c)) => Ok((n, c, false)),
        Err(_) => Err(PyValueError::new_err(
            "shape must be a number of points or (points, components)",
        )),
    }
}

#[pymethods]
impl Outbox {
    /// A writable array of `shape` for field `name` on `interface`, to fill in place. It holds
    /// the previous window's values when the field was sent before with the same size.
    fn put<'py>(
        &self,
        py: Python<'py>,
        interface: &str,
        name: &str,
        shape: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (points, components, flat) = parse_shape(shape)?;
        let (ptr, n) = self.buffer(interface, name, points, components)?;
        let label = format!("outbox['{interface}', '{name}']");
        let a = self.leases.view(py, label, ptr, n, components, false)?;
        if flat || components == 1 {
            return Ok(a);
        }
        // (points, 1) was asked for explicitly: give that shape back.
        a.call_method1("reshape", ((points, components),))
    }

    /// `outbox[interface, name] = values`: copy an array of shape (points,) or
    /// (points, components) in.
    fn __setitem__(
        &self,
        py: Python<'_>,
        key: (String, String),
        values: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let (i, n) = key;
        let a = ascontiguousarray(py)?.call1((values, "float64"))?;
        let shape: Vec<usize> = a.getattr("shape")?.extract()?;
        let (points, components) = match shape.as_slice() {
            [p] => (*p, 1),
            [p, c] => (*p, *c),
            _ => {
                return Err(PyValueError::new_err(format!(
                    "field '{n}': values must be 1-D or 2-D (points, components), got shape {shape:?}"
                )));
            }
        };
        let (ptr, len) = self.buffer(&i, &n, points, components)?;
        let src = PyBuffer::<f64>::get(&a)?;
        // SAFETY: `buffer` returned `len` writable values; a view of them lent earlier in this
        // call is only read by Python code, which cannot run during this copy.
        let dst = unsafe { std::slice::from_raw_parts_mut(ptr, len) };
        src.copy_to_slice(py, dst)
    }

    fn __repr__(&self) -> String {
        let s = self.sizes.borrow();
        let k: Vec<String> = s
            .iter()
            .map(|(i, f, _)| format!("('{i}', '{f}')"))
            .collect();
        format!("Outbox([{}])", k.join(", "))
    }
}
