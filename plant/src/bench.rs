//! `crawler-plant bench`: cell updates per second of the stepping loop (single thread).

use serde::Serialize;
use std::time::Instant;

use crawler_physics::plant::Plant;
use crawler_physics::scenario::Scenario;

/// One measurement.
#[derive(Debug, Clone, Serialize)]
pub struct BenchResult {
    /// Cells N.
    pub cells: usize,
    /// Internal steps timed.
    pub steps: u64,
    /// Wall time of the timed steps, s.
    pub seconds: f64,
    /// N * steps / seconds.
    pub cell_updates_per_second: f64,
    /// Nanoseconds per cell update.
    pub ns_per_cell_update: f64,
}

/// Steps the plant of `scenario` (with `cells` cells) for about `seconds` of wall time after a
/// warm-up, and reports the rate. The plant runs its full stepping loop (metrics and events
/// included), driven by the scenario's wave.
pub fn bench(scenario: &Scenario, cells: usize, seconds: f64) -> anyhow::Result<BenchResult> {
    let mut s = scenario.clone();
    s.plant.numerics.cells = cells;
    let mut plant = Plant::new(s.plant, 0.0)?;
    plant.set_wave(s.wave)?;
    let substeps = plant.discretisation().substeps;
    // warm-up: a tenth of the budget
    let warm = Instant::now();
    while warm.elapsed().as_secs_f64() < 0.1 * seconds {
        plant.advance()?;
    }
    let start = Instant::now();
    let mut macro_steps = 0u64;
    loop {
        plant.advance()?;
        macro_steps += 1;
        if start.elapsed().as_secs_f64() >= seconds {
            break;
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    let steps = macro_steps * substeps;
    let updates = steps as f64 * cells as f64;
    Ok(BenchResult {
        cells,
        steps,
        seconds: elapsed,
        cell_updates_per_second: updates / elapsed,
        ns_per_cell_update: elapsed * 1e9 / updates,
    })
}
