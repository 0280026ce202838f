//! A process holding the credential: every kind of bad payload, sealed, on every key.

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde::Serialize;
use zenoh::sample::Locality;
use zenoh::Wait;

use crawler_e2e::{json, Ended, Run};
use crawler_protocol::{decode, encode, Join, ProcessId, Role, RunKeys, State, PROTOCOL_VERSION};
use crawler_transport::{Access, Participant, Seal};

use super::{
    bridge_count, controller_refused, forged_events, rejected, simulated, status, Budgets,
    Captured, Outlets, RECORDER, WAVE,
};

#[derive(Serialize, Clone)]
struct W {
    f0: f64,
    k: f64,
    omega: f64,
    phase: f64,
}

#[derive(Serialize, Clone)]
pub(crate) struct Act {
    v: u16,
    step: u64,
    controller: String,
    wave: Option<W>,
    field: Option<Vec<f64>>,
}

pub(crate) fn pack<T: Serialize>(t: &T) -> Vec<u8> {
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

pub(crate) fn act(step: u64, controller: &str) -> Act {
    Act {
        v: PROTOCOL_VERSION,
        step,
        controller: controller.into(),
        wave: Some(wave()),
        field: None,
    }
}

/// A wave of another amplitude: what a spoofer would like the plant to apply.
pub(crate) fn spoofed(step: u64, controller: &str) -> Vec<u8> {
    let mut a = act(step, controller);
    a.wave.as_mut().unwrap().f0 = 2.0;
    pack(&a)
}

/// Every kind of bad payload, by name; `me` is the real controller's id (to forge plausible ones).
pub(crate) fn payloads(me: &str) -> Vec<(&'static str, Vec<u8>)> {
    let valid = pack(&act(1, me));
    let nested = vec![0x91u8; 20_000]; // fixarray of length 1, nested 20 000 deep
    let mut huge = vec![0x85]; // map of 5 with an array32 claiming 2^31 values
    huge.extend(
        b"\xa1v\x03\xa4step\x01\xaacontroller\xa1x\xa4wave\xc0\xa5field\xdd\x80\x00\x00\x00",
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
        ("array form", rmp_serde::to_vec(&act(1, me)).unwrap()),
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

/// A process holding the run's credential sends every kind of bad payload on every key (sealed,
/// in its own name), replays the controller's answers byte for byte, asks to join as a second
/// controller, forges terminal statuses with the plant's own id that do not fit the run, and a
/// last state from beyond the run's end: all refused at arrival or rejected, counted, nothing
/// applied, the recording complete.
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
    let (insider, plant_id) = run.participant(
        &Access::Password(credential.transport_password()),
        Some(seal),
        Role::Controller,
        512,
    );
    let session = insider.session().clone();
    let keys = RunKeys::new(&run.id).unwrap();
    // It learns the controller's id from the states it sees and captures the controller's own
    // actuation (payload, envelope, seal) so it can replay it.
    let (seen_controller, _states) = learn_the_controller(&session, &keys);
    let Replaying {
        captured,
        acts,
        replaying,
    } = capture_and_replay(&session, &keys);
    std::thread::sleep(Duration::from_millis(300));
    let me = seen_controller.lock().unwrap().clone();
    assert!(!me.is_empty(), "the stray session saw no state");

    let mut out = Outlets::of(&insider);
    let sent_to_plant = attack(
        &mut out, &insider, &plant_id, &session, &keys, &me, &captured,
    );

    let p = plant.wait(Duration::from_secs(120));
    let c = controller.wait(Duration::from_secs(60));
    let b = bridge.wait(Duration::from_secs(60));
    budgets.check();
    drop(acts);
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
    check_everything_was_counted(&p, &c, &b, &insider, sent_to_plant);
    check_the_recording(&rrd, &p, &b);
}

/// Subscribes `session` to the run's states: the shared string holds the controller's id of the
/// latest state seen (empty until one arrives); keep the subscriber alive while it is needed.
fn learn_the_controller(
    session: &zenoh::Session,
    keys: &RunKeys,
) -> (Arc<Mutex<String>>, zenoh::pubsub::Subscriber<()>) {
    let seen_controller = Arc::new(Mutex::new(String::new()));
    let s2 = seen_controller.clone();
    let states = session
        .declare_subscriber(keys.state())
        .callback(move |s| {
            if let Ok(st) = decode::<State>(&s.payload().to_bytes()) {
                *s2.lock().unwrap() = st.controller;
            }
        })
        .wait()
        .unwrap();
    (seen_controller, states)
}

/// The insider's capture of the controller's actuation and its replaying thread.
struct Replaying {
    /// The first 50 actuation samples of the controller, as they arrived.
    captured: Arc<Mutex<Vec<Captured>>>,
    /// The subscriber to the actuation key; dropping it ends the replaying thread's input.
    acts: zenoh::pubsub::Subscriber<()>,
    /// The replaying thread: it answers with the number of samples it sent again.
    replaying: std::thread::JoinHandle<u64>,
}

/// Subscribes `session` to the controller's actuation (remote samples only): keeps the first 50
/// and sends each of the first 300 again at once.
fn capture_and_replay(session: &zenoh::Session, keys: &RunKeys) -> Replaying {
    let captured: Arc<Mutex<Vec<Captured>>> = Arc::default();
    let c2 = captured.clone();
    // Each of the controller's answers, sent again at once (by a thread: a zenoh callback must
    // not block): the first 300.
    let (replay_tx, replay_rx) = std::sync::mpsc::channel::<Captured>();
    let replayer = session.clone();
    let replaying = std::thread::spawn(move || {
        let mut n = 0u64;
        for c in replay_rx.iter().take(300) {
            c.replay(&replayer);
            n += 1;
        }
        n
    });
    let replay_tx = Mutex::new(Some(replay_tx));
    let acts = session
        .declare_subscriber(keys.actuation())
        .allowed_origin(Locality::Remote)
        .callback(move |s| {
            let c = Captured::of(&s);
            let mut all = c2.lock().unwrap();
            if all.len() < 50 {
                all.push(c.clone());
            }
            if let Some(tx) = replay_tx.lock().unwrap().as_ref() {
                let _ = tx.send(c);
            }
        })
        .wait()
        .unwrap();
    Replaying {
        captured,
        acts,
        replaying,
    }
}

/// The insider's attack, sealed in its own name through `out` (its outlets): a request to join,
/// then three rounds of every bad payload on every key, replays of `captured` from `session`,
/// forged statuses, a last state and impossible episodes; `me` is the controller's id. Returns
/// the number of payloads it sent the plant (on the actuation and join keys).
fn attack(
    out: &mut Outlets<'_>,
    insider: &Participant,
    plant_id: &ProcessId,
    session: &zenoh::Session,
    keys: &RunKeys,
    me: &str,
    captured: &Mutex<Vec<Captured>>,
) -> u64 {
    // A second controller asking to join the run (it keeps its controller).
    let join = Join {
        v: PROTOCOL_VERSION,
        controller: insider.id().to_string(),
        policy: "intruder".into(),
        take_over: None,
    };
    out.put(&keys.join(), encode(&join));

    let all_keys = [
        keys.actuation(),
        keys.join(),
        keys.state(),
        keys.events(),
        keys.metrics(),
        keys.prediction(),
        keys.status(Role::Plant),
        keys.status(Role::Controller),
        keys.status(Role::Bridge),
    ];
    let kinds = payloads(me);
    assert!(kinds.len() >= 20);
    let sent_to_plant = AtomicU64::new(0);
    for round in 0..3 {
        for (_, bytes) in &kinds {
            for key in &all_keys {
                out.put(key, bytes.clone());
                if *key == keys.actuation() || *key == keys.join() {
                    sent_to_plant.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
        // replayed actuation of the real controller, later: replays
        let replay: Vec<Captured> = captured.lock().unwrap().clone();
        for c in replay {
            c.replay(session);
        }
        send_inconsistent(out, keys, plant_id, me, round);
        std::thread::sleep(Duration::from_millis(300));
    }
    sent_to_plant.load(Ordering::Relaxed)
}

/// One round (`round` from 0) of well-formed but inconsistent messages, sealed in the insider's
/// own name through `out`.
fn send_inconsistent(
    out: &mut Outlets<'_>,
    keys: &RunKeys,
    plant_id: &ProcessId,
    me: &str,
    round: u64,
) {
    // well-formed but inconsistent, sealed in the insider's own name: "finished" from
    // another id, "finished" with the plant's own id in the middle of the run, "failed"
    // beyond the run's end, a last state from beyond the end, impossible episodes
    for st in [
        status("forger", "finished", 8000),
        status(plant_id.as_str(), "finished", 1000 + round),
        status(plant_id.as_str(), "failed", 9000),
        status(plant_id.as_str(), "stopped", u64::MAX),
    ] {
        out.put(&keys.status(Role::Plant), encode(&st));
    }
    let fake = State {
        v: PROTOCOL_VERSION,
        step: 999_999 + round,
        time: 1.0,
        controller: me.to_string(),
        u: vec![0.0; 512],
        vel: vec![0.0; 512],
        tension: vec![0.0; 512],
        stuck: vec![false; 512],
        mean_speed: 0.0,
        input_power: 0.0,
        last: true,
        applied: None,
    };
    out.put(&keys.state(), encode(&fake));
    out.put(&keys.events(), encode(&forged_events(700)));
}

/// Checks that the plant counted every payload the insider sent it (`sent_to_plant`) and each
/// kind of rejection, saw the join request, and that the controller (`c`) and the recorder (`b`)
/// refused the forged messages at arrival.
fn check_everything_was_counted(
    p: &Ended,
    c: &Ended,
    b: &Ended,
    insider: &Participant,
    sent_to_plant: u64,
) {
    // Every payload it sent the plant was counted: too large ones as malformed, actuation not
    // from the run's controller as foreign, join requests by what is wrong with them (or as
    // overflow, beyond their inbox); the replays as replayed.
    let counted: u64 = ["malformed", "foreign", "version", "invalid", "overflow"]
        .iter()
        .map(|k| rejected(&p.stderr, k))
        .sum();
    assert!(
        counted >= sent_to_plant,
        "{counted} counted of {} sent: {}",
        sent_to_plant,
        p.stderr
    );
    for kind in ["malformed", "foreign", "replayed"] {
        assert!(
            rejected(&p.stderr, kind) > 0,
            "no {kind} rejection counted: {}",
            p.stderr
        );
    }
    assert!(
        p.stderr.contains(&format!(
            "another controller {} asked to join",
            insider.id()
        )),
        "{}",
        p.stderr
    );
    // the controller refused the forged states and statuses at arrival (not the plant's)
    assert!(
        controller_refused(&c.stderr, " from senders that may not send there") > 0,
        "{}",
        c.stderr
    );
    assert!(
        bridge_count(&b.stderr, " refused at arrival") > 0,
        "bridge: {}",
        b.stderr
    );
}

/// Checks that the recording at `rrd` holds every state and the plant's own report (of `p`),
/// not the forged one; `b` is the recorder.
fn check_the_recording(rrd: &Path, p: &Ended, b: &Ended) {
    let rec = crawler_e2e::read_recording(rrd).unwrap();
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
