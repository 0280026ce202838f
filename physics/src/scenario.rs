//! Scenario files (TOML): the plant's parameters, the actuation, the run length, the task.
//!
//! Unknown keys and wrong types are rejected with the line they are on; every value is checked
//! and an error names the field, the value and what is allowed. See `scenarios/paper.toml`.

use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;
use std::path::Path;

use crate::error::{finite, non_negative, positive, ParamError};
use crate::params::{Body, Boundary, Discretisation, Friction, Numerics, PlantParams};
use crate::pipe::Pipe;
use crate::wave::Wave;

/// The paper's scenario, embedded in the binaries.
pub const PAPER_TOML: &str = include_str!("../../scenarios/paper.toml");

/// Why a scenario could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file could not be read.
    // (The causes are shown in the message, not chained as `source`, so that printing the
    // error chain does not repeat them.)
    #[error("cannot read scenario {path}: {cause}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        cause: std::io::Error,
    },
    /// Not valid TOML, an unknown key or a wrong type (the message gives the line).
    #[error("scenario {origin}: {message}")]
    Syntax {
        /// The file name or `<embedded>`.
        origin: String,
        /// The parser's message with line and column.
        message: String,
    },
    /// A value out of range.
    #[error("scenario {origin}: {cause}")]
    Invalid {
        /// The file name.
        origin: String,
        /// The field at fault.
        cause: ParamError,
    },
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    name: Option<String>,
    description: Option<String>,
    body: RawBody,
    friction: Friction,
    actuation: RawActuation,
    #[serde(default)]
    numerics: RawNumerics,
    #[serde(default)]
    events: RawEvents,
    #[serde(default)]
    task: Task,
    #[serde(default)]
    limits: Limits,
    #[serde(default)]
    pipe: Pipe,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBody {
    area: f64,
    density: f64,
    youngs_modulus: f64,
    length: Option<f64>,
    #[serde(default)]
    boundary: Boundary,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawActuation {
    f0: f64,
    k: f64,
    omega: Option<f64>,
    alpha: Option<f64>,
    #[serde(default)]
    phase: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawNumerics {
    cells: i64,
    courant: Option<f64>,
    step: f64,
    t_end: f64,
    settle: f64,
    block: Option<f64>,
    filter: f64,
    ticks_per_second: Option<u64>,
}

impl Default for RawNumerics {
    fn default() -> Self {
        Self {
            cells: 256,
            courant: None,
            step: 1e-3,
            t_end: 10.0,
            settle: 5.0,
            block: None,
            filter: crate::params::DEFAULT_FILTER,
            ticks_per_second: None,
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawEvents {
    min_stick_periods: f64,
}

impl Default for RawEvents {
    fn default() -> Self {
        Self {
            min_stick_periods: 0.005,
        }
    }
}

/// Above this frequency ratio the default Courant number is `1 / alpha`.
pub const SUPERSONIC_ALPHA: f64 = 1.1;

/// The default Courant number for a scenario whose wave has frequency ratio `alpha`: 1 (the
/// scheme is then exact along characteristics, which the stick phases near resonance need), and
/// `1 / alpha` for waves more than 10 % faster than the body's sound speed, so that the wave's
/// pattern (and the stick phases it drives) moves at most one cell per step (`docs/numerics.md`).
pub fn default_courant(alpha: f64) -> f64 {
    if alpha > SUPERSONIC_ALPHA {
        1.0 / alpha
    } else {
        1.0
    }
}

/// The task of the paper's Sec. V: travel `distance` on `energy`, never exceed `sigma_max`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Task {
    /// Distance to travel `D`, m.
    pub distance: f64,
    /// Stored energy `J0`, J.
    pub energy: f64,
    /// Ultimate tensile strength `sigma_max`, Pa.
    pub sigma_max: f64,
    /// Time the stress may spend above `sigma_max` before the run has failed its task, s
    /// (0: any time above it fails; the outcome is then "stress exceeded").
    pub stress_tolerance: f64,
    /// True: the run ends when the centre of mass has travelled `distance` or the actuator has
    /// spent `energy` (task mode, [`crate::task`]); false: it runs to `t_end`.
    pub end_run: bool,
}

impl Default for Task {
    fn default() -> Self {
        Self {
            distance: 1.0,
            energy: 20.0,
            sigma_max: 100e3,
            stress_tolerance: 0.0,
            end_run: false,
        }
    }
}

impl Task {
    /// Required mileage `D / J0`, m/J.
    pub fn min_mileage(&self) -> f64 {
        self.distance / self.energy
    }

    /// Validates signs.
    pub fn validate(&self) -> Result<(), ParamError> {
        positive("task.distance", self.distance)?;
        positive("task.energy", self.energy)?;
        positive("task.sigma_max", self.sigma_max)?;
        non_negative("task.stress_tolerance", self.stress_tolerance)?;
        Ok(())
    }
}

/// Actuator and body limits for the optimiser.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Limits {
    /// `[omega_min, omega_max]`, rad/s.
    #[serde(deserialize_with = "crate::pair::pair")]
    pub omega: [f64; 2],
    /// `[k_min, k_max]`, rad/m.
    #[serde(deserialize_with = "crate::pair::pair")]
    pub k: [f64; 2],
    /// Largest muscle-force amplitude, N.
    pub f0_max: f64,
    /// Largest body strain `|u_x|`.
    pub strain_max: f64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            omega: [10.0, 300.0],
            k: [TAU, 4.0 * TAU],
            f0_max: 5.0,
            strain_max: 0.3,
        }
    }
}

impl Limits {
    /// Validates bounds: positive, finite, `min <= max`.
    pub fn validate(&self) -> Result<(), ParamError> {
        for (name, [lo, hi]) in [("limits.omega", self.omega), ("limits.k", self.k)] {
            positive(&format!("{name}[0]"), lo)?;
            positive(&format!("{name}[1]"), hi)?;
            if lo > hi {
                return Err(ParamError::new(
                    name,
                    format!("[{lo}, {hi}]"),
                    "[min, max] with min <= max",
                ));
            }
        }
        positive("limits.f0_max", self.f0_max)?;
        positive("limits.strain_max", self.strain_max)?;
        Ok(())
    }
}

/// Command-line overrides of the common fields.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// Dry friction coefficient.
    pub eps: Option<f64>,
    /// Asymmetry `n_F`.
    pub n_f: Option<f64>,
    /// Wave amplitude, N.
    pub f0: Option<f64>,
    /// Wave number, rad/m.
    pub k: Option<f64>,
    /// Angular frequency, rad/s.
    pub omega: Option<f64>,
    /// Frequency ratio `omega / omega_n`.
    pub alpha: Option<f64>,
    /// Number of cells.
    pub cells: Option<i64>,
    /// End time, s.
    pub t_end: Option<f64>,
    /// Task mode (`task.end_run`).
    pub end_run: Option<bool>,
}

