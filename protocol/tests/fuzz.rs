//! Property-based fuzzing of every decoder: arbitrary bytes, truncations and mutations of valid
//! messages never panic, never allocate without bound, and whatever decodes is valid and survives
//! encoding and decoding again unchanged. Valid messages round-trip to equal values and bytes.

use crawler_facts::{Metric, MetricValues};
use proptest::prelude::*;

use crawler_protocol::*;

/// One valid message of every kind (two actuations: a wave and a field).
type Samples = (
    State,
    Actuation,
    Actuation,
    Events,
    Metrics,
    Status,
    Prediction,
    ModelInfo,
);

/// Cells of the sample run.
const N: usize = 16;

fn samples() -> Samples {
    let n = N;
    let state = sample_state(n);
    let wave = WaveMsg {
        f0: 0.5,
        k: 6.25,
        omega: 37.0,
        phase: 0.0,
    };
    let act = Actuation {
        v: PROTOCOL_VERSION,
        step: 7,
        controller: "abc".into(),
        wave: Some(wave),
        field: None,
    };
    let field = Actuation {
        v: PROTOCOL_VERSION,
        step: 7,
        controller: "abc".into(),
        wave: None,
        field: Some(vec![0.0; n]),
    };
    let events = Events {
        v: PROTOCOL_VERSION,
        step: 3,
        time: 1.0,
        episodes: vec![EpisodeMsg {
            node: 1,
            start: 0.5,
            end: 0.6,
            duration: 0.1,
            direction: 1,
        }],
    };
    let metrics = sample_metrics();
    let status = Status {
        v: PROTOCOL_VERSION,
        role: Role::Plant,
        id: "x".into(),
        state: ProcessState::Finished,
        message: "ok".into(),
        step: 1,
        rejected: Rejections::default(),
        report: Some(sample_report(n)),
    };
    let prediction = sample_prediction(wave);
    let model = ModelInfo::example("r", n as u64, 100);
    (
        state, act, field, events, metrics, status, prediction, model,
    )
}

/// A valid state of a run of `n` cells, with an applied field.
fn sample_state(n: usize) -> State {
    State {
        v: PROTOCOL_VERSION,
        step: 7,
        time: 0.007,
        controller: "abc".into(),
        u: vec![0.1; n],
        vel: vec![0.2; n],
        tension: vec![0.3; n],
        stuck: vec![true; n],
        mean_speed: 0.01,
        input_power: 0.5,
        last: false,
        applied: Some(Applied {
            wave: None,
            field: Some(vec![0.4; n]),
        }),
    }
}

/// A valid metrics block with every metric.
fn sample_metrics() -> Metrics {
    Metrics {
        v: PROTOCOL_VERSION,
        step: 9,
        block: 2,
        steady: true,
        start: 1.0,
        end: 1.2,
        values: MetricValues::of(&[
            (Metric::Velocity, 0.05),
            (Metric::Power, 0.1),
            (Metric::Mileage, 0.5),
            (Metric::MaxStress, 1000.0),
            (Metric::MaxStrain, 0.01),
            (Metric::StuckFraction, 0.2),
            (Metric::MeanFrictionSelection, 0.1),
            (Metric::EpisodesPerNodePerPeriod, 1.0),
        ]),
        clock: false,
    }
}

/// A valid final report of a run of `n` cells, with a task result.
fn sample_report(n: usize) -> FinalReport {
    FinalReport {
        scenario: "paper".into(),
        values: MetricValues::of(&[
            (Metric::Velocity, 0.05),
            (Metric::Power, 0.1),
            (Metric::MaxStress, 1000.0),
            (Metric::MaxStrain, 0.01),
            (Metric::StuckFraction, 0.2),
            (Metric::MeanFrictionSelection, 0.1),
        ]),
        dissipation: 0.1,
        identity_velocity: 0.05,
        momentum_residual: Some(1e-15),
        events: EpisodeStats {
            count: 3,
            per_node_per_period: 1.0,
            mean_duration: 0.1,
            min_duration: 0.01,
        },
        window: ReportWindow {
            start: 0.5,
            end: 1.0,
            periods: 3.0,
            steady: true,
            whole_run: false,
        },
        cells: n as u64,
        dt: 1e-4,
        step: 1e-3,
        courant: 1.0,
        dx: 1.0 / n as f64,
        cells_per_wavelength: Some(16.0),
        steps: 1000,
        macro_steps: 100,
        t_end: 1.0,
        state_digest: "0123abcd".into(),
        task: Some(TaskResult {
            outcome: Outcome::EnergyExhausted,
            distance_target: 1.0,
            distance: 0.2,
            time_to_distance: None,
            energy_budget: 20.0,
            energy_used: 20.0,
            energy_at_distance: None,
            energy_exhausted_at: Some(0.9),
            sigma_max: 1e5,
            max_stress: 1000.0,
            time_over_sigma_max: 0.0,
            stress_tolerance: 0.0,
            stress_exceeded_at: None,
            run_time: 1.0,
        }),
    }
}

