//! Replays of a run's own sealed messages by a session that holds only the zenoh password (a
//! shared router's position): inside the run, and from an earlier run with the same id and a
//! credential kept for both. None is answered, applied or recorded; each is counted.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use zenoh::sample::Locality;
use zenoh::Wait;

use crawler_e2e::{json, Proc, Run};
use crawler_protocol::{ProcessId, RunKeys, RunNonce};
use crawler_transport::{Access, Credential};

use super::{
    bridge_count, controller_refused, in_process_digest, rejected, Captured, Honest, Shared,
};

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

/// The run of these tests: the stateful `reflex` controller on a small plant in stick-slip,
/// the controller told the same scenario.
const SCENARIO: &[&str] = &["--eps", "1", "--cells", "128", "--t-end"];

fn plant_args(t_end: &str) -> Vec<&str> {
    let mut a = SCENARIO.to_vec();
    a.extend([t_end, "--json"]);
    a
}

fn controller_args(t_end: &str) -> Vec<&str> {
    let mut a = vec!["--policy", "reflex"];
    a.extend(SCENARIO);
    a.push(t_end);
    a
}

/// Subscribes `session` to every key of the run the plant and the controller publish on, and
/// keeps what arrives (`keep`, at most `max` samples), counting the plant's events and metrics
/// of instance `run` from `plant` once each in `honest`; `replay` (if given) gets every sample
/// to send it again at once.
fn capture(
    session: &zenoh::Session,
    keys: &RunKeys,
    (keep, max): (Shared<Vec<Captured>>, usize),
    honest: Option<(Shared<Honest>, RunNonce, ProcessId)>,
    replay: Option<std::sync::mpsc::Sender<Captured>>,
) -> Vec<zenoh::pubsub::Subscriber<()>> {
    let replay = Arc::new(Mutex::new(replay));
    [
        keys.state(),
        keys.events(),
        keys.metrics(),
        keys.actuation(),
        keys.prediction(),
        keys.status_all(),
        keys.join(),
    ]
    .into_iter()
    .map(|key| {
        let (keep, honest, replay) = (keep.clone(), honest.clone(), replay.clone());
        session
            .declare_subscriber(key)
            .allowed_origin(Locality::Remote)
            .callback(move |s| {
                let c = Captured::of(&s);
                if let Some((h, run, plant)) = &honest {
                    h.lock().unwrap().count(&s, run, plant);
                }
                {
                    let mut k = keep.lock().unwrap();
                    if k.len() < max {
                        k.push(c.clone());
                    }
                }
                if let Some(tx) = replay.lock().unwrap().as_ref() {
                    let _ = tx.send(c);
                }
            })
            .wait()
            .unwrap()
    })
    .collect()
}

/// What the recorder recorded of the plant's events and metrics is what the plant sent, once:
/// never more than an honest listener counted, and all of it when the recorder dropped
/// nothing (it drops only when it falls behind, and says so).
fn recorded_once(bridge_stderr: &str, honest: &Honest) {
    let episodes = bridge_count(bridge_stderr, " stick episodes");
    let blocks = bridge_count(bridge_stderr, " metric blocks");
    assert!(
        honest.episodes > 100 && honest.blocks > 5,
        "too short a run"
    );
    assert!(
        episodes <= honest.episodes && blocks <= honest.blocks,
        "recorded {episodes} episodes and {blocks} blocks of {} and {} sent: {bridge_stderr}",
        honest.episodes,
        honest.blocks
    );
    if bridge_count(bridge_stderr, " dropped") == 0 {
        assert_eq!(
            (episodes, blocks),
            (honest.episodes, honest.blocks),
            "{bridge_stderr}"
        );
    }
}

/// A session with the zenoh password only sends every state, event, metric block, status and
/// actuation of the run again as soon as it sees it, twice, and everything once more at the end:
/// the stateful controller answers each step once (its result is the in-process one), the plant
/// applies nothing twice, the recorder records each episode and block once, and every replay
/// that reached them is counted.
#[test]
fn replays_of_a_runs_own_messages_are_refused_and_counted() {
    let run = Run::new("replay");
    let rrd = run.path("replay.rrd");
    let plant = run.plant(&plant_args("6"));
    let bridge = run.bridge(&rrd, super::RECORDER);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let (spy, plant_id) = run.participant(
        &Access::Password(run.load_credential().transport_password()),
        None,
        crawler_protocol::Role::Bridge,
        128,
    );
    let nonce = spy.run().get().unwrap();
    let session = spy.session().clone();
    let keys = RunKeys::new(&run.id).unwrap();
    let (tx, rx) = std::sync::mpsc::channel::<Captured>();
    let replayer = session.clone();
    let replaying = std::thread::spawn(move || {
        let mut n = 0u64;
        for c in rx.iter() {
            c.replay(&replayer);
            c.replay(&replayer);
            n += 2;
        }
        n
    });
    let kept: Shared<Vec<Captured>> = Arc::default();
    let honest: Shared<Honest> = Arc::default();
    let subs = capture(
        &session,
        &keys,
        (kept.clone(), 20_000),
        Some((honest.clone(), nonce, plant_id)),
        Some(tx),
    );
    let controller = run.controller(&controller_args("6"));
    // once the run is under way, its first messages once more, long after they were taken
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    while kept.lock().unwrap().len() < 1000 && std::time::Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    let early: Vec<Captured> = kept.lock().unwrap().clone();
    for c in &early {
        c.replay(&session);
    }
    let p = plant.wait(Duration::from_secs(300));
    let c = controller.wait(Duration::from_secs(60));
    let b = bridge.wait(Duration::from_secs(60));
    drop(subs);
    let replayed = replaying.join().unwrap();
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    assert!(b.status.success(), "bridge: {}", b.stderr);
    assert!(replayed > 1000, "only {replayed} replays were sent");
    assert_eq!(
        json(&p.stdout)["state_digest"].as_str().unwrap(),
        in_process_digest("reflex", 128, 6.0),
        "replays changed the stateful controller's run"
    );
    assert!(rejected(&p.stderr, "replayed") > 0, "{}", p.stderr);
    assert!(
        controller_refused(&c.stderr, " replayed") > 0,
        "{}",
        c.stderr
    );
    assert!(
        bridge_count(&b.stderr, " refused at arrival") > 0,
        "{}",
        b.stderr
    );
    recorded_once(&b.stderr, &honest.lock().unwrap());
}