/// A validated scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scenario {
    /// Short name.
    pub name: String,
    /// One line of description.
    pub description: String,
    /// The plant.
    pub plant: PlantParams,
    /// The travelling wave.
    pub wave: Wave,
    /// End time of a run, s.
    pub t_end: f64,
    /// The task constraints.
    pub task: Task,
    /// The optimiser's limits.
    pub limits: Limits,
    /// Shortest counted stick phase, in forcing periods.
    pub min_stick_periods: f64,
}

/// How big a run of a scenario is, known before it starts.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RunSize {
    /// Communication steps to the end of the run.
    pub macro_steps: u64,
    /// Internal (leapfrog) steps to the end of the run.
    pub internal_steps: u64,
    /// Cells times internal steps: the work of the run.
    pub cell_updates: f64,
    /// The time the run actually ends, s: the first communication point at or after `t_end`.
    pub t_end: f64,
    /// The communication step `H`, s.
    pub step: f64,
}

impl Scenario {
    /// The size of a run of this scenario to its `t_end` (the discretisation exists: the
    /// scenario was validated).
    pub fn run_size(&self) -> Result<RunSize, ParamError> {
        let d = self.plant.discretisation()?;
        let macro_steps = d.steps_until(self.t_end);
        let internal_steps = macro_steps.saturating_mul(d.substeps);
        Ok(RunSize {
            macro_steps,
            internal_steps,
            cell_updates: internal_steps as f64 * self.plant.numerics.cells as f64,
            t_end: macro_steps as f64 * d.step,
            step: d.step,
        })
    }

