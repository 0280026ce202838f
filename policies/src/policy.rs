//! The policy interface: an observation of the plant in, an actuation out.
//!
//! A policy is one type implementing [`Policy`] with a factory that builds it from a
//! [`Context`] and its [`Params`]; register it with one line in [`crate::REGISTRY`] and it is
//! available everywhere a policy is named: `crawler-controller run --policy NAME`, `crawler run
//! --policy NAME`, a sweep plan's `[evaluate] policy`, Python.

use crawler_models::prediction::Prediction;
use crawler_physics::execution::{Actuation, Briefing, Observation};
use crawler_physics::params::{Body, Boundary, Friction};
use crawler_physics::scenario::Scenario;
use crawler_physics::wave::Wave;

/// What a policy knows when it is built: the plant as the controller is told it
/// ([`Briefing`]) over the controller's own scenario (task, limits, default wave).
#[derive(Debug, Clone)]
pub struct Context {
    /// Body material.
    pub body: Body,
    /// The friction the controller is told (nominal unless the pipe is disclosed).
    pub friction: Friction,
    /// Body length, m.
    pub length: f64,
    /// Periodic body or free ends.
    pub boundary: Boundary,
    /// Number of cells.
    pub cells: usize,
    /// Communication step H actually used, s.
    pub step: f64,
    /// The controller's scenario with the plant as told (task, limits, default wave).
    pub scenario: Scenario,
}

impl Context {
    /// The context of a controller told `briefing`, with its own scenario `own`.
    pub fn new(briefing: &Briefing, own: &Scenario) -> Self {
        let scenario = briefing.scenario(own);
        let p = &scenario.plant;
        Self {
            body: p.body,
            friction: p.friction,
            length: p.length,
            boundary: p.boundary,
            cells: p.numerics.cells,
            step: p.numerics.step,
            scenario,
        }
    }

    /// The context of a controller of a run of `scenario` from t = 0 (in process: the same as a
    /// co-simulated controller with the same scenario file is told).
    pub fn of(scenario: &Scenario) -> Result<Self, crawler_physics::ParamError> {
        Ok(Self::new(&Briefing::of(scenario)?, scenario))
    }

    /// The scenario's wave (the default wave a policy starts from).
    pub fn wave(&self) -> Wave {
        self.scenario.wave
    }
}

/// A controller policy: called once per communication step with the plant's state.
pub trait Policy: Send {
    /// Short name.
    fn name(&self) -> &str;

    /// The actuation for the step starting at `obs.time`.
    fn act(&mut self, obs: &Observation) -> Actuation;

    /// A one-line description of what it does (printed at start).
    fn describe(&self) -> String {
        self.name().to_string()
    }

    /// What the policy has to report since the last call (called after every [`Self::act`]):
    /// estimates with their confidence and the decisions taken, for the recorder. Open-loop
    /// policies have nothing to say.
    fn insight(&mut self) -> Option<Insight> {
        None
    }
}

/// A feedback policy's report: one line for the log, and the steady state it now expects.
#[derive(Debug, Clone, PartialEq)]
pub struct Insight {
    /// The estimates with their uncertainty and the decision taken, in words.
    pub text: String,
    /// The policy's own prediction of the steady state under what it applies (recorded as the
    /// model named in `prediction.model` beside the plant's metrics).
    pub prediction: Option<Prediction>,
}
