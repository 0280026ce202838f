//! A pipe whose friction varies along it: each node feels the friction at its own position.

mod common;

use std::f64::consts::TAU;

use common::{custom, rel, run};
use crawler_physics::slave::{Slave, StepStatus};
use crawler_physics::Scenario;

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
    let mean = |p: &crawler_physics::Plant| p.displacement().iter().sum::<f64>() / p.cells() as f64;
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
    let plant = crawler_physics::Plant::new(s.plant.clone(), 0.0).unwrap();
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
fn node_0_of_a_periodic_body_feels_both_ends_of_the_body() {
    // Node 0 stands for the half cells at the tail (X = 1.0) and at the head (X = 1.25, one body
    // length ahead); the patch covers the head's place only.
    let s = body(
        0.1,
        6.0,
        "[pipe]\nstart = 1.0\n[[pipe.features]]\nkind = \"patch\"\nfrom = 1.2\nto = 1.3\neps = 0.7\nn_f = 0.3\n",
    );
    let plant = crawler_physics::Plant::new(s.plant.clone(), 0.0).unwrap();
    let friction = plant.node_friction();
    // the mean eps, and the n_F of the mean eps n_F: (0.1 * 0.5 + 0.7 * 0.3) / 2 / 0.4
    let (eps, n_f) = friction[0];
    assert!((eps - 0.4).abs() < 1e-15, "node 0's eps {eps}");
    assert!((n_f - 0.325).abs() < 1e-15, "node 0's n_F {n_f}");
    // the other nodes feel their own place only
    let dx = plant.discretisation().dx;
    for (i, &(eps, _)) in friction.iter().enumerate().skip(1) {
        let x = 1.0 + i as f64 * dx;
        assert_eq!(eps, if x >= 1.2 { 0.7 } else { 0.1 }, "node {i} at X = {x}");
    }
    // a free body has no seam: its node 0 is at the tail's cell centre only
    let mut free = s.plant.clone();
    free.boundary = crawler_physics::params::Boundary::Free;
    let plant = crawler_physics::Plant::new(free, 0.0).unwrap();
    assert_eq!(plant.node_friction()[0], (0.1, 0.5));
}

/// Displacement of the centre of mass (m) of the paper's crawler (1 m, at resonance, eps = 0.1)
/// at 5 s on `cells` cells, its head starting on a patch of eps = 0.5 at [1, 1.5) m.
fn patch_crossing(cells: usize) -> f64 {
    let s = custom(
        0.1,
        0.5,
        TAU,
        1.0,
        1.0,
        cells,
        10.0,
        "[pipe]\n[[pipe.features]]\nkind = \"patch\"\nfrom = 1.0\nto = 1.5\neps = 0.5\n",
    );
    let mut slave = Slave::instantiate("pipe", s.plant.clone()).unwrap();
    slave.enter_initialization_mode(0.0, None).unwrap();
    slave.set_wave(s.wave).unwrap();
    slave.exit_initialization_mode().unwrap();
    let h = slave.plant().step_length();
    for n in 0..slave.plant().discretisation().steps_until(5.0) {
        assert_eq!(slave.do_step(n as f64 * h, h), StepStatus::Ok);
    }
    // the run ends at the first communication point at or after 5 s, which depends on the grid:
    // back to 5 s with the centre of mass's speed
    let p = slave.plant();
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    mean(p.displacement()) - (p.time() - 5.0) * mean(p.velocity())
}

#[test]
fn a_patch_crossing_converges_at_second_order() {
    // The body is where its cells are: with node 0 at the tail's place only, a periodic body
    // would sit half a cell behind (a centre of mass 1.3 mm short at 512 cells, converging at
    // first order).
    let reference = patch_crossing(2048);
    let (coarse, fine) = (patch_crossing(128), patch_crossing(512));
    let (e_coarse, e_fine) = ((coarse - reference).abs(), (fine - reference).abs());
    assert!(
        e_fine < 1e-4,
        "512 cells: {fine} m against {reference} m at 2048"
    );
    assert!(
        e_coarse > 8.0 * e_fine,
        "errors {e_coarse:e} m at 128 cells and {e_fine:e} m at 512: not second order"
    );
    assert!(reference > 0.3, "the crawler moved only {reference} m");
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
    let digest = crawler_physics::report::state_digest;
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
