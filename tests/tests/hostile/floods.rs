//! Floods: every key, from the legal size to 50 MB, before and after the join.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crawler_e2e::{json, rss_kib, simulate, Proc, Run};
use crawler_protocol::{Role, RunKeys, RunLimits};
use crawler_transport::participant::{Congestion, Outlet};
use crawler_transport::{Access, Participant, Seal};

use super::{bridge_count, put, rejected, sample_peaks, BUDGET_MIB, WAVE};

/// What a flood sent, by where it went.
#[derive(Default)]
struct Sent {
    /// Everything.
    all: AtomicU64,
    /// Delivered (blocking) to the plant's own keys (actuation, join), within what zenoh
    /// reassembles: each must be counted by the plant.
    to_plant: AtomicU64,
    /// Delivered (blocking) to the plant's keys the recorder listens to (state, events, metrics):
    /// each must be refused and counted by the recorder.
    to_recorder: AtomicU64,
}

/// Sends payloads around every key's limit until `stop`, from `participant` (enveloped and
/// sealed when it holds the message key; enveloped with no valid seal when not). One thread
/// delivers (blocking when the link is busy) bursts of payloads of each key's legal size and
/// one byte more; another sends payloads beyond what zenoh reassembles (2 MiB, and the 50 MB of
/// the original report), which the sender drops when its queue is full.
fn flood(
    participant: Arc<Participant>,
    keys: RunKeys,
    stop: Arc<AtomicBool>,
    sent: Arc<Sent>,
) -> Vec<std::thread::JoinHandle<()>> {
    let limits = RunLimits::new(128);
    let plan = vec![
        (keys.actuation(), limits.actuation()),
        (keys.join(), RunLimits::join()),
        (keys.state(), limits.state()),
        (keys.events(), limits.events()),
        (keys.metrics(), RunLimits::metrics()),
        (keys.prediction(), RunLimits::text_message()),
        (keys.status(Role::Plant), RunLimits::text_message()),
    ];
    let bulk = {
        let (p, plan, stop, sent, keys) = (
            participant.clone(),
            plan.clone(),
            stop.clone(),
            sent.clone(),
            keys.clone(),
        );
        std::thread::spawn(move || {
            let outlets: Vec<(String, usize, Outlet)> = plan
                .iter()
                .map(|(k, l)| {
                    (
                        k.clone(),
                        *l,
                        p.outlet(k, Congestion::Block, false).unwrap(),
                    )
                })
                .collect();
            while !stop.load(Ordering::Relaxed) {
                for (key, limit, outlet) in &outlets {
                    let n = if *limit > 64 << 10 { 2 } else { 20 };
                    for size in std::iter::repeat_n(*limit, n).chain([*limit + 1]) {
                        outlet.put(vec![0xc1; size]).unwrap();
                        sent.all.fetch_add(1, Ordering::Relaxed);
                        if *key == keys.actuation() || *key == keys.join() {
                            sent.to_plant.fetch_add(1, Ordering::Relaxed);
                        }
                        if *key == keys.state() || *key == keys.events() || *key == keys.metrics() {
                            sent.to_recorder.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        })
    };
    let big = std::thread::spawn(move || {
        let session = participant.session();
        let mut round = 0u64;
        while !stop.load(Ordering::Relaxed) {
            for (key, _) in &plan {
                put(session, key, vec![0xc1; RunLimits::text_message() + 64]);
                if round.is_multiple_of(10) {
                    put(session, key, vec![0xc1; 50 << 20]);
                }
                sent.all.fetch_add(1, Ordering::Relaxed);
            }
            round += 1;
            std::thread::sleep(Duration::from_millis(100));
        }
    });
    vec![bulk, big]
}

/// Floods every key with payloads from the legal size to 50 MB, from a session without the
/// message key and from one holding the credential (sealed), before the controller joins and
/// again while the run goes on. Each process stays within [`BUDGET_MIB`] of its idle resident
/// memory, the run's result is unchanged, and what was dropped was counted: every payload
/// delivered to the plant's keys is counted by the plant under some cause (an overflow among
/// them when the inbox was full, which may or may not happen), every one on the keys the
/// recorder takes only from the plant is refused and counted by the recorder.
#[test]
fn floods_before_and_after_the_join_stay_within_every_process_budget() {
    let run = Run::new("flood");
    let rrd = run.path("flood.rrd");
    // long enough (20 000 steps) that the run outlasts the flood: what the flood delivered
    // reached a plant that was there to count it
    let plant = run.plant(&["--eps", "1", "--t-end", "20", "--cells", "128", "--json"]);
    let bridge = run.bridge(&rrd, &[]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    plant.wait_for_stderr("waiting for a controller", Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(300));
    let idle_of = |p: &Proc| rss_kib(p.pid()).expect("running").0;
    let (plant_idle, bridge_idle) = (idle_of(&plant), idle_of(&bridge));

    let credential = run.load_credential();
    let seal = Seal::new(&credential.message_key());
    let keys = RunKeys::new(&run.id).unwrap();
    let password = Access::Password(credential.transport_password());
    let outsider = Arc::new(run.participant(&password, None, Role::Controller, 512).0);
    let insider = Arc::new(
        run.participant(&password, Some(seal), Role::Controller, 512)
            .0,
    );
    let sent = Arc::new(Sent::default());
    let floods = |stop: &Arc<AtomicBool>| {
        let mut threads = flood(outsider.clone(), keys.clone(), stop.clone(), sent.clone());
        threads.extend(flood(
            insider.clone(),
            keys.clone(),
            stop.clone(),
            sent.clone(),
        ));
        threads
    };
    // before the join: plant and recorder
    let stop = Arc::new(AtomicBool::new(false));
    let sampling = sample_peaks(vec![plant.pid(), bridge.pid()], stop.clone());
    let pre = floods(&stop);
    std::thread::sleep(Duration::from_secs(3));
    stop.store(true, Ordering::Relaxed);
    pre.into_iter().for_each(|f| f.join().unwrap());
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
    during.into_iter().for_each(|f| f.join().unwrap());
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
            "--eps", "1", "--f0", "0.2", "--alpha", "0.5", "--t-end", "20", "--cells", "128"
        ])["state_digest"],
        "the flood changed the trajectory"
    );
    let all = sent.all.load(Ordering::Relaxed);
    assert!(all > 100, "the flood sent only {all} payloads");
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
    // Every payload delivered to the plant's keys was counted, by cause: oversized ones as
    // malformed, the outsider's (no valid seal) and the insider's (not the run's controller)
    // as foreign, join requests that do not decode as malformed, and any beyond an inbox's
    // budget as overflow (counted whenever it happens; whether it happens depends on how fast
    // the plant drains its inbox).
    let counted: u64 = ["malformed", "foreign", "version", "invalid", "overflow"]
        .iter()
        .map(|k| rejected(&p.stderr, k))
        .sum();
    let to_plant = sent.to_plant.load(Ordering::Relaxed);
    // The flood goes on after the plant has ended (its puts then reach no one), so the plant
    // cannot count all that was sent; it counts each one it received once, under one cause.
    assert!(
        counted > 0 && counted <= to_plant,
        "the plant counted {counted} payloads of the {to_plant} sent to its keys: {}",
        p.stderr
    );
    let to_recorder = sent.to_recorder.load(Ordering::Relaxed);
    assert!(
        bridge_count(&b.stderr, " refused at arrival") >= to_recorder,
        "the recorder counted fewer than the {to_recorder} payloads delivered on the plant's keys: {}",
        b.stderr
    );
    assert!(
        c.stderr.contains("refused at arrival"),
        "controller: {}",
        c.stderr
    );
}
