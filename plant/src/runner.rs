//! `crawler-plant run`: the plant as a co-simulation slave, owning the clock.
//!
//! Lockstep on a fixed-step clock: the plant publishes `State(n)` at `t = t0 + n H`, the controller
//! that joined the run answers `Actuation(n)`, the plant applies it over `[t_n, t_{n+1}]` and
//! publishes `State(n + 1)`. What [`crate::admission`] rejects (malformed, another protocol
//! version, invalid, from another controller, stale, a duplicate, for a future step) is counted,
//! never applied. A controller that leaves (its liveliness token disappears: exit, crash,
//! `kill -9`) stops the run with a checkpoint from which `crawler-plant run --resume` continues
//! bit-identically.
//!
//! The state machine reads an [`Inbox`] and writes to an [`Outbox`]; [`run`] connects them to
//! the zenoh [`Link`], tests to channels.

use std::cell::RefCell;
use std::path::PathBuf;
use std::rc::Rc;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, Sender};

use crawler_cli::Exit;
use crawler_facts::Metric;
use crawler_physics::execution::{
    Actuation, Briefing, Controller, Execution, ExecutionError, Observation, Observer, Resume,
    Start, Stepped,
};
use crawler_physics::model_description::ModelDescription;
use crawler_physics::plant::{Drive, Plant};
use crawler_physics::report::Report;
use crawler_physics::scenario::Scenario;
use crawler_protocol::{
    encode, Applied, Environment, EpisodeMsg, Events, FinalReport, Metrics as MetricsMsg,
    ModelInfo, ProcessState, Rejections, Role, RunLimits, State, Status, WaveMsg, PROTOCOL_VERSION,
};
use crawler_transport::Network as NetworkSpec;

use crate::access::PlantAccess;
use crate::admission::{Admission, Rejection};
use crate::checkpoint::Checkpoint;
use crate::link::{Control, Inbox, Link, Outbox, Topic};
use crate::wire::wire_report;

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
    let mut runner = Runner::new(opts, id.clone())?;
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
        &id,
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
    admission: Rc<RefCell<Admission>>,
    joined: Option<String>,
    opts: RunOptions,
    id: String,
}

