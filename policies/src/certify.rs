//! Certification of an open-loop wave on the task it is for: the plant the controller is told
//! (same body, grid and step), driven from rest by the wave in task mode until it has travelled
//! `D` or spent `J0`, must do so with every limit kept with a margin. The amplitude is lowered
//! until it does.
//!
//! What is certified is the task itself (start-up transient included), not a steady window of a
//! run of some length, so the verdict does not depend on the scenario's `t_end`. The run lasts
//! until the task is decided, or until a horizon of its own (the settling time plus twice the
//! predicted time to `D`, between [`MIN_HORIZON`] and [`MAX_HORIZON`]); a run still undecided
//! there is judged by the energy it would need at the mileage it showed.

use crawler_physics::execution::{Actuation, Observation};
use crawler_physics::params::Boundary;
use crawler_physics::scenario::Scenario;
use crawler_physics::wave::Wave;

use crate::policy::Policy;

/// Shortest certification run, s.
pub const MIN_HORIZON: f64 = 10.0;
/// Longest certification run, s.
pub const MAX_HORIZON: f64 = 600.0;

/// One certification run: the task from rest under one wave.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaskCheck {
    /// Amplitude, N.
    pub f0: f64,
    /// Energy the task took (`J0` times `D` over the distance travelled when the budget ran
    /// out, or the energy at the horizon scaled to `D`), J.
    pub energy: f64,
    /// Time to `D`, s (`None` if not reached).
    pub time_to_distance: Option<f64>,
    /// Largest stress over the run, Pa.
    pub stress: f64,
    /// Largest strain `|u_x|` over the run.
    pub strain: f64,
    /// The smallest relative margin of energy, stress, strain and amplitude (>= 0: all hold).
    pub margin: f64,
}

/// The result of a certification.
#[derive(Debug, Clone)]
pub struct TaskCertification {
    /// Relative margin required on every limit.
    pub margin: f64,
    /// The certified amplitude, N.
    pub f0: f64,
    /// Runs made, in order.
    pub runs: Vec<TaskCheck>,
    /// True if the task holds with the margin at `f0`.
    pub certified: bool,
    /// Horizon of the runs, s.
    pub horizon: f64,
}

impl TaskCertification {
    /// The run at the certified amplitude.
    pub fn certified_run(&self) -> Option<&TaskCheck> {
        self.runs.iter().rev().find(|r| r.f0 == self.f0)
    }
}

/// A fixed wave that keeps the largest strain it sees.
struct Watching {
    wave: Wave,
    dx: f64,
    boundary: Boundary,
    strain: f64,
}

impl Policy for Watching {
    fn name(&self) -> &str {
        "certification"
    }

    fn act(&mut self, obs: &Observation) -> Actuation {
        let u = obs.u;
        let n = u.len();
        for i in 0..n {
            let j = match (i + 1 < n, self.boundary) {
                (true, _) => i + 1,
                (false, Boundary::Periodic) => 0,
                (false, Boundary::Free) => break,
            };
            self.strain = self.strain.max((u[j] - u[i]).abs() / self.dx);
        }
        Actuation::Wave(self.wave)
    }
}

/// The task from rest on the plant of `scenario` under `wave`, until `D`, `J0` or `horizon` s.
pub fn check(scenario: &Scenario, wave: Wave, horizon: f64) -> anyhow::Result<TaskCheck> {
    let mut s = scenario.clone();
    s.wave = wave;
    s.t_end = horizon;
    s.task.end_run = true;
    let p = &s.plant;
    let mut watch = Watching {
        wave,
        dx: p.length / p.numerics.cells as f64,
        boundary: p.boundary,
        strain: 0.0,
    };
    let run = crate::in_process::run(&s, &mut watch)?;
    let t = run
        .report
        .task
        .ok_or_else(|| anyhow::anyhow!("the certification run has no task report"))?;
    let task = s.task;
    let energy = match (t.energy_at_distance, t.distance > 0.0) {
        (Some(e), _) => e,
        // spent, or still on its way at the horizon: the energy it would need at its mileage
        (None, true) => t.energy_used * task.distance / t.distance,
        (None, false) => f64::INFINITY,
    };
    let stress = t.max_stress.max(0.0);
    let limits = &s.limits;
    let margin = [
        1.0 - energy / task.energy,
        1.0 - stress / task.sigma_max,
        1.0 - watch.strain / limits.strain_max,
        1.0 - wave.f0 / limits.f0_max,
    ]
    .into_iter()
    .fold(f64::INFINITY, f64::min);
    Ok(TaskCheck {
        f0: wave.f0,
        energy,
        time_to_distance: t.time_to_distance,
        stress,
        strain: watch.strain,
        margin: if margin.is_nan() { -1.0 } else { margin },
    })
}

/// The horizon of a certification: settling plus twice the time to `D` at `speed` (m/s), within
/// [`MIN_HORIZON`, `MAX_HORIZON`].
pub fn horizon(scenario: &Scenario, speed: Option<f64>) -> f64 {
    let settle = scenario.plant.numerics.settle;
    match speed {
        Some(v) if v > 0.0 && v.is_finite() => {
            (settle + 2.0 * scenario.task.distance / v).clamp(MIN_HORIZON, MAX_HORIZON)
        }
        _ => MAX_HORIZON,
    }
}

/// Lowers the amplitude of `wave` (secant on the smallest margin, which falls as `f0` grows on
/// the optimiser's side of the mileage peak) until the task holds with `margin` on every limit;
/// at most `max_runs` runs of at most `horizon` s.
pub fn certify(
    scenario: &Scenario,
    wave: Wave,
    margin: f64,
    horizon: f64,
    max_runs: usize,
) -> anyhow::Result<TaskCertification> {
    crawler_models::verify::check_margin("margin", margin)?;
    let mut runs = Vec::new();
    let eval = |f0: f64, runs: &mut Vec<TaskCheck>| -> anyhow::Result<f64> {
        let c = check(scenario, Wave { f0, ..wave }, horizon)?;
        runs.push(c);
        Ok(c.margin - margin)
    };
    let done = |f0: f64, runs: Vec<TaskCheck>, certified: bool| TaskCertification {
        margin,
        f0,
        runs,
        certified,
        horizon,
    };
    let mut f_hi = wave.f0;
    let mut g_hi = eval(f_hi, &mut runs)?;
    if g_hi >= 0.0 {
        return Ok(done(f_hi, runs, true));
    }
    // bracket: shrink f0 until the margin holds
    let mut f_lo = f_hi;
    let mut g_lo = g_hi;
    while g_lo < 0.0 && runs.len() < max_runs {
        f_hi = f_lo;
        g_hi = g_lo;
        f_lo *= 0.9;
        g_lo = eval(f_lo, &mut runs)?;
    }
    if g_lo < 0.0 {
        return Ok(done(f_lo, runs, false));
    }
    // regula falsi inside [f_lo (holds), f_hi (fails)]; keep the best f0 that holds
    while runs.len() < max_runs && (f_hi - f_lo) > 1e-4 * f_hi {
        let f = f_lo - g_lo * (f_hi - f_lo) / (g_hi - g_lo);
        let f = f.clamp(f_lo + 0.1 * (f_hi - f_lo), f_hi - 0.1 * (f_hi - f_lo));
        let g = eval(f, &mut runs)?;
        if g >= 0.0 {
            f_lo = f;
            g_lo = g;
            if g < 0.25 * margin.max(1e-3) {
                break;
            }
        } else {
            f_hi = f;
            g_hi = g;
        }
    }
    Ok(done(f_lo, runs, true))
}
