//! The controller interface: an observation of the plant in, an actuation out.
//!
//! A controller is one type implementing [`Controller`]; register it with one line in
//! [`crate::policies::REGISTRY`] and it is available as `crawler-controller run --policy NAME`.

use crawler_plant::params::{Body, Boundary, Friction};
use crawler_plant::scenario::Scenario;
use crawler_plant::wave::Wave;

use crate::optimizer::ModelChoice;
use crate::policies::{AdaptiveOptions, ReflexOptions};
use crate::prediction::Prediction;

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
    /// Settings of the feedback policies (`adaptive`, `reflex`).
    pub feedback: FeedbackOptions,
}

/// Settings of the feedback policies.
#[derive(Debug, Clone, Default)]
pub struct FeedbackOptions {
    /// `adaptive`: estimator and re-planning.
    pub adaptive: AdaptiveOptions,
    /// `reflex`: the oscillators and reflexes.
    pub reflex: ReflexOptions,
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

impl FeedbackOptions {
    /// The defaults with `KEY=VALUE` settings applied (`--adaptive`, `--reflex`).
    pub fn from_settings(adaptive: &[String], reflex: &[String]) -> anyhow::Result<Self> {
        let mut me = Self::default();
        for s in adaptive {
            let (k, v) = split_setting("adaptive", s)?;
            me.adaptive.set(k, v)?;
        }
        for s in reflex {
            let (k, v) = split_setting("reflex", s)?;
            me.reflex.set(k, v)?;
        }
        me.adaptive.validate()?;
        me.reflex.validate()?;
        Ok(me)
    }
}

/// `KEY=VALUE` with VALUE a finite number.
fn split_setting<'a>(flag: &str, s: &'a str) -> anyhow::Result<(&'a str, f64)> {
    let bad = || anyhow::anyhow!("invalid --{flag} {s:?}: allowed KEY=VALUE with a number");
    let (k, v) = s.split_once('=').ok_or_else(bad)?;
    let x: f64 = v.trim().parse().map_err(|_| bad())?;
    anyhow::ensure!(
        x.is_finite(),
        "invalid --{flag} {s:?}: the value must be finite"
    );
    Ok((k.trim(), x))
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
            feedback: FeedbackOptions::default(),
        }
    }

    /// What a controller of a co-simulated run of `scenario` is told (the plant's model
    /// description: the nominal friction and no pipe map when the pipe is not disclosed, the
    /// communication step actually used), as [`crate::client::context_of`] builds it; an
    /// in-process run with this context is bit-identical to the co-simulated one.
    pub fn as_told(
        scenario: &Scenario,
        options: PolicyOptions,
        feedback: FeedbackOptions,
    ) -> Result<Self, crawler_plant::ParamError> {
        let mut s = scenario.clone();
        s.plant = scenario.plant.told();
        s.plant.numerics.step = scenario.plant.discretisation()?.step;
        Ok(Self {
            body: s.plant.body,
            friction: s.plant.friction,
            length: s.plant.length,
            boundary: s.plant.boundary,
            cells: s.plant.numerics.cells,
            step: s.plant.numerics.step,
            scenario: s,
            options,
            feedback,
        })
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

    /// What the controller has to report since the last call (called after every [`Self::act`]):
    /// estimates with their confidence and the decisions taken, for the recorder. Open-loop
    /// policies have nothing to say.
    fn insight(&mut self) -> Option<Insight> {
        None
    }
}

/// A feedback controller's report: one line for the log, and the steady state it now expects.
#[derive(Debug, Clone, PartialEq)]
pub struct Insight {
    /// The estimates with their uncertainty and the decision taken, in words.
    pub text: String,
    /// The controller's own prediction of the steady state under what it applies (recorded as
    /// the model named in `prediction.model` beside the plant's metrics).
    pub prediction: Option<Prediction>,
}
