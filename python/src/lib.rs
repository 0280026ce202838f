//! `softcrawler._native`: the project's libraries bound for Python with PyO3.
//!
//! The Python package `softcrawler` (python/softcrawler/) wraps this module; everything here
//! calls the libraries the programs use (no second implementation): the scenario parser and its
//! validation, the physics crate's execution loop, the models and the optimiser, the sweep
//! library, the policies and the co-simulation client. The GIL is released while Rust computes.
//!
//! Arrays cross the boundary as `bytes` holding native-endian `f64` (or `u8` for booleans): Rust
//! writes them once into a new `bytes` object and NumPy views that object without copying
//! (`numpy.frombuffer`, read-only); arrays coming in are read from `bytes` the same way.

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyBytes, PyDict, PyList};

mod client;
mod env;
mod models;
mod plant;
mod policy;
mod scenario;
mod sweep;

/// The package's exception for an input that is not allowed: `InvalidInput(message, field,
/// value, allowed)` (python/softcrawler/errors.py).
pub(crate) fn invalid(py: Python<'_>, field: &str, value: &str, allowed: &str) -> PyErr {
    static CLS: PyOnceLock<Py<pyo3::types::PyType>> = PyOnceLock::new();
    let message = format!("invalid {field} = {value}: allowed {allowed}");
    match CLS.import(py, "softcrawler.errors", "InvalidInput") {
        Ok(cls) => match cls.call1((message.clone(), field, value, allowed)) {
            Ok(e) => PyErr::from_value(e),
            Err(e) => e,
        },
        Err(_) => pyo3::exceptions::PyValueError::new_err(message),
    }
}

/// A physics `ParamError` as the package's `InvalidInput`.
pub(crate) fn param_error(py: Python<'_>, e: &crawler_physics::ParamError) -> PyErr {
    invalid(py, &e.field, &e.value, &e.allowed)
}

/// The package's exception for a run that failed (`RunError`).
pub(crate) fn run_error(py: Python<'_>, message: String) -> PyErr {
    static CLS: PyOnceLock<Py<pyo3::types::PyType>> = PyOnceLock::new();
    match CLS.import(py, "softcrawler.errors", "RunError") {
        Ok(cls) => match cls.call1((message.clone(),)) {
            Ok(e) => PyErr::from_value(e),
            Err(e) => e,
        },
        Err(_) => PyRuntimeError::new_err(message),
    }
}

/// An error of the libraries (anyhow) as the package's exception: `InvalidInput` when it is a
/// physics `ParamError` (field, value, allowed), `RunError` otherwise.
pub(crate) fn any_error(py: Python<'_>, e: anyhow::Error) -> PyErr {
    if let Some(p) = e.downcast_ref::<crawler_physics::ParamError>() {
        return param_error(py, p);
    }
    if let Some(crawler_physics::scenario::ScenarioError::Invalid { cause, .. }) = e.downcast_ref()
    {
        return param_error(py, cause);
    }
    if let Some(crawler_models::optimizer::OptimizeError::Invalid(p)) = e.downcast_ref() {
        return param_error(py, p);
    }
    run_error(py, format!("{e:#}"))
}

/// An error of checking inputs (the network options' run id, endpoint, zenoh configuration):
/// `InvalidInput` when it is worded as every check of the project words its refusals, `invalid
/// FIELD = VALUE: allowed ...` (a flag's name given as the Python argument's, `--zenoh-config`
/// as `zenoh_config`), else as [`any_error`].
pub(crate) fn input_error(py: Python<'_>, e: anyhow::Error) -> PyErr {
    let root = e.root_cause().to_string();
    let parts = root.strip_prefix("invalid ").and_then(|rest| {
        let (head, allowed) = rest.split_once(": allowed ")?;
        let (field, value) = head.split_once(" = ")?;
        Some((
            field.trim_start_matches("--").replace('-', "_"),
            value,
            allowed,
        ))
    });
    match parts {
        Some((field, value, allowed)) => invalid(py, &field, value, allowed),
        None => any_error(py, e),
    }
}

