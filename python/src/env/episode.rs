//! One crawler on the task: an episode, its reward and its end.

use std::cell::RefCell;

use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crawler_physics::execution::{Actuation, Execution, ExecutionError, Start};
use crawler_physics::scenario::Scenario;
use crawler_physics::task::Outcome;
use crawler_policies::Context;

use super::*;
use crate::{invalid, param_error, run_error};

/// The options of an environment.
#[derive(Debug, Clone)]
pub(super) struct EnvOptions {
    pub(super) action: String,
    pub(super) segments: usize,
    pub(super) fields: Vec<String>,
    pub(super) frame_skip: u64,
    pub(super) stress_weight: f64,
}

/// One crawler on the task.
pub(super) struct EnvCore {
    pub(super) opts: EnvOptions,
    pub(super) scenario: Scenario,
    pub(super) run: Execution,
    pub(super) sensor: Sensor,
    pub(super) actuator: Actuator,
    pub(super) current: Option<Actuation>,
    pub(super) distance: f64,
    pub(super) over_stress: f64,
    pub(super) done: bool,
    /// The observation's buffer (reused).
    pub(super) scratch: Vec<f64>,
}

/// What one environment step gives.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct StepResult {
    pub(super) reward: f64,
    pub(super) terminated: bool,
    pub(super) truncated: bool,
}

thread_local! {
    /// The tension of the observation being sensed: one buffer per thread, shared by the runs
    /// the thread steps (a vector's crawlers), so it stays in the thread's cache.
    static TENSION: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
}

/// The sensor's numbers for the run's current state (the distance is the task's: the same
/// subtraction of the same means).
pub(super) fn sensed(run: &Execution, sensor: &Sensor, out: &mut Vec<f64>) {
    let travelled = run.task().distance;
    TENSION.with_borrow_mut(|tension| {
        sensor.encode(&run.observation_with(tension), Some(travelled), out);
    });
}

impl EnvCore {
    /// An episode of `scenario` (its task in task mode), at step 0.
    pub(super) fn new(scenario: &Scenario, opts: EnvOptions) -> anyhow::Result<Self> {
        let mut s = scenario.clone();
        s.task.end_run = true;
        let ctx = Context::of(&s)?;
        let sensor = Sensor::new(&ctx, &opts.fields, opts.segments).map_err(anyhow::Error::msg)?;
        let actuator =
            Actuator::new(&ctx, &opts.action, opts.segments).map_err(anyhow::Error::msg)?;
        let run = Execution::new(&s, Start::default())?;
        let mut env = Self {
            opts,
            scenario: s,
            run,
            sensor,
            actuator,
            current: None,
            distance: 0.0,
            over_stress: 0.0,
            done: false,
            scratch: Vec::new(),
        };
        let obs = env.run.observation();
        env.sensor.feed(obs.step, obs.u, obs.input_power);
        Ok(env)
    }

    pub(super) fn observe(&mut self, out: &mut Vec<f64>) {
        sensed(&self.run, &self.sensor, out);
    }

    /// The observation into `row` (as long as the sensor's dimension).
    pub(super) fn observe_into(&mut self, row: &mut [f64]) {
        self.scratch.clear();
        sensed(&self.run, &self.sensor, &mut self.scratch);
        row.copy_from_slice(&self.scratch);
    }

