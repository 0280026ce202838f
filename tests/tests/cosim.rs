//! The co-simulation: lockstep determinism, start order, liveliness, checkpoint and resume.

use std::time::{Duration, Instant};

use crawler_e2e::{json, simulate, Run};

const PLANT: &[&str] = &["--eps", "1", "--t-end", "6", "--json"];
const WAVE: &[&str] = &["--policy", "wave", "--f0", "0.2", "--alpha", "0.5"];
const SIM: &[&str] = &[
    "--eps", "1", "--f0", "0.2", "--alpha", "0.5", "--t-end", "6",
];

#[test]
fn cosimulation_is_bit_identical_to_the_in_process_run() {
    let run = Run::new("det");
    let plant = run.plant(PLANT);
    let controller = run.controller(WAVE);
    let p = plant.wait(Duration::from_secs(60));
    let c = controller.wait(Duration::from_secs(30));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    let co = json(&p.stdout);
    let sim = simulate(SIM);
    assert_eq!(
        co["state_digest"], sim["state_digest"],
        "trajectories differ"
    );
    for key in [
        "velocity",
        "power",
        "mileage",
        "max_stress",
        "max_strain",
        "stuck_fraction",
        "steps",
    ] {
        assert_eq!(co[key], sim[key], "{key}");
    }
    assert!(
        c.stdout.contains("velocity V"),
        "controller prints predicted against simulated: {}",
        c.stdout
    );
}

#[test]
fn the_controller_may_start_before_the_plant() {
    let run = Run::new("order");
    let controller = run.controller(WAVE);
    controller.wait_for_stderr("waiting for the plant", Duration::from_secs(10));
    std::thread::sleep(Duration::from_millis(500));
    let plant = run.plant(PLANT);
    let p = plant.wait(Duration::from_secs(60));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(controller.wait(Duration::from_secs(30)).status.success());
    assert_eq!(
        json(&p.stdout)["state_digest"],
        simulate(SIM)["state_digest"]
    );
}

#[test]
fn the_plant_waits_and_says_for_what() {
    let run = Run::new("wait");
    let plant = run.plant(&["--wait-timeout", "1"]);
    let p = plant.wait(Duration::from_secs(20));
    assert_eq!(
        p.status.code(),
        Some(4),
        "timeout exit code; stderr: {}",
        p.stderr
    );
    assert!(
        p.stderr.contains("waiting for a controller") && p.stderr.contains(&run.id),
        "{}",
        p.stderr
    );
    assert!(p.stderr.contains("no controller joined"), "{}", p.stderr);
    // nothing was simulated: nothing to resume, no checkpoint left behind
    assert!(p.stderr.contains("no checkpoint"), "{}", p.stderr);
    assert!(!run.path("plant.ckpt").exists());
}

