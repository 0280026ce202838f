//! Python policies as the libraries' `Policy`: one adapter, used by the in-process closed loop
//! (`run_policy`, the execution loop) and by the co-simulation client (`client.rs`), so a Python
//! policy drives both routes through the same code and gives the same bits.

use std::sync::{Arc, Mutex};

use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyBytes, PyDict, PyTuple};

use crawler_physics::execution::{Actuation, Observation};
use crawler_physics::scenario::Scenario;
use crawler_physics::wave::Wave;
use crawler_policies::{Context, Params, Policy};

use crate::scenario::PyScenario;
use crate::{any_error, bool_array, f64_array, invalid, to_json, to_py};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyObservation>()?;
    m.add_function(wrap_pyfunction!(run_policy, m)?)?;
    m.add_function(wrap_pyfunction!(policies, m)?)?;
    m.add_function(wrap_pyfunction!(context, m)?)?;
    Ok(())
}

/// What a controller sees at the start of a communication step (a copy of the plant's state at
/// that instant; its arrays are read-only NumPy views of that copy).
#[pyclass(name = "Observation", module = "softcrawler._native", frozen)]
pub struct PyObservation {
    /// Communication step n.
    #[pyo3(get)]
    pub step: u64,
    /// Time, s.
    #[pyo3(get)]
    pub time: f64,
    pub u: Vec<f64>,
    pub vel: Vec<f64>,
    pub tension: Vec<f64>,
    pub stuck: Vec<bool>,
    /// Mean speed of the body over the last step, m/s.
    #[pyo3(get)]
    pub mean_speed: f64,
    /// Input power of the actuator over the last step, W.
    #[pyo3(get)]
    pub input_power: f64,
}

impl PyObservation {
    pub fn of(obs: &Observation<'_>) -> Self {
        Self {
            step: obs.step,
            time: obs.time,
            u: obs.u.to_vec(),
            vel: obs.vel.to_vec(),
            tension: obs.tension.to_vec(),
            stuck: obs.stuck.to_vec(),
            mean_speed: obs.mean_speed,
            input_power: obs.input_power,
        }
    }

    pub fn view(&self) -> Observation<'_> {
        Observation {
            step: self.step,
            time: self.time,
            u: &self.u,
            vel: &self.vel,
            tension: &self.tension,
            stuck: &self.stuck,
            mean_speed: self.mean_speed,
            input_power: self.input_power,
        }
    }
}

#[pymethods]
impl PyObservation {
    /// Displacement at the nodes, m.
    #[getter]
    fn u<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        f64_array(py, &self.u)
    }

    /// Velocity at the nodes, m/s.
    #[getter]
    fn vel<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        f64_array(py, &self.vel)
    }

    /// Tension at the half nodes, N.
    #[getter]
    fn tension<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        f64_array(py, &self.tension)
    }

    /// Nodes held by static friction.
    #[getter]
    fn stuck<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        bool_array(py, &self.stuck)
    }

    fn __repr__(&self) -> String {
        format!(
            "Observation(step={}, time={} s, cells={}, mean_speed={} m/s, input_power={} W)",
            self.step,
            self.time,
            self.u.len(),
            self.mean_speed,
            self.input_power
        )
    }
}

/// What a Python policy is told when it starts: the briefing (the plant as a controller is told
/// it) and its own scenario's task, limits and wave.
pub fn context_dict<'py>(py: Python<'py>, ctx: &Context) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("body", to_py(py, &ctx.body)?)?;
    d.set_item("friction", to_py(py, &ctx.friction)?)?;
    d.set_item("length", ctx.length)?;
    d.set_item("boundary", ctx.boundary.as_str())?;
    d.set_item("cells", ctx.cells)?;
    d.set_item("step", ctx.step)?;
    d.set_item("disclosed", ctx.scenario.plant.pipe.disclose)?;
    d.set_item("settle", ctx.scenario.plant.numerics.settle)?;
    d.set_item("task", to_py(py, &ctx.scenario.task)?)?;
    d.set_item("limits", to_py(py, &ctx.scenario.limits)?)?;
    d.set_item("wave", to_py(py, &ctx.scenario.wave)?)?;
    d.set_item(
        "scenario",
        PyScenario {
            inner: ctx.scenario.clone(),
        },
    )?;
    Ok(d)
}

/// A Python object with `act(observation)` as a `Policy`. Its `reset(context)`, if it has one,
/// is called when it is built. An exception inside the policy stops the run: the adapter answers
/// a refused actuation, and the exception is kept for the caller ([`PyPolicy::take_error`]).
pub struct PyPolicy {
    obj: Py<PyAny>,
    name: String,
    error: Arc<Mutex<Option<PyErr>>>,
    /// Told when the policy raised (the client stops at once).
    pub on_error: Option<crossbeam_channel::Sender<crawler_controller::client::Interrupt>>,
}

impl PyPolicy {
    /// The adapter of `obj`, told `ctx` (its `reset(context)` is called if it has one).
    pub fn new(py: Python<'_>, obj: Py<PyAny>, ctx: &Context) -> PyResult<Self> {
        let o = obj.bind(py);
        if o.hasattr("reset")? {
            o.call_method1("reset", (context_dict(py, ctx)?,))?;
        }
        let name = match o.getattr("name") {
            Ok(n) if n.extract::<String>().is_ok() => n.extract::<String>()?,
            _ => o.get_type().name()?.to_string(),
        };
        Ok(Self {
            obj,
            name,
            error: Arc::new(Mutex::new(None)),
            on_error: None,
        })
    }

