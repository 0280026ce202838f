//! The byte-level examples of `docs/protocol.md` are the real encoding: each example message is
//! encoded here, decoded back, and its hex dump must appear verbatim in the document.
//!
//! `PRINT_WIRE_EXAMPLES=1 cargo test --release -p crawler-protocol --test wire_examples -- --nocapture`
//! prints the dumps (to refresh the document after a deliberate change of the protocol).

use crawler_protocol::{
    decode, encode, Actuation, EpisodeMsg, Events, Message, Metrics, ModelInfo, ModelPrediction,
    Prediction, Rejections, Series, State, Status, WaveMsg, PROTOCOL_VERSION,
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
        controller: "c0ffee".into(),
        u: vec![0.0, 0.001],
        vel: vec![0.0, 0.5],
        tension: vec![-0.25, 0.25],
        stuck: vec![true, false],
        mean_speed: 0.25,
        input_power: 1.5,
        last: false,
    }
}

fn actuation_wave() -> Actuation {
    Actuation {
        v: V,
        step: 3,
        controller: "c0ffee".into(),
        wave: Some(wave()),
        field: None,
    }
}

fn actuation_field() -> Actuation {
    Actuation {
        v: V,
        step: 3,
        controller: "c0ffee".into(),
        wave: None,
        field: Some(vec![0.5, -0.5]),
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
        velocity: 0.049,
        power: 4.73,
        mileage: 0.0103,
        max_stress: 36300.0,
        max_strain: 0.0026,
        stuck_fraction: 0.0,
        mean_friction_selection: -0.5,
        episodes_per_node_per_period: 0.0,
    }
}

fn status() -> Status {
    Status {
        v: V,
        role: "plant".into(),
        id: "5eed".into(),
        state: "running".into(),
        message: "step 9 of 10".into(),
        step: 9,
        rejected: Rejections {
            stale: 1,
            ..Rejections::default()
        },
        summary: None,
    }
}

fn prediction() -> Prediction {
    Prediction {
        v: V,
        controller: "c0ffee".into(),
        policy: "wave".into(),
        step: 0,
        wave: wave(),
        models: vec![ModelPrediction {
            model: "improved".into(),
            velocity: Some(0.049),
            power: Some(4.73),
            mileage: Some(0.0103),
            max_stress: Some(36300.0),
            stuck_fraction: Some(0.0),
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
    ModelInfo {
        v: V,
        run: "demo".into(),
        cells: 2,
        length: 1.0,
        step: 0.001,
        start_time: 0.0,
        last_step: 10,
        area: 1e-4,
        density: 0.1,
        youngs_modulus: 140e3,
        viscous: 1.0,
        dry: 1.0,
        eps: 0.1,
        n_f: 0.5,
        settle: 5.0,
        model_description: "{}".into(),
        boundary: "periodic".into(),
        disclosed: true,
    }
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
        check("Actuation (wave)", actuation_wave(), &doc),
        check("Actuation (field)", actuation_field(), &doc),
        check("Events", events(), &doc),
        check("Metrics", metrics(), &doc),
        check("Status", status(), &doc),
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