/// Two runs with the same id and a credential kept for both (`--credential FILE`): a session
/// with the zenoh password only records the first run and sends all of it again during the
/// second. The first run's messages are sealed with the same key, but of another run instance:
/// each is refused and counted as such, the second run's result is the in-process one and its
/// recording holds its own episodes and blocks once.
#[test]
fn replays_from_an_earlier_run_with_a_kept_credential_are_refused() {
    let first = Run::new("kept");
    let cred = first.path("kept.credential");
    let cred_arg = cred.display().to_string();
    let with_cred = |args: Vec<&str>| {
        let mut a = args;
        a.extend(["--credential", cred_arg.as_str()]);
        a.into_iter().map(String::from).collect::<Vec<String>>()
    };

    // the first run, recorded by the spy
    let pa = with_cred(plant_args("6"));
    let plant = first.plant(&strs(&pa));
    let bridge = first.bridge(
        &first.path("first.rrd"),
        &strs(&with_cred(super::RECORDER.to_vec())),
    );
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let password = Credential::load(&cred, &first.id)
        .unwrap()
        .transport_password();
    let (spy, _) = first.participant(
        &Access::Password(password.clone()),
        None,
        crawler_protocol::Role::Bridge,
        128,
    );
    let keys = RunKeys::new(&first.id).unwrap();
    let kept: Shared<Vec<Captured>> = Arc::default();
    let subs = capture(spy.session(), &keys, (kept.clone(), 50_000), None, None);
    let controller = first.controller(&strs(&with_cred(controller_args("6"))));
    let p = plant.wait(Duration::from_secs(300));
    assert!(p.status.success(), "first plant: {}", p.stderr);
    assert!(controller.wait(Duration::from_secs(60)).status.success());
    assert!(bridge.wait(Duration::from_secs(60)).status.success());
    drop(subs);
    spy.close();
    let old: Vec<Captured> = kept.lock().unwrap().clone();
    assert!(old.len() > 3000, "only {} messages recorded", old.len());
    assert!(cred.is_file(), "the named credential is kept");

    // the second run: same id, same credential
    let second = first.same_id();
    let rrd = second.path("second.rrd");
    let plant: Proc = second.plant(&strs(&pa));
    let bridge = second.bridge(&rrd, &strs(&with_cred(super::RECORDER.to_vec())));
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let (spy, plant_id) = second.participant(
        &Access::Password(password),
        None,
        crawler_protocol::Role::Bridge,
        128,
    );
    let nonce = spy.run().get().unwrap();
    let session = spy.session().clone();
    let honest: Shared<Honest> = Arc::default();
    let subs = capture(
        &session,
        &keys,
        (Arc::default(), 0),
        Some((honest.clone(), nonce, plant_id)),
        None,
    );
    // the first run's messages, again and again while the second goes on
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let replaying = {
        let (session, stop) = (session.clone(), stop.clone());
        std::thread::spawn(move || {
            let mut n = 0u64;
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                for c in &old {
                    c.replay(&session);
                    n += 1;
                    if stop.load(std::sync::atomic::Ordering::Relaxed) {
                        break;
                    }
                }
            }
            n
        })
    };
    let controller = second.controller(&strs(&with_cred(controller_args("6"))));
    let p = plant.wait(Duration::from_secs(300));
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let c = controller.wait(Duration::from_secs(60));
    let b = bridge.wait(Duration::from_secs(60));
    drop(subs);
    let replayed = replaying.join().unwrap();
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    assert!(b.status.success(), "bridge: {}", b.stderr);
    assert!(replayed > 1000, "only {replayed} replays were sent");
    assert_eq!(
        json(&p.stdout)["state_digest"].as_str().unwrap(),
        in_process_digest("reflex", 128, 6.0),
        "the first run's messages changed the second run"
    );
    assert!(rejected(&p.stderr, "other_run") > 0, "{}", p.stderr);
    assert!(
        controller_refused(&c.stderr, " of another run instance") > 0,
        "{}",
        c.stderr
    );
    assert!(
        bridge_count(&b.stderr, " refused at arrival") > 0,
        "{}",
        b.stderr
    );
    recorded_once(&b.stderr, &honest.lock().unwrap());
}
