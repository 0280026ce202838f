//! `crawler-controller run`: a controller of a co-simulation run over zenoh.
//!
//! The controller queries the plant's [`ModelInfo`] (retrying until the plant exists, so either
//! process may start first), builds its policy for that plant, declares its liveliness token
//! (which is how it joins the run) and then answers every `State(n)` with `Actuation(n)`. It also
//! publishes the models' predictions for the wave it applies, for the recorder.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use std::sync::Arc;

use crossbeam_channel::{unbounded, Receiver};
use serde::Serialize;
use zenoh::qos::CongestionControl;
use zenoh::sample::SampleKind;
use zenoh::Wait;

use crawler_cli::Exit;
use crawler_plant::params::{Body, Boundary, Friction};
use crawler_plant::scenario::Scenario;
use crawler_plant::wave::Wave;
use crawler_protocol::{
    decode, encode, Actuation as ActuationMsg, FinalReport, ModelInfo, ModelPrediction,
    Prediction as PredictionMsg, ProcessState, Rejections, Role, RunKeys, RunLimits, Series, State,
    Status, WaveMsg, PROTOCOL_VERSION,
};
use crawler_transport::budget::{ByteBudget, Charged};
use crawler_transport::gate::{self, Gate, Refused};
use crawler_transport::{Credential, Network, Seal};

/// The smallest byte budget of the state inbox: a plant has
/// one state in flight; this holds eight of a 28 000-cell run's.
pub const STATE_INBOX_BYTES: usize = 8 << 20;

/// Byte budget of the plant's statuses waiting to be read: their own, so that a backlog of
/// states never crowds out the plant's final status (about one status a second arrives).
pub const STATUS_INBOX_BYTES: usize = 4 << 20;

use crate::controller::{Actuation, Context, FeedbackOptions, Insight, Observation, PolicyOptions};
use crate::operating_point::OperatingPoint;
use crate::paper_model::{first_order_harmonic, PaperModel, PaperTerms};
use crate::prediction::{Model, Prediction, Validity};
use crate::travelling_wave::TravellingWaveModel;

/// Options of `crawler-controller run`.
#[derive(Debug, Clone)]
pub struct ClientOptions {
    /// Registered policy name.
    pub policy: String,
    /// Policy options.
    pub options: PolicyOptions,
    /// Settings of the feedback policies.
    pub feedback: FeedbackOptions,
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

/// Predicted against simulated metrics at the end of a run.
#[derive(Debug, Clone, Serialize)]
pub struct FinalSummary {
    /// Policy.
    pub policy: String,
    /// The last wave applied.
    pub wave: Option<WaveMsg>,
    /// The plant's final report, from its `finished` status, if received.
    pub plant: Option<FinalReport>,
    /// The models' predictions for the last wave.
    pub predictions: Vec<ModelPrediction>,
    /// Steps answered.
    pub steps: u64,
}

impl FinalSummary {
    /// A table of predicted against simulated metrics, headed by what the plant's window was.
    /// Errors are relative, except for the stuck fraction (a share, often near zero), whose
    /// difference is given in absolute terms.
    pub fn table(&self) -> String {
        let steady = self.plant.as_ref().map(|p| p.window.steady);
        let mut out = match steady {
            Some(false) => "predicted (steady state of the last wave) against simulated (run averages: \
                            the actuation changed within the plant's window, so it is not a steady state):\n"
                .to_string(),
            _ => "predicted against simulated (plant's steady window):\n".to_string(),
        };
        if let Some(w) = self.wave {
            out += &format!(
                "wave: f0 = {:.4} N, k = {:.4} rad/m, omega = {:.4} rad/s\n",
                w.f0, w.k, w.omega
            );
        }
        let rows: [Row; 5] = [
            ("velocity V", "m/s", |m| m.velocity, |r| Some(r.velocity)),
            ("power P", "W", |m| m.power, |r| Some(r.power)),
            ("mileage M", "m/J", |m| m.mileage, |r| r.mileage),
            ("max stress", "Pa", |m| m.max_stress, |r| Some(r.max_stress)),
            (
                "stuck fraction",
                "",
                |m| m.stuck_fraction,
                |r| Some(r.stuck_fraction),
            ),
        ];
        out += &format!("{:<16} {:>14}", "metric", "plant");
        for m in &self.predictions {
            out += &format!(" {:>14} {:>8}", m.model, "error");
        }
        out += "\n";
        for (name, unit, get, simulated) in &rows {
            let sim = self.plant.as_ref().and_then(simulated);
            let share = *name == "stuck fraction";
            out += &format!(
                "{:<16} {:>14}",
                format!("{name} {unit}").trim_end(),
                fmt(sim)
            );
            for m in &self.predictions {
                let p = get(m);
                let err = match (p, sim) {
                    (Some(p), Some(s)) if share => format!("{:+.4}", p - s),
                    (Some(p), Some(s)) if s != 0.0 => format!("{:+.2}%", 100.0 * (p / s - 1.0)),
                    _ => "-".into(),
                };
                out += &format!(" {:>14} {:>8}", fmt(p), err);
            }
            out += "\n";
        }
        out
    }
}

/// A row of the comparison table: label, unit, the model's value, the plant's value.
type Row = (
    &'static str,
    &'static str,
    fn(&ModelPrediction) -> Option<f64>,
    fn(&FinalReport) -> Option<f64>,
);

fn fmt(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.5e}"))
}

