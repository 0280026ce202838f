//! A controller in closed loop with the in-process plant: the co-simulation's lockstep without the
//! network (the plant's state at step n in, the actuation for step n out, one step), so a run
//! here is bit-identical to the same run co-simulated (`crawler-plant run` + `crawler-controller
//! run`), task mode included.

use crawler_plant::scenario::Scenario;
use crawler_plant::simulate::{mean_position, report_with_task, EpisodeLog, Report};
use crawler_plant::slave::{Slave, StepStatus};
use crawler_plant::task::TaskTracker;

use crate::controller::{Actuation, Controller, Insight, Observation};

/// The outcome of an in-process closed-loop run.
#[derive(Debug, Clone)]
pub struct ClosedLoopRun {
    /// The plant's final report, as `crawler-plant run` prints it (task included).
    pub report: Report,
    /// Communication steps taken.
    pub steps: u64,
    /// What the controller reported along the way, with the step it was reported at.
    pub insights: Vec<(u64, Insight)>,
}

/// Runs `policy` against the plant of `scenario` from t = 0 to the scenario's end (or, in task
/// mode, to the step that decides the task).
pub fn run(scenario: &Scenario, policy: &mut dyn Controller) -> anyhow::Result<ClosedLoopRun> {
    let mut slave = Slave::instantiate("closed-loop", scenario.plant.clone())?;
    slave.enter_initialization_mode(0.0, None)?;
    slave.exit_initialization_mode()?;
    slave.set_stress_limit(Some(scenario.task.sigma_max))?;
    let h = slave.plant().step_length();
    let mut last_step = scenario.plant.discretisation()?.steps_until(scenario.t_end);
    let mut task = TaskTracker::new(
        scenario.task,
        slave.plant().time(),
        mean_position(slave.plant()),
    );
    let mut log = EpisodeLog::new(0);
    let mut insights = Vec::new();
    let mut n = 0;
    while n < last_step {
        let plant = slave.plant();
        let tension = plant.tension();
        let out = plant.outputs();
        let obs = Observation {
            step: plant.macro_step(),
            time: plant.time(),
            u: plant.displacement(),
            v: plant.velocity(),
            tension: &tension,
            stuck: plant.stuck(),
            mean_speed: out.mean_speed,
            input_power: out.input_power,
        };
        let actuation = policy.act(&obs);
        if let Some(i) = policy.insight() {
            insights.push((n, i));
        }
        match actuation {
            Actuation::Wave(w) => slave.set_wave(w),
            Actuation::Field(f) => slave.set_field(&f),
        }
        .map_err(|e| anyhow::anyhow!("step {n}: actuation refused: {e}"))?;
        match slave.do_step(slave.plant().time(), h) {
            StepStatus::Ok => {}
            StepStatus::Discard { reason, .. } => anyhow::bail!("step {n} discarded: {reason}"),
            StepStatus::Error(e) => anyhow::bail!("step {n}: {e}"),
        }
        log.observe(slave.plant());
        let plant = slave.plant();
        let decided = task.observe(plant.time(), h, mean_position(plant), &plant.outputs());
        if scenario.task.end_run && decided.is_some() {
            last_step = last_step.min(n + 1);
        }
        n += 1;
    }
    let report = report_with_task(&scenario.name, slave.plant(), &log, Some(&task))?;
    Ok(ClosedLoopRun {
        report,
        steps: n,
        insights,
    })
}
