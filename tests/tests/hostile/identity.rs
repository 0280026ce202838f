//! Who is who: sessions without the credential, or with the zenoh password only, that forge
//! messages, liveliness tokens and answers to the plant's queries.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use zenoh::sample::Locality;
use zenoh::Wait;

use crawler_e2e::{json, Ended, Run};
use crawler_protocol::{decode, encode, ModelInfo, ProcessId, Role, RunKeys, State};
use crawler_transport::Access;

use super::payloads::{payloads, spoofed};
use super::{
    block, bridge_count, forged_events, rejected, simulated, status, Budgets, RECORDER, WAVE,
};

/// The counters of the plant that only an attack can move (a `duplicate` can come from the
/// controller's own answer to a resent state, on a busy machine).
const ATTACK_COUNTERS: [&str; 5] = ["malformed", "foreign", "other_run", "replayed", "overflow"];

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
        .declare_token(keys.alive(Role::Controller, "ffffffffffffffff"))
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
        keys.join(),
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
                block(&session, key, bytes.clone());
            }
        }
        for st in [status("x", "finished", 6000), status("x", "failed", 10)] {
            block(&session, &keys.status(Role::Plant), encode(&st));
        }
        for key in [keys.model(), keys.environment()] {
            let replies = session
                .get(&key)
                .payload(vec![0u8; 16])
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
    for kind in ATTACK_COUNTERS {
        assert_eq!(rejected(&p.stderr, kind), 0, "{kind}: {}", p.stderr);
    }
    assert!(!p.stderr.contains("ffffffffffffffff"), "{}", p.stderr);
    // The recorder recorded the run and nothing else: every state, nothing rejected after
    // decoding. (Its count of payloads refused at arrival also holds the run's own messages
    // that arrived before it learnt the run instance from the plant's sealed reply, which it
    // cannot judge: `Refused::other_run`; the outsider's never reached it, as above.)
    let states = json(&p.stdout)["macro_steps"].as_u64().unwrap() + 1;
    assert_eq!(bridge_count(&b.stderr, " states"), states, "{}", b.stderr);
    assert_eq!(bridge_count(&b.stderr, " rejected"), 0, "{}", b.stderr);
}

/// A session that passed zenoh's authentication but does not hold the message key (a shared
/// router's position: it relays and sees everything) reads the controller's id and each step
/// from the states, and answers every state before the controller does with an actuation
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
    let (outsider, pid) = run.participant(
        &Access::Password(run.load_credential().transport_password()),
        None,
        Role::Controller,
        512,
    );
    let session = outsider.session().clone();
    let keys = RunKeys::new(&run.id).unwrap();
    // it can read the run's description (a router sees everything): its last step
    let info = read_the_run_description(&session, &keys);
    let Spoofer {
        seen,
        states,
        spoofing,
    } = spoof_every_state(&session, &keys);
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
    forge_the_plants_end(&session, &keys, &pid, &info);
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
    check_no_spoofed_answer_was_taken(&p, &c, &b, spoofed, &info);
}

/// The run's description as anyone on the run's keys can read it (a router sees everything):
/// the plant's answer to a `model` query from `session`.
fn read_the_run_description(session: &zenoh::Session, keys: &RunKeys) -> ModelInfo {
    let replies = session
        .get(keys.model())
        .payload(vec![1u8; 16])
        .wait()
        .unwrap();
    let reply = replies.recv().unwrap();
    decode(&reply.result().unwrap().payload().to_bytes()).unwrap()
}

/// The spoofer of [`spoof_every_state`]: what it saw and its sending thread.
struct Spoofer {
    /// The number of states with a controller's id it saw.
    seen: Arc<AtomicU64>,
    /// The subscriber to the run's states; dropping it ends the spoofing thread's input.
    states: zenoh::pubsub::Subscriber<()>,
    /// The spoofing thread: it answers with the number of spoofed actuations it sent.
    spoofing: std::thread::JoinHandle<u64>,
}

