//! Memory soak of the recorder without zenoh: feeds synthetic states, metrics and episodes
//! straight into `Recorder` and prints the resident memory every tenth of the run.
//!
//! `cargo run --release -p crawler-recorder --example soak -- STEPS CELLS OUT.rrd`

use std::time::Duration;

use crawler_facts::{Metric, MetricValues};
use crawler_protocol::{
    encode, Applied, EpisodeMsg, Events, Metrics, ModelInfo, State, WaveMsg, PROTOCOL_VERSION,
};
use crawler_recorder::{Incoming, Recorder, RecorderOptions};

fn rss_mib() -> f64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines()
        .find(|l| l.starts_with("VmRSS:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|k| k.parse::<f64>().ok())
        .map_or(f64::NAN, |k| k / 1024.0)
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let steps: u64 = args.get(1).map_or(Ok(200_000), |s| s.parse())?;
    let cells: usize = args.get(2).map_or(Ok(256), |s| s.parse())?;
    let out = args
        .get(3)
        .cloned()
        .unwrap_or_else(|| "/tmp/soak.rrd".into());
    let rec = crawler_recorder::recorder::open_file(std::path::Path::new(&out), false)?;
    let mut r = Recorder::new(rec, RecorderOptions::default())?;
    r.set_model(&ModelInfo::example("soak", cells as u64, steps), None)?;
    let started = std::time::Instant::now();
    for n in 0..=steps {
        let t = n as f64 * 1e-3;
        let phase = |i: usize| i as f64 / cells as f64 * std::f64::consts::TAU - 74.0 * t;
        let s = State {
            v: PROTOCOL_VERSION,
            step: n,
            time: t,
            controller: "c".into(),
            u: (0..cells)
                .map(|i| 0.01 * phase(i).sin() + 0.05 * t)
                .collect(),
            vel: (0..cells).map(|i| 0.7 * phase(i).cos()).collect(),
            tension: (0..cells).map(|i| 0.5 * phase(i).sin()).collect(),
            stuck: (0..cells)
                .map(|i| (i + n as usize).is_multiple_of(7))
                .collect(),
            mean_speed: 0.05,
            input_power: 4.7,
            last: n == steps,
            applied: (n > 0).then_some(Applied {
                wave: Some(WaveMsg {
                    f0: 0.5,
                    k: std::f64::consts::TAU,
                    omega: 74.0,
                    phase: 0.0,
                }),
                field: None,
            }),
        };
        r.handle(Incoming::State(encode(&s)))?;
        if n % 85 == 84 {
            let m = Metrics {
                v: PROTOCOL_VERSION,
                step: n,
                block: n / 85,
                steady: t > 5.0,
                start: t - 0.085,
                end: t,
                values: MetricValues::of(&[
                    (Metric::Velocity, 0.049),
                    (Metric::Power, 4.73),
                    (Metric::Mileage, 0.0103),
                    (Metric::MaxStress, 36300.0),
                    (Metric::MaxStrain, 0.0026),
                    (Metric::StuckFraction, 0.1),
                    (Metric::MeanFrictionSelection, -0.5),
                    (Metric::EpisodesPerNodePerPeriod, 1.0),
                ]),
                clock: false,
            };
            r.handle(Incoming::Metrics(encode(&m)))?;
            let e = Events {
                v: PROTOCOL_VERSION,
                step: n,
                time: t,
                episodes: vec![EpisodeMsg {
                    node: 3,
                    start: t - 0.05,
                    end: t,
                    duration: 0.05,
                    direction: 1,
                }],
            };
            r.handle(Incoming::Events(encode(&e)))?;
        }
        r.maybe_flush()?;
        if n % (steps / 10).max(1) == 0 {
            println!(
                "step {n:>8}: {:6.1} MiB, {:.1} s",
                rss_mib(),
                started.elapsed().as_secs_f64()
            );
        }
    }
    r.finish()?;
    std::thread::sleep(Duration::from_millis(100));
    println!("finished: {:6.1} MiB, {:?}", rss_mib(), r.counts());
    Ok(())
}
