//! The plant in process: the physics crate's execution loop (`Execution`), stepped by Python one
//! or many communication steps at a time, and `simulate` (the same loop with no controller).

use pyo3::prelude::*;
use pyo3::types::PyBytes;
use serde::{Deserialize, Serialize};

use crawler_physics::execution::{Actuation, Execution, ExecutionError, Resume, Start};
use crawler_physics::plant::PlantState;
use crawler_physics::report::EpisodeLog;
use crawler_physics::scenario::Scenario;
use crawler_physics::simulate::{simulate, SimulateOptions};
use crawler_physics::slave::SlaveError;
use crawler_physics::task::TaskTracker;
use crawler_physics::wave::Wave;

use crate::policy::PyObservation;
use crate::scenario::PyScenario;
use crate::{bool_array, f64_array, invalid, param_error, run_error, to_json, to_py};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyPlant>()?;
    m.add_class::<PyState>()?;
    m.add_function(wrap_pyfunction!(simulate_json, m)?)?;
    Ok(())
}

/// An execution error as the package's exception.
pub fn execution_error<S>(py: Python<'_>, e: ExecutionError<S>) -> PyErr {
    match e {
        ExecutionError::Slave(SlaveError::Invalid(p)) => param_error(py, &p),
        ExecutionError::Refused {
            source: SlaveError::Invalid(p),
            ..
        } => param_error(py, &p),
        other => run_error(py, other.to_string()),
    }
}

/// `crawler-plant simulate --json`: the scenario's plant under its wave from t = 0 to its end,
/// run by the execution loop with no controller; the report as JSON.
#[pyfunction]
#[pyo3(signature = (scenario, max_episodes=10_000))]
fn simulate_json(py: Python<'_>, scenario: &PyScenario, max_episodes: usize) -> PyResult<String> {
    let s = &scenario.inner;
    let report = py
        .detach(|| {
            simulate(
                s,
                SimulateOptions {
                    max_episodes,
                    progress: None,
                },
            )
        })
        .map_err(|e| execution_error(py, e))?;
    to_json(py, &report)
}

/// What a run needs to continue where it was: the plant's state, the episode log, the task so
/// far and the run's last step (`Execution::resume_point`).
#[derive(Serialize, Deserialize)]
struct Saved {
    state: PlantState,
    log: EpisodeLog,
    task: TaskTracker,
    last_step: u64,
}

const STATE_MAGIC: &[u8; 8] = b"CRWLPYRN";
const STATE_VERSION: u32 = 1;

/// A plant's complete state with its run's task and episode log: setting it continues the run
/// bit-identically (also in another `Plant` of the same scenario).
#[pyclass(name = "State", module = "softcrawler._native", frozen)]
#[derive(Clone)]
pub struct PyState {
    resume: Resume,
}

#[pymethods]
impl PyState {
    /// The state as bytes (framed, checksummed MessagePack).
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        let r = &self.resume;
        let saved = Saved {
            state: r.state.clone(),
            log: r.log.clone(),
            task: r.task,
            last_step: r.last_step,
        };
        PyBytes::new(
            py,
            &crawler_physics::framing::encode(STATE_MAGIC, STATE_VERSION, &saved),
        )
    }

    /// A state from `to_bytes` (magic, version and checksum checked; values when it is set).
    #[staticmethod]
    fn from_bytes(py: Python<'_>, data: &[u8]) -> PyResult<Self> {
        let saved: Saved = crawler_physics::framing::decode(
            STATE_MAGIC,
            STATE_VERSION,
            "softcrawler plant state",
            data,
        )
        .map_err(|e| invalid(py, "state", &format!("{} bytes", data.len()), &e.0))?;
        saved.task.validate().map_err(|e| param_error(py, &e))?;
        Ok(Self {
            resume: Resume {
                state: saved.state,
                log: saved.log,
                task: saved.task,
                last_step: saved.last_step,
            },
        })
    }

    /// Communication step of the state (`macro_step`; `step` counts internal steps).
    #[getter]
    #[allow(clippy::misnamed_getters)]
    fn step(&self) -> u64 {
        self.resume.state.macro_step
    }

    /// Time of the state, s.
    #[getter]
    fn time(&self) -> f64 {
        let s = &self.resume.state;
        match s.params.discretisation() {
            Ok(d) => s.t0 + s.step as f64 * d.dt,
            Err(_) => f64::NAN,
        }
    }

    fn __repr__(&self) -> String {
        format!(
            "State(step={}, cells={})",
            self.resume.state.macro_step,
            self.resume.state.u.len()
        )
    }
}

