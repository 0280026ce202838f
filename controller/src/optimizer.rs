//! The constrained optimal open-loop policy (paper Sec. V), with explicit actuator and body limits.
//!
//! Maximise `V(omega, k, f0)` subject to `M >= D / J0`, `sigma <= sigma_max`, `max |u_x| <= strain_max`,
//! `f0 <= f0_max`, `omega in [omega_min, omega_max]`, `k in [k_min, k_max]`. Method (the paper's): a
//! grid over `(omega, k)`; at each cell `f0` is the largest amplitude the constraints allow (speed
//! grows with `f0`; stress and strain grow with it; mileage first grows then falls), found by
//! bracketed root finding; then a compass search refines the best cell. For the paper's model the
//! mileage condition reduces to `h(z) = z^2 (n_F - 2 asin(z) / pi) >= K(omega, k)` with
//! `z = eps c_d n_F / (f0 k zeta R0 alpha)`, and `h` depends on `n_F` only, so each cell costs a
//! few Newton steps.
//!
//! Where the mileage binds the speed hardly depends on `(omega, k)` (exactly not at all in the
//! paper's model on a body of fixed length): the optimum is a ridge, not a point
//! (`docs/physics.md` §5.2-5.3). Cells within a relative speed tolerance of the fastest are
//! therefore ranked by a second criterion, the lowest amplitude `f0` (the weakest drive that
//! achieves the speed), and the refinement follows the same order.

use serde::Serialize;
use std::f64::consts::{PI, TAU};

use crawler_plant::params::{Body, Friction};
use crawler_plant::scenario::{Limits, Task};
use crawler_plant::wave::Wave;

use crate::operating_point::OperatingPoint;
use crate::paper_model::{r0, PaperModel};
use crate::prediction::{Model, Prediction};
use crate::roots::{brent, golden_max};
use crate::travelling_wave::TravellingWaveModel;

/// How the body relates to the wave.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", content = "length", rename_all = "snake_case")]
pub enum BodyLength {
    /// The paper's setting: the body is one wavelength of whatever `k` is chosen; P is per wavelength.
    OneWavelength,
    /// A real body of this length, m: `k` must fit it a whole number of times; P is for the body.
    Fixed(f64),
}

/// The model used by the optimiser.
#[derive(Debug, Clone, Copy)]
pub enum ModelChoice {
    /// The paper's eqs. (31)-(33).
    Paper,
    /// The travelling-wave model.
    Improved(TravellingWaveModel),
}

impl ModelChoice {
    /// Parses `paper` or `improved` (alias `travelling-wave`).
    pub fn parse(name: &str) -> Result<Self, String> {
        match name {
            "paper" => Ok(Self::Paper),
            "improved" | "travelling-wave" => Ok(Self::Improved(TravellingWaveModel::default())),
            other => Err(format!(
                "unknown model {other:?}: allowed paper, improved (alias travelling-wave)"
            )),
        }
    }

    /// The model's name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Paper => "paper",
            Self::Improved(_) => "improved",
        }
    }

    /// The prediction at `op`.
    pub fn predict(&self, op: &OperatingPoint) -> Prediction {
        match self {
            Self::Paper => PaperModel::default().predict(op),
            Self::Improved(m) => m.predict(op),
        }
    }
}

/// The optimisation problem.
#[derive(Debug, Clone, Copy)]
pub struct Problem {
    /// Body material.
    pub body: Body,
    /// Friction law.
    pub friction: Friction,
    /// Task constraints.
    pub task: Task,
    /// Actuator and body limits.
    pub limits: Limits,
    /// Body length convention.
    pub body_length: BodyLength,
}

/// The default relative speed tolerance of the tie-break, well below the models' accuracy.
pub const DEFAULT_TIE_TOLERANCE: f64 = 1e-3;

/// Grid resolution and tie-break.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct GridSpec {
    /// Points in omega.
    pub omega_points: usize,
    /// Points in k (ignored for a fixed body: every fitting k is used).
    pub k_points: usize,
    /// Refine the best cell by a compass search.
    pub refine: bool,
    /// Cells whose speed is within this share of the fastest are tied; among them the lowest
    /// `f0` wins (`docs/physics.md` §5.3). In `[0, 0.1]`; 0 picks the fastest cell.
    pub tie_tolerance: f64,
}

