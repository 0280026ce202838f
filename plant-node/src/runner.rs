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

use std::path::PathBuf;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, Sender};

use crawler_cli::Exit;
use crawler_plant::model_description::ModelDescription;
use crawler_plant::plant::{Drive, Plant};
use crawler_plant::scenario::Scenario;
use crawler_plant::simulate::{mean_position, report_with_task, EpisodeLog, Report};
use crawler_plant::slave::{Slave, StepStatus};
use crawler_plant::task::TaskTracker;
use crawler_protocol::{
    encode, Applied, Environment, EpisodeMsg, Events, FinalReport, Metrics as MetricsMsg,
    ModelInfo, ProcessState, Rejections, Role, RunLimits, State, Status, WaveMsg, PROTOCOL_VERSION,
};
use crawler_transport::Network;

use crate::access::PlantAccess;
use crate::admission::{Admission, Rejection};
use crate::checkpoint::Checkpoint;
use crate::link::{Control, Inbox, Link, Outbox, Topic};

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
    pub network: Network,
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

/// The run's state machine: the slave, the clock's end, the bookkeeping of a checkpoint.
pub struct Runner {
    slave: Slave,
    scenario: Scenario,
    last_step: u64,
    log: EpisodeLog,
    admission: Admission,
    joined: Option<String>,
    opts: RunOptions,
    id: String,
    tension: Vec<f64>,
    /// Progress against the scenario's task (it ends the run in task mode).
    task: TaskTracker,
}

impl Runner {
    /// The plant of `opts` (fresh, or restored from its checkpoint), ready to run as process `id`.
    pub fn new(opts: RunOptions, id: String) -> anyhow::Result<Self> {
        let (scenario, state, log, rejections, last_step) = match &opts.resume {
            Some(c) => (
                c.scenario.clone(),
                Some(c.state.clone()),
                c.log.clone(),
                c.rejections,
                c.last_step,
            ),
            None => {
                let s = opts.scenario.clone();
                let last = s.plant.discretisation()?.steps_until(s.t_end);
                (
                    s,
                    None,
                    EpisodeLog::new(opts.max_episodes),
                    Rejections::default(),
                    last,
                )
            }
        };
        let mut slave = Slave::instantiate("crawler-plant", scenario.plant.clone())?;
        slave.enter_initialization_mode(0.0, None)?;
        slave.exit_initialization_mode()?;
        if let Some(st) = &state {
            slave.set_state(st)?;
        }
        slave.set_stress_limit(Some(scenario.task.sigma_max))?;
        let task = match &opts.resume {
            Some(c) => c.task,
            None => TaskTracker::new(
                scenario.task,
                slave.plant().time(),
                mean_position(slave.plant()),
            ),
        };
        let p = &scenario.plant;
        Ok(Self {
            task,
            tension: Vec::with_capacity(p.numerics.cells),
            admission: Admission::new(p.numerics.cells, p.length, p.boundary, rejections),
            slave,
            scenario,
            last_step,
            log,
            joined: None,
            opts,
            id,
        })
    }

    /// The plant's description, answered to `model` queries.
    pub fn model_info(&self) -> ModelInfo {
        // What controllers are told: nominal friction and no map unless the pipe is disclosed.
        let p = self.scenario.plant.told();
        let md = ModelDescription::new(&p);
        ModelInfo {
            v: PROTOCOL_VERSION,
            run: self.opts.network.run_id.clone(),
            cells: p.numerics.cells as u64,
            length: p.length,
            step: self.plant().step_length(),
            start_time: self.plant().start_time(),
            last_step: self.last_step,
            area: p.body.area,
            density: p.body.density,
            youngs_modulus: p.body.youngs_modulus,
            viscous: p.friction.viscous,
            dry: p.friction.dry,
            eps: p.friction.eps,
            n_f: p.friction.n_f,
            settle: p.numerics.settle,
            model_description: md.to_json(),
            boundary: p.boundary.as_str().to_string(),
            disclosed: p.pipe.disclose,
        }
    }

    /// The pipe's true friction, answered to the recorder's `environment` queries (whatever
    /// controllers are told).
    pub fn environment(&self) -> Environment {
        let p = &self.scenario.plant;
        crate::environment::environment(self.run_id(), p.pipe.start, &p.friction_map())
    }

    fn plant(&self) -> &Plant {
        self.slave.plant()
    }

    fn run_id(&self) -> &str {
        &self.opts.network.run_id
    }