/// `f64`s as a `bytes` object (native endianness), written once.
pub(crate) fn f64_bytes<'py>(py: Python<'py>, xs: &[f64]) -> Bound<'py, PyBytes> {
    PyBytes::new(py, bytemuck::cast_slice(xs))
}

/// Booleans as a `bytes` object of 0/1.
pub(crate) fn bool_bytes<'py>(py: Python<'py>, xs: &[bool]) -> Bound<'py, PyBytes> {
    PyBytes::new_with(py, xs.len(), |buf| {
        for (b, &x) in buf.iter_mut().zip(xs) {
            *b = x as u8;
        }
        Ok(())
    })
    .expect("bytes of a known length")
}

/// A read-only NumPy array viewing `bytes` (no copy): `numpy.frombuffer(b, dtype)`.
pub(crate) fn numpy_view<'py>(
    py: Python<'py>,
    bytes: Bound<'py, PyBytes>,
    dtype: &str,
) -> PyResult<Bound<'py, PyAny>> {
    static FROMBUFFER: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
    let f = FROMBUFFER.import(py, "numpy", "frombuffer")?;
    f.call1((bytes, dtype))
}

/// `f64`s as a read-only NumPy array (one copy, made here; NumPy views it).
pub(crate) fn f64_array<'py>(py: Python<'py>, xs: &[f64]) -> PyResult<Bound<'py, PyAny>> {
    numpy_view(py, f64_bytes(py, xs), "float64")
}

/// Booleans as a read-only NumPy array of `bool`.
pub(crate) fn bool_array<'py>(py: Python<'py>, xs: &[bool]) -> PyResult<Bound<'py, PyAny>> {
    numpy_view(py, bool_bytes(py, xs), "bool")
}

/// `f64`s read from a `bytes` object of native-endian doubles (`ndarray.tobytes()`); `field`
/// names the input in the error.
pub(crate) fn f64s_from(py: Python<'_>, field: &str, b: &[u8]) -> PyResult<Vec<f64>> {
    if !b.len().is_multiple_of(8) {
        return Err(invalid(
            py,
            field,
            &format!("{} bytes", b.len()),
            "whole float64 values (8 bytes each)",
        ));
    }
    Ok(b.chunks_exact(8)
        .map(|c| f64::from_ne_bytes(c.try_into().expect("8 bytes")))
        .collect())
}

/// A `serde_json::Value` as the Python object `json.loads` would give.
pub(crate) fn json_to_py<'py>(
    py: Python<'py>,
    v: &serde_json::Value,
) -> PyResult<Bound<'py, PyAny>> {
    use serde_json::Value;
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any(),
        Value::Number(n) => match (n.as_i64(), n.as_u64()) {
            (Some(i), _) => i.into_pyobject(py)?.into_any(),
            (_, Some(u)) => u.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(a) => {
            let l = PyList::empty(py);
            for x in a {
                l.append(json_to_py(py, x)?)?;
            }
            l.into_any()
        }
        Value::Object(o) => {
            let d = PyDict::new(py);
            for (k, x) in o {
                d.set_item(k, json_to_py(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// A serialisable value as a Python object (its JSON form: dicts, lists, numbers, strings).
pub(crate) fn to_py<'py, T: serde::Serialize>(
    py: Python<'py>,
    value: &T,
) -> PyResult<Bound<'py, PyAny>> {
    let v = serde_json::to_value(value).map_err(|e| run_error(py, e.to_string()))?;
    json_to_py(py, &v)
}

/// A serialisable value as JSON text (floats in shortest round-trip form, as the programs print
/// them with `--json`).
pub(crate) fn to_json<T: serde::Serialize>(py: Python<'_>, value: &T) -> PyResult<String> {
    serde_json::to_string(value).map_err(|e| run_error(py, e.to_string()))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("PAPER_TOML", crawler_physics::scenario::PAPER_TOML)?;
    m.add("MAX_CELLS", crawler_facts::MAX_CELLS)?;
    scenario::register(m)?;
    plant::register(m)?;
    models::register(m)?;
    sweep::register(m)?;
    policy::register(m)?;
    env::register(m)?;
    client::register(m)?;
    Ok(())
}
