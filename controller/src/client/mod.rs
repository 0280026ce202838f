//! `crawler-controller run`: a controller of a co-simulation run over zenoh.
//!
//! The controller asks the plant for its [`ModelInfo`] with a fresh challenge (retrying until
//! the plant exists, so either process may start first), and believes only the sealed answer
//! that echoes it: that answer names the plant (its process id) and the run instance, which every
//! message it takes from then on must carry. It builds its policy for that plant, declares its
//! liveliness token and asks to join with a sealed request (again every 500 ms until the plant's
//! states are addressed to it): to join a run without a controller, or with `--take-over` to take
//! a run over at a step boundary. Then it answers every `State(n)` addressed to it with
//! `Actuation(n)`, each step once (a resent state gets the same answer again, [`watch`]), and
//! publishes the models' predictions for the wave it applies, for the recorder. A state addressed
//! to another controller after its own ends its part of the run (handed over).

mod answer;
mod inbox;
mod predictions;
mod summary;
pub mod watch;

use std::time::{Duration, Instant};

use crossbeam_channel::Receiver;

use crawler_cli::Exit;
use crawler_physics::scenario::Scenario;
use crawler_protocol::{
    decode, encode, Actuation as ActuationMsg, FinalReport, Join, ModelInfo, ProcessId,
    ProcessState, Rejections, Role, RunKeys, RunLimits, State, Status, PROTOCOL_VERSION,
};
use crawler_transport::gate::RunInstance;
use crawler_transport::participant::{Congestion, Outlet};
use crawler_transport::{Credential, Network, Participant, Seal};

use answer::Responder;
use crawler_policies::Params;
use inbox::Inbox;
pub use inbox::{state_inbox_bytes, status_inbox_bytes, STATE_INBOX_BYTES, STATUS_INBOX_BYTES};
pub use predictions::{briefing_of, context_of, paper_tail, predictions};
pub use summary::{FinalSummary, HandOver};
pub use watch::{finished_may_follow, last_state_fits, terminal_is_consistent};
use watch::{Verdict, Watch};

/// How often a controller asks to join until the plant's states are addressed to it.
const JOIN_EVERY: Duration = Duration::from_millis(500);

/// When a controller takes a run over.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TakeOver {
    /// At the next step boundary.
    Next,
    /// At the first step boundary at or after this simulated time, s.
    At(f64),
}

/// The first communication step at or after time `t` (s) of the run that `info` describes (0
/// for a time before its start).
pub fn step_at(t: f64, info: &ModelInfo) -> u64 {
    let steps = (t - info.start_time) / info.step;
    (steps * (1.0 - 1e-12)).ceil().max(0.0) as u64
}

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
    /// Take the run over from its controller (`None`: join a run that has none).
    pub take_over: Option<TakeOver>,
    /// Fault injection for tests of the plant's resend path: hold the answer to this step for
    /// this long (the plant resends the state meanwhile).
    pub stall: Option<(u64, Duration)>,
}

/// Interrupt signal for the client loop.
#[derive(Debug, Clone, Copy)]
pub struct Interrupt;

/// How the controller's run ended.
#[derive(Debug)]
pub enum ClientOutcome {
    /// The plant reached the end of the run.
    Finished(Box<FinalSummary>),
    /// Another controller took the run over; this one's part ended cleanly.
    HandedOver(Box<FinalSummary>),
    /// The run ended otherwise.
    Ended {
        /// Why.
        reason: String,
        /// The process's exit code.
        exit: Exit,
    },
}

/// The controller's participant in the run and what it connected with.
struct Link {
    participant: Participant,
    credential: Option<Credential>,
    limit: usize,
}

impl Link {
    /// Connects to the plant as controller `id` of run instance `run` presenting `credential`'s
    /// password (if any), reassembling messages of at most `limit` bytes; `None` if `give_up`
    /// says so first.
    fn connect(
        network: &crawler_transport::Network,
        (id, run): (ProcessId, RunInstance),
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
            participant: Participant::new(session, Role::Controller, id, seal, run),
            credential,
            limit,
        }))
    }

    fn close(self) {
        self.participant.close();
    }
}

/// Builds the controller's policy once the plant has told its body, friction and grid.
pub type BuildPolicy<'a> = Box<
    dyn FnOnce(&crawler_policies::Context) -> anyhow::Result<Box<dyn crawler_policies::Policy>>
        + Send
        + 'a,
>;

/// Runs the controller until the run ends, with the registered policy `opts.policy`.
pub fn run(opts: ClientOptions, interrupt: Receiver<Interrupt>) -> anyhow::Result<ClientOutcome> {
    let (name, params) = (opts.policy.clone(), opts.params.clone());
    let build: BuildPolicy<'_> = Box::new(move |ctx| crawler_policies::build(&name, ctx, &params));
    run_with(opts, build, interrupt)
}