    /// The same scenario driven by another wave. The body stays as it is, unless `length` is
    /// given (the paper's convention of a body one wavelength long is `Some(2 pi / k)`); the
    /// stick threshold and the averaging block follow the new period. The wave must fit the body.
    pub fn with_wave(&self, wave: Wave, length: Option<f64>) -> Result<Scenario, ParamError> {
        let mut s = self.clone();
        s.wave = wave;
        if let Some(l) = length {
            s.plant.length = positive("body.length", l)?;
        }
        s.plant.numerics.block = wave.period();
        s.plant.validate()?;
        wave.validate_for_body(s.plant.length, s.plant.numerics.cells, s.plant.boundary)?;
        Ok(s)
    }

    /// The paper's scenario (embedded copy of `scenarios/paper.toml`).
    pub fn paper() -> Self {
        Self::from_toml(PAPER_TOML, "<embedded paper.toml>", &Overrides::default())
            .expect("the embedded paper scenario is valid")
    }

    /// Loads a scenario file and applies overrides.
    pub fn from_file(path: &Path, overrides: &Overrides) -> Result<Self, ScenarioError> {
        let text =
            crate::framing::read_text_at_most(path, MAX_SCENARIO_BYTES).map_err(|cause| {
                ScenarioError::Io {
                    path: path.display().to_string(),
                    cause,
                }
            })?;
        Self::from_toml(&text, &path.display().to_string(), overrides)
    }

    /// Loads the file at `path`, or the embedded paper scenario if `None`.
    pub fn load(path: Option<&Path>, overrides: &Overrides) -> Result<Self, ScenarioError> {
        match path {
            Some(p) => Self::from_file(p, overrides),
            None => Self::from_toml(PAPER_TOML, "<embedded paper.toml>", overrides),
        }
    }

    /// Parses TOML text; `origin` names it in errors.
    pub fn from_toml(
        text: &str,
        origin: &str,
        overrides: &Overrides,
    ) -> Result<Self, ScenarioError> {
        let raw: RawScenario = toml::from_str(text).map_err(|e| ScenarioError::Syntax {
            origin: origin.to_string(),
            message: e.to_string(),
        })?;
        raw.resolve(overrides)
            .map_err(|cause| ScenarioError::Invalid {
                origin: origin.to_string(),
                cause,
            })
    }

    /// Undamped natural frequency of the wave's mode, `omega_n = k c`, rad/s.
    pub fn natural_frequency(&self) -> f64 {
        self.wave.k * self.plant.body.wave_speed()
    }

    /// Frequency ratio `alpha = omega / omega_n`.
    pub fn alpha(&self) -> f64 {
        self.wave.omega / self.natural_frequency()
    }

