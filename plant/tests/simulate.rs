//! `simulate` reports its progress through the caller's callback and draws nothing itself.

use crawler_plant::scenario::{Overrides, Scenario};
use crawler_plant::simulate::{simulate, SimulateOptions};

#[test]
fn progress_is_reported_every_256_steps_and_at_the_end_without_changing_the_run() {
    let s = Scenario::load(
        None,
        &Overrides {
            t_end: Some(5.2),
            ..Overrides::default()
        },
    )
    .unwrap();
    let steps = s.plant.discretisation().unwrap().steps_until(s.t_end);
    assert!(steps > 1000);
    let mut calls = Vec::new();
    let mut record = |done: u64, total: u64| calls.push((done, total));
    let with = simulate(
        &s,
        SimulateOptions {
            progress: Some(&mut record),
            ..SimulateOptions::default()
        },
    )
    .unwrap();
    let without = simulate(&s, SimulateOptions::default()).unwrap();
    assert_eq!(with.state_digest, without.state_digest);
    assert_eq!(with.macro_steps, steps);
    let expected: Vec<(u64, u64)> = (0..steps)
        .step_by(256)
        .map(|n| (n + 1, steps))
        .chain([(steps, steps)])
        .collect();
    assert_eq!(calls, expected);
}

/// The report on the wire (the plant's finished status) is the library's report converted in one
/// place: the same numbers, a not-a-number ratio as `None`, anything else non-finite refused by
/// name, the task's outcome in the same words.
#[test]
fn the_report_on_the_wire_holds_the_reports_numbers() {
    use crawler_protocol::{FinalReport, TaskOutcome};
    let s = Scenario::load(
        None,
        &Overrides {
            t_end: Some(5.2),
            ..Overrides::default()
        },
    )
    .unwrap();
    let r = simulate(&s, SimulateOptions::default()).unwrap();
    let w = FinalReport::try_from(&r).unwrap();
    assert_eq!(w.scenario, r.scenario);
    for (wire, lib) in [
        (w.velocity, r.velocity),
        (w.power, r.power),
        (w.mileage.unwrap(), r.mileage),
        (w.max_stress, r.max_stress),
        (w.max_strain, r.max_strain),
        (w.stuck_fraction, r.stuck_fraction),
        (w.mean_friction_selection, r.mean_friction_selection),
        (w.dissipation, r.dissipation),
        (w.identity_velocity, r.identity_velocity),
        (w.momentum_residual.unwrap(), r.momentum_residual),
        (w.events.per_node_per_period, r.events.per_node_per_period),
        (w.events.mean_duration, r.events.mean_duration),
        (w.events.min_duration, r.events.min_duration),
        (w.window.start, r.window.start),
        (w.window.end, r.window.end),
        (w.window.periods, r.window.periods),
        (w.dt, r.dt),
        (w.step, r.parameters.step),
        (w.courant, r.parameters.courant),
        (w.dx, r.parameters.dx),
        (
            w.cells_per_wavelength.unwrap(),
            r.parameters.cells_per_wavelength.unwrap(),
        ),
        (w.t_end, r.t_end),
    ] {
        assert_eq!(wire.to_bits(), lib.to_bits());
    }
    assert_eq!(w.events.count, r.events.count);
    assert_eq!(
        (w.window.steady, w.window.whole_run),
        (r.window.steady, r.window.whole_run)
    );
    assert_eq!(
        (w.cells, w.steps, w.macro_steps),
        (r.cells as u64, r.steps, r.macro_steps)
    );
    assert_eq!(w.state_digest, r.state_digest);
    let (t, lib) = (w.task.unwrap(), r.task.as_ref().unwrap());
    assert_eq!(t.outcome.as_str(), lib.outcome);
    assert_eq!(
        (
            t.time_to_distance,
            t.energy_at_distance,
            t.energy_exhausted_at
        ),
        (
            lib.time_to_distance,
            lib.energy_at_distance,
            lib.energy_exhausted_at
        )
    );
    assert_eq!(
        (t.distance_target, t.energy_budget, t.sigma_max),
        (lib.distance_target, lib.energy_budget, lib.sigma_max)
    );
    assert_eq!(t.time_over_sigma_max, lib.time_over_sigma_max);
    assert_eq!(
        (t.distance, t.energy_used, t.max_stress, t.run_time),
        (lib.distance, lib.energy_used, lib.max_stress, lib.run_time)
    );
    // every outcome the tracker reports has its word on the wire
    for o in [
        crawler_plant::task::Outcome::Reached,
        crawler_plant::task::Outcome::EnergyExhausted,
        crawler_plant::task::Outcome::TimeUp,
    ] {
        assert_eq!(TaskOutcome::parse(o.as_str()).unwrap().as_str(), o.as_str());
    }
    // P = 0 and a body at rest: the ratios are not numbers, and travel as None
    let mut rest = r.clone();
    rest.mileage = f64::NAN;
    rest.momentum_residual = f64::INFINITY;
    let w = FinalReport::try_from(&rest).unwrap();
    assert_eq!((w.mileage, w.momentum_residual), (None, None));
    // anything else not finite is refused, by name
    let mut bad = r.clone();
    bad.velocity = f64::NAN;
    let err = FinalReport::try_from(&bad).unwrap_err().to_string();
    assert!(err.contains("report.velocity = NaN"), "{err}");
    // a long scenario name is cut to the protocol's limit
    let mut long = r;
    long.scenario = "é".repeat(100);
    let w = FinalReport::try_from(&long).unwrap();
    assert!(w.scenario.len() <= crawler_protocol::MAX_SCENARIO_NAME_LEN && w.scenario.len() >= 126);
}

/// The scenario check and the run agree on the shortest run with a steady window: just below
/// the least t_end the check names, the check refuses it (by field and value); at that t_end the
/// run reports steady metrics. (The check used to ask for settle + one period, which passed
/// t_end = 5.1 s here, and the run then failed after its last step: the period that starts after
/// settle had not ended.)
#[test]
fn the_least_t_end_the_check_accepts_gives_a_steady_window() {
    let load = |t_end: f64, cells: i64| {
        Scenario::load(
            None,
            &Overrides {
                t_end: Some(t_end),
                cells: Some(cells),
                ..Overrides::default()
            },
        )
    };
    for cells in [64, 96, 512] {
        let e = load(5.1, cells).unwrap_err().to_string();
        assert!(
            e.contains("numerics.t_end") && e.contains("5.1") && e.contains("allowed"),
            "{e}"
        );
        // "a run of at least X s": the least run the check accepts
        let least: f64 = e
            .split("a run of at least ")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .and_then(|x| x.parse().ok())
            .unwrap_or_else(|| panic!("no least run in {e}"));
        // the paper's period is 1/sqrt(140) s: the first one after 5 s ends at 61 periods
        let period = 1.0 / 140f64.sqrt();
        assert!(
            least > 61.0 * period && least < 61.0 * period + 0.01,
            "{least}"
        );
        let s = load(least, cells).unwrap();
        let r = simulate(&s, SimulateOptions::default()).unwrap();
        assert!(
            r.window.steady,
            "{cells} cells: no steady window at t_end = {least}"
        );
        // one communication step less is refused
        let h = s.plant.discretisation().unwrap().step;
        let shorter = load(s.t_end - 1.5 * h, cells).unwrap_err().to_string();
        assert!(shorter.contains("numerics.t_end"), "{shorter}");
    }
}
