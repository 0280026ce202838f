//! A run's discretisation error, estimated by rerunning it on a grid twice as fine.
//!
//! The rerun keeps everything but the number of cells (so `dx` and `dt` halve at the same Courant
//! number). With the difference `d = m(N) - m(2N)` of a metric, the error of the `N` run is
//! `d / (1 - 2^-p)` for a method of order `p`: `2 d` at first order, `4 d / 3` at second. The
//! stick statistics converge at first order and the other metrics at second (see
//! `docs/numerics.md`), so the estimate below is the conservative `2 |d|` for every metric.

use serde::Serialize;

use crate::params::MAX_CELLS;
use crate::report::Report;
use crate::scenario::Scenario;
use crate::simulate::{simulate, SimulateError, SimulateOptions};

/// One metric at both resolutions.
#[derive(Debug, Clone, Serialize)]
pub struct MetricError {
    /// Metric name (as in the report).
    pub name: &'static str,
    /// Unit, SI (empty if dimensionless).
    pub unit: &'static str,
    /// Value at `N` cells.
    pub coarse: f64,
    /// Value at `2N` cells.
    pub fine: f64,
    /// Estimated error of the `N` run, `2 |coarse - fine|`, in the metric's unit.
    pub error: f64,
    /// `error / |fine|` (null when the fine value is zero).
    pub relative_error: Option<f64>,
}

/// The two runs and the per-metric estimates.
#[derive(Debug, Clone, Serialize)]
pub struct Convergence {
    /// The run at the scenario's resolution.
    pub coarse: Report,
    /// The run at twice as many cells.
    pub fine: Report,
    /// Every metric's estimated discretisation error.
    pub metrics: Vec<MetricError>,
}

/// The metrics compared: name, unit, accessor.
type Accessor = (&'static str, &'static str, fn(&Report) -> f64);

const METRICS: &[Accessor] = &[
    ("velocity", "m/s", |r| r.velocity),
    ("power", "W", |r| r.power),
    ("mileage", "m/J", |r| r.mileage),
    ("max_stress", "Pa", |r| r.max_stress),
    ("max_strain", "", |r| r.max_strain),
    ("stuck_fraction", "", |r| r.stuck_fraction),
    ("episodes_per_node_per_period", "", |r| {
        r.events.per_node_per_period
    }),
    ("mean_stick_duration", "s", |r| r.events.mean_duration),
];

/// Runs `scenario` at its resolution and at twice as many cells.
pub fn estimate(
    scenario: &Scenario,
    max_episodes: usize,
    mut progress: Option<&mut dyn FnMut(u64, u64)>,
) -> Result<Convergence, SimulateError> {
    let cells = scenario.plant.numerics.cells;
    if 2 * cells > MAX_CELLS {
        return Err(SimulateError::Slave(
            crate::error::ParamError::new(
                "numerics.cells",
                cells,
                format!(
                    "at most {} cells for a convergence check (it reruns at twice as many, and a plant takes at most {MAX_CELLS})",
                    MAX_CELLS / 2
                ),
            )
            .into(),
        ));
    }
    let mut fine_scenario = scenario.clone();
    fine_scenario.plant.numerics.cells = 2 * cells;
    // The fine run costs four times the coarse one: report progress over both as five parts.
    let mut run = |s: &Scenario, before: u64, weight: u64| {
        let mut inner = |done: u64, total: u64| {
            if let Some(p) = progress.as_deref_mut() {
                p(before * total + weight * done, 5 * total);
            }
        };
        simulate(
            s,
            SimulateOptions {
                max_episodes,
                progress: Some(&mut inner),
            },
        )
    };
    let coarse = run(scenario, 0, 1)?;
    let fine = run(&fine_scenario, 1, 4)?;
    let metrics = METRICS
        .iter()
        .map(|&(name, unit, get)| {
            let (c, f) = (get(&coarse), get(&fine));
            let error = 2.0 * (c - f).abs();
            MetricError {
                name,
                unit,
                coarse: c,
                fine: f,
                error,
                relative_error: (f != 0.0 && error.is_finite()).then(|| error / f.abs()),
            }
        })
        .collect();
    Ok(Convergence {
        coarse,
        fine,
        metrics,
    })
}

impl Convergence {
    /// A table of the metrics (several lines).
    pub fn summary(&self) -> String {
        let mut out = format!(
            "discretisation error of the run on {} cells, estimated against {} cells (twice |difference|; docs/numerics.md):\n",
            self.coarse.cells, self.fine.cells
        );
        out += &format!(
            "{:<30} {:>14} {:>14} {:>12} {:>9}\n",
            "metric", "N", "2N", "error", "relative"
        );
        // a metric that is not a number (the mileage of a run with no power put in) is undefined
        let number = |x: f64, digits: usize| {
            if x.is_finite() {
                format!("{x:.digits$e}")
            } else {
                "undefined".to_string()
            }
        };
        for m in &self.metrics {
            out += &format!(
                "{:<30} {:>14} {:>14} {:>12} {:>9}\n",
                if m.unit.is_empty() {
                    m.name.to_string()
                } else {
                    format!("{} {}", m.name, m.unit)
                },
                number(m.coarse, 6),
                number(m.fine, 6),
                number(m.error, 3),
                m.relative_error
                    .map_or("-".to_string(), |r| format!("{:.3}%", 100.0 * r))
            );
        }
        out
    }
}
