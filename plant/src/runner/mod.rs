//! `crawler-plant run`: the plant as a co-simulation slave, owning the clock.
//!
//! Lockstep on a fixed-step clock: the plant publishes `State(n)` at `t = t0 + n H` to the
//! controller of step n, the controller answers `Actuation(n)`, the plant applies it over
//! `[t_n, t_{n+1}]` and publishes `State(n + 1)`. What [`crate::admission`] rejects (malformed,
//! another protocol version, invalid, from another controller, stale, a duplicate, for a future
//! step) is counted, never applied; what the arrival gate refused (no seal, another run
//! instance, a replay, beyond the budget) is counted there.
//!
//! Controllers join with sealed requests ([`seat`]): the first plain request takes a run that
//! has no controller; a take-over request takes it over at a step boundary (the first at or
//! after the step it asks for), so that every step is answered by exactly one controller and the
//! states say which. A controller that leaves (its liveliness token disappears: exit, crash,
//! `kill -9`) stops the run with a checkpoint from which `crawler-plant run --resume` continues
//! bit-identically, or, with `--on-controller-lost wait`, keeps the clock at its step until
//! another controller takes over.
//!
//! The state machine reads an [`Inbox`] and writes to an [`Outbox`]; [`run`] connects them to
//! the zenoh [`Link`], tests to channels.

mod network;
mod publisher;
pub mod seat;

use std::cell::RefCell;
use std::path::PathBuf;
use std::rc::Rc;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, Sender};

use crawler_cli::Exit;
use crawler_physics::execution::{Briefing, Execution, ExecutionError, Observer, Resume, Start};
use crawler_physics::model_description::ModelDescription;
use crawler_physics::plant::Plant;
use crawler_physics::report::Report;
use crawler_physics::scenario::Scenario;
use crawler_protocol::{
    encode, Environment, FinalReport, ModelInfo, ProcessId, ProcessState, Rejections, Role, State,
    Status, PROTOCOL_VERSION,
};
use crawler_transport::Network as NetworkSpec;

use crate::access::PlantAccess;
use crate::admission::Admission;
use crate::checkpoint::Checkpoint;
use crate::link::{Control, Inbox, Link, Outbox, Topic};
use crate::wire::wire_report;

pub use publisher::applied;
use seat::{Controller as Seated, Heard, Seat};

/// Republish the current state if no valid answer came within this time.
const RESEND: Duration = Duration::from_millis(500);
/// Status is republished at least this often while running.
const STATUS_EVERY: Duration = Duration::from_secs(1);

/// Options of `crawler-plant run`.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// The scenario (ignored when resuming: the checkpoint's is used).
    pub scenario: Scenario,
    /// Where the run's processes meet.
    pub network: NetworkSpec,
    /// How long to wait for a controller to join, s.
    pub wait_timeout: Duration,
    /// How long to wait for the answer to one state, s.
    pub step_timeout: Duration,
    /// Where to write the checkpoint if the run stops early.
    pub checkpoint: PathBuf,
    /// A checkpoint to resume from.
    pub resume: Option<Checkpoint>,
    /// Episodes listed in the report.
    pub max_episodes: usize,
    /// What to do when the run's controller leaves.
    pub on_controller_lost: OnLost,
}

/// What the plant does when the run's controller leaves (its liveliness token disappears).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnLost {
    /// Stop with a checkpoint (exit code 3).
    Stop,
    /// Keep the clock at its step and wait this long for a controller to take the run over
    /// (then stop as above).
    Wait(Duration),
}

/// What the execution's controller and its observer share: who controls the run, the admission
/// of what the controllers send, and the last state published (resent, and readdressed when a
/// controller takes over a vacant run).
pub(crate) struct Shared {
    pub seat: Seat,
    pub admission: Admission,
    pub state: Option<State>,
    /// Controllers told that the run keeps its controller (each is told once).
    pub refused_joins: std::collections::BTreeSet<ProcessId>,
}

