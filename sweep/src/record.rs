//! What is kept of one evaluated point (serialised as one JSON object; floats round-trip exactly).

use crawler_physics::task::TaskReport;
use serde::{Deserialize, Serialize};

/// Steady-state metrics of the plant, a model or a policy run (the metric table's, SI units).
/// `None` where there is no value (a model outside its validity, or a non-finite number, which
/// is never stored).
pub type Metrics = crawler_facts::MetricValues;

/// `Some(x)` if `x` is finite.
pub fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// One plant run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlantRun {
    /// Its metrics over the steady window.
    pub metrics: Metrics,
    /// Cells.
    pub cells: u64,
    /// Internal step, s.
    pub dt: f64,
    /// Internal steps taken.
    pub steps: u64,
    /// Forcing periods in the averaging window.
    pub window_periods: f64,
    /// Relative residual of the discrete momentum balance (round-off level).
    pub momentum_residual: Option<f64>,
    /// CRC-32 of the final state (equal digests, identical trajectories).
    pub state_digest: String,
    /// How the run did against the scenario's task (the plant's report).
    #[serde(default)]
    pub task: Option<TaskReport>,
}

/// The plant at a point: the reported run and, with a convergence check, the coarser one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlantResult {
    /// The run whose values are reported (the finer one when there are two).
    pub run: PlantRun,
    /// The run at half the cells, for the discretisation-error estimate.
    pub coarse: Option<PlantRun>,
}

/// A model's prediction at a point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelResult {
    /// Model name.
    pub model: String,
    /// Whether the model's formulas apply.
    pub valid: bool,
    /// Why not, if they do not.
    pub reason: Option<String>,
    /// The predicted metrics.
    pub metrics: Metrics,
}

/// A policy's closed-loop run at a point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PolicyResult {
    /// Policy name.
    pub policy: String,
    /// The plant's metrics under the policy.
    pub run: PlantRun,
    /// True if the metrics are over a steady window (false: run averages of a time-varying policy).
    pub steady: bool,
    /// The last travelling wave the policy commanded (f0 N, k rad/m, omega rad/s), if any.
    pub wave: Option<[f64; 3]>,
}

/// Everything kept of one point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// The point's id.
    pub id: String,
    /// Result format ([`crate::point::FORMAT`]).
    pub format: u32,
    /// The plant, if evaluated and successful.
    pub plant: Option<PlantResult>,
    /// The models, in the plan's order.
    pub models: Vec<ModelResult>,
    /// The policy run, if evaluated and successful.
    pub policy: Option<PolicyResult>,
    /// Why the evaluation failed, if it did (the other fields hold what was done before).
    pub error: Option<String>,
    /// Wall time of the evaluation, s (the only field that differs between two evaluations).
    pub wall_time: f64,
}
