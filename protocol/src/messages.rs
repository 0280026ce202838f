//! The messages, their encoding and their validation.
//!
//! Every message is a MessagePack map with named fields (`rmp_serde::to_vec_named`), so any
//! MessagePack library decodes it to a dictionary; every message carries `v`, the protocol
//! version. Arrays of numbers are MessagePack arrays of float64. See `docs/protocol.md`.

use serde::de::{DeserializeOwned, Deserializer, Visitor};
use serde::{Deserialize, Serialize};

use crate::error::ProtocolError;
use crate::keys::Role;

/// Protocol version spoken by this build.
pub const PROTOCOL_VERSION: u16 = 3;

/// Largest payload accepted on any key, bytes (checked before decoding).
pub const MAX_MESSAGE_BYTES: usize = 64 << 20;

use crawler_facts::MetricValues;
pub use crawler_facts::{Outcome, MAX_CELLS, MAX_ID_LEN, MAX_SCENARIO_NAME_LEN};

/// Longest free text (status messages, model descriptions) accepted, bytes.
pub const MAX_TEXT_LEN: usize = 1 << 20;

/// A message of the protocol.
pub trait Message: Serialize + DeserializeOwned {
    /// The message's name in errors.
    const NAME: &'static str;
    /// Its protocol version field.
    fn version(&self) -> u16;
    /// Checks every field (finite numbers, sizes, lengths).
    fn validate(&self) -> Result<(), ProtocolError>;
}

/// Encodes a message (MessagePack map with named fields).
pub fn encode<M: Message>(m: &M) -> Vec<u8> {
    rmp_serde::to_vec_named(m).expect("protocol messages always serialize")
}

/// Decodes and validates a message: size limit, MessagePack structure, version, fields.
pub fn decode<M: Message>(bytes: &[u8]) -> Result<M, ProtocolError> {
    if bytes.len() > MAX_MESSAGE_BYTES {
        return Err(ProtocolError::TooLarge {
            size: bytes.len(),
            limit: MAX_MESSAGE_BYTES,
        });
    }
    // A map with named fields, nothing else: MessagePack decoders would also read a struct from
    // an array of its values in field order, which the protocol does not allow.
    if !matches!(bytes.first(), Some(0x80..=0x8f | 0xde | 0xdf)) {
        return Err(ProtocolError::Malformed {
            message: M::NAME,
            reason: format!(
                "{} where a MessagePack map with named fields is expected",
                match bytes.first() {
                    None => "no bytes".to_string(),
                    Some(b) => format!("first byte 0x{b:02x}"),
                }
            ),
        });
    }
    let m: M = rmp_serde::from_slice(bytes).map_err(|e| ProtocolError::Malformed {
        message: M::NAME,
        reason: e.to_string(),
    })?;
    if m.version() != PROTOCOL_VERSION {
        return Err(ProtocolError::Version {
            message: M::NAME,
            got: m.version(),
            expected: PROTOCOL_VERSION,
        });
    }
    m.validate()?;
    Ok(m)
}

pub(crate) fn finite(field: &str, x: f64) -> Result<(), ProtocolError> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(ProtocolError::invalid(field, x, "a finite number"))
    }
}

/// Metric values within their ranges (the metric table's), refused by `prefix.metric`.
fn metric_values(prefix: &str, values: &MetricValues) -> Result<(), ProtocolError> {
    values
        .validate(prefix)
        .map_err(|e| ProtocolError::invalid(e.field, e.value, e.allowed))
}

pub(crate) fn finite_all(field: &str, xs: &[f64]) -> Result<(), ProtocolError> {
    match xs.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(ProtocolError::invalid(
            format!("{field}[{i}]"),
            xs[i],
            "finite numbers",
        )),
        None => Ok(()),
    }
}

fn cells(field: &str, n: usize) -> Result<(), ProtocolError> {
    if (1..=MAX_CELLS).contains(&n) {
        Ok(())
    } else {
        Err(ProtocolError::invalid(
            field,
            format!("{n} values"),
            format!("1 to {MAX_CELLS} values"),
        ))
    }
}

pub(crate) fn short(field: &str, s: &str) -> Result<(), ProtocolError> {
    if s.len() <= MAX_ID_LEN {
        Ok(())
    } else {
        Err(ProtocolError::invalid(
            field,
            format!("{} bytes", s.len()),
            format!("at most {MAX_ID_LEN} bytes"),
        ))
    }
}

fn text(field: &str, s: &str) -> Result<(), ProtocolError> {
    if s.len() <= MAX_TEXT_LEN {
        Ok(())
    } else {
        Err(ProtocolError::invalid(
            field,
            format!("{} bytes", s.len()),
            format!("at most {MAX_TEXT_LEN} bytes"),
        ))
    }
}

fn non_negative(field: &str, x: f64) -> Result<(), ProtocolError> {
    if x.is_finite() && x >= 0.0 {
        Ok(())
    } else {
        Err(ProtocolError::invalid(field, x, "a finite number >= 0"))
    }
}

fn positive(field: &str, x: f64) -> Result<(), ProtocolError> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(ProtocolError::invalid(field, x, "a finite number > 0"))
    }
}

/// Deserializes a string naming one value of an enum (`parse` finds it); anything else is refused
/// naming `field`, the value received (its first 32 characters) and what is `allowed`.
pub(crate) fn named<'de, D, T>(
    d: D,
    field: &'static str,
    parse: fn(&str) -> Option<T>,
    allowed: &'static str,
) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
{
    struct Named<T> {
        field: &'static str,
        parse: fn(&str) -> Option<T>,
        allowed: &'static str,
    }
    impl<T> Visitor<'_> for Named<T> {
        type Value = T;
        fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            write!(f, "{} as a string, one of {}", self.field, self.allowed)
        }
        fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<T, E> {
            (self.parse)(v).ok_or_else(|| {
                E::custom(ProtocolError::invalid(
                    self.field,
                    format!("{:?}", v.chars().take(32).collect::<String>()),
                    self.allowed,
                ))
            })
        }
    }
    d.deserialize_str(Named {
        field,
        parse,
        allowed,
    })
}

