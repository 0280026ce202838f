//! Property-based fuzzing of the scenario parser and of serialised plant states: arbitrary text
//! and mutations of the paper scenario never panic, and whatever parses is a fully valid
//! scenario; mutated or truncated states are refused or restored, never a panic.

use proptest::prelude::*;

use crawler_physics::scenario::{Overrides, Scenario, PAPER_TOML};

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

mod states {
    use super::*;
    use crawler_physics::plant::Plant;
    use crawler_physics::slave::Slave;

    fn sample() -> crawler_physics::plant::PlantState {
        let s = Scenario::paper();
        let mut plant = Plant::new(s.plant.clone(), 0.0).unwrap();
        plant.set_wave(s.wave).unwrap();
        for _ in 0..20 {
            plant.advance().unwrap();
        }
        plant.state()
    }

    #[test]
    fn a_state_round_trips() {
        let state = sample();
        let bytes = Slave::serialize_state(&state);
        assert_eq!(Slave::deserialize_state(&bytes).unwrap(), state);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 600, ..ProptestConfig::default() })]

        #[test]
        fn mutated_states_never_panic(at in any::<prop::sample::Index>(), byte in any::<u8>(), cut in any::<prop::sample::Index>()) {
            let mut s = Slave::serialize_state(&sample());
            let j = at.index(s.len());
            s[j] ^= byte | 1;
            if let Ok(state) = Slave::deserialize_state(&s) {
                let _ = Plant::from_state(&state);
            }
            let _ = Slave::deserialize_state(&s[..cut.index(s.len())]);
        }
    }
}
