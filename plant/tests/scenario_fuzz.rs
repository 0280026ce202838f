//! Property-based fuzzing of the scenario parser: arbitrary text and mutations of the paper
//! scenario never panic, and whatever parses is a fully valid scenario.

use proptest::prelude::*;

use crawler_plant::scenario::{Overrides, Scenario, PAPER_TOML};

fn check(text: &str) {
    if let Ok(s) = Scenario::from_toml(text, "fuzz.toml", &Overrides::default()) {
        s.plant.validate().unwrap();
        s.wave
            .validate_for_body(s.plant.length, s.plant.numerics.cells, s.plant.boundary)
            .unwrap();
        assert!(s.t_end.is_finite() && s.t_end > 0.0);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1500, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_text_never_panics(text in "\\PC{0,300}") {
        check(&text);
    }

    #[test]
    fn mutated_paper_scenarios_never_panic(at in any::<prop::sample::Index>(), insert in "[-0-9a-z.e=\\[\\]\"#\n ]{0,8}", cut in 0usize..12) {
        let i = at.index(PAPER_TOML.len());
        let i = (0..=i).rev().find(|&j| PAPER_TOML.is_char_boundary(j)).unwrap();
        let end = (i + cut).min(PAPER_TOML.len());
        let end = (end..=PAPER_TOML.len()).find(|&j| PAPER_TOML.is_char_boundary(j)).unwrap();
        let text = format!("{}{}{}", &PAPER_TOML[..i], insert, &PAPER_TOML[end..]);
        check(&text);
    }

    #[test]
    fn numbers_in_every_field_are_checked(value in prop_oneof![any::<f64>(), Just(f64::NAN), Just(f64::INFINITY), Just(-0.0), Just(1e308)]) {
        for key in ["area", "density", "youngs_modulus", "viscous", "dry", "eps", "n_f", "f0", "k", "alpha", "courant", "step", "t_end", "settle"] {
            let re = format!("\n{key} = ");
            if let Some(pos) = PAPER_TOML.find(&re) {
                let start = pos + re.len();
                let stop = start + PAPER_TOML[start..].find(|c: char| c.is_whitespace()).unwrap();
                let v = if value.is_nan() { "nan".to_string() } else if value.is_infinite() { "inf".to_string() } else { format!("{value:e}") };
                let text = format!("{}{}{}", &PAPER_TOML[..start], v, &PAPER_TOML[stop..]);
                check(&text);
            }
        }
    }
}

mod checkpoints {
    use super::*;
    use crawler_plant::checkpoint::Checkpoint;
    use crawler_plant::plant::Plant;
    use crawler_plant::simulate::EpisodeLog;
    use crawler_plant::slave::Slave;

    fn sample() -> (Vec<u8>, Vec<u8>) {
        let s = Scenario::paper();
        let mut plant = Plant::new(s.plant.clone(), 0.0).unwrap();
        plant.set_wave(s.wave).unwrap();
        for _ in 0..20 {
            plant.advance().unwrap();
        }
        let ckpt = Checkpoint {
            run_id: "fuzz".into(),
            scenario: s.clone(),
            last_step: 100,
            state: plant.state(),
            log: EpisodeLog::new(10),
            rejections: Default::default(),
            reason: "test".into(),
        };
        (ckpt.to_bytes(), Slave::serialize_state(&plant.state()))
    }

    #[test]
    fn a_checkpoint_round_trips() {
        let (c, s) = sample();
        assert!(Checkpoint::from_bytes(&c).is_ok());
        assert!(Slave::deserialize_state(&s).is_ok());
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 600, ..ProptestConfig::default() })]

        #[test]
        fn mutated_checkpoints_and_states_never_panic(at in any::<prop::sample::Index>(), byte in any::<u8>(), cut in any::<prop::sample::Index>()) {
            let (mut c, mut s) = sample();
            let i = at.index(c.len());
            c[i] ^= byte | 1;
            let _ = Checkpoint::from_bytes(&c);
            let _ = Checkpoint::from_bytes(&c[..cut.index(c.len())]);
            let j = at.index(s.len());
            s[j] ^= byte | 1;
            if let Ok(state) = Slave::deserialize_state(&s) {
                let _ = Plant::from_state(&state);
            }
            let _ = Slave::deserialize_state(&s[..cut.index(s.len())]);
        }
    }
}
