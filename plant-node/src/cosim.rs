//! `crawler-plant run`: the plant as a co-simulation slave over zenoh, owning the clock.
//!
//! Lockstep on a fixed-step clock: the plant publishes `State(n)` at `t = t0 + n H`, the controller
//! that joined the run answers `Actuation(n)`, the plant applies it over `[t_n, t_{n+1}]` and
//! publishes `State(n + 1)`. Actuation that is malformed, of another protocol version, invalid,
//! from another controller, stale, a duplicate or for a future step is rejected and counted, never
//! applied. A controller that leaves (its liveliness token disappears: exit, crash, `kill -9`) stops
//! the run with a checkpoint from which `crawler-plant run --resume` continues bit-identically.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crossbeam_channel::{bounded, Receiver, Sender};
use zenoh::qos::CongestionControl;
use zenoh::sample::SampleKind;
use zenoh::Wait;

use crawler_protocol::{
    decode, encode, Actuation, EpisodeMsg, Events, Metrics as MetricsMsg, ModelInfo, ProtocolError,
    Rejections, Role, RunKeys, State, Status, PROTOCOL_VERSION,
};
use crawler_transport::Network;

use crawler_plant::model_description::ModelDescription;
use crawler_plant::plant::Plant;
use crawler_plant::scenario::Scenario;
use crawler_plant::simulate::{report, EpisodeLog, Report};
use crawler_plant::slave::{Slave, StepStatus};
use crawler_plant::wave::Wave;

use crate::checkpoint::Checkpoint;

/// Capacity of the actuation inbox; beyond it messages are dropped and counted (flooding).
const INBOX: usize = 1024;
/// Republish the current state if no valid answer came within this time.
const RESEND: Duration = Duration::from_millis(500);
/// Status is republished at least this often while running.
const STATUS_EVERY: Duration = Duration::from_secs(1);

/// Control events: never dropped.
#[derive(Debug, Clone, PartialEq)]
pub enum Control {
    /// A controller declared its liveliness token.
    ControllerUp(String),
    /// A controller's token disappeared.
    ControllerDown(String),
    /// SIGINT or SIGTERM.
    Interrupt,
}

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
        /// Suggested process exit code.
        exit_code: u8,
    },
}

/// Exit code when the controller left the run.
pub const EXIT_CONTROLLER_LOST: u8 = 3;
/// Exit code when nobody answered in time.
pub const EXIT_TIMEOUT: u8 = 4;
/// Exit code after SIGINT / SIGTERM.
pub const EXIT_INTERRUPTED: u8 = 130;

/// Why an actuation message was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reject {
    /// Undecodable.
    Malformed,
    /// Other protocol version.
    Version,
    /// Invalid values.
    Invalid,
    /// Not from the joined controller.
    Foreign,
    /// For an earlier step.
    Stale,
    /// A second answer to the step just taken.
    Duplicate,
    /// For a later step.
    Future,
}

impl Reject {
    fn count(self, r: &mut Rejections) -> u64 {
        let c = match self {
            Reject::Malformed => &mut r.malformed,
            Reject::Version => &mut r.version,
            Reject::Invalid => &mut r.invalid,
            Reject::Foreign => &mut r.foreign,
            Reject::Stale => &mut r.stale,
            Reject::Duplicate => &mut r.duplicate,
            Reject::Future => &mut r.future,
        };
        *c += 1;
        *c
    }
}

