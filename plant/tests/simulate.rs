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