/// How a run ended.
#[derive(Debug)]
pub enum Outcome {
    /// The clock reached the end.
    Finished(Box<Report>),
    /// The run stopped early; a checkpoint was written if anything had been simulated.
    Stopped {
        /// Why.
        reason: String,
        /// The checkpoint file; `None` if no controller ever joined (nothing to resume).
        checkpoint: Option<PathBuf>,
        /// The process's exit code: [`Exit::PeerLost`], [`Exit::Timeout`],
        /// [`Exit::Interrupted`] or [`Exit::Failure`] (a discarded step).
        exit: Exit,
    },
}

/// Runs the plant until the clock reaches the end or the run stops; never panics on input.
/// `control_tx` feeds `control_rx` with controllers joining and leaving; the caller sends
/// [`Control::Interrupt`] on it on SIGINT / SIGTERM.
pub fn run(
    opts: RunOptions,
    control_tx: Sender<Control>,
    control_rx: Receiver<Control>,
) -> anyhow::Result<Outcome> {
    let id = crawler_transport::process_id();
    // this run instance: every message of the run carries it, so a kept credential does not
    // make two runs one
    let nonce = crawler_transport::participant::fresh_nonce()?;
    let mut runner = Runner::new(opts, id)?;
    let info = runner.model_info();
    let environment = runner.environment();
    // Created before the session, removed (the credential and zenoh's user file, if the plant
    // made them) when it is dropped, after the session closed.
    let access = PlantAccess::prepare(&runner.opts.network)?;
    if let Some(c) = &access.credential {
        eprintln!(
            "crawler-plant: run {} authenticated with the credential {} (the controller and the recorder read it; with --credential FILE on another host)",
            runner.run_id(),
            c.path().display()
        );
    } else {
        eprintln!(
            "crawler-plant: warning: run {} is NOT authenticated (--no-auth): any process that reaches {} can join, read and disturb it",
            runner.run_id(),
            runner.opts.network.describe()
        );
    }
    let (link, inbox) = Link::open(
        &runner.opts.network,
        (id, nonce),
        (info, environment),
        (&access.access, access.seal.clone()),
        control_tx,
        control_rx,
    )?;
    let outcome = runner.lockstep(&inbox, &link);
    // Give subscribers a moment to receive the last messages, then close cleanly.
    std::thread::sleep(Duration::from_millis(100));
    link.close();
    drop(access);
    outcome
}

/// The run's state machine: the execution (slave, clock, task, episode log), the admission of
/// the controller's answers and the bookkeeping of a checkpoint.
pub struct Runner {
    execution: Execution,
    scenario: Scenario,
    /// Set once the lockstep starts (it needs the inbox's view of the admitted senders).
    shared: Option<Rc<RefCell<Shared>>>,
    rejections: Rejections,
    opts: RunOptions,
    id: ProcessId,
}

impl Runner {
    /// The plant of `opts` (fresh, or restored from its checkpoint), ready to run as process `id`.
    pub fn new(opts: RunOptions, id: ProcessId) -> anyhow::Result<Self> {
        let (scenario, execution, rejections) = match &opts.resume {
            Some(c) => {
                let resume = Resume {
                    state: c.state.clone(),
                    log: c.log.clone(),
                    task: c.task,
                    last_step: c.last_step,
                };
                let execution = Execution::resume(&c.scenario, resume)?;
                (c.scenario.clone(), execution, c.rejections)
            }
            None => {
                let start = Start {
                    actuation: None,
                    max_episodes: opts.max_episodes,
                };
                let execution = Execution::new(&opts.scenario, start)?;
                (opts.scenario.clone(), execution, Rejections::default())
            }
        };
        Ok(Self {
            shared: None,
            rejections,
            execution,
            scenario,
            opts,
            id,
        })
    }

