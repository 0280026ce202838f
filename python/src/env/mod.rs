//! The reinforcement-learning environment's core: the paper's task (travel D on J0 under
//! sigma_max) run by the physics crate's execution loop, with what a real crawler could sense
//! ([`Sensor`]) and two ways to act ([`Actuator`]). The Gymnasium classes (python/softcrawler/env.py)
//! wrap [`PyEnvCore`] (one crawler) and [`PyVecCore`] (many, stepped across threads in one call).
//!
//! The sensor and the actuator are built from what a controller is told (`Context`, from the
//! scenario's `Briefing`), never from the plant's true friction; a policy trained here drives the
//! co-simulation through the same two objects ([`PySensor`], [`PyActuator`]), so its decisions
//! are the same bits on every route.

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};
use rayon::prelude::*;

use crawler_physics::execution::Actuation;

use crate::policy::PyObservation;
use crate::scenario::PyScenario;
use crate::{f64_bytes, f64s_from, invalid, run_error};

mod act;
mod episode;
mod sense;

pub use act::Actuator;
use episode::{build, layout, option_error, options, EnvCore, EnvOptions, StepResult};
pub use sense::{context_of_told, default_fields, Sensor, FIELDS};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyEnvCore>()?;
    m.add_class::<PyVecCore>()?;
    m.add_class::<PySensor>()?;
    m.add_class::<PyActuator>()?;
    m.add("FIELDS", FIELDS.iter().map(|f| f.0).collect::<Vec<_>>())?;
    Ok(())
}

/// One crawler on the paper's task (the Gymnasium environment's core).
#[pyclass(name = "EnvCore", module = "softcrawler._native")]
pub struct PyEnvCore {
    opts: EnvOptions,
    env: EnvCore,
    obs: Vec<f64>,
}

#[pymethods]
impl PyEnvCore {
    #[new]
    #[pyo3(signature = (scenario, action="wave", segments=8, fields=vec![], frame_skip=1, stress_weight=10.0))]
    fn new(
        py: Python<'_>,
        scenario: &PyScenario,
        action: &str,
        segments: usize,
        fields: Vec<String>,
        frame_skip: u64,
        stress_weight: f64,
    ) -> PyResult<Self> {
        let opts = options(py, action, segments, fields, frame_skip, stress_weight)?;
        let env = build(py, &scenario.inner, &opts)?;
        Ok(Self {
            opts,
            env,
            obs: Vec::new(),
        })
    }

    /// Spaces and names: obs_names, obs_low, obs_high, act_low, act_high, step (s per env step).
    fn layout<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        layout(py, &self.env)
    }

    /// A new episode of `scenario`; its first observation (float64 bytes).
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        scenario: &PyScenario,
    ) -> PyResult<Bound<'py, PyBytes>> {
        self.env = build(py, &scenario.inner, &self.opts)?;
        self.obs.clear();
        self.env.observe(&mut self.obs);
        Ok(f64_bytes(py, &self.obs))
    }

    /// Applies the action (float64 bytes) over the environment's step: (observation bytes,
    /// reward, terminated, truncated, info).
    fn step<'py>(&mut self, py: Python<'py>, action: &[u8]) -> PyResult<Bound<'py, PyTuple>> {
        let a = f64s_from(py, "action", action)?;
        let env = &mut self.env;
        let obs = &mut self.obs;
        let r = py.detach(|| {
            let r = env.step(&a)?;
            obs.clear();
            env.observe(obs);
            Ok::<_, String>(r)
        });
        let r = r.map_err(|e| option_error(py, &e))?;
        (
            f64_bytes(py, &self.obs),
            r.reward,
            r.terminated,
            r.truncated,
            self.env.info(py)?,
        )
            .into_pyobject(py)
    }

    /// The plant's report of the episode so far (task included), as JSON.
    fn report_json(&self, py: Python<'_>) -> PyResult<String> {
        let r = self
            .env
            .run
            .report()
            .map_err(|e| run_error(py, e.to_string()))?;
        crate::to_json(py, &r)
    }

    /// CRC-32 of the plant's displacement and velocity bits and step count.
    #[getter]
    fn state_digest(&self) -> String {
        crawler_physics::report::state_digest(self.env.run.plant())
    }
}

/// Many crawlers on the task, stepped across threads in one call.
#[pyclass(name = "VecCore", module = "softcrawler._native")]
pub struct PyVecCore {
    opts: EnvOptions,
    envs: Vec<EnvCore>,
}

