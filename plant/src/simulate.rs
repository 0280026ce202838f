//! `crawler-plant simulate`: the plant under a fixed travelling wave, in process.

use serde::Serialize;

use crate::events::Episode;
use crate::metrics::Metrics;
use crate::scenario::Scenario;
use crate::slave::{Slave, SlaveError, StepStatus};

/// Options of an in-process run.
#[derive(Debug, Clone, Copy)]
pub struct SimulateOptions {
    /// Largest number of episodes listed in the report (all are counted).
    pub max_episodes: usize,
    /// Show a progress bar on stderr (hidden anyway when stderr is not a terminal).
    pub progress: bool,
}

impl Default for SimulateOptions {
    fn default() -> Self {
        Self {
            max_episodes: 10_000,
            progress: false,
        }
    }
}

/// Why a simulation failed.
#[derive(Debug, thiserror::Error)]
pub enum SimulateError {
    /// The slave refused a call.
    #[error(transparent)]
    Slave(#[from] SlaveError),
    /// A step was discarded.
    #[error("step discarded at t = {time} s: {reason}")]
    Discarded {
        /// Time of the last good state, s.
        time: f64,
        /// Why.
        reason: String,
    },
    /// The run ended before a whole forcing period followed the transient.
    #[error(
        "no whole forcing period after the transient: t_end = {t_end} s, settle = {settle} s, period = {period:.4} s; \
         increase --t-end (at least settle + one period)"
    )]
    NoSteadyWindow {
        /// End time, s.
        t_end: f64,
        /// Settle time, s.
        settle: f64,
        /// Forcing period, s.
        period: f64,
    },
}

/// Stick-slip statistics of the steady window.
#[derive(Debug, Clone, Serialize)]
pub struct EventsReport {
    /// Episodes that ended in the steady window.
    pub count: u64,
    /// Episodes per node per forcing period.
    pub per_node_per_period: f64,
    /// Mean episode duration, s.
    pub mean_duration: f64,
    /// Shortest stick phase counted, s.
    pub min_duration: f64,
    /// The episodes (at most `max_episodes`, in order of their end).
    pub episodes: Vec<Episode>,
    /// True if the list was cut at `max_episodes`.
    pub episodes_truncated: bool,
}

/// Resolved parameters, SI units.
#[derive(Debug, Clone, Serialize)]
pub struct ResolvedParameters {
    /// Cross-section A_c, m^2.
    pub area: f64,
    /// Linear density rho, kg/m.
    pub density: f64,
    /// Young's modulus E, Pa.
    pub youngs_modulus: f64,
    /// Viscous coefficient c_v, N s/m^2.
    pub viscous: f64,
    /// Normal load c_d, N/m.
    pub dry: f64,
    /// Dry friction coefficient eps.
    pub eps: f64,
    /// Asymmetry n_F.
    pub n_f: f64,
    /// Body length L, m.
    pub length: f64,
    /// Wave amplitude f0, N.
    pub f0: f64,
    /// Wave number k, rad/m.
    pub k: f64,
    /// Angular frequency omega, rad/s.
    pub omega: f64,
    /// omega / omega_n.
    pub alpha: f64,
    /// Phase, rad.
    pub phase: f64,
    /// Natural frequency omega_n = k c, rad/s.
    pub omega_n: f64,
    /// Wave speed c, m/s.
    pub wave_speed: f64,
    /// Paper's zeta = c_v / (k sqrt(rho A_c E)).
    pub zeta: f64,
    /// Paper's pi_r = c_d / (f0 k).
    pub pi_r: f64,
    /// Communication step H, s.
    pub step: f64,
    /// Achieved Courant number.
    pub courant: f64,
    /// Transient skipped, s.
    pub settle: f64,
}

/// The report of `simulate --json`.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// Scenario name.
    pub scenario: String,
    /// Steady mean speed V, m/s.
    pub velocity: f64,
    /// Steady input power P over the body, W.
    pub power: f64,
    /// Mileage |V|/P, m/J.
    pub mileage: f64,
    /// sup T / A_c over the window, Pa.
    pub max_stress: f64,
    /// max |u_x| over the window.
    pub max_strain: f64,
    /// Share of node-time stuck.
    pub stuck_fraction: f64,
    /// <s>, stuck points included.
    pub mean_friction_selection: f64,
    /// Dissipated power, W (equals `power` in a steady state).
    pub dissipation: f64,
    /// V predicted by the identity `eps c_d (n_F - <s>) / c_v`, m/s.
    pub identity_velocity: f64,
    /// Relative residual of the scheme's exact discrete momentum balance over the window (the
    /// discrete analogue of the identity, including `rho dV / T_w`); round-off level.
    pub momentum_residual: f64,
    /// Stick-slip events.
    pub events: EventsReport,
    /// The averaging window.
    pub window: Window,
    /// Number of cells.
    pub cells: usize,
    /// Internal step, s.
    pub dt: f64,
    /// Internal steps taken.
    pub steps: u64,
    /// Communication steps taken.
    pub macro_steps: u64,
    /// End time, s.
    pub t_end: f64,
    /// The resolved parameters.
    pub parameters: ResolvedParameters,
}

