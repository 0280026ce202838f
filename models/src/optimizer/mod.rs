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

mod choice;
mod grid;
mod outcome;
mod paper_mileage;

pub use grid::{linspace, parallel_map, parallel_map_range, set_threads};
pub use outcome::{
    Binding, Cell, Choice, Infeasibility, Infeasible, Margins, OptimizeError, OptimizeReport,
    Optimum,
};
pub use paper_mileage::{h, h_peak};

use outcome::infeasibility_summary;

use serde::Serialize;
use std::f64::consts::TAU;

use crawler_physics::params::{Body, Friction};
use crawler_physics::scenario::{Limits, Task};
use crawler_physics::wave::Wave;

use crate::operating_point::OperatingPoint;
use crate::paper_model::PaperModel;
use crate::prediction::{Model, Prediction};
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

impl Problem {
    /// Validates bounds, budgets and parameters.
    pub fn validate(&self) -> Result<(), crawler_physics::ParamError> {
        self.body.validate()?;
        self.friction.validate()?;
        self.task.validate()?;
        self.limits.validate()?;
        if let BodyLength::Fixed(l) = self.body_length {
            crawler_physics::error::positive("body.length", l)?;
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
    pub fn k_values(&self, points: usize) -> Result<Vec<f64>, crawler_physics::ParamError> {
        let [lo, hi] = self.limits.k;
        match self.body_length {
            BodyLength::OneWavelength => Ok(linspace(lo, hi, points)),
            BodyLength::Fixed(l) => {
                let m_lo = (lo * l / TAU - 1e-9).ceil().max(1.0) as u64;
                let m_hi = (hi * l / TAU + 1e-9).floor() as u64;
                if m_hi < m_lo {
                    return Err(crawler_physics::ParamError::new(
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

    /// Runs the grid search and refinement.
    pub fn optimize(
        &self,
        model: &ModelChoice,
        grid: &GridSpec,
    ) -> Result<OptimizeReport, OptimizeError> {
        let tol = self.check_grid(grid)?;
        let omegas = linspace(
            self.limits.omega[0],
            self.limits.omega[1],
            grid.omega_points,
        );
        let ks = self.k_values(grid.k_points)?;
        let cells = self.grid_cells(model, &omegas, &ks);
        let Some(grid_top) = cells
            .iter()
            .filter_map(|c| c.f0.and(c.velocity))
            .max_by(f64::total_cmp)
        else {
            return Err(OptimizeError::Infeasible(infeasibility_summary(&cells)));
        };
        let ties = Ties::of(&cells, grid_top, tol);
        let (omega, k) = (cells[ties.best_index].omega, cells[ties.best_index].k);
        let choice = self
            .choose(model, omega, k)
            .map_err(|e| OptimizeError::Infeasible(e.message))?;
        let start = Refined {
            omega,
            k,
            choice,
            top: grid_top,
            evaluations: 0,
        };
        let Refined {
            omega,
            k,
            choice,
            top,
            evaluations,
        } = if grid.refine {
            self.refine(model, &omegas, &ks, start, tol)
        } else {
            start
        };
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
                tied_cells: ties.count,
                tied_speed_spread: (ties.speeds[1] - ties.speeds[0]) / ties.speeds[1],
                tied_omega: ties.omega,
                tied_k: ties.k,
                speed_given_up: 1.0 - choice.velocity / top,
            },
        })
    }

    /// Validates the problem and the grid; returns the tie tolerance (relative speed share).
    fn check_grid(&self, grid: &GridSpec) -> Result<f64, OptimizeError> {
        self.validate()?;
        if grid.omega_points < 2
            || (grid.k_points < 2 && self.body_length == BodyLength::OneWavelength)
        {
            return Err(crawler_physics::ParamError::new(
                "grid",
                format!("{} x {}", grid.omega_points, grid.k_points),
                "at least 2 x 2 points",
            )
            .into());
        }
        let tol = grid.tie_tolerance;
        if !(0.0..=0.1).contains(&tol) {
            return Err(crawler_physics::ParamError::new(
                "grid.tie_tolerance",
                tol,
                "a relative speed tolerance in [0, 0.1]",
            )
            .into());
        }
        Ok(tol)
    }

    /// Evaluates every grid cell, k-major: `cells[j * omegas.len() + i]` is
    /// `(omegas[i], ks[j])` (omega in rad/s, k in rad/m).
    fn grid_cells(&self, model: &ModelChoice, omegas: &[f64], ks: &[f64]) -> Vec<Cell> {
        let peak = h_peak(self.friction.n_f);
        let rows: Vec<(f64, Option<f64>)> = match model {
            ModelChoice::Paper => ks.iter().map(|&k| self.mileage_root(k, peak)).collect(),
            ModelChoice::Improved(_) => Vec::new(),
        };
        let n_omega = omegas.len();
        // row-major: k by row, omega along it
        parallel_map_range(ks.len() * n_omega, |i| {
            let (row, omega) = (i / n_omega, omegas[i % n_omega]);
            let k = ks[row];
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
        })
    }

    /// Refines `start` by a compass search in `(alpha, k)` (alpha dimensionless, k in rad/m);
    /// the grids `omegas` (rad/s) and `ks` (rad/m) set the initial steps.
    fn refine(
        &self,
        model: &ModelChoice,
        omegas: &[f64],
        ks: &[f64],
        start: Refined,
        tol: f64,
    ) -> Refined {
        let Refined {
            mut omega,
            mut k,
            mut choice,
            mut top,
            mut evaluations,
        } = start;
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
        Refined {
            omega,
            k,
            choice,
            top,
            evaluations,
        }
    }
}

/// The grid cells within the tie tolerance of the fastest grid cell: the best of them and their
/// spread.
struct Ties {
    /// Index into the cells of the best tied cell.
    best_index: usize,
    /// How many cells tie.
    count: usize,
    /// Smallest and largest speed among the tied cells, m/s.
    speeds: [f64; 2],
    /// Smallest and largest `omega` among the tied cells, rad/s.
    omega: [f64; 2],
    /// Smallest and largest `k` among the tied cells, rad/m.
    k: [f64; 2],
}

impl Ties {
    /// One pass over the cells within `tol` (relative) of the fastest speed `grid_top` (m/s):
    /// the best of them (a cell outside never beats one inside), and their spread.
    fn of(cells: &[Cell], grid_top: f64, tol: f64) -> Self {
        let floor = grid_top * (1.0 - tol);
        let mut best: Option<(usize, f64, f64)> = None;
        let mut tied_cells = 0;
        let widen = |r: &mut [f64; 2], x: f64| *r = [r[0].min(x), r[1].max(x)];
        let empty = [f64::INFINITY, f64::NEG_INFINITY];
        let (mut tied_speeds, mut tied_omega, mut tied_k) = (empty, empty, empty);
        for (i, c) in cells.iter().enumerate() {
            let (Some(v), Some(f0)) = (c.velocity, c.f0) else {
                continue;
            };
            if v < floor || v.is_nan() {
                continue;
            }
            tied_cells += 1;
            widen(&mut tied_speeds, v);
            widen(&mut tied_omega, c.omega);
            widen(&mut tied_k, c.k);
            if best.is_none_or(|b| better((v, f0), (b.1, b.2), grid_top, tol)) {
                best = Some((i, v, f0));
            }
        }
        let (best_index, _, _) = best.expect("the fastest cell is within the tolerance");
        Self {
            best_index,
            count: tied_cells,
            speeds: tied_speeds,
            omega: tied_omega,
            k: tied_k,
        }
    }
}

/// The state of the search: the chosen `(omega, k)` and its choice of `f0`.
struct Refined {
    /// Angular frequency, rad/s.
    omega: f64,
    /// Wave number, rad/m.
    k: f64,
    /// The amplitude, binding constraint and speed at `(omega, k)`.
    choice: Choice,
    /// The fastest speed seen so far (grid and refinement), m/s.
    top: f64,
    /// Model evaluations of the refinement so far.
    evaluations: usize,
}