impl GridSpec {
    /// A grid of `omega_points x k_points`, refined, with the default tie tolerance.
    pub fn new(omega_points: usize, k_points: usize) -> Self {
        Self {
            omega_points,
            k_points,
            refine: true,
            tie_tolerance: DEFAULT_TIE_TOLERANCE,
        }
    }
}

/// How the optimum was chosen among nearly equally fast cells.
#[derive(Debug, Clone, Serialize)]
pub struct TieBreak {
    /// The second criterion.
    pub criterion: &'static str,
    /// Relative speed tolerance within which cells tie.
    pub tolerance: f64,
    /// The fastest speed found (grid and refinement), m/s.
    pub fastest_velocity: f64,
    /// Grid cells within the tolerance of the fastest grid cell.
    pub tied_cells: usize,
    /// `(max - min) / max` of the speeds of the tied cells.
    pub tied_speed_spread: f64,
    /// Smallest and largest `omega` among the tied cells, rad/s.
    pub tied_omega: [f64; 2],
    /// Smallest and largest `k` among the tied cells, rad/m.
    pub tied_k: [f64; 2],
    /// `1 - V / fastest_velocity` at the optimum: the speed given up for the lower `f0`.
    pub speed_given_up: f64,
}

/// Orders candidate `(velocity, f0)` pairs: within `tol` of the fastest speed `top` the lower
/// `f0` is better, otherwise the faster.
fn better(a: (f64, f64), b: (f64, f64), top: f64, tol: f64) -> bool {
    let floor = top * (1.0 - tol);
    match (a.0 >= floor, b.0 >= floor) {
        (true, true) => a.1 < b.1 * (1.0 - 1e-12) || (a.1 <= b.1 && a.0 > b.0),
        (true, false) => true,
        (false, true) => false,
        (false, false) => a.0 > b.0,
    }
}

/// Which constraint fixes `f0` at a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Binding {
    /// Mileage `M = D / J0`.
    Mileage,
    /// Stress `sigma = sigma_max`.
    Stress,
    /// Strain `max |u_x| = strain_max`.
    Strain,
    /// Actuator limit `f0 = f0_max`.
    F0Max,
    /// No feasible `f0`.
    Infeasible,
}

/// Why no amplitude is feasible at a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Infeasibility {
    /// No amplitude meets the mileage budget `M >= D / J0`.
    Mileage,
    /// The stress limit keeps `f0` below every amplitude that meets the budget moving forward.
    Stress,
    /// The strain limit does.
    Strain,
    /// The actuator limit `f0_max` does.
    F0Max,
    /// The crawler does not move forward (no friction asymmetry, or `V <= 0`).
    NoForwardMotion,
    /// The model has no answer here (outside its validity, or no periodic solution).
    ModelUndefined,
}

impl Infeasibility {
    /// Every cause, in the order of the figures' legends.
    pub const ALL: [Infeasibility; 6] = [
        Self::Mileage,
        Self::Stress,
        Self::Strain,
        Self::F0Max,
        Self::NoForwardMotion,
        Self::ModelUndefined,
    ];

    /// A short description for legends and summaries.
    pub fn describe(self) -> &'static str {
        match self {
            Self::Mileage => "mileage budget D/J0 unreachable",
            Self::Stress => "stress limit keeps f0 too small",
            Self::Strain => "strain limit keeps f0 too small",
            Self::F0Max => "actuator limit f0_max too small",
            Self::NoForwardMotion => "no forward motion",
            Self::ModelUndefined => "model undefined",
        }
    }

    fn of(binding: Binding) -> Self {
        match binding {
            Binding::Stress => Self::Stress,
            Binding::Strain => Self::Strain,
            Binding::F0Max => Self::F0Max,
            Binding::Mileage | Binding::Infeasible => Self::Mileage,
        }
    }
}

