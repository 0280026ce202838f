//! `crawler-plant simulate`: the plant under the scenario's travelling wave, in process, run by
//! the [`crate::execution`] loop with no controller.

use crate::execution::{Actuation, Execution, ExecutionError, Hold, Observer, Progress, Start};
use crate::report::Report;
use crate::scenario::Scenario;

/// Options of an in-process run.
pub struct SimulateOptions<'a> {
    /// Largest number of episodes listed in the report (all are counted).
    pub max_episodes: usize,
    /// Called with `(communication steps done, communication steps in the run)` every 256
    /// steps and once at the end (a program draws its progress bar from it; the library draws
    /// nothing).
    pub progress: Option<&'a mut dyn FnMut(u64, u64)>,
}

impl Default for SimulateOptions<'_> {
    fn default() -> Self {
        Self {
            max_episodes: 10_000,
            progress: None,
        }
    }
}

impl std::fmt::Debug for SimulateOptions<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimulateOptions")
            .field("max_episodes", &self.max_episodes)
            .field("progress", &self.progress.is_some())
            .finish()
    }
}

/// Why a simulation failed.
pub type SimulateError = ExecutionError;

/// Runs the scenario's plant under its wave from t = 0 to `t_end` (rounded up to a whole number
/// of communication steps), or until the task ends the run in task mode.
pub fn simulate(scenario: &Scenario, opts: SimulateOptions) -> Result<Report, SimulateError> {
    let start = Start {
        actuation: Some(Actuation::Wave(scenario.wave)),
        max_episodes: opts.max_episodes,
    };
    let mut run = Execution::new(scenario, start)?;
    match opts.progress {
        Some(report) => {
            let mut progress = Progress { every: 256, report };
            let observers: &mut [&mut dyn Observer] = &mut [&mut progress];
            run.run(&mut Hold, observers)?;
        }
        None => run.run(&mut Hold, &mut [])?,
    }
    Ok(run.report()?)
}
