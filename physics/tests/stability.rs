//! Stability at the characteristic limit: 10^6 internal steps at Courant number 1.

mod common;

use std::f64::consts::TAU;

use common::{custom, rel, run};

/// 64 cells on a 1 m body: dt = 1.32 ms, so 10^6 steps are 1320 s.
fn long(
    eps: f64,
    alpha: f64,
    t_end: f64,
    settle: f64,
    filter: f64,
) -> crawler_physics::report::Report {
    let mut s = custom(
        eps,
        0.5,
        TAU,
        alpha,
        1.0,
        64,
        t_end,
        &format!("filter = {filter:?}"),
    );
    s.plant.numerics.settle = settle;
    assert_eq!(s.plant.discretisation().unwrap().courant, 1.0);
    run(&s)
}

#[test]
fn a_million_steps_at_courant_one_stay_bounded() {
    for (eps, alpha, filter) in [
        (0.0, 1.0, 0.0),
        (0.3, 1.0, 0.1),
        (0.3, 1.0, 0.0),
        (0.3, 0.5, 0.1),
    ] {
        let short = long(eps, alpha, 20.0, 15.0, filter);
        let long = long(eps, alpha, 1330.0, 1320.0, filter);
        assert!(long.steps >= 1_000_000, "{} steps", long.steps);
        // A periodic steady state: the same extremes and averages after 10^6 steps as after 10^4.
        for (name, a, b) in [
            ("max stress", short.max_stress, long.max_stress),
            ("max strain", short.max_strain, long.max_strain),
            ("power", short.power, long.power),
        ] {
            assert!(
                rel(b, a) < 1e-3,
                "eps {eps}, alpha {alpha}, filter {filter}: {name} {a} after 20 s, {b} after 1330 s"
            );
        }
    }
}

#[test]
fn without_the_filter_the_grid_mode_can_take_over_but_stays_bounded() {
    // A wave twice as fast as sound at Courant number 1 (set explicitly; the default would be
    // 1/2): without the filter the checkerboard mode grows until friction limits it; it does
    // not blow up, and the filter removes it.
    let run_at = |filter: f64| {
        let mut s = custom(
            0.3,
            0.5,
            TAU,
            2.0,
            1.0,
            256,
            10.0,
            &format!("filter = {filter:?}"),
        );
        s.plant.numerics.courant = 1.0;
        run(&s)
    };
    let (raw, filtered) = (run_at(0.0), run_at(0.1));
    let mut reference = custom(0.3, 0.5, TAU, 2.0, 1.0, 256, 10.0, "");
    reference.plant.numerics.courant = 0.5;
    let reference = run(&reference);
    println!(
        "sigma: unfiltered {} filtered {} at Courant 0.5 {}",
        raw.max_stress, filtered.max_stress, reference.max_stress
    );
    assert!(raw.max_stress.is_finite() && raw.max_stress < 2.0 * reference.max_stress);
    assert!(
        rel(raw.max_stress, reference.max_stress) > 0.2,
        "the mode did not show"
    );
    assert!(rel(filtered.max_stress, reference.max_stress) < 0.005);
    assert!(rel(filtered.power, reference.power) < 0.005);
}