/// Why a cell is infeasible: the cause and a message with the numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct Infeasible {
    /// The cause.
    pub cause: Infeasibility,
    /// What was found, with numbers.
    pub message: String,
}

impl Infeasible {
    fn new(cause: Infeasibility, message: impl Into<String>) -> Self {
        Self {
            cause,
            message: message.into(),
        }
    }
}

impl std::fmt::Display for Infeasible {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

/// One grid cell.
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    /// rad/s.
    pub omega: f64,
    /// rad/m.
    pub k: f64,
    /// omega / omega_n.
    pub alpha: f64,
    /// Chosen amplitude, N.
    pub f0: Option<f64>,
    /// Predicted speed at that amplitude, m/s.
    pub velocity: Option<f64>,
    /// The binding constraint.
    pub binding: Binding,
    /// Why the cell is infeasible.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub infeasibility: Option<Infeasibility>,
    /// The same, with numbers.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

/// The optimum and its predicted metrics.
#[derive(Debug, Clone, Serialize)]
pub struct Optimum {
    /// rad/s.
    pub omega: f64,
    /// rad/m.
    pub k: f64,
    /// omega / omega_n.
    pub alpha: f64,
    /// N.
    pub f0: f64,
    /// Wavelengths on the body.
    pub wavelengths: f64,
    /// Binding constraint.
    pub binding: Binding,
    /// The model's prediction at the optimum.
    pub prediction: Prediction,
    /// Margins of every constraint at the optimum (>= 0 means satisfied).
    pub margins: Margins,
}

/// Constraint margins, relative to the bound (>= 0 means satisfied).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Margins {
    /// `M / (D/J0) - 1`.
    pub mileage: f64,
    /// `1 - sigma / sigma_max`.
    pub stress: f64,
    /// `1 - strain / strain_max`.
    pub strain: f64,
    /// `1 - f0 / f0_max`.
    pub f0: f64,
}

impl Margins {
    /// Margins of metrics `(mileage, stress, strain)` at amplitude `f0`.
    pub fn of(problem: &Problem, f0: f64, mileage: f64, stress: f64, strain: f64) -> Self {
        Self {
            mileage: mileage / problem.task.min_mileage() - 1.0,
            stress: 1.0 - stress / problem.task.sigma_max,
            strain: 1.0 - strain / problem.limits.strain_max,
            f0: 1.0 - f0 / problem.limits.f0_max,
        }
    }

    /// True if every constraint holds up to `tol` (relative).
    pub fn all_hold(&self, tol: f64) -> bool {
        self.mileage >= -tol && self.stress >= -tol && self.strain >= -tol && self.f0 >= -tol
    }
}

/// The whole result.
#[derive(Debug, Clone, Serialize)]
pub struct OptimizeReport {
    /// Model used.
    pub model: &'static str,
    /// The optimum.
    pub optimum: Optimum,
    /// Required mileage D / J0, m/J.
    pub min_mileage: f64,
    /// The task.
    pub task: Task,
    /// The limits.
    pub limits: Limits,
    /// Body convention.
    pub body_length: BodyLength,
    /// omega values of the grid, rad/s.
    pub omega_grid: Vec<f64>,
    /// k values of the grid, rad/m.
    pub k_grid: Vec<f64>,
    /// Cells, k-major: `cells[j * omega_grid.len() + i]` is `(omega_grid[i], k_grid[j])`.
    pub cells: Vec<Cell>,
    /// Model evaluations of the refinement.
    pub refinement_evaluations: usize,
    /// How the optimum was chosen on the ridge of nearly equal speeds.
    pub tie_break: TieBreak,
}

/// Why the optimisation failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OptimizeError {
    /// Bad problem data.
    #[error(transparent)]
    Invalid(#[from] crawler_plant::ParamError),
    /// No cell is feasible.
    #[error("infeasible: {0}")]
    Infeasible(String),
}

/// The choice of `f0` at one `(omega, k)`.
#[derive(Debug, Clone)]
pub struct Choice {
    /// N.
    pub f0: f64,
    /// Binding constraint.
    pub binding: Binding,
    /// Speed at f0, m/s.
    pub velocity: f64,
}

