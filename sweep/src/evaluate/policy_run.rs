//! A co-simulated policy evaluated in process: the plant's execution loop with the policy as its
//! controller, told what a co-simulated controller is told (the plant's step, the nominal
//! friction of an undisclosed pipe), with the scenario's task and stress limit; bit-identical to
//! a co-simulated run of the same scenario and policy.

use crawler_physics::scenario::Scenario;

use crate::plan::PolicySpec;
use crate::record::PolicyResult;

use super::convergence::plant_run;

/// Runs `spec`'s policy against the plant of `scenario` from t = 0 to its end (or until its task
/// ends the run in task mode).
pub fn run_policy(scenario: &Scenario, spec: &PolicySpec) -> Result<PolicyResult, String> {
    let run = crawler_policies::in_process::run_named(scenario, &spec.name, &spec.params())
        .map_err(|e| format!("policy {} on the plant: {e:#}", spec.name))?;
    let w = run.last_wave;
    Ok(PolicyResult {
        policy: spec.name.clone(),
        run: plant_run(&run.report),
        steady: run.report.window.steady,
        wave: w.map(|w| [w.f0, w.k, w.omega]),
    })
}
