//! The optimiser: constraints hold, the paper's observation, the ridge and its tie-break,
//! certification, bad input.

mod common;

use std::f64::consts::TAU;

use crawler_models::optimizer::{
    Binding, BodyLength, GridSpec, ModelChoice, OptimizeError, OptimizeReport, Problem,
    DEFAULT_TIE_TOLERANCE,
};
use crawler_models::paper_model::PaperModel;
use crawler_models::verify;
use crawler_models::Model;
use crawler_physics::scenario::Scenario;

fn problem(body_length: BodyLength) -> Problem {
    let s = Scenario::paper();
    Problem {
        body: s.plant.body,
        friction: s.plant.friction,
        task: s.task,
        limits: s.limits,
        body_length,
    }
}

#[test]
fn paper_optimum_satisfies_every_constraint_of_its_model() {
    let p = problem(BodyLength::OneWavelength);
    let r = p
        .optimize(&ModelChoice::Paper, &GridSpec::new(120, 120))
        .unwrap();
    let o = &r.optimum;
    assert!(o.margins.all_hold(1e-9), "{:?}", o.margins);
    assert!(o.omega >= p.limits.omega[0] && o.omega <= p.limits.omega[1]);
    assert!(o.k >= p.limits.k[0] && o.k <= p.limits.k[1]);
    assert!(o.f0 <= p.limits.f0_max);
    // every feasible cell also satisfies them (checked through the model's own predictions)
    for c in r.cells.iter().filter(|c| c.velocity.is_some()) {
        let pred = ModelChoice::Paper.predict(&p.point(c.omega, c.k, c.f0.unwrap()));
        assert!(pred.mileage.unwrap() >= p.task.min_mileage() * (1.0 - 1e-9));
        assert!(pred.max_stress.unwrap() <= p.task.sigma_max * (1.0 + 1e-9));
        assert!(pred.max_strain.unwrap() <= p.limits.strain_max * (1.0 + 1e-9));
        assert!((pred.velocity.unwrap() - c.velocity.unwrap()).abs() < 1e-9 * c.velocity.unwrap());
    }
    assert_is_the_tie_break_optimum(&r);
    // on the ridge V = V(k) the lowest f0 is at resonance on the k bound (docs/physics.md §5.3)
    assert!((o.k - p.limits.k[1]).abs() < 1e-9 * o.k, "k = {}", o.k);
    assert!((o.alpha - 1.0).abs() < 1e-3, "alpha = {}", o.alpha);
}

/// The optimum is the lowest-f0 point among those within the tolerance of the fastest speed:
/// no grid cell is faster by more than the tolerance, and none within it has a lower f0.
fn assert_is_the_tie_break_optimum(r: &OptimizeReport) {
    let o = &r.optimum;
    let t = &r.tie_break;
    let v = o.prediction.velocity.unwrap();
    let fastest = r
        .cells
        .iter()
        .filter_map(|c| c.velocity)
        .fold(0.0f64, f64::max);
    assert!(t.fastest_velocity >= fastest);
    assert!(
        v >= t.fastest_velocity * (1.0 - t.tolerance) * (1.0 - 1e-12),
        "optimum V = {v} more than {} below the fastest {}",
        t.tolerance,
        t.fastest_velocity
    );
    let mut tied = 0;
    for c in r.cells.iter().filter(|c| c.velocity.is_some()) {
        let (cv, cf) = (c.velocity.unwrap(), c.f0.unwrap());
        if cv >= fastest * (1.0 - t.tolerance) {
            tied += 1;
            assert!(
                o.f0 <= cf * (1.0 + 1e-9),
                "cell (omega {}, k {}) ties at V = {cv} with f0 = {cf} < the optimum's {}",
                c.omega,
                c.k,
                o.f0
            );
        }
    }
    assert_eq!(tied, t.tied_cells);
}

