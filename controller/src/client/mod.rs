//! `crawler-controller run`: a controller of a co-simulation run over zenoh.
//!
//! The controller queries the plant's [`ModelInfo`] (retrying until the plant exists, so either
//! process may start first), builds its policy for that plant, declares its liveliness token
//! (which is how it joins the run) and then answers every `State(n)` with `Actuation(n)`. It also
//! publishes the models' predictions for the wave it applies, for the recorder.

mod answer;
mod inbox;
mod predictions;
mod summary;
pub mod watch;

use std::sync::Arc;
use std::time::{Duration, Instant};

use crossbeam_channel::Receiver;
use zenoh::qos::CongestionControl;
use zenoh::Wait;

use crawler_cli::Exit;
use crawler_physics::scenario::Scenario;
use crawler_protocol::{
    decode, encode, ModelInfo, ProcessState, Rejections, Role, RunKeys, RunLimits, State, Status,
    PROTOCOL_VERSION,
};
use crawler_transport::gate::{self, Gate, Refused};
use crawler_transport::{Credential, Network, Seal};

use answer::Responder;
use crawler_policies::Params;
use inbox::{Event, Inbox};
pub use inbox::{STATE_INBOX_BYTES, STATUS_INBOX_BYTES};
pub use predictions::{briefing_of, context_of, paper_tail, predictions};
pub use summary::FinalSummary;
pub use watch::{finished_may_follow, last_state_fits, terminal_is_consistent};
use watch::{Verdict, Watch};

/// Options of `crawler-controller run`.
#[derive(Debug, Clone)]
pub struct ClientOptions {
    /// Registered policy name.
    pub policy: String,
    /// The policy's parameters (`--param KEY=VALUE`).
    pub params: Params,
    /// The scenario: task, limits and default wave (the plant's parameters come from the plant).
    pub scenario: Scenario,
    /// Where the run's processes meet.
    pub network: Network,
    /// How long to wait for the plant, s.
    pub wait_timeout: Duration,
}

/// Interrupt signal for the client loop.
#[derive(Debug, Clone, Copy)]
pub struct Interrupt;

/// How the controller's run ended.
#[derive(Debug)]
pub enum ClientOutcome {
    /// The plant reached the end of the run.
    Finished(Box<FinalSummary>),
    /// The run ended otherwise.
    Ended {
        /// Why.
        reason: String,
        /// The process's exit code.
        exit: Exit,
    },
}

/// The controller's session and what it checks arriving messages with.
struct Link {
    session: zenoh::Session,
    credential: Option<Credential>,
    seal: Option<Seal>,
    limit: usize,
}

impl Link {
    /// Connects to the plant presenting `credential`'s password (if any), reassembling messages
    /// of at most `limit` bytes; `None` if `give_up` says so first.
    fn connect(
        network: &crawler_transport::Network,
        credential: Option<Credential>,
        limit: usize,
        give_up: &mut dyn FnMut() -> bool,
    ) -> anyhow::Result<Option<Self>> {
        let Some((session, credential)) = crawler_transport::connect_client(
            Role::Controller,
            network,
            credential,
            limit,
            give_up,
        )?
        else {
            return Ok(None);
        };
        let seal = credential.as_ref().map(|c| Seal::new(&c.message_key()));
        Ok(Some(Self {
            session,
            credential,
            seal,
            limit,
        }))
    }

    fn close(self) {
        let _ = self.session.close().wait();
    }
}