/// The steady averaging window.
#[derive(Debug, Clone, Serialize)]
pub struct Window {
    /// Start, s.
    pub start: f64,
    /// End, s.
    pub end: f64,
    /// Whole forcing periods in it.
    pub periods: f64,
}

impl ResolvedParameters {
    /// The parameters of a scenario.
    pub fn of(s: &Scenario, courant: f64) -> Self {
        let p = &s.plant;
        let omega_n = s.natural_frequency();
        Self {
            area: p.body.area,
            density: p.body.density,
            youngs_modulus: p.body.youngs_modulus,
            viscous: p.friction.viscous,
            dry: p.friction.dry,
            eps: p.friction.eps,
            n_f: p.friction.n_f,
            length: p.length,
            f0: s.wave.f0,
            k: s.wave.k,
            omega: s.wave.omega,
            alpha: s.wave.omega / omega_n,
            phase: s.wave.phase,
            omega_n,
            wave_speed: p.body.wave_speed(),
            zeta: p.friction.viscous / (s.wave.k * (p.body.density * p.body.stiffness()).sqrt()),
            pi_r: p.friction.dry / (s.wave.f0 * s.wave.k),
            step: p.numerics.step,
            courant,
            settle: p.numerics.settle,
        }
    }
}

/// Runs the scenario's plant under its wave from t = 0 to `t_end` (rounded to whole steps).
pub fn simulate(scenario: &Scenario, opts: SimulateOptions) -> Result<Report, SimulateError> {
    let mut slave = Slave::instantiate("simulate", scenario.plant)?;
    slave.enter_initialization_mode(0.0, None)?;
    slave.set_wave(scenario.wave)?;
    slave.exit_initialization_mode()?;
    let h = scenario.plant.numerics.step;
    let steps = (scenario.t_end / h).round().max(1.0) as u64;
    let bar = opts.progress.then(|| progress_bar(steps));
    let mut episodes: Vec<Episode> = Vec::new();
    let mut truncated = false;
    for n in 0..steps {
        let t = n as f64 * h;
        match slave.do_step(t, h) {
            StepStatus::Ok => {}
            StepStatus::Discard {
                last_successful_time,
                reason,
            } => {
                return Err(SimulateError::Discarded {
                    time: last_successful_time,
                    reason,
                })
            }
            StepStatus::Error(e) => return Err(e.into()),
        }
        let plant = slave.plant();
        let settled = plant.metrics_tracker().settle_until;
        for ep in plant.episodes() {
            if ep.end >= settled {
                if episodes.len() < opts.max_episodes {
                    episodes.push(*ep);
                } else {
                    truncated = true;
                }
            }
        }
        if let Some(b) = &bar {
            if n % 256 == 0 {
                b.set_position(n);
            }
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let plant = slave.plant();
    let m: Metrics = plant
        .steady_metrics()
        .ok_or(SimulateError::NoSteadyWindow {
            t_end: scenario.t_end,
            settle: scenario.plant.numerics.settle,
            period: scenario.wave.period(),
        })?;
    episodes.retain(|e| e.end >= m.start && e.end < m.end);
    let d = *plant.discretisation();
    let f = scenario.plant.friction;
    Ok(Report {
        scenario: scenario.name.clone(),
        velocity: m.velocity,
        power: m.power,
        mileage: m.mileage,
        max_stress: m.max_stress,
        max_strain: m.max_strain,
        stuck_fraction: m.stuck_fraction,
        mean_friction_selection: m.mean_friction_selection,
        dissipation: m.dissipation,
        identity_velocity: f.band() * (f.n_f - m.mean_friction_selection) / f.viscous,
        momentum_residual: m.momentum_residual(scenario.plant.body.density, &f),
        events: EventsReport {
            count: m.episodes,
            per_node_per_period: m.episodes_per_node_per_period,
            mean_duration: m.mean_stick_duration,
            min_duration: scenario.plant.numerics.min_stick,
            episodes,
            episodes_truncated: truncated,
        },
        window: Window {
            start: m.start,
            end: m.end,
            periods: m.periods,
        },
        cells: scenario.plant.numerics.cells,
        dt: d.dt,
        steps: plant.internal_steps(),
        macro_steps: plant.macro_step(),
        t_end: plant.time(),
        parameters: ResolvedParameters::of(scenario, d.courant),
    })
}

fn progress_bar(total: u64) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::with_draw_target(
        Some(total),
        indicatif::ProgressDrawTarget::stderr(),
    );
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} simulating [{bar:40}] {pos}/{len} steps ({eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar
}