impl Problem {
    /// Validates bounds, budgets and parameters.
    pub fn validate(&self) -> Result<(), crawler_plant::ParamError> {
        self.body.validate()?;
        self.friction.validate()?;
        self.task.validate()?;
        self.limits.validate()?;
        if let BodyLength::Fixed(l) = self.body_length {
            crawler_plant::error::positive("body.length", l)?;
        }
        Ok(())
    }

    /// Wavelengths on the body for wave number `k`.
    pub fn wavelengths(&self, k: f64) -> f64 {
        match self.body_length {
            BodyLength::OneWavelength => 1.0,
            BodyLength::Fixed(l) => (k * l / TAU).round().max(1.0),
        }
    }

    /// The operating point `(omega, k, f0)`.
    pub fn point(&self, omega: f64, k: f64, f0: f64) -> OperatingPoint {
        OperatingPoint {
            body: self.body,
            friction: self.friction,
            wave: Wave {
                f0,
                k,
                omega,
                phase: 0.0,
            },
            wavelengths: self.wavelengths(k),
        }
    }

    /// The k values searched: a uniform grid, or every `2 pi m / L` in bounds for a fixed body.
    pub fn k_values(&self, points: usize) -> Result<Vec<f64>, crawler_plant::ParamError> {
        let [lo, hi] = self.limits.k;
        match self.body_length {
            BodyLength::OneWavelength => Ok(linspace(lo, hi, points)),
            BodyLength::Fixed(l) => {
                let m_lo = (lo * l / TAU - 1e-9).ceil().max(1.0) as u64;
                let m_hi = (hi * l / TAU + 1e-9).floor() as u64;
                if m_hi < m_lo {
                    return Err(crawler_plant::ParamError::new(
                        "limits.k",
                        format!("[{lo}, {hi}]"),
                        format!(
                            "a range holding some k = 2 pi m / L for the body length L = {l} m"
                        ),
                    ));
                }
                Ok((m_lo..=m_hi).map(|m| TAU * m as f64 / l).collect())
            }
        }
    }

    /// The largest feasible `f0` at `(omega, k)` under `model`, or why there is none.
    pub fn choose(&self, model: &ModelChoice, omega: f64, k: f64) -> Result<Choice, Infeasible> {
        match model {
            ModelChoice::Paper => self.choose_paper(omega, k),
            ModelChoice::Improved(_) => self.choose_generic(model, omega, k),
        }
    }

    fn choose_paper(&self, omega: f64, k: f64) -> Result<Choice, Infeasible> {
        let peak = h_peak(self.friction.n_f);
        self.choose_paper_with(omega, k, peak, &self.mileage_root(k, peak))
    }

    /// The mileage condition of the paper's model at wave number `k`: `(K, z_a)`, with `z_a` the
    /// rising root of `h(z) = K`. `K = (D/J0) c_v P(f0 = 1) g^2 / (eps c_d)` depends on `k` only
    /// (`docs/physics.md` §5.2), so a grid solves it once per row of k.
    fn mileage_root(&self, k: f64, peak: (f64, f64)) -> (f64, Option<f64>) {
        let f = self.friction;
        let band = f.band();
        let op = self.point(k * self.body.wave_speed(), k, 1.0);
        let (alpha, zeta) = (op.alpha(), op.zeta());
        let r0 = r0(alpha, zeta);
        let g = band * f.n_f / (k * zeta * r0 * alpha);
        let p = PI * zeta * alpha * r0 * r0 * op.wave.omega / (k * self.body.stiffness())
            * op.wavelengths;
        let kk = self.task.min_mileage() * f.viscous * p * g * g / band;
        let (z_star, h_star) = peak;
        (
            kk,
            (kk <= h_star && kk.is_finite()).then(|| h_root_rising(f.n_f, kk, z_star)),
        )
    }

