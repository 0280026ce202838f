//! The lockstep state machine in process: the runner's inbox and outbox are channels and the
//! controller is a thread, so every path (finish, hostile answers, a controller that leaves,
//! timeouts, an interrupt, resume) is checked without zenoh or processes, against `simulate`.

use std::path::Path;
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::{unbounded, Receiver, Sender};

use crawler_cli::Exit;
use crawler_physics::scenario::{Overrides, Scenario};
use crawler_physics::simulate::{simulate, SimulateOptions};
use crawler_plant::checkpoint::Checkpoint;
use crawler_plant::link::{Control, Feeder, Inbox, Outbox, Topic, INBOX_BYTES};
use crawler_plant::runner::{Outcome, RunOptions, Runner};
use crawler_protocol::{
    decode, encode, Actuation, Applied, ProcessState, Rejections, State, Status, WaveMsg,
    PROTOCOL_VERSION,
};
use crawler_transport::Network;

/// The paper's body in real stick-slip (eps = 1, f0 = 0.2 N, alpha = 0.5), cut to 6 s (a
/// steady window of 1 s): thousands of stick-slip episodes, whose count a resumed run must
/// reproduce as well as the trajectory.
fn scenario() -> Scenario {
    Scenario::load(
        None,
        &Overrides {
            eps: Some(1.0),
            f0: Some(0.2),
            alpha: Some(0.5),
            t_end: Some(6.0),
            ..Overrides::default()
        },
    )
    .unwrap()
}

/// The communication steps of `scenario()`: 6 s in whole steps.
fn last_step() -> u64 {
    let s = scenario();
    s.plant.discretisation().unwrap().steps_until(s.t_end)
}

fn options(dir: &Path) -> RunOptions {
    RunOptions {
        scenario: scenario(),
        network: Network::loopback("lockstep", "tcp/127.0.0.1:1").unwrap(),
        wait_timeout: Duration::from_secs(30),
        step_timeout: Duration::from_secs(30),
        checkpoint: dir.join("run.ckpt"),
        resume: None,
        max_episodes: 100,
    }
}

/// The outbox of the tests: every message, in order, on a channel.
struct Wire(Sender<(Topic, Vec<u8>)>);

impl Outbox for Wire {
    fn put(&self, topic: Topic, bytes: Vec<u8>) {
        let _ = self.0.send((topic, bytes));
    }
}

/// What the test controller does on the first `State(n)` it sees (a resent state is ignored).
enum Act {
    /// Send these messages, in order.
    Send(Vec<Vec<u8>>),
    /// Send this control event instead of an answer, and stop answering.
    Then(Control),
    /// Stop answering.
    Silence,
}

/// The answer of controller `id` to step `n`: the scenario's wave.
fn answer(id: &str, n: u64, wave: WaveMsg) -> Vec<u8> {
    encode(&Actuation {
        v: PROTOCOL_VERSION,
        step: n,
        controller: id.into(),
        wave: Some(wave),
        field: None,
    })
}

fn wave_msg(s: &Scenario) -> WaveMsg {
    WaveMsg {
        f0: s.wave.f0,
        k: s.wave.k,
        omega: s.wave.omega,
        phase: s.wave.phase,
    }
}

struct Harness {
    inbox: Inbox,
    wire: Wire,
    controller: JoinHandle<Vec<Status>>,
}

impl Harness {
    /// A runner's inbox and outbox with a controller `id` that joins at once (when `join`) and
    /// acts on each state by `act`. The controller thread returns the plant's status messages.
    fn new(
        id: &'static str,
        join: bool,
        mut act: impl FnMut(&State) -> Act + Send + 'static,
    ) -> Self {
        let (control_tx, control) = unbounded::<Control>();
        let (data_tx, inbox) = Inbox::channel(control, INBOX_BYTES);
        let (out_tx, out_rx) = unbounded::<(Topic, Vec<u8>)>();
        if join {
            control_tx.send(Control::ControllerUp(id.into())).unwrap();
        }
        let controller =
            std::thread::spawn(move || controller(out_rx, &data_tx, &control_tx, &mut act));
        Self {
            inbox,
            wire: Wire(out_tx),
            controller,
        }
    }

    /// Runs `runner` to its outcome; returns it with the statuses the plant published.
    fn run(self, mut runner: Runner) -> (Outcome, Vec<Status>) {
        let outcome = runner.lockstep(&self.inbox, &self.wire).unwrap();
        drop(self.wire);
        (outcome, self.controller.join().unwrap())
    }
}

