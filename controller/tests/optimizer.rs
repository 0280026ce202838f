//! The optimiser: constraints hold, the paper's observation, certification, bad input.

use std::f64::consts::TAU;

use crawler_controller::optimizer::{
    Binding, BodyLength, GridSpec, ModelChoice, OptimizeError, Problem,
};
use crawler_controller::verify;
use crawler_plant::scenario::Scenario;

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
        .optimize(
            &ModelChoice::Paper,
            &GridSpec {
                omega_points: 120,
                k_points: 120,
                refine: true,
            },
        )
        .unwrap();
    let o = &r.optimum;
    assert!(o.margins.all_hold(1e-9), "{:?}", o.margins);
    assert!(o.omega >= p.limits.omega[0] && o.omega <= p.limits.omega[1]);
    assert!(o.k >= p.limits.k[0] && o.k <= p.limits.k[1]);
    assert!(o.f0 <= p.limits.f0_max);
    // every feasible cell also satisfies them, and none beats the optimum
    for c in r.cells.iter().filter(|c| c.velocity.is_some()) {
        let pred = ModelChoice::Paper.predict(&p.point(c.omega, c.k, c.f0.unwrap()));
        assert!(pred.mileage.unwrap() >= p.task.min_mileage() * (1.0 - 1e-9));
        assert!(pred.max_stress.unwrap() <= p.task.sigma_max * (1.0 + 1e-9));
        assert!(c.velocity.unwrap() <= o.prediction.velocity.unwrap() * (1.0 + 1e-12));
    }
}

#[test]
fn at_the_mileage_bound_the_speed_depends_on_k_only() {
    // Paper Fig. 6(b) / physics-notes §5: with f0 at the mileage bound V is a function of k alone.
    let p = problem(BodyLength::OneWavelength);
    let r = p
        .optimize(
            &ModelChoice::Paper,
            &GridSpec {
                omega_points: 40,
                k_points: 12,
                refine: false,
            },
        )
        .unwrap();
    let mut rows = 0;
    for (j, _) in r.k_grid.iter().enumerate() {
        let row: Vec<f64> = r.cells[j * r.omega_grid.len()..(j + 1) * r.omega_grid.len()]
            .iter()
            .filter(|c| c.binding == Binding::Mileage)
            .map(|c| c.velocity.unwrap())
            .collect();
        if row.len() >= 2 {
            rows += 1;
            let (lo, hi) = row
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                    (a.min(v), b.max(v))
                });
            assert!(
                (hi - lo) / hi < 1e-9,
                "k row {j}: V varies with omega: {lo} .. {hi}"
            );
        }
    }
    assert!(rows >= 5, "mileage binds on too few rows to test ({rows})");
    // and it grows with k, so the optimum sits on the k bound
    assert!(
        (r.optimum.k - p.limits.k[1]).abs() < 1e-9 * p.limits.k[1],
        "optimum k {}",
        r.optimum.k
    );
}

#[test]
fn improved_optimum_on_a_fixed_body_satisfies_its_constraints_and_certifies_on_the_plant() {
    let p = problem(BodyLength::Fixed(1.0));
    let r = p
        .optimize(
            &ModelChoice::parse("improved").unwrap(),
            &GridSpec {
                omega_points: 16,
                k_points: 0,
                refine: true,
            },
        )
        .unwrap();
    let o = &r.optimum;
    assert!(o.margins.all_hold(1e-6), "{:?}", o.margins);
    assert!(
        (o.k * 1.0 / TAU - (o.k / TAU).round()).abs() < 1e-9,
        "k fits the body"
    );
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
        omega_points: 10,
        k_points: 10,
        refine: false,
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
}

#[test]
fn optimize_output_never_contains_nan() {
    let p = problem(BodyLength::OneWavelength);
    let r = p
        .optimize(
            &ModelChoice::Paper,
            &GridSpec {
                omega_points: 30,
                k_points: 30,
                refine: true,
            },
        )
        .unwrap();
    let json = serde_json::to_string(&r).unwrap();
    assert!(!json.contains("NaN") && !json.contains("inf"));
}
