//! The improved reduced model against converged plant runs, sticking regimes included.

use crawler_models::travelling_wave::TravellingWaveModel;
use crawler_models::{Model, OperatingPoint};
use crawler_physics::scenario::{Overrides, Scenario};
use crawler_physics::simulate::{simulate, SimulateOptions};

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// The default scenario with this friction and drive; with `cells`, set up for a 10 s plant run.
fn scenario(eps: f64, f0: f64, alpha: f64, cells: Option<i64>) -> Scenario {
    Scenario::load(
        None,
        &Overrides {
            eps: Some(eps),
            f0: Some(f0),
            alpha: Some(alpha),
            cells,
            t_end: cells.map(|_| 10.0),
            ..Default::default()
        },
    )
    .unwrap()
}

/// The default scenario's operating point with this friction and drive.
fn point(eps: f64, f0: f64, alpha: f64) -> OperatingPoint {
    OperatingPoint::of(&scenario(eps, f0, alpha, None))
}

/// (eps, f0, alpha, cells): cells chosen so that the plant itself is converged to well under 1 %.
const POINTS: &[(f64, f64, f64, i64)] = &[
    (0.1, 0.5, 0.3, 2048), // a slow wave: sigma converges at first order (velocity reversals)
    (0.1, 0.5, 0.5, 512),
    (0.1, 0.5, 1.0, 512),
    (0.3, 0.5, 2.0, 512),
    (0.5, 0.5, 1.5, 512),
    (1.0, 0.5, 0.5, 1024),
    (1.0, 0.5, 1.0, 1024),
    (1.0, 0.2, 0.5, 2048), // sticks ~43 % of the time; V converges at first order in dt
    (1.0, 0.2, 1.8, 1024), // sticks ~42 % of the time, above resonance
    (1.0, 0.1, 0.5, 2048), // sticks ~69 % of the time
];

#[test]
fn predicts_speed_power_and_stress_within_one_percent_of_the_plant() {
    let model = TravellingWaveModel::default();
    for &(eps, f0, alpha, cells) in POINTS {
        let s = scenario(eps, f0, alpha, Some(cells));
        let plant = simulate(&s, SimulateOptions::default()).unwrap();
        let p = model.predict(&OperatingPoint::of(&s));
        let (v, pw, sg) = (p.velocity.unwrap(), p.power.unwrap(), p.max_stress.unwrap());
        println!(
            "eps {eps} f0 {f0} alpha {alpha}: V {:+.3}% P {:+.3}% sigma {:+.3}% stuck {:.3}/{:.3}",
            100.0 * (v / plant.velocity - 1.0),
            100.0 * (pw / plant.power - 1.0),
            100.0 * (sg / plant.max_stress - 1.0),
            p.stuck_fraction.unwrap(),
            plant.stuck_fraction
        );
        assert!(
            rel(v, plant.velocity) < 0.01,
            "eps {eps} f0 {f0} alpha {alpha}: V {v} vs plant {}",
            plant.velocity
        );
        assert!(
            rel(pw, plant.power) < 0.01,
            "eps {eps} f0 {f0} alpha {alpha}: P {pw} vs plant {}",
            plant.power
        );
        assert!(
            rel(sg, plant.max_stress) < 0.01,
            "eps {eps} f0 {f0} alpha {alpha}: sigma {sg} vs plant {}",
            plant.max_stress
        );
        if plant.stuck_fraction > 0.3 {
            assert!(
                rel(p.stuck_fraction.unwrap(), plant.stuck_fraction) < 0.05,
                "stuck fraction"
            );
            assert!(
                rel(
                    p.episodes_per_node_per_period.unwrap(),
                    plant.events.per_node_per_period
                ) < 0.05,
                "episodes"
            );
        }
    }
}

#[test]
fn satisfies_the_steady_identity_and_bound() {
    let model = TravellingWaveModel::default();
    for &(eps, f0, alpha, _) in POINTS {
        let op = point(eps, f0, alpha);
        let p = model.predict(&op);
        let f = op.friction;
        let v = p.velocity.unwrap();
        let identity = f.band() * (f.n_f - p.mean_friction_selection.unwrap()) / f.viscous;
        assert!(
            (v - identity).abs() < 1e-3 * v.abs(),
            "V {v} vs identity {identity}"
        );
        assert!(v.abs() <= f.speed_bound());
    }
}

#[test]
fn a_forcing_too_strong_for_f64_is_outside_validity_not_noise() {
    let model = TravellingWaveModel::default();
    let at = |f0: f64| {
        let s = Scenario::load(
            None,
            &Overrides {
                f0: Some(f0),
                ..Default::default()
            },
        )
        .unwrap();
        model.predict(&OperatingPoint::of(&s))
    };
    let reference = at(100.0).velocity.unwrap();
    // strong but representable: the speed saturates at the same value, every number finite
    for f0 in [1e3, 1e6, 1e9] {
        let p = at(f0);
        assert!(p.validity.is_valid(), "f0 = {f0}: {:?}", p.validity);
        let v = p.velocity.unwrap();
        assert!(rel(v, reference) < 1e-4, "f0 = {f0}: V {v} vs {reference}");
        assert!(p.power.unwrap().is_finite() && p.max_stress.unwrap().is_finite());
    }
    // where the round-off swamps the speed (V changes sign near 1e14 N) and where P overflows
    for f0 in [1e14, 1e16, 1e200, 1e300] {
        let p = at(f0);
        let reason = match &p.validity {
            crawler_models::Validity::OutsideValidity(r) => r.clone(),
            v => panic!("f0 = {f0}: {v:?}, V = {:?}, P = {:?}", p.velocity, p.power),
        };
        assert!(reason.contains("round-off"), "{reason}");
        assert!(p.velocity.is_none() && p.power.is_none());
    }
}

