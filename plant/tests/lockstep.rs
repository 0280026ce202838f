//! The lockstep state machine in process: the runner's inbox and outbox are channels and the
//! controller is a thread, so every path (finish, hostile answers, a controller that leaves,
//! timeouts, an interrupt, resume) is checked without zenoh or processes, against `simulate`.

use std::collections::HashMap;
use std::path::Path;
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::{unbounded, Receiver, Sender};

use crawler_cli::Exit;
use crawler_physics::scenario::{Overrides, Scenario};
use crawler_physics::simulate::{simulate, SimulateOptions};
use crawler_plant::checkpoint::Checkpoint;
use crawler_plant::link::{Control, Feeders, Inbox, Outbox, Topic, INBOX_BYTES};
use crawler_plant::runner::{OnLost, Outcome, RunOptions, Runner};
use crawler_protocol::{
    decode, encode, Actuation, Applied, Header, Join, ProcessId, ProcessState, Rejections, Role,
    RunNonce, State, Status, WaveMsg, PROTOCOL_VERSION,
};
use crawler_transport::participant::Admitted;
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
        on_controller_lost: OnLost::Stop,
    }
}

fn plant_id() -> ProcessId {
    ProcessId::parse("000000000000000a").unwrap()
}

/// The test controllers' ids: `C1`, `C2`, `C3`.
const C1: &str = "00000000000000c1";
const C2: &str = "00000000000000c2";
const C3: &str = "00000000000000c3";

fn pid(id: &str) -> ProcessId {
    ProcessId::parse(id).unwrap()
}

/// A message from controller `id` as the arrival gate hands it over (the gate itself is tested
/// in crawler-transport).
fn from(id: &str, bytes: Vec<u8>) -> Admitted {
    Admitted {
        header: Header {
            run: RunNonce([7; 16]),
            role: Role::Controller,
            sender: pid(id),
            seq: 1,
        },
        bytes,
    }
}

/// Controller `id`'s join request (`take_over` as in the message).
fn join(id: &str, take_over: Option<u64>) -> Admitted {
    from(
        id,
        encode(&Join {
            v: PROTOCOL_VERSION,
            controller: id.into(),
            policy: "test".into(),
            take_over,
        }),
    )
}

/// The outbox of the tests: every message, in order, on a channel.
struct Wire(Sender<(Topic, Vec<u8>)>);

impl Outbox for Wire {
    fn put(&self, topic: Topic, bytes: Vec<u8>) {
        let _ = self.0.send((topic, bytes));
    }
}

