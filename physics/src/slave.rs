//! An FMI 3.0 co-simulation style slave around the [`Plant`].
//!
//! Lifecycle: `instantiate` → Instantiated (⇄ ConfigurationMode, where the structural parameters
//! `cells` and `boundary` are set) → `enter_initialization_mode` → InitializationMode →
//! `exit_initialization_mode` → StepMode → `terminate` → Terminated; `reset` returns to
//! Instantiated from any state. A call that is not allowed in the current state, or any other
//! failure reported as `Error`, puts the slave into the Error state, from which only getters,
//! `set_state` and `reset` are accepted (as in FMI 3.0).
//!
//! Times given by an importer are compared with the plant's own (`t0 + n H`, from an integer
//! step count) within [`time_tolerance`], which grows with `|t|`: importers compute their time
//! and step by adding and subtracting floats (FMPy sends `h = 0.009999999999999787` for 10 ms).

use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::framing;
use crate::model_description::{vr, ModelDescription};
use crate::params::PlantParams;
use crate::plant::{Drive, Plant, PlantState, StepError};
use crate::wave::Wave;

/// Lifecycle states.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum LifecycleState {
    /// Created; fixed parameters may be set.
    Instantiated,
    /// Structural parameters (`cells`, `boundary`) may be set (FMI 3.0 Configuration Mode).
    ConfigurationMode,
    /// Initialisation: parameters and inputs may be set, outputs read.
    InitializationMode,
    /// Stepping.
    StepMode,
    /// Finished; only getters and reset.
    Terminated,
    /// A call failed; only getters, `set_state` and reset.
    Error,
}