    /// Applies `action` and takes `frame_skip` communication steps (fewer if the run ends),
    /// applying the actuation at every step as the co-simulation's controller does.
    pub(super) fn step(&mut self, action: &[f64]) -> Result<StepResult, String> {
        if self.done {
            return Err("the episode has ended: call reset".into());
        }
        let time = self.run.plant().time();
        let a = self.actuator.decode(action, time)?;
        self.current = Some(a);
        let mut taken = 0;
        while taken < self.opts.frame_skip && !self.run.finished() {
            let r: Result<(), ExecutionError> = self.run.step(self.current.as_ref(), &mut []);
            r.map_err(|e| e.to_string())?;
            taken += 1;
            let p = self.run.plant();
            let out = p.outputs();
            self.sensor
                .feed(p.macro_step(), p.displacement(), out.input_power);
        }
        let task = *self.run.task();
        let t = &self.scenario.task;
        let h = self.run.plant().step_length();
        let mut reward = (task.distance - self.distance) / t.distance;
        reward -= taken as f64 * h / self.scenario.t_end;
        reward -= self.opts.stress_weight * (task.time_over_stress - self.over_stress)
            / self.scenario.t_end;
        self.distance = task.distance;
        self.over_stress = task.time_over_stress;
        let decided = task.decided();
        match decided {
            Some(Outcome::Reached) => reward += 1.0,
            Some(Outcome::EnergyExhausted) => reward -= 1.0,
            _ => {}
        }
        let terminated = decided.is_some();
        let truncated = !terminated && self.run.finished();
        self.done = terminated || truncated;
        Ok(StepResult {
            reward,
            terminated,
            truncated,
        })
    }

    pub(super) fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let t = self.run.task().report();
        d.set_item(intern!(py, "time"), self.run.plant().time())?;
        d.set_item(intern!(py, "step"), self.run.plant().macro_step())?;
        d.set_item(intern!(py, "distance"), t.distance)?;
        d.set_item(intern!(py, "energy_used"), t.energy_used)?;
        d.set_item(intern!(py, "max_stress"), t.max_stress)?;
        d.set_item(intern!(py, "time_over_sigma_max"), t.time_over_sigma_max)?;
        d.set_item(intern!(py, "outcome"), t.outcome.to_string())?;
        Ok(d)
    }
}

pub(super) fn options(
    py: Python<'_>,
    action: &str,
    segments: usize,
    fields: Vec<String>,
    frame_skip: u64,
    stress_weight: f64,
) -> PyResult<EnvOptions> {
    if frame_skip == 0 {
        return Err(invalid(
            py,
            "frame_skip",
            "0",
            "1 or more communication steps",
        ));
    }
    if !(stress_weight.is_finite() && stress_weight >= 0.0) {
        return Err(invalid(
            py,
            "stress_weight",
            &stress_weight.to_string(),
            "a finite number >= 0",
        ));
    }
    Ok(EnvOptions {
        action: action.to_string(),
        segments,
        fields: if fields.is_empty() {
            default_fields()
        } else {
            fields
        },
        frame_skip,
        stress_weight,
    })
}

/// `"field: message"` errors of the sensor and the actuator as `InvalidInput`.
pub(super) fn option_error(py: Python<'_>, msg: &str) -> PyErr {
    match msg.split_once(": allowed ") {
        Some((head, allowed)) => {
            let (field, value) = head.split_once(" = ").unwrap_or((head, ""));
            let (field, value) = match field.split_once(": ") {
                Some((f, v)) => (f, v),
                None => (field, value),
            };
            invalid(py, field, value, allowed)
        }
        None => run_error(py, msg.to_string()),
    }
}

pub(super) fn build(py: Python<'_>, scenario: &Scenario, opts: &EnvOptions) -> PyResult<EnvCore> {
    EnvCore::new(scenario, opts.clone()).map_err(|e| {
        if let Some(p) = e.downcast_ref::<crawler_physics::ParamError>() {
            return param_error(py, p);
        }
        option_error(py, &format!("{e}"))
    })
}

pub(super) fn layout<'py>(py: Python<'py>, env: &EnvCore) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let (lo, hi) = env.actuator.low_high();
    d.set_item("obs_names", env.sensor.names())?;
    d.set_item("obs_low", env.sensor.low())?;
    d.set_item("obs_high", env.sensor.high())?;
    d.set_item("act_low", lo)?;
    d.set_item("act_high", hi)?;
    d.set_item(
        "step",
        env.run.plant().step_length() * env.opts.frame_skip as f64,
    )?;
    Ok(d)
}