    /// [`Self::choose_paper`] with the peak of `h`, which depends on `n_F` only, computed once.
    fn choose_paper_with(
        &self,
        omega: f64,
        k: f64,
        peak: (f64, f64),
        row: &(f64, Option<f64>),
    ) -> Result<Choice, Infeasible> {
        let op = self.point(omega, k, 1.0);
        let (alpha, zeta) = (op.alpha(), op.zeta());
        let r0 = r0(alpha, zeta);
        let ae = self.body.stiffness();
        let f = self.friction;
        let band = f.band();
        if band * f.n_f <= 0.0 {
            return Err(Infeasible::new(
                Infeasibility::NoForwardMotion,
                "no forward motion is possible: eps c_d n_F = 0",
            ));
        }
        // caps
        let f_stress = self.task.sigma_max * self.body.area
            / (r0 * alpha * (alpha * alpha + zeta * zeta).sqrt());
        let f_strain = self.limits.strain_max * ae / r0;
        let (mut cap, mut binding) = (self.limits.f0_max, Binding::F0Max);
        if f_stress < cap {
            cap = f_stress;
            binding = Binding::Stress;
        }
        if f_strain < cap {
            cap = f_strain;
            binding = Binding::Strain;
        }
        // mileage in z = g / f0
        let g = band * f.n_f / (k * zeta * r0 * alpha);
        // P at f0 = 1 N: eq. (32), pi zeta alpha R0^2 omega / (k A_c E) per wavelength
        let p = PI * zeta * alpha * r0 * r0 * omega / (k * ae) * op.wavelengths;
        let (kk, z_root) = *row;
        let h_star = peak.1;
        if kk > h_star {
            return Err(Infeasible::new(
                Infeasibility::Mileage,
                format!(
                    "mileage: the best amplitude gives M = {:.4e} m/J < D/J0 = {:.4e} m/J",
                    h_star * band / (f.viscous * p * g * g),
                    self.task.min_mileage()
                ),
            ));
        }
        let z_a = z_root.expect("feasible rows have a root");
        let z_cap = g / cap;
        let z = if z_a > z_cap {
            binding = Binding::Mileage;
            z_a
        } else {
            z_cap
        };
        // z must also lie below the falling root of h = K (mileage) and below 1 (validity).
        if h(f.n_f, z) < kk * (1.0 - 1e-9) || z > 1.0 {
            return Err(Infeasible::new(
                Infeasibility::of(binding),
                format!(
                    "{}: the amplitude it allows ({:.4} N) is too small to meet the mileage D/J0 with forward motion",
                    binding_name(binding),
                    cap
                ),
            ));
        }
        let velocity = band / f.viscous * (f.n_f - 2.0 * z.asin() / PI);
        Ok(Choice {
            f0: g / z,
            binding,
            velocity,
        })
    }

