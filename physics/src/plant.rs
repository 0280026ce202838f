//! The plant: solver + actuation + metrics + events, advanced one communication step at a time.

use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::events::{Episode, EventTracker};
use crate::metrics::{BlockReport, Metrics, MetricsTracker, Sums};
use crate::params::{Discretisation, PlantParams};
use crate::solver::{Solver, StepSums};
use crate::wave::Wave;

/// What drives the muscles.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Drive {
    /// No actuation yet: zero muscle force.
    Idle,
    /// A travelling wave, evaluated continuously inside each step.
    Wave(Wave),
    /// A general muscle-force field on the half nodes, held over each step.
    Field,
}

/// Outputs of the last communication step.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct StepOutputs {
    /// Mean speed of the body over the step, `(mean u(t+H) - mean u(t)) / H`, m/s.
    pub mean_speed: f64,
    /// Mean input power of the actuator over the step, W.
    pub input_power: f64,
    /// Nodes stuck at the end of the step.
    pub stuck_nodes: u64,
    /// Largest engineering stress `sup T / A_c` over the step, Pa.
    pub max_stress: f64,
    /// Time within the step during which the stress exceeded the stress limit, s (0 without one,
    /// see [`Plant::set_stress_limit`]).
    pub time_over_stress: f64,
}

/// Why a step was not taken.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StepError {
    /// The state became non-finite; the plant was rolled back to the start of the step.
    #[error(
        "state became non-finite at t = {time} s; rolled back to t = {last_successful_time} s"
    )]
    NonFinite {
        /// Time at which it happened, s.
        time: f64,
        /// Time of the restored state, s.
        last_successful_time: f64,
    },
}

/// The complete dynamic state of a plant: restoring it continues a run bit-identically.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlantState {
    /// Parameters the state belongs to.
    pub params: PlantParams,
    /// Start time of the run, s.
    pub t0: f64,
    /// Internal steps taken.
    pub step: u64,
    /// Communication steps taken.
    pub macro_step: u64,
    /// Displacement at nodes, m.
    pub u: Vec<f64>,
    /// Velocity at nodes over the last internal step, m/s.
    pub v: Vec<f64>,
    /// Stick flags of the last internal step.
    pub stuck: Vec<bool>,
    /// Muscle-force field at half nodes, N.
    pub field: Vec<f64>,
    /// Current actuation.
    pub drive: Drive,
    /// Metric accumulators.
    pub metrics: MetricsTracker,
    /// Stick-phase tracking.
    pub events: EventTracker,
    /// Outputs of the last step.
    pub outputs: StepOutputs,
    /// Actuator work of a muscle-force jump not yet reported in a step's input power, J.
    pub pending_work: f64,
    /// Σ v over the nodes as the kernel summed it in the last step, m/s.
    pub velocity_sum: f64,
    /// Stress above which a step's time counts as a violation, Pa (`None`: not counted).
    #[serde(default)]
    pub stress_limit: Option<f64>,
}

/// The dynamic state at the start of a step, restored if the step fails (buffers are reused).
#[derive(Debug, Clone)]
struct Backup {
    u: Vec<f64>,
    v: Vec<f64>,
    stuck: Vec<bool>,
    metrics: MetricsTracker,
    events: EventTracker,
    step: u64,
    velocity_sum: f64,
}

/// A finite-difference crawler, stepped in communication steps of `H` seconds
/// ([`Discretisation::step`], a whole number of internal steps).
#[derive(Debug, Clone)]
pub struct Plant {
    params: PlantParams,
    disc: Discretisation,
    solver: Solver,
    drive: Drive,
    t0: f64,
    step: u64,
    macro_step: u64,
    metrics: MetricsTracker,
    events: EventTracker,
    outputs: StepOutputs,
    episodes: Vec<Episode>,
    backup: Backup,
    pending_work: f64,
    /// Tension above which a step counts as a stress violation, N (`+inf`: none).
    tension_limit: f64,
}

impl Plant {
    /// A body at rest at time `t0` (s), without actuation.
    pub fn new(params: PlantParams, t0: f64) -> Result<Self, ParamError> {
        params.validate()?;
        crate::error::finite("start_time", t0)?;
        let disc = params.discretisation()?;
        let solver = Solver::new(&params, &disc);
        let n = params.numerics.cells;
        let numerics = params.numerics;
        Ok(Self {
            params,
            disc,
            solver,
            drive: Drive::Idle,
            t0,
            step: 0,
            macro_step: 0,
            metrics: MetricsTracker::new(t0, numerics.block, numerics.settle),
            events: EventTracker::new(n, numerics.min_stick_periods * numerics.block),
            outputs: StepOutputs::default(),
            episodes: Vec::new(),
            backup: Backup {
                u: Vec::new(),
                v: Vec::new(),
                stuck: Vec::new(),
                metrics: MetricsTracker::new(t0, numerics.block, numerics.settle),
                events: EventTracker::new(0, 0.0),
                step: 0,
                velocity_sum: 0.0,
            },
            pending_work: 0.0,
            tension_limit: f64::INFINITY,
        })
    }