    /// Everything rejected so far: by admission, and at arrival (an oversized payload counts as
    /// malformed, an unsealed one as foreign, one beyond the inbox's budget as overflow).
    fn rejected(&self, inbox: &Inbox) -> Rejections {
        let r = self.admission.rejections();
        Rejections {
            malformed: r.malformed + inbox.refused.oversize(),
            foreign: r.foreign + inbox.refused.unsealed(),
            overflow: r.overflow + inbox.overflow(),
            ..r
        }
    }

    fn status(
        &self,
        out: &impl Outbox,
        state: ProcessState,
        message: &str,
        step: u64,
        rejected: Rejections,
        report: Option<FinalReport>,
    ) {
        let s = Status {
            v: PROTOCOL_VERSION,
            role: Role::Plant,
            id: self.id.clone(),
            state,
            message: message.into(),
            step,
            rejected,
            report,
        };
        out.put(Topic::Status, encode(&s));
    }

    fn stop(
        &self,
        inbox: &Inbox,
        out: &impl Outbox,
        reason: String,
        exit: Exit,
    ) -> anyhow::Result<Outcome> {
        let ckpt = Checkpoint {
            run_id: self.run_id().to_string(),
            scenario: self.scenario.clone(),
            last_step: self.last_step,
            state: self.slave.get_state(),
            log: self.log.clone(),
            rejections: self.rejected(inbox),
            reason: reason.clone(),
            task: self.task,
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
            None,
        );
        Ok(Outcome::Stopped {
            reason,
            checkpoint: path,
            exit,
        })
    }

    fn publish_state(&mut self, out: &impl Outbox) -> usize {
        let plant = self.slave.plant();
        let n = plant.macro_step();
        self.tension.clear();
        self.tension.extend(plant.tension());
        let s = State {
            v: PROTOCOL_VERSION,
            step: n,
            time: plant.time(),
            controller: self.joined.clone().unwrap_or_default(),
            u: plant.displacement().to_vec(),
            vel: plant.velocity().to_vec(),
            tension: self.tension.clone(),
            stuck: plant.stuck().to_vec(),
            mean_speed: plant.outputs().mean_speed,
            input_power: plant.outputs().input_power,
            last: n >= self.last_step,
            applied: applied(plant),
        };
        let bytes = encode(&s);
        let len = bytes.len();
        out.put(Topic::State, bytes);
        len
    }

