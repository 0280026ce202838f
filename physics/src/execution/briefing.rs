//! What a controller is told about the plant it drives: the one place that decides it, for every
//! route (in process, over the wire, in a sweep, from Python).
//!
//! A controller is told the body, the grid and the communication step the plant really uses, and
//! the pipe's friction only when the scenario discloses it: otherwise it is told the nominal
//! friction (`pipe.nominal`) and no map, and has to find out the rest from what it observes.
//! Task, limits and the default wave come from the controller's own scenario.

use crate::error::ParamError;
use crate::params::{Body, Boundary, Friction};
use crate::scenario::Scenario;

/// The plant as a controller knows it. The co-simulation carries these fields on the wire (the
/// plant's `model` reply); in process they are taken from the scenario directly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Briefing {
    /// Body material.
    pub body: Body,
    /// The friction the controller is told: the pipe's own when disclosed, else the nominal one.
    pub friction: Friction,
    /// Body length L, m.
    pub length: f64,
    /// Periodic body or free ends.
    pub boundary: Boundary,
    /// Number of cells N.
    pub cells: usize,
    /// Communication step H actually used (a whole number of internal steps), s.
    pub step: f64,
    /// Time of the run's first communication point, s.
    pub start_time: f64,
    /// The run's last communication step.
    pub last_step: u64,
    /// Transient the plant's steady metrics skip, s.
    pub settle: f64,
    /// True if the friction told is the pipe's true friction (and its map may be used).
    pub disclosed: bool,
}

impl Briefing {
    /// What a controller of a run of `scenario` from t = 0 to its end is told.
    pub fn of(scenario: &Scenario) -> Result<Self, ParamError> {
        let disc = scenario.plant.discretisation()?;
        Ok(Self::at(
            scenario,
            0.0,
            disc.steps_until(scenario.t_end),
            disc.step,
        ))
    }

    /// What a controller that joins a run of `scenario` (communication step `step`) is told,
    /// the run starting at `start_time` and ending at step `last_step`.
    pub fn at(scenario: &Scenario, start_time: f64, last_step: u64, step: f64) -> Self {
        let told = scenario.plant.told();
        Self {
            body: told.body,
            friction: told.friction,
            length: told.length,
            boundary: told.boundary,
            cells: told.numerics.cells,
            step,
            start_time,
            last_step,
            settle: told.numerics.settle,
            disclosed: told.pipe.disclose,
        }
    }

    /// The controller's scenario: its own file's (task, limits, default wave, numerics) with the
    /// plant as told. When the pipe is not disclosed, the pipe map of the controller's own file
    /// is dropped too, so that no policy can read the environment from a file it shares.
    pub fn scenario(&self, own: &Scenario) -> Scenario {
        let mut s = own.clone();
        let p = &mut s.plant;
        if !self.disclosed {
            p.pipe.features.clear();
            p.pipe.disclose = false;
        }
        p.body = self.body;
        p.friction = self.friction;
        p.length = self.length;
        p.boundary = self.boundary;
        p.numerics.cells = self.cells;
        p.numerics.step = self.step;
        p.numerics.settle = self.settle;
        s
    }
}