    /// What controllers are told ([`Briefing`]: nominal friction and no map unless the pipe is
    /// disclosed), answered to `model` queries.
    pub fn model_info(&self) -> ModelInfo {
        let plant = self.plant();
        let b = Briefing::at(
            &self.scenario,
            plant.start_time(),
            self.execution.last_step(),
            plant.step_length(),
        );
        let md = ModelDescription::new(&self.scenario.plant.told());
        ModelInfo {
            v: PROTOCOL_VERSION,
            run: self.opts.network.run_id.clone(),
            cells: b.cells as u64,
            length: b.length,
            step: b.step,
            start_time: b.start_time,
            last_step: b.last_step,
            area: b.body.area,
            density: b.body.density,
            youngs_modulus: b.body.youngs_modulus,
            viscous: b.friction.viscous,
            dry: b.friction.dry,
            eps: b.friction.eps,
            n_f: b.friction.n_f,
            settle: b.settle,
            model_description: md.to_json(),
            boundary: b.boundary.as_str().to_string(),
            disclosed: b.disclosed,
        }
    }

    /// The pipe's true friction, answered to the recorder's `environment` queries (whatever
    /// controllers are told).
    pub fn environment(&self) -> Environment {
        let p = &self.scenario.plant;
        crate::environment::environment(self.run_id(), p.pipe.start, &p.friction_map())
    }

    fn plant(&self) -> &Plant {
        self.execution.plant()
    }

    fn run_id(&self) -> &str {
        &self.opts.network.run_id
    }

    /// Everything rejected so far: by admission, and at arrival.
    fn rejected(&self, inbox: &Inbox) -> Rejections {
        match &self.shared {
            Some(s) => rejected(&s.borrow().admission, inbox),
            None => add_arrivals(self.rejections, inbox),
        }
    }

    fn status(
        &self,
        out: &impl Outbox,
        state: ProcessState,
        message: &str,
        step: u64,
        rejected: Rejections,
    ) {
        publish_status(out, &self.id, (state, message, step), rejected, None);
    }

    fn ever_joined(&self) -> bool {
        self.shared
            .as_ref()
            .is_some_and(|s| s.borrow().seat.ever_joined())
    }

    fn stop(
        &self,
        inbox: &Inbox,
        out: &impl Outbox,
        reason: String,
        exit: Exit,
    ) -> anyhow::Result<Outcome> {
        let resume = self.execution.resume_point();
        let ckpt = Checkpoint {
            run_id: self.run_id().to_string(),
            scenario: self.scenario.clone(),
            last_step: resume.last_step,
            state: resume.state,
            log: resume.log,
            rejections: self.rejected(inbox),
            reason: reason.clone(),
            task: resume.task,
        };
        // Before a controller joins nothing has been simulated: no checkpoint (a resumed run's
        // own checkpoint stays as it was).
        let path = if self.ever_joined() {
            let path = self.opts.checkpoint.clone();
            ckpt.save(&path)?;
            Some(path)
        } else {
            None
        };
        let state = if exit == Exit::Interrupted {
            ProcessState::Stopped
        } else {
            ProcessState::Failed
        };
        let message = match &path {
            Some(p) => format!("{reason}; checkpoint written to {}", p.display()),
            None => format!("{reason}; nothing simulated, no checkpoint"),
        };
        self.status(
            out,
            state,
            &message,
            self.plant().macro_step(),
            self.rejected(inbox),
        );
        Ok(Outcome::Stopped {
            reason,
            checkpoint: path,
            exit,
        })
    }