    /// What in the scenario's numerics is known to bias its results, each naming the field, its
    /// value and what is allowed (empty when nothing is). A Courant number other than
    /// [`default_courant`] of the wave's `alpha` smears the stick phases' edges once there is dry
    /// friction (`friction.eps > 0`): at `alpha = 1.7` Courant 0.9 gives a stuck fraction of 0.351
    /// against 0.390, and the convergence estimate (N against 2N at the same Courant number) does
    /// not show it (`docs/numerics.md`). Such a scenario still runs (the benchmarks compare
    /// Courant numbers on purpose); programs print these caveats.
    pub fn caveats(&self) -> Vec<Caveat> {
        let mut out = Vec::new();
        let alpha = self.alpha();
        let courant = self.plant.numerics.courant;
        let unbiased = default_courant(alpha);
        if self.plant.friction.eps > 0.0 && (courant - unbiased).abs() > 1e-9 * unbiased {
            out.push(Caveat {
                field: "numerics.courant",
                value: courant,
                allowed: format!(
                    "{unbiased:.6} (the default at alpha = {alpha:.4}: {}) for unbiased stick statistics; other values smear the stick phases' edges (stuck fraction, episodes)",
                    if alpha > SUPERSONIC_ALPHA {
                        "1 / alpha"
                    } else {
                        "1"
                    }
                ),
            });
        }
        out
    }
}

/// A setting that runs but is known to bias a scenario's results ([`Scenario::caveats`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Caveat {
    /// The scenario field, e.g. `numerics.courant`.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
    /// What gives unbiased results, and what the value biases.
    pub allowed: String,
}

impl std::fmt::Display for Caveat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} = {} is known to bias the results: use {}",
            self.field, self.value, self.allowed
        )
    }
}

impl RawScenario {
    /// The validated scenario of this file with the overrides `o` applied.
    fn resolve(mut self, o: &Overrides) -> Result<Scenario, ParamError> {
        self.apply_overrides(o)?;
        if let Some(name) = self.name.as_deref() {
            check_name(name)?;
        }
        if let Some(text) = self.description.as_deref() {
            check_description(text)?;
        }
        let body = Body {
            area: self.body.area,
            density: self.body.density,
            youngs_modulus: self.body.youngs_modulus,
        };
        body.validate()?;
        self.friction.validate()?;
        let (wave, omega_n) = self.actuation.resolve(&body)?;
        let length = match self.body.length {
            Some(l) => positive("body.length", l)?,
            None => wave.wavelength(),
        };
        let (numerics, t_end) = self.resolve_numerics(&wave, omega_n)?;
        let min_stick_periods = numerics.min_stick_periods;
        let plant = PlantParams {
            body,
            friction: self.friction,
            length,
            boundary: self.body.boundary,
            pipe: self.pipe,
            numerics,
        };
        let scenario = Scenario {
            name: self.name.unwrap_or_else(|| "unnamed".into()),
            description: self.description.unwrap_or_default(),
            plant,
            wave,
            t_end,
            task: self.task,
            limits: self.limits,
            min_stick_periods,
        };
        // the wave is the file's [actuation] section
        scenario.validate().map_err(|mut e| {
            if let Some(rest) = e.field.strip_prefix("wave.") {
                e.field = format!("actuation.{rest}");
            }
            e
        })?;
        Ok(scenario)
    }

    /// Applies the command-line overrides `o` to the file's values (at most one of omega and
    /// alpha may be overridden; either replaces both of the file's).
    fn apply_overrides(&mut self, o: &Overrides) -> Result<(), ParamError> {
        if let Some(x) = o.eps {
            self.friction.eps = x;
        }
        if let Some(x) = o.n_f {
            self.friction.n_f = x;
        }
        if let Some(x) = o.f0 {
            self.actuation.f0 = x;
        }
        if let Some(x) = o.k {
            self.actuation.k = x;
        }
        if o.omega.is_some() && o.alpha.is_some() {
            return Err(ParamError::new(
                "omega/alpha",
                "both given",
                "at most one of --omega and --alpha",
            ));
        }
        if let Some(x) = o.omega {
            self.actuation.omega = Some(x);
            self.actuation.alpha = None;
        }
        if let Some(x) = o.alpha {
            self.actuation.alpha = Some(x);
            self.actuation.omega = None;
        }
        if let Some(x) = o.cells {
            self.numerics.cells = x;
        }
        if let Some(x) = o.t_end {
            self.numerics.t_end = x;
        }
        if let Some(x) = o.end_run {
            self.task.end_run = x;
        }
        Ok(())
    }

