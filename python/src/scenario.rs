//! Scenarios: the scenario parser and its validation (`crawler_physics::scenario`), fed TOML text
//! or a Python dict of the same shape.

use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use crawler_physics::execution::Briefing;
use crawler_physics::scenario::{Overrides, Scenario, ScenarioError};
use crawler_physics::wave::Wave;

use crate::{invalid, param_error, to_py};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyScenario>()?;
    m.add_function(wrap_pyfunction!(parse_toml, m)?)?;
    m.add_function(wrap_pyfunction!(read_text, m)?)?;
    Ok(())
}

/// A validated scenario (`crawler_physics::scenario::Scenario`).
#[pyclass(name = "Scenario", module = "softcrawler._native", frozen)]
pub struct PyScenario {
    pub inner: Scenario,
}

/// The dotted key on line `line` (1-based) of TOML `text`: the last section header above it and
/// the key before `=` on it.
fn key_at_line(text: &str, line: usize) -> Option<(String, String)> {
    let lines: Vec<&str> = text.lines().collect();
    let here = lines.get(line.checked_sub(1)?)?;
    let (key, value) = here.split_once('=')?;
    let key = key.trim().trim_matches('"');
    let section = lines[..line - 1]
        .iter()
        .rev()
        .map(|l| l.trim())
        .find(|l| l.starts_with('['))
        .map(|l| l.trim_matches(|c| c == '[' || c == ']').trim().to_string());
    let field = match section {
        Some(s) if !s.is_empty() => format!("{s}.{key}"),
        _ => key.to_string(),
    };
    Some((field, value.trim().to_string()))
}

/// A scenario error as the package's `InvalidInput`: a value out of range names its field; a
/// syntax error (unknown key, wrong type) names the key on the line the parser points at.
pub fn scenario_error(py: Python<'_>, e: &ScenarioError, text: &str) -> PyErr {
    match e {
        ScenarioError::Invalid { cause, .. } => param_error(py, cause),
        ScenarioError::Syntax { origin, message } => {
            let line = message
                .split("at line ")
                .nth(1)
                .and_then(|r| r.split(|c: char| !c.is_ascii_digit()).next())
                .and_then(|n| n.parse::<usize>().ok());
            let why = message.lines().last().unwrap_or(message).trim();
            // an unknown key is named by the parser itself
            let unknown = why
                .strip_prefix("unknown field `")
                .and_then(|r| r.split('`').next());
            match line.and_then(|l| key_at_line(text, l)) {
                Some((field, value)) => {
                    let field = match unknown {
                        Some(k) if !field.ends_with(k) => k.to_string(),
                        _ => field,
                    };
                    invalid(py, &field, &value, &format!("{why} (scenario {origin})"))
                }
                None => invalid(py, "scenario", origin, why),
            }
        }
        ScenarioError::Io { path, cause } => invalid(
            py,
            "scenario",
            path,
            &format!("a readable scenario file ({cause})"),
        ),
    }
}

/// A Python value (dict, list, str, bool, int, float) as a TOML value; `at` names it in errors.
fn toml_value(py: Python<'_>, v: &Bound<'_, PyAny>, at: &str) -> PyResult<toml::Value> {
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract::<bool>()?));
    }
    if v.is_instance_of::<PyInt>() {
        return match v.extract::<i64>() {
            Ok(i) => Ok(toml::Value::Integer(i)),
            Err(_) => Err(invalid(py, at, &v.to_string(), "an integer within 64 bits")),
        };
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract::<f64>()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract::<String>()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        let mut t = toml::Table::new();
        for (k, x) in d.iter() {
            let key: String = k
                .extract()
                .map_err(|_| invalid(py, at, &k.to_string(), "string keys"))?;
            let here = if at.is_empty() {
                key.clone()
            } else {
                format!("{at}.{key}")
            };
            if x.is_none() {
                continue;
            }
            t.insert(key, toml_value(py, &x, &here)?);
        }
        return Ok(toml::Value::Table(t));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let mut a = Vec::new();
        for (i, x) in v.try_iter()?.enumerate() {
            a.push(toml_value(py, &x?, &format!("{at}[{i}]"))?);
        }
        return Ok(toml::Value::Array(a));
    }
    // NumPy scalars and anything else that is a number
    if let Ok(x) = v.extract::<f64>() {
        return Ok(toml::Value::Float(x));
    }
    Err(invalid(
        py,
        if at.is_empty() { "scenario" } else { at },
        &v.repr().map(|r| r.to_string()).unwrap_or_default(),
        "a table, array, string, boolean or number (the scenario file's TOML types)",
    ))
}

/// A TOML value as Python (dicts, lists, str, bool, int, float).
fn py_value<'py>(py: Python<'py>, v: &toml::Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        toml::Value::String(s) => s.into_pyobject(py)?.into_any(),
        toml::Value::Integer(i) => i.into_pyobject(py)?.into_any(),
        toml::Value::Float(f) => f.into_pyobject(py)?.into_any(),
        toml::Value::Boolean(b) => b.into_pyobject(py)?.to_owned().into_any(),
        toml::Value::Datetime(d) => d.to_string().into_pyobject(py)?.into_any(),
        toml::Value::Array(a) => {
            let l = PyList::empty(py);
            for x in a {
                l.append(py_value(py, x)?)?;
            }
            l.into_any()
        }
        toml::Value::Table(t) => {
            let d = PyDict::new(py);
            for (k, x) in t {
                d.set_item(k, py_value(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// TOML text as a dict (the scenario file's shape); `origin` names it in errors.
#[pyfunction]
fn parse_toml<'py>(py: Python<'py>, text: &str, origin: &str) -> PyResult<Bound<'py, PyAny>> {
    match toml::from_str::<toml::Table>(text) {
        Ok(t) => py_value(py, &toml::Value::Table(t)),
        Err(e) => Err(scenario_error(
            py,
            &ScenarioError::Syntax {
                origin: origin.to_string(),
                message: e.to_string(),
            },
            text,
        )),
    }
}

/// The text of a scenario file (at most the parser's size limit).
#[pyfunction]
fn read_text(py: Python<'_>, path: std::path::PathBuf) -> PyResult<String> {
    crawler_physics::framing::read_text_at_most(
        &path,
        crawler_physics::scenario::MAX_SCENARIO_BYTES,
    )
    .map_err(|cause| {
        scenario_error(
            py,
            &ScenarioError::Io {
                path: path.display().to_string(),
                cause,
            },
            "",
        )
    })
}

fn wave_dict<'py>(py: Python<'py>, w: &Wave) -> PyResult<Bound<'py, PyAny>> {
    to_py(py, w)
}