/// The plant's state at the start of communication step `step` (time `t0 + step H`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct State {
    /// Protocol version.
    pub v: u16,
    /// Communication step n.
    pub step: u64,
    /// Time t0 + n H, s.
    pub time: f64,
    /// Id of the controller that joined the run ("" before one has).
    pub controller: String,
    /// Displacement at nodes x_i = i dx, m.
    pub u: Vec<f64>,
    /// Velocity at nodes over the last internal step, m/s.
    pub vel: Vec<f64>,
    /// Tension at half nodes x_{i+1/2}, N.
    pub tension: Vec<f64>,
    /// Nodes held by static friction.
    pub stuck: Vec<bool>,
    /// Mean speed of the body over the last step, m/s.
    pub mean_speed: f64,
    /// Actuator input power over the last step, W.
    pub input_power: f64,
    /// True for the last state of the run (no actuation expected).
    pub last: bool,
    /// The actuation the plant applied over the step that ended here, from `t0 + (step - 1) H`
    /// to `t0 + step H` (the one it admitted for step `step - 1`); `None` before any was applied
    /// (the first state of a run).
    pub applied: Option<Applied>,
}

/// What the plant applied over one communication step: exactly one of `wave` and `field`, as in
/// the [`Actuation`] it admitted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Applied {
    /// The travelling wave, evaluated continuously over the step.
    pub wave: Option<WaveMsg>,
    /// Muscle force at the half nodes, N (one value per cell), held over the step.
    pub field: Option<Vec<f64>>,
}

impl Applied {
    /// Checks the applied actuation of a body of `cells` cells; `field` names it in errors
    /// (`state.applied`).
    fn validate(&self, field: &str, cells: usize) -> Result<(), ProtocolError> {
        match (&self.wave, &self.field) {
            (Some(w), None) => w.validate(&format!("{field}.wave")),
            (None, Some(f)) => {
                if f.len() != cells {
                    return Err(ProtocolError::invalid(
                        format!("{field}.field"),
                        format!("{} values", f.len()),
                        format!("{cells} values, one per cell (as many as state.u)"),
                    ));
                }
                finite_all(&format!("{field}.field"), f)
            }
            _ => Err(ProtocolError::invalid(
                field,
                "wave and field both given or both missing",
                "exactly one of wave and field",
            )),
        }
    }
}

impl Message for State {
    const NAME: &'static str = "state";
    fn version(&self) -> u16 {
        self.v
    }
    fn validate(&self) -> Result<(), ProtocolError> {
        let n = self.u.len();
        cells("state.u", n)?;
        for (name, len) in [
            ("state.vel", self.vel.len()),
            ("state.tension", self.tension.len()),
            ("state.stuck", self.stuck.len()),
        ] {
            if len != n {
                return Err(ProtocolError::invalid(
                    name,
                    format!("{len} values"),
                    format!("{n} values, as many as state.u"),
                ));
            }
        }
        short("state.controller", &self.controller)?;
        finite("state.time", self.time)?;
        finite("state.mean_speed", self.mean_speed)?;
        finite("state.input_power", self.input_power)?;
        finite_all("state.u", &self.u)?;
        finite_all("state.vel", &self.vel)?;
        finite_all("state.tension", &self.tension)?;
        match &self.applied {
            Some(a) => a.validate("state.applied", n),
            None => Ok(()),
        }
    }
}

/// A travelling wave `A_m f = f0 sin(k x - omega t + phase)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WaveMsg {
    /// Amplitude, N.
    pub f0: f64,
    /// Wave number, rad/m.
    pub k: f64,
    /// Angular frequency, rad/s.
    pub omega: f64,
    /// Phase, rad.
    pub phase: f64,
}

impl WaveMsg {
    fn validate(&self, field: &str) -> Result<(), ProtocolError> {
        for (name, x) in [
            ("f0", self.f0),
            ("k", self.k),
            ("omega", self.omega),
            ("phase", self.phase),
        ] {
            finite(&format!("{field}.{name}"), x)?;
        }
        if self.f0 < 0.0 {
            return Err(ProtocolError::invalid(
                format!("{field}.f0"),
                self.f0,
                "f0 >= 0 (N)",
            ));
        }
        if self.k <= 0.0 {
            return Err(ProtocolError::invalid(
                format!("{field}.k"),
                self.k,
                "k > 0 (rad/m)",
            ));
        }
        if self.omega <= 0.0 {
            return Err(ProtocolError::invalid(
                format!("{field}.omega"),
                self.omega,
                "omega > 0 (rad/s)",
            ));
        }
        Ok(())
    }
}

/// The controller's answer to [`State`] `step`: exactly one of `wave` and `field`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Actuation {
    /// Protocol version.
    pub v: u16,
    /// The step this answers (the plant applies it from t0 + step H to t0 + (step + 1) H).
    pub step: u64,
    /// Id of the controller sending it.
    pub controller: String,
    /// A travelling wave, evaluated continuously over the step.
    pub wave: Option<WaveMsg>,
    /// Muscle force at the half nodes, N, held over the step.
    pub field: Option<Vec<f64>>,
}

impl Message for Actuation {
    const NAME: &'static str = "actuation";
    fn version(&self) -> u16 {
        self.v
    }
    fn validate(&self) -> Result<(), ProtocolError> {
        short("actuation.controller", &self.controller)?;
        match (&self.wave, &self.field) {
            (Some(w), None) => w.validate("actuation.wave"),
            (None, Some(f)) => {
                cells("actuation.field", f.len())?;
                finite_all("actuation.field", f)
            }
            _ => Err(ProtocolError::invalid(
                "actuation",
                "wave and field both given or both missing",
                "exactly one of wave and field",
            )),
        }
    }
}

/// A controller's request to control a run, on `crawler/<run>/join`: sent (again every 500 ms)
/// until the plant's states are addressed to it. The plant admits it at a step boundary: at once
/// when the run has no controller, or, to take over from the run's controller, at the first
/// boundary at or after `take_over`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Join {
    /// Protocol version.
    pub v: u16,
    /// The controller's id (as in its envelope and its liveliness token).
    pub controller: String,
    /// Its policy's name (said in the plant's log).
    pub policy: String,
    /// `None`: join a run that has no controller (a run that has one keeps it). A step: take
    /// the run over from its controller at the first step boundary at or after it (0: the next
    /// one).
    pub take_over: Option<u64>,
}