    fn choose_generic(
        &self,
        model: &ModelChoice,
        omega: f64,
        k: f64,
    ) -> Result<Choice, Infeasible> {
        let pred = |f0: f64| model.predict(&self.point(omega, k, f0));
        let tol = 1e-7 * self.limits.f0_max;
        let mut cap = self.limits.f0_max;
        let mut binding = Binding::F0Max;
        let top = pred(cap);
        let stress_at = |p: &Prediction| p.max_stress.unwrap_or(f64::INFINITY);
        let strain_at = |p: &Prediction| p.max_strain.unwrap_or(f64::INFINITY);
        if stress_at(&top) > self.task.sigma_max {
            cap = brent(
                |f0| stress_at(&pred(f0)) - self.task.sigma_max,
                0.0,
                cap,
                tol,
            )
            .ok_or_else(|| {
                Infeasible::new(
                    Infeasibility::Stress,
                    "stress: no amplitude meets sigma_max",
                )
            })?;
            binding = Binding::Stress;
        }
        let at_cap = pred(cap);
        if strain_at(&at_cap) > self.limits.strain_max {
            cap = brent(
                |f0| strain_at(&pred(f0)) - self.limits.strain_max,
                0.0,
                cap,
                tol,
            )
            .ok_or_else(|| {
                Infeasible::new(
                    Infeasibility::Strain,
                    "strain: no amplitude meets strain_max",
                )
            })?;
            binding = Binding::Strain;
        }
        let req = self.task.min_mileage();
        let mileage = |f0: f64| {
            let p = pred(f0);
            match (p.velocity, p.mileage) {
                (Some(v), Some(m)) if v > 0.0 && m.is_finite() => m,
                _ => 0.0,
            }
        };
        let mut f0 = cap;
        if mileage(cap) < req {
            let (f_peak, m_peak) = golden_max(mileage, 1e-3 * cap, cap, 1e-4 * cap);
            if m_peak < req {
                return Err(Infeasible::new(
                    Infeasibility::Mileage,
                    format!(
                        "mileage: the best amplitude at or below {:.4} N ({}) gives M = {:.4e} m/J < D/J0 = {:.4e} m/J",
                        cap,
                        binding_name(binding),
                        m_peak,
                        req
                    ),
                ));
            }
            f0 = brent(|f| mileage(f) - req, f_peak, cap, tol).ok_or_else(|| {
                Infeasible::new(Infeasibility::Mileage, "mileage: root not bracketed")
            })?;
            binding = Binding::Mileage;
        }
        let p = pred(f0);
        let velocity = p.velocity.ok_or_else(|| {
            Infeasible::new(Infeasibility::ModelUndefined, "model has no speed here")
        })?;
        if velocity <= 0.0 {
            return Err(Infeasible::new(
                Infeasibility::NoForwardMotion,
                "no forward motion at the allowed amplitude",
            ));
        }
        Ok(Choice {
            f0,
            binding,
            velocity,
        })
    }

