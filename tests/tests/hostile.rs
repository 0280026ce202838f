//! Attacks on a run, as another process of the same machine would try them (loopback only):
//! - a session without the credential: it cannot even connect, on any key;
//! - a session that passed zenoh's authentication but lacks the message key (what a shared router
//!   is): its forged terminal statuses, its actuation carrying the joined controller's id and its
//!   events are refused at arrival;
//! - a process holding the credential that sends every kind of malformed or inconsistent
//!   message: each is rejected and counted, never applied;
//! - floods before and after the join: every process stays within its memory budget.
//!
//! Every attack leaves the run's result (its state digest) unchanged and every process within
//! its memory budget.

use crawler_facts::{Metric, MetricValues};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde::Serialize;
use zenoh::qos::CongestionControl;
use zenoh::sample::Locality;
use zenoh::Wait;

use crawler_e2e::{json, rss_kib, simulate, Proc, Run};
use crawler_protocol::{
    decode, encode, EpisodeMsg, EpisodeStats, Events, FinalReport, ModelInfo, ProcessState,
    ReportWindow, Role, RunKeys, RunLimits, State, Status, PROTOCOL_VERSION,
};
use crawler_transport::{Access, Seal};

/// The memory budget of every process: growth of its resident memory above its idle size.
const BUDGET_MIB: f64 = 64.0;

/// The recorder of the attacked runs records the fields of every 64th state (and every state's
/// scalars). Its working set grows with what it records, attack or not: rerun's buffers take it
/// about 55 MiB above its idle size when it records the fields of every 4th state of a 512-cell
/// run (measured without any attack); recording fewer fields keeps what an attack would add
/// visible against [`BUDGET_MIB`].
const RECORDER: &[&str] = &["--every", "64"];

/// The wave policy of these runs, and the same run in process.
const WAVE: &[&str] = &["--policy", "wave", "--f0", "0.2", "--alpha", "0.5"];

fn simulated(t_end: &str) -> serde_json::Value {
    simulate(&[
        "--eps", "1", "--f0", "0.2", "--alpha", "0.5", "--t-end", t_end,
    ])
}

/// Puts `bytes` on `key` from `session`, sealed when `seal` is given (a process holding the
/// credential); dropped by the sender if its queue is full.
fn put(session: &zenoh::Session, seal: Option<&Seal>, key: &str, bytes: Vec<u8>) {
    send(session, seal, key, bytes, CongestionControl::Drop)
}

/// Like [`put`], but waits for room in the sender's queue: delivered unless the link breaks.
fn block(session: &zenoh::Session, seal: Option<&Seal>, key: &str, bytes: Vec<u8>) {
    send(session, seal, key, bytes, CongestionControl::Block)
}

fn send(
    session: &zenoh::Session,
    seal: Option<&Seal>,
    key: &str,
    bytes: Vec<u8>,
    cc: CongestionControl,
) {
    let b = session.put(key, bytes.clone()).congestion_control(cc);
    match seal {
        Some(s) => b.attachment(s.seal(key, &bytes).to_vec()).wait().unwrap(),
        None => b.wait().unwrap(),
    }
}

/// The id of the run's plant, from its liveliness token.
fn plant_id(session: &zenoh::Session, keys: &RunKeys) -> String {
    let deadline = Instant::now() + Duration::from_secs(10);
    while Instant::now() < deadline {
        let replies = session
            .liveliness()
            .get(keys.alive_all(Role::Plant))
            .timeout(Duration::from_millis(500))
            .wait()
            .unwrap();
        while let Ok(r) = replies.recv() {
            if let Ok(s) = r.result() {
                if let Some(id) = keys.id_of_alive_key(Role::Plant, s.key_expr().as_str()) {
                    return id.to_string();
                }
            }
        }
    }
    panic!("the plant's liveliness token was not seen");
}

/// A plant status claiming `state` at `step` from `id`; a `finished` one with a forged (valid)
/// report.
fn status(id: &str, state: &str, step: u64) -> Status {
    let state = ProcessState::parse(state).unwrap();
    Status {
        v: PROTOCOL_VERSION,
        role: Role::Plant,
        id: id.into(),
        state,
        message: "forged".into(),
        step,
        rejected: Default::default(),
        report: (state == ProcessState::Finished).then(forged_report),
    }
}

