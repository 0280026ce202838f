//! `crawler-plant bench`: cell updates per second of the stepping loop (single thread), of one
//! plant or of several stepped in turn.

use serde::Serialize;
use std::time::Instant;

use crawler_physics::plant::Plant;
use crawler_physics::scenario::Scenario;

/// One measurement.
#[derive(Debug, Clone, Serialize)]
pub struct BenchResult {
    /// Cells N.
    pub cells: usize,
    /// Plants stepped in turn, one communication step each (their states do not all stay in
    /// the cache as one plant's does: what stepping a vector of crawlers costs).
    pub plants: usize,
    /// Internal steps timed, all plants.
    pub steps: u64,
    /// Wall time of the timed steps, s.
    pub seconds: f64,
    /// N * steps / seconds (all plants).
    pub cell_updates_per_second: f64,
    /// Nanoseconds per cell update.
    pub ns_per_cell_update: f64,
}

/// Communication steps every plant takes before the timing starts.
pub const WARM_STEPS: u64 = 2000;

/// Steps the plant of `scenario` (`plants` of them, in turn, one communication step each) for
/// about `seconds` of wall time after a warm-up ([`WARM_STEPS`] and a tenth of `seconds`), and
/// reports the rate. The plants run their full stepping loop (metrics and events included),
/// driven by the scenario's wave.
pub fn bench(
    scenario: &Scenario,
    cells: usize,
    plants: usize,
    seconds: f64,
) -> anyhow::Result<BenchResult> {
    let plants = plants.max(1);
    let mut s = scenario.clone();
    s.plant.numerics.cells = cells;
    let mut all = (0..plants)
        .map(|_| {
            let mut plant = Plant::new(s.plant.clone(), 0.0)?;
            plant.set_wave(s.wave)?;
            Ok(plant)
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let substeps = all[0].discretisation().substeps;
    let mut round = || -> anyhow::Result<()> {
        for plant in all.iter_mut() {
            plant.advance()?;
        }
        Ok(())
    };
    // warm-up: a tenth of the budget, and past the first communication steps from rest (cheaper
    // than the rest of a run: few nodes stick yet) on every plant
    let warm = Instant::now();
    let mut warm_rounds = 0;
    while warm.elapsed().as_secs_f64() < 0.1 * seconds || warm_rounds < WARM_STEPS {
        round()?;
        warm_rounds += 1;
    }
    let start = Instant::now();
    let mut rounds = 0u64;
    loop {
        round()?;
        rounds += 1;
        if start.elapsed().as_secs_f64() >= seconds {
            break;
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    let steps = rounds * substeps * plants as u64;
    let updates = steps as f64 * cells as f64;
    Ok(BenchResult {
        cells,
        plants,
        steps,
        seconds: elapsed,
        cell_updates_per_second: updates / elapsed,
        ns_per_cell_update: elapsed * 1e9 / updates,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plants_stepped_in_turn_each_take_whole_communication_steps() {
        let s = Scenario::paper();
        let r = bench(&s, 32, 3, 0.01).unwrap();
        let mut params = s.plant.clone();
        params.numerics.cells = 32;
        let substeps = params.discretisation().unwrap().substeps;
        assert_eq!(r.plants, 3);
        assert!(r.steps > 0);
        assert_eq!(r.steps % (3 * substeps), 0, "{} steps", r.steps);
        assert_eq!(r.cell_updates_per_second, r.steps as f64 * 32.0 / r.seconds);
    }
}