#[pymethods]
impl PyVecCore {
    /// `scenarios[i]` is crawler i's first episode.
    #[new]
    #[pyo3(signature = (scenarios, action="wave", segments=8, fields=vec![], frame_skip=1, stress_weight=10.0))]
    fn new(
        py: Python<'_>,
        scenarios: Vec<PyRef<'_, PyScenario>>,
        action: &str,
        segments: usize,
        fields: Vec<String>,
        frame_skip: u64,
        stress_weight: f64,
    ) -> PyResult<Self> {
        if scenarios.is_empty() {
            return Err(invalid(py, "num_envs", "0", "1 or more environments"));
        }
        let opts = options(py, action, segments, fields, frame_skip, stress_weight)?;
        let envs = scenarios
            .iter()
            .map(|s| build(py, &s.inner, &opts))
            .collect::<PyResult<Vec<_>>>()?;
        Ok(Self { opts, envs })
    }

    fn layout<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        layout(py, &self.envs[0])
    }

    /// Number of crawlers.
    fn __len__(&self) -> usize {
        self.envs.len()
    }

    /// Starts a new episode of crawler `i` on `scenario`; its first observation (bytes).
    fn reset_one<'py>(
        &mut self,
        py: Python<'py>,
        i: usize,
        scenario: &PyScenario,
    ) -> PyResult<Bound<'py, PyBytes>> {
        if i >= self.envs.len() {
            return Err(invalid(py, "i", &i.to_string(), "an index of a crawler"));
        }
        self.envs[i] = build(py, &scenario.inner, &self.opts)?;
        let mut obs = Vec::new();
        self.envs[i].observe(&mut obs);
        Ok(f64_bytes(py, &obs))
    }

    /// Checks a step's `actions` and `mask` as [`Self::step`] does, stepping nothing (so that a
    /// caller can refuse them before it resets anything).
    fn check(&self, py: Python<'_>, actions: &[u8], mask: &[u8]) -> PyResult<()> {
        self.checked(py, actions, mask).map(|_| ())
    }

    /// Steps the crawlers whose `mask` byte is 1 with their rows of `actions` (float64 bytes,
    /// one row per crawler), in parallel with the GIL released: (observations, rewards,
    /// terminated, truncated) as bytes (float64 rows; float64; bool; bool). Crawlers not stepped
    /// give their current observation and zeros. Actions are checked before any crawler steps.
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: &[u8],
        mask: &[u8],
    ) -> PyResult<Bound<'py, PyTuple>> {
        let a = self.checked(py, actions, mask)?;
        let n = self.envs.len();
        let dim = self.envs[0].actuator.dim();
        let obs_dim = self.envs[0].sensor.dim();
        let envs = &mut self.envs;
        let mut obs = vec![0.0; n * obs_dim];
        let mut results = vec![StepResult::default(); n];
        let failed: Option<(usize, String)> = py.detach(|| {
            envs.par_iter_mut()
                .zip(obs.par_chunks_mut(obs_dim))
                .zip(results.par_iter_mut())
                .zip(a.par_chunks(dim).zip(mask.par_iter()))
                .enumerate()
                .map(|(i, (((env, row), result), (act, &m)))| {
                    if m != 0 {
                        *result = env.step(act).map_err(|e| (i, e))?;
                    }
                    env.observe_into(row);
                    Ok(())
                })
                .collect::<Result<(), (usize, String)>>()
                .err()
        });
        if let Some((i, e)) = failed {
            return Err(option_error(py, &format!("crawler {i}: {e}")));
        }
        let rewards: Vec<f64> = results.iter().map(|r| r.reward).collect();
        let term: Vec<bool> = results.iter().map(|r| r.terminated).collect();
        let trunc: Vec<bool> = results.iter().map(|r| r.truncated).collect();
        (
            f64_bytes(py, &obs),
            f64_bytes(py, &rewards),
            crate::bool_bytes(py, &term),
            crate::bool_bytes(py, &trunc),
        )
            .into_pyobject(py)
    }

    /// Crawler `i`'s episode so far: (time (s), distance (m), energy used (J), max stress (Pa),
    /// time above sigma_max (s), outcome).
    fn info(&self, i: usize) -> PyResult<(f64, f64, f64, f64, f64, String)> {
        let e = self
            .envs
            .get(i)
            .ok_or_else(|| pyo3::exceptions::PyIndexError::new_err(i))?;
        let t = e.run.task().report();
        Ok((
            e.run.plant().time(),
            t.distance,
            t.energy_used,
            t.max_stress,
            t.time_over_sigma_max,
            t.outcome.to_string(),
        ))
    }

    /// Crawler `i`'s state digest.
    fn state_digest(&self, i: usize) -> PyResult<String> {
        let e = self
            .envs
            .get(i)
            .ok_or_else(|| pyo3::exceptions::PyIndexError::new_err(i))?;
        Ok(crawler_physics::report::state_digest(e.run.plant()))
    }
}