/// A final report no run of these tests produced: its digest is `f0f0f0f0`.
fn forged_report() -> FinalReport {
    FinalReport {
        scenario: "forged".into(),
        values: MetricValues::of(&[
            (Metric::Velocity, 9.0),
            (Metric::Power, 1.0),
            (Metric::Mileage, 9.0),
            (Metric::MaxStress, 1.0),
            (Metric::MaxStrain, 0.0),
            (Metric::StuckFraction, 0.0),
            (Metric::MeanFrictionSelection, 0.0),
        ]),
        dissipation: 1.0,
        identity_velocity: 9.0,
        momentum_residual: None,
        events: EpisodeStats {
            count: 0,
            per_node_per_period: 0.0,
            mean_duration: 0.0,
            min_duration: 0.0,
        },
        window: ReportWindow {
            start: 0.0,
            end: 1.0,
            periods: 1.0,
            steady: true,
            whole_run: false,
        },
        cells: 512,
        dt: 1e-5,
        step: 1e-3,
        courant: 1.0,
        dx: 1.0 / 512.0,
        cells_per_wavelength: None,
        steps: 1,
        macro_steps: 1,
        t_end: 1.0,
        state_digest: "f0f0f0f0".into(),
        task: None,
    }
}

/// Episodes no run can have: a node far out of range, a negative duration.
fn forged_events(step: u64) -> Events {
    let ep = |node, duration| EpisodeMsg {
        node,
        start: 0.5,
        end: 0.6,
        duration,
        direction: 1,
    };
    Events {
        v: PROTOCOL_VERSION,
        step,
        time: 0.7,
        episodes: vec![ep(u32::MAX, 0.1), ep(3, -0.1), ep(4, 1e9)],
    }
}

/// The count after `kind: ` in the plant's "rejected actuation messages" line.
fn rejected(stderr: &str, kind: &str) -> u64 {
    let line = stderr
        .lines()
        .find(|l| l.contains("rejected actuation messages"))
        .unwrap_or("");
    line.split(&format!("{kind}: "))
        .nth(1)
        .and_then(|r| r.split(|ch: char| !ch.is_ascii_digit()).next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0)
}

/// The number before `what` in the bridge's closing line.
fn bridge_count(stderr: &str, what: &str) -> u64 {
    stderr
        .lines()
        .filter(|l| l.contains("recording closed"))
        .find_map(|l| {
            l.split(what)
                .next()
                .and_then(|s| s.rsplit(' ').next())
                .and_then(|n| n.trim_start_matches('(').parse().ok())
        })
        .unwrap_or(0)
}

#[derive(Serialize, Clone)]
struct W {
    f0: f64,
    k: f64,
    omega: f64,
    phase: f64,
}

#[derive(Serialize, Clone)]
struct Act {
    v: u16,
    step: u64,
    controller: String,
    wave: Option<W>,
    field: Option<Vec<f64>>,
}

fn pack<T: Serialize>(t: &T) -> Vec<u8> {
    rmp_serde::to_vec_named(t).unwrap()
}

fn wave() -> W {
    W {
        f0: 0.2,
        k: std::f64::consts::TAU,
        omega: 37.17,
        phase: 0.0,
    }
}

fn act(step: u64, controller: &str) -> Act {
    Act {
        v: PROTOCOL_VERSION,
        step,
        controller: controller.into(),
        wave: Some(wave()),
        field: None,
    }
}

