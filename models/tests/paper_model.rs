//! The paper's analytic model: formulas against hand-checked values, and against the plant.

mod common;

use std::f64::consts::PI;

use crawler_models::paper_model::{
    first_order_harmonic, square_wave_coefficients, PaperModel, PaperTerms,
};
use crawler_models::{Model, OperatingPoint, Validity};
use crawler_physics::scenario::{Overrides, Scenario};

fn op(o: Overrides) -> OperatingPoint {
    OperatingPoint::of(&Scenario::load(None, &o).unwrap())
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn dimensionless_groups_match_the_hand_values() {
    // docs/physics.md §1.5: c = 11.83 m/s, omega_n = 74.3 rad/s, zeta = 0.1345, pi_r = 0.318 at k = 2 pi, f0 = 0.5 N
    let p = op(Overrides::default());
    assert!((p.body.wave_speed() - 11.832).abs() < 1e-3);
    assert!((p.omega_n() - 74.34).abs() < 0.01);
    assert!((p.zeta() - 0.1345).abs() < 1e-4);
    // pi_r = c_d / (f0 k) = 1 N/m / (0.5 N * 2 pi / m) = 1 / pi
    assert!((p.pi_r() - 1.0 / std::f64::consts::PI).abs() < 1e-12);
}

#[test]
fn terms_at_resonance_by_hand() {
    let p = op(Overrides {
        alpha: Some(1.0),
        ..Default::default()
    });
    let t = PaperTerms::at(&p);
    let zeta = 1.0 / (2.0 * PI * 0.1f64.sqrt() * 14f64.sqrt() / 1.0 / 1.0); // c_v / (k sqrt(rho A E))
    assert!(rel(t.zeta, zeta) < 1e-12);
    assert!(rel(t.r0, 1.0 / zeta) < 1e-12, "R0 = 1/zeta at resonance");
    assert!(
        (t.phi0 - PI / 2.0).abs() < 1e-12,
        "phi0 = pi/2 at resonance"
    );
    let c0 = t.pi_r * 0.5 / zeta;
    assert!(rel(t.c0, c0) < 1e-12);
    // gamma = asin(eps pi_r n_F) at resonance; V = eps c_d / c_v (n_F - 2 gamma / pi) = 0.048986...
    let gamma = (0.1 * t.pi_r * 0.5).asin();
    assert!(rel(t.gamma.unwrap(), gamma) < 1e-12);
    let v = PaperModel::velocity(&p).unwrap();
    assert!(rel(v, 0.1 * (0.5 - 2.0 * gamma / PI)) < 1e-12);
    assert!(rel(v, 0.048986) < 1e-4, "{v}");
    assert!(
        rel(PaperModel::resonance_velocity(&p).unwrap(), v) < 1e-12,
        "eq. (34) is eq. (31) at resonance"
    );
    // power per wavelength pi zeta alpha R0^2 f0^2 omega / (k A_c E)
    let power = PI * zeta / zeta / zeta * 0.25 * p.wave.omega / (2.0 * PI * 14.0);
    assert!(rel(PaperModel::power(&p), power) < 1e-12);
    // at resonance the printed eq. (30) times E equals the stress from definition (4)
    assert!(
        rel(
            PaperModel::stress_eq30(&p) * 140e3,
            PaperModel::max_stress(&p)
        ) < 1e-12
    );
}

#[test]
fn phase_uses_the_atan2_branch_and_stress_eq30_differs_off_resonance() {
    let below = PaperTerms::at(&op(Overrides {
        alpha: Some(0.5),
        ..Default::default()
    }));
    let above = PaperTerms::at(&op(Overrides {
        alpha: Some(2.0),
        ..Default::default()
    }));
    assert!(
        below.phi0 > PI / 2.0 && below.phi0 < PI,
        "below resonance phi0 in (pi/2, pi): {}",
        below.phi0
    );
    assert!(
        above.phi0 > 0.0 && above.phi0 < PI / 2.0,
        "above resonance phi0 in (0, pi/2): {}",
        above.phi0
    );
    let p = op(Overrides {
        alpha: Some(0.5),
        ..Default::default()
    });
    assert!(
        rel(
            PaperModel::stress_eq30(&p) * 140e3,
            PaperModel::max_stress(&p)
        ) > 0.1
    );
}

#[test]
fn square_wave_series_reconstructs_the_friction_selection() {
    let gamma = 0.3f64;
    let dc = 2.0 * gamma / PI;
    for &xi in &[0.1, 1.0, 2.0, 3.5, 5.0, 6.0] {
        let exact = if gamma.sin() - f64::sin(xi) > 0.0 {
            1.0
        } else {
            -1.0
        };
        let series: f64 = dc
            + (1..=4000)
                .map(|n| {
                    let (a, b) = square_wave_coefficients(gamma, n);
                    a * (n as f64 * xi).cos() + b * (n as f64 * xi).sin()
                })
                .sum::<f64>();
        assert!(
            (series - exact).abs() < 0.02,
            "xi = {xi}: series {series} vs {exact}"
        );
    }
}

#[test]
fn outside_validity_is_reported_not_nan() {
    let p = op(Overrides {
        eps: Some(1.0),
        f0: Some(0.1),
        alpha: Some(0.5),
        ..Default::default()
    });
    let pred = PaperModel::default().predict(&p);
    assert!(matches!(pred.validity, Validity::OutsideValidity(ref r) if r.contains("validity")));
    assert!(pred.velocity.is_none() && pred.mileage.is_none());
    // what the model still knows is a finite number, the rest is absent (not NaN, which JSON
    // would print as null just like an absent value)
    assert!(pred.power.is_some_and(f64::is_finite) && pred.max_stress.is_some_and(f64::is_finite));
    assert_eq!(common::finite_floats(&pred), Ok(2));
    assert!(PaperModel::default().displacement(&p, 0.0, 1.0).is_none());
    assert!(first_order_harmonic(&PaperTerms::at(&p), 1).is_none());
}

#[test]
fn a_forcing_that_overflows_f64_is_reported_not_infinite() {
    let at = |f0: f64| {
        PaperModel::default().predict(&op(Overrides {
            f0: Some(f0),
            ..Default::default()
        }))
    };
    // P grows as f0^2: 1e100 N is absurd but representable, 1e300 N is not
    let p = at(1e100);
    assert!(p.validity.is_valid(), "{:?}", p.validity);
    assert_eq!(common::finite_floats(&p), Ok(8));
    let p = at(1e300);
    assert!(
        matches!(p.validity, Validity::OutsideValidity(ref r) if r.contains("overflow")),
        "{:?}",
        p.validity
    );
    assert_eq!(common::finite_floats(&p), Ok(0));
}

#[test]
fn reconstructed_displacement_overlays_the_plant_at_small_eps() {
    // eps = 0.1 at resonance: the paper's mu0 + eps mu1 against the converged plant, shape only
    // (the drift's origin is arbitrary: compare u - mean u over the body at one instant).
    let s = Scenario::load(
        None,
        &Overrides {
            alpha: Some(1.0),
            cells: Some(256),
            t_end: Some(8.0),
            ..Default::default()
        },
    )
    .unwrap();
    let mut plant = crawler_physics::Plant::new(s.plant.clone(), 0.0).unwrap();
    plant.set_wave(s.wave).unwrap();
    while plant.time() < s.t_end - 1e-9 {
        plant.advance().unwrap();
    }
    let p = OperatingPoint::of(&s);
    let model = PaperModel { harmonics: 20 };
    let t = plant.time();
    let n = plant.cells();
    let dx = s.plant.length / n as f64;
    let sim: Vec<f64> = plant.displacement().to_vec();
    let ana: Vec<f64> = (0..n)
        .map(|i| model.displacement(&p, i as f64 * dx, t).unwrap())
        .collect();
    let (ms, ma) = (
        sim.iter().sum::<f64>() / n as f64,
        ana.iter().sum::<f64>() / n as f64,
    );
    let err: f64 = sim
        .iter()
        .zip(&ana)
        .map(|(a, b)| ((a - ms) - (b - ma)).powi(2))
        .sum::<f64>()
        .sqrt();
    let norm: f64 = sim.iter().map(|a| (a - ms).powi(2)).sum::<f64>().sqrt();
    assert!(err / norm < 0.03, "relative L2 difference {}", err / norm);
    // With the paper's sign slip (eq. 27: +R0 cos) the shape would be off by a phase of pi.
    let flipped: f64 = sim
        .iter()
        .zip(&ana)
        .map(|(a, b)| ((a - ms) + (b - ma)).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(flipped / norm > 1.5);
}