/// A valid prediction of `wave` by one model.
fn sample_prediction(wave: WaveMsg) -> Prediction {
    Prediction {
        v: PROTOCOL_VERSION,
        controller: "abc".into(),
        policy: "wave".into(),
        step: 0,
        wave,
        models: vec![ModelPrediction {
            model: "paper".into(),
            values: MetricValues::of(&[
                (Metric::Velocity, 0.04),
                (Metric::Power, 0.1),
                (Metric::MaxStress, 1.0),
                (Metric::StuckFraction, 0.0),
            ]),
            validity: "valid".into(),
            tail: Some(Series {
                omega: 37.0,
                drift: 0.04,
                harmonics: vec![(0.01, 0.2)],
            }),
        }],
    }
}

fn join() -> Join {
    Join {
        v: PROTOCOL_VERSION,
        controller: "00000000000000ab".into(),
        policy: "reflex".into(),
        take_over: Some(12),
    }
}

fn valid_messages() -> Vec<(&'static str, Vec<u8>)> {
    let (state, act, field, events, metrics, status, prediction, model) = samples();
    vec![
        ("join", encode(&join())),
        ("state", encode(&state)),
        ("actuation", encode(&act)),
        ("field", encode(&field)),
        ("events", encode(&events)),
        ("metrics", encode(&metrics)),
        ("status", encode(&status)),
        ("prediction", encode(&prediction)),
        ("model", encode(&model)),
    ]
}

/// A message that decoded: it is valid, and encoding and decoding it again gives the same value
/// and the same bytes.
fn check_decoded<M: Message + PartialEq + std::fmt::Debug>(m: &M) {
    m.validate().unwrap();
    let bytes = encode(m);
    let again: M = decode(&bytes).unwrap();
    assert_eq!(&again, m);
    assert_eq!(encode(&again), bytes);
}

/// A valid message encodes, decodes to an equal value, and re-encodes to the same bytes.
fn round_trip<M: Message + PartialEq + std::fmt::Debug>(m: &M) {
    let bytes = encode(m);
    let back: M = decode(&bytes).unwrap();
    assert_eq!(&back, m, "{} changed in a round trip", M::NAME);
    assert_eq!(encode(&back), bytes);
}

/// Runs every decoder on `bytes`; decoded messages must validate and round-trip.
fn decode_all(bytes: &[u8]) {
    if let Ok(m) = decode::<State>(bytes) {
        check_decoded(&m);
    }
    if let Ok(m) = decode::<Actuation>(bytes) {
        check_decoded(&m);
    }
    if let Ok(m) = decode::<Events>(bytes) {
        check_decoded(&m);
    }
    if let Ok(m) = decode::<Metrics>(bytes) {
        check_decoded(&m);
    }
    if let Ok(m) = decode::<Status>(bytes) {
        check_decoded(&m);
    }
    if let Ok(m) = decode::<Prediction>(bytes) {
        check_decoded(&m);
    }
    if let Ok(m) = decode::<ModelInfo>(bytes) {
        check_decoded(&m);
    }
    if let Ok(m) = decode::<Join>(bytes) {
        check_decoded(&m);
    }
}

#[test]
fn valid_messages_round_trip() {
    let (state, act, field, events, metrics, status, prediction, model) = samples();
    round_trip(&state);
    round_trip(&act);
    round_trip(&field);
    round_trip(&events);
    round_trip(&metrics);
    round_trip(&status);
    round_trip(&prediction);
    round_trip(&model);
    round_trip(&join());
    // whatever other kinds the bytes also decode as is valid and round-trips
    for (_, bytes) in valid_messages() {
        decode_all(&bytes);
    }
}

#[test]
fn hostile_headers_are_refused_without_allocating() {
    // an array32 claiming 2^32-1 float64 values, inside an otherwise plausible actuation
    let mut b = vec![0x85];
    b.extend(b"\xa1v\x01\xa4step\x01\xaacontroller\xa1x\xa4wave\xc0\xa5field\xdd\xff\xff\xff\xff");
    assert!(decode::<Actuation>(&b).is_err());
    // a bin32 claiming 4 GiB
    assert!(decode::<State>(b"\xc6\xff\xff\xff\xff").is_err());
    // nesting 100 000 levels deep
    assert!(decode::<Status>(&vec![0x91; 100_000]).is_err());
    // an actuation in array form (values in field order): not a map with named fields
    assert!(decode::<Actuation>(b"\x95\x03\x01\xa1x\xc0\x90").is_err());
    // larger than the limit
    assert!(matches!(
        decode::<State>(&vec![0u8; MAX_MESSAGE_BYTES + 1]),
        Err(ProtocolError::TooLarge { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        decode_all(&bytes);
    }

    #[test]
    fn mutated_messages_never_panic(which in 0usize..9, at in any::<prop::sample::Index>(), byte in any::<u8>(), cut in any::<prop::sample::Index>()) {
        let (_, mut bytes) = valid_messages().swap_remove(which);
        let i = at.index(bytes.len());
        bytes[i] = byte;
        decode_all(&bytes);
        let c = cut.index(bytes.len() + 1);
        decode_all(&bytes[..c]);
    }
}
