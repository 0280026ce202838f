//! The plant at a point with a discretisation-error estimate: the point at its N cells and again
//! at 2N (the plant library's convergence check); the finer run is reported and the difference
//! estimates its error ([`crate::table::conv_error`]: `|m(N) - m(2N)|`, which bounds the 2N run's
//! error at first order or better; the library's `2 |m(N) - m(2N)|` is the N run's).
//!
//! This is the one place that decides how the plant is run at a point.

use crawler_physics::report::Report;
use crawler_physics::scenario::Scenario;
use crawler_physics::simulate::{simulate, SimulateOptions};

use crate::record::{finite, PlantResult, PlantRun};

/// Options of the plant runs of a sweep: no progress bar, episodes counted but not listed.
pub fn run_options() -> SimulateOptions<'static> {
    SimulateOptions {
        max_episodes: 0,
        progress: None,
    }
}

/// The metrics and resolution of a plant report.
pub fn plant_run(r: &Report) -> PlantRun {
    PlantRun {
        metrics: r.values(),
        cells: r.cells as u64,
        dt: r.dt,
        steps: r.steps,
        window_periods: r.window.periods,
        momentum_residual: finite(r.momentum_residual),
        state_digest: r.state_digest.clone(),
        task: r.task.clone(),
    }
}

/// Runs the plant of `scenario`; with `refine`, also at twice its cells (the plant library's
/// [`crawler_physics::convergence::estimate`]: the same scenario with `2N` cells, so `dx` and `dt`
/// halve at the same Courant number) and reports the finer run with the coarser one beside it.
pub fn plant_with_estimate(scenario: &Scenario, refine: bool) -> Result<PlantResult, String> {
    let n = scenario.plant.numerics.cells;
    if !refine {
        let r = simulate(scenario, run_options()).map_err(|e| format!("plant at N = {n}: {e}"))?;
        return Ok(PlantResult {
            run: plant_run(&r),
            coarse: None,
        });
    }
    let c = crawler_physics::convergence::estimate(scenario, 0, None)
        .map_err(|e| format!("plant at N = {n} and 2N = {}: {e}", 2 * n))?;
    Ok(PlantResult {
        run: plant_run(&c.fine),
        coarse: Some(plant_run(&c.coarse)),
    })
}