#[test]
fn a_killed_controller_stops_the_plant_and_resume_is_bit_identical() {
    let run = Run::new("kill");
    // long enough to be killed mid-run
    let plant = run.plant(&["--eps", "1", "--t-end", "30", "--json"]);
    let controller = run.controller(WAVE);
    plant.wait_for_stderr("joined run", Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(700));
    controller.signal("-9");
    let killed = Instant::now();
    let p = plant.wait(Duration::from_secs(10));
    let noticed = p.at.duration_since(killed);
    assert_eq!(
        p.status.code(),
        Some(3),
        "plant exit code; stderr: {}",
        p.stderr
    );
    assert!(
        noticed < Duration::from_secs(1),
        "the plant took {noticed:?} to stop"
    );
    assert!(
        p.stderr.contains("left the run") && p.stderr.contains("--resume"),
        "{}",
        p.stderr
    );
    // Noticed through liveliness within 100 ms of the controller's last answer (it was
    // answering thousands of states per second when it was killed).
    let ms: u64 = p
        .stderr
        .split("disappeared ")
        .nth(1)
        .and_then(|rest| rest.split(" ms after its last answer").next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no detection latency in: {}", p.stderr));
    assert!(ms < 100, "liveliness noticed the loss after {ms} ms");
    let ckpt = run.path("plant.ckpt");
    assert!(ckpt.is_file());

    // resume with a new controller: the final result equals the uninterrupted run
    let resumed = crawler_e2e::Proc::spawn(
        "plant-resumed",
        &crawler_e2e::bin("crawler-plant"),
        &[
            "run".into(),
            "--resume".into(),
            ckpt.display().to_string(),
            "--endpoint".into(),
            run.endpoint.clone(),
            "--json".into(),
        ],
        run.dir.path(),
    );
    let controller = run.controller(WAVE);
    let r = resumed.wait(Duration::from_secs(120));
    assert!(r.status.success(), "resumed plant: {}", r.stderr);
    assert!(controller.wait(Duration::from_secs(30)).status.success());
    let full = simulate(&[
        "--eps", "1", "--f0", "0.2", "--alpha", "0.5", "--t-end", "30",
    ]);
    let resumed = json(&r.stdout);
    assert_eq!(resumed["state_digest"], full["state_digest"]);
    assert_eq!(resumed["velocity"], full["velocity"]);
    assert_eq!(resumed["events"]["count"], full["events"]["count"]);
}

#[test]
fn two_runs_at_once_do_not_cross_talk() {
    let (a, b) = (Run::new("twin-a"), Run::new("twin-b"));
    let pa = a.plant(&["--t-end", "6", "--json"]);
    let pb = b.plant(&["--t-end", "6", "--json", "--eps", "0.5"]);
    let ca = a.controller(&["--policy", "wave", "--alpha", "0.5"]);
    let cb = b.controller(&["--policy", "wave", "--alpha", "1.0"]);
    let (ra, rb) = (
        pa.wait(Duration::from_secs(60)),
        pb.wait(Duration::from_secs(60)),
    );
    assert!(
        ra.status.success() && rb.status.success(),
        "{}\n{}",
        ra.stderr,
        rb.stderr
    );
    assert!(ca.wait(Duration::from_secs(30)).status.success());
    assert!(cb.wait(Duration::from_secs(30)).status.success());
    assert_eq!(
        json(&ra.stdout)["state_digest"],
        simulate(&["--t-end", "6", "--alpha", "0.5"])["state_digest"]
    );
    assert_eq!(
        json(&rb.stdout)["state_digest"],
        simulate(&["--t-end", "6", "--eps", "0.5", "--alpha", "1.0"])["state_digest"]
    );
}

#[test]
fn the_python_controller_gives_the_rust_wave_trajectory() {
    let run = Run::new("py");
    let plant = run.plant(&["--t-end", "6", "--json"]);
    let py = run.python_controller(&["--f0", "0.5", "--alpha", "0.5"]);
    let p = plant.wait(Duration::from_secs(90));
    let c = py.wait(Duration::from_secs(30));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "python controller: {}", c.stderr);
    let rust = Run::new("py-rust");
    let plant = rust.plant(&["--t-end", "6", "--json"]);
    let controller = rust.controller(&["--policy", "wave", "--f0", "0.5", "--alpha", "0.5"]);
    let r = plant.wait(Duration::from_secs(60));
    assert!(controller.wait(Duration::from_secs(30)).status.success());
    assert_eq!(
        json(&p.stdout)["state_digest"],
        json(&r.stdout)["state_digest"],
        "Python and Rust trajectories differ"
    );
}

#[test]
fn ctrl_c_stops_the_plant_cleanly_and_the_controller_notices() {
    let run = Run::new("sigint");
    let plant = run.plant(&["--t-end", "30"]);
    let controller = run.controller(WAVE);
    plant.wait_for_stderr("joined run", Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(300));
    plant.signal("-INT");
    let p = plant.wait(Duration::from_secs(10));
    assert_eq!(p.status.code(), Some(130), "{}", p.stderr);
    assert!(
        p.stderr.contains("interrupted") && run.path("plant.ckpt").is_file(),
        "{}",
        p.stderr
    );
    let c = controller.wait(Duration::from_secs(10));
    assert!(
        !c.status.success(),
        "the controller must notice the plant stopped"
    );
    assert!(c.stderr.contains("plant"), "{}", c.stderr);
}