/// Runs the controller until the run ends.
pub fn run(opts: ClientOptions, interrupt: Receiver<Interrupt>) -> anyhow::Result<ClientOutcome> {
    let keys = RunKeys::new(&opts.network.run_id)?;
    let id = crawler_transport::process_id();
    let deadline = Instant::now() + opts.wait_timeout;
    let credential =
        opts.network
            .wait_for_credential("crawler-controller", opts.wait_timeout, &|| {
                !interrupt.is_empty()
            })?;
    if credential.is_none() {
        eprintln!(
            "crawler-controller: warning: unauthenticated (--no-auth): this controller cannot tell its plant's messages from anyone else's"
        );
    }
    eprintln!(
        "crawler-controller: waiting for the plant of {} (start it with: crawler-plant run --run-id {})",
        opts.network.describe(),
        keys.run()
    );
    let (intr, wait_timeout) = (&interrupt, opts.wait_timeout);
    let waited = |deadline: Instant| {
        move || -> Option<ClientOutcome> {
            if !intr.is_empty() {
                return Some(ClientOutcome::Ended {
                    reason: "interrupted while waiting for the plant".into(),
                    exit: Exit::Interrupted,
                });
            }
            (Instant::now() >= deadline).then(|| ClientOutcome::Ended {
                reason: format!(
                    "no plant answered within {:.0} s",
                    wait_timeout.as_secs_f64()
                ),
                exit: Exit::Timeout,
            })
        }
    };
    let give_up = waited(deadline);
    let mut ended = None;
    let link = Link::connect(
        &opts.network,
        credential,
        RunLimits::before_model(),
        &mut || {
            ended = give_up();
            ended.is_some()
        },
    )?;
    let Some(link) = link else {
        return Ok(ended.expect("gave up for a reason"));
    };
    let info = match discover(&link, &keys, &id, &waited(deadline))? {
        Ok(info) => info,
        Err(ended) => {
            link.close();
            return Ok(ended);
        }
    };
    // The run's largest legal message may exceed what the first session reassembles (very
    // large grids): then reconnect with the run's own limit.
    let limits = RunLimits::new(info.cells as usize);
    let link = if limits.largest() > link.limit {
        let credential = link.credential.clone();
        link.close();
        let give_up = waited(Instant::now() + opts.wait_timeout);
        let mut ended = None;
        match Link::connect(&opts.network, credential, limits.largest(), &mut || {
            ended = give_up();
            ended.is_some()
        })? {
            Some(link) => link,
            None => return Ok(ended.expect("gave up for a reason")),
        }
    } else {
        link
    };
    let outcome = serve(&link, &keys, &id, &opts, &interrupt, info);
    link.close();
    outcome
}

/// Publishes the controller's status (sealed in an authenticated run).
fn publish_status(
    publisher: &zenoh::pubsub::Publisher<'_>,
    seal: Option<&Seal>,
    id: &str,
    (state, message, step): (ProcessState, &str, u64),
) {
    let s = Status {
        v: PROTOCOL_VERSION,
        role: Role::Controller,
        id: id.to_string(),
        state,
        message: message.into(),
        step,
        rejected: Rejections::default(),
        report: None,
    };
    let _ = gate::put(publisher, seal, encode(&s));
}

