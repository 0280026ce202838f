//! A pipe whose friction varies along it: each node feels the friction at its own position.

mod common;

use std::f64::consts::TAU;

use common::{custom, rel, run};
use crawler_plant::slave::{Slave, StepStatus};
use crawler_plant::Scenario;

/// The main job's wave on one wavelength of body (0.25 m), f0 = 0.3 N at resonance.
fn body(eps: f64, t_end: f64, pipe: &str) -> Scenario {
    custom(eps, 0.3, 4.0 * TAU, 1.0, 0.25, 128, t_end, pipe)
}

#[test]
fn a_map_that_changes_nothing_is_bit_identical_to_no_map() {
    let plain = run(&body(0.1, 8.0, ""));
    // features whose values equal the uniform ones compile to a uniform map: the fast path runs
    let same = run(&body(
        0.1,
        8.0,
        "[pipe]\nstart = 3.0\ndisclose = false\nnominal = { eps = 0.5, n_f = 0.2 }\n\
         [[pipe.features]]\nkind = \"patch\"\nfrom = 3.1\nto = 3.2\neps = 0.1\n",
    ));
    assert_eq!(plain.state_digest, same.state_digest);
    assert_eq!(plain.velocity.to_bits(), same.velocity.to_bits());
    assert_eq!(plain.events.count, same.events.count);
    // and a map that does change something changes the run
    let patch = run(&body(
        0.1,
        8.0,
        "[pipe]\n[[pipe.features]]\nkind = \"patch\"\nfrom = 0.1\nto = 0.2\neps = 0.2\n",
    ));
    assert_ne!(plain.state_digest, patch.state_digest);
}

/// Mean speed over the last `periods` forcing periods of a run to `s.t_end`, m/s.
fn final_speed(s: &Scenario, periods: f64) -> f64 {
    let mut slave = Slave::instantiate("pipe", s.plant.clone()).unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    slave.set_wave(s.wave).unwrap();
    slave.exit_initialization_mode().unwrap();
    let h = slave.plant().step_length();
    let steps = slave.plant().discretisation().steps_until(s.t_end);
    let mut u_at = None;
    let from = s.t_end - periods * s.wave.period();
    let mean = |p: &crawler_plant::Plant| p.displacement().iter().sum::<f64>() / p.cells() as f64;
    for n in 0..steps {
        if u_at.is_none() && slave.plant().time() >= from {
            u_at = Some((slave.plant().time(), mean(slave.plant())));
        }
        assert_eq!(slave.do_step(n as f64 * h, h), StepStatus::Ok);
    }
    let (t0, u0) = u_at.unwrap();
    (mean(slave.plant()) - u0) / (slave.plant().time() - t0)
}

#[test]
fn entering_a_patch_the_crawler_reaches_the_patchs_steady_speed() {
    // From eps = 0.1 (V = 0.05 m/s) into eps = 0.3 at X = 0.4 m: the head arrives after about 3 s,
    // the whole body is on the patch after about 6 s.
    let uniform_b = run(&body(0.3, 20.0, ""));
    let patched = body(
        0.1,
        20.0,
        "[pipe]\n[[pipe.features]]\nkind = \"patch\"\nfrom = 0.4\nto = 1000.0\neps = 0.3\n",
    );
    let before = final_speed(
        &{
            let mut s = patched.clone();
            s.t_end = 2.5;
            s
        },
        50.0,
    );
    let after = final_speed(&patched, 200.0);
    let uniform_a = run(&body(0.1, 10.0, ""));
    println!(
        "before the patch {before} (uniform eps 0.1: {}), after {after} (uniform eps 0.3: {})",
        uniform_a.velocity, uniform_b.velocity
    );
    assert!(rel(before, uniform_a.velocity) < 0.01);
    assert!(
        rel(after, uniform_b.velocity) < 0.005,
        "on the patch {after} vs {}",
        uniform_b.velocity
    );
}

#[test]
fn the_momentum_balance_holds_with_the_local_friction() {
    // A random texture and a ramp: the exact discrete balance uses each node's own eps and n_F.
    let s = body(
        0.3,
        10.0,
        "[pipe]\nresolution = 0.002\n\
         [[pipe.features]]\nkind = \"ramp\"\nfrom = 0.0\nto = 2.0\neps = [0.2, 0.5]\nn_f = [0.4, 0.6]\n\
         [[pipe.features]]\nkind = \"texture\"\nfrom = -1.0\nto = 3.0\neps_std = 0.05\ncorrelation = 0.05\nseed = 3\n",
    );
    let r = run(&s);
    assert!(
        r.momentum_residual < 1e-9,
        "discrete momentum balance off by {:e}",
        r.momentum_residual
    );
    // The balance with the uniform eps and n_F does not hold: the local values matter.
    let f = s.plant.friction;
    let uniform = f.band() * (f.n_f - r.mean_friction_selection) / f.viscous;
    assert!(
        rel(uniform, r.identity_velocity) > 0.05,
        "the uniform and the local identity agree: {uniform} vs {}",
        r.identity_velocity
    );
    assert!(r.velocity > 0.0);
}