impl Message for Join {
    const NAME: &'static str = "join";
    fn version(&self) -> u16 {
        self.v
    }
    fn validate(&self) -> Result<(), ProtocolError> {
        short("join.controller", &self.controller)?;
        short("join.policy", &self.policy)
    }
}

/// A stick-slip episode.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EpisodeMsg {
    /// Node index.
    pub node: u32,
    /// Start, s.
    pub start: f64,
    /// End, s.
    pub end: f64,
    /// Duration, s.
    pub duration: f64,
    /// +1 left forward, -1 backward.
    pub direction: i8,
}

/// Episodes that ended during communication step `step`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Events {
    /// Protocol version.
    pub v: u16,
    /// Communication step.
    pub step: u64,
    /// Time at the end of the step, s.
    pub time: f64,
    /// The episodes.
    pub episodes: Vec<EpisodeMsg>,
}

impl Message for Events {
    const NAME: &'static str = "events";
    fn version(&self) -> u16 {
        self.v
    }
    fn validate(&self) -> Result<(), ProtocolError> {
        finite("events.time", self.time)?;
        if self.episodes.len() > MAX_CELLS {
            return Err(ProtocolError::invalid(
                "events.episodes",
                self.episodes.len(),
                format!("at most {MAX_CELLS}"),
            ));
        }
        for (i, e) in self.episodes.iter().enumerate() {
            for (name, x) in [("start", e.start), ("end", e.end), ("duration", e.duration)] {
                finite(&format!("events.episodes[{i}].{name}"), x)?;
            }
            if e.direction != 1 && e.direction != -1 {
                return Err(ProtocolError::invalid(
                    format!("events.episodes[{i}].direction"),
                    e.direction,
                    "+1 or -1",
                ));
            }
        }
        Ok(())
    }
}

/// Metrics of one completed forcing period (or averaging block).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Protocol version.
    pub v: u16,
    /// Communication step at which the block closed.
    pub step: u64,
    /// Block number since the last change of actuation.
    pub block: u64,
    /// True if the block is in the steady window (after the transient).
    pub steady: bool,
    /// Block start, s.
    pub start: f64,
    /// Block end, s.
    pub end: f64,
    /// The block's metrics, as fields named by the metric table (`velocity`, `power`, ...); nil
    /// where a value is not a number (the mileage when P = 0).
    #[serde(flatten)]
    pub values: MetricValues,

    /// True for a clock block: `numerics.block` seconds on the run's clock from its start, closed
    /// whatever the actuation did (the running metrics of any controller; `block` counts them from
    /// the run's start, `steady` is false). False for a block of the forcing period counted from
    /// the last change of actuation. Absent: false.
    #[serde(default)]
    pub clock: bool,
}

impl Message for Metrics {
    const NAME: &'static str = "metrics";
    fn version(&self) -> u16 {
        self.v
    }
    fn validate(&self) -> Result<(), ProtocolError> {
        finite("metrics.start", self.start)?;
        finite("metrics.end", self.end)?;
        metric_values("metrics", &self.values)
    }
}

/// Counts of rejected actuation messages, by cause.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Rejections {
    /// Not decodable (garbage, truncated, too large, wrong types).
    pub malformed: u64,
    /// Another protocol version.
    pub version: u64,
    /// Invalid values (NaN, infinite, wrong sign, wrong size, wave not fitting the body).
    pub invalid: u64,
    /// From a controller other than the one that joined (or, at arrival, without a valid seal,
    /// or from a sender that may not send on the key).
    pub foreign: u64,
    /// Sealed for another run instance (an earlier run with the same credential), or before the
    /// receiver knew the run's instance. (Absent, as in a checkpoint of protocol 2: 0.)
    #[serde(default)]
    pub other_run: u64,
    /// Not newer than the last message taken from its sender on its key: a replay. (Absent: 0.)
    #[serde(default)]
    pub replayed: u64,
    /// For a step already taken.
    pub stale: u64,
    /// A second answer to the current step from the joined controller.
    pub duplicate: u64,
    /// For a step not reached yet.
    pub future: u64,
    /// Dropped because the inbox was full (flooding).
    pub overflow: u64,
}

impl Rejections {
    /// Total rejected.
    pub fn total(&self) -> u64 {
        self.malformed
            + self.version
            + self.invalid
            + self.foreign
            + self.other_run
            + self.replayed
            + self.stale
            + self.duplicate
            + self.future
            + self.overflow
    }
}

/// The life-cycle state a [`Status`] reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ProcessState {
    /// Started, waiting for its peers (the plant: for a controller to join).
    Waiting,
    /// Stepping.
    Running,
    /// The run reached its end (the plant: its last step; it sends its [`FinalReport`]).
    Finished,
    /// Ended on an error.
    Failed,
    /// Ended early on purpose or for want of a peer (interrupted, controller lost, timeout).
    Stopped,
}

impl ProcessState {
    /// Every state.
    pub const ALL: [ProcessState; 5] = [
        ProcessState::Waiting,
        ProcessState::Running,
        ProcessState::Finished,
        ProcessState::Failed,
        ProcessState::Stopped,
    ];

    /// The state's name on the wire: `"waiting"`, `"running"`, `"finished"`, `"failed"` or
    /// `"stopped"`.
    pub fn as_str(self) -> &'static str {
        match self {
            ProcessState::Waiting => "waiting",
            ProcessState::Running => "running",
            ProcessState::Finished => "finished",
            ProcessState::Failed => "failed",
            ProcessState::Stopped => "stopped",
        }
    }

    /// The state named `name`.
    pub fn parse(name: &str) -> Option<ProcessState> {
        ProcessState::ALL.into_iter().find(|s| s.as_str() == name)
    }

    /// True for the states that end a process's run: finished, failed, stopped.
    pub fn is_terminal(self) -> bool {
        matches!(
            self,
            ProcessState::Finished | ProcessState::Failed | ProcessState::Stopped
        )
    }
}

wire_name!(
    ProcessState,
    "status.state",
    "\"waiting\", \"running\", \"finished\", \"failed\" or \"stopped\""
);

