//! The writer without zenoh: messages in, the recording's chunks read back from memory.

use crawler_facts::{Metric, MetricValues};
use crawler_protocol::{
    encode, Applied, EpisodeMsg, Events, Metrics, ModelInfo, State, WaveMsg, PROTOCOL_VERSION,
};

use super::*;

/// The chunks of the recording (not the blueprint), in order.
fn chunks(storage: &rerun::sink::MemorySinkStorage) -> Vec<rerun::log::Chunk> {
    storage
        .take()
        .into_iter()
        .filter_map(|m| match m {
            rerun::log::LogMsg::ArrowMsg(store, a) if store.is_recording() => {
                rerun::log::Chunk::from_arrow_msg(&a).ok()
            }
            _ => None,
        })
        .collect()
}

/// Steps of the rows of `path`, chunk by chunk.
fn rows_of(chunks: &[rerun::log::Chunk], path: &str) -> Vec<Vec<i64>> {
    chunks
        .iter()
        .filter(|c| c.entity_path().to_string() == format!("/{path}") && !c.is_static())
        .map(|c| {
            let steps = c.timelines().get(&"step".into()).expect("step timeline");
            assert_eq!(steps.times_raw().len(), c.num_rows());
            steps.times_raw().to_vec()
        })
        .collect()
}

fn state(n: u64, cells: usize, last: bool, f0: f64) -> State {
    let t = n as f64 * 1e-3;
    State {
        v: PROTOCOL_VERSION,
        step: n,
        time: t,
        controller: "c".into(),
        u: (0..cells)
            .map(|i| 1e-3 * (i as f64 - 74.0 * t).sin() + 0.05 * t)
            .collect(),
        vel: vec![0.05; cells],
        tension: (0..cells).map(|i| i as f64).collect(),
        stuck: (0..cells)
            .map(|i| (i + n as usize).is_multiple_of(3))
            .collect(),
        mean_speed: 0.05,
        input_power: 2.0,
        last,
        applied: (n > 0).then_some(Applied {
            wave: Some(WaveMsg {
                f0,
                k: std::f64::consts::TAU,
                omega: 74.0,
                phase: 0.0,
            }),
            field: None,
        }),
    }
}

fn recorder(
    opts: RecorderOptions,
    cells: u64,
    steps: u64,
) -> (Recorder, rerun::sink::MemorySinkStorage) {
    let (sinks, storage) = in_memory("tests").expect("memory recording");
    let mut r = Recorder::new(sinks, opts).expect("recorder");
    r.set_model(&ModelInfo::example("tests", cells, steps), None)
        .expect("model");
    (r, storage)
}

#[test]
fn every_state_is_recorded_with_its_fields_in_one_chunk_per_entity_per_block() {
    let (cells, last) = (64usize, 999u64);
    let opts = RecorderOptions {
        block_states: Some(100),
        ..Default::default()
    };
    let (mut r, storage) = recorder(opts, cells as u64, last);
    for n in 0..=last {
        r.handle(Incoming::State(encode(&state(n, cells, n == last, 0.5))))
            .unwrap();
    }
    r.finish().unwrap();
    let c = r.counts();
    assert_eq!(
        (c.states, c.recorded_steps, c.missing_states),
        (1000, 1000, 0)
    );
    assert_eq!(
        r.closing_note(),
        "1000 states (1000 with fields): every state's fields recorded"
    );
    let chunks = chunks(&storage);
    let all: Vec<i64> = (0..=last as i64).collect();
    for path in [
        "tail/plant",
        "fields/u",
        "fields/v",
        "fields/tension",
        "body/segments",
        "body/world",
        "step/velocity",
        "task/distance",
    ] {
        let rows = rows_of(&chunks, path);
        assert_eq!(rows.concat(), all, "{path}: every state, in order");
        if path.starts_with("fields/") || path.starts_with("body/") {
            assert_eq!(rows.len(), 10, "{path}: one chunk per block of 100 states");
        }
    }
    // the applied wave from the second state on, the heatmap in blocks of 256 rows
    assert_eq!(rows_of(&chunks, "actuation/applied/f0").concat().len(), 999);
    let heat: Vec<i64> = rows_of(&chunks, "heatmap/u").concat();
    assert_eq!(heat, [0, 256, 512, 768]);
}

