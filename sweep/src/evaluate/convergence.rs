//! The plant at a point with a discretisation-error estimate: the point at its N cells and again
//! at 2N; the finer run is reported and the difference estimates its error.
//!
//! This is the one place that decides how convergence is estimated. When the plant library
//! offers its own estimate (a `crawler_plant::convergence` module is planned), only
//! [`plant_with_estimate`] changes.

use crawler_plant::scenario::{Overrides, Scenario};
use crawler_plant::simulate::{simulate, Report, SimulateOptions};

use crate::record::{finite, Metrics, PlantResult, PlantRun};

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
        metrics: Metrics {
            velocity: finite(r.velocity),
            power: finite(r.power),
            mileage: finite(r.mileage),
            max_stress: finite(r.max_stress),
            max_strain: finite(r.max_strain),
            stuck_fraction: finite(r.stuck_fraction),
            mean_friction_selection: finite(r.mean_friction_selection),
            episodes_per_node_per_period: finite(r.events.per_node_per_period),
        },
        cells: r.cells as u64,
        dt: r.dt,
        steps: r.steps,
        window_periods: r.window.periods,
        momentum_residual: finite(r.momentum_residual),
        state_digest: r.state_digest.clone(),
    }
}

/// Runs the plant of `scenario`; with `refine`, also at twice its cells (re-resolved from the
/// point's TOML `toml`, so every rule of the scenario format applies to the finer grid too) and
/// reports the finer run with the coarser one beside it.
pub fn plant_with_estimate(
    scenario: &Scenario,
    toml: &str,
    refine: bool,
) -> Result<PlantResult, String> {
    let coarse = simulate(scenario, run_options())
        .map_err(|e| format!("plant at N = {}: {e}", scenario.plant.numerics.cells))?;
    if !refine {
        return Ok(PlantResult {
            run: plant_run(&coarse),
            coarse: None,
        });
    }
    let n2 = 2 * scenario.plant.numerics.cells as i64;
    let overrides = Overrides {
        cells: Some(n2),
        ..Overrides::default()
    };
    let finer = Scenario::from_toml(toml, "<the point at twice the cells>", &overrides)
        .map_err(|e| format!("the convergence check's grid: {e}"))?;
    let fine = simulate(&finer, run_options()).map_err(|e| format!("plant at 2N = {n2}: {e}"))?;
    Ok(PlantResult {
        run: plant_run(&fine),
        coarse: Some(plant_run(&coarse)),
    })
}