#[test]
fn each_node_feels_the_friction_at_its_position() {
    let s = body(
        0.1,
        6.0,
        "[pipe]\nstart = 1.0\n[[pipe.features]]\nkind = \"patch\"\nfrom = 1.1\nto = 1.2\neps = 0.7\nn_f = 0.3\n",
    );
    let plant = crawler_plant::Plant::new(s.plant.clone(), 0.0).unwrap();
    let dx = plant.discretisation().dx;
    for (i, (eps, n_f)) in plant.node_friction().into_iter().enumerate() {
        let x = 1.0 + i as f64 * dx;
        let inside = (1.1..1.2).contains(&x);
        assert_eq!(
            (eps, n_f),
            if inside { (0.7, 0.3) } else { (0.1, 0.5) },
            "node {i} at X = {x}"
        );
    }
}

#[test]
fn controllers_are_told_nominal_friction_unless_the_pipe_is_disclosed() {
    let hidden = body(
        0.3,
        6.0,
        "[pipe]\ndisclose = false\nnominal = { eps = 0.1, n_f = 0.5 }\n\
         [[pipe.features]]\nkind = \"patch\"\nfrom = 0.0\nto = 1.0\neps = 0.8\n",
    );
    let told = hidden.plant.told();
    assert_eq!((told.friction.eps, told.friction.n_f), (0.1, 0.5));
    assert!(told.pipe.is_uniform());
    let shown = body(
        0.3,
        6.0,
        "[pipe]\n[[pipe.features]]\nkind = \"patch\"\nfrom = 0.0\nto = 1.0\neps = 0.8\n",
    );
    assert_eq!(shown.plant.told(), shown.plant);
}

#[test]
fn a_state_restored_at_every_step_continues_bit_for_bit_in_a_fine_texture() {
    // Each node takes the friction of the position where the whole internal step leaves it
    // (after the grid filter's share), the same position a restored state is placed at; so a
    // run restored from its own state after every communication step stays bit-identical. The
    // texture is fine (pieces of 10 um) so that nodes sit near piece edges all the time.
    let s = body(
        0.3,
        6.0,
        "[pipe]\nresolution = 0.00001\n[[pipe.features]]\nkind = \"texture\"\n\
         from = -0.1\nto = 0.5\neps_std = 0.1\ncorrelation = 0.0001\nseed = 5\n",
    );
    let start = |s: &Scenario| {
        let mut slave = Slave::instantiate("pipe", s.plant.clone()).unwrap();
        slave.enter_initialization_mode(0.0, None).unwrap();
        slave.set_wave(s.wave).unwrap();
        slave.exit_initialization_mode().unwrap();
        slave
    };
    let (mut straight, mut restored) = (start(&s), start(&s));
    let h = straight.plant().step_length();
    let mut last = straight.plant().node_friction();
    let mut moves = 0;
    for n in 0..straight.plant().discretisation().steps_until(1.0) {
        let t = n as f64 * h;
        assert_eq!(straight.do_step(t, h), StepStatus::Ok);
        assert_eq!(restored.do_step(t, h), StepStatus::Ok);
        let state = restored.get_state();
        restored.set_state(&state).unwrap();
        let now = straight.plant().node_friction();
        let differ = now
            .iter()
            .zip(&restored.plant().node_friction())
            .position(|(a, b)| a != b);
        assert_eq!(differ, None, "node's friction differs after step {n}");
        moves += now.iter().zip(&last).filter(|(a, b)| a != b).count();
        last = now;
    }
    let digest = crawler_plant::simulate::state_digest;
    assert_eq!(digest(straight.plant()), digest(restored.plant()));
    // not vacuous: nodes kept crossing piece edges
    assert!(moves > 1000, "only {moves} changes of a node's friction");
}

#[test]
fn nothing_sticks_where_the_pipe_has_no_dry_friction() {
    // a body at rest (no muscle force) on a piece of pipe with eps = 0: every node has zero
    // velocity and zero force, and nothing holds it, as in a pipe with eps = 0 everywhere
    let frictionless = run(&custom(0.0, 0.0, 4.0 * TAU, 1.0, 0.25, 128, 6.0, ""));
    let piece = run(&custom(
        0.1,
        0.0,
        4.0 * TAU,
        1.0,
        0.25,
        128,
        6.0,
        "[pipe]\n[[pipe.features]]\nkind = \"patch\"\nfrom = -1.0\nto = 1.0\neps = 0.0\n",
    ));
    assert_eq!(frictionless.stuck_fraction, 0.0);
    assert_eq!(piece.stuck_fraction, 0.0);
    assert_eq!(piece.events.count, 0);
    assert_eq!(frictionless.velocity, piece.velocity);
}