/// The plant's parameters as a controller context: what the plant tells (its body, grid, step and
/// the friction it discloses) over the controller's own scenario file (task, limits, default
/// wave). When the plant does not disclose its pipe, the pipe map of the controller's file is
/// dropped too, so that no policy can read the environment from a file it happens to share.
pub fn context_of(
    info: &ModelInfo,
    scenario: &Scenario,
    options: PolicyOptions,
    feedback: FeedbackOptions,
) -> Context {
    let mut scenario = scenario.clone();
    if !info.disclosed {
        scenario.plant.pipe.features.clear();
        scenario.plant.pipe.disclose = false;
    }
    scenario.plant.body = Body {
        area: info.area,
        density: info.density,
        youngs_modulus: info.youngs_modulus,
    };
    scenario.plant.friction = Friction {
        viscous: info.viscous,
        dry: info.dry,
        eps: info.eps,
        n_f: info.n_f,
    };
    scenario.plant.length = info.length;
    scenario.plant.boundary = if info.boundary == "free" {
        Boundary::Free
    } else {
        Boundary::Periodic
    };
    scenario.plant.numerics.cells = info.cells as usize;
    scenario.plant.numerics.step = info.step;
    Context {
        body: scenario.plant.body,
        friction: scenario.plant.friction,
        length: info.length,
        boundary: scenario.plant.boundary,
        cells: info.cells as usize,
        step: info.step,
        scenario,
        options,
        feedback,
    }
}

/// The paper's reconstructed tail displacement `u(0, t) = u_c (mu0 + eps mu1)` as a series.
pub fn paper_tail(op: &OperatingPoint, harmonics: u32) -> Option<Series> {
    let t = PaperTerms::at(op);
    let v = PaperModel::velocity(op)?;
    let uc = op.u_c();
    let eps = op.friction.eps;
    let shift = t.phi0 - op.wave.phase;
    // xi at x = 0 is -(omega t + phi0 - phase): cos(n xi - phi_n) = cos(n omega t + n shift + phi_n).
    let mut h = Vec::new();
    for n in 1..=harmonics {
        let (rn, phin) = first_order_harmonic(&t, n)?;
        let (mut re, mut im) = (
            (n as f64 * shift + phin).cos() * eps * rn,
            (n as f64 * shift + phin).sin() * eps * rn,
        );
        if n == 1 {
            re -= t.r0 * shift.cos();
            im -= t.r0 * shift.sin();
        }
        h.push((uc * (re * re + im * im).sqrt(), im.atan2(re)));
    }
    Some(Series {
        omega: op.wave.omega,
        drift: v,
        harmonics: h,
    })
}

fn model_prediction(p: &Prediction, tail: Option<Series>) -> ModelPrediction {
    ModelPrediction {
        model: p.model.to_string(),
        velocity: p.velocity,
        power: p.power,
        mileage: p.mileage.filter(|m| m.is_finite()),
        max_stress: p.max_stress,
        stuck_fraction: p.stuck_fraction,
        validity: match &p.validity {
            Validity::Valid => "valid".into(),
            Validity::OutsideValidity(r) => r.clone(),
        },
        tail,
    }
}

