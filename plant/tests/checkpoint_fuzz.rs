//! Property-based fuzzing of co-simulation checkpoints: mutated or truncated files are refused
//! or read, never a panic. The checksum stops almost every mutation of the file as it is, so the
//! payload is also mutated behind a recomputed, valid checksum: what then decodes must be a
//! checkpoint a plant can continue from, and must round-trip unchanged.

use proptest::prelude::*;

use crawler_physics::plant::Plant;
use crawler_physics::report::EpisodeLog;
use crawler_physics::scenario::Scenario;
use crawler_plant::checkpoint::Checkpoint;

/// The framing header: magic (8 bytes), version (4), CRC-32 of the payload (4).
const HEADER: usize = 16;

fn sample() -> Checkpoint {
    let s = Scenario::paper();
    let mut plant = Plant::new(s.plant.clone(), 0.0).unwrap();
    plant.set_wave(s.wave).unwrap();
    for _ in 0..20 {
        plant.advance().unwrap();
    }
    Checkpoint {
        run_id: "fuzz".into(),
        scenario: s.clone(),
        last_step: 100,
        state: plant.state(),
        log: EpisodeLog::new(10),
        rejections: Default::default(),
        reason: "test".into(),
        task: crawler_physics::task::TaskTracker::new(s.task, 0.0, 0.0),
    }
}

/// `payload` behind the header of `framed`, with its correct checksum.
fn reframe(framed: &[u8], payload: &[u8]) -> Vec<u8> {
    let mut out = framed[..HEADER - 4].to_vec();
    out.extend_from_slice(&crc32fast::hash(payload).to_le_bytes());
    out.extend_from_slice(payload);
    out
}

/// Whatever a checkpoint file decodes to is usable: a plant restores from its state and takes a
/// step without panicking, and it encodes and decodes to an equal checkpoint.
fn check(bytes: &[u8]) -> bool {
    let Ok(c) = Checkpoint::from_bytes(bytes) else {
        return false;
    };
    let mut plant = Plant::from_state(&c.state).expect("from_bytes restored this state once");
    let _ = plant.advance();
    assert_eq!(Checkpoint::from_bytes(&c.to_bytes()).unwrap(), c);
    true
}

#[test]
fn a_checkpoint_round_trips() {
    let ckpt = sample();
    assert_eq!(Checkpoint::from_bytes(&ckpt.to_bytes()).unwrap(), ckpt);
    // and the re-framing used below reproduces the file exactly
    let bytes = ckpt.to_bytes();
    assert_eq!(reframe(&bytes, &bytes[HEADER..]), bytes);
    assert!(check(&bytes));
}

#[test]
fn a_changed_number_behind_a_valid_checksum_is_read_as_that_number() {
    // Past the checksum the decoder's own checks are all that stand: change the run's last step
    // inside the payload and the checkpoint says so, with nothing else changed.
    let ckpt = sample();
    let bytes = ckpt.to_bytes();
    let payload = &bytes[HEADER..];
    let key = b"\xa9last_step";
    let at = payload
        .windows(key.len())
        .position(|w| w == key)
        .expect("the payload names its fields")
        + key.len();
    assert_eq!(payload[at], 100, "last_step = 100 is a positive fixint");
    let mut changed = payload.to_vec();
    changed[at] = 120;
    let read = Checkpoint::from_bytes(&reframe(&bytes, &changed)).unwrap();
    assert_eq!(read.last_step, 120);
    assert_eq!(
        Checkpoint {
            last_step: 100,
            ..read
        },
        ckpt
    );
    // a step past the last one is refused with the reason
    changed[at] = 0;
    let e = Checkpoint::from_bytes(&reframe(&bytes, &changed)).unwrap_err();
    assert!(e.to_string().contains("past the last step"), "{e:#}");
}

