//! The co-simulation: lockstep determinism, start order, liveliness, checkpoint and resume.

use std::time::{Duration, Instant};

use crawler_e2e::{json, read_recording, repo_root, simulate, Run};

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
    // the plant creates the run's credential: the controller waits for it, then for the plant
    controller.wait_for_stderr("waiting for the run's credential", Duration::from_secs(10));
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
    // the venv and the package first (a fresh clone builds it): the plant's wait for a
    // controller is bounded
    crawler_e2e::softcrawler();
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

/// Task mode: the plant ends the run at the step that decided the task, long before the model's
/// last step, with a `finished` status at that step. The controller and the recorder believe it
/// (the plant's last state came at that step), so both end cleanly with the plant's summary; the
/// trajectory is the in-process task-mode run's.
#[test]
fn a_task_mode_run_ends_early_and_everyone_believes_its_finished_status() {
    let run = Run::new("task");
    // the paper's scenario with a short task: 2 cm, reached after about 0.7 s of the 6 s
    let paper = std::fs::read_to_string(repo_root().join("scenarios/paper.toml")).unwrap();
    let short = paper.replace("distance = 1.0 ", "distance = 0.02 ");
    assert_ne!(
        short, paper,
        "the paper's scenario sets the task's distance"
    );
    let scenario = run.path("task.toml");
    std::fs::write(&scenario, short).unwrap();
    let scenario = scenario.display().to_string();
    let task = ["--scenario", scenario.as_str(), "--task"];
    let rrd = run.path("task.rrd");
    let plant = run.plant(&[PLANT, &task].concat());
    let bridge = run.bridge(&rrd, &[]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let controller = run.controller(&[WAVE, &["--json"]].concat());
    let p = plant.wait(Duration::from_secs(60));
    let c = controller.wait(Duration::from_secs(30));
    let b = bridge.wait(Duration::from_secs(30));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    assert!(b.status.success(), "bridge: {}", b.stderr);
    let sim = simulate(&[SIM, &task].concat());
    let full = simulate(SIM);
    let co = json(&p.stdout);
    assert_eq!(co["task"]["outcome"], "reached", "{}", p.stdout);
    for key in ["state_digest", "steps", "macro_steps", "task"] {
        assert_eq!(co[key], sim[key], "{key}");
    }
    let last = sim["macro_steps"].as_u64().unwrap();
    assert!(
        last < full["macro_steps"].as_u64().unwrap() / 2,
        "the task did not end the run early: {last} steps"
    );
    assert!(p.stderr.contains("the run ends there"), "{}", p.stderr);
    // the controller answered every step up to the plant's last and took its real summary
    let summary = json(&c.stdout);
    assert_eq!(summary["steps"].as_u64(), Some(last), "{}", c.stdout);
    assert_eq!(summary["plant"]["state_digest"], sim["state_digest"]);
    // the typed task result on the wire is the plant's own, field for field
    assert_eq!(summary["plant"]["task"], sim["task"]);
    assert_eq!(summary["plant"]["task"]["outcome"], "reached");
    assert!(!c.stderr.contains("inconsistent"), "{}", c.stderr);
    // the recorder rejected nothing and kept the plant's summary and every state
    assert!(b.stderr.contains("(0 invalid)"), "{}", b.stderr);
    let rec = read_recording(&rrd).unwrap();
    assert_eq!(rec.entity("tail/plant").rows as u64, last + 1);
    assert!(rec.entity("summary/velocity").rows > 0);
}
