//! The scenario flags shared by `crawler-plant` and `crawler-controller`.

use std::path::PathBuf;

use clap::Args;

use crawler_plant::scenario::{Overrides, Scenario, ScenarioError};

/// Scenario file and the common overrides.
#[derive(Args, Debug, Clone, Default)]
pub struct ScenarioArgs {
    /// Scenario TOML file (default: the embedded scenarios/paper.toml).
    #[arg(long, value_name = "FILE")]
    pub scenario: Option<PathBuf>,
    /// Dry friction coefficient eps (>= 0).
    #[arg(long, allow_hyphen_values = true)]
    pub eps: Option<f64>,
    /// Friction asymmetry n_F (0 <= n_F <= 1).
    #[arg(long = "n-f", allow_hyphen_values = true)]
    pub n_f: Option<f64>,
    /// Wave amplitude f0, N.
    #[arg(long, allow_hyphen_values = true)]
    pub f0: Option<f64>,
    /// Wave number k, rad/m (the body is one wavelength unless the scenario sets body.length).
    #[arg(long, allow_hyphen_values = true)]
    pub k: Option<f64>,
    /// Angular frequency omega, rad/s.
    #[arg(long, conflicts_with = "alpha", allow_hyphen_values = true)]
    pub omega: Option<f64>,
    /// Frequency ratio: omega = alpha * omega_n, omega_n = k sqrt(A_c E / rho).
    #[arg(long, allow_hyphen_values = true)]
    pub alpha: Option<f64>,
    /// Number of cells N.
    #[arg(long, allow_hyphen_values = true)]
    pub cells: Option<i64>,
    /// End time, s.
    #[arg(long = "t-end", allow_hyphen_values = true)]
    pub t_end: Option<f64>,
    /// Task mode: end the run when the body has travelled task.distance (success) or spent
    /// task.energy (failure), as `task.end_run = true` in the scenario.
    #[arg(long)]
    pub task: bool,
}

impl ScenarioArgs {
    /// The overrides given.
    pub fn overrides(&self) -> Overrides {
        Overrides {
            eps: self.eps,
            n_f: self.n_f,
            f0: self.f0,
            k: self.k,
            omega: self.omega,
            alpha: self.alpha,
            cells: self.cells,
            t_end: self.t_end,
            end_run: self.task.then_some(true),
        }
    }

    /// Loads the scenario with the overrides applied.
    pub fn load(&self) -> Result<Scenario, ScenarioError> {
        Scenario::load(self.scenario.as_deref(), &self.overrides())
    }
}
