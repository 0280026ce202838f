//! An operating point: the plant's physical parameters and a travelling wave.

use serde::Serialize;

use crawler_physics::params::{Body, Friction};
use crawler_physics::scenario::Scenario;
use crawler_physics::wave::Wave;

/// What a model needs to predict the steady state.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct OperatingPoint {
    /// Body material.
    pub body: Body,
    /// Friction law.
    pub friction: Friction,
    /// The drive.
    pub wave: Wave,
    /// Wavelengths on the body (power and mileage are for the whole body); 1 in the paper.
    pub wavelengths: f64,
}

impl OperatingPoint {
    /// The scenario's operating point.
    pub fn of(s: &Scenario) -> Self {
        Self {
            body: s.plant.body,
            friction: s.plant.friction,
            wave: s.wave,
            wavelengths: (s.wave.k * s.plant.length / std::f64::consts::TAU)
                .round()
                .max(1.0),
        }
    }

    /// The same point with another wave.
    pub fn with_wave(&self, wave: Wave) -> Self {
        Self { wave, ..*self }
    }

    /// Natural frequency `omega_n = k c`, rad/s.
    pub fn omega_n(&self) -> f64 {
        self.wave.k * self.body.wave_speed()
    }

    /// `alpha = omega / omega_n`.
    pub fn alpha(&self) -> f64 {
        self.wave.omega / self.omega_n()
    }

    /// Paper's `zeta = c_v / (k sqrt(rho A_c E))` (twice the usual damping ratio).
    pub fn zeta(&self) -> f64 {
        self.friction.viscous / (self.wave.k * (self.body.density * self.body.stiffness()).sqrt())
    }

    /// Paper's `pi_r = c_d / (f0 k)`.
    pub fn pi_r(&self) -> f64 {
        self.friction.dry / (self.wave.f0 * self.wave.k)
    }

    /// Characteristic displacement `u_c = f0 / (k A_c E)`, m.
    pub fn u_c(&self) -> f64 {
        self.wave.f0 / (self.wave.k * self.body.stiffness())
    }
}
