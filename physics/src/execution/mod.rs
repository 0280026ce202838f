//! The execution: the one loop that drives a plant through a run, as libcosim's execution drives
//! its slaves.
//!
//! Roles:
//! - the **slave** ([`Slave`]): the plant, stepped by whole communication steps `H`;
//! - the **execution** ([`Execution`]): owns the clock and the loop. It instantiates the slave
//!   from a scenario (or restores it from a checkpoint), sets the stress limit, follows the task,
//!   keeps the episode log and writes the report;
//! - the **controller** ([`Controller`]): called exactly once per communication step, before the
//!   step, with that step's [`Observation`]; it answers the [`Actuation`] applied over the step
//!   (a policy in process, or the network in the co-simulation node); [`Hold`], the controller of
//!   an open-loop run, never acts and is not asked;
//! - **observers** ([`Observer`]): called after every step with the plant at the step's end
//!   (progress, the node's publisher, ...); they can watch, not act.
//!
//! Every route (simulate, the closed loop, the sweep's policy run, the co-simulation node, the
//! FMU's importers aside, Python) runs this loop, so the same inputs give the same bits.
//! What a controller is told about the plant is decided in one place, [`Briefing::of`].
//!
//! No network, terminal or clock here: a controller that waits on the network lives in the
//! program that has one.

mod briefing;

pub use briefing::Briefing;

use std::convert::Infallible;

use crate::plant::{Plant, PlantState};
use crate::report::{mean_position, report_with_task, EpisodeLog, Report, ReportError};
use crate::scenario::Scenario;
use crate::slave::{Slave, SlaveError, StepStatus};
use crate::task::TaskTracker;
use crate::wave::Wave;

/// What a controller sees at the start of each communication step.
#[derive(Debug, Clone, Copy)]
pub struct Observation<'a> {
    /// Communication step number n (the plant is at time t0 + n H).
    pub step: u64,
    /// Time, s.
    pub time: f64,
    /// Displacement at the nodes, m.
    pub u: &'a [f64],
    /// Velocity at the nodes, m/s.
    pub vel: &'a [f64],
    /// Tension at the half nodes, N.
    pub tension: &'a [f64],
    /// Nodes held by static friction.
    pub stuck: &'a [bool],
    /// Mean speed of the body over the last step, m/s.
    pub mean_speed: f64,
    /// Input power of the actuator over the last step, W.
    pub input_power: f64,
}

/// What a controller commands for the next communication step.
#[derive(Debug, Clone, PartialEq)]
pub enum Actuation {
    /// A travelling wave, evaluated continuously by the plant over the step.
    Wave(Wave),
    /// Muscle force at the half nodes, N (one value per cell), held over the step.
    Field(Vec<f64>),
}

impl Actuation {
    /// Hands the actuation to the slave (applied at its next step).
    pub fn apply(&self, slave: &mut Slave) -> Result<(), SlaveError> {
        match self {
            Actuation::Wave(w) => slave.set_wave(*w),
            Actuation::Field(f) => slave.set_field(f),
        }
    }
}

/// The controller of an execution: asked once per communication step, before the step.
pub trait Controller {
    /// Why a controller may stop a run (a network controller that went away); `Infallible` for a
    /// policy in process.
    type Stop;

    /// The actuation over the step that starts at `obs` (`None`: keep what the plant applies).
    fn act(&mut self, obs: &Observation<'_>) -> Result<Option<Actuation>, Self::Stop>;

    /// False for a controller that never acts ([`Hold`]): the execution then neither builds the
    /// observation nor calls [`Controller::act`] (an open-loop run pays nothing for a controller).
    fn acts(&self) -> bool {
        true
    }
}

/// A controller that never acts: the plant keeps the actuation it started with.
#[derive(Debug, Clone, Copy, Default)]
pub struct Hold;

impl Controller for Hold {
    type Stop = Infallible;

    fn act(&mut self, _: &Observation<'_>) -> Result<Option<Actuation>, Infallible> {
        Ok(None)
    }

    fn acts(&self) -> bool {
        false
    }
}

/// What an observer is shown after each communication step.
#[derive(Debug, Clone, Copy)]
pub struct Stepped<'a> {
    /// The step just taken (the plant is now at step `step + 1`).
    pub step: u64,
    /// The plant at the step's end.
    pub plant: &'a Plant,
    /// The run's task so far.
    pub task: &'a TaskTracker,
    /// The run's last communication step (it moves earlier when the task ends the run).
    pub last_step: u64,
}