/// The paper model's and the improved model's predictions for `wave` on the plant of `ctx`.
pub fn predictions(ctx: &Context, wave: Wave) -> Vec<ModelPrediction> {
    let op = OperatingPoint {
        body: ctx.body,
        friction: ctx.friction,
        wave,
        wavelengths: (wave.k * ctx.length / std::f64::consts::TAU)
            .round()
            .max(1.0),
    };
    let paper = PaperModel { harmonics: 15 };
    vec![
        model_prediction(&paper.predict(&op), paper_tail(&op, 15)),
        model_prediction(&TravellingWaveModel::default().predict(&op), None),
    ]
}

/// A feedback controller's report as a model prediction: its own model's numbers (if any) under
/// its name, and its text (estimates, confidence, decision) where a model says how valid it is.
fn insight_prediction(i: &Insight) -> ModelPrediction {
    let mut m = match &i.prediction {
        Some(p) => model_prediction(p, None),
        None => ModelPrediction {
            model: "controller".into(),
            velocity: None,
            power: None,
            mileage: None,
            max_stress: None,
            stuck_fraction: None,
            validity: String::new(),
            tail: None,
        },
    };
    m.validity = i.text.clone();
    m
}

/// The plant's liveliness (never dropped).
enum Event {
    Up(String),
    Down(String),
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
    let limits = RunLimits::new(info.cells as usize);
    // What arrives is checked in the callbacks (size, seal) and queued within a byte budget.
    let refused = Arc::new(Refused::default());
    let budget = ByteBudget::new(STATE_INBOX_BYTES.max(8 * limits.state()));
    let (state_tx, state_rx) = unbounded::<Charged<Vec<u8>>>();
    let state_gate = Gate::new(limits.state(), link.seal.clone(), refused.clone());
    let state_budget = budget.clone();
    let _states = session
        .declare_subscriber(keys.state())
        .callback(move |s| {
            if let Ok(bytes) = state_gate.admit(&s) {
                let len = bytes.len();
                if let Some(charged) = state_budget.charge(bytes, len) {
                    let _ = state_tx.send(charged);
                }
            }
        })
        .wait()
        .map_err(z)?;
    let (ev_tx, ev_rx) = unbounded::<Event>();
    // Statuses are few (about one a second) and have a budget of their own: a backlog of states
    // must never drop the plant's final status, and a flood of statuses never crowds out states.
    let (status_tx, status_rx) = unbounded::<Charged<Status>>();
    let status_gate = Gate::new(
        RunLimits::text_message(),
        link.seal.clone(),
        refused.clone(),
    );
    let status_budget = ByteBudget::new(STATUS_INBOX_BYTES.max(2 * RunLimits::text_message()));
    let _status = session
        .declare_subscriber(keys.status(Role::Plant))
        .callback(move |s| {
            let Ok(bytes) = status_gate.admit(&s) else {
                return;
            };
            let len = bytes.len();
            if let Ok(st) = decode::<Status>(&bytes) {
                if let Some(charged) = status_budget.charge(st, len) {
                    let _ = status_tx.send(charged);
                }
            }
        })
        .wait()
        .map_err(z)?;
    let status_pub = session
        .declare_publisher(keys.status(Role::Controller))
        .wait()
        .map_err(z)?;
    let publish_status = |state: ProcessState, message: &str, step: u64| {
        publish_status(&status_pub, seal, id, (state, message, step));
    };

    let ctx = context_of(
        &info,
        &opts.scenario,
        opts.options.clone(),
        opts.feedback.clone(),
    );
    let mut policy = crate::policies::build(&opts.policy, &ctx)?;
    eprintln!(
        "crawler-controller: plant found ({} cells, L = {} m, H = {} s); policy {}",
        info.cells,
        info.length,
        info.step,
        policy.describe()
    );

