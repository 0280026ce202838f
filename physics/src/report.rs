//! The report of a run: the plant's metrics over its window, its stick-slip statistics, its
//! resolved parameters and, when the run followed one, its task; one report whichever route ran
//! it (simulate, closed loop, sweep, co-simulation, FMU, Python).

use crawler_facts::{Metric, MetricValues};
use serde::{Deserialize, Serialize};

use crate::events::Episode;
use crate::metrics::Metrics;
use crate::plant::{Drive, Plant};
use crate::task::{TaskReport, TaskTracker};

/// Why a run has no report.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReportError {
    /// The run ended before a whole forcing period followed the transient.
    #[error(
        "no whole forcing period after the transient: t_end = {t_end} s, settle = {settle} s, period = {period:.4} s; \
         increase --t-end (the first whole period counted from t = 0 that starts after settle must end, and one internal step more)"
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

/// Resolved parameters, SI units. The wave fields describe the actuation in force at the end
/// of the run (null under a general muscle-force field).
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
    pub f0: Option<f64>,
    /// Wave number k, rad/m.
    pub k: Option<f64>,
    /// Angular frequency omega, rad/s.
    pub omega: Option<f64>,
    /// omega / omega_n.
    pub alpha: Option<f64>,
    /// Phase, rad.
    pub phase: Option<f64>,
    /// Natural frequency omega_n = k c, rad/s.
    pub omega_n: Option<f64>,
    /// Paper's zeta = c_v / (k sqrt(rho A_c E)).
    pub zeta: Option<f64>,
    /// Paper's pi_r = c_d / (f0 k) (null when f0 = 0).
    pub pi_r: Option<f64>,
    /// Wave speed c, m/s.
    pub wave_speed: f64,
    /// Communication step H actually used (a whole number of internal steps), s.
    pub step: f64,
    /// Achieved Courant number `c dt / dx`.
    pub courant: f64,
    /// Cell size dx, m.
    pub dx: f64,
    /// Cells per wavelength of the applied wave (null under a field).
    pub cells_per_wavelength: Option<f64>,
    /// `"periodic"` or `"free"`.
    pub boundary: &'static str,
    /// Grid filter strength per step.
    pub filter: f64,
    /// True if the pipe's friction varies along it.
    pub friction_map: bool,
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
    /// CRC-32 of the final displacement and velocity bits: equal digests, identical trajectories.
    pub state_digest: String,
    /// The resolved parameters.
    pub parameters: ResolvedParameters,
    /// How the run did against the scenario's task (null when no task was followed).
    pub task: Option<TaskReport>,
}

/// The averaging window of a report.
#[derive(Debug, Clone, Serialize)]
pub struct Window {
    /// Start, s.
    pub start: f64,
    /// End, s.
    pub end: f64,
    /// Forcing periods (averaging blocks) in it.
    pub periods: f64,
    /// True for a steady window: whole periods at least `numerics.settle` after the last change
    /// of actuation. False when the actuation changed later than that (a time-varying
    /// controller): the window is then every step after the run's first `settle` seconds, and
    /// the metrics are run averages, not a steady state.
    pub steady: bool,
    /// True when the run ended before its transient did (a task reached early): the metrics are
    /// averages over the whole run, transient included.
    pub whole_run: bool,
}

impl Report {
    /// The value of `metric` over the report's window.
    pub fn value(&self, metric: Metric) -> f64 {
        match metric {
            Metric::Velocity => self.velocity,
            Metric::Power => self.power,
            Metric::Mileage => self.mileage,
            Metric::MaxStress => self.max_stress,
            Metric::MaxStrain => self.max_strain,
            Metric::StuckFraction => self.stuck_fraction,
            Metric::MeanFrictionSelection => self.mean_friction_selection,
            Metric::EpisodesPerNodePerPeriod => self.events.per_node_per_period,
        }
    }

    /// Every metric of the table over the report's window (`None` where not finite).
    pub fn values(&self) -> MetricValues {
        MetricValues::from_fn(|m| Some(self.value(m)))
    }
}

