//! `crawler-controller run`: a controller of a co-simulation run over zenoh.
//!
//! The controller queries the plant's [`ModelInfo`] (retrying until the plant exists, so either
//! process may start first), builds its policy for that plant, declares its liveliness token
//! (which is how it joins the run) and then answers every `State(n)` with `Actuation(n)`. It also
//! publishes the models' predictions for the wave it applies, for the recorder.

use std::time::{Duration, Instant};

use crossbeam_channel::{bounded, unbounded, Receiver};
use serde::Serialize;
use zenoh::qos::CongestionControl;
use zenoh::sample::SampleKind;
use zenoh::Wait;

use crawler_cli::Exit;
use crawler_plant::params::{Body, Boundary, Friction};
use crawler_plant::scenario::Scenario;
use crawler_plant::wave::Wave;
use crawler_protocol::{
    decode, encode, Actuation as ActuationMsg, ModelInfo, ModelPrediction,
    Prediction as PredictionMsg, Rejections, Role, RunKeys, Series, State, Status, WaveMsg,
    PROTOCOL_VERSION,
};
use crawler_transport::Network;

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
    /// The plant's final report (the object of `crawler-plant simulate --json`), if received.
    pub plant: Option<serde_json::Value>,
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
        let steady = self
            .plant
            .as_ref()
            .and_then(|p| p.pointer("/window/steady"))
            .and_then(|v| v.as_bool());
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
        let plant = |key: &str| {
            self.plant
                .as_ref()
                .and_then(|p| p.get(key))
                .and_then(|v| v.as_f64())
        };
        let rows: [Row; 5] = [
            ("velocity V", "m/s", |m| m.velocity),
            ("power P", "W", |m| m.power),
            ("mileage M", "m/J", |m| m.mileage),
            ("max stress", "Pa", |m| m.max_stress),
            ("stuck fraction", "", |m| m.stuck_fraction),
        ];
        let keys = [
            "velocity",
            "power",
            "mileage",
            "max_stress",
            "stuck_fraction",
        ];
        out += &format!("{:<16} {:>14}", "metric", "plant");
        for m in &self.predictions {
            out += &format!(" {:>14} {:>8}", m.model, "error");
        }
        out += "\n";
        for ((name, unit, get), key) in rows.iter().zip(keys) {
            let sim = plant(key);
            out += &format!(
                "{:<16} {:>14}",
                format!("{name} {unit}").trim_end(),
                fmt(sim)
            );
            for m in &self.predictions {
                let p = get(m);
                let err = match (p, sim) {
                    (Some(p), Some(s)) if key == "stuck_fraction" => format!("{:+.4}", p - s),
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

/// A row of the comparison table: label, unit, the model value.
type Row = (
    &'static str,
    &'static str,
    fn(&ModelPrediction) -> Option<f64>,
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

enum Event {
    Up(String),
    Down(String),
    Status(Status),
}

/// Runs the controller until the run ends.
pub fn run(opts: ClientOptions, interrupt: Receiver<Interrupt>) -> anyhow::Result<ClientOutcome> {
    let keys = RunKeys::new(&opts.network.run_id)?;
    let id = crawler_transport::process_id();
    let session = crawler_transport::open(Role::Controller, &opts.network)?;
    let outcome = serve(&session, &keys, &id, &opts, &interrupt);
    let _ = session.close().wait();
    outcome
}

fn serve(
    session: &zenoh::Session,
    keys: &RunKeys,
    id: &str,
    opts: &ClientOptions,
    interrupt: &Receiver<Interrupt>,
) -> anyhow::Result<ClientOutcome> {
    let z = |e: zenoh::Error| anyhow::anyhow!("zenoh: {e}");
    let (state_tx, state_rx) = bounded::<Vec<u8>>(1024);
    let _states = session
        .declare_subscriber(keys.state())
        .callback(move |s| {
            let _ = state_tx.try_send(s.payload().to_bytes().into_owned());
        })
        .wait()
        .map_err(z)?;
    let (ev_tx, ev_rx) = unbounded::<Event>();
    let ev2 = ev_tx.clone();
    let _status = session
        .declare_subscriber(keys.status(Role::Plant))
        .callback(move |s| {
            if let Ok(st) = decode::<Status>(&s.payload().to_bytes()) {
                let _ = ev2.send(Event::Status(st));
            }
        })
        .wait()
        .map_err(z)?;
    let status_pub = session
        .declare_publisher(keys.status(Role::Controller))
        .wait()
        .map_err(z)?;
    let publish_status = |state: &str, message: &str, step: u64| {
        let s = Status {
            v: PROTOCOL_VERSION,
            role: Role::Controller.as_str().into(),
            id: id.to_string(),
            state: state.into(),
            message: message.into(),
            step,
            rejected: Rejections::default(),
            summary: None,
        };
        let _ = status_pub.put(encode(&s)).wait();
    };

    // The plant's description; retried until the plant answers.
    let what = format!(
        "waiting for the plant of {} (start it with: crawler-plant run --run-id {})",
        opts.network.describe(),
        keys.run()
    );
    eprintln!("crawler-controller: {what}");
    publish_status("waiting", &what, 0);
    let deadline = Instant::now() + opts.wait_timeout;
    let info = loop {
        if interrupt.try_recv().is_ok() {
            return Ok(ClientOutcome::Ended {
                reason: "interrupted while waiting for the plant".into(),
                exit: Exit::Interrupted,
            });
        }
        if Instant::now() >= deadline {
            return Ok(ClientOutcome::Ended {
                reason: format!(
                    "no plant answered within {:.0} s",
                    opts.wait_timeout.as_secs_f64()
                ),
                exit: Exit::Timeout,
            });
        }
        let replies = session
            .get(keys.model())
            .timeout(Duration::from_millis(500))
            .wait()
            .map_err(z)?;
        let mut found = None;
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                match decode::<ModelInfo>(&sample.payload().to_bytes()) {
                    Ok(info) => found = Some(info),
                    Err(e) => {
                        eprintln!("crawler-controller: ignoring an invalid model description: {e}")
                    }
                }
            }
        }
        match found {
            Some(info) => break info,
            None => std::thread::sleep(Duration::from_millis(200)),
        }
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
    publish_status("running", &format!("policy {}", policy.name()), 0);

    let mut last_wave: Option<Wave> = None;
    let mut last_predictions = Vec::new();
    let mut answered = 0u64;
    let plant_summary: Option<serde_json::Value>;
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
                publish_status("stopped", "interrupted", answered);
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
                Ok(Event::Status(st)) if plant_id.as_deref() != Some(st.id.as_str()) || st.role != "plant" => {
                    ignored += 1;
                }
                Ok(Event::Status(st)) => match st.state.as_str() {
                    "finished" => {
                        plant_summary = st.summary.as_deref().and_then(|s| serde_json::from_str(s).ok());
                        break;
                    }
                    "failed" | "stopped" if answered > 0 || st.step > 0 => {
                        publish_status("stopped", &format!("plant {}: {}", st.state, st.message), answered);
                        return Ok(ClientOutcome::Ended { reason: format!("the plant {}: {}", st.state, st.message), exit: Exit::Failure });
                    }
                    _ => {}
                },
                _ => {}
            },
            recv(state_rx) -> bytes => {
                let Ok(bytes) = bytes else { continue };
                let state: State = match decode(&bytes) {
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
                    continue; // the plant's finished status ends the run
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
                actuation_pub.put(encode(&msg)).wait().map_err(z)?;
                answered += 1;
                if let Some(p) = prediction {
                    let _ = prediction_pub.put(encode(&p)).wait();
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
    publish_status("finished", &format!("answered {answered} steps"), answered);
    if ignored > 0 {
        eprintln!("crawler-controller: ignored {ignored} messages (invalid, or not from this run's plant)");
    }
    Ok(ClientOutcome::Finished(Box::new(FinalSummary {
        policy: policy.name().to_string(),
        wave: last_wave.map(|w| WaveMsg {
            f0: w.f0,
            k: w.k,
            omega: w.omega,
            phase: w.phase,
        }),
        plant: plant_summary,
        predictions: last_predictions,
        steps: answered,
    })))
}