/// What a test controller does on the first `State(n)` addressed to it (a resent state is
/// ignored).
enum Act {
    /// Send these messages (from this controller), in order.
    Send(Vec<Vec<u8>>),
    /// Send these messages, each from the given sender.
    SendFrom(Vec<(&'static str, Vec<u8>)>),
    /// Send this control event instead of an answer, and stop answering.
    Then(Control),
    /// Send this control event instead of an answer, and these join requests once the plant
    /// says it waits (as a controller asks again until it is admitted); stop answering.
    ThenJoin(Control, Vec<Admitted>),
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

type Policy = Box<dyn FnMut(&State) -> Act + Send>;

/// What the test controllers saw: the plant's statuses, and the steps of the states addressed
/// to each controller (resent ones included).
struct Seen {
    statuses: Vec<Status>,
    steps: HashMap<String, Vec<u64>>,
}

struct Harness {
    inbox: Inbox,
    wire: Wire,
    controllers: JoinHandle<Seen>,
}

impl Harness {
    /// A runner's inbox and outbox with a controller `id` that joins at once (when `join`) and
    /// acts on each state by `act`.
    fn new(
        id: &'static str,
        join_now: bool,
        act: impl FnMut(&State) -> Act + Send + 'static,
    ) -> Self {
        let joins = if join_now {
            vec![join(id, None)]
        } else {
            vec![]
        };
        Self::with(vec![(id, Box::new(act) as Policy)], joins)
    }

    /// A runner's inbox and outbox with controllers `policies` (each acting on the states
    /// addressed to it) and the join requests `joins`, sent at once.
    fn with(policies: Vec<(&'static str, Policy)>, joins: Vec<Admitted>) -> Self {
        let (control_tx, control) = unbounded::<Control>();
        let (feeders, inbox) = Inbox::channel(control, INBOX_BYTES);
        let (out_tx, out_rx) = unbounded::<(Topic, Vec<u8>)>();
        for j in joins {
            assert!(feeders.join(j));
        }
        let controllers =
            std::thread::spawn(move || controllers(out_rx, &feeders, &control_tx, policies));
        Self {
            inbox,
            wire: Wire(out_tx),
            controllers,
        }
    }

    /// Runs `runner` to its outcome; returns it with what the controllers saw.
    fn run(self, mut runner: Runner) -> (Outcome, Seen) {
        let outcome = runner.lockstep(&self.inbox, &self.wire).unwrap();
        drop(self.wire);
        (outcome, self.controllers.join().unwrap())
    }
}

fn controllers(
    out: Receiver<(Topic, Vec<u8>)>,
    feeders: &Feeders,
    control: &Sender<Control>,
    policies: Vec<(&'static str, Policy)>,
) -> Seen {
    let mut policies: HashMap<String, (Policy, Option<u64>, bool)> = policies
        .into_iter()
        .map(|(id, p)| (id.to_string(), (p, None, true)))
        .collect();
    let mut seen = Seen {
        statuses: Vec::new(),
        steps: HashMap::new(),
    };
    let mut published = Vec::new();
    let mut joins_when_waiting = Vec::new();
    for (topic, bytes) in out {
        match topic {
            Topic::Status => {
                let st = decode::<Status>(&bytes).unwrap();
                if st.state == ProcessState::Waiting {
                    for j in joins_when_waiting.drain(..) {
                        assert!(feeders.join(j));
                    }
                }
                seen.statuses.push(st);
            }
            Topic::State => {
                let s: State = decode(&bytes).unwrap();
                published.push(s.step);
                seen.steps
                    .entry(s.controller.clone())
                    .or_default()
                    .push(s.step);
                let Some((act, answered, answering)) = policies.get_mut(&s.controller) else {
                    continue;
                };
                if s.last || !*answering || answered.is_some_and(|a| s.step <= a) {
                    continue;
                }
                if let Some(a) = *answered {
                    assert_eq!(s.step, a + 1, "the plant skipped a step");
                }
                *answered = Some(s.step);
                match act(&s) {
                    Act::Send(msgs) => msgs
                        .into_iter()
                        .for_each(|m| assert!(feeders.offer(from(&s.controller, m)))),
                    Act::SendFrom(msgs) => msgs
                        .into_iter()
                        .for_each(|(id, m)| assert!(feeders.offer(from(id, m)))),
                    Act::Then(c) => {
                        control.send(c).unwrap();
                        *answering = false;
                    }
                    Act::ThenJoin(c, joins) => {
                        control.send(c).unwrap();
                        joins_when_waiting.extend(joins);
                        *answering = false;
                    }
                    Act::Silence => *answering = false,
                }
            }
            Topic::Events | Topic::Metrics => {}
        }
    }
    // Every state was published in order (a resent or readdressed state repeats the one before).
    assert!(published
        .windows(2)
        .all(|w| w[1] == w[0] || w[1] == w[0] + 1));
    seen
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
    let runner = Runner::new(opts, plant_id()).unwrap();
    let last_step = last_step();
    assert_eq!(runner.model_info().last_step, last_step);
    let h = Harness::new(C1, true, move |s| Act::Send(vec![answer(C1, s.step, wave)]));
    let (outcome, seen) = h.run(runner);
    let statuses = seen.statuses;
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
    let runner = Runner::new(opts, plant_id()).unwrap();
    const HOSTILE_STEPS: u64 = 20;
    let h = Harness::new(C1, true, move |s| {
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
                controller: C1.into(),
                wave: Some(wave),
                field: None,
            })); // version
            msgs.push(answer(C1, n, bad_wave)); // invalid: does not fit the body
            msgs.push(encode(&Actuation {
                v: PROTOCOL_VERSION,
                step: n,
                controller: C1.into(),
                wave: None,
                field: Some(vec![0.0; cells - 1]),
            })); // invalid: wrong size
            msgs.push(answer("intruder", n, wave)); // foreign
            msgs.push(answer(C1, n + 1, wave)); // future
            if n >= 2 {
                msgs.push(answer(C1, n - 2, wave)); // stale
            }
        }
        msgs.push(answer(C1, n, wave));
        if n < HOSTILE_STEPS {
            msgs.push(answer(C1, n, wave)); // a duplicate, seen at step n + 1
        }
        Act::Send(msgs)
    });
    let (outcome, seen) = h.run(runner);
    let statuses = seen.statuses;
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
            other_run: 0,
            replayed: 0,
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
    let runner = Runner::new(opts.clone(), plant_id()).unwrap();
    let h = Harness::new(C1, true, move |s| {
        if s.step == 2500 {
            Act::Then(Control::ControllerDown(pid(C1)))
        } else {
            Act::Send(vec![answer(C1, s.step, wave)])
        }
    });
    let (outcome, seen) = h.run(runner);
    let statuses = seen.statuses;
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
        reason.contains(&format!("controller {} left the run at step 2500", pid(C1))),
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
    let runner = Runner::new(resumed, plant_id()).unwrap();
    let h = Harness::new(C2, true, move |s| {
        assert!(s.step >= 2500, "a resumed run continues at its checkpoint");
        Act::Send(vec![answer(C2, s.step, wave)])
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
    let runner = Runner::new(opts, plant_id()).unwrap();
    let h = Harness::new(C1, false, |_| Act::Silence);
    let (outcome, seen) = h.run(runner);
    let statuses = seen.statuses;
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
    let runner = Runner::new(opts, plant_id()).unwrap();
    let h = Harness::new(C1, true, move |s| {
        if s.step < 10 {
            Act::Send(vec![answer(C1, s.step, wave)])
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
    let runner = Runner::new(opts, plant_id()).unwrap();
    let h = Harness::new(C1, true, move |s| {
        if s.step == 100 {
            Act::Then(Control::Interrupt)
        } else {
            Act::Send(vec![answer(C1, s.step, wave)])
        }
    });
    let (outcome, seen) = h.run(runner);
    let statuses = seen.statuses;
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
    let runner = Runner::new(opts.clone(), plant_id()).unwrap();
    let h = Harness::new(C1, true, controller(C1, 0, 300, checked.clone()));
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
    let runner = Runner::new(resumed, plant_id()).unwrap();
    let h = Harness::new(C2, true, controller(C2, 300, 400, checked.clone()));
    let _ = h.run(runner);
    assert_eq!(checked.load(Ordering::Relaxed), 401);
}

/// A wave of another amplitude: what the second controller of a hand-over applies.
fn other_wave(s: &Scenario) -> WaveMsg {
    WaveMsg {
        f0: 0.3,
        ..wave_msg(s)
    }
}

/// A run handed from controller A (the scenario's wave) to controller B (another wave) at step
/// 2500, by B's take-over request sent before the run started, is bit-identical to A's run
/// stopped at step 2500 with a checkpoint and resumed with B; every state before 2500 went to A,
/// every one from 2500 on to B.
#[test]
fn a_take_over_at_a_step_equals_a_checkpoint_there_resumed_with_the_new_controller() {
    const N: u64 = 2500;
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path());
    let (wa, wb) = (wave_msg(&opts.scenario), other_wave(&opts.scenario));
    let a: Policy = Box::new(move |s: &State| Act::Send(vec![answer(C1, s.step, wa)]));
    let b: Policy = Box::new(move |s: &State| Act::Send(vec![answer(C2, s.step, wb)]));
    // B asks first: it must still wait for its step, A takes the run from its start
    let h = Harness::with(
        vec![(C1, a), (C2, b)],
        vec![join(C2, Some(N)), join(C1, None)],
    );
    let (outcome, seen) = h.run(Runner::new(opts.clone(), plant_id()).unwrap());
    let handed = finished(outcome);
    let steps_a = &seen.steps[C1];
    let steps_b = &seen.steps[C2];
    assert_eq!(steps_a.first(), Some(&0));
    assert_eq!(steps_a.last(), Some(&(N - 1)));
    assert_eq!(steps_b.first(), Some(&N));
    assert_eq!(steps_b.last(), Some(&last_step()));
    assert!(
        seen.statuses
            .iter()
            .any(|st| st.step == N && st.message.contains("takes the run over")),
        "the plant said nothing of the hand-over"
    );

    // A to step N, a checkpoint, and B from there
    let dir2 = tempfile::tempdir().unwrap();
    let opts2 = options(dir2.path());
    let h = Harness::new(C1, true, move |s| {
        if s.step == N {
            Act::Then(Control::Interrupt)
        } else {
            Act::Send(vec![answer(C1, s.step, wa)])
        }
    });
    let (outcome, _) = h.run(Runner::new(opts2.clone(), plant_id()).unwrap());
    let Outcome::Stopped {
        checkpoint: Some(path),
        ..
    } = outcome
    else {
        panic!("{outcome:?}")
    };
    let resumed = RunOptions {
        resume: Some(Checkpoint::load(&path).unwrap()),
        ..opts2
    };
    let h = Harness::new(C2, true, move |s| Act::Send(vec![answer(C2, s.step, wb)]));
    let (outcome, _) = h.run(Runner::new(resumed, plant_id()).unwrap());
    assert_eq!(handed, finished(outcome));
    // and the hand-over changed the run: B's wave is not A's
    assert_ne!(handed, result_of_simulate(&scenario()));
}

/// With `--on-controller-lost wait`, a run whose controller leaves keeps its clock at that step
/// until another controller joins; the new one gets that step's state and the run goes on as if
/// nothing happened (both answer the scenario's wave: the result is `simulate`'s). Without a new
/// controller it stops, with the checkpoint of that step, once the wait is over.
#[test]
fn a_run_whose_controller_leaves_waits_for_another_when_asked_to() {
    const N: u64 = 2500;
    let dir = tempfile::tempdir().unwrap();
    let opts = RunOptions {
        on_controller_lost: OnLost::Wait(Duration::from_secs(60)),
        ..options(dir.path())
    };
    let wave = wave_msg(&opts.scenario);
    let a: Policy = Box::new(move |s: &State| {
        if s.step == N {
            Act::ThenJoin(Control::ControllerDown(pid(C1)), vec![join(C2, None)])
        } else {
            Act::Send(vec![answer(C1, s.step, wave)])
        }
    });
    let b: Policy = Box::new(move |s: &State| Act::Send(vec![answer(C2, s.step, wave)]));
    let h = Harness::with(vec![(C1, a), (C2, b)], vec![join(C1, None)]);
    let (outcome, seen) = h.run(Runner::new(opts.clone(), plant_id()).unwrap());
    assert_eq!(finished(outcome), result_of_simulate(&scenario()));
    assert_eq!(seen.steps[C2].first(), Some(&N));
    assert!(seen
        .statuses
        .iter()
        .any(|st| st.state == ProcessState::Waiting && st.step == N));

    let opts = RunOptions {
        on_controller_lost: OnLost::Wait(Duration::from_millis(300)),
        ..opts
    };
    let h = Harness::new(C1, true, move |s| {
        if s.step == N {
            Act::Then(Control::ControllerDown(pid(C1)))
        } else {
            Act::Send(vec![answer(C1, s.step, wave)])
        }
    });
    let (outcome, _) = h.run(Runner::new(opts, plant_id()).unwrap());
    let Outcome::Stopped {
        reason,
        checkpoint: Some(path),
        exit,
    } = outcome
    else {
        panic!("{outcome:?}")
    };
    assert_eq!(exit, Exit::PeerLost);
    assert!(reason.contains("no controller took it over"), "{reason}");
    assert_eq!(Checkpoint::load(&path).unwrap().state.macro_step, N);
}

/// A plain join request while the run has a controller changes nothing (the run keeps its
/// controller and its result); the requester never gets a state; an answer sent by it in the
/// controller's name is refused as foreign.
#[test]
fn a_plain_join_does_not_take_a_run_that_has_a_controller() {
    let dir = tempfile::tempdir().unwrap();
    let opts = options(dir.path());
    let wave = wave_msg(&opts.scenario);
    let a: Policy = Box::new(move |s: &State| {
        let mut msgs = vec![(C1, answer(C1, s.step, wave))];
        if s.step == 100 {
            // C3 sends C1's answer to the next step before C1 can
            msgs.insert(0, (C3, answer(C1, s.step, other_wave(&scenario()))));
        }
        Act::SendFrom(msgs)
    });
    let h = Harness::with(
        vec![(C1, a)],
        vec![join(C1, None), join(C2, None), join(C3, None)],
    );
    let (outcome, seen) = h.run(Runner::new(opts, plant_id()).unwrap());
    assert_eq!(finished(outcome), result_of_simulate(&scenario()));
    assert_eq!(seen.steps.len(), 1, "{:?}", seen.steps.keys());
    assert_eq!(seen.statuses.last().unwrap().rejected.foreign, 1);
}