impl ResolvedParameters {
    /// The parameters of `plant`, with the wave it is driven by, if any.
    pub fn of(plant: &Plant) -> Self {
        let p = plant.params();
        let c = p.body.wave_speed();
        let wave = match plant.drive() {
            Drive::Wave(w) => Some(w),
            _ => None,
        };
        let omega_n = wave.map(|w| w.k * c);
        Self {
            area: p.body.area,
            density: p.body.density,
            youngs_modulus: p.body.youngs_modulus,
            viscous: p.friction.viscous,
            dry: p.friction.dry,
            eps: p.friction.eps,
            n_f: p.friction.n_f,
            length: p.length,
            f0: wave.map(|w| w.f0),
            k: wave.map(|w| w.k),
            omega: wave.map(|w| w.omega),
            alpha: wave.map(|w| w.omega / (w.k * c)),
            phase: wave.map(|w| w.phase),
            omega_n,
            zeta: wave
                .map(|w| p.friction.viscous / (w.k * (p.body.density * p.body.stiffness()).sqrt())),
            pi_r: wave
                .filter(|w| w.f0 > 0.0)
                .map(|w| p.friction.dry / (w.f0 * w.k)),
            wave_speed: c,
            step: plant.step_length(),
            courant: plant.discretisation().courant,
            dx: plant.discretisation().dx,
            cells_per_wavelength: wave.map(|w| w.wavelength() / plant.discretisation().dx),
            boundary: p.boundary.as_str(),
            filter: p.numerics.filter,
            friction_map: !p.pipe.is_uniform(),
            settle: p.numerics.settle,
        }
    }
}

/// The stick-slip episodes of the steady window, kept for the report (bounded).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct EpisodeLog {
    /// Largest number kept.
    pub max: usize,
    /// Kept episodes, in order of their end.
    pub episodes: Vec<Episode>,
    /// True if some were not kept.
    pub truncated: bool,
}

impl EpisodeLog {
    /// An empty log keeping at most `max` episodes.
    pub fn new(max: usize) -> Self {
        Self {
            max,
            episodes: Vec::new(),
            truncated: false,
        }
    }

    /// Takes the episodes that ended in the plant's last communication step, after the transient.
    pub fn observe(&mut self, plant: &Plant) {
        // The run's transient, not the steady window's: a report falls back to the run window
        // when the actuation changed late.
        let settled = plant.metrics_tracker().run_settle_until;
        for ep in plant.episodes() {
            if ep.end >= settled {
                if self.episodes.len() < self.max {
                    self.episodes.push(*ep);
                } else {
                    self.truncated = true;
                }
            }
        }
    }
}

/// CRC-32 (hex) of the bits of the displacement and velocity fields and the step count: equal
/// digests mean bit-identical states.
pub fn state_digest(plant: &Plant) -> String {
    let mut h = crc32fast::Hasher::new();
    h.update(&plant.internal_steps().to_le_bytes());
    for x in plant.displacement().iter().chain(plant.velocity()) {
        h.update(&x.to_bits().to_le_bytes());
    }
    format!("{:08x}", h.finalize())
}

/// The report of a finished run of `plant` (scenario `name`), with the episodes of `log`.
pub fn report(name: &str, plant: &Plant, log: &EpisodeLog) -> Result<Report, ReportError> {
    report_with_task(name, plant, log, None)
}

/// [`report`] with the run's task progress (a task-mode run may end before its transient does:
/// its metrics are then averages over the whole run).
pub fn report_with_task(
    name: &str,
    plant: &Plant,
    log: &EpisodeLog,
    task: Option<&TaskTracker>,
) -> Result<Report, ReportError> {
    let p = plant.params();
    let ended_early = task.is_some_and(|t| t.task.end_run && t.decided().is_some());
    let (m, steady, whole_run): (Metrics, bool, bool) =
        match (plant.steady_metrics(), plant.run_metrics()) {
            (Some(m), _) => (m, true, false),
            (None, Some(m)) => (m, false, false),
            (None, None) => match plant.whole_run_metrics().filter(|_| ended_early) {
                Some(m) => (m, false, true),
                None => {
                    return Err(ReportError::NoSteadyWindow {
                        t_end: plant.time(),
                        settle: p.numerics.settle,
                        period: plant.block_length(),
                    })
                }
            },
        };
    let mut episodes = log.episodes.clone();
    episodes.retain(|e| e.end >= m.start && e.end < m.end);
    let d = *plant.discretisation();
    let f = p.friction;
    Ok(Report {
        scenario: name.to_string(),
        velocity: m.velocity,
        power: m.power,
        mileage: m.mileage,
        max_stress: m.max_stress,
        max_strain: m.max_strain,
        stuck_fraction: m.stuck_fraction,
        mean_friction_selection: m.mean_friction_selection,
        dissipation: m.dissipation,
        identity_velocity: -m.mean_friction_force / f.viscous,
        momentum_residual: m.momentum_residual(p.body.density, f.viscous),
        events: EventsReport {
            count: m.episodes,
            per_node_per_period: m.episodes_per_node_per_period,
            mean_duration: m.mean_stick_duration,
            min_duration: plant.min_stick(),
            episodes,
            episodes_truncated: log.truncated,
        },
        window: Window {
            start: m.start,
            end: m.end,
            periods: m.periods,
            steady,
            whole_run,
        },
        cells: p.numerics.cells,
        dt: d.dt,
        steps: plant.internal_steps(),
        macro_steps: plant.macro_step(),
        t_end: plant.time(),
        state_digest: state_digest(plant),
        parameters: ResolvedParameters::of(plant),
        task: task.map(TaskTracker::report),
    })
}