/// Decodes and checks an actuation for step `n` from controller `joined` on a body of `cells`
/// cells and length `length` (m). The returned actuation can be applied as is.
pub fn classify(
    bytes: &[u8],
    n: u64,
    joined: &str,
    cells: usize,
    length: f64,
    boundary: crawler_plant::params::Boundary,
) -> Result<Actuation, (Reject, String)> {
    let a: Actuation = decode(bytes).map_err(|e| match e {
        ProtocolError::Version { .. } => (Reject::Version, e.to_string()),
        ProtocolError::Invalid { .. } => (Reject::Invalid, e.to_string()),
        _ => (Reject::Malformed, e.to_string()),
    })?;
    if a.controller != joined {
        return Err((
            Reject::Foreign,
            format!(
                "actuation from controller {:?}, the run's controller is {joined:?}",
                a.controller
            ),
        ));
    }
    if a.step < n {
        let kind = if a.step + 1 == n {
            Reject::Duplicate
        } else {
            Reject::Stale
        };
        return Err((
            kind,
            format!("actuation for step {} while at step {n}", a.step),
        ));
    }
    if a.step > n {
        return Err((
            Reject::Future,
            format!("actuation for step {} while at step {n}", a.step),
        ));
    }
    if let Some(f) = &a.field {
        if f.len() != cells {
            return Err((
                Reject::Invalid,
                format!(
                    "actuation.field has {} values, the body has {cells} cells",
                    f.len()
                ),
            ));
        }
    }
    if let Some(w) = a.wave {
        let wave = Wave {
            f0: w.f0,
            k: w.k,
            omega: w.omega,
            phase: w.phase,
        };
        wave.validate_for_body(length, cells, boundary)
            .map_err(|e| (Reject::Invalid, e.to_string()))?;
    }
    Ok(a)
}

/// The zenoh side of the plant: publishers, subscribers and the inboxes they fill.
struct Link {
    keys: RunKeys,
    id: String,
    session: zenoh::Session,
    state: zenoh::pubsub::Publisher<'static>,
    events: zenoh::pubsub::Publisher<'static>,
    metrics: zenoh::pubsub::Publisher<'static>,
    status: zenoh::pubsub::Publisher<'static>,
    data: Receiver<Vec<u8>>,
    control: Receiver<Control>,
    overflow: Arc<AtomicU64>,
    _token: zenoh::liveliness::LivelinessToken,
    _actuation: zenoh::pubsub::Subscriber<()>,
    _controllers: zenoh::pubsub::Subscriber<()>,
    _model: zenoh::query::Queryable<()>,
}

impl Link {
    fn open(
        network: &Network,
        info: ModelInfo,
        control_tx: Sender<Control>,
        control_rx: Receiver<Control>,
    ) -> anyhow::Result<Self> {
        let keys = RunKeys::new(&network.run_id)?;
        let id = crawler_transport::process_id();
        let session = crawler_transport::open(Role::Plant, network)?;
        let z = |e: zenoh::Error| anyhow::anyhow!("zenoh: {e}");
        let publisher = |key: String, block: bool| {
            session
                .declare_publisher(key)
                .congestion_control(if block {
                    CongestionControl::Block
                } else {
                    CongestionControl::Drop
                })
                .express(true)
                .wait()
                .map_err(z)
        };
        let state = publisher(keys.state(), true)?;
        let events = publisher(keys.events(), false)?;
        let metrics = publisher(keys.metrics(), false)?;
        let status = publisher(keys.status(Role::Plant), true)?;
        let (data_tx, data) = bounded::<Vec<u8>>(INBOX);
        let overflow = Arc::new(AtomicU64::new(0));
        let dropped = overflow.clone();
        let actuation = session
            .declare_subscriber(keys.actuation())
            .callback(move |sample| {
                let bytes = sample.payload().to_bytes().into_owned();
                if data_tx.try_send(bytes).is_err() {
                    dropped.fetch_add(1, Ordering::Relaxed);
                }
            })
            .wait()
            .map_err(z)?;
        let keys2 = keys.clone();
        let controllers = session
            .liveliness()
            .declare_subscriber(keys.alive_all(Role::Controller))
            .history(true)
            .callback(move |sample| {
                if let Some(cid) =
                    keys2.id_of_alive_key(Role::Controller, sample.key_expr().as_str())
                {
                    let ev = match sample.kind() {
                        SampleKind::Put => Control::ControllerUp(cid.to_string()),
                        SampleKind::Delete => Control::ControllerDown(cid.to_string()),
                    };
                    let _ = control_tx.send(ev);
                }
            })
            .wait()
            .map_err(z)?;
        let info_bytes = encode(&info);
        let model = session
            .declare_queryable(keys.model())
            .callback(move |query| {
                let _ = query
                    .reply(query.key_expr().clone(), info_bytes.clone())
                    .wait();
            })
            .wait()
            .map_err(z)?;
        let token = session
            .liveliness()
            .declare_token(keys.alive(Role::Plant, &id))
            .wait()
            .map_err(z)?;
        Ok(Self {
            keys,
            id,
            session,
            state,
            events,
            metrics,
            status,
            data,
            control: control_rx,
            overflow,
            _token: token,
            _actuation: actuation,
            _controllers: controllers,
            _model: model,
        })
    }

