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
fn every_episode_is_a_row_at_its_step_with_its_numbers_sent_in_few_chunks() {
    use rerun::external::arrow::array::{Array, Float64Array, Int8Array, UInt32Array};
    let (mut r, storage) = recorder(RecorderOptions::default(), 64, 1000);
    // 100 messages of 50 episodes (node j, from step/1000 - (j+1)/1e4 s to step/1000 s, leaving
    // forward on even nodes): a chunk once EPISODE_ROWS episodes are held, the rest at the end
    for step in 100..200u64 {
        let t = step as f64 * 1e-3;
        let episodes = (0..50u32)
            .map(|j| EpisodeMsg {
                node: j,
                start: t - (j + 1) as f64 * 1e-4,
                end: t,
                duration: (j + 1) as f64 * 1e-4,
                direction: if j % 2 == 0 { 1 } else { -1 },
            })
            .collect();
        let e = Events {
            v: PROTOCOL_VERSION,
            step,
            time: t,
            episodes,
        };
        r.handle(Incoming::Events(encode(&e))).unwrap();
    }
    r.finish().unwrap();
    let all = chunks(&storage);
    let first_chunk_rows = messages::EPISODE_ROWS.div_ceil(50) * 50;
    let rows = rows_of(&all, paths::EPISODES);
    let lengths: Vec<usize> = rows.iter().map(Vec::len).collect();
    assert_eq!(lengths, vec![first_chunk_rows, 5000 - first_chunk_rows]);
    let steps: Vec<i64> = (100..200).flat_map(|s| [s; 50]).collect();
    assert_eq!(rows.concat(), steps);
    let list = |c: &rerun::log::Chunk, name: &'static str| {
        let id = format!("{}:{name}", paths::EPISODE_ARCHETYPE);
        let (_, column) = c
            .components()
            .iter()
            .find(|(k, _)| k.as_str() == id)
            .unwrap_or_else(|| panic!("{id} in {:?}", c.components().keys()));
        let column = column.list_array.clone();
        let lengths: Vec<usize> = column.iter().map(|row| row.unwrap().len()).collect();
        assert!(lengths.iter().all(|&n| n == 1), "{name}: one episode a row");
        column.values().clone()
    };
    let mut nodes: Vec<u32> = vec![];
    let mut starts: Vec<f64> = vec![];
    let mut durations: Vec<f64> = vec![];
    let mut directions: Vec<i8> = vec![];
    for c in all
        .iter()
        .filter(|c| c.entity_path().to_string() == format!("/{}", paths::EPISODES))
    {
        let node = list(c, "node");
        nodes.extend(
            node.as_any()
                .downcast_ref::<UInt32Array>()
                .unwrap()
                .values(),
        );
        let start = list(c, "start");
        starts.extend(
            start
                .as_any()
                .downcast_ref::<Float64Array>()
                .unwrap()
                .values(),
        );
        let d = list(c, "duration");
        durations.extend(d.as_any().downcast_ref::<Float64Array>().unwrap().values());
        let dir = list(c, "direction");
        directions.extend(dir.as_any().downcast_ref::<Int8Array>().unwrap().values());
    }
    assert_eq!(nodes.len(), 5000);
    for (k, step) in (100..200u64).enumerate() {
        for j in 0..50usize {
            let i = 50 * k + j;
            assert_eq!(nodes[i], j as u32);
            assert_eq!(starts[i], step as f64 * 1e-3 - (j + 1) as f64 * 1e-4);
            assert_eq!(durations[i], (j + 1) as f64 * 1e-4);
            assert_eq!(directions[i], if j % 2 == 0 { 1 } else { -1 });
        }
    }
    assert_eq!(r.counts().episodes, 5000);
}