/// Watches the run after each communication step.
pub trait Observer {
    /// Called after every step.
    fn stepped(&mut self, _: &Stepped<'_>) {}
}

/// A progress callback as an observer: told `(communication steps done, steps in the run)` every
/// `every` steps and when the run's last step is taken.
pub struct Progress<F: FnMut(u64, u64)> {
    /// Steps between two calls.
    pub every: u64,
    /// The callback.
    pub report: F,
}

impl<F: FnMut(u64, u64)> Observer for Progress<F> {
    fn stepped(&mut self, s: &Stepped<'_>) {
        let done = s.step + 1;
        if s.step.is_multiple_of(self.every.max(1)) || done >= s.last_step {
            (self.report)(done, s.last_step);
        }
    }
}

/// Why a run stopped before its end.
#[derive(Debug, thiserror::Error)]
pub enum ExecutionError<S = Infallible> {
    /// The slave refused a call (instantiation, initialisation, a step).
    #[error(transparent)]
    Slave(#[from] SlaveError),
    /// The controller's actuation was refused by the plant.
    #[error("step {step}: actuation refused: {source}")]
    Refused {
        /// The communication step.
        step: u64,
        /// Why.
        source: SlaveError,
    },
    /// A step was discarded (the state became non-finite); the plant is at its start.
    #[error("step {step} discarded at t = {time} s: {reason}")]
    Discarded {
        /// The communication step.
        step: u64,
        /// Time of the last good state, s.
        time: f64,
        /// Why.
        reason: String,
    },
    /// The controller stopped the run.
    #[error("the controller stopped the run")]
    Stopped(S),
    /// The run ended without a report (no steady window).
    #[error(transparent)]
    Report(#[from] ReportError),
}

/// Where an execution starts.
#[derive(Debug, Clone, Default)]
pub struct Start {
    /// Actuation set in initialisation mode, before the first step (`simulate` drives the plant
    /// with the scenario's wave from t = 0 this way); `None`: the controller's first answer.
    pub actuation: Option<Actuation>,
    /// Episodes kept for the report's list (all are counted).
    pub max_episodes: usize,
}

/// What a run needs to continue where it stopped: a checkpoint's contents.
#[derive(Debug, Clone)]
pub struct Resume {
    /// The plant's state.
    pub state: PlantState,
    /// The episode log so far.
    pub log: EpisodeLog,
    /// The task so far.
    pub task: TaskTracker,
    /// The run's last communication step.
    pub last_step: u64,
}

/// One run of a plant: the slave, its clock's end, the task and the episode log.
pub struct Execution {
    slave: Slave,
    name: String,
    end_run: bool,
    last_step: u64,
    task: TaskTracker,
    log: EpisodeLog,
    tension: Vec<f64>,
}

impl Execution {
    /// A new run of `scenario` from t = 0 to its `t_end` (the first communication point at or
    /// after it), with its stress limit and task.
    pub fn new(scenario: &Scenario, start: Start) -> Result<Self, SlaveError> {
        let mut slave = Slave::instantiate(&scenario.name, scenario.plant.clone())?;
        slave.enter_initialization_mode(0.0, None)?;
        if let Some(a) = &start.actuation {
            a.apply(&mut slave)?;
        }
        slave.exit_initialization_mode()?;
        let last_step = scenario.plant.discretisation()?.steps_until(scenario.t_end);
        Self::with_slave(
            scenario,
            slave,
            EpisodeLog::new(start.max_episodes),
            None,
            last_step,
        )
    }

    /// A run of `scenario` continued from `resume` (bit-identical to the run never stopped).
    pub fn resume(scenario: &Scenario, resume: Resume) -> Result<Self, SlaveError> {
        let mut slave = Slave::instantiate(&scenario.name, scenario.plant.clone())?;
        slave.enter_initialization_mode(0.0, None)?;
        slave.exit_initialization_mode()?;
        slave.set_state(&resume.state)?;
        Self::with_slave(
            scenario,
            slave,
            resume.log,
            Some(resume.task),
            resume.last_step,
        )
    }

    fn with_slave(
        scenario: &Scenario,
        mut slave: Slave,
        log: EpisodeLog,
        task: Option<TaskTracker>,
        last_step: u64,
    ) -> Result<Self, SlaveError> {
        slave.set_stress_limit(Some(scenario.task.sigma_max))?;
        let plant = slave.plant();
        let task = task
            .unwrap_or_else(|| TaskTracker::new(scenario.task, plant.time(), mean_position(plant)));
        Ok(Self {
            tension: Vec::with_capacity(plant.cells()),
            slave,
            name: scenario.name.clone(),
            end_run: scenario.task.end_run,
            last_step,
            task,
            log,
        })
    }

    /// The plant.
    pub fn plant(&self) -> &Plant {
        self.slave.plant()
    }

    /// The slave (for its state and description).
    pub fn slave(&self) -> &Slave {
        &self.slave
    }

    /// The run's last communication step (earlier once the task ended the run).
    pub fn last_step(&self) -> u64 {
        self.last_step
    }

    /// True when the clock has reached the run's last step.
    pub fn finished(&self) -> bool {
        self.plant().macro_step() >= self.last_step
    }

    /// The task so far.
    pub fn task(&self) -> &TaskTracker {
        &self.task
    }

    /// The episode log so far.
    pub fn log(&self) -> &EpisodeLog {
        &self.log
    }

    /// What a run continued from here needs.
    pub fn resume_point(&self) -> Resume {
        Resume {
            state: self.slave.get_state(),
            log: self.log.clone(),
            task: self.task,
            last_step: self.last_step,
        }
    }

    /// The observation of the plant's current state (what the controller is shown).
    pub fn observation(&mut self) -> Observation<'_> {
        self.slave.plant().tension_into(&mut self.tension);
        observation_of(self.slave.plant(), &self.tension)
    }

    /// [`Self::observation`] with its tension computed into the caller's `tension` instead of
    /// the run's own buffer (a caller stepping many runs on one thread keeps one buffer, warm in
    /// its cache, for all of them).
    pub fn observation_with<'a>(&'a self, tension: &'a mut Vec<f64>) -> Observation<'a> {
        self.slave.plant().tension_into(tension);
        observation_of(self.slave.plant(), tension)
    }

    /// Applies `actuation` (if any) and takes one communication step; then follows the task,
    /// keeps the episodes and shows the step to `observers`.
    pub fn step<S>(
        &mut self,
        actuation: Option<&Actuation>,
        observers: &mut [&mut dyn Observer],
    ) -> Result<(), ExecutionError<S>> {
        let n = self.plant().macro_step();
        if let Some(a) = actuation {
            a.apply(&mut self.slave)
                .map_err(|source| ExecutionError::Refused { step: n, source })?;
        }
        let h = self.plant().step_length();
        match self.slave.do_step(self.plant().time(), h) {
            StepStatus::Ok => {}
            StepStatus::Discard {
                last_successful_time,
                reason,
            } => {
                return Err(ExecutionError::Discarded {
                    step: n,
                    time: last_successful_time,
                    reason,
                })
            }
            StepStatus::Error(e) => return Err(e.into()),
        }
        let plant = self.slave.plant();
        self.log.observe(plant);
        let decided = self
            .task
            .observe(plant.time(), h, mean_position(plant), &plant.outputs());
        if self.end_run && decided.is_some() {
            self.last_step = self.last_step.min(n + 1);
        }
        let stepped = Stepped {
            step: n,
            plant,
            task: &self.task,
            last_step: self.last_step,
        };
        for o in observers.iter_mut() {
            o.stepped(&stepped);
        }
        Ok(())
    }

    /// Steps under `controller` until the run's last step (or the task ends the run).
    pub fn run<C: Controller>(
        &mut self,
        controller: &mut C,
        observers: &mut [&mut dyn Observer],
    ) -> Result<(), ExecutionError<C::Stop>> {
        while !self.finished() {
            let actuation = if controller.acts() {
                controller
                    .act(&self.observation())
                    .map_err(ExecutionError::Stopped)?
            } else {
                None
            };
            self.step(actuation.as_ref(), observers)?;
        }
        Ok(())
    }

    /// The report of the run so far (its task included).
    pub fn report(&self) -> Result<Report, ReportError> {
        report_with_task(&self.name, self.plant(), &self.log, Some(&self.task))
    }
}

/// What a controller is shown of `plant`'s current state, with `tension` (one value per half
/// node, N).
fn observation_of<'a>(plant: &'a Plant, tension: &'a [f64]) -> Observation<'a> {
    let out = plant.outputs();
    Observation {
        step: plant.macro_step(),
        time: plant.time(),
        u: plant.displacement(),
        vel: plant.velocity(),
        tension,
        stuck: plant.stuck(),
        mean_speed: out.mean_speed,
        input_power: out.input_power,
    }
}