#[pymethods]
impl PyScenario {
    /// Parses and validates TOML text as the programs read a scenario file; `origin` names it in
    /// errors.
    #[staticmethod]
    fn from_toml(py: Python<'_>, text: &str, origin: &str) -> PyResult<Self> {
        Scenario::from_toml(text, origin, &Overrides::default())
            .map(|inner| Self { inner })
            .map_err(|e| scenario_error(py, &e, text))
    }

    /// Validates a dict shaped as a scenario file (sections `body`, `friction`, `actuation`, ...).
    #[staticmethod]
    fn from_dict(py: Python<'_>, table: &Bound<'_, PyDict>, origin: &str) -> PyResult<Self> {
        let value = toml_value(py, table.as_any(), "")?;
        let text =
            toml::to_string(&value).map_err(|e| invalid(py, "scenario", origin, &e.to_string()))?;
        Self::from_toml(py, &text, origin)
    }

    /// The same scenario driven by another wave (the body stays unless `length` is given).
    #[pyo3(signature = (f0, k, omega, phase=0.0, length=None))]
    fn with_wave(
        &self,
        py: Python<'_>,
        f0: f64,
        k: f64,
        omega: f64,
        phase: f64,
        length: Option<f64>,
    ) -> PyResult<Self> {
        let wave = Wave {
            f0,
            k,
            omega,
            phase,
        };
        self.inner
            .with_wave(wave, length)
            .map(|inner| Self { inner })
            .map_err(|e| param_error(py, &e))
    }

    /// Short name.
    #[getter]
    fn name(&self) -> &str {
        &self.inner.name
    }

    /// One line of description.
    #[getter]
    fn description(&self) -> &str {
        &self.inner.description
    }

    /// End time of a run, s.
    #[getter]
    fn t_end(&self) -> f64 {
        self.inner.t_end
    }

    /// Number of cells N.
    #[getter]
    fn cells(&self) -> usize {
        self.inner.plant.numerics.cells
    }

    /// Body length L, m.
    #[getter]
    fn length(&self) -> f64 {
        self.inner.plant.length
    }

    /// `"periodic"` or `"free"`.
    #[getter]
    fn boundary(&self) -> &'static str {
        self.inner.plant.boundary.as_str()
    }

    /// The travelling wave: f0 (N), k (rad/m), omega (rad/s), phase (rad).
    #[getter]
    fn wave<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        wave_dict(py, &self.inner.wave)
    }

    /// The task: distance (m), energy (J), sigma_max (Pa), end_run.
    #[getter]
    fn task<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.inner.task)
    }

    /// The optimiser's limits: omega [min, max] (rad/s), k (rad/m), f0_max (N), strain_max.
    #[getter]
    fn limits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.inner.limits)
    }

    /// The resolved plant parameters (body, friction, length, boundary, pipe, numerics; SI).
    #[getter]
    fn plant<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.inner.plant)
    }

    /// The grid and steps: dx (m), dt (s), substeps, step H (s), courant.
    #[getter]
    fn discretisation<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let d = self
            .inner
            .plant
            .discretisation()
            .map_err(|e| param_error(py, &e))?;
        to_py(py, &d)
    }

    /// What a controller of a run of this scenario is told (`Briefing::of`): body, friction (the
    /// nominal one when the pipe is not disclosed), length, boundary, cells, step H, start time,
    /// last step, settle, disclosed.
    #[getter]
    fn briefing<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let b = Briefing::of(&self.inner).map_err(|e| param_error(py, &e))?;
        briefing_dict(py, &b)
    }

    /// The resolved scenario as JSON (every field, SI units).
    fn to_json(&self, py: Python<'_>) -> PyResult<String> {
        crate::to_json(py, &self.inner)
    }

    fn __eq__(&self, other: &Self) -> bool {
        self.inner == other.inner
    }

    fn __repr__(&self) -> String {
        format!(
            "Scenario(name={:?}, cells={}, length={} m, t_end={} s)",
            self.inner.name,
            self.inner.plant.numerics.cells,
            self.inner.plant.length,
            self.inner.t_end
        )
    }
}

/// A briefing as a dict.
pub fn briefing_dict<'py>(py: Python<'py>, b: &Briefing) -> PyResult<Bound<'py, PyAny>> {
    let d = PyDict::new(py);
    d.set_item("body", to_py(py, &b.body)?)?;
    d.set_item("friction", to_py(py, &b.friction)?)?;
    d.set_item("length", b.length)?;
    d.set_item("boundary", b.boundary.as_str())?;
    d.set_item("cells", b.cells)?;
    d.set_item("step", b.step)?;
    d.set_item("start_time", b.start_time)?;
    d.set_item("last_step", b.last_step)?;
    d.set_item("settle", b.settle)?;
    d.set_item("disclosed", b.disclosed)?;
    Ok(d.into_any())
}