    fn status(
        &self,
        state: &str,
        message: &str,
        step: u64,
        rejected: Rejections,
        summary: Option<String>,
    ) {
        let s = Status {
            v: PROTOCOL_VERSION,
            role: Role::Plant.as_str().into(),
            id: self.id.clone(),
            state: state.into(),
            message: message.into(),
            step,
            rejected,
            summary,
        };
        let _ = self.status.put(encode(&s)).wait();
    }
}

/// The run's state machine.
struct Runner {
    slave: Slave,
    scenario: Scenario,
    last_step: u64,
    log: EpisodeLog,
    rejections: Rejections,
    joined: Option<String>,
    opts: RunOptions,
    tension: Vec<f64>,
    warned: u64,
}

/// Runs the plant until the clock reaches the end or the run stops; never panics on input.
pub fn run(
    opts: RunOptions,
    control_tx: Sender<Control>,
    control_rx: Receiver<Control>,
) -> anyhow::Result<Outcome> {
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
    // What controllers are told: nominal friction and no map unless the pipe is disclosed.
    let p = scenario.plant.told();
    let md = ModelDescription::new(&p);
    let info = ModelInfo {
        v: PROTOCOL_VERSION,
        run: opts.network.run_id.clone(),
        cells: p.numerics.cells as u64,
        length: p.length,
        step: slave.plant().step_length(),
        start_time: slave.plant().start_time(),
        last_step,
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
    };
    let link = Link::open(&opts.network, info, control_tx, control_rx)?;
    let mut r = Runner {
        tension: Vec::with_capacity(p.numerics.cells),
        slave,
        scenario,
        last_step,
        log,
        rejections,
        joined: None,
        opts,
        warned: 0,
    };
    let outcome = r.lockstep(&link);
    // Give subscribers a moment to receive the last messages, then close cleanly.
    std::thread::sleep(Duration::from_millis(100));
    let _ = link.session.close().wait();
    outcome
}

impl Runner {
    fn plant(&self) -> &Plant {
        self.slave.plant()
    }

    fn rejected(&self, link: &Link) -> Rejections {
        Rejections {
            overflow: link.overflow.load(Ordering::Relaxed),
            ..self.rejections
        }
    }

    fn stop(&self, link: &Link, reason: String, exit_code: u8) -> anyhow::Result<Outcome> {
        let ckpt = Checkpoint {
            run_id: link.keys.run().to_string(),
            scenario: self.scenario.clone(),
            last_step: self.last_step,
            state: self.slave.get_state(),
            log: self.log.clone(),
            rejections: self.rejected(link),
            reason: reason.clone(),
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
        let state = if exit_code == EXIT_INTERRUPTED {
            "stopped"
        } else {
            "failed"
        };
        let message = match &path {
            Some(p) => format!("{reason}; checkpoint written to {}", p.display()),
            None => format!("{reason}; nothing simulated, no checkpoint"),
        };
        link.status(
            state,
            &message,
            self.plant().macro_step(),
            self.rejected(link),
            None,
        );
        Ok(Outcome::Stopped {
            reason,
            checkpoint: path,
            exit_code,
        })
    }

    fn publish_state(&mut self, link: &Link) -> usize {
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
        };
        let bytes = encode(&s);
        let len = bytes.len();
        let _ = link.state.put(bytes).wait();
        len
    }