    /// The exception the policy raised, if any.
    pub fn take_error(&self) -> Option<PyErr> {
        self.error.lock().ok().and_then(|mut e| e.take())
    }

    /// Keeps the exception the policy raises in `slot` (shared with the caller: the policy may
    /// be moved into a client).
    pub fn keep_errors_in(&mut self, slot: Arc<Mutex<Option<PyErr>>>) {
        self.error = slot;
    }

    fn call(&self, py: Python<'_>, obs: &Observation<'_>) -> PyResult<Actuation> {
        static NORMALISE: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
        let normalise = NORMALISE.import(py, "softcrawler.policy", "_actuation")?;
        let o = Py::new(py, PyObservation::of(obs))?;
        let a = normalise.call1((self.obj.bind(py), o))?;
        if let Ok(b) = a.cast::<PyBytes>() {
            return Ok(Actuation::Field(crate::f64s_from(
                py,
                "action",
                b.as_bytes(),
            )?));
        }
        let t = a.cast::<PyTuple>()?;
        let (f0, k, omega, phase): (f64, f64, f64, f64) = t.extract()?;
        Ok(Actuation::Wave(Wave {
            f0,
            k,
            omega,
            phase,
        }))
    }
}

impl Policy for PyPolicy {
    fn name(&self) -> &str {
        &self.name
    }

    fn act(&mut self, obs: &Observation) -> Actuation {
        if self.error.lock().map(|e| e.is_some()).unwrap_or(true) {
            return refused(obs.u.len());
        }
        let out = Python::attach(|py| self.call(py, obs));
        match out {
            Ok(a) => a,
            Err(e) => {
                if let Ok(mut slot) = self.error.lock() {
                    *slot = Some(e);
                }
                if let Some(tx) = &self.on_error {
                    let _ = tx.send(crawler_controller::client::Interrupt);
                }
                refused(obs.u.len())
            }
        }
    }

    fn describe(&self) -> String {
        format!("{} (Python)", self.name)
    }
}

/// An actuation every plant refuses (a non-finite force): it stops the run at the step the
/// policy failed.
fn refused(cells: usize) -> Actuation {
    Actuation::Field(vec![f64::NAN; cells.max(1)])
}

/// Runs a policy against the in-process plant of `scenario` through the execution loop (the
/// loop the co-simulation runs, so the same bits): `policy` is a registered name (with
/// `params`, `KEY=VALUE`) or a Python object with `act(observation)`. Returns the report as JSON
/// and the number of communication steps.
#[pyfunction]
#[pyo3(signature = (scenario, policy, params=Vec::new()))]
fn run_policy(
    py: Python<'_>,
    scenario: &PyScenario,
    policy: &Bound<'_, PyAny>,
    params: Vec<String>,
) -> PyResult<(String, u64)> {
    let s: Scenario = scenario.inner.clone();
    if let Ok(name) = policy.extract::<String>() {
        let params = checked_params(py, &name, &params)?;
        let run = py
            .detach(|| crawler_policies::in_process::run_named(&s, &name, &params))
            .map_err(|e| any_error(py, e))?;
        return Ok((to_json(py, &run.report)?, run.steps));
    }
    let ctx = Context::of(&s).map_err(|e| crate::param_error(py, &e))?;
    let mut p = PyPolicy::new(py, policy.clone().unbind(), &ctx)?;
    let run = py.detach(|| crawler_policies::in_process::run(&s, &mut p));
    if let Some(e) = p.take_error() {
        return Err(e);
    }
    let run = run.map_err(|e| any_error(py, e.into()))?;
    Ok((to_json(py, &run.report)?, run.steps))
}

/// The parameters `KEY=VALUE` of the registered policy `name`, parsed and checked by the
/// policy's own check: an unknown policy is an `InvalidInput` of field `policy`, a parameter it
/// does not take or a bad value one of field `params`.
pub(crate) fn checked_params(py: Python<'_>, name: &str, params: &[String]) -> PyResult<Params> {
    let names = || {
        crawler_policies::REGISTRY
            .iter()
            .map(|e| e.name)
            .collect::<Vec<_>>()
            .join(", ")
    };
    if crawler_policies::REGISTRY.iter().all(|e| e.name != name) {
        return Err(invalid(
            py,
            "policy",
            name,
            &format!("a registered policy ({})", names()),
        ));
    }
    let shown = format!("{params:?}");
    let parsed =
        Params::parse(params).map_err(|e| invalid(py, "params", &shown, &format!("{e:#}")))?;
    crawler_policies::check(name, &parsed)
        .map_err(|e| invalid(py, "params", &shown, &format!("{e:#}")))?;
    Ok(parsed)
}

/// What a policy of a run of `scenario` is told when it starts (the `context` of its
/// `reset`): the briefing with the scenario's task, limits and wave.
#[pyfunction]
fn context<'py>(py: Python<'py>, scenario: &PyScenario) -> PyResult<Bound<'py, PyDict>> {
    let ctx = Context::of(&scenario.inner).map_err(|e| crate::param_error(py, &e))?;
    context_dict(py, &ctx)
}

/// A registered policy: name, one line of help, [(parameter, doc)].
type PolicyEntry = (String, String, Vec<(String, String)>);

/// The registered policies.
#[pyfunction]
fn policies() -> Vec<PolicyEntry> {
    crawler_policies::REGISTRY
        .iter()
        .map(|e| {
            (
                e.name.to_string(),
                e.help.to_string(),
                e.keys
                    .iter()
                    .map(|k| (k.name.to_string(), k.doc.to_string()))
                    .collect(),
            )
        })
        .collect()
}