    fn publish_step_outputs(&self, out: &impl Outbox) {
        let plant = self.plant();
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
            out.put(Topic::Events, encode(&ev));
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
                velocity: m.velocity,
                power: m.power,
                mileage: Some(m.mileage).filter(|x| x.is_finite()),
                max_stress: m.max_stress,
                max_strain: m.max_strain,
                stuck_fraction: m.stuck_fraction,
                mean_friction_selection: m.mean_friction_selection,
                episodes_per_node_per_period: m.episodes_per_node_per_period,
                clock: b.clock,
            };
            if msg.velocity.is_finite() && msg.power.is_finite() {
                out.put(Topic::Metrics, encode(&msg));
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
            None,
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
        eprintln!(
            "crawler-plant: controller {joined} joined run {}; stepping to step {}",
            self.run_id(),
            self.last_step
        );
        self.joined = Some(joined.clone());
        let h = self.plant().step_length();
        let first = self.plant().macro_step();
        let started = Instant::now();
        let mut state_bytes;
        let bar = crawler_cli::progress::bar(self.last_step, "co-simulating");
        bar.set_position(first);
        self.status(
            out,
            ProcessState::Running,
            &format!("controller {joined} joined"),
            first,
            self.rejected(inbox),
            None,
        );
        let mut last_status = Instant::now();
        // When the joined controller's last valid answer arrived: how fast a lost controller is
        // noticed is measured from there.
        let mut last_answer = Instant::now();
        loop {
            state_bytes = self.publish_state(out);
            let n = self.plant().macro_step();
            if n >= self.last_step {
                break;
            }
            // Wait for the joined controller's answer to State(n).
            let deadline = Instant::now() + self.opts.step_timeout;
            let mut resend = Instant::now() + RESEND;
            let command = loop {
                let now = Instant::now();
                if now >= deadline {
                    let reason = format!(
                        "controller {joined} did not answer step {n} within {:.1} s",
                        self.opts.step_timeout.as_secs_f64()
                    );
                    bar.abandon();
                    return self.stop(inbox, out, reason, Exit::Timeout);
                }
                let wake = resend.min(deadline);
                crossbeam_channel::select! {
                    recv(inbox.control) -> ev => match ev {
                        Ok(Control::ControllerDown(id)) if id == joined => {
                            bar.abandon();
                            let reason = format!(
                                "controller {joined} left the run at step {n} (its liveliness token disappeared {} ms after its last answer)",
                                last_answer.elapsed().as_millis()
                            );
                            return self.stop(inbox, out, reason, Exit::PeerLost);
                        }
                        Ok(Control::Interrupt) => {
                            bar.abandon();
                            return self.stop(inbox, out, format!("interrupted at step {n}"), Exit::Interrupted);
                        }
                        Ok(Control::ControllerUp(id)) if id != joined => {
                            eprintln!("crawler-plant: another controller {id} appeared; the run keeps {joined} and rejects the others");
                        }
                        _ => {}
                    },
                    recv(inbox.data) -> bytes => {
                        let Ok(bytes) = bytes else { continue };
                        match self.admission.admit(bytes.get(), n, &joined) {
                            Ok(command) => {
                                last_answer = Instant::now();
                                break command;
                            }
                            Err(rejection) => Self::warn(&rejection),
                        }
                    },
                    default(wake.saturating_duration_since(now)) => {
                        if Instant::now() >= resend {
                            let _ = self.publish_state(out);
                            resend = Instant::now() + RESEND;
                        }
                    },
                }
            };
            // Apply and step.
            if let Err(e) = command.apply(&mut self.slave) {
                // Admission checked everything set_* checks, so this is a bug, not bad input.
                anyhow::bail!("internal error: validated actuation refused by the slave: {e}");
            }
            match self.slave.do_step(self.plant().time(), h) {
                StepStatus::Ok => {}
                StepStatus::Discard { reason, .. } => {
                    bar.abandon();
                    let reason = format!("step {n} discarded: {reason}");
                    return self.stop(inbox, out, reason, Exit::Failure);
                }
                StepStatus::Error(e) => anyhow::bail!("step {n} failed: {e}"),
            }
            self.log.observe(self.slave.plant());
            let plant = self.slave.plant();
            let decided =
                self.task
                    .observe(plant.time(), h, mean_position(plant), &plant.outputs());
            if let (true, Some(outcome)) = (self.scenario.task.end_run, decided) {
                // Task mode: this step is the run's last; the next state says so.
                if self.last_step > n + 1 {
                    eprintln!(
                        "crawler-plant: task {} at step {}; the run ends there",
                        outcome.as_str(),
                        n + 1
                    );
                    self.last_step = n + 1;
                }
            }
            self.publish_step_outputs(out);
            if n.is_multiple_of(64) {
                bar.set_position(n + 1);
            }
            if last_status.elapsed() >= STATUS_EVERY {
                self.status(
                    out,
                    ProcessState::Running,
                    &format!("step {} of {}", n + 1, self.last_step),
                    n + 1,
                    self.rejected(inbox),
                    None,
                );
                last_status = Instant::now();
            }
        }
        bar.finish_and_clear();
        let steps = self.last_step - first;
        let secs = started.elapsed().as_secs_f64();
        eprintln!(
            "crawler-plant: lockstep: {steps} steps in {secs:.3} s ({:.0} steps/s, {state_bytes} bytes per state)",
            steps as f64 / secs
        );
        let rep = report_with_task(
            &self.scenario.name,
            self.plant(),
            &self.log,
            Some(&self.task),
        );
        // The report on the wire: the library's report in the protocol's terms (without the
        // episode list: the events stream carried every episode).
        let report = match &rep {
            Ok(r) => match FinalReport::try_from(r) {
                Ok(w) => Some(w),
                Err(e) => {
                    eprintln!("crawler-plant: the final report cannot go on the wire: {e}");
                    None
                }
            },
            Err(_) => None,
        };
        let rejected = self.rejected(inbox);
        let message = format!(
            "finished at step {}; rejected actuation: {}",
            self.last_step,
            rejected.total()
        );
        self.status(
            out,
            ProcessState::Finished,
            &message,
            self.last_step,
            rejected,
            report,
        );
        if rejected.total() > 0 {
            eprintln!("crawler-plant: rejected actuation messages: {rejected:?}");
        }
        Ok(Outcome::Finished(Box::new(rep?)))
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