    /// Waits for the run's first controller: a plain join request, or a take-over due at the
    /// first step (later take-overs are kept for their step).
    fn wait_for_controller(
        &mut self,
        inbox: &Inbox,
        out: &impl Outbox,
    ) -> Result<(), anyhow::Result<Outcome>> {
        let what = format!(
            "waiting for a controller to join {} (start one with: crawler-controller run --run-id {}); timeout {:.0} s",
            self.opts.network.describe(),
            self.run_id(),
            self.opts.wait_timeout.as_secs_f64()
        );
        eprintln!("crawler-plant: {what}");
        self.status(
            out,
            ProcessState::Waiting,
            &what,
            self.plant().macro_step(),
            self.rejected(inbox),
        );
        let first = self.plant().macro_step();
        let shared = self.shared.clone().expect("the lockstep set it up");
        let deadline = Instant::now() + self.opts.wait_timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            crossbeam_channel::select! {
                recv(inbox.control) -> ev => match ev {
                    Ok(Control::Interrupt) => {
                        return Err(self.stop(
                            inbox,
                            out,
                            "interrupted while waiting for a controller".into(),
                            Exit::Interrupted,
                        ))
                    }
                    Ok(Control::ControllerDown(id)) => {
                        shared.borrow_mut().seat.left(&id);
                    }
                    Err(_) => {}
                },
                recv(inbox.joins) -> m => {
                    let Ok(m) = m else { continue };
                    let m = m.get();
                    let mut s = shared.borrow_mut();
                    let join = s.admission.join(&m.bytes, &m.header.sender);
                    match join {
                        Err(r) => network::warn(&r),
                        Ok(j) => {
                            let heard = s.seat.hear(
                                Seated { id: m.header.sender, policy: j.policy },
                                j.take_over,
                                first,
                            );
                            match heard {
                                Heard::Admitted(_) => return Ok(()),
                                Heard::Requested { at, again: false } => eprintln!(
                                    "crawler-plant: controller {} takes the run over at step {at}",
                                    m.header.sender
                                ),
                                _ => {}
                            }
                        }
                    }
                },
                default(left) => {
                    let reason = format!(
                        "no controller joined within {:.0} s",
                        self.opts.wait_timeout.as_secs_f64()
                    );
                    return Err(self.stop(inbox, out, reason, Exit::Timeout));
                }
            }
        }
    }

    /// Waits for a controller, then steps in lockstep with the run's controllers until the end
    /// of the run or a stop (controller lost, timeout, interrupt, discarded step).
    pub fn lockstep(&mut self, inbox: &Inbox, out: &impl Outbox) -> anyhow::Result<Outcome> {
        let p = &self.scenario.plant;
        let shared = Rc::new(RefCell::new(Shared {
            seat: Seat::new(inbox.controllers.clone()),
            admission: Admission::new(p.numerics.cells, p.length, p.boundary, self.rejections),
            state: None,
            refused_joins: Default::default(),
        }));
        self.shared = Some(shared.clone());
        if let Err(outcome) = self.wait_for_controller(inbox, out) {
            return outcome;
        }
        let last_step = self.execution.last_step();
        let joined = shared.borrow().seat.joined().cloned().expect("admitted");
        eprintln!(
            "crawler-plant: controller {joined} joined run {}; stepping to step {last_step}",
            self.run_id()
        );
        let first = self.plant().macro_step();
        let started = Instant::now();
        let bar = crawler_cli::progress::bar(last_step, "co-simulating");
        bar.set_position(first);
        self.status(
            out,
            ProcessState::Running,
            &format!("controller {joined} joined"),
            first,
            self.rejected(inbox),
        );
        let mut publisher = publisher::Publisher {
            out,
            inbox,
            shared: shared.clone(),
            id: self.id,
            tension: Vec::with_capacity(self.plant().cells()),
            bar: &bar,
            last_status: Instant::now(),
            announced: false,
        };
        publisher.publish_state(self.execution.plant(), last_step);
        let mut network = network::Network {
            inbox,
            out,
            shared: shared.clone(),
            id: self.id,
            step_timeout: self.opts.step_timeout,
            on_lost: self.opts.on_controller_lost,
            last_answer: Instant::now(),
        };
        let observers: &mut [&mut dyn Observer] = &mut [&mut publisher];
        let result = self.execution.run(&mut network, observers);
        let state_bytes = shared
            .borrow()
            .state
            .as_ref()
            .map_or(0, |s| encode(s).len());
        match result {
            Ok(()) => {}
            Err(ExecutionError::Stopped(Stop { reason, exit })) => {
                bar.abandon();
                return self.stop(inbox, out, reason, exit);
            }
            Err(ExecutionError::Discarded { step, reason, .. }) => {
                bar.abandon();
                let reason = format!("step {step} discarded: {reason}");
                return self.stop(inbox, out, reason, Exit::Failure);
            }
            Err(ExecutionError::Refused { source, .. }) => {
                // Admission checked everything set_* checks, so this is a bug, not bad input.
                anyhow::bail!("internal error: validated actuation refused by the slave: {source}");
            }
            Err(e) => anyhow::bail!("{e}"),
        }
        bar.finish_and_clear();
        let last_step = self.execution.last_step();
        let steps = last_step - first;
        let secs = started.elapsed().as_secs_f64();
        eprintln!(
            "crawler-plant: lockstep: {steps} steps in {secs:.3} s ({:.0} steps/s, {state_bytes} bytes per state)",
            steps as f64 / secs
        );
        let history = shared.borrow().seat.history().to_vec();
        if history.len() > 1 {
            let turns: Vec<String> = history
                .iter()
                .enumerate()
                .map(|(i, t)| {
                    let end = history.get(i + 1).map_or(last_step, |next| next.first);
                    format!(
                        "{} steps {} to {}",
                        t.controller,
                        t.first,
                        end.saturating_sub(1)
                    )
                })
                .collect();
            eprintln!("crawler-plant: controllers: {}", turns.join(", "));
        }
        self.finish(inbox, out)
    }

    /// The report, on the wire in the plant's `finished` status and as the outcome.
    fn finish(&self, inbox: &Inbox, out: &impl Outbox) -> anyhow::Result<Outcome> {
        let rep = self.execution.report();
        let report = match &rep {
            Ok(r) => match wire_report(r) {
                Ok(w) => Some(w),
                Err(e) => {
                    eprintln!("crawler-plant: the final report cannot go on the wire: {e}");
                    None
                }
            },
            Err(_) => None,
        };
        let rejected = self.rejected(inbox);
        let last_step = self.execution.last_step();
        let message = format!(
            "finished at step {last_step}; rejected messages: {}",
            rejected.total()
        );
        publish_status(
            out,
            &self.id,
            (ProcessState::Finished, &message, last_step),
            rejected,
            report,
        );
        if rejected.total() > 0 {
            eprintln!("crawler-plant: rejected messages: {rejected:?}");
        }
        let dropped = crawler_transport::reassembly::dropped();
        if dropped > 0 {
            eprintln!(
                "crawler-plant: {dropped} messages larger than zenoh reassembles for this run were dropped on arrival"
            );
        }
        Ok(Outcome::Finished(Box::new(rep?)))
    }
}

