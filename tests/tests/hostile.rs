//! Malformed and hostile payloads on every key of a run: rejected and counted, never applied,
//! no crash, and the run's result unchanged.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde::Serialize;
use zenoh::Wait;

use crawler_e2e::{json, simulate, Run};
use crawler_protocol::{encode, Role, RunKeys, State, Status, PROTOCOL_VERSION};

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
                &serde_json::json!({"v": 1, "step": 1.5, "controller": me, "wave": null, "field": null}),
            ),
        ),
    ]
}

#[test]
fn hostile_payloads_on_every_key_change_nothing() {
    let run = Run::new("hostile");
    let rrd = run.path("hostile.rrd");
    let plant = run.plant(&["--eps", "1", "--t-end", "8", "--json"]);
    let bridge = run.bridge(&rrd, &[]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let controller = run.controller(&["--policy", "wave", "--f0", "0.2", "--alpha", "0.5"]);
    plant.wait_for_stderr("joined run", Duration::from_secs(30));

    // A stray session on the same run: it learns the controller's id from the states it sees and
    // records the controller's own actuation so it can replay it (duplicates, stale steps).
    let net = crawler_transport::Network::loopback(&run.id, &run.endpoint).unwrap();
    let session = crawler_transport::open(Role::Controller, &net).unwrap();
    let keys = RunKeys::new(&run.id).unwrap();
    let seen_controller = Arc::new(Mutex::new(String::new()));
    let s2 = seen_controller.clone();
    let _states = session
        .declare_subscriber(keys.state())
        .callback(move |s| {
            if let Ok(st) = crawler_protocol::decode::<State>(&s.payload().to_bytes()) {
                *s2.lock().unwrap() = st.controller;
            }
        })
        .wait()
        .unwrap();
    let captured: Arc<Mutex<Vec<Vec<u8>>>> = Arc::default();
    let latest: Arc<Mutex<Vec<u8>>> = Arc::default();
    let (c2, l2) = (captured.clone(), latest.clone());
    let _acts = session
        .declare_subscriber(keys.actuation())
        .callback(move |s| {
            let bytes = s.payload().to_bytes().into_owned();
            let mut c = c2.lock().unwrap();
            if c.len() < 50 {
                c.push(bytes.clone());
            }
            *l2.lock().unwrap() = bytes;
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
    ];
    let kinds = payloads(&me);
    assert!(kinds.len() >= 20);
    for round in 0..3 {
        for (_, bytes) in &kinds {
            for key in &all_keys {
                session.put(key.as_str(), bytes.clone()).wait().unwrap();
            }
        }
        // replayed actuation of the real controller: duplicates and stale steps
        // (copied first: our own subscriber on that key receives these puts in this thread)
        let replay: Vec<Vec<u8>> = captured.lock().unwrap().clone();
        for bytes in replay {
            session.put(keys.actuation(), bytes).wait().unwrap();
        }
        // the controller's latest answer again, at once: a duplicate of the step just taken
        for _ in 0..200 {
            let last = latest.lock().unwrap().clone();
            session.put(keys.actuation(), last).wait().unwrap();
            std::thread::sleep(Duration::from_micros(300));
        }
        // forged but well-formed messages: a "finished" plant status from another id, a last state
        let forged = Status {
            v: PROTOCOL_VERSION,
            role: "plant".into(),
            id: "forger".into(),
            state: "finished".into(),
            message: "forged".into(),
            step: 0,
            rejected: Default::default(),
            summary: None,
        };
        session
            .put(keys.status(Role::Plant), encode(&forged))
            .wait()
            .unwrap();
        let fake = State {
            v: PROTOCOL_VERSION,
            step: 999_999 + round,
            time: 1.0,
            controller: me.clone(),
            u: vec![0.0; 128],
            vel: vec![0.0; 128],
            tension: vec![0.0; 128],
            stuck: vec![false; 128],
            mean_speed: 0.0,
            input_power: 0.0,
            last: true,
        };
        session.put(keys.state(), encode(&fake)).wait().unwrap();
        std::thread::sleep(Duration::from_millis(300));
    }

    let p = plant.wait(Duration::from_secs(120));
    let c = controller.wait(Duration::from_secs(60));
    let b = bridge.wait(Duration::from_secs(60));
    assert!(p.status.success(), "plant crashed or failed: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    assert!(b.status.success(), "bridge: {}", b.stderr);
    // the result is unchanged
    let sim = simulate(&[
        "--eps", "1", "--f0", "0.2", "--alpha", "0.5", "--t-end", "8",
    ]);
    assert_eq!(
        json(&p.stdout)["state_digest"],
        sim["state_digest"],
        "hostile payloads changed the trajectory"
    );
    // and everything was counted
    let line = p
        .stderr
        .lines()
        .find(|l| l.contains("rejected actuation messages"))
        .unwrap_or_else(|| panic!("{}", p.stderr));
    for kind in [
        "malformed",
        "version",
        "invalid",
        "foreign",
        "stale",
        "duplicate",
        "future",
    ] {
        let count: u64 = line
            .split(&format!("{kind}: "))
            .nth(1)
            .and_then(|r| r.split(|ch: char| !ch.is_ascii_digit()).next())
            .and_then(|n| n.parse().ok())
            .unwrap_or(0);
        assert!(count > 0, "no {kind} rejection counted: {line}");
    }
    assert!(
        p.stderr.contains("another controller intruder"),
        "{}",
        p.stderr
    );
    assert!(
        c.stderr.contains("ignored"),
        "controller did not count what it ignored: {}",
        c.stderr
    );
    let rejected: u64 = b
        .stderr
        .split(" rejected")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(rejected > 0, "bridge counted no rejection: {}", b.stderr);
    let rec = crawler_e2e::read_recording(&rrd).unwrap();
    let rows = rec.entity("tail/plant").rows;
    assert!(
        rows >= 8001,
        "the recording lost states: {rows} rows; bridge: {}",
        b.stderr
    );
}