/// Runs the controller until the run ends, with the policy `build` makes (a policy that is not
/// registered: the Python package's); `opts.policy` and `opts.params` are not used.
pub fn run_with(
    opts: ClientOptions,
    build: BuildPolicy<'_>,
    interrupt: Receiver<Interrupt>,
) -> anyhow::Result<ClientOutcome> {
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
    let run_instance = RunInstance::default();
    let link = Link::connect(
        &opts.network,
        (id, run_instance.clone()),
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
    let (info, plant) = match discover(&link, &keys, &waited(deadline))? {
        Ok(found) => found,
        Err(ended) => {
            link.close();
            return Ok(ended);
        }
    };
    // The run's largest legal message may exceed what the first session reassembles (very
    // large grids): then reconnect with the run's own limit (same run instance, same plant).
    let limits = RunLimits::new(info.cells as usize);
    let link = if limits.largest() > link.limit {
        let credential = link.credential.clone();
        link.close();
        let give_up = waited(Instant::now() + opts.wait_timeout);
        let mut ended = None;
        match Link::connect(
            &opts.network,
            (id, run_instance),
            credential,
            limits.largest(),
            &mut || {
                ended = give_up();
                ended.is_some()
            },
        )? {
            Some(link) => link,
            None => return Ok(ended.expect("gave up for a reason")),
        }
    } else {
        link
    };
    let outcome = serve(&link, &keys, &opts, build, &interrupt, (info, plant));
    link.close();
    outcome
}

/// Asks the plant for its model description with a fresh challenge until a sealed answer of
/// this run comes (or `give_up` gives a reason to stop): the description, and the plant's id;
/// the answer's run instance is learnt.
fn discover(
    link: &Link,
    keys: &RunKeys,
    give_up: &dyn Fn() -> Option<ClientOutcome>,
) -> anyhow::Result<Result<(ModelInfo, ProcessId), ClientOutcome>> {
    let p = &link.participant;
    loop {
        if let Some(ended) = give_up() {
            return Ok(Err(ended));
        }
        let answer = p.query(
            &keys.model(),
            Role::Plant,
            RunLimits::before_model(),
            Duration::from_millis(500),
        )?;
        if let Some(a) = answer {
            match decode::<ModelInfo>(&a.bytes) {
                Ok(info) if info.run == keys.run() => {
                    p.run().learn(a.header.run);
                    return Ok(Ok((info, a.header.sender)));
                }
                Ok(info) => eprintln!(
                    "crawler-controller: ignoring the model description of another run ({})",
                    info.run
                ),
                Err(e) => {
                    eprintln!("crawler-controller: ignoring an invalid model description: {e}")
                }
            }
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// Answers the plant `plant` of `info` until the run ends or another controller takes it over.
fn serve(
    link: &Link,
    keys: &RunKeys,
    opts: &ClientOptions,
    build: BuildPolicy<'_>,
    interrupt: &Receiver<Interrupt>,
    (info, plant): (ModelInfo, ProcessId),
) -> anyhow::Result<ClientOutcome> {
    let p = &link.participant;
    let id = p.id();
    let inbox = Inbox::open(p, keys, &RunLimits::new(info.cells as usize), plant)?;
    let status_out = p.outlet(&keys.status(Role::Controller), Congestion::Block, false)?;
    let publish_status = |state: ProcessState, message: &str, step: u64| {
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
        let _ = status_out.put(encode(&s));
    };

    let ctx = context_of(&info, &opts.scenario);
    let policy = build(&ctx)?;
    eprintln!(
        "crawler-controller: plant {plant} found ({} cells, L = {} m, communication step H = {:.6e} s); policy {}",
        info.cells,
        info.length,
        info.step,
        policy.describe()
    );
    let mut responder = Responder::new(policy, &ctx, id.as_str());

    let actuation_out = p.outlet(&keys.actuation(), Congestion::Block, true)?;
    // Blocking like the actuation: a wave's predictions are sent once, and the recorder gets
    // them through the plant's link, behind its states; a dropping publisher lost them whenever
    // that link was congested for a moment, and with them the models' lines for the whole run.
    let prediction_out = p.outlet(&keys.prediction(), Congestion::Block, false)?;
    let join_out = p.outlet(&keys.join(), Congestion::Block, true)?;
    // The token says only when this process goes away; joining is the sealed request below.
    let _token = p.token(keys)?;
    let take_over = opts.take_over.map(|t| match t {
        TakeOver::Next => 0,
        TakeOver::At(time) => step_at(time, &info),
    });
    let join = encode(&Join {
        v: PROTOCOL_VERSION,
        controller: id.to_string(),
        policy: responder.policy().to_string(),
        take_over,
    });
    join_out.put(join.clone())?;
    let next_join = Instant::now() + JOIN_EVERY;
    let asked = asked_to_join(responder.policy(), take_over);
    eprintln!("crawler-controller: {asked}");
    publish_status(ProcessState::Running, &asked, 0);

    let mut answering = Answering {
        id,
        take_over,
        responder: &mut responder,
        watch: Watch::new(id.as_str(), &info, plant.as_str()),
        actuation_out: &actuation_out,
        prediction_out: &prediction_out,
        join_out: &join_out,
        join: &join,
        next_join,
        answer: None,
        first_step: None,
        stall: opts.stall,
        deadline_idle: opts.wait_timeout.max(Duration::from_secs(60)),
        last_seen: Instant::now(),
    };
    let outcome = match answering.run(&inbox, interrupt, keys, &publish_status)? {
        LoopEnd::Done(outcome) => outcome.map(|report| report.map(|r| *r)),
        LoopEnd::Ended(ended) => return Ok(ended),
    };
    let Answering {
        watch, first_step, ..
    } = answering;
    Ok(wrap_up(
        outcome,
        responder,
        &watch,
        first_step,
        p,
        &publish_status,
    ))
}

/// What a controller running `policy` says it asked for: to join, or to take the run over at
/// step `take_over` (0: the next).
fn asked_to_join(policy: &str, take_over: Option<u64>) -> String {
    match take_over {
        None => format!("policy {policy}; asked to join"),
        Some(0) => format!("policy {policy}; asked to take the run over at the next step"),
        Some(n) => format!("policy {policy}; asked to take the run over at step {n}"),
    }
}

/// How the answering loop ended.
enum LoopEnd {
    /// The run finished (with the plant's final report, if it sent one) or was handed over:
    /// this controller's part ends with a summary.
    Done(Result<Option<Box<FinalReport>>, HandOver>),
    /// The run ended otherwise: this is the outcome.
    Ended(ClientOutcome),
}

/// The controller at work in the run: where it sends, and what it keeps between messages.
struct Answering<'s, 'a> {
    /// This controller's id.
    id: ProcessId,
    /// The step at which this controller asked to take the run over (0: the next), if it did.
    take_over: Option<u64>,
    /// The policy answering the states.
    responder: &'s mut Responder<'a>,
    /// What the controller knows of its plant and of the run's end.
    watch: Watch,
    /// Publisher of the actuations.
    actuation_out: &'s Outlet,
    /// Publisher of the models' predictions.
    prediction_out: &'s Outlet,
    /// Publisher of the join request.
    join_out: &'s Outlet,
    /// The encoded join request.
    join: &'s [u8],
    /// When to ask to join again if the plant's states are not addressed to this controller yet.
    next_join: Instant,
    /// The answer to the latest step, sent again if the plant resends its state.
    answer: Option<ActuationMsg>,
    /// The first step this controller answered.
    first_step: Option<u64>,
    /// The answer to hold, and for how long (`--stall`), until it is held.
    stall: Option<(u64, Duration)>,
    /// Longest wait for a state before giving up.
    deadline_idle: Duration,
    /// When the last state that keeps this controller waiting came.
    last_seen: Instant,
}

impl Answering<'_, '_> {
    /// Answers the plant's messages from `inbox` until the run ends, `interrupt` comes, or no
    /// state came for `deadline_idle`; `publish_status` tells the run of a stop.
    fn run(
        &mut self,
        inbox: &Inbox,
        interrupt: &Receiver<Interrupt>,
        keys: &RunKeys,
        publish_status: &dyn Fn(ProcessState, &str, u64),
    ) -> anyhow::Result<LoopEnd> {
        loop {
            let verdict = crossbeam_channel::select! {
                recv(interrupt) -> _ => {
                    publish_status(ProcessState::Stopped, "interrupted", self.responder.answered());
                    return Ok(LoopEnd::Ended(ClientOutcome::Ended { reason: "interrupted".into(), exit: Exit::Interrupted }));
                }
                recv(inbox.gone) -> pid => match pid {
                    Ok(pid) => self.watch.plant_down(pid.as_str()),
                    Err(_) => Verdict::Wait,
                },
                recv(inbox.statuses) -> st => match st {
                    Ok(st) => self.watch.status(st.split().0, self.responder.answered()),
                    Err(_) => Verdict::Wait,
                },
                recv(inbox.states) -> m => match m.map(|m| decode::<State>(&m.get().bytes)) {
                    Ok(Ok(state)) => self.state(&state)?,
                    Ok(Err(e)) => {
                        self.watch.ignore();
                        if self.watch.ignored() <= 5 {
                            eprintln!("crawler-controller: ignoring an invalid state: {e}");
                        }
                        Verdict::Wait
                    }
                    Err(_) => Verdict::Wait,
                },
                default(JOIN_EVERY) => {
                    if self.last_seen.elapsed() > self.deadline_idle {
                        let reason = match self.watch.other_controller() {
                            Some(c) => format!("run {} already has controller {c}", keys.run()),
                            None => format!("no state from the plant for {:.0} s", self.deadline_idle.as_secs_f64()),
                        };
                        return Ok(LoopEnd::Ended(ClientOutcome::Ended { reason, exit: Exit::Timeout }));
                    }
                    Verdict::Wait
                },
            };
            // until the plant's states are addressed to it, a controller asks again
            if self.watch.latest_step().is_none() && Instant::now() >= self.next_join {
                self.join_out.put(self.join.to_vec())?;
                self.next_join = Instant::now() + JOIN_EVERY;
            }
            for note in self.watch.take_notes() {
                eprintln!("crawler-controller: {note}");
            }
            match verdict {
                Verdict::Wait | Verdict::Answer | Verdict::Resend => {}
                Verdict::Finished(report) => return Ok(LoopEnd::Done(Ok(report))),
                Verdict::HandedOver { to, step } => {
                    return Ok(LoopEnd::Done(Err(HandOver { to, step })))
                }
                Verdict::Ended(reason) => {
                    publish_status(ProcessState::Stopped, &reason, self.responder.answered());
                    return Ok(LoopEnd::Ended(ClientOutcome::Ended {
                        reason,
                        exit: Exit::Failure,
                    }));
                }
                Verdict::PlantLeft => {
                    return Ok(LoopEnd::Ended(ClientOutcome::Ended {
                        reason: "the plant left the run".into(),
                        exit: Exit::PeerLost,
                    }))
                }
            }
        }
    }

    /// Takes a decoded `state`: answers it if it is a new step for this controller, sends the
    /// same answer again if it is a resent one; the watch's verdict.
    fn state(&mut self, state: &State) -> anyhow::Result<Verdict> {
        // a controller waiting to take over waits as long as the run goes on
        if state.controller == self.id.as_str() || self.take_over.is_some() {
            self.last_seen = Instant::now();
        }
        let verdict = self.watch.state(state);
        match verdict {
            Verdict::Answer => {
                if let Some((step, hold)) = self.stall.filter(|(s, _)| *s == state.step) {
                    eprintln!(
                        "crawler-controller: holding the answer to step {step} for {} ms (--stall)",
                        hold.as_millis()
                    );
                    std::thread::sleep(hold);
                    self.stall = None;
                }
                self.first_step.get_or_insert(state.step);
                let (actuation, prediction) = self.responder.respond(state);
                self.actuation_out.put(encode(&actuation))?;
                if let Some(pr) = prediction {
                    let _ = self.prediction_out.put(encode(&pr));
                }
                self.answer = Some(actuation);
            }
            Verdict::Resend => {
                if let Some(a) = &self.answer {
                    self.actuation_out.put(encode(a))?;
                }
            }
            _ => {}
        }
        Ok(verdict)
    }
}

/// The end of this controller's part once the run finished or was handed over (`outcome`):
/// publishes the finished status, tells what was resent and ignored, and sums the run up.
fn wrap_up(
    outcome: Result<Option<FinalReport>, HandOver>,
    responder: Responder<'_>,
    watch: &Watch,
    first_step: Option<u64>,
    p: &Participant,
    publish_status: &dyn Fn(ProcessState, &str, u64),
) -> ClientOutcome {
    let answered = responder.answered();
    let said = match &outcome {
        Ok(_) => format!("answered {answered} steps"),
        Err(h) => format!(
            "answered {answered} steps; handed the run over to {} at step {}",
            h.to, h.step
        ),
    };
    publish_status(ProcessState::Finished, &said, answered);
    if watch.resent() > 0 {
        eprintln!(
            "crawler-controller: the plant resent {} states of steps already answered; each got the same answer again",
            watch.resent()
        );
    }
    let refusals = inbox::refusals(p);
    if watch.ignored() > 0 || refusals.is_some() {
        eprintln!(
            "crawler-controller: ignored {} messages (invalid, stale, or not for this controller); refused at arrival: {}",
            watch.ignored(),
            refusals.as_deref().unwrap_or("none")
        );
    }
    match outcome {
        Ok(report) => {
            ClientOutcome::Finished(Box::new(responder.summary(report, first_step, None)))
        }
        Err(h) => {
            eprintln!("crawler-controller: {said}");
            ClientOutcome::HandedOver(Box::new(responder.summary(None, first_step, Some(h))))
        }
    }
}
