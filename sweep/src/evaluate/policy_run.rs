//! A co-simulated policy evaluated in process: the same lockstep as the co-simulation (the plant
//! publishes its state, the controller answers with the next step's actuation, the plant steps),
//! without the network; bit-identical to a co-simulated run.

use crawler_controller::controller::{Actuation, Context, Observation};
use crawler_controller::policies;
use crawler_plant::scenario::Scenario;
use crawler_plant::simulate::{report, EpisodeLog};
use crawler_plant::slave::{Slave, StepStatus};

use crate::plan::PolicySpec;
use crate::record::PolicyResult;

use super::convergence::plant_run;

/// Runs `spec`'s policy against the plant of `scenario` from t = 0 to its end.
pub fn run_policy(scenario: &Scenario, spec: &PolicySpec) -> Result<PolicyResult, String> {
    let ctx = Context::of_scenario(scenario, spec.options());
    let mut policy =
        policies::build(&spec.name, &ctx).map_err(|e| format!("policy {}: {e:#}", spec.name))?;
    let err = |e: &dyn std::fmt::Display| format!("policy {} on the plant: {e}", spec.name);
    let mut slave = Slave::instantiate("sweep", scenario.plant.clone()).map_err(|e| err(&e))?;
    slave
        .enter_initialization_mode(0.0, None)
        .map_err(|e| err(&e))?;
    slave.exit_initialization_mode().map_err(|e| err(&e))?;
    // the plant's communication step (the requested one rounded to whole internal steps), as the
    // co-simulation node runs it
    let disc = scenario.plant.discretisation().map_err(|e| err(&e))?;
    let h = slave.plant().step_length();
    let steps = disc.steps_until(scenario.t_end);
    let mut log = EpisodeLog::new(0);
    let mut last_wave = None;
    for n in 0..steps {
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
        let applied = match policy.act(&obs) {
            Actuation::Wave(w) => {
                last_wave = Some([w.f0, w.k, w.omega]);
                slave.set_wave(w)
            }
            Actuation::Field(f) => slave.set_field(&f),
        };
        applied.map_err(|e| err(&format!("step {n}: actuation refused: {e}")))?;
        match slave.do_step(slave.plant().time(), h) {
            StepStatus::Ok => {}
            StepStatus::Discard { reason, .. } => {
                return Err(err(&format!("step {n} discarded: {reason}")))
            }
            StepStatus::Error(e) => return Err(err(&format!("step {n}: {e}"))),
        }
        log.observe(slave.plant());
    }
    let r = report(&scenario.name, slave.plant(), &log).map_err(|e| err(&e))?;
    Ok(PolicyResult {
        policy: spec.name.clone(),
        run: plant_run(&r),
        steady: r.window.steady,
        wave: last_wave,
    })
}