    fn publish_step_outputs(&self, link: &Link) {
        let plant = self.plant();
        let n = plant.macro_step();
        if !plant.episodes().is_empty() {
            let ev = Events {
                v: PROTOCOL_VERSION,
                step: n,
                time: plant.time(),
                episodes: plant
                    .episodes()
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
            let _ = link.events.put(encode(&ev)).wait();
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
                mileage: m.mileage,
                max_stress: m.max_stress,
                max_strain: m.max_strain,
                stuck_fraction: m.stuck_fraction,
                mean_friction_selection: m.mean_friction_selection,
                episodes_per_node_per_period: m.episodes_per_node_per_period,
            };
            if msg.velocity.is_finite() && msg.power.is_finite() {
                let _ = link.metrics.put(encode(&msg)).wait();
            }
        }
    }

    fn warn(&mut self, kind: Reject, count: u64, why: &str) {
        // The first few of each kind, then every 1000th: a flood must not flood the terminal.
        if count <= 5 || count.is_multiple_of(1000) {
            self.warned += 1;
            eprintln!("crawler-plant: rejected actuation ({kind:?}, #{count}): {why}");
        }
    }

    fn wait_for_controller(&mut self, link: &Link) -> Result<String, anyhow::Result<Outcome>> {
        let what = format!(
            "waiting for a controller to join {} (start one with: crawler-controller run --run-id {}); timeout {:.0} s",
            self.opts.network.describe(),
            link.keys.run(),
            self.opts.wait_timeout.as_secs_f64()
        );
        eprintln!("crawler-plant: {what}");
        link.status(
            "waiting",
            &what,
            self.plant().macro_step(),
            self.rejected(link),
            None,
        );
        let deadline = Instant::now() + self.opts.wait_timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match link.control.recv_timeout(left) {
                Ok(Control::ControllerUp(id)) => return Ok(id),
                Ok(Control::ControllerDown(_)) => {}
                Ok(Control::Interrupt) => {
                    return Err(self.stop(
                        link,
                        "interrupted while waiting for a controller".into(),
                        EXIT_INTERRUPTED,
                    ))
                }
                Err(_) => {
                    let reason = format!(
                        "no controller joined within {:.0} s",
                        self.opts.wait_timeout.as_secs_f64()
                    );
                    return Err(self.stop(link, reason, EXIT_TIMEOUT));
                }
            }
        }
    }

    fn lockstep(&mut self, link: &Link) -> anyhow::Result<Outcome> {
        let joined = match self.wait_for_controller(link) {
            Ok(id) => id,
            Err(outcome) => return outcome,
        };
        eprintln!(
            "crawler-plant: controller {joined} joined run {}; stepping to step {}",
            link.keys.run(),
            self.last_step
        );
        self.joined = Some(joined.clone());
        let cells = self.plant().cells();
        let length = self.plant().params().length;
        let boundary = self.plant().params().boundary;
        let h = self.plant().step_length();
        let first = self.plant().macro_step();
        let started = Instant::now();
        let mut state_bytes;
        let bar = crawler_cli::progress::bar(self.last_step, "co-simulating");
        bar.set_position(first);
        link.status(
            "running",
            &format!("controller {joined} joined"),
            first,
            self.rejected(link),
            None,
        );
        let mut last_status = Instant::now();
        // When the joined controller's last valid answer arrived: how fast a lost controller is
        // noticed is measured from there.
        let mut last_answer = Instant::now();
        loop {
            state_bytes = self.publish_state(link);
            let n = self.plant().macro_step();
            if n >= self.last_step {
                break;
            }
            // Wait for the joined controller's answer to State(n).
            let deadline = Instant::now() + self.opts.step_timeout;
            let mut resend = Instant::now() + RESEND;
            let actuation = loop {
                let now = Instant::now();
                if now >= deadline {
                    let reason = format!(
                        "controller {joined} did not answer step {n} within {:.1} s",
                        self.opts.step_timeout.as_secs_f64()
                    );
                    bar.abandon();
                    return self.stop(link, reason, EXIT_TIMEOUT);
                }
                let wake = resend.min(deadline);
                crossbeam_channel::select! {
                    recv(link.control) -> ev => match ev {
                        Ok(Control::ControllerDown(id)) if id == joined => {
                            bar.abandon();
                                                        let reason = format!(
                                "controller {joined} left the run at step {n} (its liveliness token disappeared {} ms after its last answer)",
                                last_answer.elapsed().as_millis()
                            );
                            return self.stop(link, reason, EXIT_CONTROLLER_LOST);
                        }
                        Ok(Control::Interrupt) => {
                            bar.abandon();
                            return self.stop(link, format!("interrupted at step {n}"), EXIT_INTERRUPTED);
                        }
                        Ok(Control::ControllerUp(id)) if id != joined => {
                            eprintln!("crawler-plant: another controller {id} appeared; the run keeps {joined} and rejects the others");
                        }
                        _ => {}
                    },
                    recv(link.data) -> bytes => {
                        let Ok(bytes) = bytes else { continue };
                        match classify(&bytes, n, &joined, cells, length, boundary) {
                                                        Ok(a) => {
                                last_answer = Instant::now();
                                break a;
                            }
                            Err((kind, why)) => {
                                let count = kind.count(&mut self.rejections);
                                self.warn(kind, count, &why);
                            }
                        }
                    },
                    default(wake.saturating_duration_since(now)) => {
                                                if Instant::now() >= resend {
                            let _ = self.publish_state(link);
                            resend = Instant::now() + RESEND;
                        }
                    },
                }
            };
            // Apply and step.
            let applied = match (&actuation.wave, &actuation.field) {
                (Some(w), _) => self.slave.set_wave(Wave {
                    f0: w.f0,
                    k: w.k,
                    omega: w.omega,
                    phase: w.phase,
                }),
                (_, Some(f)) => self.slave.set_field(f),
                _ => unreachable!("validated: exactly one of wave and field"),
            };
            if let Err(e) = applied {
                // classify() checked everything set_* checks, so this is a bug, not bad input.
                anyhow::bail!("internal error: validated actuation refused by the slave: {e}");
            }
            match self.slave.do_step(self.plant().time(), h) {
                StepStatus::Ok => {}
                StepStatus::Discard { reason, .. } => {
                    bar.abandon();
                    let reason = format!("step {n} discarded: {reason}");
                    return self.stop(link, reason, 1);
                }
                StepStatus::Error(e) => anyhow::bail!("step {n} failed: {e}"),
            }
            self.log.observe(self.slave.plant());
            self.publish_step_outputs(link);
            if n.is_multiple_of(64) {
                bar.set_position(n + 1);
            }
            if last_status.elapsed() >= STATUS_EVERY {
                link.status(
                    "running",
                    &format!("step {} of {}", n + 1, self.last_step),
                    n + 1,
                    self.rejected(link),
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
        let rep = report(&self.scenario.name, self.plant(), &self.log);
        let summary = rep
            .as_ref()
            .ok()
            .map(|r| serde_json::to_string(r).expect("report serializes"));
        let rejected = self.rejected(link);
        let message = format!(
            "finished at step {}; rejected actuation: {}",
            self.last_step,
            rejected.total()
        );
        link.status("finished", &message, self.last_step, rejected, summary);
        if rejected.total() > 0 {
            eprintln!("crawler-plant: rejected actuation messages: {rejected:?}");
        }
        Ok(Outcome::Finished(Box::new(rep?)))
    }
}
