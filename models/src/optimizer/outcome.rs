//! What the optimiser finds: the binding constraint and feasibility of each grid cell, the
//! optimum with its margins, and the report.

use serde::Serialize;

use crate::prediction::Prediction;

use crawler_physics::scenario::{Limits, Task};

use super::{BodyLength, Problem, TieBreak};

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

    pub(super) fn of(binding: Binding) -> Self {
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
    pub(super) fn new(cause: Infeasibility, message: impl Into<String>) -> Self {
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
    Invalid(#[from] crawler_physics::ParamError),
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

pub(super) fn binding_name(b: Binding) -> &'static str {
    match b {
        Binding::Mileage => "mileage",
        Binding::Stress => "stress (sigma_max)",
        Binding::Strain => "strain (strain_max)",
        Binding::F0Max => "actuator limit f0_max",
        Binding::Infeasible => "infeasible",
    }
}

pub(super) fn infeasibility_summary(cells: &[Cell]) -> String {
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