fn controller(
    out: Receiver<(Topic, Vec<u8>)>,
    data: &Feeder,
    control: &Sender<Control>,
    act: &mut dyn FnMut(&State) -> Act,
) -> Vec<Status> {
    let mut statuses = Vec::new();
    let mut answered: Option<u64> = None;
    let mut answering = true;
    let mut published = Vec::new();
    for (topic, bytes) in out {
        match topic {
            Topic::Status => statuses.push(decode::<Status>(&bytes).unwrap()),
            Topic::State => {
                let s: State = decode(&bytes).unwrap();
                published.push(s.step);
                if s.last || !answering || answered.is_some_and(|a| s.step <= a) {
                    continue;
                }
                if let Some(a) = answered {
                    assert_eq!(s.step, a + 1, "the plant skipped a step");
                }
                answered = Some(s.step);
                match act(&s) {
                    Act::Send(msgs) => msgs.into_iter().for_each(|m| assert!(data.offer(m))),
                    Act::Then(c) => {
                        control.send(c).unwrap();
                        answering = false;
                    }
                    Act::Silence => answering = false,
                }
            }
            Topic::Events | Topic::Metrics => {}
        }
    }
    // Every state was published in order (a resent state repeats the one before).
    assert!(published
        .windows(2)
        .all(|w| w[1] == w[0] || w[1] == w[0] + 1));
    statuses
}

/// What must agree between two runs: the final state's digest, the velocity's bits and the
/// number of stick-slip episodes.
type RunResult = (String, u64, u64);

fn result_of_simulate(s: &Scenario) -> RunResult {
    let r = simulate(s, SimulateOptions::default()).unwrap();
    assert!(
        r.events.count > 1000,
        "stick-slip expected: {}",
        r.events.count
    );
    (r.state_digest, r.velocity.to_bits(), r.events.count)
}

fn finished(outcome: Outcome) -> RunResult {
    match outcome {
        Outcome::Finished(r) => (r.state_digest, r.velocity.to_bits(), r.events.count),
        Outcome::Stopped { reason, .. } => panic!("the run stopped: {reason}"),
    }
}

#[test]
fn lockstep_under_the_scenarios_wave_is_bit_identical_to_simulate() {
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path());
    let wave = wave_msg(&opts.scenario);
    let runner = Runner::new(opts, "plant".into()).unwrap();
    let last_step = last_step();
    assert_eq!(runner.model_info().last_step, last_step);
    let h = Harness::new("c1", true, move |s| {
        Act::Send(vec![answer("c1", s.step, wave)])
    });
    let (outcome, statuses) = h.run(runner);
    let result = finished(outcome);
    assert_eq!(result, result_of_simulate(&scenario()));
    let last = statuses.last().unwrap();
    assert_eq!((last.state, last.step), (ProcessState::Finished, last_step));
    assert_eq!(last.rejected, Rejections::default());
    let report = last
        .report
        .as_ref()
        .expect("the finished status carries the report");
    assert_eq!(report.state_digest, result.0);
    assert_eq!(
        report
            .values
            .get(crawler_facts::Metric::Velocity)
            .unwrap()
            .to_bits(),
        result.1
    );
    assert_eq!(report.events.count, result.2);
    assert_eq!(report.macro_steps, last_step);
    // only the finished status carries it
    assert!(statuses[..statuses.len() - 1]
        .iter()
        .all(|s| s.report.is_none() && s.state != ProcessState::Finished));
    assert!(
        !dir.path().join("run.ckpt").exists(),
        "a finished run writes no checkpoint"
    );
}