/// The plant of a scenario run by the execution loop, stepped from Python.
#[pyclass(name = "Plant", module = "softcrawler._native")]
pub struct PyPlant {
    scenario: Scenario,
    run: Execution,
    pending: Option<Actuation>,
}

impl PyPlant {
    fn check_wave(&self, py: Python<'_>, w: &Wave) -> PyResult<()> {
        let p = &self.scenario.plant;
        w.validate_for_body(p.length, p.numerics.cells, p.boundary)
            .map_err(|e| param_error(py, &e))
    }
}

#[pymethods]
impl PyPlant {
    /// A run of `scenario` from t = 0. With `start_wave` the scenario's wave drives the plant
    /// from the start (as `simulate` does); without, the plant is idle until an actuation is set.
    #[new]
    #[pyo3(signature = (scenario, start_wave=true, max_episodes=10_000))]
    fn new(
        py: Python<'_>,
        scenario: &PyScenario,
        start_wave: bool,
        max_episodes: usize,
    ) -> PyResult<Self> {
        let s = scenario.inner.clone();
        let start = Start {
            actuation: start_wave.then_some(Actuation::Wave(s.wave)),
            max_episodes,
        };
        let run = Execution::new(&s, start).map_err(|e| match e {
            SlaveError::Invalid(p) => param_error(py, &p),
            other => run_error(py, other.to_string()),
        })?;
        Ok(Self {
            scenario: s,
            run,
            pending: None,
        })
    }

    /// Drives the body from the next step on with the wave `f0 sin(k x - omega t + phase)`
    /// (f0 in N, k in rad/m, omega in rad/s, phase in rad); it must fit the body.
    #[pyo3(signature = (f0, k, omega, phase=0.0))]
    fn set_wave(
        &mut self,
        py: Python<'_>,
        f0: f64,
        k: f64,
        omega: f64,
        phase: f64,
    ) -> PyResult<()> {
        let w = Wave {
            f0,
            k,
            omega,
            phase,
        };
        self.check_wave(py, &w)?;
        self.pending = Some(Actuation::Wave(w));
        Ok(())
    }

    /// Drives the body from the next step on with a muscle-force field held over each step: one
    /// value per cell (at the half nodes), N, as native float64 bytes.
    fn set_field_bytes(&mut self, py: Python<'_>, field: &[u8]) -> PyResult<()> {
        let f = crate::f64s_from(py, "field", field)?;
        let n = self.scenario.plant.numerics.cells;
        if f.len() != n {
            return Err(invalid(
                py,
                "field",
                &format!("{} values", f.len()),
                &format!("exactly {n} values (one per cell), N"),
            ));
        }
        if let Some((i, x)) = f.iter().enumerate().find(|(_, x)| !x.is_finite()) {
            return Err(invalid(
                py,
                &format!("field[{i}]"),
                &x.to_string(),
                "finite numbers (N)",
            ));
        }
        self.pending = Some(Actuation::Field(f));
        Ok(())
    }

    /// Takes up to `n` communication steps (fewer if the run ends), the actuation set since the
    /// last step applied before the first; returns the steps taken. The GIL is released.
    #[pyo3(signature = (n=1))]
    fn step(&mut self, py: Python<'_>, n: u64) -> PyResult<u64> {
        let pending = self.pending.take();
        let run = &mut self.run;
        let r = py.detach(|| -> Result<u64, ExecutionError> {
            let mut taken = 0;
            let mut a = pending;
            while taken < n && !run.finished() {
                run.step(a.take().as_ref(), &mut [])?;
                taken += 1;
            }
            Ok(taken)
        });
        r.map_err(|e| execution_error(py, e))
    }