    let actuation_pub = session
        .declare_publisher(keys.actuation())
        .congestion_control(CongestionControl::Block)
        .express(true)
        .wait()
        .map_err(z)?;
    let prediction_pub = session
        .declare_publisher(keys.prediction())
        .wait()
        .map_err(z)?;
    let plant_keys = keys.clone();
    let _plant_alive = session
        .liveliness()
        .declare_subscriber(keys.alive_all(Role::Plant))
        .history(true)
        .callback(move |s| {
            if let Some(pid) = plant_keys.id_of_alive_key(Role::Plant, s.key_expr().as_str()) {
                let _ = ev_tx.send(match s.kind() {
                    SampleKind::Put => Event::Up(pid.to_string()),
                    SampleKind::Delete => Event::Down(pid.to_string()),
                });
            }
        })
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
        &format!("policy {}", policy.name()),
        0,
    );

    let mut last_wave: Option<Wave> = None;
    // The step of the plant's last state (last: true) to us: the run's last step, which is the
    // model's `last_step` unless the plant ended the run early (task mode). Only at that step can
    // the plant have finished; a `finished` status that overtakes the last state waits for it
    // (a few at most, each dropped once the run goes on past its step).
    let mut last_state_step: Option<u64> = None;
    let mut latest_step: Option<u64> = None;
    let mut pending_finished: BTreeMap<u64, Status> = BTreeMap::new();
    let mut last_predictions = Vec::new();
    let mut answered = 0u64;
    let plant_report: Option<FinalReport>;
    // The plant is the process whose liveliness token we see; statuses from any other id are
    // ignored (a stray publisher cannot end the run for us), and so are states for another
    // controller (if no state ever comes for us, we report who has the run).
    let mut plant_id: Option<String> = None;
    let mut other_controller: Option<String> = None;
    let mut ignored = 0u64;
    let deadline_idle = opts.wait_timeout.max(Duration::from_secs(60));
    let mut last_seen = Instant::now();
    loop {
        crossbeam_channel::select! {
            recv(interrupt) -> _ => {
                publish_status(ProcessState::Stopped, "interrupted", answered);
                return Ok(ClientOutcome::Ended { reason: "interrupted".into(), exit: Exit::Interrupted });
            }
            recv(ev_rx) -> ev => match ev {
                Ok(Event::Up(pid))
                    if plant_id.is_none() => {
                        plant_id = Some(pid);
                    }
                Ok(Event::Down(pid)) if plant_id.as_deref() == Some(pid.as_str()) => {
                    return Ok(ClientOutcome::Ended { reason: "the plant left the run".into(), exit: Exit::PeerLost });
                }
                _ => {}
            },
            recv(status_rx) -> st => {
                let Ok(st) = st else { continue };
                let (st, _charge) = st.split();
                if plant_id.as_deref() != Some(st.id.as_str()) || st.role != Role::Plant {
                    ignored += 1;
                    continue;
                }
                if st.state == ProcessState::Finished
                    && last_state_step.is_none()
                    && finished_may_follow(&st, &info, latest_step)
                {
                    // the last state may still be on its way (another channel): wait for it
                    if pending_finished.len() < PENDING_FINISHED_MAX {
                        pending_finished.entry(st.step).or_insert(st);
                    } else {
                        ignored += 1;
                    }
                    continue;
                }
                if !terminal_is_consistent(&st, &info, last_state_step) {
                    ignored += 1;
                    eprintln!(
                        "crawler-controller: ignoring an inconsistent plant status \"{}\" at step {} (the run ends at step {})",
                        st.state, st.step, info.last_step
                    );
                    continue;
                }
                match st.state {
                    ProcessState::Finished => {
                        plant_report = st.report;
                        break;
                    }
                    ProcessState::Failed | ProcessState::Stopped if answered > 0 || st.step > 0 => {
                        publish_status(ProcessState::Stopped, &format!("plant {}: {}", st.state, st.message), answered);
                        return Ok(ClientOutcome::Ended { reason: format!("the plant {}: {}", st.state, st.message), exit: Exit::Failure });
                    }
                    _ => {}
                }
            },
            recv(state_rx) -> bytes => {
                let Ok(bytes) = bytes else { continue };
                let state: State = match decode(bytes.get()) {
                    Ok(s) => s,
                    Err(e) => {
                        ignored += 1;
                        if ignored <= 5 {
                            eprintln!("crawler-controller: ignoring an invalid state: {e}");
                        }
                        continue;
                    }
                };
                if state.controller != id {
                    if !state.controller.is_empty() {
                        other_controller = Some(state.controller.clone());
                    }
                    ignored += 1;
                    continue; // for another controller, or before we joined
                }
                last_seen = Instant::now();
                if state.u.len() != ctx.cells {
                    ignored += 1;
                    continue;
                }
                if state.last {
                    if last_state_step.is_none() && last_state_fits(state.step, &info, latest_step) {
                        last_state_step = Some(state.step);
                        if let Some(st) = pending_finished.remove(&state.step) {
                            plant_report = st.report;
                            break;
                        }
                    } else {
                        ignored += 1;
                    }
                    continue; // the plant's finished status ends the run
                }
                latest_step = Some(state.step);
                // a finished status for a step the run went on past was not the plant's
                while let Some(entry) = pending_finished.first_entry() {
                    if *entry.key() > state.step {
                        break;
                    }
                    let st = entry.remove();
                    ignored += 1;
                    eprintln!(
                        "crawler-controller: ignoring an inconsistent plant status \"finished\" at step {} (the run went on to step {})",
                        st.step, state.step
                    );
                }
                let obs = Observation {
                    step: state.step,
                    time: state.time,
                    u: &state.u,
                    v: &state.vel,
                    tension: &state.tension,
                    stuck: &state.stuck,
                    mean_speed: state.mean_speed,
                    input_power: state.input_power,
                };
                let (wave, field) = match policy.act(&obs) {
                    Actuation::Wave(w) => (Some(w), None),
                    Actuation::Field(f) => (None, Some(f)),
                };
                let insight = policy.insight();
                // published after the actuation, so that the plant does not wait for it
                let mut prediction = None;
                if let Some(w) = wave {
                    if last_wave != Some(w) || insight.is_some() {
                        if last_wave != Some(w) {
                            last_predictions = predictions(&ctx, w);
                        }
                        let mut models = last_predictions.clone();
                        if let Some(i) = &insight {
                            models.push(insight_prediction(i));
                        }
                        let msg = PredictionMsg {
                            v: PROTOCOL_VERSION,
                            controller: id.to_string(),
                            policy: policy.name().to_string(),
                            step: state.step,
                            wave: WaveMsg { f0: w.f0, k: w.k, omega: w.omega, phase: w.phase },
                            models,
                        };
                        prediction = Some(msg);
                        last_wave = Some(w);
                    }
                }
                let msg = ActuationMsg {
                    v: PROTOCOL_VERSION,
                    step: state.step,
                    controller: id.to_string(),
                    wave: wave.map(|w| WaveMsg { f0: w.f0, k: w.k, omega: w.omega, phase: w.phase }),
                    field,
                };
                gate::put(&actuation_pub, seal, encode(&msg)).map_err(z)?;
                answered += 1;
                if let Some(p) = prediction {
                    let _ = gate::put(&prediction_pub, seal, encode(&p));
                }
            },
            default(Duration::from_millis(500)) => {
                if last_seen.elapsed() > deadline_idle {
                    let reason = match &other_controller {
                        Some(c) => format!("run {} already has controller {c}", keys.run()),
                        None => format!("no state from the plant for {:.0} s", deadline_idle.as_secs_f64()),
                    };
                    return Ok(ClientOutcome::Ended { reason, exit: Exit::Timeout });
                }
            },
        }
    }
    publish_status(
        ProcessState::Finished,
        &format!("answered {answered} steps"),
        answered,
    );
    let refused_total = refused.oversize() + refused.unsealed() + budget.overflow();
    if ignored > 0 || refused_total > 0 {
        eprintln!(
            "crawler-controller: ignored {ignored} messages (invalid, or not from this run's plant); refused at arrival: {} oversized, {} without a valid seal, {} beyond the inbox's {} bytes",
            refused.oversize(),
            refused.unsealed(),
            budget.overflow(),
            budget.cap()
        );
    }
    Ok(ClientOutcome::Finished(Box::new(FinalSummary {
        policy: policy.name().to_string(),
        wave: last_wave.map(|w| WaveMsg {
            f0: w.f0,
            k: w.k,
            omega: w.omega,
            phase: w.phase,
        }),
        plant: plant_report,
        predictions: last_predictions,
        steps: answered,
    })))
}