impl Runner {
    /// The plant of `opts` (fresh, or restored from its checkpoint), ready to run as process `id`.
    pub fn new(opts: RunOptions, id: String) -> anyhow::Result<Self> {
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
        let p = &scenario.plant;
        Ok(Self {
            admission: Rc::new(RefCell::new(Admission::new(
                p.numerics.cells,
                p.length,
                p.boundary,
                rejections,
            ))),
            execution,
            scenario,
            joined: None,
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

    /// Everything rejected so far: by admission, and at arrival (an oversized payload counts as
    /// malformed, an unsealed one as foreign, one beyond the inbox's budget as overflow).
    fn rejected(&self, inbox: &Inbox) -> Rejections {
        rejected(&self.admission.borrow(), inbox)
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
        let path = match self.joined {
            Some(_) => {
                let path = self.opts.checkpoint.clone();
                ckpt.save(&path)?;
                Some(path)
            }
            None => None,
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

    fn wait_for_controller(
        &mut self,
        inbox: &Inbox,
        out: &impl Outbox,
    ) -> Result<String, anyhow::Result<Outcome>> {
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
        let deadline = Instant::now() + self.opts.wait_timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match inbox.control.recv_timeout(left) {
                Ok(Control::ControllerUp(id)) => return Ok(id),
                Ok(Control::ControllerDown(_)) => {}
                Ok(Control::Interrupt) => {
                    return Err(self.stop(
                        inbox,
                        out,
                        "interrupted while waiting for a controller".into(),
                        Exit::Interrupted,
                    ))
                }
                Err(_) => {
                    let reason = format!(
                        "no controller joined within {:.0} s",
                        self.opts.wait_timeout.as_secs_f64()
                    );
                    return Err(self.stop(inbox, out, reason, Exit::Timeout));
                }
            }
        }
    }

    /// Waits for a controller, then steps in lockstep with it until the end of the run or a
    /// stop (controller lost, timeout, interrupt, discarded step).
    pub fn lockstep(&mut self, inbox: &Inbox, out: &impl Outbox) -> anyhow::Result<Outcome> {
        let joined = match self.wait_for_controller(inbox, out) {
            Ok(id) => id,
            Err(outcome) => return outcome,
        };
        let last_step = self.execution.last_step();
        eprintln!(
            "crawler-plant: controller {joined} joined run {}; stepping to step {last_step}",
            self.run_id()
        );
        self.joined = Some(joined.clone());
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
        let state = Rc::new(RefCell::new(Vec::new()));
        let mut publisher = Publisher {
            out,
            inbox,
            admission: self.admission.clone(),
            id: &self.id,
            joined: &joined,
            state: state.clone(),
            tension: Vec::with_capacity(self.plant().cells()),
            bar: &bar,
            last_status: Instant::now(),
            announced: false,
        };
        publisher.publish_state(self.execution.plant(), last_step);
        let mut network = JoinedController {
            inbox,
            out,
            admission: self.admission.clone(),
            joined: &joined,
            step_timeout: self.opts.step_timeout,
            state,
            last_answer: Instant::now(),
        };
        let observers: &mut [&mut dyn Observer] = &mut [&mut publisher];
        let result = self.execution.run(&mut network, observers);
        let state_bytes = network.state.borrow().len();
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
            "finished at step {last_step}; rejected actuation: {}",
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
            eprintln!("crawler-plant: rejected actuation messages: {rejected:?}");
        }
        Ok(Outcome::Finished(Box::new(rep?)))
    }
}

/// Everything rejected so far: by `admission`, and at arrival (an oversized payload counts as
/// malformed, an unsealed one as foreign, one beyond the inbox's budget as overflow).
fn rejected(admission: &Admission, inbox: &Inbox) -> Rejections {
    let r = admission.rejections();
    Rejections {
        malformed: r.malformed + inbox.refused.oversize(),
        foreign: r.foreign + inbox.refused.unsealed(),
        overflow: r.overflow + inbox.overflow(),
        ..r
    }
}

/// Publishes the plant's status `(state, message, step)`.
fn publish_status(
    out: &impl Outbox,
    id: &str,
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
struct Stop {
    reason: String,
    exit: Exit,
}

/// The joined controller as the execution's controller: waits for its answer to each state
/// (the state itself is published by the [`Publisher`]), resending the state while none comes.
struct JoinedController<'a, O: Outbox> {
    inbox: &'a Inbox,
    out: &'a O,
    admission: Rc<RefCell<Admission>>,
    joined: &'a str,
    step_timeout: Duration,
    /// The last state published, encoded (resent from here).
    state: Rc<RefCell<Vec<u8>>>,
    /// When the joined controller's last valid answer arrived: how fast a lost controller is
    /// noticed is measured from there.
    last_answer: Instant,
}

impl<O: Outbox> Controller for JoinedController<'_, O> {
    type Stop = Stop;

    fn act(&mut self, obs: &Observation<'_>) -> Result<Option<Actuation>, Stop> {
        let n = obs.step;
        let joined = self.joined;
        let deadline = Instant::now() + self.step_timeout;
        let mut resend = Instant::now() + RESEND;
        loop {
            let now = Instant::now();
            if now >= deadline {
                return Err(Stop {
                    reason: format!(
                        "controller {joined} did not answer step {n} within {:.1} s",
                        self.step_timeout.as_secs_f64()
                    ),
                    exit: Exit::Timeout,
                });
            }
            let wake = resend.min(deadline);
            crossbeam_channel::select! {
                recv(self.inbox.control) -> ev => match ev {
                    Ok(Control::ControllerDown(id)) if id == joined => {
                        return Err(Stop {
                            reason: format!(
                                "controller {joined} left the run at step {n} (its liveliness token disappeared {} ms after its last answer)",
                                self.last_answer.elapsed().as_millis()
                            ),
                            exit: Exit::PeerLost,
                        });
                    }
                    Ok(Control::Interrupt) => {
                        return Err(Stop {
                            reason: format!("interrupted at step {n}"),
                            exit: Exit::Interrupted,
                        });
                    }
                    Ok(Control::ControllerUp(id)) if id != joined => {
                        eprintln!("crawler-plant: another controller {id} appeared; the run keeps {joined} and rejects the others");
                    }
                    _ => {}
                },
                recv(self.inbox.data) -> bytes => {
                    let Ok(bytes) = bytes else { continue };
                    let admitted = self.admission.borrow_mut().admit(bytes.get(), n, joined);
                    match admitted {
                        Ok(command) => {
                            self.last_answer = Instant::now();
                            return Ok(Some(command));
                        }
                        Err(rejection) => warn(&rejection),
                    }
                },
                default(wake.saturating_duration_since(now)) => {
                    if Instant::now() >= resend {
                        self.out.put(Topic::State, self.state.borrow().clone());
                        resend = Instant::now() + RESEND;
                    }
                },
            }
        }
    }
}

fn warn(rejection: &Rejection) {
    if rejection.worth_reporting() {
        eprintln!(
            "crawler-plant: rejected actuation ({:?}, #{}): {}",
            rejection.kind, rejection.count, rejection.reason
        );
    }
}

/// Publishes what each step produced (its episodes, the blocks it closed, the next state) and
/// the progress, as an observer of the execution.
struct Publisher<'a, O: Outbox> {
    out: &'a O,
    inbox: &'a Inbox,
    admission: Rc<RefCell<Admission>>,
    id: &'a str,
    joined: &'a str,
    /// The last state published, encoded (the network controller resends it).
    state: Rc<RefCell<Vec<u8>>>,
    tension: Vec<f64>,
    bar: &'a crawler_cli::progress::ProgressBar,
    last_status: Instant,
    /// True once the end of the run by its task was said.
    announced: bool,
}

impl<O: Outbox> Publisher<'_, O> {
    fn publish_state(&mut self, plant: &Plant, last_step: u64) {
        let n = plant.macro_step();
        self.tension.clear();
        self.tension.extend(plant.tension());
        let out = plant.outputs();
        let s = State {
            v: PROTOCOL_VERSION,
            step: n,
            time: plant.time(),
            controller: self.joined.to_string(),
            u: plant.displacement().to_vec(),
            vel: plant.velocity().to_vec(),
            tension: self.tension.clone(),
            stuck: plant.stuck().to_vec(),
            mean_speed: out.mean_speed,
            input_power: out.input_power,
            last: n >= last_step,
            applied: applied(plant),
        };
        let bytes = encode(&s);
        self.out.put(Topic::State, bytes.clone());
        *self.state.borrow_mut() = bytes;
    }