impl PyVecCore {
    /// The actions of a step, refused whole when they are not one row per crawler or when a
    /// crawler to step has a NaN (no crawler steps then).
    fn checked(&self, py: Python<'_>, actions: &[u8], mask: &[u8]) -> PyResult<Vec<f64>> {
        let a = f64s_from(py, "actions", actions)?;
        let n = self.envs.len();
        let dim = self.envs[0].actuator.dim();
        if a.len() != n * dim || mask.len() != n {
            return Err(invalid(
                py,
                "actions",
                &format!("{} numbers", a.len()),
                &format!("{n} rows of {dim} numbers"),
            ));
        }
        for (i, (row, &m)) in a.chunks(dim).zip(mask).enumerate() {
            if let Some(j) = row.iter().position(|x| x.is_nan()).filter(|_| m != 0) {
                return Err(invalid(
                    py,
                    &format!("actions[{i}][{j}]"),
                    "NaN",
                    "numbers (not NaN)",
                ));
            }
        }
        Ok(a)
    }
}

/// The environment's sensor for a controller (the co-simulation route of a trained policy):
/// built from the controller's told scenario, fed every observation.
#[pyclass(name = "Sensor", module = "softcrawler._native")]
pub struct PySensor {
    sensor: Sensor,
    out: Vec<f64>,
}

#[pymethods]
impl PySensor {
    #[new]
    #[pyo3(signature = (told, fields=vec![], segments=8))]
    fn new(
        py: Python<'_>,
        told: &PyScenario,
        fields: Vec<String>,
        segments: usize,
    ) -> PyResult<Self> {
        let ctx = context_of_told(&told.inner);
        let fields = if fields.is_empty() {
            default_fields()
        } else {
            fields
        };
        let sensor = Sensor::new(&ctx, &fields, segments).map_err(|e| option_error(py, &e))?;
        Ok(Self {
            sensor,
            out: Vec::new(),
        })
    }

    /// Takes the observation of a communication step (every step, in order).
    fn feed(&mut self, obs: &PyObservation) {
        self.sensor.feed(obs.step, &obs.u, obs.input_power);
    }

    /// The sensed numbers for `obs` (fed already), as float64 bytes.
    fn encode<'py>(&mut self, py: Python<'py>, obs: &PyObservation) -> Bound<'py, PyBytes> {
        self.out.clear();
        self.sensor.encode(&obs.view(), None, &mut self.out);
        f64_bytes(py, &self.out)
    }

    /// The entries' names.
    fn names(&self) -> Vec<String> {
        self.sensor.names()
    }
}

/// The environment's actuator for a controller: actions in, actuations out (a wave as
/// `(f0, k, omega, phase)`, a field as float64 bytes, one value per cell).
#[pyclass(name = "Actuator", module = "softcrawler._native")]
pub struct PyActuator {
    actuator: Actuator,
}

#[pymethods]
impl PyActuator {
    #[new]
    #[pyo3(signature = (told, action="wave", segments=8))]
    fn new(py: Python<'_>, told: &PyScenario, action: &str, segments: usize) -> PyResult<Self> {
        let ctx = context_of_told(&told.inner);
        let actuator = Actuator::new(&ctx, action, segments).map_err(|e| option_error(py, &e))?;
        Ok(Self { actuator })
    }

    /// The actuation of `action` (float64 bytes) at time `time` (s).
    fn decode<'py>(
        &mut self,
        py: Python<'py>,
        action: &[u8],
        time: f64,
    ) -> PyResult<Bound<'py, PyAny>> {
        let a = f64s_from(py, "action", action)?;
        match self
            .actuator
            .decode(&a, time)
            .map_err(|e| option_error(py, &e))?
        {
            Actuation::Wave(w) => Ok((w.f0, w.k, w.omega, w.phase).into_pyobject(py)?.into_any()),
            Actuation::Field(f) => Ok(f64_bytes(py, &f).into_any()),
        }
    }

    /// The admissible wave number nearest to `k`, rad/m.
    fn snap_k(&self, k: f64) -> f64 {
        self.actuator.snap_k(k)
    }
}
