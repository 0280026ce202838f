//! Every step acted on exactly once: a stateful policy (`reflex`, whose every call changes its
//! state) gives one result in process, co-simulated, when the plant has to resend its states
//! (the controller holds an answer past the plant's resend time) and under twice as much CPU
//! load as the machine has cores; and a run handed over from one controller to another at a
//! step, live (`--take-over-at`, `crawler run --then`, or after the first one died with the
//! plant's `--on-controller-lost wait`), is bit-identical to the first controller's run to that
//! step, a checkpoint there and the second controller's run from it, computed in process with
//! the execution's resume point.
//!
//! Nothing here depends on timing: the resend is forced by the controller's hold (longer than
//! the plant's resend time whatever the load), and every wait is bounded generously.

use std::convert::Infallible;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crawler_e2e::{bin, json, read_recording, Proc, Run};
use crawler_physics::execution::{
    Actuation, Controller, Execution, ExecutionError, Observation, Start,
};
use crawler_physics::scenario::{Overrides, Scenario};
use crawler_policies::in_process::Acting;
use crawler_policies::{Context, Params};

/// The scenario of these runs: the paper's body in stick-slip on 128 cells for 6 s (the
/// shortest run with a steady window after the 5 s transient).
const FLAGS: &[&str] = &["--eps", "1", "--cells", "128", "--t-end", "6"];

fn scenario() -> Scenario {
    Scenario::load(
        None,
        &Overrides {
            eps: Some(1.0),
            cells: Some(128),
            t_end: Some(6.0),
            ..Overrides::default()
        },
    )
    .unwrap()
}

/// The first communication step at or after `t` seconds of `scenario()`.
fn step_at(t: f64) -> u64 {
    scenario().plant.discretisation().unwrap().steps_until(t)
}

/// A policy as the execution's controller until step `until` (it stops the run there).
struct Until<'a> {
    acting: Acting<'a>,
    until: u64,
}

impl Controller for Until<'_> {
    type Stop = ();

    fn act(&mut self, obs: &Observation<'_>) -> Result<Option<Actuation>, ()> {
        if obs.step >= self.until {
            return Err(());
        }
        let a: Result<_, Infallible> = self.acting.act(obs);
        Ok(a.unwrap_or_else(|e| match e {}))
    }
}

/// The state digest of policy `a` from the start to step `n`, the run's resume point there (what
/// a checkpoint holds), and policy `b` from there to the end, in process: the execution's own
/// loop, each policy built as a controller of the run is told it.
fn handed_over(a: &str, n: u64, b: &str) -> String {
    let s = scenario();
    let ctx = Context::of(&s).unwrap();
    let mut first = crawler_policies::build(a, &ctx, &Params::none()).unwrap();
    let mut execution = Execution::new(&s, Start::default()).unwrap();
    let mut until = Until {
        acting: Acting::new(first.as_mut()),
        until: n,
    };
    match execution.run(&mut until, &mut []) {
        Err(ExecutionError::Stopped(())) => {}
        other => panic!("the first policy's run did not stop at step {n}: {other:?}"),
    }
    assert_eq!(execution.plant().macro_step(), n);
    let resume = execution.resume_point();
    let mut execution = Execution::resume(&s, resume).unwrap();
    let mut second = crawler_policies::build(b, &ctx, &Params::none()).unwrap();
    execution
        .run(&mut Acting::new(second.as_mut()), &mut [])
        .unwrap();
    execution.report().unwrap().state_digest
}

/// `policy`'s state digest over the whole run, in process.
fn in_process(policy: &str) -> String {
    crawler_policies::in_process::run_named(&scenario(), policy, &Params::none())
        .unwrap()
        .report
        .state_digest
}

