//! `crawler-controller bench`: timings of the optimiser and of the reduced model against the plant.

use std::time::Instant;

use serde::Serialize;

use crawler_physics::scenario::{Overrides, Scenario};
use crawler_physics::simulate::{simulate, SimulateOptions};

use crate::operating_point::OperatingPoint;
use crate::optimizer::{
    set_threads, BodyLength, GridSpec, ModelChoice, Problem, DEFAULT_TIE_TOLERANCE,
};
use crate::prediction::Model;
use crate::travelling_wave::TravellingWaveModel;

/// The measurements, seconds.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    /// Paper model, 500 x 500 grid, one thread (best of 5).
    pub paper_500_one_thread: f64,
    /// Paper model, 500 x 500 grid, all cores (best of 5).
    pub paper_500_all_cores: f64,
    /// Cores used for the line above.
    pub cores: usize,
    /// Paper model, 500 x 500 grid plus refinement, all cores.
    pub paper_500_refined: f64,
    /// The optimum's speed (to compare with the NumPy implementation), m/s.
    pub paper_500_velocity: f64,
    /// The optimum's amplitude, N.
    pub paper_500_f0: f64,
    /// The fastest speed on the grid (the optimum is the lowest f0 within the tie tolerance of
    /// it), m/s.
    pub paper_500_fastest: f64,
    /// Improved model, one-wavelength body, 24 x 24 grid plus refinement, all cores.
    pub improved_24_refined: f64,
    /// Improved model, the co-simulation's fixed 1 m body: 48 omegas x 4 wave numbers plus refinement.
    pub improved_fixed_body: f64,
    /// One prediction of the improved model (median of 200), at eps = 0.1, alpha = 0.5.
    pub improved_prediction: f64,
    /// One prediction of the improved model in a sticking regime (eps = 1, f0 = 0.2 N).
    pub improved_prediction_sticking: f64,
    /// One plant run to a steady state at the same point (N = 256, 10 s).
    pub plant_run: f64,
    /// plant_run / improved_prediction.
    pub speedup_vs_plant: f64,
}

fn best_of(n: usize, mut f: impl FnMut()) -> f64 {
    (0..n)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn median_of(n: usize, mut f: impl FnMut()) -> f64 {
    let mut v: Vec<f64> = (0..n)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .collect();
    v.sort_by(f64::total_cmp);
    v[n / 2]
}

/// Runs every measurement on the scenario's problem.
pub fn run(scenario: &Scenario) -> anyhow::Result<BenchReport> {
    let problem = |body_length| Problem {
        body: scenario.plant.body,
        friction: scenario.plant.friction,
        task: scenario.task,
        limits: scenario.limits,
        body_length,
    };
    let paper = problem(BodyLength::OneWavelength);
    let grid = GridSpec {
        omega_points: 500,
        k_points: 500,
        refine: false,
        tie_tolerance: DEFAULT_TIE_TOLERANCE,
    };
    let (mut velocity, mut f0, mut fastest) = (0.0, 0.0, 0.0);
    set_threads(1);
    let one = best_of(5, || {
        let r = paper.optimize(&ModelChoice::Paper, &grid).unwrap();
        velocity = r.optimum.prediction.velocity.unwrap();
        f0 = r.optimum.f0;
        fastest = r.tie_break.fastest_velocity;
    });
    set_threads(0);
    let all = best_of(5, || {
        paper.optimize(&ModelChoice::Paper, &grid).unwrap();
    });
    let refined = best_of(3, || {
        paper
            .optimize(
                &ModelChoice::Paper,
                &GridSpec {
                    refine: true,
                    ..grid
                },
            )
            .unwrap();
    });
    let improved = ModelChoice::Improved(TravellingWaveModel::default());
    let improved_24 = best_of(1, || {
        paper
            .optimize(
                &improved,
                &GridSpec {
                    omega_points: 24,
                    k_points: 24,
                    refine: true,
                    tie_tolerance: DEFAULT_TIE_TOLERANCE,
                },
            )
            .unwrap();
    });
    let fixed = problem(BodyLength::Fixed(scenario.plant.length));
    let improved_fixed = best_of(1, || {
        fixed
            .optimize(
                &improved,
                &GridSpec {
                    omega_points: 48,
                    k_points: 48,
                    refine: true,
                    tie_tolerance: DEFAULT_TIE_TOLERANCE,
                },
            )
            .unwrap();
    });
    let point = Scenario::load(
        None,
        &Overrides {
            alpha: Some(0.5),
            cells: Some(256),
            ..Default::default()
        },
    )?;
    let sticking = Scenario::load(
        None,
        &Overrides {
            eps: Some(1.0),
            f0: Some(0.2),
            alpha: Some(0.5),
            ..Default::default()
        },
    )?;
    let model = TravellingWaveModel::default();
    let op = OperatingPoint::of(&point);
    let op_stick = OperatingPoint::of(&sticking);
    let prediction = median_of(200, || {
        std::hint::black_box(model.predict(&op));
    });
    let prediction_sticking = median_of(200, || {
        std::hint::black_box(model.predict(&op_stick));
    });
    let plant_run = best_of(3, || {
        simulate(&point, SimulateOptions::default()).unwrap();
    });
    Ok(BenchReport {
        paper_500_one_thread: one,
        paper_500_all_cores: all,
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        paper_500_refined: refined,
        paper_500_velocity: velocity,
        paper_500_f0: f0,
        paper_500_fastest: fastest,
        improved_24_refined: improved_24,
        improved_fixed_body: improved_fixed,
        improved_prediction: prediction,
        improved_prediction_sticking: prediction_sticking,
        plant_run,
        speedup_vs_plant: plant_run / prediction,
    })
}