/// Every kind of bad payload, by name; `me` is the real controller's id (to forge plausible ones).
fn payloads(me: &str) -> Vec<(&'static str, Vec<u8>)> {
    let valid = pack(&act(1, me));
    let nested = vec![0x91u8; 20_000]; // fixarray of length 1, nested 20 000 deep
    let mut huge = vec![0x85]; // map of 5 with an array32 claiming 2^31 values
    huge.extend(
        b"\xa1v\x01\xa4step\x01\xaacontroller\xa1x\xa4wave\xc0\xa5field\xdd\x80\x00\x00\x00",
    );
    let big_noise: Vec<u8> = (0..2_000_000u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
        .collect();
    let with = |f: &dyn Fn(&mut Act)| {
        let mut a = act(1, me);
        f(&mut a);
        pack(&a)
    };
    vec![
        ("garbage", b"\xde\xad\xbe\xef not msgpack at all".to_vec()),
        ("empty", Vec::new()),
        ("truncated", valid[..valid.len() / 2].to_vec()),
        ("version 2", with(&|a| a.v = 2)),
        ("version 0", with(&|a| a.v = 0)),
        ("NaN f0", with(&|a| a.wave.as_mut().unwrap().f0 = f64::NAN)),
        (
            "inf omega",
            with(&|a| a.wave.as_mut().unwrap().omega = f64::INFINITY),
        ),
        (
            "-inf phase",
            with(&|a| a.wave.as_mut().unwrap().phase = f64::NEG_INFINITY),
        ),
        ("negative k", with(&|a| a.wave.as_mut().unwrap().k = -6.0)),
        (
            "zero omega",
            with(&|a| a.wave.as_mut().unwrap().omega = 0.0),
        ),
        ("negative f0", with(&|a| a.wave.as_mut().unwrap().f0 = -1.0)),
        (
            "wave not fitting the body",
            with(&|a| a.wave.as_mut().unwrap().k = 1.5 * std::f64::consts::TAU),
        ),
        (
            "field of 3 values",
            with(&|a| {
                a.wave = None;
                a.field = Some(vec![0.1, 0.2, 0.3]);
            }),
        ),
        (
            "field with NaN",
            with(&|a| {
                a.wave = None;
                let mut f = vec![0.0; 128];
                f[7] = f64::NAN;
                a.field = Some(f);
            }),
        ),
        ("wave and field", with(&|a| a.field = Some(vec![0.0; 128]))),
        ("neither wave nor field", with(&|a| a.wave = None)),
        ("huge declared array", huge),
        ("2 MB of noise", big_noise),
        ("depth bomb", nested),
        (
            "wrong types",
            pack(
                &serde_json::json!({"v": "one", "step": "two", "controller": 3, "wave": [1, 2], "field": {"a": 1}}),
            ),
        ),
        ("foreign controller", pack(&act(1, "not-the-controller"))),
        ("stale step", pack(&act(0, me))),
        ("future step", pack(&act(1_000_000_000, me))),
        ("step u64::MAX", pack(&act(u64::MAX, me))),
        ("10 kB controller id", pack(&act(1, &"x".repeat(10_000)))),
        (
            "unknown extra layout",
            pack(&serde_json::json!([1, 2, 3, 4, 5])),
        ),
        (
            "float as step",
            pack(
                &serde_json::json!({"v": PROTOCOL_VERSION, "step": 1.5, "controller": me, "wave": null, "field": null}),
            ),
        ),
    ]
}

/// A process holding the run's credential sends every kind of bad payload on every key, replays
/// the controller's answers, tries to join as a second controller, forges terminal statuses with
/// the plant's own id that do not fit the run, and a last state from beyond the run's end: all
/// rejected and counted, nothing applied, the recording complete.
#[test]
fn hostile_payloads_from_a_credential_holder_change_nothing() {
    let run = Run::new("hostile");
    let rrd = run.path("hostile.rrd");
    let plant = run.plant(&["--eps", "1", "--t-end", "8", "--json"]);
    let bridge = run.bridge(&rrd, RECORDER);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let controller = run.controller(WAVE);
    plant.wait_for_stderr("joined run", Duration::from_secs(30));
    let budgets = Budgets::watch(&[
        ("plant", &plant),
        ("controller", &controller),
        ("recorder", &bridge),
    ]);

    let credential = run.load_credential();
    let seal = Seal::new(&credential.message_key());
    let session = run.session(&Access::Password(credential.transport_password()), 512);
    let keys = RunKeys::new(&run.id).unwrap();
    let pid = plant_id(&session, &keys);
    // It learns the controller's id from the states it sees and records the controller's own
    // actuation so it can replay it (duplicates, stale steps).
    let seen_controller = Arc::new(Mutex::new(String::new()));
    let s2 = seen_controller.clone();
    let _states = session
        .declare_subscriber(keys.state())
        .callback(move |s| {
            if let Ok(st) = decode::<State>(&s.payload().to_bytes()) {
                *s2.lock().unwrap() = st.controller;
            }
        })
        .wait()
        .unwrap();
    let captured: Arc<Mutex<Vec<Vec<u8>>>> = Arc::default();
    let c2 = captured.clone();
    // Each of the controller's answers, sent again at once (by a thread: a zenoh callback must
    // not block): it reaches the plant just after the original, a duplicate of the step just
    // taken (the first 300).
    let (replay_tx, replay_rx) = std::sync::mpsc::channel::<Vec<u8>>();
    let (replayer, replay_seal, act_key) = (session.clone(), seal.clone(), keys.actuation());
    let replaying = std::thread::spawn(move || {
        let mut n = 0u64;
        for bytes in replay_rx.iter().take(300) {
            block(&replayer, Some(&replay_seal), &act_key, bytes);
            n += 1;
        }
        n
    });
    let replay_tx = Mutex::new(Some(replay_tx));
    let _acts = session
        .declare_subscriber(keys.actuation())
        .allowed_origin(Locality::Remote)
        .callback(move |s| {
            let bytes = s.payload().to_bytes().into_owned();
            let mut c = c2.lock().unwrap();
            if c.len() < 50 {
                c.push(bytes.clone());
            }
            if let Some(tx) = replay_tx.lock().unwrap().as_ref() {
                let _ = tx.send(bytes);
            }
        })
        .wait()
        .unwrap();
    // A second controller trying to join the run.
    let _intruder = session
        .liveliness()
        .declare_token(keys.alive(Role::Controller, "intruder"))
        .wait()
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let me = seen_controller.lock().unwrap().clone();
    assert!(!me.is_empty(), "the stray session saw no state");

    let all_keys = [
        keys.actuation(),
        keys.state(),
        keys.events(),
        keys.metrics(),
        keys.prediction(),
        keys.status(Role::Plant),
        keys.status(Role::Controller),
        keys.status(Role::Bridge),
        keys.model(),
        keys.environment(),
    ];
    let kinds = payloads(&me);
    assert!(kinds.len() >= 20);
    let s = Some(&seal);
    for round in 0..3 {
        for (_, bytes) in &kinds {
            for key in &all_keys {
                block(&session, s, key, bytes.clone());
            }
        }
        // replayed actuation of the real controller, later: stale steps
        let replay: Vec<Vec<u8>> = captured.lock().unwrap().clone();
        for bytes in replay {
            block(&session, s, &keys.actuation(), bytes);
        }
        // well-formed but inconsistent: "finished" from another id, "finished" with the plant's
        // own id in the middle of the run, "failed" beyond the run's end, a last state from
        // beyond the end, impossible episodes
        for st in [
            status("forger", "finished", 8000),
            status(&pid, "finished", 1000 + round),
            status(&pid, "failed", 9000),
            status(&pid, "stopped", u64::MAX),
        ] {
            block(&session, s, &keys.status(Role::Plant), encode(&st));
        }
        let fake = State {
            v: PROTOCOL_VERSION,
            step: 999_999 + round,
            time: 1.0,
            controller: me.clone(),
            u: vec![0.0; 512],
            vel: vec![0.0; 512],
            tension: vec![0.0; 512],
            stuck: vec![false; 512],
            mean_speed: 0.0,
            input_power: 0.0,
            last: true,
            applied: None,
        };
        block(&session, s, &keys.state(), encode(&fake));
        block(&session, s, &keys.events(), encode(&forged_events(700)));
        std::thread::sleep(Duration::from_millis(300));
    }

    let p = plant.wait(Duration::from_secs(120));
    let c = controller.wait(Duration::from_secs(60));
    let b = bridge.wait(Duration::from_secs(60));
    budgets.check();
    drop(_acts);
    let replayed = replaying.join().unwrap();
    assert!(replayed > 0, "nothing was replayed");
    assert!(p.status.success(), "plant crashed or failed: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    assert!(b.status.success(), "bridge: {}", b.stderr);
    assert_eq!(
        json(&p.stdout)["state_digest"],
        simulated("8")["state_digest"],
        "hostile payloads changed the trajectory"
    );
    for kind in [
        "malformed",
        "version",
        "invalid",
        "foreign",
        "stale",
        "duplicate",
        "future",
    ] {
        assert!(
            rejected(&p.stderr, kind) > 0,
            "no {kind} rejection counted: {}",
            p.stderr
        );
    }
    assert!(
        p.stderr.contains("another controller intruder"),
        "{}",
        p.stderr
    );
    assert!(
        c.stderr
            .contains("ignoring an inconsistent plant status \"finished\""),
        "the controller did not notice the forged finished status: {}",
        c.stderr
    );
    assert!(
        bridge_count(&b.stderr, " invalid)") > 0,
        "bridge: {}",
        b.stderr
    );
    let rec = crawler_e2e::read_recording(&rrd).unwrap();
    let rows = rec.entity("tail/plant").rows;
    assert!(
        rows >= 8001,
        "the recording lost states: {rows} rows; bridge: {}",
        b.stderr
    );
    // the recording kept the plant's report, not the forged one (V = 9 m/s)
    assert_eq!(
        rec.entity("summary/velocity").scalars,
        [json(&p.stdout)["velocity"].as_f64().unwrap()],
        "{:?}",
        rec.entities.keys()
    );
}

/// A session without the credential connects to the run's endpoint and tries every key: it is
/// never admitted (zenoh's user/password check fails), so it receives nothing, and nothing it
/// sends arrives anywhere.
#[test]
fn an_unauthenticated_session_reaches_nothing_on_any_key() {
    let run = Run::new("unauth");
    let rrd = run.path("unauth.rrd");
    let plant = run.plant(&["--eps", "1", "--t-end", "6", "--json"]);
    let bridge = run.bridge(&rrd, RECORDER);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let session = run.session(&Access::Open, 512);
    let keys = RunKeys::new(&run.id).unwrap();
    let received = Arc::new(AtomicU64::new(0));
    let r2 = received.clone();
    let _all = session
        .declare_subscriber(keys.all())
        .allowed_origin(Locality::Remote)
        .callback(move |_| {
            r2.fetch_add(1, Ordering::Relaxed);
        })
        .wait()
        .unwrap();
    let _token = session
        .liveliness()
        .declare_token(keys.alive(Role::Controller, "intruder-unauth"))
        .wait()
        .unwrap();
    let controller = run.controller(WAVE);
    plant.wait_for_stderr("joined run", Duration::from_secs(30));
    let budgets = Budgets::watch(&[
        ("plant", &plant),
        ("controller", &controller),
        ("recorder", &bridge),
    ]);
    let kinds = payloads("x");
    let all_keys = [
        keys.actuation(),
        keys.state(),
        keys.events(),
        keys.metrics(),
        keys.prediction(),
        keys.status(Role::Plant),
        keys.status(Role::Controller),
        keys.status(Role::Bridge),
        keys.model(),
        keys.environment(),
    ];
    for _ in 0..2 {
        for (_, bytes) in &kinds {
            for key in &all_keys {
                block(&session, None, key, bytes.clone());
            }
        }
        for st in [status("x", "finished", 6000), status("x", "failed", 10)] {
            block(&session, None, &keys.status(Role::Plant), encode(&st));
        }
        for key in [keys.model(), keys.environment()] {
            let replies = session
                .get(&key)
                .timeout(Duration::from_millis(300))
                .wait()
                .unwrap();
            assert!(
                replies.recv().is_err(),
                "the plant answered an unauthenticated query on {key}"
            );
        }
    }
    assert!(
        session.info().routers_zid().wait().next().is_none()
            && session.info().peers_zid().wait().next().is_none(),
        "an unauthenticated session got linked to the run"
    );
    let p = plant.wait(Duration::from_secs(60));
    let c = controller.wait(Duration::from_secs(30));
    let b = bridge.wait(Duration::from_secs(30));
    budgets.check();
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    assert!(b.status.success(), "bridge: {}", b.stderr);
    assert_eq!(
        json(&p.stdout)["state_digest"],
        simulated("6")["state_digest"]
    );
    assert_eq!(
        received.load(Ordering::Relaxed),
        0,
        "it received messages of the run"
    );
    // nothing it sent reached the plant: not even a rejection to count
    assert!(
        !p.stderr.contains("rejected actuation messages"),
        "{}",
        p.stderr
    );
    assert!(!p.stderr.contains("intruder"), "{}", p.stderr);
    assert_eq!(
        bridge_count(&b.stderr, " refused at arrival"),
        0,
        "{}",
        b.stderr
    );
}

/// A session that passed zenoh's authentication but does not hold the message key (a shared
/// router's position: it relays and sees everything) reads the joined controller's id and each
/// step from the states, and answers every state before the controller does with an actuation
/// carrying that id; it forges the plant's terminal statuses with the plant's own id, at the
/// run's last step and mid-run, and impossible episodes. None of it is applied, recorded or
/// believed: the run's result is unchanged and the controller answered every step.
#[test]
fn without_the_message_key_nobody_can_end_or_steer_the_run() {
    let run = Run::new("nokey");
    let rrd = run.path("nokey.rrd");
    let plant = run.plant(&["--eps", "1", "--t-end", "6", "--json"]);
    let bridge = run.bridge(&rrd, RECORDER);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let session = run.transport_only_session(512);
    let keys = RunKeys::new(&run.id).unwrap();
    let pid = plant_id(&session, &keys);
    // it can read the run's description (a router sees everything): its last step
    let info: ModelInfo = {
        let replies = session.get(keys.model()).wait().unwrap();
        let reply = replies.recv().unwrap();
        decode(&reply.result().unwrap().payload().to_bytes()).unwrap()
    };
    // the spoofer: Actuation(n) and Actuation(n + 1) with the joined controller's id, another
    // wave, sent as soon as State(n) arrives (by a thread: a zenoh callback must not block)
    let (spoof_tx, spoof_rx) = std::sync::mpsc::channel::<(u64, String)>();
    let (spoofer, act_key) = (session.clone(), keys.actuation());
    let spoofing = std::thread::spawn(move || {
        let mut n = 0u64;
        for (step, controller) in spoof_rx.iter() {
            for step in [step, step + 1] {
                let mut a = act(step, &controller);
                a.wave.as_mut().unwrap().f0 = 2.0;
                block(&spoofer, None, &act_key, pack(&a));
                n += 1;
            }
        }
        n
    });
    let spoof_tx = Mutex::new(Some(spoof_tx));
    let seen = Arc::new(AtomicU64::new(0));
    let seen2 = seen.clone();
    let states = session
        .declare_subscriber(keys.state())
        .callback(move |s| {
            let Ok(st) = decode::<State>(&s.payload().to_bytes()) else {
                return;
            };
            if st.controller.is_empty() {
                return;
            }
            seen2.fetch_add(1, Ordering::Relaxed);
            if let Some(tx) = spoof_tx.lock().unwrap().as_ref() {
                let _ = tx.send((st.step, st.controller));
            }
        })
        .wait()
        .unwrap();
    let controller = run.controller(&[WAVE, &["--json"]].concat());
    plant.wait_for_stderr("joined run", Duration::from_secs(30));
    let budgets = Budgets::watch(&[
        ("plant", &plant),
        ("controller", &controller),
        ("recorder", &bridge),
    ]);
    let deadline = Instant::now() + Duration::from_secs(30);
    while seen.load(Ordering::Relaxed) < 100 && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(10));
    }
    for step in [info.last_step, info.last_step / 2, 0] {
        for state in ["finished", "failed", "stopped"] {
            block(
                &session,
                None,
                &keys.status(Role::Plant),
                encode(&status(&pid, state, step)),
            );
        }
    }
    block(&session, None, &keys.events(), encode(&forged_events(700)));
    let p = plant.wait(Duration::from_secs(60));
    let c = controller.wait(Duration::from_secs(30));
    let b = bridge.wait(Duration::from_secs(30));
    budgets.check();
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(
        c.status.success(),
        "the controller ended early: {}",
        c.stderr
    );
    assert!(b.status.success(), "bridge: {}", b.stderr);
    assert_eq!(
        json(&p.stdout)["state_digest"],
        simulated("6")["state_digest"],
        "spoofed actuation changed the trajectory"
    );
    drop(states);
    let spoofed = spoofing.join().unwrap();
    assert!(spoofed >= 200, "only {spoofed} spoofed answers were sent");
    // every spoofed answer was refused at arrival (counted as foreign: not from the controller)
    assert!(rejected(&p.stderr, "foreign") >= 200, "{}", p.stderr);
    // the controller answered every step and took the plant's real summary
    let summary = json(&c.stdout);
    assert_eq!(
        summary["steps"].as_u64(),
        Some(info.last_step),
        "{}",
        c.stdout
    );
    assert_eq!(
        summary["plant"]["state_digest"],
        simulated("6")["state_digest"]
    );
    assert!(
        bridge_count(&b.stderr, " refused at arrival") >= 10,
        "{}",
        b.stderr
    );
    assert_eq!(bridge_count(&b.stderr, " invalid)"), 0, "{}", b.stderr);
}

