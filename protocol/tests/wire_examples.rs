//! The byte-level examples of `docs/protocol.md` are the real encoding: each example message is
//! encoded here, decoded back, and its hex dump must appear verbatim in the document.
//!
//! `PRINT_WIRE_EXAMPLES=1 cargo test --release -p crawler-protocol --test wire_examples -- --nocapture`
//! prints the dumps (to refresh the document after a deliberate change of the protocol).

use crawler_facts::{Metric, MetricValues};
use crawler_protocol::{
    decode, encode, Actuation, Applied, EpisodeMsg, EpisodeStats, Events, FinalReport, Join,
    Message, Metrics, ModelInfo, ModelPrediction, Outcome, Prediction, ProcessState, Rejections,
    ReportWindow, Role, Series, State, Status, TaskResult, WaveMsg, PROTOCOL_VERSION,
};

const V: u16 = PROTOCOL_VERSION;

fn wave() -> WaveMsg {
    WaveMsg {
        f0: 0.5,
        k: 6.25,
        omega: 74.0,
        phase: 0.0,
    }
}

fn state() -> State {
    State {
        v: V,
        step: 3,
        time: 0.003,
        controller: "c0ffee00c0ffee00".into(),
        u: vec![0.0, 0.001],
        vel: vec![0.0, 0.5],
        tension: vec![-0.25, 0.25],
        stuck: vec![true, false],
        mean_speed: 0.25,
        input_power: 1.5,
        last: false,
        applied: Some(Applied {
            wave: Some(wave()),
            field: None,
        }),
    }
}

/// The state after a step driven by a field: the field it applied.
fn state_field() -> State {
    State {
        applied: Some(Applied {
            wave: None,
            field: Some(vec![0.5, -0.5]),
        }),
        ..state()
    }
}

fn actuation_wave() -> Actuation {
    Actuation {
        v: V,
        step: 3,
        controller: "c0ffee00c0ffee00".into(),
        wave: Some(wave()),
        field: None,
    }
}

fn actuation_field() -> Actuation {
    Actuation {
        v: V,
        step: 3,
        controller: "c0ffee00c0ffee00".into(),
        wave: None,
        field: Some(vec![0.5, -0.5]),
    }
}

fn join() -> Join {
    Join {
        v: V,
        controller: "c0ffee00c0ffee00".into(),
        policy: "reflex".into(),
        take_over: Some(5000),
    }
}

fn events() -> Events {
    Events {
        v: V,
        step: 700,
        time: 0.701,
        episodes: vec![EpisodeMsg {
            node: 17,
            start: 0.625,
            end: 0.7,
            duration: 0.075,
            direction: 1,
        }],
    }
}

fn metrics() -> Metrics {
    Metrics {
        v: V,
        step: 5070,
        block: 59,
        steady: true,
        start: 4.987,
        end: 5.071,
        values: MetricValues::of(&[
            (Metric::Velocity, 0.049),
            (Metric::Power, 4.73),
            (Metric::Mileage, 0.0103),
            (Metric::MaxStress, 36300.0),
            (Metric::MaxStrain, 0.0026),
            (Metric::StuckFraction, 0.0),
            (Metric::MeanFrictionSelection, -0.5),
            (Metric::EpisodesPerNodePerPeriod, 0.0),
        ]),
        clock: false,
    }
}

fn status() -> Status {
    Status {
        v: V,
        role: Role::Plant,
        id: "5eed00005eed0000".into(),
        state: ProcessState::Running,
        message: "step 9 of 10".into(),
        step: 9,
        rejected: Rejections {
            stale: 1,
            ..Rejections::default()
        },
        report: None,
    }
}