/// Answers every state `session` sees that names a controller, from `session`, with spoofed
/// actuation for its step and the next.
fn spoof_every_state(session: &zenoh::Session, keys: &RunKeys) -> Spoofer {
    // the spoofer: Actuation(n) and Actuation(n + 1) with the controller's id and another wave,
    // sent as soon as State(n) arrives, with a copy of the state's envelope where the
    // controller's would be (it cannot seal), by a thread (a zenoh callback must not block)
    let (spoof_tx, spoof_rx) = std::sync::mpsc::channel::<(u64, String, Vec<u8>)>();
    let (spoofer, act_key) = (session.clone(), keys.actuation());
    let spoofing = std::thread::spawn(move || {
        let mut n = 0u64;
        for (step, controller, att) in spoof_rx.iter() {
            for step in [step, step + 1] {
                spoofer
                    .put(&act_key, spoofed(step, &controller))
                    .attachment(att.clone())
                    .congestion_control(zenoh::qos::CongestionControl::Block)
                    .wait()
                    .unwrap();
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
            let att = s
                .attachment()
                .map(|a| a.to_bytes().into_owned())
                .unwrap_or_default();
            if let Some(tx) = spoof_tx.lock().unwrap().as_ref() {
                let _ = tx.send((st.step, st.controller, att));
            }
        })
        .wait()
        .unwrap();
    Spoofer {
        seen,
        states,
        spoofing,
    }
}

/// Forges, from `session` without a seal, the plant's (`pid`) terminal statuses at the run's
/// last step, mid-run and at step 0, and impossible episodes.
fn forge_the_plants_end(
    session: &zenoh::Session,
    keys: &RunKeys,
    pid: &ProcessId,
    info: &ModelInfo,
) {
    for step in [info.last_step, info.last_step / 2, 0] {
        for state in ["finished", "failed", "stopped"] {
            block(
                session,
                &keys.status(Role::Plant),
                encode(&status(pid.as_str(), state, step)),
            );
        }
    }
    block(session, &keys.events(), encode(&forged_events(700)));
}

/// Checks that the `spoofed` answers were sent and refused by the plant (`p`), that the
/// controller (`c`) answered every step and took the plant's real summary, and that the
/// recorder (`b`) refused the forgeries at arrival.
fn check_no_spoofed_answer_was_taken(
    p: &Ended,
    c: &Ended,
    b: &Ended,
    spoofed: u64,
    info: &ModelInfo,
) {
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

/// A session with the zenoh password only declares a controller's liveliness token before the
/// real controller starts and plant tokens (one with the plant's own id), answers the plant's
/// `model` and `environment` queries with rival replies (a copy of the plant's own answer
/// without its seal, echoing each challenge; and the plant's own sealed answer to an earlier
/// question), and withdraws its tokens during the run. Nobody is joined or ended by it: the
/// plant takes the real controller, the controller and the recorder find the real plant, every
/// process ends cleanly and the result is the in-process one.
#[test]
fn forged_tokens_and_rival_replies_neither_join_nor_end_a_run() {
    let run = Run::new("rival");
    let rrd = run.path("rival.rrd");
    let plant = run.plant(&["--eps", "1", "--t-end", "6", "--json"]);
    let (outsider, pid) = run.participant(
        &Access::Password(run.load_credential().transport_password()),
        None,
        Role::Controller,
        512,
    );
    let session = outsider.session().clone();
    let keys = RunKeys::new(&run.id).unwrap();
    // the plant's own sealed answers to an earlier question: a replay for any later one
    let earlier = |key: String| {
        let replies = session.get(key).payload(vec![7u8; 16]).wait().unwrap();
        let s = replies.recv().unwrap().into_result().unwrap();
        (
            s.payload().to_bytes().into_owned(),
            s.attachment().unwrap().to_bytes().into_owned(),
        )
    };
    let model = earlier(keys.model());
    let environment = earlier(keys.environment());
    let rival = |key: String, (payload, attachment): (Vec<u8>, Vec<u8>)| {
        let k = key.clone();
        session
            .declare_queryable(key)
            .callback(move |q| {
                let challenge = q
                    .payload()
                    .map(|p| p.to_bytes().into_owned())
                    .unwrap_or_default();
                // the replayed sealed answer, then the plant's payload echoing this challenge,
                // without a valid seal
                let _ = q
                    .reply(k.as_str(), payload.clone())
                    .attachment(attachment.clone())
                    .wait();
                let mut forged = attachment[..42].to_vec();
                forged.extend(&challenge);
                forged.extend([0u8; 32]);
                let _ = q
                    .reply(k.as_str(), payload.clone())
                    .attachment(forged)
                    .wait();
            })
            .wait()
            .unwrap()
    };
    let _model = rival(keys.model(), model);
    let _environment = rival(keys.environment(), environment);
    let tokens: Vec<zenoh::liveliness::LivelinessToken> = [
        keys.alive(Role::Controller, "ffffffffffffffff"),
        keys.alive(Role::Plant, "0123456789abcdef"),
        keys.alive(Role::Plant, pid.as_str()),
    ]
    .into_iter()
    .map(|k| session.liveliness().declare_token(k).wait().unwrap())
    .collect();
    std::thread::sleep(Duration::from_millis(300));
    let bridge = run.bridge(&rrd, RECORDER);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let controller = run.controller(&[WAVE, &["--json"]].concat());
    plant.wait_for_stderr("joined run", Duration::from_secs(30));
    // the tokens go away while the run goes on
    std::thread::sleep(Duration::from_millis(500));
    for t in tokens {
        t.undeclare().wait().unwrap();
    }
    let p = plant.wait(Duration::from_secs(60));
    let c = controller.wait(Duration::from_secs(30));
    let b = bridge.wait(Duration::from_secs(30));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    assert!(b.status.success(), "bridge: {}", b.stderr);
    let digest = simulated("6")["state_digest"].clone();
    assert_eq!(json(&p.stdout)["state_digest"], digest);
    // the controller joined (not the token's id), found the real plant and took its report
    assert!(!p.stderr.contains("ffffffffffffffff"), "{}", p.stderr);
    let summary = json(&c.stdout);
    assert_eq!(summary["plant"]["state_digest"], digest, "{}", c.stdout);
    assert!(
        c.stderr.contains(&format!("plant {pid} found")),
        "{}",
        c.stderr
    );
    // the recorder recorded the run and its end
    let rec = crawler_e2e::read_recording(&rrd).unwrap();
    assert!(rec.entity("tail/plant").rows > 6000);
    assert_eq!(
        rec.entity("summary/velocity").scalars,
        [json(&p.stdout)["velocity"].as_f64().unwrap()]
    );
}