#[test]
fn hostile_answers_are_counted_by_cause_and_never_applied() {
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path());
    let wave = wave_msg(&opts.scenario);
    let cells = opts.scenario.plant.numerics.cells;
    let runner = Runner::new(opts, "plant".into()).unwrap();
    const HOSTILE_STEPS: u64 = 20;
    let h = Harness::new("c1", true, move |s| {
        let n = s.step;
        let mut msgs = Vec::new();
        if n < HOSTILE_STEPS {
            let bad_wave = WaveMsg {
                k: wave.k + 1.0,
                ..wave
            };
            msgs.push(vec![0xc1, 0x00, 0xff]); // malformed
            msgs.push(encode(&Actuation {
                v: PROTOCOL_VERSION + 1,
                step: n,
                controller: "c1".into(),
                wave: Some(wave),
                field: None,
            })); // version
            msgs.push(answer("c1", n, bad_wave)); // invalid: does not fit the body
            msgs.push(encode(&Actuation {
                v: PROTOCOL_VERSION,
                step: n,
                controller: "c1".into(),
                wave: None,
                field: Some(vec![0.0; cells - 1]),
            })); // invalid: wrong size
            msgs.push(answer("intruder", n, wave)); // foreign
            msgs.push(answer("c1", n + 1, wave)); // future
            if n >= 2 {
                msgs.push(answer("c1", n - 2, wave)); // stale
            }
        }
        msgs.push(answer("c1", n, wave));
        if n < HOSTILE_STEPS {
            msgs.push(answer("c1", n, wave)); // a duplicate, seen at step n + 1
        }
        Act::Send(msgs)
    });
    let (outcome, statuses) = h.run(runner);
    assert_eq!(finished(outcome), result_of_simulate(&scenario()));
    let last = statuses.last().unwrap();
    assert_eq!(last.state, ProcessState::Finished);
    let k = HOSTILE_STEPS;
    assert_eq!(
        last.rejected,
        Rejections {
            malformed: k,
            version: k,
            invalid: 2 * k,
            foreign: k,
            stale: k - 2,
            duplicate: k,
            future: k,
            overflow: 0,
        }
    );
}

#[test]
fn a_controller_that_leaves_stops_the_run_and_resume_is_bit_identical() {
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path());
    let wave = wave_msg(&opts.scenario);
    let runner = Runner::new(opts.clone(), "plant".into()).unwrap();
    let h = Harness::new("c1", true, move |s| {
        if s.step == 2500 {
            Act::Then(Control::ControllerDown("c1".into()))
        } else {
            Act::Send(vec![answer("c1", s.step, wave)])
        }
    });
    let (outcome, statuses) = h.run(runner);
    let Outcome::Stopped {
        reason,
        checkpoint: Some(path),
        exit,
    } = outcome
    else {
        panic!("the run should stop with a checkpoint: {outcome:?}")
    };
    assert_eq!(exit, Exit::PeerLost);
    assert!(
        reason.contains("controller c1 left the run at step 2500"),
        "{reason}"
    );
    let last = statuses.last().unwrap();
    assert_eq!((last.state, last.step), (ProcessState::Failed, 2500));
    assert_eq!(last.report, None);
    assert!(
        last.message.contains("checkpoint written"),
        "{}",
        last.message
    );

    let ckpt = Checkpoint::load(&path).unwrap();
    assert_eq!((ckpt.state.macro_step, ckpt.last_step), (2500, last_step()));
    assert_eq!(ckpt.run_id, "lockstep");
    let resumed = RunOptions {
        resume: Some(ckpt),
        ..opts
    };
    let runner = Runner::new(resumed, "plant".into()).unwrap();
    let h = Harness::new("c2", true, move |s| {
        assert!(s.step >= 2500, "a resumed run continues at its checkpoint");
        Act::Send(vec![answer("c2", s.step, wave)])
    });
    let (outcome, _) = h.run(runner);
    assert_eq!(finished(outcome), result_of_simulate(&scenario()));
}

#[test]
fn without_a_controller_the_plant_times_out_and_writes_no_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let opts = RunOptions {
        wait_timeout: Duration::from_millis(50),
        ..options(dir.path())
    };
    let runner = Runner::new(opts, "plant".into()).unwrap();
    let h = Harness::new("c1", false, |_| Act::Silence);
    let (outcome, statuses) = h.run(runner);
    match outcome {
        Outcome::Stopped {
            reason,
            checkpoint,
            exit,
        } => {
            assert_eq!(exit, Exit::Timeout);
            assert!(reason.contains("no controller joined"), "{reason}");
            assert_eq!(checkpoint, None);
        }
        o => panic!("{o:?}"),
    }
    assert!(!dir.path().join("run.ckpt").exists());
    let states: Vec<ProcessState> = statuses.iter().map(|s| s.state).collect();
    assert_eq!(states, [ProcessState::Waiting, ProcessState::Failed]);
}