    /// Runs the grid search and refinement.
    pub fn optimize(
        &self,
        model: &ModelChoice,
        grid: &GridSpec,
    ) -> Result<OptimizeReport, OptimizeError> {
        self.validate()?;
        if grid.omega_points < 2
            || (grid.k_points < 2 && self.body_length == BodyLength::OneWavelength)
        {
            return Err(crawler_plant::ParamError::new(
                "grid",
                format!("{} x {}", grid.omega_points, grid.k_points),
                "at least 2 x 2 points",
            )
            .into());
        }
        let tol = grid.tie_tolerance;
        if !(0.0..=0.1).contains(&tol) {
            return Err(crawler_plant::ParamError::new(
                "grid.tie_tolerance",
                tol,
                "a relative speed tolerance in [0, 0.1]",
            )
            .into());
        }
        let omegas = linspace(
            self.limits.omega[0],
            self.limits.omega[1],
            grid.omega_points,
        );
        let ks = self.k_values(grid.k_points)?;
        let points: Vec<(f64, f64)> = ks
            .iter()
            .flat_map(|&k| omegas.iter().map(move |&w| (w, k)))
            .collect();
        let peak = h_peak(self.friction.n_f);
        let rows: Vec<(f64, Option<f64>)> = match model {
            ModelChoice::Paper => ks.iter().map(|&k| self.mileage_root(k, peak)).collect(),
            ModelChoice::Improved(_) => Vec::new(),
        };
        let n_omega = omegas.len();
        let indexed: Vec<(usize, f64, f64)> = points
            .iter()
            .enumerate()
            .map(|(i, &(w, k))| (i / n_omega, w, k))
            .collect();
        let cells = parallel_map(&indexed, |&(row, omega, k)| {
            let alpha = omega / (k * self.body.wave_speed());
            let choice = match model {
                ModelChoice::Paper => self.choose_paper_with(omega, k, peak, &rows[row]),
                ModelChoice::Improved(_) => self.choose_generic(model, omega, k),
            };
            match choice {
                Ok(c) => Cell {
                    omega,
                    k,
                    alpha,
                    f0: Some(c.f0),
                    velocity: Some(c.velocity),
                    binding: c.binding,
                    infeasibility: None,
                    reason: None,
                },
                Err(why) => Cell {
                    omega,
                    k,
                    alpha,
                    f0: None,
                    velocity: None,
                    binding: Binding::Infeasible,
                    infeasibility: Some(why.cause),
                    reason: Some(why.message),
                },
            }
        });
        let feasible = || {
            cells
                .iter()
                .enumerate()
                .filter_map(|(i, c)| Some((i, c.velocity?, c.f0?)))
        };
        let Some(grid_top) = feasible().map(|c| c.1).max_by(f64::total_cmp) else {
            return Err(OptimizeError::Infeasible(infeasibility_summary(&cells)));
        };
        let (best_index, _, _) = feasible()
            .reduce(|a, b| {
                if better((b.1, b.2), (a.1, a.2), grid_top, tol) {
                    b
                } else {
                    a
                }
            })
            .expect("a feasible cell exists");
        let tied: Vec<&Cell> = feasible()
            .filter(|c| c.1 >= grid_top * (1.0 - tol))
            .map(|c| &cells[c.0])
            .collect();
        let range = |f: &dyn Fn(&Cell) -> f64| {
            tied.iter()
                .fold([f64::INFINITY, f64::NEG_INFINITY], |r, c| {
                    [r[0].min(f(c)), r[1].max(f(c))]
                })
        };
        let tied_speeds = range(&|c| c.velocity.unwrap_or(0.0));
        let (tied_omega, tied_k) = (range(&|c| c.omega), range(&|c| c.k));
        let tied_cells = tied.len();
        let mut top = grid_top;
        let (mut omega, mut k) = (cells[best_index].omega, cells[best_index].k);
        let mut choice = self
            .choose(model, omega, k)
            .map_err(|e| OptimizeError::Infeasible(e.message))?;
        let mut evaluations = 0;
        if grid.refine {
            // A compass search in (alpha, k): a step in k keeps alpha, so the search can follow
            // the resonance line, along which the optimum's ridge runs (docs/physics.md §5.3).
            let c = self.body.wave_speed();
            let d_alpha = (omegas[1] - omegas[0]).abs() / (k * c);
            let d_k = if ks.len() > 1 && self.body_length == BodyLength::OneWavelength {
                (ks[1] - ks[0]).abs()
            } else {
                0.0
            };
            let mut alpha = omega / (k * c);
            let (mut s_alpha, mut s_k) = (0.5 * d_alpha, 0.5 * d_k);
            while s_alpha > 1e-4 * d_alpha && evaluations < 200 {
                let mut improved = false;
                for (da, dk) in [(s_alpha, 0.0), (-s_alpha, 0.0), (0.0, s_k), (0.0, -s_k)] {
                    if da == 0.0 && dk == 0.0 {
                        continue;
                    }
                    let (a2, k2) = (alpha + da, k + dk);
                    let w2 = a2 * k2 * c;
                    if w2 < self.limits.omega[0]
                        || w2 > self.limits.omega[1]
                        || k2 < self.limits.k[0]
                        || k2 > self.limits.k[1]
                    {
                        continue;
                    }
                    evaluations += 1;
                    if let Ok(c) = self.choose(model, w2, k2) {
                        top = top.max(c.velocity);
                        if better((c.velocity, c.f0), (choice.velocity, choice.f0), top, tol) {
                            (alpha, omega, k) = (a2, w2, k2);
                            choice = c;
                            improved = true;
                        }
                    }
                }
                if !improved {
                    s_alpha *= 0.5;
                    s_k *= 0.5;
                }
            }
        }
        let op = self.point(omega, k, choice.f0);
        let prediction = model.predict(&op);
        let margins = Margins::of(
            self,
            choice.f0,
            prediction.mileage.unwrap_or(0.0),
            prediction.max_stress.unwrap_or(f64::INFINITY),
            prediction.max_strain.unwrap_or(f64::INFINITY),
        );
        Ok(OptimizeReport {
            model: model.name(),
            optimum: Optimum {
                omega,
                k,
                alpha: op.alpha(),
                f0: choice.f0,
                wavelengths: op.wavelengths,
                binding: choice.binding,
                prediction,
                margins,
            },
            min_mileage: self.task.min_mileage(),
            task: self.task,
            limits: self.limits,
            body_length: self.body_length,
            omega_grid: omegas,
            k_grid: ks,
            cells,
            refinement_evaluations: evaluations,
            tie_break: TieBreak {
                criterion: "lowest f0 among the cells within the tolerance of the fastest speed",
                tolerance: tol,
                fastest_velocity: top,
                tied_cells,
                tied_speed_spread: (tied_speeds[1] - tied_speeds[0]) / tied_speeds[1],
                tied_omega,
                tied_k,
                speed_given_up: 1.0 - choice.velocity / top,
            },
        })
    }
}

