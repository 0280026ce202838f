//! The controller interface: an observation of the plant in, an actuation out.
//!
//! A controller is one type implementing [`Controller`]; register it with one line in
//! [`crate::policies::REGISTRY`] and it is available as `crawler-controller run --policy NAME`.

use crawler_plant::params::{Body, Boundary, Friction};
use crawler_plant::scenario::Scenario;
use crawler_plant::wave::Wave;

use crate::optimizer::ModelChoice;

/// What the controller sees each communication step.
#[derive(Debug, Clone, Copy)]
pub struct Observation<'a> {
    /// Communication step number n (the plant is at time t0 + n H).
    pub step: u64,
    /// Time, s.
    pub time: f64,
    /// Displacement at the nodes, m.
    pub u: &'a [f64],
    /// Velocity at the nodes, m/s.
    pub v: &'a [f64],
    /// Tension at the half nodes, N.
    pub tension: &'a [f64],
    /// Nodes held by static friction.
    pub stuck: &'a [bool],
    /// Mean speed over the last step, m/s.
    pub mean_speed: f64,
    /// Input power over the last step, W.
    pub input_power: f64,
}

/// What the controller commands for the next step.
#[derive(Debug, Clone, PartialEq)]
pub enum Actuation {
    /// A travelling wave, evaluated continuously by the plant.
    Wave(Wave),
    /// Muscle force at the half nodes, N, held over the step.
    Field(Vec<f64>),
}

/// The plant as the controller knows it (from the run's model description) plus the scenario.
#[derive(Debug, Clone)]
pub struct Context {
    /// Body material.
    pub body: Body,
    /// Friction law.
    pub friction: Friction,
    /// Body length, m.
    pub length: f64,
    /// Periodic body or free ends.
    pub boundary: Boundary,
    /// Number of cells.
    pub cells: usize,
    /// Communication step H, s.
    pub step: f64,
    /// The scenario (task, limits, default wave).
    pub scenario: Scenario,
    /// Policy options from the command line.
    pub options: PolicyOptions,
}

/// Options common to the built-in policies.
#[derive(Debug, Clone)]
pub struct PolicyOptions {
    /// Wave amplitude, N (default: the scenario's).
    pub f0: Option<f64>,
    /// Wave number, rad/m (default: the scenario's).
    pub k: Option<f64>,
    /// Angular frequency, rad/s.
    pub omega: Option<f64>,
    /// omega / omega_n.
    pub alpha: Option<f64>,
    /// `sweep`: the alpha values visited in turn.
    pub sweep: Vec<f64>,
    /// `sweep`: seconds spent at each.
    pub dwell: Option<f64>,
    /// `optimal`: the model to optimise with.
    pub model: Option<ModelChoice>,
    /// `optimal`: grid points per axis.
    pub grid: Option<usize>,
    /// `optimal`: certify the constraints on the in-process plant (lowering f0 if needed).
    pub certify: bool,
    /// `optimal`: relative margin of the certification.
    pub margin: f64,
}

impl Default for PolicyOptions {
    fn default() -> Self {
        Self {
            f0: None,
            k: None,
            omega: None,
            alpha: None,
            sweep: Vec::new(),
            dwell: None,
            model: None,
            grid: None,
            certify: true,
            margin: 0.005,
        }
    }
}

impl Context {
    /// The context of an in-process run of `scenario`.
    pub fn of_scenario(scenario: &Scenario, options: PolicyOptions) -> Self {
        Self {
            body: scenario.plant.body,
            friction: scenario.plant.friction,
            length: scenario.plant.length,
            boundary: scenario.plant.boundary,
            cells: scenario.plant.numerics.cells,
            step: scenario.plant.numerics.step,
            scenario: scenario.clone(),
            options,
        }
    }

    /// The wave of the options, falling back to the scenario's (omega from alpha if given).
    pub fn wave(&self) -> Wave {
        let base = self.scenario.wave;
        let k = self.options.k.unwrap_or(base.k);
        let omega_n = k * self.body.wave_speed();
        let omega = match (self.options.omega, self.options.alpha) {
            (Some(w), _) => w,
            (None, Some(a)) => a * omega_n,
            (None, None) if self.options.k.is_some() => {
                base.omega / (base.k * self.body.wave_speed()) * omega_n
            }
            (None, None) => base.omega,
        };
        Wave {
            f0: self.options.f0.unwrap_or(base.f0),
            k,
            omega,
            phase: base.phase,
        }
    }
}

/// A controller: called once per communication step with the plant's state.
pub trait Controller: Send {
    /// Short name.
    fn name(&self) -> &str;

    /// The actuation for the step starting at `obs.time`.
    fn act(&mut self, obs: &Observation) -> Actuation;

    /// A one-line description of what it does (printed at start).
    fn describe(&self) -> String {
        self.name().to_string()
    }
}