/// Waits for the plant's (sealed) model description, retrying until it answers or `give_up`
/// gives a reason to stop.
fn discover(
    link: &Link,
    keys: &RunKeys,
    id: &str,
    give_up: &dyn Fn() -> Option<ClientOutcome>,
) -> anyhow::Result<Result<ModelInfo, ClientOutcome>> {
    let z = |e: zenoh::Error| anyhow::anyhow!("zenoh: {e}");
    let status_pub = link
        .session
        .declare_publisher(keys.status(Role::Controller))
        .congestion_control(CongestionControl::Block)
        .wait()
        .map_err(z)?;
    publish_status(
        &status_pub,
        link.seal.as_ref(),
        id,
        (
            ProcessState::Waiting,
            "waiting for the plant's model description",
            0,
        ),
    );
    let gate = Gate::new(
        RunLimits::before_model(),
        link.seal.clone(),
        Arc::new(Refused::default()),
    );
    loop {
        if let Some(ended) = give_up() {
            return Ok(Err(ended));
        }
        let replies = link
            .session
            .get(keys.model())
            .timeout(Duration::from_millis(500))
            .wait()
            .map_err(z)?;
        let mut found = None;
        while let Ok(reply) = replies.recv() {
            let Ok(sample) = reply.result() else { continue };
            let Ok(bytes) = gate.admit(sample) else {
                eprintln!("crawler-controller: ignoring a model description without a valid seal");
                continue;
            };
            match decode::<ModelInfo>(&bytes) {
                Ok(info) if info.run == keys.run() => found = Some(info),
                Ok(info) => eprintln!(
                    "crawler-controller: ignoring the model description of another run ({})",
                    info.run
                ),
                Err(e) => {
                    eprintln!("crawler-controller: ignoring an invalid model description: {e}")
                }
            }
        }
        if let Some(info) = found {
            return Ok(Ok(info));
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// Answers the plant of `info` until the run ends.
fn serve(
    link: &Link,
    keys: &RunKeys,
    id: &str,
    opts: &ClientOptions,
    interrupt: &Receiver<Interrupt>,
    info: ModelInfo,
) -> anyhow::Result<ClientOutcome> {
    let z = |e: zenoh::Error| anyhow::anyhow!("zenoh: {e}");
    let session = &link.session;
    let seal = link.seal.as_ref();
    let inbox = Inbox::open(session, keys, &RunLimits::new(info.cells as usize), seal)?;
    let status_pub = session
        .declare_publisher(keys.status(Role::Controller))
        .congestion_control(CongestionControl::Block)
        .wait()
        .map_err(z)?;
    let publish_status = |state: ProcessState, message: &str, step: u64| {
        publish_status(&status_pub, seal, id, (state, message, step));
    };

    let ctx = context_of(&info, &opts.scenario);
    let policy = crawler_policies::build(&opts.policy, &ctx, &opts.params)?;
    eprintln!(
        "crawler-controller: plant found ({} cells, L = {} m, communication step H = {:.6e} s); policy {}",
        info.cells,
        info.length,
        info.step,
        policy.describe()
    );
    let mut responder = Responder::new(policy, &ctx, id);

    let actuation_pub = session
        .declare_publisher(keys.actuation())
        .congestion_control(CongestionControl::Block)
        .express(true)
        .wait()
        .map_err(z)?;
    // Blocking like the actuation: a wave's predictions are sent once, and the recorder gets
    // them through the plant's link, behind its states; a dropping publisher lost them whenever
    // that link was congested for a moment, and with them the models' lines for the whole run.
    let prediction_pub = session
        .declare_publisher(keys.prediction())
        .congestion_control(CongestionControl::Block)
        .wait()
        .map_err(z)?;
    // Joining: the plant takes the first controller whose token it sees.
    let _token = session
        .liveliness()
        .declare_token(keys.alive(Role::Controller, id))
        .wait()
        .map_err(z)?;
    publish_status(
        ProcessState::Running,
        &format!("policy {}", responder.policy()),
        0,
    );

    let mut watch = Watch::new(id, &info);
    let deadline_idle = opts.wait_timeout.max(Duration::from_secs(60));
    let mut last_seen = Instant::now();
    let plant_report = loop {
        let verdict = crossbeam_channel::select! {
            recv(interrupt) -> _ => {
                publish_status(ProcessState::Stopped, "interrupted", responder.answered());
                return Ok(ClientOutcome::Ended { reason: "interrupted".into(), exit: Exit::Interrupted });
            }
            recv(inbox.events) -> ev => match ev {
                Ok(Event::Up(pid)) => watch.plant_up(&pid),
                Ok(Event::Down(pid)) => watch.plant_down(&pid),
                Err(_) => Verdict::Wait,
            },
            recv(inbox.statuses) -> st => match st {
                Ok(st) => watch.status(st.split().0, responder.answered()),
                Err(_) => Verdict::Wait,
            },
            recv(inbox.states) -> bytes => match bytes.map(|b| decode::<State>(b.get())) {
                Ok(Ok(state)) => {
                    if state.controller == id {
                        last_seen = Instant::now();
                    }
                    let verdict = watch.state(&state);
                    if verdict == Verdict::Answer {
                        let (actuation, prediction) = responder.respond(&state);
                        gate::put(&actuation_pub, seal, encode(&actuation)).map_err(z)?;
                        if let Some(p) = prediction {
                            let _ = gate::put(&prediction_pub, seal, encode(&p));
                        }
                    }
                    verdict
                }
                Ok(Err(e)) => {
                    watch.ignore();
                    if watch.ignored() <= 5 {
                        eprintln!("crawler-controller: ignoring an invalid state: {e}");
                    }
                    Verdict::Wait
                }
                Err(_) => Verdict::Wait,
            },
            default(Duration::from_millis(500)) => {
                if last_seen.elapsed() > deadline_idle {
                    let reason = match watch.other_controller() {
                        Some(c) => format!("run {} already has controller {c}", keys.run()),
                        None => format!("no state from the plant for {:.0} s", deadline_idle.as_secs_f64()),
                    };
                    return Ok(ClientOutcome::Ended { reason, exit: Exit::Timeout });
                }
                Verdict::Wait
            },
        };
        for note in watch.take_notes() {
            eprintln!("crawler-controller: {note}");
        }
        match verdict {
            Verdict::Wait | Verdict::Answer => {}
            Verdict::Finished(report) => break report.map(|r| *r),
            Verdict::Ended(reason) => {
                publish_status(ProcessState::Stopped, &reason, responder.answered());
                return Ok(ClientOutcome::Ended {
                    reason,
                    exit: Exit::Failure,
                });
            }
            Verdict::PlantLeft => {
                return Ok(ClientOutcome::Ended {
                    reason: "the plant left the run".into(),
                    exit: Exit::PeerLost,
                })
            }
        }
    };
    let answered = responder.answered();
    publish_status(
        ProcessState::Finished,
        &format!("answered {answered} steps"),
        answered,
    );
    let refusals = inbox.refusals();
    if watch.ignored() > 0 || refusals.is_some() {
        eprintln!(
            "crawler-controller: ignored {} messages (invalid, or not from this run's plant); refused at arrival: {}",
            watch.ignored(),
            refusals.as_deref().unwrap_or("none")
        );
    }
    Ok(ClientOutcome::Finished(Box::new(
        responder.summary(plant_report),
    )))
}