/// The largest `f0` at which the paper model still meets the mileage budget at `(omega, k)`, and
/// the speed there, solved cell by cell from the model's predictions (bisection on `M(f0)`), not
/// with the optimiser's per-row root.
fn speed_at_the_mileage_bound(p: &Problem, omega: f64, k: f64) -> Option<(f64, f64)> {
    let req = p.task.min_mileage();
    let mileage = |f0: f64| {
        let pred = PaperModel::default().predict(&p.point(omega, k, f0));
        match (pred.velocity, pred.mileage) {
            (Some(v), Some(m)) if v > 0.0 => m,
            _ => 0.0,
        }
    };
    // M(f0) rises from the validity limit to a peak, then falls like 1 / f0^2
    let grid: Vec<f64> = (0..=600)
        .map(|i| 1e-3 * 1e4f64.powf(i as f64 / 600.0))
        .collect();
    let peak = grid
        .iter()
        .copied()
        .max_by(|a, b| mileage(*a).total_cmp(&mileage(*b)))?;
    if mileage(peak) < req {
        return None;
    }
    let (mut lo, mut hi) = (peak, peak);
    while mileage(hi) >= req {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mileage(mid) >= req {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let v = PaperModel::default()
        .predict(&p.point(omega, k, lo))
        .velocity?;
    Some((lo, v))
}

#[test]
fn at_the_mileage_bound_the_speed_depends_on_k_only() {
    // Paper Fig. 6(b) / docs/physics.md §5.2: with f0 at the mileage bound V is a function of k
    // alone. Solved here cell by cell from the model's predictions, for frequencies on both sides
    // of resonance.
    let p = problem(BodyLength::OneWavelength);
    let c = p.body.wave_speed();
    let mut rows = Vec::new();
    for k in [TAU, 2.0 * TAU, 4.0 * TAU] {
        let speeds: Vec<f64> = [0.5, 0.8, 1.0, 1.25, 1.6]
            .iter()
            .map(|alpha| speed_at_the_mileage_bound(&p, alpha * k * c, k).unwrap().1)
            .collect();
        let (lo, hi) = speeds
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        assert!(
            (hi - lo) / hi < 1e-9,
            "k = {k}: V varies with omega at the mileage bound: {speeds:?}"
        );
        rows.push(hi);
    }
    // ... and it grows with k (a shorter one-wavelength body dissipates less), so the optimum
    // sits on the k bound
    assert!(rows[0] < rows[1] && rows[1] < rows[2], "{rows:?}");
    // the closed form of docs/physics.md §5.2 at k = 8 pi: z = 0.0179, V = 0.04886 m/s
    assert!((rows[2] - 0.04886).abs() < 1e-5, "{rows:?}");
    // The optimiser's cells where the mileage binds agree with the cell-by-cell solution, and
    // its fastest cell (no tie-break) lies on the k bound.
    let r = p
        .optimize(
            &ModelChoice::Paper,
            &GridSpec {
                refine: false,
                tie_tolerance: 0.0,
                ..GridSpec::new(40, 12)
            },
        )
        .unwrap();
    let mut checked = 0;
    for cell in r
        .cells
        .iter()
        .filter(|c| c.binding == Binding::Mileage)
        .step_by(7)
    {
        let (f0, v) = speed_at_the_mileage_bound(&p, cell.omega, cell.k).unwrap();
        assert!(
            (f0 - cell.f0.unwrap()).abs() < 1e-7 * f0,
            "{cell:?}: f0 {f0}"
        );
        assert!(
            (v - cell.velocity.unwrap()).abs() < 1e-9 * v,
            "{cell:?}: V {v}"
        );
        checked += 1;
    }
    assert!(
        checked >= 10,
        "mileage binds on too few cells to test ({checked})"
    );
    assert!(
        (r.optimum.k - p.limits.k[1]).abs() < 1e-9 * p.limits.k[1],
        "optimum k {}",
        r.optimum.k
    );
}

#[test]
fn on_a_fixed_body_the_paper_model_speed_at_the_mileage_bound_is_one_plateau() {
    // docs/physics.md §5.3: on a body of fixed length P = (c_v v_amp^2 / 2) L for every k, so the
    // mileage bound fixes the same speed for every (omega, k): V = 0.04769 m/s on a 1 m body.
    let p = problem(BodyLength::Fixed(1.0));
    let c = p.body.wave_speed();
    for m in [1.0, 2.0, 4.0] {
        let k = TAU * m;
        for alpha in [0.7, 1.0, 1.4] {
            let (_, v) = speed_at_the_mileage_bound(&p, alpha * k * c, k).unwrap();
            assert!(
                (v - 0.047695).abs() < 2e-6,
                "k = {k}, alpha = {alpha}: V = {v} off the plateau"
            );
        }
    }
}

#[test]
fn at_resonance_the_improved_model_depends_on_f0_k_alone() {
    // docs/physics.md §5.3: at alpha = 1 the travelling-wave equation (4.1) has no inertia term,
    // so the velocity profile, V and the power per unit length depend on the drive only through
    // f0 k. On a fixed body the mileage bound therefore fixes the same V for every k that fits:
    // the ridge is exactly flat in k.
    let model = ModelChoice::parse("improved").unwrap();
    let p = problem(BodyLength::Fixed(1.0));
    let c = p.body.wave_speed();
    let f0_k = 1.45; // N/m, near the mileage bound of the paper's task
    let at = |m: f64| {
        let k = TAU * m;
        model.predict(&p.point(k * c, k, f0_k / k))
    };
    let one = at(1.0);
    for m in [2.0, 4.0] {
        let other = at(m);
        for (what, a, b) in [
            ("V", one.velocity, other.velocity),
            ("P", one.power, other.power),
            ("stuck fraction", one.stuck_fraction, other.stuck_fraction),
        ] {
            let (a, b) = (a.unwrap(), b.unwrap());
            assert!(
                (a - b).abs() <= 1e-9 * a.abs().max(1e-12),
                "{what}: {a} vs {b} at k = {m} x 2 pi"
            );
        }
    }
    // ... while off resonance the same f0 k gives a different speed
    let k = 2.0 * TAU;
    let off = model.predict(&p.point(0.7 * k * c, k, f0_k / k));
    assert!((off.velocity.unwrap() - one.velocity.unwrap()).abs() > 1e-3 * one.velocity.unwrap());
}

#[test]
fn improved_optimum_on_a_fixed_body_satisfies_its_constraints_and_certifies_on_the_plant() {
    let p = problem(BodyLength::Fixed(1.0));
    let r = p
        .optimize(
            &ModelChoice::parse("improved").unwrap(),
            &GridSpec::new(48, 0),
        )
        .unwrap();
    let o = &r.optimum;
    assert!(o.margins.all_hold(1e-6), "{:?}", o.margins);
    assert!(
        (o.k * 1.0 / TAU - (o.k / TAU).round()).abs() < 1e-9,
        "k fits the body"
    );
    // The ridge (docs/physics.md §5.3): the cells near resonance of every wave number that fits
    // tie within the tolerance, and the lowest f0 among them is at resonance on the shortest
    // wave, where f0 = c_v v_amp / k is smallest.
    assert_is_the_tie_break_optimum(&r);
    let t = &r.tie_break;
    assert!(
        t.tied_cells >= 4 && t.tied_k == [p.limits.k[0], p.limits.k[1]],
        "{t:?}"
    );
    assert!(t.tied_speed_spread < DEFAULT_TIE_TOLERANCE, "{t:?}");
    assert!((o.k - p.limits.k[1]).abs() < 1e-9 * o.k, "k = {}", o.k);
    assert!((o.alpha - 1.0).abs() < 0.01, "alpha = {}", o.alpha);
    // Without the tolerance the fastest cell wins, at a higher f0.
    let fastest = p
        .optimize(
            &ModelChoice::parse("improved").unwrap(),
            &GridSpec {
                tie_tolerance: 0.0,
                ..GridSpec::new(48, 0)
            },
        )
        .unwrap();
    let top = fastest.optimum.prediction.velocity.unwrap();
    assert!(fastest.tie_break.speed_given_up == 0.0);
    for c in fastest.cells.iter().filter_map(|c| c.velocity) {
        assert!(
            top >= c,
            "a cell is faster ({c}) than the tolerance-0 optimum {top}"
        );
    }
    let base = Scenario::paper();
    let c = verify::certify(&base, &p, o, 0.005, 8).unwrap();
    assert!(c.certified);
    let last = c.runs.iter().find(|v| (v.f0 - c.f0).abs() < 1e-15).unwrap();
    assert!(
        last.plant_margins.mileage >= 0.005
            && last.plant_margins.stress >= 0.005
            && last.plant_margins.strain >= 0.005
    );
    assert!(last.holds.mileage && last.holds.stress && last.holds.strain && last.holds.f0);
}

#[test]
fn bad_problems_are_refused_with_the_field_at_fault() {
    let mut p = problem(BodyLength::OneWavelength);
    let grid = GridSpec {
        refine: false,
        ..GridSpec::new(10, 10)
    };
    p.limits.omega = [300.0, 10.0];
    let e = p
        .optimize(&ModelChoice::Paper, &grid)
        .unwrap_err()
        .to_string();
    assert!(e.contains("limits.omega"), "{e}");
    let mut p = problem(BodyLength::OneWavelength);
    p.task.energy = -1.0;
    let e = p
        .optimize(&ModelChoice::Paper, &grid)
        .unwrap_err()
        .to_string();
    assert!(e.contains("task.energy") && e.contains("-1"), "{e}");
    let mut p = problem(BodyLength::OneWavelength);
    p.limits.f0_max = f64::NAN;
    assert!(p
        .optimize(&ModelChoice::Paper, &grid)
        .unwrap_err()
        .to_string()
        .contains("limits.f0_max"));
    // an impossible budget: the message says mileage is what makes it infeasible
    let mut p = problem(BodyLength::OneWavelength);
    p.task.energy = 1e-6;
    match p.optimize(&ModelChoice::Paper, &grid) {
        Err(OptimizeError::Infeasible(msg)) => assert!(msg.contains("mileage"), "{msg}"),
        other => panic!("expected infeasible, got {other:?}"),
    }
    // a stress limit so low that no amplitude moves the crawler forward under the budget
    let mut p = problem(BodyLength::OneWavelength);
    p.task.sigma_max = 1.0;
    match p.optimize(&ModelChoice::Paper, &grid) {
        Err(OptimizeError::Infeasible(msg)) => assert!(msg.contains("stress"), "{msg}"),
        other => panic!("expected infeasible, got {other:?}"),
    }
    assert!(ModelChoice::parse("magic").is_err());
    // the tie tolerance is a share of the speed
    for bad in [-1e-3, 0.5, f64::NAN] {
        let e = problem(BodyLength::OneWavelength)
            .optimize(
                &ModelChoice::Paper,
                &GridSpec {
                    tie_tolerance: bad,
                    ..grid
                },
            )
            .unwrap_err()
            .to_string();
        assert!(e.contains("invalid grid.tie_tolerance = "), "{e}");
    }
}

#[test]
fn optimize_output_never_contains_nan() {
    let p = problem(BodyLength::OneWavelength);
    let r = p
        .optimize(&ModelChoice::Paper, &GridSpec::new(30, 30))
        .unwrap();
    // every float of the report, the infeasible cells' included, is finite
    let floats = common::finite_floats(&r).unwrap();
    assert!(floats > 30 * 30, "only {floats} floats in the report");
}

#[test]
fn the_finite_float_scan_finds_a_nan_and_an_infinity_that_json_would_hide() {
    use serde::Serialize;
    #[derive(Serialize)]
    struct Inner {
        x: Option<f64>,
        label: &'static str,
    }
    #[derive(Serialize)]
    struct Outer {
        a: f64,
        list: Vec<Inner>,
    }
    let fine = Outer {
        a: 1.0,
        list: vec![
            Inner {
                x: Some(2.0),
                label: "inf",
            },
            Inner {
                x: None,
                label: "NaN",
            },
        ],
    };
    assert_eq!(common::finite_floats(&fine), Ok(2));
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let v = Outer {
            a: 1.0,
            list: vec![Inner {
                x: Some(bad),
                label: "",
            }],
        };
        assert!(serde_json::to_string(&v).unwrap().contains("null"));
        assert!(common::finite_floats(&v).is_err(), "{bad} not found");
    }
}