#[test]
fn a_silent_controller_times_out_the_step_with_a_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let opts = RunOptions {
        step_timeout: Duration::from_millis(200),
        ..options(dir.path())
    };
    let wave = wave_msg(&opts.scenario);
    let runner = Runner::new(opts, "plant".into()).unwrap();
    let h = Harness::new("c1", true, move |s| {
        if s.step < 10 {
            Act::Send(vec![answer("c1", s.step, wave)])
        } else {
            Act::Silence
        }
    });
    let (outcome, _) = h.run(runner);
    let Outcome::Stopped {
        reason,
        checkpoint: Some(path),
        exit,
    } = outcome
    else {
        panic!("{outcome:?}")
    };
    assert_eq!(exit, Exit::Timeout);
    assert!(reason.contains("did not answer step 10"), "{reason}");
    assert_eq!(Checkpoint::load(&path).unwrap().state.macro_step, 10);
}

#[test]
fn an_interrupt_stops_the_run_with_a_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path());
    let wave = wave_msg(&opts.scenario);
    let runner = Runner::new(opts, "plant".into()).unwrap();
    let h = Harness::new("c1", true, move |s| {
        if s.step == 100 {
            Act::Then(Control::Interrupt)
        } else {
            Act::Send(vec![answer("c1", s.step, wave)])
        }
    });
    let (outcome, statuses) = h.run(runner);
    let Outcome::Stopped {
        reason,
        checkpoint: Some(path),
        exit,
    } = outcome
    else {
        panic!("{outcome:?}")
    };
    assert_eq!(exit, Exit::Interrupted);
    assert_eq!(reason, "interrupted at step 100");
    assert_eq!(statuses.last().unwrap().state, ProcessState::Stopped);
    let ckpt = Checkpoint::load(&path).unwrap();
    assert_eq!(
        (ckpt.state.macro_step, ckpt.reason.as_str()),
        (100, reason.as_str())
    );
}

/// Every state says what the plant applied over the step before it: nothing at the first, then
/// exactly the wave or the field the controller sent for that step (here a wave whose phase
/// changes every step, alternating with a field that changes every step), also after a resume.
#[test]
fn every_state_carries_the_actuation_applied_over_the_step_before() {
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::sync::Arc;
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path());
    let wave = wave_msg(&opts.scenario);
    let cells = opts.scenario.plant.numerics.cells;
    // what controller `id` sends for step n
    let actuation = move |n: u64| -> Applied {
        if n.is_multiple_of(2) {
            Applied {
                wave: Some(WaveMsg {
                    phase: 1e-3 * n as f64,
                    ..wave
                }),
                field: None,
            }
        } else {
            Applied {
                wave: None,
                field: Some(
                    (0..cells)
                        .map(|i| 0.2 * (0.1 * i as f64 + 0.01 * n as f64).sin())
                        .collect(),
                ),
            }
        }
    };
    let checked = Arc::new(AtomicU64::new(0));
    let controller = |id: &'static str, first: u64, stop: u64, checked: Arc<AtomicU64>| {
        move |s: &State| {
            if s.step == first && first == 0 {
                assert_eq!(s.applied, None, "nothing applied before the first state");
            } else {
                assert_eq!(
                    s.applied.as_ref(),
                    Some(&actuation(s.step - 1)),
                    "state {} does not carry what was sent for step {}",
                    s.step,
                    s.step - 1
                );
                checked.fetch_add(1, Ordering::Relaxed);
            }
            if s.step == stop {
                return Act::Then(Control::Interrupt);
            }
            let a = actuation(s.step);
            Act::Send(vec![encode(&Actuation {
                v: PROTOCOL_VERSION,
                step: s.step,
                controller: id.into(),
                wave: a.wave,
                field: a.field,
            })])
        }
    };
    let runner = Runner::new(opts.clone(), "plant".into()).unwrap();
    let h = Harness::new("c1", true, controller("c1", 0, 300, checked.clone()));
    let (outcome, _) = h.run(runner);
    let Outcome::Stopped {
        checkpoint: Some(path),
        ..
    } = outcome
    else {
        panic!("{outcome:?}")
    };
    assert_eq!(checked.load(Ordering::Relaxed), 300);
    // resumed at step 300: its first state says what was applied over step 299
    let resumed = RunOptions {
        resume: Some(Checkpoint::load(&path).unwrap()),
        ..opts
    };
    let runner = Runner::new(resumed, "plant".into()).unwrap();
    let h = Harness::new("c2", true, controller("c2", 300, 400, checked.clone()));
    let _ = h.run(runner);
    assert_eq!(checked.load(Ordering::Relaxed), 401);
}