fn binding_name(b: Binding) -> &'static str {
    match b {
        Binding::Mileage => "mileage",
        Binding::Stress => "stress (sigma_max)",
        Binding::Strain => "strain (strain_max)",
        Binding::F0Max => "actuator limit f0_max",
        Binding::Infeasible => "infeasible",
    }
}

fn infeasibility_summary(cells: &[Cell]) -> String {
    let counts: Vec<String> = Infeasibility::ALL
        .iter()
        .filter_map(|&cause| {
            let n = cells
                .iter()
                .filter(|c| c.infeasibility == Some(cause))
                .count();
            (n > 0).then(|| format!("{} ({n} cells)", cause.describe()))
        })
        .collect();
    let example = cells
        .iter()
        .find_map(|c| c.reason.clone())
        .unwrap_or_default();
    format!(
        "no (omega, k) in the bounds is feasible; cause per cell: {}. Example: {example}",
        counts.join(", ")
    )
}

/// `h(z) = z^2 (n_F - 2 asin(z) / pi)`: the paper's mileage as a function of `z = g / f0`.
pub fn h(n_f: f64, z: f64) -> f64 {
    z * z * (n_f - 2.0 * z.min(1.0).asin() / PI)
}

/// The maximum of `h` on `[0, sin(pi n_F / 2)]`: `(z*, h(z*))`.
pub fn h_peak(n_f: f64) -> (f64, f64) {
    let z0 = (PI * n_f / 2.0).sin();
    golden_max(|z| h(n_f, z), 0.0, z0, 1e-13)
}

/// The root of `h(z) = target` on the rising branch `[0, z*]` (safeguarded Newton).
fn h_root_rising(n_f: f64, target: f64, z_star: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, z_star);
    let mut z = (target / n_f).sqrt().min(z_star);
    for _ in 0..60 {
        let f = h(n_f, z) - target;
        if f > 0.0 {
            hi = z;
        } else {
            lo = z;
        }
        let d = 2.0 * z * (n_f - 2.0 * z.asin() / PI) - z * z * 2.0 / (PI * (1.0 - z * z).sqrt());
        let mut next = z - f / d;
        if !(next > lo && next < hi && next.is_finite()) {
            next = 0.5 * (lo + hi);
        }
        if (next - z).abs() <= 1e-15 * z.max(1e-300) {
            return next;
        }
        z = next;
    }
    z
}

/// `n` evenly spaced values from `a` to `b` inclusive.
pub fn linspace(a: f64, b: f64, n: usize) -> Vec<f64> {
    if n == 1 {
        return vec![a];
    }
    (0..n)
        .map(|i| a + (b - a) * i as f64 / (n - 1) as f64)
        .collect()
}

static THREADS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Limits the threads of [`parallel_map`] (0: all cores).
pub fn set_threads(n: usize) {
    THREADS.store(n, std::sync::atomic::Ordering::Relaxed);
}

/// Maps `f` over `items` on all cores (or [`set_threads`]), preserving order.
pub fn parallel_map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let limit = THREADS.load(std::sync::atomic::Ordering::Relaxed);
    let threads = (if limit == 0 { cores } else { limit.min(cores) }).min(items.len().max(1));
    if threads <= 1 || items.len() < 64 {
        return items.iter().map(&f).collect();
    }
    let chunk = items.len().div_ceil(threads);
    std::thread::scope(|scope| {
        let handles: Vec<_> = items
            .chunks(chunk)
            .map(|part| scope.spawn(|| part.iter().map(&f).collect::<Vec<R>>()))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("worker thread"))
            .collect()
    })
}