/// The body's mean displacement (its centre of mass), m.
pub fn mean_position(plant: &Plant) -> f64 {
    plant.displacement().iter().sum::<f64>() / plant.cells() as f64
}

impl Report {
    /// A human-readable summary (several lines).
    pub fn summary(&self) -> String {
        let p = &self.parameters;
        let opt =
            |x: Option<f64>, prec: usize| x.map_or("-".to_string(), |v| format!("{v:.prec$}"));
        let mut out = String::new();
        out += &format!(
            "scenario {}: eps = {}, n_F = {}, f0 = {} N, k = {} rad/m, omega = {} rad/s (alpha = {})\n",
            self.scenario,
            p.eps,
            p.n_f,
            opt(p.f0, 4),
            opt(p.k, 4),
            opt(p.omega, 3),
            opt(p.alpha, 3)
        );
        out += &format!(
            "grid: {} cells ({}, {} body of {} m), dx = {:.3e} m, dt = {:.3e} s at Courant number {:.6}, communication step H = {:.6e} s\n",
            self.cells,
            p.cells_per_wavelength
                .map_or("field actuation".to_string(), |c| format!("{c:.1} per wavelength")),
            p.boundary,
            p.length,
            p.dx,
            self.dt,
            p.courant,
            p.step,
        );
        out += &format!(
            "run: {} internal steps{} to t = {:.6} s; {} window {:.3}-{:.3} s ({:.1} periods)\n",
            self.steps,
            communication_steps(self.steps, self.dt, p.step)
                .map_or(String::new(), |n| format!(" = {n} communication steps")),
            self.t_end,
            if self.window.steady {
                "steady"
            } else if self.window.whole_run {
                "whole-run (the task ended the run before its transient settled)"
            } else {
                "run-average (the actuation changed within the last settle time, so no steady state)"
            },
            self.window.start,
            self.window.end,
            self.window.periods
        );
        out += &format!("  velocity V        {:+.6e} m/s\n", self.velocity);
        out += &format!("  power P           {:.6e} W\n", self.power);
        out += &if self.mileage.is_finite() {
            format!("  mileage M         {:.6e} m/J\n", self.mileage)
        } else {
            "  mileage M         undefined (no power put in: M = V / P)\n".to_string()
        };
        out += &format!("  max stress        {:.6e} Pa\n", self.max_stress);
        out += &format!("  max strain        {:.6e}\n", self.max_strain);
        out += &format!("  stuck fraction    {:.4}\n", self.stuck_fraction);
        out += &format!("  <s>               {:+.6}\n", self.mean_friction_selection);
        out += &format!(
            "  stick episodes    {} in the window ({:.3} per node per period, mean {:.3e} s)\n",
            self.events.count, self.events.per_node_per_period, self.events.mean_duration
        );
        out += &format!("  state digest      {}", self.state_digest);
        if let Some(t) = &self.task {
            out += &format!("\n{}", t.summary());
        }
        out
    }
}

/// The communication steps that `steps` internal steps of `dt` make, when they make a whole
/// number of communication steps of `h` (a report counts both; the summary names both).
fn communication_steps(steps: u64, dt: f64, h: f64) -> Option<u64> {
    let per = (h / dt).round();
    if !(1.0..=u64::MAX as f64).contains(&per) {
        return None;
    }
    let per = per as u64;
    steps.is_multiple_of(per).then_some(steps / per)
}