    /// The file's numerics for the validated `wave` (`omega_n`, rad/s, the natural frequency of
    /// its mode), and the run's end time `t_end`, s.
    fn resolve_numerics(&self, wave: &Wave, omega_n: f64) -> Result<(Numerics, f64), ParamError> {
        let cells = self.numerics.cells;
        if cells < crate::params::MIN_CELLS as i64 || cells > crate::params::MAX_CELLS as i64 {
            return Err(ParamError::new(
                "numerics.cells",
                cells,
                format!(
                    "an integer in [{}, {}]",
                    crate::params::MIN_CELLS,
                    crate::params::MAX_CELLS
                ),
            ));
        }
        let t_end = positive("numerics.t_end", self.numerics.t_end)?;
        let min_stick_periods =
            non_negative("events.min_stick_periods", self.events.min_stick_periods)?;
        let block = match self.numerics.block {
            Some(b) => positive("numerics.block", b)?,
            None => wave.period(),
        };
        let numerics = Numerics {
            cells: cells as usize,
            courant: match self.numerics.courant {
                Some(c) => c,
                None => default_courant(wave.omega / omega_n),
            },
            step: self.numerics.step,
            settle: self.numerics.settle,
            min_stick_periods,
            block,
            filter: self.numerics.filter,
            ticks_per_second: self.numerics.ticks_per_second,
        };
        Ok((numerics, t_end))
    }
}

impl RawActuation {
    /// The travelling wave of the [actuation] section on `body` (exactly one of omega and alpha
    /// given), and the natural frequency `omega_n = k c` of its mode, rad/s.
    fn resolve(&self, body: &Body) -> Result<(Wave, f64), ParamError> {
        positive("actuation.k", self.k)?;
        let omega_n = self.k * body.wave_speed();
        let omega = match (self.omega, self.alpha) {
            (Some(_), Some(_)) => {
                return Err(ParamError::new(
                    "actuation.omega/alpha",
                    "both given",
                    "exactly one of omega and alpha",
                ))
            }
            (None, None) => {
                return Err(ParamError::new(
                    "actuation.omega/alpha",
                    "neither given",
                    "exactly one of omega and alpha",
                ))
            }
            (Some(w), None) => positive("actuation.omega", w)?,
            (None, Some(a)) => positive("actuation.alpha", a)? * omega_n,
        };
        let wave = Wave {
            f0: non_negative("actuation.f0", self.f0)?,
            k: self.k,
            omega,
            phase: finite("actuation.phase", self.phase)?,
        };
        Ok((wave, omega_n))
    }
}

impl Scenario {
    /// Validates a whole scenario, also one that was not read from a scenario file (a
    /// checkpoint's): the plant, the wave on the body, the run's length against the
    /// discretisation, the task and the limits.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_name(&self.name)?;
        check_description(&self.description)?;
        let plant = &self.plant;
        plant.validate()?;
        let t_end = positive("numerics.t_end", self.t_end)?;
        let min_stick_periods = non_negative("events.min_stick_periods", self.min_stick_periods)?;
        if min_stick_periods != plant.numerics.min_stick_periods {
            return Err(ParamError::new(
                "events.min_stick_periods",
                min_stick_periods,
                format!(
                    "the plant's numerics.min_stick_periods = {}",
                    plant.numerics.min_stick_periods
                ),
            ));
        }
        let d = plant.discretisation()?;
        let h = d.step;
        let longest = crate::params::MAX_RUN_STEPS as f64 * d.dt;
        if t_end > longest {
            return Err(ParamError::new(
                "numerics.t_end",
                format!("{t_end:e}"),
                format!(
                    "<= {longest:e} s (2^53 internal steps of dt = {:e} s, so that the step count and the clock stay exact)",
                    d.dt
                ),
            ));
        }
        if h > t_end {
            return Err(ParamError::new(
                "numerics.step",
                plant.numerics.step,
                format!(
                    "a communication step no longer than numerics.t_end = {t_end} s (it is rounded to H = {h:e} s, a whole number of internal steps dt = Courant dx / c = {:e} s, with dx = body.length / numerics.cells = {:e} m and c = sqrt(body.area body.youngs_modulus / body.density) = {:e} m/s)",
                    d.dt,
                    d.dx,
                    plant.body.wave_speed()
                ),
            ));
        }
        self.wave
            .validate_for_body(plant.length, plant.numerics.cells, plant.boundary)?;
        check_run_length(t_end, &d, plant.numerics.block, plant.numerics.settle)?;
        self.task.validate()?;
        self.limits.validate()?;
        Ok(())
    }
}