    fn publish_step_outputs(&self, plant: &Plant) {
        let n = plant.macro_step();
        // At most N episodes per message, the run's legal size (rarely more than one message).
        let per_message = RunLimits::new(plant.cells()).episodes_per_message();
        for chunk in plant.episodes().chunks(per_message) {
            let ev = Events {
                v: PROTOCOL_VERSION,
                step: n,
                time: plant.time(),
                episodes: chunk
                    .iter()
                    .map(|e| EpisodeMsg {
                        node: e.node,
                        start: e.start,
                        end: e.end,
                        duration: e.duration,
                        direction: e.direction,
                    })
                    .collect(),
            };
            self.out.put(Topic::Events, encode(&ev));
        }
        for b in plant.closed_blocks() {
            let m = b.sums.metrics(
                plant.cells(),
                plant.discretisation().dt,
                plant.params().body.area,
                plant.block_length(),
            );
            let msg = MetricsMsg {
                v: PROTOCOL_VERSION,
                step: n,
                block: b.index,
                steady: b.steady,
                start: m.start,
                end: m.end,
                values: m.values(),
                clock: b.clock,
            };
            if msg.values.get(Metric::Velocity).is_some() && msg.values.get(Metric::Power).is_some()
            {
                self.out.put(Topic::Metrics, encode(&msg));
            }
        }
    }
}

impl<O: Outbox> Observer for Publisher<'_, O> {
    fn stepped(&mut self, s: &Stepped<'_>) {
        let n = s.step;
        self.publish_step_outputs(s.plant);
        self.publish_state(s.plant, s.last_step);
        if n.is_multiple_of(64) {
            self.bar.set_position(n + 1);
        }
        if self.last_status.elapsed() >= STATUS_EVERY {
            publish_status(
                self.out,
                self.id,
                (
                    ProcessState::Running,
                    &format!("step {} of {}", n + 1, s.last_step),
                    n + 1,
                ),
                rejected(&self.admission.borrow(), self.inbox),
                None,
            );
            self.last_status = Instant::now();
        }
        let ended_by_task = s.task.task.end_run && s.last_step == n + 1;
        if let Some(outcome) = s
            .task
            .decided()
            .filter(|_| ended_by_task && !self.announced)
        {
            eprintln!(
                "crawler-plant: task {} at step {}; the run ends there",
                outcome.as_str(),
                n + 1
            );
            self.announced = true;
        }
    }
}

/// What `plant` applied over its last communication step, as the protocol says it: the wave it
/// is driven by, or its muscle-force field (N, one value per cell); `None` before any actuation
/// (the first state of a run).
pub fn applied(plant: &Plant) -> Option<Applied> {
    match plant.drive() {
        Drive::Idle => None,
        Drive::Wave(w) => Some(Applied {
            wave: Some(WaveMsg {
                f0: w.f0,
                k: w.k,
                omega: w.omega,
                phase: w.phase,
            }),
            field: None,
        }),
        Drive::Field => Some(Applied {
            wave: None,
            field: Some(plant.field().to_vec()),
        }),
    }
}