/// Life-cycle status of a process.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Status {
    /// Protocol version.
    pub v: u16,
    /// Who sends it: `"plant"`, `"controller"` or `"bridge"` on the wire.
    pub role: Role,
    /// The process's id.
    pub id: String,
    /// `"waiting"`, `"running"`, `"finished"`, `"failed"` or `"stopped"` on the wire.
    pub state: ProcessState,
    /// Human-readable detail.
    pub message: String,
    /// Current communication step.
    pub step: u64,
    /// Rejected actuation so far (plant).
    pub rejected: Rejections,
    /// The plant's final report: only in a plant's `finished` status (and `None` if the plant
    /// could not compute one).
    pub report: Option<FinalReport>,
}

impl Message for Status {
    const NAME: &'static str = "status";
    fn version(&self) -> u16 {
        self.v
    }
    fn validate(&self) -> Result<(), ProtocolError> {
        short("status.id", &self.id)?;
        text("status.message", &self.message)?;
        if let Some(r) = &self.report {
            if (self.role, self.state) != (Role::Plant, ProcessState::Finished) {
                return Err(ProtocolError::invalid(
                    "status.report",
                    format!("a report in a {} status of the {}", self.state, self.role),
                    "a report only in the plant's finished status",
                ));
            }
            r.validate()?;
        }
        Ok(())
    }
}

/// The task's outcome on the wire, in the words of the plant's report, refused by field and value
/// when unknown.
fn outcome_named<'de, D: Deserializer<'de>>(d: D) -> Result<Outcome, D::Error> {
    named(d, "report.task.outcome", Outcome::parse, Outcome::ALLOWED)
}

/// The task's result in a [`FinalReport`] (SI units; times from the start of the run).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TaskResult {
    /// How it ended.
    #[serde(deserialize_with = "outcome_named")]
    pub outcome: Outcome,
    /// The task's distance D, m (> 0).
    pub distance_target: f64,
    /// Distance the centre of mass travelled, m.
    pub distance: f64,
    /// Time until D was reached, s (>= 0); only when reached.
    pub time_to_distance: Option<f64>,
    /// The task's energy budget J0, J (> 0).
    pub energy_budget: f64,
    /// Net actuator work over the run, J.
    pub energy_used: f64,
    /// Net actuator work when D was reached, J; only when reached.
    pub energy_at_distance: Option<f64>,
    /// Time until J0 was spent, s (>= 0); only when the energy was exhausted.
    pub energy_exhausted_at: Option<f64>,
    /// The stress limit sigma_max, Pa (> 0).
    pub sigma_max: f64,
    /// Largest stress over the run, Pa (>= 0).
    pub max_stress: f64,
    /// Time during which the stress exceeded sigma_max, s (>= 0).
    pub time_over_sigma_max: f64,
    /// Time above sigma_max the task tolerates before it fails, s (>= 0). Absent: 0.
    #[serde(default)]
    pub stress_tolerance: f64,
    /// When the time above sigma_max first exceeded the tolerance, s from the task's start
    /// (>= 0); only when the outcome is "stress exceeded".
    #[serde(default)]
    pub stress_exceeded_at: Option<f64>,
    /// Length of the run, s (>= 0).
    pub run_time: f64,
}

impl TaskResult {
    fn validate(&self) -> Result<(), ProtocolError> {
        positive("report.task.distance_target", self.distance_target)?;
        finite("report.task.distance", self.distance)?;
        positive("report.task.energy_budget", self.energy_budget)?;
        finite("report.task.energy_used", self.energy_used)?;
        positive("report.task.sigma_max", self.sigma_max)?;
        non_negative("report.task.max_stress", self.max_stress)?;
        non_negative("report.task.time_over_sigma_max", self.time_over_sigma_max)?;
        non_negative("report.task.stress_tolerance", self.stress_tolerance)?;
        if let Some(t) = self.stress_exceeded_at {
            non_negative("report.task.stress_exceeded_at", t)?;
        }
        non_negative("report.task.run_time", self.run_time)?;
        if let Some(t) = self.time_to_distance {
            non_negative("report.task.time_to_distance", t)?;
        }
        if let Some(e) = self.energy_at_distance {
            finite("report.task.energy_at_distance", e)?;
        }
        if let Some(t) = self.energy_exhausted_at {
            non_negative("report.task.energy_exhausted_at", t)?;
        }
        // the outcome and the times that decide it agree
        let reached = (
            self.time_to_distance.is_some(),
            self.energy_at_distance.is_some(),
            self.energy_exhausted_at.is_some(),
        );
        let (expected, allowed) = match self.outcome {
            Outcome::Reached => (
                (true, true, false),
                "time_to_distance and energy_at_distance, and no energy_exhausted_at, when reached",
            ),
            Outcome::EnergyExhausted => (
                (false, false, true),
                "energy_exhausted_at only, when the energy was exhausted",
            ),
            Outcome::TimeUp => (
                (false, false, false),
                "none of time_to_distance, energy_at_distance, energy_exhausted_at at time up",
            ),
            // the stress limit broke first; the run went on to D, to J0 or to its end
            Outcome::StressExceeded => (
                (reached.0, reached.0, !reached.0 && reached.2),
                "time_to_distance with energy_at_distance, or energy_exhausted_at, or none, when the stress was exceeded",
            ),
        };
        if reached != expected {
            return Err(ProtocolError::invalid(
                "report.task",
                format!(
                    "outcome {:?} with time_to_distance {:?}, energy_at_distance {:?}, energy_exhausted_at {:?}",
                    self.outcome.as_str(),
                    self.time_to_distance,
                    self.energy_at_distance,
                    self.energy_exhausted_at
                ),
                allowed,
            ));
        }
        Ok(())
    }
}

/// Stick-slip statistics of a [`FinalReport`]'s window (the episodes themselves went out in
/// [`Events`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EpisodeStats {
    /// Episodes that ended in the window.
    pub count: u64,
    /// Episodes per node per forcing period (>= 0).
    pub per_node_per_period: f64,
    /// Mean episode duration, s (>= 0; 0 without episodes).
    pub mean_duration: f64,
    /// Shortest stick phase counted as an episode, s (>= 0).
    pub min_duration: f64,
}

/// The averaging window of a [`FinalReport`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ReportWindow {
    /// Start, s.
    pub start: f64,
    /// End, s (>= start).
    pub end: f64,
    /// Forcing periods (averaging blocks) in it (>= 0).
    pub periods: f64,
    /// True for a steady window (whole periods at least `settle` after the last change of
    /// actuation); false when the actuation changed later: the metrics are then run averages.
    pub steady: bool,
    /// True when the run ended before its transient did (a task reached early): the metrics are
    /// averages over the whole run.
    pub whole_run: bool,
}