/// `r` with what the arrival gate refused added: an oversized payload counts as malformed, one
/// without a valid envelope or seal or from a sender that may not send there as foreign, one of
/// another run instance (or before the instance was known, which the plant never is) as
/// `other_run`, a replay as `replayed`, one beyond a budget as overflow.
fn add_arrivals(r: Rejections, inbox: &Inbox) -> Rejections {
    let a = &inbox.refused;
    Rejections {
        malformed: r.malformed + a.oversize(),
        foreign: r.foreign + a.unsealed() + a.foreign(),
        other_run: r.other_run + a.other_run() + a.early(),
        replayed: r.replayed + a.replayed(),
        overflow: r.overflow + a.overflow(),
        ..r
    }
}

/// Everything rejected so far: by `admission`, and at arrival.
pub(crate) fn rejected(admission: &Admission, inbox: &Inbox) -> Rejections {
    add_arrivals(admission.rejections(), inbox)
}

/// Publishes the plant's status `(state, message, step)`.
pub(crate) fn publish_status(
    out: &impl Outbox,
    id: &ProcessId,
    (state, message, step): (ProcessState, &str, u64),
    rejected: Rejections,
    report: Option<FinalReport>,
) {
    let s = Status {
        v: PROTOCOL_VERSION,
        role: Role::Plant,
        id: id.to_string(),
        state,
        message: message.into(),
        step,
        rejected,
        report,
    };
    out.put(Topic::Status, encode(&s));
}

/// Why the network controller stopped the run, and the exit code it means.
pub(crate) struct Stop {
    reason: String,
    exit: Exit,
}
