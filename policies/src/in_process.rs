//! A policy in closed loop with the in-process plant: the plant's execution loop with the policy
//! as its controller (the plant's state at step n in, the actuation for step n out, one step).
//! The co-simulation runs the same loop with the network in between, so a run here is
//! bit-identical to the same run co-simulated (`crawler-plant run` + `crawler-controller run`),
//! task mode included.

use std::convert::Infallible;

use crawler_physics::execution::{
    Actuation, Controller, Execution, ExecutionError, Observation, Observer, Start,
};
use crawler_physics::report::Report;
use crawler_physics::scenario::Scenario;

use crate::params::Params;
use crate::policy::{Context, Insight, Policy};

/// The outcome of an in-process closed-loop run.
#[derive(Debug, Clone)]
pub struct InProcessRun {
    /// The plant's final report, as `crawler-plant run` prints it (task included).
    pub report: Report,
    /// Communication steps taken.
    pub steps: u64,
    /// What the policy reported along the way, with the step it was reported at.
    pub insights: Vec<(u64, Insight)>,
    /// The last travelling wave the policy commanded, if any.
    pub last_wave: Option<crawler_physics::wave::Wave>,
}

/// A policy as the execution's controller: asked once per step, its insights kept.
pub struct Acting<'a> {
    policy: &'a mut dyn Policy,
    /// What the policy reported, with the step.
    pub insights: Vec<(u64, Insight)>,
    /// The last wave it commanded.
    pub last_wave: Option<crawler_physics::wave::Wave>,
}

impl<'a> Acting<'a> {
    /// `policy` as a controller.
    pub fn new(policy: &'a mut dyn Policy) -> Self {
        Self {
            policy,
            insights: Vec::new(),
            last_wave: None,
        }
    }
}

impl Controller for Acting<'_> {
    type Stop = Infallible;

    fn act(&mut self, obs: &Observation<'_>) -> Result<Option<Actuation>, Infallible> {
        let a = self.policy.act(obs);
        if let Some(i) = self.policy.insight() {
            self.insights.push((obs.step, i));
        }
        if let Actuation::Wave(w) = &a {
            self.last_wave = Some(*w);
        }
        Ok(Some(a))
    }
}

/// Runs `policy` against the plant of `scenario` from t = 0 to the scenario's end (or, in task
/// mode, to the step that decides the task), with `observers` watching every step.
pub fn run_with(
    scenario: &Scenario,
    policy: &mut dyn Policy,
    observers: &mut [&mut dyn Observer],
) -> Result<InProcessRun, ExecutionError> {
    let mut execution = Execution::new(scenario, Start::default())?;
    let mut acting = Acting::new(policy);
    execution.run(&mut acting, observers)?;
    Ok(InProcessRun {
        report: execution.report()?,
        steps: execution.plant().macro_step(),
        insights: acting.insights,
        last_wave: acting.last_wave,
    })
}

/// Runs `policy` against the plant of `scenario` from t = 0 to the scenario's end (or, in task
/// mode, to the step that decides the task).
pub fn run(scenario: &Scenario, policy: &mut dyn Policy) -> Result<InProcessRun, ExecutionError> {
    run_with(scenario, policy, &mut [])
}

/// Builds the policy `name` with `params` as a controller of `scenario` is told it (the same
/// briefing as in the co-simulation) and runs it in process.
pub fn run_named(scenario: &Scenario, name: &str, params: &Params) -> anyhow::Result<InProcessRun> {
    let ctx = Context::of(scenario)?;
    let mut policy = crate::build(name, &ctx, params)?;
    Ok(run(scenario, policy.as_mut())?)
}