/// The plant's final report of a finished run, in its `finished` [`Status`]: the metrics of its
/// window (steady, or run averages: see `window`), the stick-slip statistics, the grid and the
/// clock, the state digest and the task's result. SI units. The plant library's report converts
/// into it in one place (`crawler_physics::simulate`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FinalReport {
    /// Scenario name (at most [`MAX_SCENARIO_NAME_LEN`] bytes).
    pub scenario: String,
    /// The window's metrics, as fields named by the metric table (`velocity`, `power`, ...,
    /// each within its range); nil where a value is not a number (the mileage when P = 0).
    #[serde(flatten)]
    pub values: MetricValues,
    /// Power dissipated by friction, W.
    pub dissipation: f64,
    /// V predicted by the identity `eps c_d (n_F - <s>) / c_v`, m/s.
    pub identity_velocity: f64,
    /// Relative residual of the scheme's discrete momentum balance over the window (>= 0);
    /// `None` when it is not a number (a body at rest).
    pub momentum_residual: Option<f64>,
    /// Stick-slip statistics.
    pub events: EpisodeStats,
    /// The averaging window.
    pub window: ReportWindow,
    /// Number of cells N.
    pub cells: u64,
    /// Internal step dt, s (> 0).
    pub dt: f64,
    /// Communication step H, s (> 0).
    pub step: f64,
    /// Achieved Courant number `c dt / dx` (> 0).
    pub courant: f64,
    /// Cell size dx, m (> 0).
    pub dx: f64,
    /// Cells per wavelength of the wave in force at the end (`None` under a field).
    pub cells_per_wavelength: Option<f64>,
    /// Internal steps taken.
    pub steps: u64,
    /// Communication steps taken.
    pub macro_steps: u64,
    /// End time, s.
    pub t_end: f64,
    /// CRC-32 of the final displacement and velocity bits, 8 lowercase hex digits: equal
    /// digests, identical trajectories.
    pub state_digest: String,
    /// The run against the scenario's task, if the plant followed one.
    pub task: Option<TaskResult>,
}

impl FinalReport {
    /// Checks every field: finite numbers in their ranges, a consistent window and task.
    pub fn validate(&self) -> Result<(), ProtocolError> {
        if self.scenario.len() > MAX_SCENARIO_NAME_LEN {
            return Err(ProtocolError::invalid(
                "report.scenario",
                format!("{} bytes", self.scenario.len()),
                format!("at most {MAX_SCENARIO_NAME_LEN} bytes"),
            ));
        }
        for (name, x) in [
            ("dissipation", self.dissipation),
            ("identity_velocity", self.identity_velocity),
            ("t_end", self.t_end),
        ] {
            finite(&format!("report.{name}"), x)?;
        }
        metric_values("report", &self.values)?;
        if let Some(r) = self.momentum_residual {
            non_negative("report.momentum_residual", r)?;
        }
        let e = &self.events;
        non_negative("report.events.per_node_per_period", e.per_node_per_period)?;
        non_negative("report.events.mean_duration", e.mean_duration)?;
        non_negative("report.events.min_duration", e.min_duration)?;
        let w = &self.window;
        finite("report.window.start", w.start)?;
        finite("report.window.end", w.end)?;
        if w.end < w.start {
            return Err(ProtocolError::invalid(
                "report.window.end",
                w.end,
                format!("at least report.window.start = {}", w.start),
            ));
        }
        non_negative("report.window.periods", w.periods)?;
        cells(
            "report.cells",
            usize::try_from(self.cells).unwrap_or(usize::MAX),
        )?;
        positive("report.dt", self.dt)?;
        positive("report.step", self.step)?;
        positive("report.courant", self.courant)?;
        positive("report.dx", self.dx)?;
        if let Some(c) = self.cells_per_wavelength {
            positive("report.cells_per_wavelength", c)?;
        }
        let d = &self.state_digest;
        if !(d.len() == 8 && d.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))) {
            return Err(ProtocolError::invalid(
                "report.state_digest",
                format!("{:?}", d.chars().take(32).collect::<String>()),
                "8 lowercase hex digits",
            ));
        }
        match &self.task {
            Some(t) => t.validate(),
            None => Ok(()),
        }
    }
}

/// A periodic signal `offset + drift t + sum_n amplitude_n cos(n omega t + phase_n)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Series {
    /// Angular frequency, rad/s.
    pub omega: f64,
    /// Drift per second (units of the signal per s).
    pub drift: f64,
    /// `(amplitude, phase)` of harmonics 1, 2, ...
    pub harmonics: Vec<(f64, f64)>,
}

impl Series {
    /// The value at time `t` (plus an offset chosen by the caller).
    pub fn at(&self, t: f64) -> f64 {
        self.drift * t
            + self
                .harmonics
                .iter()
                .enumerate()
                .map(|(n, (a, p))| a * ((n + 1) as f64 * self.omega * t + p).cos())
                .sum::<f64>()
    }
}

/// One model's steady-state prediction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelPrediction {
    /// "paper" or "improved".
    pub model: String,
    /// The predicted metrics, as fields named by the metric table; nil where the model has no
    /// value.
    #[serde(flatten)]
    pub values: MetricValues,
    /// "valid" or why not.
    pub validity: String,
    /// Tail displacement u(0, t), m, when the model gives it.
    pub tail: Option<Series>,
}

/// The controller's predictions for the wave it applies from `step` on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Prediction {
    /// Protocol version.
    pub v: u16,
    /// Controller id.
    pub controller: String,
    /// Policy name.
    pub policy: String,
    /// First step the wave applies to.
    pub step: u64,
    /// The wave.
    pub wave: WaveMsg,
    /// Per model.
    pub models: Vec<ModelPrediction>,
}