    /// Steps to the end of the run (or the step that decides the task in task mode); returns the
    /// steps taken.
    fn run(&mut self, py: Python<'_>) -> PyResult<u64> {
        self.step(py, u64::MAX)
    }

    /// True when the run has reached its last step.
    #[getter]
    fn finished(&self) -> bool {
        self.run.finished()
    }

    /// Communication steps taken.
    #[getter]
    fn steps(&self) -> u64 {
        self.run.plant().macro_step()
    }

    /// The run's last communication step (earlier once the task ended the run).
    #[getter]
    fn last_step(&self) -> u64 {
        self.run.last_step()
    }

    /// Time, s.
    #[getter]
    fn time(&self) -> f64 {
        self.run.plant().time()
    }

    /// Communication step H actually used, s.
    #[getter]
    fn step_length(&self) -> f64 {
        self.run.plant().step_length()
    }

    /// Number of cells N.
    #[getter]
    fn cells(&self) -> usize {
        self.run.plant().cells()
    }

    /// Displacement at the nodes, m (read-only copy of this instant).
    #[getter]
    fn u<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        f64_array(py, self.run.plant().displacement())
    }

    /// Velocity at the nodes, m/s.
    #[getter]
    fn vel<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        f64_array(py, self.run.plant().velocity())
    }

    /// Tension at the half nodes, N.
    #[getter]
    fn tension<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        f64_array(py, &self.run.plant().tension())
    }

    /// Nodes held by static friction.
    #[getter]
    fn stuck<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        bool_array(py, self.run.plant().stuck())
    }

    /// Muscle force at the half nodes now, N.
    #[getter]
    fn muscle_force<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        f64_array(py, &self.run.plant().muscle_force())
    }

    /// Outputs of the last step: mean_speed (m/s), input_power (W), stuck_nodes, max_stress
    /// (Pa), time_over_stress (s).
    #[getter]
    fn outputs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.run.plant().outputs())
    }

    /// The task so far (as in the report: outcome, distance, energy_used, ...; SI units).
    #[getter]
    fn task<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.run.task().report())
    }

    /// What a controller sees now.
    fn observation(&mut self) -> PyObservation {
        PyObservation::of(&self.run.observation())
    }

    /// CRC-32 of the displacement and velocity bits and the step count.
    #[getter]
    fn state_digest(&self) -> String {
        crawler_physics::report::state_digest(self.run.plant())
    }

    /// The report of the run so far, as JSON.
    fn report_json(&self, py: Python<'_>) -> PyResult<String> {
        let r = self
            .run
            .report()
            .map_err(|e| run_error(py, e.to_string()))?;
        to_json(py, &r)
    }

    /// The run's complete state (plant, task, episode log).
    fn get_state(&self) -> PyState {
        PyState {
            resume: self.run.resume_point(),
        }
    }

    /// Continues from `state` (taken from a plant of the same scenario): bit-identical to the
    /// run never stopped. Any actuation set and not yet applied is dropped.
    fn set_state(&mut self, py: Python<'_>, state: &PyState) -> PyResult<()> {
        let run = Execution::resume(&self.scenario, state.resume.clone()).map_err(|e| match e {
            SlaveError::Invalid(p) => param_error(py, &p),
            other => invalid(py, "state", "a state", &other.to_string()),
        })?;
        self.run = run;
        self.pending = None;
        Ok(())
    }

    /// The scenario.
    #[getter]
    fn scenario(&self) -> PyScenario {
        PyScenario {
            inner: self.scenario.clone(),
        }
    }

    fn __repr__(&self) -> String {
        format!(
            "Plant(scenario={:?}, step={} of {}, t={} s)",
            self.scenario.name,
            self.run.plant().macro_step(),
            self.run.last_step(),
            self.run.plant().time()
        )
    }
}
