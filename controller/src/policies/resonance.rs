//! `resonance`: drive at the undamped natural frequency of the wave's mode.

use crawler_plant::wave::Wave;

use crate::controller::{Actuation, Context, Controller, Observation};

/// A travelling wave at `omega = omega_n = k sqrt(A_c E / rho)`.
#[derive(Debug, Clone)]
pub struct Resonance {
    /// The wave.
    pub wave: Wave,
}

pub(crate) fn build(ctx: &Context) -> anyhow::Result<Box<dyn Controller>> {
    let base = ctx.wave();
    let wave = Wave {
        omega: base.k * ctx.body.wave_speed(),
        ..base
    };
    wave.validate_for_body(ctx.length, ctx.cells, ctx.boundary)?;
    Ok(Box::new(Resonance { wave }))
}

impl Controller for Resonance {
    fn name(&self) -> &str {
        "resonance"
    }

    fn act(&mut self, _obs: &Observation) -> Actuation {
        Actuation::Wave(self.wave)
    }

    fn describe(&self) -> String {
        format!(
            "resonance: f0 = {} N, k = {:.4} rad/m, omega = omega_n = {:.4} rad/s",
            self.wave.f0, self.wave.k, self.wave.omega
        )
    }
}