/// The scenario's name: at most [`crawler_facts::MAX_SCENARIO_NAME_LEN`] bytes (it travels
/// in the plant's final report), no control characters (it is printed).
fn check_name(name: &str) -> Result<(), ParamError> {
    let most = crawler_facts::MAX_SCENARIO_NAME_LEN;
    check_text(
        "name",
        name,
        most,
        format!("at most {most} bytes (it travels in the plant's final report)"),
    )
}

/// The scenario's description: one line of at most [`MAX_DESCRIPTION_LEN`] bytes.
fn check_description(text: &str) -> Result<(), ParamError> {
    check_text(
        "description",
        text,
        MAX_DESCRIPTION_LEN,
        format!("one line of at most {MAX_DESCRIPTION_LEN} bytes"),
    )
}

/// `text` holds at most `most` bytes (else the error says `allowed`) and no control characters
/// (escape sequences, line breaks).
fn check_text(field: &str, text: &str, most: usize, allowed: String) -> Result<(), ParamError> {
    if text.len() > most {
        return Err(ParamError::new(
            field,
            format!(
                "{:?}... ({} bytes)",
                text.chars().take(24).collect::<String>(),
                text.len()
            ),
            allowed,
        ));
    }
    match text.chars().position(char::is_control) {
        None => Ok(()),
        Some(at) => Err(ParamError::new(
            field,
            format!("{text:?}"),
            format!("text without control characters (character {at} is one)"),
        )),
    }
}

/// Largest scenario file, bytes (a [`MAX_FEATURES`](crate::pipe::MAX_FEATURES)-feature pipe
/// takes about 100 KB).
pub const MAX_SCENARIO_BYTES: u64 = 16 << 20;

/// Longest scenario description, bytes.
pub const MAX_DESCRIPTION_LEN: usize = 4096;

/// The run to `t_end` (s) on the discretisation `d` must close the first steady averaging block:
/// the steady metrics average whole blocks of `block` seconds (forcing periods) counted from
/// t = 0 that start after `settle` seconds, and a block closes at the first internal step after
/// its end ([`crate::metrics::steps_to_steady_block`]).
fn check_run_length(
    t_end: f64,
    d: &Discretisation,
    block: f64,
    settle: f64,
) -> Result<(), ParamError> {
    let Some(needed) = crate::metrics::steps_to_steady_block(d.dt, block, settle) else {
        // counts beyond 2^52: the block rules cannot be followed exactly, only roughly
        let needed = settle + block;
        if t_end < needed {
            return Err(ParamError::new(
                "numerics.t_end",
                t_end,
                format!(">= settle + one averaging block = {needed:e} s"),
            ));
        }
        return Ok(());
    };
    if d.steps_until(t_end).saturating_mul(d.substeps) < needed {
        let macro_steps = needed.div_ceil(d.substeps);
        return Err(ParamError::new(
            "numerics.t_end",
            t_end,
            format!(
                "a run of at least {:.6} s ({macro_steps} communication steps of H = {:e} s): \
                 the steady metrics average whole forcing periods counted from t = 0 that start \
                 after settle = {settle} s, and the first of them closes at the first internal \
                 step after its end",
                needed as f64 * d.dt,
                d.step
            ),
        ));
    }
    Ok(())
}