impl Message for Prediction {
    const NAME: &'static str = "prediction";
    fn version(&self) -> u16 {
        self.v
    }
    fn validate(&self) -> Result<(), ProtocolError> {
        short("prediction.controller", &self.controller)?;
        short("prediction.policy", &self.policy)?;
        self.wave.validate("prediction.wave")?;
        if self.models.len() > 16 {
            return Err(ProtocolError::invalid(
                "prediction.models",
                self.models.len(),
                "at most 16 models",
            ));
        }
        for (i, m) in self.models.iter().enumerate() {
            short(&format!("prediction.models[{i}].model"), &m.model)?;
            text(&format!("prediction.models[{i}].validity"), &m.validity)?;
            metric_values(&format!("prediction.models[{i}]"), &m.values)?;
            if let Some(s) = &m.tail {
                finite("tail.omega", s.omega)?;
                finite("tail.drift", s.drift)?;
                if s.harmonics.len() > 256 {
                    return Err(ProtocolError::invalid(
                        "tail.harmonics",
                        s.harmonics.len(),
                        "at most 256",
                    ));
                }
                for (j, (a, p)) in s.harmonics.iter().enumerate() {
                    finite(&format!("tail.harmonics[{j}].0"), *a)?;
                    finite(&format!("tail.harmonics[{j}].1"), *p)?;
                }
            }
        }
        Ok(())
    }
}

/// What the plant tells anyone who queries `crawler/<run>/model`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelInfo {
    /// Protocol version.
    pub v: u16,
    /// Run id.
    pub run: String,
    /// Number of cells N (length of every field).
    pub cells: u64,
    /// Body length L, m.
    pub length: f64,
    /// Communication step H, s.
    pub step: f64,
    /// Start time t0, s.
    pub start_time: f64,
    /// Last step of the run (the plant stops at t0 + last_step H).
    pub last_step: u64,
    /// Cross-section A_c, m^2.
    pub area: f64,
    /// Linear density rho, kg/m.
    pub density: f64,
    /// Young's modulus E, Pa.
    pub youngs_modulus: f64,
    /// c_v, N s/m^2.
    pub viscous: f64,
    /// c_d, N/m.
    pub dry: f64,
    /// eps: the true uniform value when `disclosed`, else the nominal value the scenario tells
    /// controllers.
    pub eps: f64,
    /// n_F (true or nominal, as `eps`).
    pub n_f: f64,
    /// Transient skipped by the plant's steady metrics, s.
    pub settle: f64,
    /// The FMI-style model description, JSON text.
    pub model_description: String,
    /// `"periodic"` (the body closed on itself) or `"free"` (two free ends). Absent: periodic.
    #[serde(default = "periodic")]
    pub boundary: String,
    /// True if `eps` and `n_f` are the pipe's true friction (and the model description holds its
    /// map); false if they are nominal values and the environment is not disclosed. Absent: true.
    #[serde(default = "disclosed")]
    pub disclosed: bool,
}

fn periodic() -> String {
    "periodic".to_string()
}

fn disclosed() -> bool {
    true
}

impl ModelInfo {
    /// A plant on the uniform test body of the examples and tests: 1 m long, cross-section
    /// 1e-4 m2, 0.1 kg/m, E = 140 kPa, c_v = 1 N.s/m2, c_d = 1 N/m, eps = 0.1, n_F = 0.5 (told
    /// to controllers), periodic, 1 ms communication steps from t = 0, 5 s settling; run `run`,
    /// `cells` cells, the last communication step `last_step`.
    pub fn example(run: &str, cells: u64, last_step: u64) -> Self {
        Self {
            v: PROTOCOL_VERSION,
            run: run.into(),
            cells,
            length: 1.0,
            step: 1e-3,
            start_time: 0.0,
            last_step,
            area: 1e-4,
            density: 0.1,
            youngs_modulus: 140e3,
            viscous: 1.0,
            dry: 1.0,
            eps: 0.1,
            n_f: 0.5,
            settle: 5.0,
            model_description: "{}".into(),
            boundary: "periodic".into(),
            disclosed: true,
        }
    }
}