#[test]
fn refines_towards_a_limit_as_the_march_is_refined() {
    let op = point(1.0, 0.2, 0.5);
    let v: Vec<f64> = [512, 2048, 8192]
        .iter()
        .map(|&steps| {
            TravellingWaveModel {
                steps,
                ..Default::default()
            }
            .predict(&op)
            .velocity
            .unwrap()
        })
        .collect();
    assert!((v[1] - v[2]).abs() < (v[0] - v[2]).abs(), "{v:?}");
    assert!(rel(v[1], v[2]) < 2e-3, "{v:?}");
}

/// At the operating point `--policy optimal` picks on the paper's scenario (alpha = 1.001, four
/// waves on the 1 m body; here one wave on its own wavelength), the travelling-frame inertia kappa
/// almost vanishes and the body sticks in two short phases per period, 2.5 % of the time. The
/// plant resolves them at the main job's resolution (192 cells per wavelength, Courant number 1);
/// the model's value is converged in its march.
#[test]
fn near_resonance_the_plant_and_the_model_agree_on_the_stick_phases() {
    let load = |cells: i64| {
        Scenario::load(
            None,
            &Overrides {
                f0: Some(0.0577),
                k: Some(8.0 * std::f64::consts::PI),
                alpha: Some(1.001),
                cells: Some(cells),
                t_end: Some(10.0),
                ..Default::default()
            },
        )
        .unwrap()
    };
    // the model's own limit: refining the march leaves the stuck fraction where it is
    let op = OperatingPoint::of(&load(192));
    let model: Vec<_> = [1024, 4096, 16384]
        .iter()
        .map(|&steps| {
            TravellingWaveModel {
                steps,
                ..Default::default()
            }
            .predict(&op)
        })
        .collect();
    let stuck: Vec<f64> = model.iter().map(|p| p.stuck_fraction.unwrap()).collect();
    assert!(rel(stuck[1], stuck[2]) < 0.01, "{stuck:?}");
    assert!(rel(stuck[0], stuck[2]) < 0.03, "{stuck:?}");
    let m = &model[0];
    assert_eq!(m.episodes_per_node_per_period, Some(2.0));
    let plant = simulate(&load(192), SimulateOptions::default()).unwrap();
    println!(
        "model stuck {stuck:?}, plant N = 192: stuck {} episodes {} per node per period",
        plant.stuck_fraction, plant.events.per_node_per_period
    );
    assert!(
        rel(plant.stuck_fraction, stuck[2]) < 0.05,
        "plant {} vs model {}",
        plant.stuck_fraction,
        stuck[2]
    );
    assert!(
        (plant.events.per_node_per_period - 2.0).abs() < 0.05,
        "{}",
        plant.events.per_node_per_period
    );
    assert!(rel(plant.velocity, m.velocity.unwrap()) < 1e-3);
    assert!(rel(plant.power, m.power.unwrap()) < 5e-3);
    assert!(rel(plant.max_stress, m.max_stress.unwrap()) < 5e-3);
}

/// A prediction and the steady profile come from the same periodic solution: the profile's
/// mean velocity and mean friction selection are the predicted V and <s> to the last bit (the
/// prediction takes its sums from the sweep that found the fixed point, the profile from a
/// sweep of its own at that point), on sliding, reversing and sticking points.
#[test]
fn the_profile_is_the_solution_the_prediction_reports() {
    let model = TravellingWaveModel::default();
    let mut sticking = 0;
    for &(eps, f0, alpha, _) in POINTS
        .iter()
        .chain(&[(0.1, 0.5, 2.0, 0), (1.0, 1.0, 0.9, 0)])
    {
        let op = point(eps, f0, alpha);
        let p = model.predict(&op);
        let profile = model.profile(&op).expect("a periodic solution");
        let n = profile.velocity.len();
        assert_eq!(n, model.steps);
        let mean = |x: &[f64]| x.iter().sum::<f64>() / n as f64;
        let at = format!("eps {eps} f0 {f0} alpha {alpha}");
        assert_eq!(mean(&profile.velocity), p.velocity.unwrap(), "V at {at}");
        assert_eq!(
            mean(&profile.selection),
            p.mean_friction_selection.unwrap(),
            "<s> at {at}"
        );
        if p.stuck_fraction.unwrap() > 0.0 {
            sticking += 1;
        }
    }
    assert!(sticking >= 3, "{sticking} sticking points");
}
