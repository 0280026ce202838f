//! Helpers shared by the plant's integration tests.
#![allow(dead_code)]

use crawler_plant::scenario::{Overrides, Scenario};
use crawler_plant::simulate::{simulate, Report, SimulateOptions};

/// The paper scenario with overrides.
pub fn paper(o: Overrides) -> Scenario {
    Scenario::load(None, &o).expect("valid scenario")
}

/// Runs a scenario in process.
pub fn run(s: &Scenario) -> Report {
    simulate(s, SimulateOptions::default()).expect("simulation runs")
}

/// Relative difference |a - b| / |b|.
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// The exact linear (eps = 0) steady state of physics-notes §3.
pub struct Linear {
    pub r0: f64,
    pub phi0: f64,
    pub u_c: f64,
    pub power: f64,
    pub stress: f64,
    pub zeta: f64,
    pub alpha: f64,
}

impl Linear {
    pub fn of(s: &Scenario) -> Self {
        let b = s.plant.body;
        let ae = b.stiffness();
        let k = s.wave.k;
        let omega = s.wave.omega;
        let f0 = s.wave.f0;
        let zeta = s.plant.friction.viscous / (k * (b.density * ae).sqrt());
        let alpha = omega / (k * b.wave_speed());
        let r0 = 1.0 / ((alpha * alpha - 1.0).powi(2) + (zeta * alpha).powi(2)).sqrt();
        let phi0 = (zeta * alpha).atan2(alpha * alpha - 1.0);
        let u_c = f0 / (k * ae);
        let power = std::f64::consts::PI * zeta * alpha * r0 * r0 * f0 * f0 * omega / (k * ae);
        let stress = f0 / b.area * r0 * alpha * (alpha * alpha + zeta * zeta).sqrt();
        Self {
            r0,
            phi0,
            u_c,
            power,
            stress,
            zeta,
            alpha,
        }
    }
}
