//! Entity paths of a crawler recording (what tests and users query).

use crawler_facts::Metric;

/// The body in space: `body/points` at `x + u`, `body/exaggerated` at `x + mean u + 10 (u - mean u)`,
/// classed stick / slip.
pub const BODY: &str = "body";
/// Points at `x + u`.
pub const BODY_POINTS: &str = "body/points";
/// Points with the deformation magnified ten times (one row below).
pub const BODY_EXAGGERATED: &str = "body/exaggerated";
/// How much `body/exaggerated` magnifies the deformation.
pub const EXAGGERATION: f64 = 10.0;
/// Displacement field `u(x) - mean u`, one bar per node, m.
pub const FIELD_U: &str = "fields/u";
/// Velocity field `v(x)`, one bar per node, m/s.
pub const FIELD_V: &str = "fields/v";
/// Space-time heatmap of `u - mean u`: blocks of rows (time) by nodes.
pub const HEATMAP: &str = "heatmap/u";
/// The pipe: friction along it against the world position X = start + x + u (m), with the
/// body's nodes on it.
pub const PIPE: &str = "pipe";
/// eps(X): a step line over the pipe (static), drawn at y = -eps (a 2D view's y points down).
pub const PIPE_EPS: &str = "pipe/eps";
/// n_F(X): a step line over the pipe (static), at y = -n_F.
pub const PIPE_N_F: &str = "pipe/n_f";
/// The body's nodes at (X, -eps(X)), classed stick / slip, each recorded step.
pub const PIPE_BODY: &str = "pipe/body";
/// eps under the body's centre of mass, each state.
pub const PIPE_CENTRE_EPS: &str = "pipe/centre_eps";
/// Stick/slip lanes, one entity per recorded node: `lanes/node_0017`.
pub const LANES: &str = "lanes";
/// Tail displacement: `tail/plant`, `tail/paper`.
pub const TAIL: &str = "tail";
/// Text log: episodes, status, recorder notes.
pub const LOG: &str = "log";
/// Episodes in the text log.
pub const LOG_EPISODES: &str = "log/episodes";
/// Status messages of the processes.
pub const LOG_STATUS: &str = "log/status";
/// Notes of the recorder itself (decimation, drops).
pub const LOG_RECORDER: &str = "log/recorder";
/// Per-step scalars: mean speed and input power of each communication step.
pub const STEP: &str = "step";
/// What the plant applied over each step (`State.applied`): under a wave, its parameters as
/// scalar series `actuation/applied/<param>` at every state; under a field, the field.
pub const APPLIED: &str = "actuation/applied";
/// The applied muscle-force field `A_m f` at the half nodes, one bar per cell, N (at the steps
/// whose fields are recorded).
pub const APPLIED_FIELD: &str = "actuation/applied/field";
/// The wave's parameters recorded under [`APPLIED`]: amplitude f0 (N), wave number k (rad/m),
/// angular frequency omega (rad/s), phase (rad).
pub const APPLIED_WAVE: [&str; 4] = ["f0", "k", "omega", "phase"];

/// The series of the applied wave's parameter `param` (`f0`, `k`, `omega`, `phase`).
pub fn applied(param: &str) -> String {
    format!("{APPLIED}/{param}")
}

/// The time series of `metric` (`velocity`, `power`, ...): `metrics/<metric>/<source>`.
pub fn metric(metric: &str) -> String {
    format!("metrics/{metric}")
}

/// The series of `metric` from `source` (`plant`, `paper`, `improved`).
pub fn metric_series(metric: Metric, source: &str) -> String {
    format!("metrics/{metric}/{source}")
}

/// The lane of node `i`.
pub fn lane(i: usize) -> String {
    format!("{LANES}/node_{i:04}")
}

/// The metrics recorded per forcing period (`metrics/<name>/<source>`).
pub const METRICS: [Metric; 5] = [
    Metric::Velocity,
    Metric::Power,
    Metric::Mileage,
    Metric::MaxStress,
    Metric::StuckFraction,
];

/// The plant's final report (its `finished` status): `summary/<metric>` scalars and the report
/// as a JSON document at `summary`.
pub const SUMMARY_ROOT: &str = "summary";

/// The final report's scalars beside its metrics (every metric of the metric table is
/// recorded as `summary/<name>`, a value that is not a number, such as the mileage at P = 0,
/// not at all).
pub const SUMMARY_EXTRA: [&str; 1] = ["dissipation"];
