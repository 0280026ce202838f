//! One result per input: every route that runs a policy against the plant (in process, a sweep
//! plan's policy run, the co-simulation over zenoh) runs the plant's one execution loop with the
//! controller told the same briefing, so each gives the same state digest and the same report,
//! here with a task that ends the run, a stress limit that binds and a pipe whose friction the
//! controllers are not told.

use std::time::Duration;

use crawler_e2e::{json, Run};
use crawler_physics::scenario::{Overrides, Scenario};
use crawler_policies::Params;
use crawler_sweep::plan::PolicySpec;

/// The mismatch pipe (eps = 0.3, n_F = 0.7, told 0.1 and 0.5), a short task that ends the run
/// and a stress limit below what the waves reach.
fn scenario_text() -> String {
    let base = std::fs::read_to_string(crawler_e2e::repo_root().join("scenarios/mismatch.toml"))
        .expect("scenarios/mismatch.toml");
    base.replace("cells = 512 ", "cells = 128 ")
        .replace("t_end = 60.0 ", "t_end = 8.0 ")
        .replace("settle = 5.0 ", "settle = 1.0 ")
        .replace("distance = 1.0 ", "distance = 0.15 ")
        .replace("sigma_max = 100e3 ", "sigma_max = 12e3 ")
        .replace("[task]", "[task]\nend_run = true")
}

/// What must agree between routes: the final state, the window's metrics (bits), the task.
fn essentials(report: &serde_json::Value) -> serde_json::Value {
    let t = &report["task"];
    serde_json::json!({
        "state_digest": report["state_digest"],
        "steps": report["steps"],
        "velocity": report["velocity"],
        "power": report["power"],
        "max_stress": report["max_stress"],
        "stuck_fraction": report["stuck_fraction"],
        "outcome": t["outcome"],
        "distance": t["distance"],
        "energy_used": t["energy_used"],
        "time_over_sigma_max": t["time_over_sigma_max"],
        "run_time": t["run_time"],
    })
}

#[test]
fn every_policy_gives_one_digest_and_one_report_in_process_in_a_sweep_and_cosimulated() {
    for policy in ["wave", "optimal", "adaptive", "reflex"] {
        let run = Run::new(&format!("one-{policy}"));
        let path = run.path("one-result.toml");
        std::fs::write(&path, scenario_text()).unwrap();
        let scenario = Scenario::from_file(&path, &Overrides::default()).unwrap();
        assert!(!scenario.plant.pipe.disclose && scenario.task.end_run);
        // in process
        let local = crawler_policies::in_process::run_named(&scenario, policy, &Params::none())
            .unwrap_or_else(|e| panic!("{policy} in process: {e:#}"));
        let local_json = serde_json::to_value(&local.report).unwrap();
        let task = local.report.task.as_ref().expect("a task");
        assert!(
            task.time_over_sigma_max > 0.0 || policy == "reflex",
            "{policy}: the stress limit should bind ({} Pa at most)",
            task.max_stress
        );
        // a sweep plan's policy run
        let spec = PolicySpec {
            name: policy.to_string(),
            params: Vec::new(),
        };
        let swept = crawler_sweep::evaluate::policy_run::run_policy(&scenario, &spec)
            .unwrap_or_else(|e| panic!("{policy} in a sweep: {e}"));
        assert_eq!(
            swept.run.state_digest, local.report.state_digest,
            "{policy}: the sweep's run differs from the in-process run"
        );
        assert_eq!(swept.run.metrics, local.report.values(), "{policy}");
        assert_eq!(
            swept.run.task, local.report.task,
            "{policy}: the sweep's task"
        );
        // co-simulated over zenoh
        let file = path.to_str().unwrap();
        let plant = run.plant(&["--scenario", file, "--json"]);
        let controller = run.controller(&["--policy", policy, "--scenario", file]);
        let p = plant.wait(Duration::from_secs(600));
        let c = controller.wait(Duration::from_secs(120));
        assert!(p.status.success(), "{policy}: plant: {}", p.stderr);
        assert!(c.status.success(), "{policy}: controller: {}", c.stderr);
        let co = json(&p.stdout);
        assert_eq!(
            essentials(&co),
            essentials(&local_json),
            "{policy}: the co-simulation differs from the in-process run"
        );
    }
}