    /// Counts, from now on, the time during which the stress exceeds `sigma_max` Pa (the task's
    /// limit); `None` stops counting. See [`StepOutputs::time_over_stress`].
    pub fn set_stress_limit(&mut self, sigma_max: Option<f64>) -> Result<(), ParamError> {
        self.tension_limit = match sigma_max {
            Some(s) => crate::error::positive("task.sigma_max", s)? * self.params.body.area,
            None => f64::INFINITY,
        };
        Ok(())
    }

    /// The stress limit being counted against, Pa.
    pub fn stress_limit(&self) -> Option<f64> {
        self.tension_limit
            .is_finite()
            .then(|| self.tension_limit / self.params.body.area)
    }

    /// Metrics of everything simulated so far (from the run's start, the open block included):
    /// the fallback of a run that ended before any window closed. `None` before the first step.
    pub fn whole_run_metrics(&self) -> Option<Metrics> {
        let mut all = self.metrics.all;
        all.merge(&self.metrics.block);
        self.metrics_of(&all)
    }

    /// The parameters.
    pub fn params(&self) -> &PlantParams {
        &self.params
    }

    /// Grid spacing and time step.
    pub fn discretisation(&self) -> &Discretisation {
        &self.disc
    }

    /// Number of nodes.
    pub fn cells(&self) -> usize {
        self.params.numerics.cells
    }

    /// Communication steps taken.
    pub fn macro_step(&self) -> u64 {
        self.macro_step
    }

    /// Internal steps taken.
    pub fn internal_steps(&self) -> u64 {
        self.step
    }

    /// Current time `t0 + n H`, s, computed from the integer step count.
    pub fn time(&self) -> f64 {
        self.t0 + self.macro_step as f64 * self.disc.step
    }

    /// The communication step `H` actually used (a whole number of internal steps), s.
    pub fn step_length(&self) -> f64 {
        self.disc.step
    }

    /// `(eps, n_F)` each node feels at its current position in the pipe.
    pub fn node_friction(&self) -> Vec<(f64, f64)> {
        self.solver.node_friction()
    }

    /// Start time, s.
    pub fn start_time(&self) -> f64 {
        self.t0
    }

    /// Current actuation.
    pub fn drive(&self) -> Drive {
        self.drive
    }

    /// Displacement at nodes `x_i = i dx`, m.
    pub fn displacement(&self) -> &[f64] {
        &self.solver.u
    }

    /// Velocity at nodes over the last internal step, m/s.
    pub fn velocity(&self) -> &[f64] {
        &self.solver.v
    }

    /// Stick flags of the last internal step.
    pub fn stuck(&self) -> &[bool] {
        self.solver.stuck()
    }

    /// Muscle-force field at half nodes (general actuation), N.
    pub fn field(&self) -> &[f64] {
        &self.solver.field
    }

    /// Outputs of the last communication step.
    pub fn outputs(&self) -> StepOutputs {
        self.outputs
    }

    /// Episodes that ended during the last communication step.
    pub fn episodes(&self) -> &[Episode] {
        &self.episodes
    }

    /// Metric blocks (forcing periods) that closed during the last communication step.
    pub fn closed_blocks(&self) -> &[BlockReport] {
        &self.metrics.closed
    }

    /// The metric tracker (current block and steady window).
    pub fn metrics_tracker(&self) -> &MetricsTracker {
        &self.metrics
    }

    /// Shortest stick phase counted as an episode under the current actuation, s.
    pub fn min_stick(&self) -> f64 {
        self.events.min_stick
    }

    /// Length of the averaging block (forcing period for a wave), s.
    pub fn block_length(&self) -> f64 {
        self.metrics.block_len
    }

    /// Metrics of every step after the run's initial transient (`numerics.settle` after the
    /// start), whatever the actuation did: averages over a time-varying actuation, not a steady
    /// state. `None` before the first block after the transient closes.
    pub fn run_metrics(&self) -> Option<Metrics> {
        self.metrics_of(&self.metrics.run)
    }

    fn metrics_of(&self, s: &Sums) -> Option<Metrics> {
        (s.steps > 0).then(|| {
            s.metrics(
                self.cells(),
                self.disc.dt,
                self.params.body.area,
                self.metrics.block_len,
            )
        })
    }