/// The plant's last status, with its final report (a run of 2 cells to t = 0.01 s under the
/// wave above, in task mode: the energy ran out).
fn status_finished() -> Status {
    Status {
        state: ProcessState::Finished,
        message: "finished at step 10".into(),
        step: 10,
        rejected: Rejections::default(),
        report: Some(FinalReport {
            scenario: "demo".into(),
            values: MetricValues::of(&[
                (Metric::Velocity, 0.049),
                (Metric::Power, 4.73),
                (Metric::Mileage, 0.0103),
                (Metric::MaxStress, 36300.0),
                (Metric::MaxStrain, 0.0026),
                (Metric::StuckFraction, 0.0),
                (Metric::MeanFrictionSelection, -0.5),
            ]),
            dissipation: 4.73,
            identity_velocity: 0.049,
            momentum_residual: None,
            events: EpisodeStats {
                count: 0,
                per_node_per_period: 0.0,
                mean_duration: 0.0,
                min_duration: 0.0005,
            },
            window: ReportWindow {
                start: 0.0,
                end: 0.01,
                periods: 0.125,
                steady: false,
                whole_run: true,
            },
            cells: 2,
            dt: 0.0005,
            step: 0.001,
            courant: 1.0,
            dx: 0.5,
            cells_per_wavelength: Some(2.0),
            steps: 20,
            macro_steps: 10,
            t_end: 0.01,
            state_digest: "4832f1ec".into(),
            task: Some(TaskResult {
                outcome: Outcome::EnergyExhausted,
                distance_target: 1.0,
                distance: 0.0005,
                time_to_distance: None,
                energy_budget: 0.04,
                energy_used: 0.0473,
                energy_at_distance: None,
                energy_exhausted_at: Some(0.0085),
                sigma_max: 100000.0,
                max_stress: 36300.0,
                time_over_sigma_max: 0.0,
                stress_tolerance: 0.0,
                stress_exceeded_at: None,
                run_time: 0.01,
            }),
        }),
        ..status()
    }
}

fn prediction() -> Prediction {
    Prediction {
        v: V,
        controller: "c0ffee00c0ffee00".into(),
        policy: "wave".into(),
        step: 0,
        wave: wave(),
        models: vec![ModelPrediction {
            model: "improved".into(),
            values: MetricValues::of(&[
                (Metric::Velocity, 0.049),
                (Metric::Power, 4.73),
                (Metric::Mileage, 0.0103),
                (Metric::MaxStress, 36300.0),
                (Metric::StuckFraction, 0.0),
            ]),
            validity: "valid".into(),
            tail: Some(Series {
                omega: 74.0,
                drift: 0.049,
                harmonics: vec![(0.002, 1.5)],
            }),
        }],
    }
}

fn model_info() -> ModelInfo {
    ModelInfo::example("demo", 2, 10)
}

/// 16 bytes per line: offset, hex bytes, printable ASCII.
fn hexdump(bytes: &[u8]) -> String {
    let mut out = String::new();
    for (i, chunk) in bytes.chunks(16).enumerate() {
        let hex: Vec<String> = chunk.iter().map(|b| format!("{b:02x}")).collect();
        let ascii: String = chunk
            .iter()
            .map(|&b| {
                if (0x20..0x7f).contains(&b) {
                    b as char
                } else {
                    '.'
                }
            })
            .collect();
        out.push_str(&format!(
            "{:08x}  {:<47}  |{}|\n",
            i * 16,
            hex.join(" "),
            ascii
        ));
    }
    out
}

fn check<M: Message + PartialEq + std::fmt::Debug>(name: &str, m: M, doc: &str) -> Option<String> {
    let bytes = encode(&m);
    let back: M = decode(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(back, m, "{name}: decode(encode(m)) != m");
    let dump = hexdump(&bytes);
    if std::env::var_os("PRINT_WIRE_EXAMPLES").is_some() {
        println!("{name} ({} bytes)\n```text\n{dump}```\n", bytes.len());
    }
    (!doc.contains(&dump)).then(|| format!("{name} ({} bytes):\n{dump}", bytes.len()))
}

#[test]
fn docs_show_the_real_encoding() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/protocol.md");
    let doc = std::fs::read_to_string(path).expect("docs/protocol.md exists");
    let missing: Vec<String> = [
        check("State", state(), &doc),
        check("State (applied field)", state_field(), &doc),
        check("Actuation (wave)", actuation_wave(), &doc),
        check("Actuation (field)", actuation_field(), &doc),
        check("Join", join(), &doc),
        check("Events", events(), &doc),
        check("Metrics", metrics(), &doc),
        check("Status", status(), &doc),
        check("Status (finished)", status_finished(), &doc),
        check("Prediction", prediction(), &doc),
        check("ModelInfo", model_info(), &doc),
    ]
    .into_iter()
    .flatten()
    .collect();
    assert!(
        missing.is_empty(),
        "docs/protocol.md does not show the real encoding of:\n{}",
        missing.join("\n")
    );
}
