//! Recordings read back with the rerun crate's own reader.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use zenoh::Wait;

use crawler_e2e::{json, read_recording, simulate, Run};
use crawler_protocol::{decode, RunKeys, State};

const PLANT: &[&str] = &["--eps", "1", "--t-end", "8", "--json"];
const WAVE: &[&str] = &["--policy", "wave", "--f0", "0.2", "--alpha", "0.5"];

#[test]
fn a_full_recording_holds_the_metrics_of_the_in_process_run() {
    let run = Run::new("rec");
    let rrd = run.path("run.rrd");
    let plant = run.plant(PLANT);
    let bridge = run.bridge(&rrd, &["--every", "2"]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let controller = run.controller(WAVE);
    let p = plant.wait(Duration::from_secs(60));
    assert!(controller.wait(Duration::from_secs(30)).status.success());
    let b = bridge.wait(Duration::from_secs(60));
    assert!(
        p.status.success() && b.status.success(),
        "{}\n{}",
        p.stderr,
        b.stderr
    );
    let summary = json(&p.stdout);
    let sim = simulate(&[
        "--eps", "1", "--f0", "0.2", "--alpha", "0.5", "--t-end", "8",
    ]);

    // the run ends at the first communication point at or after t_end (H is a whole
    // number of internal steps), as the in-process run says
    let last = sim["macro_steps"].as_u64().unwrap();
    assert!((8000..8200).contains(&last), "{last} communication steps");
    assert_eq!(summary["macro_steps"], sim["macro_steps"]);

    let rec = read_recording(&rrd).unwrap();
    // every state: the tail displacement is logged for each step 0..=last
    let tail = rec.entity("tail/plant");
    assert_eq!(tail.rows as u64, last + 1);
    assert_eq!(tail.steps.first(), Some(&0));
    assert_eq!(tail.steps.last(), Some(&(last as i64)));
    assert!(
        tail.steps.windows(2).all(|w| w[1] == w[0] + 1),
        "states out of order or missing"
    );
    // fields every 2nd step (no decimation needed at this size, or fewer with it)
    let u = rec.entity("fields/u");
    assert!(
        (u.rows as u64) <= last / 2 + 1 && u.rows > 1000,
        "fields rows {}",
        u.rows
    );
    assert_eq!(rec.entity("fields/v").rows, u.rows);
    assert_eq!(rec.entity("body/points").rows, u.rows);
    assert!(rec.entity("heatmap/u").rows >= 1);
    // per-period metrics with the models' predictions overlaid
    let blocks = rec.entity("metrics/velocity/plant").rows;
    assert!(blocks >= 40, "{blocks} metric blocks; bridge: {}", b.stderr);
    assert_eq!(rec.entity("metrics/velocity/improved").rows, blocks);
    assert_eq!(rec.entity("metrics/power/paper").rows, blocks);
    // stick-slip: lanes and episode log
    assert!(
        rec.entities
            .keys()
            .filter(|k| k.starts_with("lanes/node_"))
            .count()
            >= 32
    );
    assert!(rec.entity("log/episodes").rows > 1000, "episodes logged");
    // the plant's final metrics, equal to the in-process run of the same scenario
    for key in [
        "velocity",
        "power",
        "mileage",
        "max_stress",
        "max_strain",
        "stuck_fraction",
    ] {
        let recorded = rec.entity(&format!("summary/{key}")).scalars[0];
        assert_eq!(
            recorded,
            sim[key].as_f64().unwrap(),
            "{key}: recording vs in-process"
        );
        assert_eq!(
            recorded,
            summary[key].as_f64().unwrap(),
            "{key}: recording vs plant"
        );
    }
    // and the recorded tail equals the in-process trajectory's last state (bit for bit)
    assert_eq!(summary["state_digest"], sim["state_digest"]);
}

/// Tracks the latest step the plant published (a passive subscriber of the run).
fn watch_steps(run: &Run) -> (zenoh::Session, Arc<AtomicU64>) {
    let session = run.transport_only_session(128);
    let keys = RunKeys::new(&run.id).unwrap();
    let latest = Arc::new(AtomicU64::new(0));
    let l2 = latest.clone();
    session
        .declare_subscriber(keys.state())
        .callback(move |s| {
            if let Ok(st) = decode::<State>(&s.payload().to_bytes()) {
                l2.fetch_max(st.step, Ordering::Relaxed);
            }
        })
        .background()
        .wait()
        .unwrap();
    (session, latest)
}

fn interrupted_recording(signal: &str) {
    let run = Run::new("sig");
    let rrd = run.path("sig.rrd");
    let plant = run.plant(&["--eps", "1", "--t-end", "40"]);
    let bridge = run.bridge(&rrd, &[]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let (_watch, latest) = watch_steps(&run);
    let controller = run.controller(WAVE);
    plant.wait_for_stderr("joined run", Duration::from_secs(30));
    let t0 = Instant::now();
    while latest.load(Ordering::Relaxed) < 3000 && t0.elapsed() < Duration::from_secs(30) {
        std::thread::sleep(Duration::from_millis(20));
    }
    // steps per second of the run, to translate "one second" into steps
    let (s0, w0) = (latest.load(Ordering::Relaxed), Instant::now());
    std::thread::sleep(Duration::from_millis(500));
    let rate = (latest.load(Ordering::Relaxed) - s0) as f64 / w0.elapsed().as_secs_f64();
    let at_kill = latest.load(Ordering::Relaxed);
    bridge.signal(signal);
    let b = bridge.wait(Duration::from_secs(20));
    if signal != "-9" {
        // closed properly, and says it was interrupted: 130, like every program of the project
        assert_eq!(b.status.code(), Some(130), "{}", b.stderr);
        assert!(
            b.stderr.contains("interrupted; recording closed properly"),
            "{}",
            b.stderr
        );
    }
    // the co-simulation goes on without the recorder and finishes
    let p = plant.wait(Duration::from_secs(120));
    assert!(
        p.status.success(),
        "the plant must not notice the recorder going away: {}",
        p.stderr
    );
    assert!(controller.wait(Duration::from_secs(30)).status.success());
    // the file is readable, in order, and lost at most about one second of data
    let rec = read_recording(&rrd)
        .unwrap_or_else(|e| panic!("recording unreadable after {signal}: {e:#}"));
    let tail = rec.entity("tail/plant");
    let last = *tail.steps.last().unwrap() as u64;
    assert!(tail.steps.windows(2).all(|w| w[1] > w[0]));
    let lost = at_kill.saturating_sub(last) as f64 / rate;
    eprintln!("{signal}: {lost:.3} s lost at {rate:.0} steps/s");
    assert!(
        lost <= 1.0,
        "{signal}: last recorded step {last}, {at_kill} at the kill: {lost:.2} s lost"
    );
}

#[test]
fn sigint_finishes_the_recording_properly() {
    interrupted_recording("-INT");
}

#[test]
fn sigterm_finishes_the_recording_properly() {
    interrupted_recording("-TERM");
}

#[test]
fn kill_9_leaves_a_readable_recording_and_the_run_goes_on() {
    interrupted_recording("-9");
}