    /// Metrics of the steady window: whole forcing periods (blocks) that started at least
    /// `numerics.settle` after the last change of actuation; `None` before the first one closes.
    pub fn steady_metrics(&self) -> Option<Metrics> {
        self.metrics_of(&self.metrics.steady)
    }

    /// Muscle coefficients `(a, b)` of the sine/cosine tables at internal time `t`, and `omega`.
    fn wave_coefficients(&self, t: f64) -> (f64, f64, f64) {
        match self.drive {
            Drive::Wave(w) => {
                let (s, c) = (w.omega * t - w.phase).sin_cos();
                (w.f0 * c, -w.f0 * s, w.omega)
            }
            _ => (0.0, 0.0, 0.0),
        }
    }

    /// Internal time of step `j`, s.
    fn internal_time(&self, j: u64) -> f64 {
        self.t0 + j as f64 * self.disc.dt
    }

    /// Tension at half nodes at the current time, N.
    pub fn tension(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.cells());
        self.tension_into(&mut out);
        out
    }

    /// [`Plant::tension`] into `out` (cleared first), reusing its memory.
    pub fn tension_into(&self, out: &mut Vec<f64>) {
        let (a, b, _) = self.wave_coefficients(self.internal_time(self.step));
        self.solver.tension_into(a, b, out);
    }

    /// Muscle force at half nodes at the current time, N.
    pub fn muscle_force(&self) -> Vec<f64> {
        let (a, b, _) = self.wave_coefficients(self.internal_time(self.step));
        (0..self.cells())
            .map(|i| self.solver.muscle(i, a, b))
            .collect()
    }

    /// Drives the body with a travelling wave from now on. Its wavelength must fit the body.
    pub fn set_wave(&mut self, wave: Wave) -> Result<(), ParamError> {
        wave.validate_for_body(self.params.length, self.cells(), self.params.boundary)?;
        if self.drive == Drive::Wave(wave) {
            return Ok(());
        }
        let before = self.muscle_force();
        self.solver.field.iter_mut().for_each(|g| *g = 0.0);
        self.solver.set_field_active(false);
        self.solver.set_wave_number(wave.k, self.disc.dx);
        self.drive = Drive::Wave(wave);
        self.account_jump(&before);
        let now = self.internal_time(self.step);
        self.metrics
            .restart(now, wave.period(), self.params.numerics.settle);
        self.events.min_stick = self.params.numerics.min_stick_periods * wave.period();
        Ok(())
    }

    /// Drives the body with a muscle-force field (N, one value per half node `x_{i+1/2}`),
    /// held until the next call.
    pub fn set_field(&mut self, field: &[f64]) -> Result<(), ParamError> {
        if field.len() != self.cells() {
            return Err(ParamError::new(
                "muscle_force",
                format!("{} values", field.len()),
                format!("exactly {} values (one per cell)", self.cells()),
            ));
        }
        if let Some((i, x)) = field.iter().enumerate().find(|(_, x)| !x.is_finite()) {
            return Err(ParamError::new(
                format!("muscle_force[{i}]"),
                x,
                "finite numbers (N)",
            ));
        }
        let before = self.muscle_force();
        let was_field = self.drive == Drive::Field;
        self.drive = Drive::Field;
        self.solver.field.copy_from_slice(field);
        self.solver.set_field_active(true);
        self.account_jump(&before);
        if !was_field {
            let now = self.internal_time(self.step);
            self.metrics
                .restart(now, self.params.numerics.block, self.params.numerics.settle);
            self.events.min_stick =
                self.params.numerics.min_stick_periods * self.params.numerics.block;
        }
        Ok(())
    }

    /// Adds the work of a sudden change of muscle force, `sum dx (u_x + (m_old + m_new) / 2 A_c E) dm`.
    fn account_jump(&mut self, before: &[f64]) {
        let after = self.muscle_force();
        let ae = self.params.body.stiffness();
        let work: f64 = (0..self.cells())
            .map(|i| {
                (self.solver.strain(i) + 0.5 * (before[i] + after[i]) / ae) * (after[i] - before[i])
            })
            .sum::<f64>()
            * self.disc.dx;
        self.metrics.add_energy(work);
        self.pending_work += work;
    }

    fn save_backup(&mut self) {
        let b = &mut self.backup;
        b.u.clear();
        b.u.extend_from_slice(&self.solver.u);
        b.v.clear();
        b.v.extend_from_slice(&self.solver.v);
        b.stuck.clear();
        b.stuck.extend_from_slice(self.solver.stuck());
        b.metrics.clone_from(&self.metrics);
        b.events.clone_from(&self.events);
        b.step = self.step;
        b.velocity_sum = self.solver.velocity_sum();
    }

    fn restore_backup(&mut self) {
        let b = &self.backup;
        self.solver.u.copy_from_slice(&b.u);
        self.solver.v.copy_from_slice(&b.v);
        self.solver.set_stuck(&b.stuck);
        self.metrics.clone_from(&b.metrics);
        self.events.clone_from(&b.events);
        self.step = b.step;
        self.solver.set_velocity_sum(b.velocity_sum);
        self.solver.refresh_friction();
        self.episodes.clear();
    }

    /// Advances one communication step `H` ([`Self::step_length`]).
    pub fn advance(&mut self) -> Result<StepOutputs, StepError> {
        self.metrics.closed.clear();
        self.episodes.clear();
        self.save_backup();

        let dt = self.disc.dt;
        let dx = self.disc.dx;
        let ae = self.params.body.stiffness();
        let mut energy = 0.0;
        let mut sum_v = 0.0;
        let mut stuck = 0.0;
        let mut max_tension = f64::NEG_INFINITY;
        let mut steps_over = 0u64;
        for _ in 0..self.disc.substeps {
            let t = self.internal_time(self.step);
            let (a, b, omega) = self.wave_coefficients(t);
            let sums: StepSums = self.solver.step(a, b);
            if !(sums.sum_v.is_finite()
                && sums.max_tension.is_finite()
                && sums.dissipation.is_finite())
            {
                let last = self.time();
                self.restore_backup();
                return Err(StepError::NonFinite {
                    time: t,
                    last_successful_time: last,
                });
            }
            // Input power: sum_i dx T_i m_t,i / A_c E with m = f0 (S cos θ - C sin θ).
            let (sin_t, cos_t) = if omega != 0.0 { (-b, a) } else { (0.0, 0.0) };
            let power = -omega * dx / ae * (sin_t * sums.tension_sin + cos_t * sums.tension_cos);
            let e = power * dt;
            energy += e;
            sum_v += sums.sum_v;
            stuck = sums.stuck;
            max_tension = max_tension.max(sums.max_tension);
            if sums.max_tension > self.tension_limit {
                steps_over += 1;
            }
            let first_new = self.episodes.len();
            if !self.solver.transitions.is_empty() {
                let applied = self.events.apply(
                    self.step,
                    self.t0,
                    dt,
                    &self.solver.transitions,
                    &mut self.episodes,
                );
                // The half step taken off a stick phase belongs to its last stuck step, which is
                // in the block still open (the step below may close it).
                self.metrics.correct_stuck(applied.stuck_correction);
            }
            self.metrics
                .add_step(t, dt, &sums, e, sums.dissipation * dx * dt);
            for ep in &self.episodes[first_new..] {
                self.metrics.add_episode(ep.duration);
            }
            self.step += 1;
        }
        self.macro_step += 1;
        let h = self.disc.step;
        // Work of a jump of the muscle force applied just before this step.
        energy += std::mem::take(&mut self.pending_work);
        self.outputs = StepOutputs {
            mean_speed: sum_v / (self.cells() as f64 * self.disc.substeps as f64),
            input_power: energy / h,
            stuck_nodes: stuck as u64,
            max_stress: max_tension / self.params.body.area,
            time_over_stress: steps_over as f64 * dt,
        };
        Ok(self.outputs)
    }

    /// A copy of the complete dynamic state.
    pub fn state(&self) -> PlantState {
        PlantState {
            params: self.params.clone(),
            t0: self.t0,
            step: self.step,
            macro_step: self.macro_step,
            u: self.solver.u.to_vec(),
            v: self.solver.v.to_vec(),
            stuck: self.solver.stuck().to_vec(),
            field: self.solver.field.to_vec(),
            drive: self.drive,
            metrics: MetricsTracker {
                closed: Vec::new(),
                ..self.metrics.clone()
            },
            events: self.events.clone(),
            outputs: self.outputs,
            pending_work: self.pending_work,
            velocity_sum: self.solver.velocity_sum(),
            stress_limit: self.stress_limit(),
        }
    }

    /// Restores a state taken from a plant with the same parameters.
    pub fn set_state(&mut self, state: &PlantState) -> Result<(), ParamError> {
        if state.params != self.params {
            return Err(ParamError::new(
                "state.params",
                "parameters of another plant",
                "a state taken from a plant with identical parameters",
            ));
        }
        let n = self.cells();
        for (name, len) in [
            ("state.u", state.u.len()),
            ("state.v", state.v.len()),
            ("state.stuck", state.stuck.len()),
            ("state.field", state.field.len()),
        ] {
            if len != n {
                return Err(ParamError::new(
                    name,
                    format!("{len} values"),
                    format!("{n} values (one per cell)"),
                ));
            }
        }
        for (name, xs) in [
            ("state.u", &state.u),
            ("state.v", &state.v),
            ("state.field", &state.field),
        ] {
            if let Some((i, x)) = xs.iter().enumerate().find(|(_, x)| !x.is_finite()) {
                return Err(ParamError::new(format!("{name}[{i}]"), x, "finite numbers"));
            }
        }
        check_magnitudes(state, &self.params, self.disc.dx)?;
        crate::error::finite("state.t0", state.t0)?;
        crate::error::finite("state.pending_work", state.pending_work)?;
        crate::error::finite("state.velocity_sum", state.velocity_sum)?;
        crate::error::finite("state.outputs.mean_speed", state.outputs.mean_speed)?;
        crate::error::finite("state.outputs.input_power", state.outputs.input_power)?;
        crate::error::non_negative("state.outputs.max_stress", state.outputs.max_stress)?;
        crate::error::non_negative(
            "state.outputs.time_over_stress",
            state.outputs.time_over_stress,
        )?;
        if let Some(limit) = state.stress_limit {
            crate::error::positive("state.stress_limit", limit)?;
        }
        state.events.validate(n)?;
        state.metrics.validate()?;
        state.metrics.validate_steps(self.disc.dt, state.step)?;
        if state.step != state.macro_step.saturating_mul(self.disc.substeps) {
            return Err(ParamError::new(
                "state.step",
                state.step,
                format!(
                    "macro_step * substeps = {}",
                    state.macro_step.saturating_mul(self.disc.substeps)
                ),
            ));
        }
        if let Drive::Wave(w) = state.drive {
            w.validate_for_body(self.params.length, n, self.params.boundary)?;
            self.solver.set_wave_number(w.k, self.disc.dx);
        }
        self.t0 = state.t0;
        self.step = state.step;
        self.macro_step = state.macro_step;
        // (the lengths were checked above)
        self.solver.u.copy_from_slice(&state.u);
        self.solver.v.copy_from_slice(&state.v);
        self.solver.set_stuck(&state.stuck);
        self.solver.field.copy_from_slice(&state.field);
        self.solver
            .set_field_active(state.field.iter().any(|&g| g != 0.0));
        self.drive = state.drive;
        self.metrics = state.metrics.clone();
        self.events = state.events.clone();
        self.outputs = state.outputs;
        self.pending_work = state.pending_work;
        self.solver.set_velocity_sum(state.velocity_sum);
        self.solver.refresh_friction();
        self.episodes.clear();
        self.set_stress_limit(state.stress_limit)?;
        Ok(())
    }

    /// A plant restored from a state (parameters included).
    pub fn from_state(state: &PlantState) -> Result<Self, ParamError> {
        let mut plant = Self::new(state.params.clone(), state.t0)?;
        plant.set_state(state)?;
        Ok(plant)
    }
}