impl Message for ModelInfo {
    const NAME: &'static str = "model";
    fn version(&self) -> u16 {
        self.v
    }
    fn validate(&self) -> Result<(), ProtocolError> {
        crate::keys::validate_run_id(&self.run)?;
        cells(
            "model.cells",
            usize::try_from(self.cells).unwrap_or(usize::MAX),
        )?;
        for (name, x) in [
            ("length", self.length),
            ("step", self.step),
            ("area", self.area),
            ("density", self.density),
            ("youngs_modulus", self.youngs_modulus),
            ("viscous", self.viscous),
        ] {
            if !(x.is_finite() && x > 0.0) {
                return Err(ProtocolError::invalid(
                    format!("model.{name}"),
                    x,
                    "a finite number > 0",
                ));
            }
        }
        for (name, x) in [
            ("start_time", self.start_time),
            ("dry", self.dry),
            ("eps", self.eps),
            ("n_f", self.n_f),
            ("settle", self.settle),
        ] {
            finite(&format!("model.{name}"), x)?;
        }
        if !matches!(self.boundary.as_str(), "periodic" | "free") {
            return Err(ProtocolError::invalid(
                "model.boundary",
                format!("{:?}", self.boundary.chars().take(32).collect::<String>()),
                "\"periodic\" or \"free\"",
            ));
        }
        text("model.model_description", &self.model_description)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crawler_facts::Metric;

    fn state(n: usize, applied: Option<Applied>) -> State {
        State {
            v: PROTOCOL_VERSION,
            step: 4,
            time: 0.004,
            controller: "c".into(),
            u: vec![0.0; n],
            vel: vec![0.0; n],
            tension: vec![0.0; n],
            stuck: vec![false; n],
            mean_speed: 0.0,
            input_power: 0.0,
            last: false,
            applied,
        }
    }

    #[test]
    fn a_mileage_that_is_not_a_number_travels_as_nil_never_as_nan() {
        let mut m = Metrics {
            v: PROTOCOL_VERSION,
            step: 10,
            block: 0,
            steady: false,
            start: 0.0,
            end: 0.1,
            // P = 0: no mileage
            values: MetricValues::of(&[
                (Metric::Velocity, 0.0),
                (Metric::Power, 0.0),
                (Metric::MaxStress, 0.0),
                (Metric::MaxStrain, 0.0),
                (Metric::StuckFraction, 0.0),
                (Metric::MeanFrictionSelection, 0.0),
                (Metric::EpisodesPerNodePerPeriod, 0.0),
            ]),
            clock: false,
        };
        assert_eq!(decode::<Metrics>(&encode(&m)).unwrap(), m);
        m.values = m.values.with_raw(Metric::Mileage, Some(f64::NAN));
        let e = decode::<Metrics>(&encode(&m)).unwrap_err().to_string();
        assert!(e.starts_with("invalid metrics.mileage = NaN"), "{e}");
    }

    fn wave() -> WaveMsg {
        WaveMsg {
            f0: 0.5,
            k: 6.25,
            omega: 74.0,
            phase: 0.25,
        }
    }

    fn applied_wave(w: WaveMsg) -> Option<Applied> {
        Some(Applied {
            wave: Some(w),
            field: None,
        })
    }

    fn applied_field(f: Vec<f64>) -> Option<Applied> {
        Some(Applied {
            wave: None,
            field: Some(f),
        })
    }

    /// The error of decoding `m`, as text (panics if it decodes).
    fn refused<M: Message + std::fmt::Debug>(m: &M) -> String {
        match decode::<M>(&encode(m)) {
            Ok(m) => panic!("{m:?} decoded"),
            Err(e) => e.to_string(),
        }
    }

    fn round_trip<M: Message + PartialEq + std::fmt::Debug>(m: &M) {
        let back: M = decode(&encode(m)).unwrap();
        assert_eq!(&back, m);
    }

    #[test]
    fn a_message_in_array_form_is_refused_as_malformed() {
        // the same actuation as an array of its values in field order, which MessagePack
        // decoders would otherwise read as the struct
        let a = Actuation {
            v: PROTOCOL_VERSION,
            step: 3,
            controller: "c".into(),
            wave: Some(wave()),
            field: None,
        };
        let array = rmp_serde::to_vec(&a).unwrap();
        assert_eq!(array[0], 0x95, "an array of 5");
        let e = decode::<Actuation>(&array).unwrap_err().to_string();
        assert!(
            e.contains("first byte 0x95 where a MessagePack map with named fields is expected"),
            "{e}"
        );
        assert!(matches!(
            decode::<Actuation>(&[]),
            Err(ProtocolError::Malformed { .. })
        ));
        round_trip(&a);
    }

    #[test]
    fn a_state_carries_the_applied_wave_or_field_and_nothing_else() {
        round_trip(&state(3, None));
        round_trip(&state(3, applied_wave(wave())));
        round_trip(&state(3, applied_field(vec![0.5, -0.5, 0.0])));
        for (applied, needle) in [
            (
                applied_field(vec![0.5, f64::NAN, 0.0]),
                "invalid state.applied.field[1] = NaN: allowed finite numbers",
            ),
            (
                applied_field(vec![0.5, f64::INFINITY, 0.0]),
                "state.applied.field[1] = inf",
            ),
            (
                applied_field(vec![0.5, 0.5]),
                "invalid state.applied.field = 2 values: allowed 3 values, one per cell",
            ),
            (
                applied_field(vec![0.5; 4]),
                "state.applied.field = 4 values",
            ),
            (
                Some(Applied {
                    wave: Some(wave()),
                    field: Some(vec![0.0; 3]),
                }),
                "invalid state.applied = wave and field both given or both missing: allowed exactly one of wave and field",
            ),
            (
                Some(Applied {
                    wave: None,
                    field: None,
                }),
                "exactly one of wave and field",
            ),
            (
                applied_wave(WaveMsg {
                    omega: f64::NAN,
                    ..wave()
                }),
                "invalid state.applied.wave.omega = NaN",
            ),
            (
                applied_wave(WaveMsg { k: 0.0, ..wave() }),
                "invalid state.applied.wave.k = 0: allowed k > 0 (rad/m)",
            ),
            (
                applied_wave(WaveMsg { f0: -1.0, ..wave() }),
                "state.applied.wave.f0 = -1",
            ),
        ] {
            let err = refused(&state(3, applied));
            assert!(err.contains(needle), "{needle:?} not in {err:?}");
        }
    }

    pub(crate) fn report() -> FinalReport {
        FinalReport {
            scenario: "paper".into(),
            values: MetricValues::of(&[
                (Metric::Velocity, 0.049),
                (Metric::Power, 4.73),
                (Metric::Mileage, 0.0103),
                (Metric::MaxStress, 36300.0),
                (Metric::MaxStrain, 0.0026),
                (Metric::StuckFraction, 0.04),
                (Metric::MeanFrictionSelection, -0.5),
            ]),
            dissipation: 4.73,
            identity_velocity: 0.049,
            momentum_residual: Some(1e-15),
            events: EpisodeStats {
                count: 12,
                per_node_per_period: 0.5,
                mean_duration: 0.002,
                min_duration: 0.0005,
            },
            window: ReportWindow {
                start: 5.0,
                end: 8.0,
                periods: 35.3,
                steady: true,
                whole_run: false,
            },
            cells: 256,
            dt: 1e-5,
            step: 1e-3,
            courant: 1.0,
            dx: 1.0 / 256.0,
            cells_per_wavelength: Some(256.0),
            steps: 800_000,
            macro_steps: 8000,
            t_end: 8.0,
            state_digest: "4832f1ec".into(),
            task: Some(TaskResult {
                outcome: Outcome::Reached,
                distance_target: 1.0,
                distance: 1.0,
                time_to_distance: Some(7.5),
                energy_budget: 20.0,
                energy_used: 19.0,
                energy_at_distance: Some(18.5),
                energy_exhausted_at: None,
                sigma_max: 1e5,
                max_stress: 4e4,
                time_over_sigma_max: 0.0,
                stress_tolerance: 0.0,
                stress_exceeded_at: None,
                run_time: 8.0,
            }),
        }
    }

    fn finished(report: Option<FinalReport>) -> Status {
        Status {
            v: PROTOCOL_VERSION,
            role: Role::Plant,
            id: "p".into(),
            state: ProcessState::Finished,
            message: "finished".into(),
            step: 8000,
            rejected: Rejections::default(),
            report,
        }
    }

    #[test]
    fn the_final_report_is_typed_and_round_trips() {
        round_trip(&finished(Some(report())));
        round_trip(&finished(None));
        let mut r = report();
        r.values.set(Metric::Mileage, None); // P = 0
        r.momentum_residual = None;
        r.cells_per_wavelength = None;
        r.task = None;
        round_trip(&finished(Some(r)));
        for outcome in [Outcome::EnergyExhausted, Outcome::TimeUp] {
            let mut r = report();
            let t = r.task.as_mut().unwrap();
            t.outcome = outcome;
            t.time_to_distance = None;
            t.energy_at_distance = None;
            t.energy_exhausted_at = (outcome == Outcome::EnergyExhausted).then_some(6.5);
            round_trip(&finished(Some(r)));
        }
    }

    #[test]
    fn every_field_of_the_final_report_is_checked_and_named() {
        type Edit = fn(&mut FinalReport);
        let cases: [(Edit, &str); 22] = [
            (
                |r| r.values = r.values.with_raw(Metric::Velocity, Some(f64::NAN)),
                "invalid report.velocity = NaN: allowed a finite number",
            ),
            (
                |r| r.values = r.values.with_raw(Metric::Power, Some(f64::INFINITY)),
                "report.power = inf",
            ),
            (
                |r| r.values = r.values.with_raw(Metric::Mileage, Some(f64::NAN)),
                "report.mileage = NaN",
            ),
            (
                |r| r.values.set(Metric::MaxStress, Some(-1.0)),
                "invalid report.max_stress = -1: allowed a finite number >= 0",
            ),
            (
                |r| r.values = r.values.with_raw(Metric::MaxStrain, Some(f64::NAN)),
                "report.max_strain = NaN",
            ),
            (
                |r| r.values.set(Metric::StuckFraction, Some(1.5)),
                "invalid report.stuck_fraction = 1.5: allowed a finite number from 0 to 1",
            ),
            (
                |r| r.values.set(Metric::MeanFrictionSelection, Some(-1.01)),
                "report.mean_friction_selection = -1.01",
            ),
            (
                |r| r.momentum_residual = Some(f64::INFINITY),
                "report.momentum_residual = inf",
            ),
            (
                |r| r.events.mean_duration = -0.1,
                "report.events.mean_duration = -0.1",
            ),
            (
                |r| r.window.end = 4.0,
                "invalid report.window.end = 4: allowed at least report.window.start = 5",
            ),
            (
                |r| r.window.periods = f64::NAN,
                "report.window.periods = NaN",
            ),
            (|r| r.cells = 0, "report.cells = 0 values"),
            (
                |r| r.dt = 0.0,
                "invalid report.dt = 0: allowed a finite number > 0",
            ),
            (|r| r.courant = f64::NAN, "report.courant = NaN"),
            (
                |r| r.cells_per_wavelength = Some(-2.0),
                "report.cells_per_wavelength = -2",
            ),
            (|r| r.t_end = f64::NEG_INFINITY, "report.t_end = -inf"),
            (
                |r| r.state_digest = "forged".into(),
                "invalid report.state_digest = \"forged\": allowed 8 lowercase hex digits",
            ),
            (
                |r| r.scenario = "s".repeat(MAX_SCENARIO_NAME_LEN + 1),
                "report.scenario = 129 bytes",
            ),
            (
                |r| r.task.as_mut().unwrap().sigma_max = 0.0,
                "report.task.sigma_max = 0",
            ),
            (
                |r| r.task.as_mut().unwrap().energy_used = f64::NAN,
                "report.task.energy_used = NaN",
            ),
            (
                |r| r.task.as_mut().unwrap().time_to_distance = None,
                "invalid report.task = outcome \"reached\"",
            ),
            (
                |r| r.task.as_mut().unwrap().outcome = Outcome::TimeUp,
                "allowed none of time_to_distance",
            ),
        ];
        for (edit, needle) in cases {
            let mut r = report();
            edit(&mut r);
            let err = refused(&finished(Some(r)));
            assert!(err.contains(needle), "{needle:?} not in {err:?}");
        }
    }

    #[test]
    fn only_the_plants_finished_status_carries_a_report() {
        for (role, state) in [
            (Role::Plant, ProcessState::Running),
            (Role::Plant, ProcessState::Failed),
            (Role::Plant, ProcessState::Stopped),
            (Role::Controller, ProcessState::Finished),
            (Role::Bridge, ProcessState::Finished),
        ] {
            let s = Status {
                role,
                state,
                ..finished(Some(report()))
            };
            let err = refused(&s);
            assert!(
                err.contains(&format!(
                    "invalid status.report = a report in a {state} status of the {role}: allowed a report only in the plant's finished status"
                )),
                "{err}"
            );
            round_trip(&Status { report: None, ..s });
        }
    }

    #[test]
    fn roles_states_and_outcomes_travel_as_their_lowercase_names() {
        let bytes = encode(&finished(Some(report())));
        let text = String::from_utf8_lossy(&bytes);
        for name in ["plant", "finished", "reached"] {
            assert!(text.contains(name), "{name} not in {text:?}");
        }
        for role in Role::ALL {
            assert_eq!(Role::parse(role.as_str()), Some(role));
        }
        for state in ProcessState::ALL {
            assert_eq!(ProcessState::parse(state.as_str()), Some(state));
        }
        for o in Outcome::ALL {
            assert_eq!(Outcome::parse(&o.to_string()), Some(o));
        }
        assert!(ProcessState::Finished.is_terminal() && !ProcessState::Running.is_terminal());
        // anything else is refused, naming the field, the value and what is allowed
        let forged = |from: &[u8], to: &[u8]| {
            let i = bytes
                .windows(from.len())
                .position(|w| w == from)
                .expect("present");
            let mut b = bytes.clone();
            b.splice(i..i + from.len(), to.iter().copied());
            decode::<Status>(&b).unwrap_err().to_string()
        };
        let err = forged(b"\xa5plant", b"\xa5plans");
        assert!(
            err.contains(
                "invalid status.role = \"plans\": allowed \"plant\", \"controller\" or \"bridge\""
            ),
            "{err}"
        );
        let err = forged(b"\xa8finished", b"\xa8FINISHED");
        assert!(
            err.contains("invalid status.state = \"FINISHED\": allowed \"waiting\", \"running\""),
            "{err}"
        );
        let err = forged(b"\xa7reached", b"\xa7reaches");
        assert!(
            err.contains("invalid report.task.outcome = \"reaches\""),
            "{err}"
        );
        let err = forged(b"\xa5plant", b"\x05");
        assert!(err.contains("status.role as a string"), "{err}");
    }
}