#[test]
fn every_kth_state_has_its_fields_and_every_state_its_scalars() {
    let (cells, last) = (16usize, 100u64);
    let opts = RecorderOptions {
        every: 8,
        ..Default::default()
    };
    let (mut r, storage) = recorder(opts, cells as u64, last);
    for n in 0..=last {
        r.handle(Incoming::State(encode(&state(n, cells, n == last, 0.5))))
            .unwrap();
    }
    r.finish().unwrap();
    let chunks = chunks(&storage);
    let fields: Vec<i64> = rows_of(&chunks, "fields/u").concat();
    let expected: Vec<i64> = (0..=100).filter(|n| n % 8 == 0 || *n == 100).collect();
    assert_eq!(fields, expected);
    assert_eq!(rows_of(&chunks, "tail/plant").concat().len(), 101);
    assert_eq!(
        r.closing_note(),
        "101 states (14 with fields): the fields of every 8th state recorded"
    );
}

/// A state missing from the sequence (dropped before the writer) is counted and said.
#[test]
fn a_missing_state_is_counted_and_said() {
    let (mut r, _storage) = recorder(RecorderOptions::default(), 8, 10);
    for n in (0..=10u64).filter(|&n| n != 4) {
        r.handle(Incoming::State(encode(&state(n, 8, n == 10, 0.5))))
            .unwrap();
    }
    r.finish().unwrap();
    assert_eq!(r.counts().missing_states, 1);
    assert!(
        r.closing_note()
            .contains("1 states never reached the writer"),
        "{}",
        r.closing_note()
    );
}

/// The plant's clock blocks are the running metrics (`metrics/<metric>/running`), its
/// forcing-period blocks the `plant` series.
#[test]
fn clock_blocks_are_the_running_metrics_and_period_blocks_the_plants() {
    let (mut r, storage) = recorder(RecorderOptions::default(), 8, 1000);
    let block = |step: u64, clock: bool, velocity: f64| Metrics {
        v: PROTOCOL_VERSION,
        step,
        block: step / 100,
        steady: false,
        start: (step - 100) as f64 * 1e-3,
        end: step as f64 * 1e-3,
        values: MetricValues::of(&[
            (Metric::Velocity, velocity),
            (Metric::Power, 1.0),
            (Metric::Mileage, velocity),
            (Metric::MaxStress, 1.0),
            (Metric::MaxStrain, 0.01),
            (Metric::StuckFraction, 0.1),
            (Metric::MeanFrictionSelection, 0.0),
            (Metric::EpisodesPerNodePerPeriod, 0.0),
        ]),
        clock,
    };
    for step in [100, 200, 300] {
        r.handle(Incoming::Metrics(encode(&block(step, true, 0.02))))
            .unwrap();
    }
    r.handle(Incoming::Metrics(encode(&block(300, false, 0.03))))
        .unwrap();
    r.finish().unwrap();
    let chunks = chunks(&storage);
    assert_eq!(
        rows_of(&chunks, "metrics/velocity/running").concat(),
        [100, 200, 300]
    );
    assert_eq!(rows_of(&chunks, "metrics/velocity/plant").concat(), [300]);
    assert_eq!(r.counts().clock_blocks, 3);
}

#[test]
fn every_episode_is_one_row_at_its_step_sent_in_few_chunks() {
    let (mut r, storage) = recorder(RecorderOptions::default(), 64, 1000);
    // 5000 episodes in blocks of 50 (at most one per node and message): one full chunk on the way, the rest at the end
    let ep = EpisodeMsg {
        node: 3,
        start: 0.05,
        end: 0.06,
        duration: 0.01,
        direction: 1,
    };
    for step in 100..200u64 {
        let e = Events {
            v: PROTOCOL_VERSION,
            step,
            time: step as f64 * 1e-3,
            episodes: vec![ep; 50],
        };
        r.handle(Incoming::Events(encode(&e))).unwrap();
    }
    r.finish().unwrap();
    let chunks = rows_of(&chunks(&storage), paths::LOG_EPISODES);
    let lengths: Vec<usize> = chunks.iter().map(Vec::len).collect();
    assert_eq!(
        lengths,
        vec![messages::EPISODE_ROWS, 5000 - messages::EPISODE_ROWS]
    );
    let steps: Vec<i64> = chunks.concat();
    let expected: Vec<i64> = (100..200)
        .flat_map(|s| std::iter::repeat_n(s, 50))
        .collect();
    assert_eq!(steps, expected);
    assert_eq!(r.counts().episodes, 5000);
}