/// Most `finished` statuses held while the plant's last state is awaited.
const PENDING_FINISHED_MAX: usize = 8;

/// Whether a plant status can be what it says: `finished` only at the step of the plant's last
/// state to this controller (`last_state_step`: the model's last step, or an earlier one where
/// the plant decided its task and ended the run), `failed` and `stopped` only within the run's
/// steps. Non-terminal states are always consistent.
pub fn terminal_is_consistent(st: &Status, info: &ModelInfo, last_state_step: Option<u64>) -> bool {
    match st.state {
        ProcessState::Finished => st.step <= info.last_step && last_state_step == Some(st.step),
        ProcessState::Failed | ProcessState::Stopped => st.step <= info.last_step,
        ProcessState::Waiting | ProcessState::Running => true,
    }
}

/// Whether a `finished` status that arrives before the plant's last state can still turn out
/// consistent: its step is within the run and after the latest state this controller answered.
pub fn finished_may_follow(st: &Status, info: &ModelInfo, latest_step: Option<u64>) -> bool {
    st.step <= info.last_step && latest_step.is_none_or(|l| st.step > l)
}

/// Whether a state marked `last` at `step` can be the plant's last: within the run, and either
/// the model's last step or the step right after the latest state this controller answered (the
/// plant ends a task-mode run early, at the step that decided the task).
pub fn last_state_fits(step: u64, info: &ModelInfo, latest_step: Option<u64>) -> bool {
    step <= info.last_step && (step == info.last_step || latest_step.is_some_and(|l| l + 1 == step))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(last_step: u64) -> ModelInfo {
        ModelInfo {
            v: PROTOCOL_VERSION,
            run: "r".into(),
            cells: 2,
            length: 1.0,
            step: 0.001,
            start_time: 0.0,
            last_step,
            area: 1e-4,
            density: 0.1,
            youngs_modulus: 140e3,
            viscous: 1.0,
            dry: 1.0,
            eps: 0.1,
            n_f: 0.5,
            settle: 5.0,
            model_description: "{}".into(),
            boundary: "periodic".into(),
            disclosed: true,
        }
    }

    fn status(state: &str, step: u64) -> Status {
        Status {
            v: PROTOCOL_VERSION,
            role: Role::Plant,
            id: "p".into(),
            state: ProcessState::parse(state).unwrap(),
            message: String::new(),
            step,
            rejected: Default::default(),
            report: None,
        }
    }

    #[test]
    fn finished_is_believed_only_at_the_step_of_the_plants_last_state() {
        let info = info(8000);
        // the whole run
        assert!(terminal_is_consistent(
            &status("finished", 8000),
            &info,
            Some(8000)
        ));
        // before the last state came, and at another step than the last state's
        assert!(!terminal_is_consistent(
            &status("finished", 8000),
            &info,
            None
        ));
        assert!(!terminal_is_consistent(
            &status("finished", 1000),
            &info,
            Some(8000)
        ));
        // a task-mode run the plant ended at step 4321 (its last state said so)
        assert!(terminal_is_consistent(
            &status("finished", 4321),
            &info,
            Some(4321)
        ));
        assert!(!terminal_is_consistent(
            &status("finished", 8000),
            &info,
            Some(4321)
        ));
        // never beyond the run, whatever state came
        assert!(!terminal_is_consistent(
            &status("finished", 9000),
            &info,
            Some(9000)
        ));
        // failed and stopped: anywhere within the run
        assert!(terminal_is_consistent(&status("failed", 10), &info, None));
        assert!(terminal_is_consistent(
            &status("stopped", 8000),
            &info,
            None
        ));
        assert!(!terminal_is_consistent(
            &status("failed", 8001),
            &info,
            None
        ));
        assert!(!terminal_is_consistent(
            &status("stopped", u64::MAX),
            &info,
            None
        ));
        assert!(terminal_is_consistent(
            &status("running", 99_999),
            &info,
            None
        ));
    }

    #[test]
    fn a_last_state_fits_only_right_after_the_latest_answered_step_or_at_the_end() {
        let info = info(8000);
        assert!(last_state_fits(8000, &info, Some(7999)));
        // resumed at the end: no state answered before
        assert!(last_state_fits(8000, &info, None));
        // task mode: right after the step just answered
        assert!(last_state_fits(4321, &info, Some(4320)));
        // a gap, a step already answered, or beyond the run: not the plant's last state
        assert!(!last_state_fits(4321, &info, Some(100)));
        assert!(!last_state_fits(4321, &info, Some(4321)));
        assert!(!last_state_fits(4321, &info, None));
        assert!(!last_state_fits(999_999, &info, Some(999_998)));
        // a finished status ahead of the last state may wait for it only if it is ahead of the
        // run and within it
        assert!(finished_may_follow(
            &status("finished", 4321),
            &info,
            Some(4320)
        ));
        assert!(finished_may_follow(&status("finished", 8000), &info, None));
        assert!(!finished_may_follow(
            &status("finished", 1000),
            &info,
            Some(4320)
        ));
        assert!(!finished_may_follow(
            &status("finished", 8001),
            &info,
            Some(4320)
        ));
    }
}
