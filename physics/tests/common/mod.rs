//! Helpers shared by the plant's integration tests.
#![allow(dead_code)]

use crawler_physics::report::Report;
use crawler_physics::scenario::{Overrides, Scenario};
use crawler_physics::simulate::{simulate, SimulateOptions};

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

/// The exact linear (eps = 0) steady state of docs/physics.md §2.3.
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

pub mod travelling_wave;

/// A scenario on the paper's body and friction coefficients with the given friction, wave
/// (`alpha = omega / omega_n`), body length and grid, from TOML text (`extra` is appended).
#[allow(clippy::too_many_arguments)]
pub fn custom(
    eps: f64,
    f0: f64,
    k: f64,
    alpha: f64,
    length: f64,
    cells: usize,
    t_end: f64,
    extra: &str,
) -> Scenario {
    custom_body(eps, f0, k, alpha, length, "periodic", cells, t_end, extra)
}

/// [`custom`] with the body's boundary (`"periodic"` or `"free"`).
#[allow(clippy::too_many_arguments)]
pub fn custom_body(
    eps: f64,
    f0: f64,
    k: f64,
    alpha: f64,
    length: f64,
    boundary: &str,
    cells: usize,
    t_end: f64,
    extra: &str,
) -> Scenario {
    let text = format!(
        r#"
name = "test"
[body]
area = 1e-4
density = 0.1
youngs_modulus = 140e3
length = {length:?}
boundary = "{boundary}"
[friction]
viscous = 1.0
dry = 1.0
eps = {eps:?}
n_f = 0.5
[actuation]
f0 = {f0:?}
k = {k:?}
alpha = {alpha:?}
[numerics]
cells = {cells}
t_end = {t_end:?}
settle = 5.0
{extra}
"#
    );
    Scenario::from_toml(&text, "<test>", &Overrides::default()).expect("valid test scenario")
}