#[test]
fn a_well_formed_checkpoint_of_an_impossible_run_is_refused_naming_the_field() {
    let refused = |c: &Checkpoint| {
        Checkpoint::from_bytes(&c.to_bytes())
            .unwrap_err()
            .to_string()
    };
    let mut c = sample();
    c.scenario.t_end = f64::NAN;
    assert!(refused(&c).contains("numerics.t_end"), "{}", refused(&c));
    let mut c = sample();
    c.scenario.wave.omega = -1.0;
    assert!(refused(&c).contains("wave.omega"), "{}", refused(&c));
    let mut c = sample();
    c.scenario.min_stick_periods = f64::NAN;
    assert!(
        refused(&c).contains("events.min_stick_periods"),
        "{}",
        refused(&c)
    );
    let mut c = sample();
    c.scenario.name = "\u{1b}[31m".into();
    assert!(
        refused(&c).contains("control characters"),
        "{}",
        refused(&c)
    );
    let mut c = sample();
    c.scenario.name = "x".repeat(100_000);
    assert!(refused(&c).contains("invalid name"), "{}", refused(&c));
    // finite numbers whose tension or energy is not
    let mut c = sample();
    c.state.u[0] = 1e308;
    let e = refused(&c);
    assert!(
        e.contains("state.u[") && e.contains("finite tension"),
        "{e}"
    );
    let mut c = sample();
    c.state.v.iter_mut().for_each(|v| *v = 1e200);
    assert!(refused(&c).contains("state.v"), "{}", refused(&c));
    // bytes after the payload
    let bytes = sample().to_bytes();
    let mut payload = bytes[HEADER..].to_vec();
    payload.push(0xc0);
    let e = Checkpoint::from_bytes(&reframe(&bytes, &payload))
        .unwrap_err()
        .to_string();
    assert!(e.contains("1 bytes after its end"), "{e}");
}

#[test]
fn metric_windows_that_disagree_with_the_clock_are_refused() {
    // a plant with no transient, past a few closed blocks: every window holds steps
    let s = Scenario::paper();
    let mut params = s.plant.clone();
    params.numerics.settle = 0.0;
    let mut plant = Plant::new(params, 0.0).unwrap();
    plant.set_wave(s.wave).unwrap();
    for _ in 0..300 {
        plant.advance().unwrap();
    }
    let state = plant.state();
    let m = &state.metrics;
    assert!(m.steady.steps > 0 && m.run.steps > 0 && m.block.steps > 0);
    Plant::from_state(&state).unwrap();
    let refused = |change: &dyn Fn(&mut crawler_physics::plant::PlantState), field: &str| {
        let mut bad = state.clone();
        change(&mut bad);
        let e = Plant::from_state(&bad).unwrap_err();
        assert_eq!(e.field, field, "{e}");
    };
    // windows emptied of steps but not of their sums (the report divided by the wrong count)
    refused(
        &|b| b.metrics.steady.steps = 0,
        "state.metrics.steady.steps",
    );
    refused(&|b| b.metrics.run.steps = 0, "state.metrics.run.steps");
    // a step more or less than the window's time span
    refused(
        &|b| b.metrics.steady.steps += 1,
        "state.metrics.steady.steps",
    );
    refused(&|b| b.metrics.block.steps -= 1, "state.metrics.block.steps");
    // the closed and open blocks hold every step taken
    refused(
        &|b| {
            b.metrics.all.steps -= 1;
            b.metrics.all.start += plant.discretisation().dt;
        },
        "state.metrics.all.steps",
    );
}

#[test]
fn a_file_of_unbounded_length_is_refused_not_read_to_the_end() {
    let e = Checkpoint::load(std::path::Path::new("/dev/zero"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("larger than"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 600, ..ProptestConfig::default() })]

    #[test]
    fn mutated_checkpoints_never_panic(at in any::<prop::sample::Index>(), byte in any::<u8>(), cut in any::<prop::sample::Index>()) {
        let mut c = sample().to_bytes();
        let i = at.index(c.len());
        c[i] ^= byte | 1;
        check(&c);
        check(&c[..cut.index(c.len())]);
    }

    #[test]
    fn mutated_payloads_behind_a_valid_checksum_are_refused_or_usable(at in any::<prop::sample::Index>(), byte in any::<u8>(), cut in any::<prop::sample::Index>()) {
        let framed = sample().to_bytes();
        let mut payload = framed[HEADER..].to_vec();
        let i = at.index(payload.len());
        payload[i] ^= byte | 1;
        check(&reframe(&framed, &payload));
        check(&reframe(&framed, &payload[..cut.index(payload.len())]));
    }
}