/// Sends payloads around every key's limit until `stop`, sealed when `seal` is given; returns
/// how many it sent. One thread delivers (blocking when the link is busy) bursts of payloads of
/// each key's legal size and one byte more; another sends payloads beyond what zenoh reassembles
/// (2 MiB, and the 50 MB of the original report), which the sender drops when its queue is full.
fn flood(
    session: zenoh::Session,
    seal: Option<Seal>,
    keys: RunKeys,
    stop: Arc<AtomicBool>,
) -> Vec<std::thread::JoinHandle<u64>> {
    let limits = RunLimits::new(128);
    let plan = vec![
        (keys.actuation(), limits.actuation()),
        (keys.state(), limits.state()),
        (keys.events(), limits.events()),
        (keys.metrics(), RunLimits::metrics()),
        (keys.prediction(), RunLimits::text_message()),
        (keys.status(Role::Plant), RunLimits::text_message()),
    ];
    let bulk = {
        let (session, seal, plan, stop) =
            (session.clone(), seal.clone(), plan.clone(), stop.clone());
        std::thread::spawn(move || {
            let mut sent = 0u64;
            while !stop.load(Ordering::Relaxed) {
                for (key, limit) in &plan {
                    let n = if *limit > 64 << 10 { 2 } else { 20 };
                    for size in std::iter::repeat_n(*limit, n).chain([*limit + 1]) {
                        block(&session, seal.as_ref(), key, vec![0xc1; size]);
                        sent += 1;
                    }
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            sent
        })
    };
    let big = std::thread::spawn(move || {
        let mut sent = 0u64;
        let mut round = 0u64;
        while !stop.load(Ordering::Relaxed) {
            for (key, _) in &plan {
                put(
                    &session,
                    seal.as_ref(),
                    key,
                    vec![0xc1; RunLimits::text_message() + 64],
                );
                if round.is_multiple_of(10) {
                    put(&session, seal.as_ref(), key, vec![0xc1; 50 << 20]);
                }
                sent += 1;
            }
            round += 1;
            std::thread::sleep(Duration::from_millis(100));
        }
        sent
    });
    vec![bulk, big]
}

/// The largest peak resident memory (KiB) seen for each pid until `stop` (a process that ended
/// keeps its last reading).
fn sample_peaks(pids: Vec<u32>, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<Vec<u64>> {
    std::thread::spawn(move || {
        let mut peaks = vec![0u64; pids.len()];
        loop {
            for (peak, pid) in peaks.iter_mut().zip(&pids) {
                if let Some((_, hwm)) = rss_kib(*pid) {
                    *peak = (*peak).max(hwm);
                }
            }
            if stop.load(Ordering::Relaxed) {
                return peaks;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    })
}

/// The processes of a run watched while an attack goes on: each must stay within [`BUDGET_MIB`]
/// of the resident memory it had when the watch began.
struct Budgets {
    names: Vec<&'static str>,
    idle: Vec<u64>,
    stop: Arc<AtomicBool>,
    sampling: std::thread::JoinHandle<Vec<u64>>,
}

impl Budgets {
    fn watch(procs: &[(&'static str, &Proc)]) -> Self {
        let idle = procs
            .iter()
            .map(|(name, p)| rss_kib(p.pid()).unwrap_or_else(|| panic!("{name} ended")).0)
            .collect();
        let stop = Arc::new(AtomicBool::new(false));
        let sampling = sample_peaks(procs.iter().map(|(_, p)| p.pid()).collect(), stop.clone());
        Self {
            names: procs.iter().map(|(name, _)| *name).collect(),
            idle,
            stop,
            sampling,
        }
    }

    /// Stops watching (call it once the processes ended) and checks every budget.
    fn check(self) {
        self.stop.store(true, Ordering::Relaxed);
        let peaks = self.sampling.join().unwrap();
        for ((name, idle), peak) in self.names.iter().zip(&self.idle).zip(peaks) {
            let growth = peak.saturating_sub(*idle) as f64 / 1024.0;
            eprintln!(
                "{name}: idle {idle} KiB, peak during the attack {peak} KiB: +{growth:.1} MiB"
            );
            assert!(
                growth < BUDGET_MIB,
                "{name} grew by {growth:.1} MiB during the attack (budget {BUDGET_MIB} MiB)"
            );
        }
    }
}

/// Floods every key with payloads from the legal size to 50 MB, from a session without the
/// message key and from one holding the credential (sealed), before the controller joins and
/// again while the run goes on. Each process stays within [`BUDGET_MIB`] of its idle resident
/// memory, everything dropped is counted, and the run's result is unchanged.
#[test]
fn floods_before_and_after_the_join_stay_within_every_process_budget() {
    let run = Run::new("flood");
    let rrd = run.path("flood.rrd");
    let plant = run.plant(&["--eps", "1", "--t-end", "8", "--cells", "128", "--json"]);
    let bridge = run.bridge(&rrd, &[]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    plant.wait_for_stderr("waiting for a controller", Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(300));
    let idle_of = |p: &Proc| rss_kib(p.pid()).expect("running").0;
    let (plant_idle, bridge_idle) = (idle_of(&plant), idle_of(&bridge));

    let credential = run.load_credential();
    let seal = Seal::new(&credential.message_key());
    let keys = RunKeys::new(&run.id).unwrap();
    let outsider = run.transport_only_session(512);
    let insider = run.session(&Access::Password(credential.transport_password()), 512);
    let floods = |stop: &Arc<AtomicBool>| {
        let mut threads = flood(outsider.clone(), None, keys.clone(), stop.clone());
        threads.extend(flood(
            insider.clone(),
            Some(seal.clone()),
            keys.clone(),
            stop.clone(),
        ));
        threads
    };
    // before the join: plant and recorder
    let stop = Arc::new(AtomicBool::new(false));
    let sampling = sample_peaks(vec![plant.pid(), bridge.pid()], stop.clone());
    let pre = floods(&stop);
    std::thread::sleep(Duration::from_secs(3));
    stop.store(true, Ordering::Relaxed);
    let mut sent: u64 = pre.into_iter().map(|f| f.join().unwrap()).sum();
    let pre_peaks = sampling.join().unwrap();
    // the controller joins; then the flood again while the run goes on
    let controller = run.controller(WAVE);
    plant.wait_for_stderr("joined run", Duration::from_secs(60));
    let controller_idle = idle_of(&controller);
    let stop = Arc::new(AtomicBool::new(false));
    let sampling = sample_peaks(
        vec![plant.pid(), bridge.pid(), controller.pid()],
        stop.clone(),
    );
    let during = floods(&stop);
    let deadline = Instant::now() + Duration::from_secs(2);
    while Instant::now() < deadline && rss_kib(plant.pid()).is_some() {
        std::thread::sleep(Duration::from_millis(50));
    }
    stop.store(true, Ordering::Relaxed);
    sent += during.into_iter().map(|f| f.join().unwrap()).sum::<u64>();
    let peaks = sampling.join().unwrap();
    let p = plant.wait(Duration::from_secs(120));
    let c = controller.wait(Duration::from_secs(60));
    let b = bridge.wait(Duration::from_secs(60));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    assert!(b.status.success(), "bridge: {}", b.stderr);
    assert_eq!(
        json(&p.stdout)["state_digest"],
        simulate(&[
            "--eps", "1", "--f0", "0.2", "--alpha", "0.5", "--t-end", "8", "--cells", "128"
        ])["state_digest"],
        "the flood changed the trajectory"
    );
    assert!(sent > 100, "the flood sent only {sent} payloads");
    for (name, idle, peak) in [
        ("plant", plant_idle, pre_peaks[0].max(peaks[0])),
        ("recorder", bridge_idle, pre_peaks[1].max(peaks[1])),
        ("controller", controller_idle, peaks[2]),
    ] {
        let growth = peak.saturating_sub(idle) as f64 / 1024.0;
        eprintln!(
            "{name}: idle {:.1} MiB, peak under the flood {:.1} MiB: +{growth:.1} MiB (budget {BUDGET_MIB} MiB)",
            idle as f64 / 1024.0,
            peak as f64 / 1024.0
        );
        assert!(
            growth < BUDGET_MIB,
            "{name} grew by {growth:.1} MiB under the flood (idle {idle} KiB, peak {peak} KiB)"
        );
    }
    // what was dropped was counted: oversized actuation (malformed), unsealed (foreign), beyond
    // the inbox's budget before the join (overflow)
    for kind in ["malformed", "foreign", "overflow"] {
        assert!(
            rejected(&p.stderr, kind) > 0,
            "no {kind} counted: {}",
            p.stderr
        );
    }
    assert!(
        bridge_count(&b.stderr, " refused at arrival") > 0,
        "{}",
        b.stderr
    );
    assert!(
        c.stderr.contains("refused at arrival"),
        "controller: {}",
        c.stderr
    );
}
