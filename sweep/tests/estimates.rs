//! The sweep's convergence estimate says when it cannot be trusted: where the N and 2N runs agree
//! to round-off because the speed is quantised, and where the Courant number biases the stick
//! statistics that both runs share.

use std::path::Path;

use crawler_facts::Metric;
use crawler_sweep::evaluate::convergence::plant_with_estimate;
use crawler_sweep::plan::Plan;
use crawler_sweep::point::{caveats, resolve, Point};
use crawler_sweep::table::{conv_error, conv_estimate, Untrusted};

/// The validity map's settings (`plans/validity.toml`) at one point, with `extra` set lines.
fn point(k: &str, f0: f64, eps: f64, alpha: f64, extra: &str) -> Point {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../plans");
    let text = format!(
        r#"
name = "estimates"
scenario = "../scenarios/paper.toml"
metrics = ["velocity", "power", "mileage", "stuck_fraction"]

[set]
numerics.cells = 256
numerics.settle = 3.0
numerics.t_end = 4.5
actuation.k = {k}
actuation.f0 = {f0}
friction.eps = {eps}
actuation.alpha = {alpha}
{extra}

[evaluate]
plant = true
convergence = true
"#
    );
    let plan = Plan::from_toml(&text, "estimates.toml", &dir).unwrap();
    let mut points = resolve(&plan).unwrap();
    assert_eq!(points.len(), 1);
    points.pop().unwrap()
}

#[test]
fn a_speed_quantised_at_courant_one_over_alpha_is_flagged_not_reported_as_converged() {
    // alpha 1.7 > 1.1: the default Courant number is 1/alpha and the wave moves one cell per
    // step; the speed then comes in steps of about eps c_d / (c_v 2N)
    let p = point("12.566370614359172", 0.15, 0.05, 1.7, "");
    assert!((p.scenario.plant.numerics.courant - 1.0 / 1.7).abs() < 1e-12);
    let r = plant_with_estimate(&p.scenario, true).unwrap();
    let fine = r.run.metrics.get(Metric::Velocity).unwrap();
    let coarse = r
        .coarse
        .as_ref()
        .unwrap()
        .metrics
        .get(Metric::Velocity)
        .unwrap();
    let agreement = (fine - coarse).abs() / fine.abs();
    println!("V(2N) = {fine:e}, V(N) = {coarse:e}, relative difference {agreement:e}");
    assert!(agreement < 1e-9, "the two runs agree to round-off here");
    // because both are whole multiples of the quantum eps c_d / (c_v 2N)
    let f = &p.scenario.plant.friction;
    let quantum = f.eps * f.dry / (f.viscous * 2.0 * p.scenario.plant.numerics.cells as f64);
    let steps = fine / quantum;
    assert!((steps - steps.round()).abs() < 1e-6, "V = {steps} quanta");
    assert_eq!(
        conv_estimate(&r, Metric::Velocity, &p),
        Some(Err(Untrusted::Quantised))
    );
    assert_eq!(conv_error(&r, Metric::Velocity, &p), None);

    // and the agreement says nothing: the run at 4N differs from the 2N run by far more
    let mut finer = p.scenario.clone();
    finer.plant.numerics.cells *= 4;
    let f4 = crawler_physics::simulate::simulate(
        &finer,
        crawler_sweep::evaluate::convergence::run_options(),
    )
    .unwrap()
    .velocity;
    let moved = (f4 - fine).abs() / fine.abs();
    println!("V(4N) = {f4:e}: {moved:e} from V(2N)");
    assert!(
        moved > 1e-5,
        "the 2N run's error is not round-off: {moved:e}"
    );
}

#[test]
fn a_speed_that_converges_gets_an_estimate() {
    // below the switch (Courant 1): the difference estimates the error as before
    let p = point("12.566370614359172", 0.5, 0.1, 0.8, "");
    let r = plant_with_estimate(&p.scenario, true).unwrap();
    let e = conv_estimate(&r, Metric::Velocity, &p).unwrap().unwrap();
    assert!(e > 0.0 && e < 0.05, "{e:e}");
    let s = conv_estimate(&r, Metric::StuckFraction, &p).unwrap();
    assert!(s.is_ok(), "{s:?}");
}

#[test]
fn stick_statistics_at_a_biased_courant_number_have_no_estimate() {
    // numerics.courant = 0.9 at alpha 1.7 biases the stuck fraction (0.351 against 0.390);
    // N and 2N share the bias, so their difference is withheld
    let p = point(
        "12.566370614359172",
        0.2,
        1.0,
        1.7,
        "numerics.courant = 0.9",
    );
    assert_eq!(p.scenario.caveats().len(), 1);
    // the sweep warns once per distinct caveat, with its field, value and the default
    let warned = caveats(std::slice::from_ref(&p));
    assert_eq!(warned.len(), 1);
    assert!(
        warned[0].0.starts_with("numerics.courant = 0.9 ") && warned[0].0.contains("1 / alpha"),
        "{warned:?}"
    );
    assert_eq!(warned[0].1, 1);
    let r = plant_with_estimate(&p.scenario, true).unwrap();
    assert_eq!(
        conv_estimate(&r, Metric::StuckFraction, &p),
        Some(Err(Untrusted::BiasedCourant))
    );
    // the speed's estimate is still given
    assert!(conv_estimate(&r, Metric::Velocity, &p).is_some_and(|e| e.is_ok()));
}