fn with(base: &[&str], more: &[&str]) -> Vec<String> {
    base.iter().chain(more).map(|s| s.to_string()).collect()
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

/// The count after `kind: ` in the plant's "rejected messages" line.
fn rejected(stderr: &str, kind: &str) -> u64 {
    let line = stderr
        .lines()
        .find(|l| l.contains("rejected messages: Rejections"))
        .unwrap_or("");
    line.split(&format!("{kind}: "))
        .nth(1)
        .and_then(|r| r.split(|ch: char| !ch.is_ascii_digit()).next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0)
}

/// Co-simulates `reflex` on `scenario()` with the controller holding its answer to step 100
/// for 1.2 s: the plant resends that state at least twice meanwhile, and the controller answers
/// the resent ones with the same actuation. Returns the plant's report and stderr, and the
/// controller's stderr.
fn reflex_with_forced_resends(tag: &str) -> (serde_json::Value, String, String) {
    let run = Run::new(tag);
    let plant = run.plant(&strs(&with(FLAGS, &["--json"])));
    let controller = run.controller(&strs(&with(
        &["--policy", "reflex", "--stall", "100:1200"],
        FLAGS,
    )));
    let p = plant.wait(Duration::from_secs(600));
    let c = controller.wait(Duration::from_secs(120));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(c.status.success(), "controller: {}", c.stderr);
    (json(&p.stdout), p.stderr, c.stderr)
}

#[test]
fn a_stateful_policy_gives_one_digest_in_process_cosimulated_and_with_forced_resends() {
    let expected = in_process("reflex");
    // plain
    let run = Run::new("once");
    let plant = run.plant(&strs(&with(FLAGS, &["--json"])));
    let controller = run.controller(&strs(&with(&["--policy", "reflex"], FLAGS)));
    let p = plant.wait(Duration::from_secs(600));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(controller.wait(Duration::from_secs(120)).status.success());
    assert_eq!(json(&p.stdout)["state_digest"], expected.as_str());
    // the plant resent state 100 while the controller held its answer: answered once
    let (report, plant_err, controller_err) = reflex_with_forced_resends("resend");
    assert_eq!(
        report["state_digest"],
        expected.as_str(),
        "a resent state was answered as a new step"
    );
    assert!(
        controller_err.contains("resent") && controller_err.contains("got the same answer again"),
        "{controller_err}"
    );
    // the same answer, again, after the plant had moved on: a duplicate, counted, not applied
    assert!(rejected(&plant_err, "duplicate") >= 1, "{plant_err}");
}

#[test]
fn a_stateful_policy_gives_the_same_digest_under_twice_the_cpu_load() {
    let expected = in_process("reflex");
    // a load generator: twice as many busy threads as the machine has cores, for this run only
    let stop = Arc::new(AtomicBool::new(false));
    let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
    let load: Vec<_> = (0..2 * cores)
        .map(|_| {
            let stop = stop.clone();
            std::thread::spawn(move || {
                let mut x = 0u64;
                while !stop.load(Ordering::Relaxed) {
                    for i in 0..100_000u64 {
                        x = x.wrapping_mul(6364136223846793005).wrapping_add(i);
                    }
                    std::hint::black_box(x);
                }
            })
        })
        .collect();
    let (report, _, _) = reflex_with_forced_resends("loaded");
    stop.store(true, Ordering::Relaxed);
    load.into_iter().for_each(|t| t.join().unwrap());
    assert_eq!(report["state_digest"], expected.as_str());
}

/// Controller A (`wave`) runs the plant from its start; controller B (`reflex`) asks, before the
/// run started, to take it over at 1.5 s. The plant hands the run over at that step: A answered
/// every step before it and ends cleanly, B every step from it; the states and the recording
/// say who controlled which; the result is A's run to that step, a checkpoint, and B from there.
#[test]
fn a_run_handed_over_at_a_step_equals_a_checkpoint_there_resumed_with_the_second_controller() {
    let n = step_at(1.5);
    let expected = handed_over("wave", n, "reflex");
    assert_ne!(expected, in_process("wave"));
    assert_ne!(expected, in_process("reflex"));
    let run = Run::new("handover");
    let rrd = run.path("handover.rrd");
    let plant = run.plant(&strs(&with(FLAGS, &["--json"])));
    let bridge = run.bridge(&rrd, &["--every", "64"]);
    bridge.wait_for_stderr("plant found", Duration::from_secs(30));
    let b = run.controller(&strs(&with(
        &["--policy", "reflex", "--take-over-at", "1.5", "--json"],
        FLAGS,
    )));
    b.wait_for_stderr(
        "asked to take the run over at step",
        Duration::from_secs(60),
    );
    let a = run.controller(&strs(&with(&["--policy", "wave", "--json"], FLAGS)));
    let p = plant.wait(Duration::from_secs(600));
    let a = a.wait(Duration::from_secs(120));
    let b = b.wait(Duration::from_secs(120));
    let r = bridge.wait(Duration::from_secs(120));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(a.status.success(), "A: {}", a.stderr);
    assert!(b.status.success(), "B: {}", b.stderr);
    assert!(r.status.success(), "recorder: {}", r.stderr);
    assert_eq!(json(&p.stdout)["state_digest"], expected.as_str());
    assert!(
        p.stderr.contains("takes the run over from") && p.stderr.contains(&format!("at step {n}")),
        "{}",
        p.stderr
    );
    let sa = json(&a.stdout);
    assert_eq!(sa["steps"].as_u64(), Some(n), "A answered steps 0 to n - 1");
    assert_eq!(sa["handed_over"]["step"].as_u64(), Some(n));
    let sb = json(&b.stdout);
    assert_eq!(sb["first_step"].as_u64(), Some(n));
    assert_eq!(sb["plant"]["state_digest"], expected.as_str());
    let last = scenario().plant.discretisation().unwrap().steps_until(6.0);
    assert_eq!(sb["steps"].as_u64(), Some(last - n), "B answered the rest");
    // the recording says who controlled which steps
    let to = sa["handed_over"]["to"].as_str().unwrap().to_string();
    let rec = read_recording(&rrd).unwrap();
    let log = rec.entity("log/recorder");
    assert!(
        log.texts
            .iter()
            .any(|t| t.contains(&format!("controller {to} controls the run from step {n}"))),
        "{:?}",
        log.texts
    );
}

/// With `--on-controller-lost wait`, the plant keeps its clock at the step where its controller
/// died (`kill -9`) until another takes the run over; the result is the first controller's run
/// to that step (the plant says which) and the second's from it.
#[test]
fn a_controller_that_dies_is_replaced_at_its_step_when_the_plant_waits() {
    let run = Run::new("replace");
    let plant = run.plant(&strs(&with(
        FLAGS,
        &["--json", "--on-controller-lost", "wait:120"],
    )));
    let a = run.controller(&strs(&with(
        &["--policy", "wave", "--stall", "1000:600000"],
        FLAGS,
    )));
    // A holds its answer to step 1000 (for ten minutes): the run is at step 1000 when it dies
    a.wait_for_stderr("holding the answer to step 1000", Duration::from_secs(120));
    a.signal("-9");
    let _ = a.wait(Duration::from_secs(30));
    plant.wait_for_stderr(
        "waiting up to 120 s for a controller",
        Duration::from_secs(60),
    );
    let b = run.controller(&strs(&with(&["--policy", "reflex", "--take-over"], FLAGS)));
    let p = plant.wait(Duration::from_secs(600));
    let b = b.wait(Duration::from_secs(120));
    assert!(p.status.success(), "plant: {}", p.stderr);
    assert!(b.status.success(), "B: {}", b.stderr);
    assert!(
        p.stderr.contains("took over the run at step 1000"),
        "{}",
        p.stderr
    );
    assert_eq!(
        json(&p.stdout)["state_digest"],
        handed_over("wave", 1000, "reflex").as_str()
    );
}

/// `crawler run --then POLICY@SECONDS` scripts the hand-over: two controllers on one timeline,
/// one command, the result of the first policy to that step and the second from it.
#[test]
fn crawler_run_then_hands_the_run_to_a_second_policy_at_a_time() {
    let run = Run::new("then");
    let rrd = run.path("then.rrd");
    let args = with(
        &[
            "run",
            "--policy",
            "wave",
            "--then",
            "reflex@1.5",
            "--every",
            "64",
        ],
        &with(
            FLAGS,
            &["--out", &rrd.display().to_string(), "--run-id", &run.id],
        )
        .iter()
        .map(String::as_str)
        .collect::<Vec<_>>(),
    );
    let p = Proc::spawn("crawler", &bin("crawler"), &args, run.dir.path());
    let out = p.wait(Duration::from_secs(600));
    assert!(out.status.success(), "{}\n{}", out.stdout, out.stderr);
    let n = step_at(1.5);
    assert!(
        out.stdout.contains("handed the run over to controller")
            && out.stdout.contains(&format!("at step {n}")),
        "{}",
        out.stdout
    );
    let expected = handed_over("wave", n, "reflex");
    assert!(
        out.stdout.contains(&expected),
        "the plant's digest is not {expected}: {}",
        out.stdout
    );
    let rec = read_recording(&rrd).unwrap();
    assert!(rec
        .entity("log/recorder")
        .texts
        .iter()
        .any(|t| t.contains(&format!("controls the run from step {n}"))));
}