/// The state's numbers are finite, and so are the quantities a step works out from them: every
/// face's elastic tension `A_c E (u_{i+1} - u_i) / dx` (N), the sum of `|u|` (m) and of `v^2`
/// (m^2/s^2) over the nodes (a displacement of 1e308 m is finite, its tension is not).
fn check_magnitudes(state: &PlantState, params: &PlantParams, dx: f64) -> Result<(), ParamError> {
    let stiffness = params.body.area * params.body.youngs_modulus / dx;
    let n = state.u.len();
    let faces = match params.boundary {
        crate::params::Boundary::Periodic => n,
        crate::params::Boundary::Free => n - 1,
    };
    for i in 0..faces {
        let tension = stiffness * (state.u[(i + 1) % n] - state.u[i]);
        if !tension.is_finite() {
            return Err(ParamError::new(
                format!("state.u[{}]", (i + 1) % n),
                state.u[(i + 1) % n],
                format!(
                    "displacements whose differences give a finite tension (u[{i}] = {:e} m, A_c E / dx = {stiffness:e} N/m)",
                    state.u[i]
                ),
            ));
        }
    }
    for (name, total) in [
        ("state.u", state.u.iter().map(|x| x.abs()).sum::<f64>()),
        ("state.v", state.v.iter().map(|x| x * x).sum::<f64>()),
    ] {
        if !total.is_finite() {
            return Err(ParamError::new(
                name,
                "values too large to sum",
                "values whose sum (of |u|, of v^2) over the nodes is finite",
            ));
        }
    }
    Ok(())
}
