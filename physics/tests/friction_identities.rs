//! Facts any correct plant must satisfy with dry friction (docs/physics.md §2.1-2.2, §3.2).

mod common;

use common::{paper, rel, run};
use crawler_physics::scenario::Overrides;

#[test]
fn steady_identity_holds_and_speed_is_bounded() {
    for eps in [0.1, 0.5, 1.0] {
        for alpha in [0.5, 1.0] {
            let s = paper(Overrides {
                eps: Some(eps),
                alpha: Some(alpha),
                t_end: Some(10.0),
                ..Default::default()
            });
            let r = run(&s);
            let f = s.plant.friction;
            // The exact discrete analogue: rho dV/T_w + c_v <(v+ + v-)/2> + eps c_d (<s> - n_F) = 0.
            assert!(
                r.momentum_residual < 1e-9,
                "eps {eps}, alpha {alpha}: discrete momentum balance off by {:e}",
                r.momentum_residual
            );
            // and the continuous identity, to the size of the window's momentum change
            let identity = f.band() * (f.n_f - r.mean_friction_selection) / f.viscous;
            assert!(
                rel(r.velocity, identity) < 1e-5,
                "eps {eps}, alpha {alpha}: V = {} but eps c_d (n_F - <s>)/c_v = {identity}",
                r.velocity
            );
            println!(
                "eps {eps} alpha {alpha}: V {} identity {identity} rel {:e} discrete residual {:e}",
                r.velocity,
                rel(r.velocity, identity),
                r.momentum_residual
            );
            assert!(
                r.velocity.abs() <= f.speed_bound(),
                "eps {eps}, alpha {alpha}: |V| = {} exceeds bound",
                r.velocity
            );
            assert!(
                r.velocity > 0.0,
                "eps {eps}, alpha {alpha}: the crawler should move forward, V = {}",
                r.velocity
            );
        }
    }
}

#[test]
fn resonance_speed_matches_the_paper_formula() {
    // eq. (31) at alpha = 1, eps = 0.1, k = 2 pi, f0 = 0.5 N: V = eps c_d/c_v (n_F - 2 gamma/pi).
    let s = paper(Overrides {
        eps: Some(0.1),
        alpha: Some(1.0),
        cells: Some(256),
        ..Default::default()
    });
    let r = run(&s);
    let b = s.plant.body;
    let f = s.plant.friction;
    let k = s.wave.k;
    let zeta = f.viscous / (k * (b.density * b.stiffness()).sqrt());
    let pi_r = f.dry / (s.wave.f0 * k);
    let r0 = 1.0 / zeta; // alpha = 1
    let c0 = pi_r * f.n_f / zeta;
    let gamma = (f.eps * c0 / r0).asin();
    let v31 = f.band() / f.viscous * (f.n_f - 2.0 * gamma / std::f64::consts::PI);
    assert!(
        rel(r.velocity, v31) < 0.01,
        "V = {} vs eq. (31) {v31}",
        r.velocity
    );
}

#[test]
fn energy_balance_with_friction() {
    for (eps, alpha) in [(0.1, 0.5), (1.0, 0.5), (0.5, 1.0)] {
        let s = paper(Overrides {
            eps: Some(eps),
            alpha: Some(alpha),
            cells: Some(256),
            ..Default::default()
        });
        let r = run(&s);
        assert!(
            rel(r.dissipation, r.power) < 0.01,
            "eps {eps} alpha {alpha}: dissipated {} vs input {}",
            r.dissipation,
            r.power
        );
    }
}

#[test]
fn without_drive_a_body_at_rest_stays_at_rest() {
    // sgn(0) = 0 would push a resting body forward by eps c_d n_F; exact stick must not.
    let s = paper(Overrides {
        eps: Some(0.5),
        f0: Some(0.0),
        t_end: Some(7.0),
        ..Default::default()
    });
    let r = run(&s);
    assert_eq!(r.velocity, 0.0);
    assert_eq!(r.stuck_fraction, 1.0);
    assert!(
        (r.mean_friction_selection - 0.5).abs() < 1e-15,
        "holding selection is n_F, got {}",
        r.mean_friction_selection
    );
}
