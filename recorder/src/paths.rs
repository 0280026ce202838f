//! Entity paths of a crawler recording (what tests and users query), and the timelines.

use crawler_facts::Metric;

/// The step timeline: the communication step n of every row.
pub const STEP_TIMELINE: &str = "step";
/// The simulated-time timeline: `t0 + n H` of every row, s.
pub const TIME_TIMELINE: &str = "sim_time";

/// The body view: the body in its own frame (a camera that follows it), the pipe under it.
pub const BODY: &str = "body";
/// The body's cells as boxes in the body's frame (its centre of mass at x = 0): cell i spans its
/// two nodes' positions, its height follows the strain (see [`STRAIN_GAIN`]), class stick (1) if
/// its first node is stuck, else slip (0). One row per recorded state.
pub const BODY_SEGMENTS: &str = "body/segments";
/// The world as the body sees it: a translation by minus the centre of mass's position in the
/// pipe, one row per recorded state; its children are drawn in pipe coordinates X (m).
pub const BODY_WORLD: &str = "body/world";
/// The pipe's patches in pipe coordinates (static), under the body: boxes whose height is eps.
pub const BODY_WORLD_PIPE: &str = "body/world/pipe";
/// Marks every 0.1 m along the pipe (static), so that the crawl shows in a uniform pipe too.
pub const BODY_WORLD_RULER: &str = "body/world/ruler";
/// Heights of the body's boxes: `BODY_HEIGHT L (1 - STRAIN_GAIN strain)` (a contracted cell is
/// thicker, a stretched one thinner, magnified), clamped to a fifth and twice the rest height.
pub const STRAIN_GAIN: f64 = 4.0;
/// Rest height of the body's boxes, in body lengths.
pub const BODY_HEIGHT: f64 = 0.04;
/// Displacement field `u(x) - mean u`, one bar per node, m (f32).
pub const FIELD_U: &str = "fields/u";
/// Velocity field `v(x)`, one bar per node, m/s (f32).
pub const FIELD_V: &str = "fields/v";
/// Tension field `T(x)` at the half nodes, one bar per cell, N (f32).
pub const FIELD_TENSION: &str = "fields/tension";
/// Space-time heatmap of `u - mean u`: blocks of rows (recorded states, time down) by nodes.
pub const HEATMAP: &str = "heatmap/u";
/// The pipe: friction along it against the world position X = start + x + u (m), with the
/// body's nodes on it.
pub const PIPE: &str = "pipe";
/// eps(X): a step line over the pipe (static), drawn at y = -eps (a 2D view's y points down).
pub const PIPE_EPS: &str = "pipe/eps";
/// n_F(X): a step line over the pipe (static), at y = -n_F.
pub const PIPE_N_F: &str = "pipe/n_f";
/// The body's nodes on the pipe map at (X, -eps(X)), classed stick / slip, each recorded state,
/// in a pipe whose friction varies.
pub const PIPE_BODY: &str = "pipe/body";
/// eps under the body's centre of mass, each state (once the pipe is known).
pub const PIPE_CENTRE_EPS: &str = "pipe/centre_eps";
/// Stick/slip lanes, one entity per recorded node: `lanes/node_0017`.
pub const LANES: &str = "lanes";
/// The controller whose actuation the plant applied (the id the states carry), a lane whose
/// value changes when another controller takes over.
pub const CONTROLLER: &str = "lanes/controller";
/// Tail displacement: `tail/plant`, `tail/paper`.
pub const TAIL: &str = "tail";
/// Text log: status, recorder notes.
pub const LOG: &str = "log";
/// Stick episodes, a row apiece at the communication step in which it ended: `node`, `start`
/// (s), `end` (s), `duration` (s) and `direction` (+1 the node left forward, -1 backward), as
/// numbers (archetype [`EPISODE_ARCHETYPE`]; the viewer's dataframe view shows them).
pub const EPISODES: &str = "events/episodes";
/// The archetype name of the episodes' columns.
pub const EPISODE_ARCHETYPE: &str = "crawler.StickEpisodes";
/// Status messages of the processes.
pub const LOG_STATUS: &str = "log/status";
/// Notes of the recorder itself (drops, rejections).
pub const LOG_RECORDER: &str = "log/recorder";
/// Counters of the recorder at each block it writes: `recorder/states` (states received so
/// far), `recorder/with_fields` (of them, recorded with their fields), `recorder/dropped`.
pub const RECORDER: &str = "recorder";
/// Per-step values (each state): `step/<metric>` for [`METRICS`].
pub const STEP: &str = "step";
/// The task's progress, each state: `task/distance` (m, the centre of mass's displacement from
/// the run's first state) and `task/energy` (J, the actuator's work since then); their targets
/// `task/distance/target` and `task/energy/target` once the plant's final report gives them.
pub const TASK: &str = "task";
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

/// The series of `metric` from `source` ([`SOURCES`]).
pub fn metric_series(metric: &str, source: &str) -> String {
    format!("metrics/{metric}/{source}")
}

/// The per-step series of `metric`: `step/<metric>`.
pub fn step_series(metric: &str) -> String {
    format!("{STEP}/{metric}")
}

/// A series of the task: `task/<name>`.
pub fn task(name: &str) -> String {
    format!("{TASK}/{name}")
}

/// The lane of node `i`.
pub fn lane(i: usize) -> String {
    format!("{LANES}/node_{i:04}")
}

/// The metrics recorded per block, per step and predicted (`metrics/<name>/<source>`,
/// `step/<name>`); names, units and meanings are the metric table's.
pub const METRICS: [Metric; 5] = [
    Metric::Velocity,
    Metric::Power,
    Metric::Mileage,
    Metric::MaxStress,
    Metric::StuckFraction,
];

/// Sources of `metrics/<metric>/<source>`: `plant`, the plant's blocks of one forcing period
/// counted from the last change of actuation; `running`, the plant's clock blocks
/// (`numerics.block` seconds on the run's clock, whatever the actuation did: every controller
/// has them); `paper` and `improved`, the models' predictions for the wave applied.
pub const SOURCES: [&str; 4] = ["plant", "running", "paper", "improved"];

/// The plant's final report (its `finished` status): `summary/<metric>` scalars and the report
/// as a JSON document at `summary`.
pub const SUMMARY_ROOT: &str = "summary";

/// The final report's scalars beside its metrics (every metric of the metric table is
/// recorded as `summary/<name>`, a value that is not a number, such as the mileage at P = 0,
/// not at all).
pub const SUMMARY_EXTRA: [&str; 1] = ["dissipation"];
