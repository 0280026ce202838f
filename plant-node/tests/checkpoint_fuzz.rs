//! Property-based fuzzing of co-simulation checkpoints: mutated or truncated files are refused
//! or read, never a panic.

use proptest::prelude::*;

use crawler_plant::plant::Plant;
use crawler_plant::scenario::Scenario;
use crawler_plant::simulate::EpisodeLog;
use crawler_plant_node::checkpoint::Checkpoint;

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
        task: crawler_plant::task::TaskTracker::new(s.task, 0.0, 0.0),
    }
}

#[test]
fn a_checkpoint_round_trips() {
    let ckpt = sample();
    assert_eq!(Checkpoint::from_bytes(&ckpt.to_bytes()).unwrap(), ckpt);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 600, ..ProptestConfig::default() })]

    #[test]
    fn mutated_checkpoints_never_panic(at in any::<prop::sample::Index>(), byte in any::<u8>(), cut in any::<prop::sample::Index>()) {
        let mut c = sample().to_bytes();
        let i = at.index(c.len());
        c[i] ^= byte | 1;
        let _ = Checkpoint::from_bytes(&c);
        let _ = Checkpoint::from_bytes(&c[..cut.index(c.len())]);
    }
}