/// Errors returned by the slave (FMI `fmi3Error`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SlaveError {
    /// The call is not allowed in the current lifecycle state.
    #[error("{call} is not allowed in state {state:?}")]
    IllegalCall {
        /// The function called.
        call: &'static str,
        /// The state it was called in.
        state: LifecycleState,
    },
    /// A value was rejected.
    #[error(transparent)]
    Invalid(#[from] ParamError),
    /// No variable has this value reference (or it has another type).
    #[error("no {kind} variable with value reference {vr}")]
    UnknownReference {
        /// The value reference.
        vr: u32,
        /// The expected type.
        kind: &'static str,
    },
    /// The variable cannot be set in this state (or never).
    #[error("variable {name} (vr {vr}) cannot be set in state {state:?}")]
    NotSettable {
        /// Variable name.
        name: &'static str,
        /// Value reference.
        vr: u32,
        /// State.
        state: LifecycleState,
    },
    /// Wrong number of values for the value references.
    #[error("{got} values given for value references needing {expected}")]
    WrongCount {
        /// Values expected.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// A serialized state could not be decoded.
    #[error("invalid serialized state: {0}")]
    BadState(String),
}

/// Result of `do_step` (FMI `fmi3OK`, `fmi3Discard`, `fmi3Error`).
#[derive(Debug, Clone, PartialEq)]
pub enum StepStatus {
    /// The step was completed.
    Ok,
    /// The step could not be completed; the state is that at `last_successful_time`.
    Discard {
        /// Time of the current (rolled back) state, s.
        last_successful_time: f64,
        /// Why.
        reason: String,
    },
    /// The call failed; the slave is in the Error state.
    Error(SlaveError),
}

/// Actuation requested through the inputs, applied at the next `do_step`.
#[derive(Debug, Clone, PartialEq)]
struct Inputs {
    mode: u64,
    wave: Wave,
    field: Vec<f64>,
    dirty: bool,
}

/// A plant instance with an FMI-style interface.
#[derive(Debug, Clone)]
pub struct Slave {
    instance_name: String,
    params: PlantParams,
    original: PlantParams,
    start_wave: Option<Wave>,
    state: LifecycleState,
    plant: Plant,
    inputs: Inputs,
    start_time: f64,
    stop_time: Option<f64>,
}

/// How far an importer's time may be from the plant's own and still name the same communication
/// point, s: `1e-9 (|t| + H)`, at most `H / 4` (so that no two points can be confused). It grows
/// with `|t|` because importers add up their time in floats.
pub fn time_tolerance(t: f64, step: f64) -> f64 {
    (1e-9 * (t.abs() + step)).min(0.25 * step)
}

const STATE_MAGIC: &[u8; 8] = b"CRWLSTAT";
const STATE_VERSION: u32 = 3;

impl Slave {
    /// `fmi3InstantiateCoSimulation`: validates the parameters and allocates the plant, without
    /// actuation until the inputs are set.
    pub fn instantiate(instance_name: &str, params: PlantParams) -> Result<Self, SlaveError> {
        Self::build(instance_name, params, None)
    }

    /// Instantiates a plant whose inputs start as `wave` (actuation mode 1): it is driven by
    /// the wave unless the importer sets other inputs. This is what an FMU does with its
    /// scenario's wave (the start values of its model description).
    pub fn instantiate_with_wave(
        instance_name: &str,
        params: PlantParams,
        wave: Wave,
    ) -> Result<Self, SlaveError> {
        wave.validate_for_body(params.length, params.numerics.cells, params.boundary)?;
        Self::build(instance_name, params, Some(wave))
    }

    fn build(
        instance_name: &str,
        params: PlantParams,
        start_wave: Option<Wave>,
    ) -> Result<Self, SlaveError> {
        let plant = Plant::new(params.clone(), 0.0)?;
        Ok(Self {
            instance_name: instance_name.to_string(),
            inputs: Self::start_inputs(&params, start_wave),
            params: params.clone(),
            original: params,
            start_wave,
            state: LifecycleState::Instantiated,
            plant,
            start_time: 0.0,
            stop_time: None,
        })
    }

    fn start_inputs(params: &PlantParams, start_wave: Option<Wave>) -> Inputs {
        Inputs {
            mode: if start_wave.is_some() { 1 } else { 0 },
            wave: start_wave.unwrap_or(Wave {
                f0: 0.0,
                k: std::f64::consts::TAU / params.length,
                omega: 1.0,
                phase: 0.0,
            }),
            field: vec![0.0; params.numerics.cells],
            dirty: start_wave.is_some(),
        }
    }

    /// Instance name.
    pub fn instance_name(&self) -> &str {
        &self.instance_name
    }

    /// Lifecycle state.
    pub fn lifecycle(&self) -> LifecycleState {
        self.state
    }

    /// The plant (read-only).
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// Current parameters.
    pub fn params(&self) -> &PlantParams {
        &self.params
    }

    /// Counts the time during which the stress exceeds `sigma_max` Pa ([`Plant::set_stress_limit`]).
    pub fn set_stress_limit(&mut self, sigma_max: Option<f64>) -> Result<(), SlaveError> {
        Ok(self.plant.set_stress_limit(sigma_max)?)
    }

    /// The model description (start values: the current parameters and the start inputs).
    pub fn model_description(&self) -> ModelDescription {
        ModelDescription::with_inputs(&self.params, self.start_wave)
    }

    /// `fmi3EnterConfigurationMode`: from Instantiated; the structural parameters `cells` and
    /// `boundary` may then be set.
    pub fn enter_configuration_mode(&mut self) -> Result<(), SlaveError> {
        self.require("enter_configuration_mode", &[LifecycleState::Instantiated])?;
        self.state = LifecycleState::ConfigurationMode;
        Ok(())
    }

    /// `fmi3ExitConfigurationMode`: back to Instantiated.
    pub fn exit_configuration_mode(&mut self) -> Result<(), SlaveError> {
        self.require(
            "exit_configuration_mode",
            &[LifecycleState::ConfigurationMode],
        )?;
        self.state = LifecycleState::Instantiated;
        Ok(())
    }

    fn fail<T>(&mut self, e: SlaveError) -> Result<T, SlaveError> {
        self.state = LifecycleState::Error;
        Err(e)
    }

    fn require(
        &mut self,
        call: &'static str,
        allowed: &[LifecycleState],
    ) -> Result<(), SlaveError> {
        if allowed.contains(&self.state) {
            Ok(())
        } else {
            let state = self.state;
            self.fail(SlaveError::IllegalCall { call, state })
        }
    }

    /// `fmi3EnterInitializationMode`: fixes the start (and optional stop) time, s.
    pub fn enter_initialization_mode(
        &mut self,
        start_time: f64,
        stop_time: Option<f64>,
    ) -> Result<(), SlaveError> {
        self.require("enter_initialization_mode", &[LifecycleState::Instantiated])?;
        if !start_time.is_finite() {
            return self
                .fail(ParamError::new("start_time", start_time, "a finite time (s)").into());
        }
        if let Some(stop) = stop_time {
            if !(stop.is_finite() && stop > start_time) {
                return self.fail(
                    ParamError::new(
                        "stop_time",
                        stop,
                        format!("a finite time > start_time = {start_time}"),
                    )
                    .into(),
                );
            }
        }
        match Plant::new(self.params.clone(), start_time) {
            Ok(p) => self.plant = p,
            Err(e) => return self.fail(e.into()),
        }
        self.start_time = start_time;
        self.stop_time = stop_time;
        self.state = LifecycleState::InitializationMode;
        Ok(())
    }

    /// `fmi3ExitInitializationMode`: applies the inputs and enters step mode.
    pub fn exit_initialization_mode(&mut self) -> Result<(), SlaveError> {
        self.require(
            "exit_initialization_mode",
            &[LifecycleState::InitializationMode],
        )?;
        if let Err(e) = self.apply_inputs() {
            return self.fail(e);
        }
        self.state = LifecycleState::StepMode;
        Ok(())
    }

    /// `fmi3Terminate`.
    pub fn terminate(&mut self) -> Result<(), SlaveError> {
        self.require("terminate", &[LifecycleState::StepMode])?;
        self.state = LifecycleState::Terminated;
        Ok(())
    }

    /// `fmi3Reset`: back to Instantiated with the parameters and start inputs given at
    /// instantiation.
    pub fn reset(&mut self) -> Result<(), SlaveError> {
        let fresh = Self::build(&self.instance_name, self.original.clone(), self.start_wave)?;
        *self = fresh;
        Ok(())
    }

    /// Sets the actuation to apply from the next step on (typed form of the input variables).
    pub fn set_wave(&mut self, wave: Wave) -> Result<(), SlaveError> {
        self.require(
            "set_wave",
            &[LifecycleState::InitializationMode, LifecycleState::StepMode],
        )?;
        if let Err(e) = wave.validate_for_body(
            self.params.length,
            self.params.numerics.cells,
            self.params.boundary,
        ) {
            return self.fail(e.into());
        }
        self.inputs.mode = 1;
        self.inputs.wave = wave;
        self.inputs.dirty = true;
        Ok(())
    }

    /// Sets a muscle-force field (N at the half nodes) to hold from the next step on.
    pub fn set_field(&mut self, field: &[f64]) -> Result<(), SlaveError> {
        self.require(
            "set_field",
            &[LifecycleState::InitializationMode, LifecycleState::StepMode],
        )?;
        if field.len() != self.params.numerics.cells {
            let e = ParamError::new(
                "muscle_force",
                format!("{} values", field.len()),
                format!("exactly {} values", self.params.numerics.cells),
            );
            return self.fail(e.into());
        }
        if let Some((i, x)) = field.iter().enumerate().find(|(_, x)| !x.is_finite()) {
            return self.fail(
                ParamError::new(format!("muscle_force[{i}]"), x, "finite numbers (N)").into(),
            );
        }
        self.inputs.mode = 2;
        self.inputs.field.copy_from_slice(field);
        self.inputs.dirty = true;
        Ok(())
    }

    fn apply_inputs(&mut self) -> Result<(), SlaveError> {
        if !self.inputs.dirty {
            return Ok(());
        }
        self.inputs.dirty = false;
        match self.inputs.mode {
            0 => Ok(()),
            1 => Ok(self.plant.set_wave(self.inputs.wave)?),
            _ => Ok(self.plant.set_field(&self.inputs.field)?),
        }
    }

    /// `fmi3DoStep` from `current_time` (the slave's time, within [`time_tolerance`]) over `h`
    /// seconds, a whole number of communication steps `H` (within the same tolerance). Any
    /// other `h` is an Error: the plant's step is fixed (`canHandleVariableCommunicationStepSize
    /// = false`), and a Discard would invite the importer to retry with the same `h`.
    pub fn do_step(&mut self, current_time: f64, h: f64) -> StepStatus {
        if let Err(e) = self.require("do_step", &[LifecycleState::StepMode]) {
            return StepStatus::Error(e);
        }
        let now = self.plant.time();
        let step = self.plant.step_length();
        let tol = time_tolerance(now, step);
        if !current_time.is_finite() || (current_time - now).abs() > tol {
            let e = ParamError::new(
                "current_time",
                current_time,
                format!("the slave's time {now} s (within {tol:.1e} s)"),
            );
            return StepStatus::Error(self.fail::<()>(e.into()).unwrap_err());
        }
        let n = (h / step).round();
        if !(h.is_finite() && (1.0..1e15).contains(&n) && (h - n * step).abs() <= tol.max(1e-9 * h))
        {
            let d = self.plant.discretisation();
            let clock = match d.ticks {
                Some(n) => format!(
                    ", {n} ticks of the clock ticks_per_second = {}",
                    self.params.numerics.ticks_per_second.unwrap_or(0)
                ),
                None => "; a master that counts time in whole ticks (libcosim: nanoseconds) \
                         sets the parameter ticks_per_second (1000000000) to make H a whole \
                         number of them"
                    .into(),
            };
            let e = ParamError::new(
                "h",
                h,
                format!(
                    "a whole number of communication steps H = {step:e} s (each H is {} internal \
                     steps of dt = {:e} s; the plant's step is fixed{clock})",
                    d.substeps, d.dt
                ),
            );
            return StepStatus::Error(self.fail::<()>(e.into()).unwrap_err());
        }
        if let Some(stop) = self.stop_time {
            if now + n * step > stop + tol {
                let e = ParamError::new(
                    "h",
                    h,
                    format!("a step ending at or before stop_time = {stop} s"),
                );
                return StepStatus::Error(self.fail::<()>(e.into()).unwrap_err());
            }
        }
        if let Err(e) = self.apply_inputs() {
            return StepStatus::Error(self.fail::<()>(e).unwrap_err());
        }
        for _ in 0..n as u64 {
            if let Err(StepError::NonFinite {
                time,
                last_successful_time,
            }) = self.plant.advance()
            {
                return StepStatus::Discard {
                    last_successful_time,
                    reason: format!(
                        "the state became non-finite at t = {time} s (actuation too large?)"
                    ),
                };
            }
        }
        StepStatus::Ok
    }

    fn settable(&self, vr: u32) -> bool {
        use LifecycleState::*;
        // FMI 3.0 sets structural parameters in Configuration Mode; importers that set every
        // exact start value after instantiation (FMPy does) may also set them in Instantiated.
        let structural = matches!(self.state, Instantiated | ConfigurationMode);
        let params = matches!(self.state, Instantiated | InitializationMode);
        let inputs = matches!(self.state, Instantiated | InitializationMode | StepMode);
        match vr {
            vr::CELLS | vr::BOUNDARY => structural,
            vr::LENGTH | vr::AREA..=vr::TICKS_PER_SECOND => params,
            vr::ACTUATION_MODE..=vr::MUSCLE_FORCE => inputs,
            _ => false,
        }
    }

    fn not_settable<T>(&mut self, r: u32, kind: &'static str) -> Result<T, SlaveError> {
        let state = self.state;
        match crate::model_description::variable_name(r) {
            Some((name, _)) => self.fail(SlaveError::NotSettable { name, vr: r, state }),
            None => self.fail(SlaveError::UnknownReference { vr: r, kind }),
        }
    }

    /// The Float64 array with value reference `r` (`muscle_force`, `u`, `v`, `tension`), or
    /// `None` for any other reference.
    pub fn float64_array(&self, r: u32) -> Option<std::borrow::Cow<'_, [f64]>> {
        use std::borrow::Cow;
        match r {
            vr::MUSCLE_FORCE => Some(Cow::Borrowed(&self.inputs.field)),
            vr::U => Some(Cow::Borrowed(self.plant.displacement())),
            vr::V => Some(Cow::Borrowed(self.plant.velocity())),
            vr::TENSION => Some(Cow::Owned(self.plant.tension())),
            _ => None,
        }
    }

    /// The value of the Float64 scalar `r`, or `None` if `r` is not one.
    pub fn float64_scalar(&self, r: u32) -> Option<f64> {
        let p = &self.params;
        let d = self.plant.discretisation();
        // Steady metrics are 0 until the first steady period closes (never NaN: importers
        // record outputs from the start); `steady_periods` says when they are meaningful.
        let steady = self.plant.steady_metrics();
        let metric = |f: fn(&crate::metrics::Metrics) -> f64| steady.as_ref().map_or(0.0, f);
        let u = self.plant.displacement();
        Some(match r {
            vr::TIME => self.plant.time(),
            vr::LENGTH => p.length,
            vr::AREA => p.body.area,
            vr::DENSITY => p.body.density,
            vr::YOUNGS_MODULUS => p.body.youngs_modulus,
            vr::VISCOUS => p.friction.viscous,
            vr::DRY => p.friction.dry,
            vr::EPS => p.friction.eps,
            vr::N_F => p.friction.n_f,
            vr::COURANT => p.numerics.courant,
            vr::STEP => p.numerics.step,
            vr::SETTLE => p.numerics.settle,
            vr::MIN_STICK => p.numerics.min_stick_periods,
            vr::BLOCK => p.numerics.block,
            vr::FILTER => p.numerics.filter,
            vr::DT => d.dt,
            vr::DX => d.dx,
            vr::WAVE_SPEED => p.body.wave_speed(),
            vr::COMMUNICATION_STEP => d.step,
            vr::WAVE_F0 => self.inputs.wave.f0,
            vr::WAVE_K => self.inputs.wave.k,
            vr::WAVE_OMEGA => self.inputs.wave.omega,
            vr::WAVE_PHASE => self.inputs.wave.phase,
            vr::MEAN_SPEED => self.plant.outputs().mean_speed,
            vr::INPUT_POWER => self.plant.outputs().input_power,
            vr::TAIL_DISPLACEMENT => u[0],
            vr::MEAN_DISPLACEMENT => u.iter().sum::<f64>() / u.len() as f64,
            vr::VELOCITY => metric(|m| m.velocity),
            vr::POWER => metric(|m| m.power),
            vr::MILEAGE => metric(|m| m.mileage),
            vr::MAX_STRESS => metric(|m| m.max_stress),
            vr::MAX_STRAIN => metric(|m| m.max_strain),
            vr::STUCK_FRACTION => metric(|m| m.stuck_fraction),
            vr::MEAN_FRICTION_SELECTION => metric(|m| m.mean_friction_selection),
            vr::STEADY_PERIODS => metric(|m| m.periods),
            vr::EPISODE_RATE => metric(|m| m.episodes_per_node_per_period),
            _ => return None,
        })
    }

    /// `fmi3GetFloat64`: values of the variables in order, arrays flattened.
    pub fn get_float64(&self, vrs: &[u32]) -> Result<Vec<f64>, SlaveError> {
        let mut out = Vec::new();
        for &r in vrs {
            if let Some(a) = self.float64_array(r) {
                out.extend_from_slice(&a);
            } else if let Some(x) = self.float64_scalar(r) {
                out.push(x);
            } else {
                return Err(SlaveError::UnknownReference {
                    vr: r,
                    kind: "Float64",
                });
            }
        }
        Ok(out)
    }

    /// `fmi3GetUInt64`.
    pub fn get_uint64(&self, vrs: &[u32]) -> Result<Vec<u64>, SlaveError> {
        vrs.iter()
            .map(|&r| match r {
                vr::CELLS => Ok(self.params.numerics.cells as u64),
                vr::SUBSTEPS => Ok(self.plant.discretisation().substeps),
                vr::ACTUATION_MODE => Ok(self.inputs.mode),
                vr::TICKS_PER_SECOND => Ok(self.params.numerics.ticks_per_second.unwrap_or(0)),
                vr::STUCK_NODES => Ok(self.plant.outputs().stuck_nodes),
                _ => Err(SlaveError::UnknownReference {
                    vr: r,
                    kind: "UInt64",
                }),
            })
            .collect()
    }

    /// `fmi3GetInt64` (the enumeration `boundary`, [`crate::model_description::BOUNDARY_ITEMS`]).
    pub fn get_int64(&self, vrs: &[u32]) -> Result<Vec<i64>, SlaveError> {
        vrs.iter()
            .map(|&r| match r {
                vr::BOUNDARY => Ok(crate::model_description::boundary_value(
                    self.params.boundary,
                )),
                _ => Err(SlaveError::UnknownReference {
                    vr: r,
                    kind: "Int64 (enumeration)",
                }),
            })
            .collect()
    }

    /// `fmi3GetString` (the pipe as JSON).
    pub fn get_string(&self, vrs: &[u32]) -> Result<Vec<String>, SlaveError> {
        vrs.iter()
            .map(|&r| match r {
                vr::PIPE => Ok(serde_json::to_string(&self.params.pipe).expect("pipe serializes")),
                _ => Err(SlaveError::UnknownReference {
                    vr: r,
                    kind: "String",
                }),
            })
            .collect()
    }

    /// `fmi3GetBoolean` (arrays flattened).
    pub fn get_boolean(&self, vrs: &[u32]) -> Result<Vec<bool>, SlaveError> {
        let mut out = Vec::new();
        for &r in vrs {
            match r {
                vr::STUCK => out.extend_from_slice(self.plant.stuck()),
                _ => {
                    return Err(SlaveError::UnknownReference {
                        vr: r,
                        kind: "Boolean",
                    })
                }
            }
        }
        Ok(out)
    }

    /// Replaces the parameters (before step mode): validated, the plant rebuilt.
    fn replace_params(&mut self, params: PlantParams) -> Result<(), SlaveError> {
        if params == self.params {
            return Ok(());
        }
        if let Err(e) = params.validate() {
            return self.fail(e.into());
        }
        match Plant::new(params.clone(), self.plant.start_time()) {
            Ok(p) => self.plant = p,
            Err(e) => return self.fail(e.into()),
        }
        if params.numerics.cells != self.params.numerics.cells {
            self.inputs.field = vec![0.0; params.numerics.cells];
        }
        self.params = params;
        Ok(())
    }

    /// `fmi3SetUInt64`: the actuation mode; `ticks_per_second` before step mode; `cells` in
    /// Configuration Mode.
    pub fn set_uint64(&mut self, vrs: &[u32], values: &[u64]) -> Result<(), SlaveError> {
        if vrs.len() != values.len() {
            return self.fail(SlaveError::WrongCount {
                expected: vrs.len(),
                got: values.len(),
            });
        }
        for (&r, &x) in vrs.iter().zip(values) {
            match r {
                vr::ACTUATION_MODE | vr::CELLS | vr::TICKS_PER_SECOND if !self.settable(r) => {
                    return self.not_settable(r, "UInt64")
                }
                vr::ACTUATION_MODE => {
                    if x > 2 {
                        return self.fail(
                            ParamError::new("actuation_mode", x, "0 (none), 1 (wave) or 2 (field)")
                                .into(),
                        );
                    }
                    self.inputs.mode = x;
                    self.inputs.dirty = true;
                }
                vr::CELLS => {
                    let cells = usize::try_from(x).unwrap_or(usize::MAX);
                    let mut params = self.params.clone();
                    params.numerics.cells = cells;
                    self.replace_params(params)?;
                }
                vr::TICKS_PER_SECOND => {
                    let mut params = self.params.clone();
                    params.numerics.ticks_per_second = (x > 0).then_some(x);
                    self.replace_params(params)?;
                }
                vr::SUBSTEPS | vr::STUCK_NODES => return self.not_settable(r, "UInt64"),
                _ => {
                    return self.fail(SlaveError::UnknownReference {
                        vr: r,
                        kind: "UInt64",
                    })
                }
            }
        }
        Ok(())
    }

    /// `fmi3SetInt64`: the enumeration `boundary`, in Configuration Mode.
    pub fn set_int64(&mut self, vrs: &[u32], values: &[i64]) -> Result<(), SlaveError> {
        if vrs.len() != values.len() {
            return self.fail(SlaveError::WrongCount {
                expected: vrs.len(),
                got: values.len(),
            });
        }
        for (&r, &x) in vrs.iter().zip(values) {
            match r {
                vr::BOUNDARY if self.settable(r) => {
                    let Some(b) = crate::model_description::boundary_of(x) else {
                        return self.fail(
                            ParamError::new("boundary", x, "1 (periodic) or 2 (free)").into(),
                        );
                    };
                    let mut params = self.params.clone();
                    params.boundary = b;
                    self.replace_params(params)?;
                }
                vr::BOUNDARY => return self.not_settable(r, "Int64 (enumeration)"),
                _ => {
                    return self.fail(SlaveError::UnknownReference {
                        vr: r,
                        kind: "Int64 (enumeration)",
                    })
                }
            }
        }
        Ok(())
    }

    /// `fmi3SetString`: the pipe, as the JSON of a scenario's `[pipe]` section (before step
    /// mode).
    pub fn set_string(&mut self, vrs: &[u32], values: &[&str]) -> Result<(), SlaveError> {
        if vrs.len() != values.len() {
            return self.fail(SlaveError::WrongCount {
                expected: vrs.len(),
                got: values.len(),
            });
        }
        for (&r, &text) in vrs.iter().zip(values) {
            match r {
                vr::PIPE if self.settable(r) => {
                    let pipe = match parse_pipe(text) {
                        Ok(p) => p,
                        Err(e) => return self.fail(e.into()),
                    };
                    let mut params = self.params.clone();
                    params.pipe = pipe;
                    self.replace_params(params)?;
                }
                vr::PIPE => return self.not_settable(r, "String"),
                _ => {
                    return self.fail(SlaveError::UnknownReference {
                        vr: r,
                        kind: "String",
                    })
                }
            }
        }
        Ok(())
    }

    /// `fmi3SetFloat64`: parameters (before step mode) and inputs; arrays take `cells` values.
    pub fn set_float64(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), SlaveError> {
        let n = self.params.numerics.cells;
        let expected: usize = vrs
            .iter()
            .map(|&r| if r == vr::MUSCLE_FORCE { n } else { 1 })
            .sum();
        if expected != values.len() {
            return self.fail(SlaveError::WrongCount {
                expected,
                got: values.len(),
            });
        }
        let mut params = self.params.clone();
        let mut inputs = self.inputs.clone();
        let mut rest = values;
        for &r in vrs {
            match crate::model_description::variable_name(r) {
                Some((_, crate::model_description::VarType::Float64)) => {}
                _ => {
                    return self.fail(SlaveError::UnknownReference {
                        vr: r,
                        kind: "Float64",
                    })
                }
            }
            if !self.settable(r) {
                return self.not_settable(r, "Float64");
            }
            let take = if r == vr::MUSCLE_FORCE { n } else { 1 };
            let (now, later) = rest.split_at(take);
            rest = later;
            let x = now[0];
            match r {
                vr::LENGTH => params.length = x,
                vr::AREA => params.body.area = x,
                vr::DENSITY => params.body.density = x,
                vr::YOUNGS_MODULUS => params.body.youngs_modulus = x,
                vr::VISCOUS => params.friction.viscous = x,
                vr::DRY => params.friction.dry = x,
                vr::EPS => params.friction.eps = x,
                vr::N_F => params.friction.n_f = x,
                vr::COURANT => params.numerics.courant = x,
                vr::STEP => params.numerics.step = x,
                vr::SETTLE => params.numerics.settle = x,
                vr::MIN_STICK => params.numerics.min_stick_periods = x,
                vr::BLOCK => params.numerics.block = x,
                vr::FILTER => params.numerics.filter = x,
                vr::WAVE_F0 => inputs.wave.f0 = x,
                vr::WAVE_K => inputs.wave.k = x,
                vr::WAVE_OMEGA => inputs.wave.omega = x,
                vr::WAVE_PHASE => inputs.wave.phase = x,
                vr::MUSCLE_FORCE => {
                    if let Some((i, x)) = now.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                        return self.fail(
                            ParamError::new(format!("muscle_force[{i}]"), x, "finite numbers (N)")
                                .into(),
                        );
                    }
                    inputs.field.copy_from_slice(now);
                }
                _ => return self.not_settable(r, "Float64"),
            }
            if (vr::WAVE_F0..=vr::MUSCLE_FORCE).contains(&r) {
                inputs.dirty = true;
            }
        }
        self.replace_params(params)?;
        if inputs.dirty && inputs.mode == 1 {
            if let Err(e) = inputs.wave.validate() {
                return self.fail(e.into());
            }
        }
        self.inputs = inputs;
        Ok(())
    }

    /// `fmi3GetFMUState`: a copy of the complete state.
    pub fn get_state(&self) -> PlantState {
        self.plant.state()
    }

    /// `fmi3SetFMUState`: restores a state of this plant (also leaves the Error state).
    pub fn set_state(&mut self, state: &PlantState) -> Result<(), SlaveError> {
        self.plant.set_state(state)?;
        self.inputs.dirty = false;
        match state.drive {
            Drive::Wave(w) => {
                self.inputs.mode = 1;
                self.inputs.wave = w;
            }
            Drive::Field => {
                self.inputs.mode = 2;
                self.inputs.field.clone_from(&state.field);
            }
            Drive::Idle => self.inputs.mode = 0,
        }
        if matches!(
            self.state,
            LifecycleState::Error | LifecycleState::Terminated
        ) {
            self.state = LifecycleState::StepMode;
        }
        Ok(())
    }

    /// `fmi3SerializeFMUState`: a framed blob ([`crate::framing`], magic `CRWLSTAT`) holding
    /// the MessagePack of the [`PlantState`].
    pub fn serialize_state(state: &PlantState) -> Vec<u8> {
        framing::encode(STATE_MAGIC, STATE_VERSION, state)
    }

    /// `fmi3DeserializeFMUState`: checks magic, version and checksum; values are validated when
    /// the state is set.
    pub fn deserialize_state(bytes: &[u8]) -> Result<PlantState, SlaveError> {
        let state: PlantState =
            framing::decode(STATE_MAGIC, STATE_VERSION, "crawler plant state", bytes)
                .map_err(|e| SlaveError::BadState(e.0))?;
        state
            .params
            .validate()
            .map_err(|e| SlaveError::BadState(e.to_string()))?;
        Ok(state)
    }
}

/// An example of the `pipe` string variable, for error messages.
const PIPE_EXAMPLE: &str = r#"{"features":[{"kind":"patch","from":0.5,"to":1.0,"eps":0.3}]}"#;

/// The pipe of the `pipe` string variable: the JSON of a scenario's `[pipe]` section.
fn parse_pipe(text: &str) -> Result<crate::pipe::Pipe, ParamError> {
    serde_json::from_str::<crate::pipe::Pipe>(text).map_err(|e| {
        ParamError::new(
            "pipe",
            format!("{text:.80}"),
            format!("the JSON of a scenario's [pipe] section ({e}), e.g. {PIPE_EXAMPLE}"),
        )
    })
}
