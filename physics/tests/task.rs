//! Task mode: a run ends when the body has travelled D (success) or spent J0 (failure).

mod common;

use std::f64::consts::TAU;

use common::{custom, paper, rel, run, Linear};
use crawler_physics::report::mean_position;
use crawler_physics::scenario::Overrides;
use crawler_physics::slave::{Slave, StepStatus};

fn task(distance: f64, energy: f64) -> String {
    format!("[task]\ndistance = {distance:?}\nenergy = {energy:?}\nend_run = true\n")
}

#[test]
fn without_dry_friction_the_budget_runs_out_at_the_closed_form_power() {
    // eps = 0 at resonance: the body does not travel, and the wave's amplitude grows from rest as
    // 1 - exp(-t / tau), tau = 2 rho / c_v, with the muscle force in phase with the velocity. The
    // input power follows, P(t) = P (1 - exp(-t / tau)) with P the exact linear power, so the
    // work is P (t - tau (1 - exp(-t / tau))) and J0 = 40 J is spent at J0 / P + tau.
    let s = custom(0.0, 0.5, TAU, 1.0, 1.0, 256, 60.0, &task(1.0, 40.0));
    let exact = Linear::of(&s);
    let r = run(&s);
    let t = r.task.expect("a task report");
    assert_eq!(t.outcome.as_str(), "energy exhausted");
    let tau = 2.0 * s.plant.body.density / s.plant.friction.viscous;
    let expected = 40.0 / exact.power + tau;
    let at = t.energy_exhausted_at.unwrap();
    assert!(
        rel(at, expected) < 2e-3,
        "budget spent after {at} s, J0 / P + tau = {expected} s"
    );
    // the run stopped at the end of that communication step
    assert!(r.t_end >= at && r.t_end - at <= r.parameters.step * (1.0 + 1e-9));
    assert!(t.distance.abs() < 1e-6);
    assert!(t.time_to_distance.is_none());
}

#[test]
fn reaching_the_distance_ends_the_run_where_the_centre_crosses_it() {
    // eps = 1, f0 = 0.2 N, alpha = 0.5: V = 0.0298 m/s; 0.2 m take about 7 s.
    let s = custom(1.0, 0.2, TAU, 0.5, 1.0, 256, 60.0, &task(0.2, 100.0));
    let r = run(&s);
    let t = r.task.unwrap();
    assert_eq!(t.outcome.as_str(), "reached");
    let reached = t.time_to_distance.unwrap();
    // An independent account: step the same plant and find where the mean displacement crosses.
    let mut slave = Slave::instantiate("task", s.plant.clone()).unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    slave.set_wave(s.wave).unwrap();
    slave.exit_initialization_mode().unwrap();
    let h = slave.plant().step_length();
    let mut n = 0u64;
    let (mut t0, mut x0) = (0.0, 0.0);
    let crossing = loop {
        assert_eq!(slave.do_step(n as f64 * h, h), StepStatus::Ok);
        n += 1;
        let (t1, x1) = (slave.plant().time(), mean_position(slave.plant()));
        if x1 >= 0.2 {
            break t0 + (t1 - t0) * (0.2 - x0) / (x1 - x0);
        }
        (t0, x0) = (t1, x1);
    };
    assert!((reached - crossing).abs() < 1e-9, "{reached} vs {crossing}");
    assert_eq!(
        r.macro_steps, n,
        "the run ends with the step in which the centre crossed"
    );
    assert!(t.energy_at_distance.unwrap() <= t.energy_used);
    assert!(t.energy_used < 100.0);
    // the steady speed after the transient: most of the way at V
    let v = run(&paper(Overrides {
        eps: Some(1.0),
        f0: Some(0.2),
        alpha: Some(0.5),
        cells: Some(256),
        ..Default::default()
    }))
    .velocity;
    assert!(reached > 0.2 / v, "{reached} s, D / V = {} s", 0.2 / v);
    assert!(
        reached < 0.2 / v + 2.0,
        "{reached} s, D / V = {} s",
        0.2 / v
    );
}

#[test]
fn outside_task_mode_the_run_goes_on_and_still_reports_the_task() {
    let s = custom(
        1.0,
        0.2,
        TAU,
        0.5,
        1.0,
        256,
        10.0,
        "[task]\ndistance = 0.1\n",
    );
    let r = run(&s);
    assert!((r.t_end - 10.0).abs() < r.parameters.step);
    let t = r.task.unwrap();
    assert_eq!(t.outcome.as_str(), "reached");
    assert!(t.distance > 0.1);
    assert!(r.window.steady);
}

#[test]
fn the_stress_limit_counts_the_time_above_it() {
    // sigma_max below the run's peak stress: some time above it, none with the limit above.
    let base = custom(1.0, 0.2, TAU, 0.5, 1.0, 256, 10.0, "");
    let peak = run(&base).max_stress;
    let low = run(&custom(
        1.0,
        0.2,
        TAU,
        0.5,
        1.0,
        256,
        10.0,
        &format!("[task]\nsigma_max = {:?}\n", 0.8 * peak),
    ))
    .task
    .unwrap();
    let high = run(&custom(
        1.0,
        0.2,
        TAU,
        0.5,
        1.0,
        256,
        10.0,
        &format!("[task]\nsigma_max = {:?}\n", 1.2 * peak),
    ))
    .task
    .unwrap();
    assert!(low.time_over_sigma_max > 0.1, "{}", low.time_over_sigma_max);
    assert!(low.time_over_sigma_max < 10.0);
    assert_eq!(high.time_over_sigma_max, 0.0);
    assert!(high.max_stress >= peak && high.max_stress < 1.2 * peak);
}
