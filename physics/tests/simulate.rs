//! `simulate` reports its progress through the caller's callback and draws nothing itself.

use crawler_physics::scenario::{Overrides, Scenario};
use crawler_physics::simulate::{simulate, SimulateOptions};

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
