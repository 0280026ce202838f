//! The messages, their encoding and their validation.
//!
//! Every message is a MessagePack map with named fields (`rmp_serde::to_vec_named`), so any
//! MessagePack library decodes it to a dictionary; every message carries `v`, the protocol
//! version. Arrays of numbers are MessagePack arrays of float64. See `docs/protocol.md`.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::error::ProtocolError;

/// Protocol version spoken by this build.
pub const PROTOCOL_VERSION: u16 = 1;

/// Largest payload accepted on any key, bytes (checked before decoding).
pub const MAX_MESSAGE_BYTES: usize = 64 << 20;

/// Largest number of cells a co-simulation carries, and the one cell limit of the whole project
/// (the plant library re-exports it as `crawler_plant::params::MAX_CELLS`).
pub const MAX_CELLS: usize = 1 << 20;

/// Longest identifier or name accepted in a message.
pub const MAX_ID_LEN: usize = 128;

/// Longest free text (status messages, summaries) accepted, bytes.
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
        finite_all("state.tension", &self.tension)
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
    /// Mean speed V, m/s.
    pub velocity: f64,
    /// Input power P, W.
    pub power: f64,
    /// Mileage |V|/P, m/J.
    pub mileage: f64,
    /// sup T / A_c, Pa.
    pub max_stress: f64,
    /// max |u_x|.
    pub max_strain: f64,
    /// Share of node-time stuck.
    pub stuck_fraction: f64,
    /// Mean friction selection <s>.
    pub mean_friction_selection: f64,
    /// Episodes per node per period.
    pub episodes_per_node_per_period: f64,
}

impl Message for Metrics {
    const NAME: &'static str = "metrics";
    fn version(&self) -> u16 {
        self.v
    }
    fn validate(&self) -> Result<(), ProtocolError> {
        for (name, x) in [
            ("start", self.start),
            ("end", self.end),
            ("velocity", self.velocity),
            ("power", self.power),
            ("max_stress", self.max_stress),
            ("max_strain", self.max_strain),
            ("stuck_fraction", self.stuck_fraction),
            ("mean_friction_selection", self.mean_friction_selection),
            (
                "episodes_per_node_per_period",
                self.episodes_per_node_per_period,
            ),
        ] {
            finite(&format!("metrics.{name}"), x)?;
        }
        if !(self.mileage.is_finite() || self.mileage.is_nan()) {
            return Err(ProtocolError::invalid(
                "metrics.mileage",
                self.mileage,
                "a finite number (NaN when P = 0)",
            ));
        }
        Ok(())
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
    /// From a controller other than the one that joined.
    pub foreign: u64,
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
            + self.stale
            + self.duplicate
            + self.future
            + self.overflow
    }
}

/// Life-cycle status of a process.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Status {
    /// Protocol version.
    pub v: u16,
    /// "plant", "controller" or "bridge".
    pub role: String,
    /// The process's id.
    pub id: String,
    /// "waiting", "running", "finished", "failed" or "stopped".
    pub state: String,
    /// Human-readable detail.
    pub message: String,
    /// Current communication step.
    pub step: u64,
    /// Rejected actuation so far (plant).
    pub rejected: Rejections,
    /// Final report as JSON text (plant, when finished).
    pub summary: Option<String>,
}

/// Allowed values of [`Status::state`].
pub const STATUS_STATES: &[&str] = &["waiting", "running", "finished", "failed", "stopped"];

impl Message for Status {
    const NAME: &'static str = "status";
    fn version(&self) -> u16 {
        self.v
    }
    fn validate(&self) -> Result<(), ProtocolError> {
        short("status.role", &self.role)?;
        short("status.id", &self.id)?;
        if !STATUS_STATES.contains(&self.state.as_str()) {
            return Err(ProtocolError::invalid(
                "status.state",
                &self.state,
                STATUS_STATES.join(", "),
            ));
        }
        text("status.message", &self.message)?;
        if let Some(s) = &self.summary {
            text("status.summary", s)?;
        }
        Ok(())
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
    /// V, m/s.
    pub velocity: Option<f64>,
    /// P, W.
    pub power: Option<f64>,
    /// M, m/J.
    pub mileage: Option<f64>,
    /// sigma, Pa.
    pub max_stress: Option<f64>,
    /// Stuck fraction.
    pub stuck_fraction: Option<f64>,
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
            for (name, x) in [
                ("velocity", m.velocity),
                ("power", m.power),
                ("mileage", m.mileage),
                ("max_stress", m.max_stress),
                ("stuck_fraction", m.stuck_fraction),
            ] {
                if let Some(x) = x {
                    finite(&format!("prediction.models[{i}].{name}"), x)?;
                }
            }
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
