//! The open-loop waves that never change: `wave` (from flags or the scenario) and `resonance`
//! (the same at the undamped natural frequency of the wave's mode). `optimal` applies its
//! optimum the same way (`super::optimal`).

use crawler_physics::wave::Wave;

use crate::params::Params;
use crate::policy::{Context, Policy};
use crawler_physics::execution::{Actuation, Observation};

/// Always the same travelling wave.
#[derive(Debug, Clone)]
pub struct FixedWave {
    /// The policy's registered name.
    pub name: &'static str,
    /// The wave.
    pub wave: Wave,
    /// How omega was chosen, for [`Controller::describe`] (`""`: as given).
    pub omega_note: &'static str,
}

impl FixedWave {
    /// The policy `name` applying `wave`, refused if the wave does not fit the body of `ctx`.
    fn fitted(
        name: &'static str,
        wave: Wave,
        omega_note: &'static str,
        ctx: &Context,
    ) -> anyhow::Result<Box<dyn Policy>> {
        wave.validate_for_body(ctx.length, ctx.cells, ctx.boundary)?;
        Ok(Box::new(FixedWave {
            name,
            wave,
            omega_note,
        }))
    }
}

/// `wave`: f0, k and omega from the flags or the scenario.
pub(crate) fn build(ctx: &Context, params: &Params) -> anyhow::Result<Box<dyn Policy>> {
    params.reader("wave", &[]).finish()?;
    FixedWave::fitted("wave", ctx.wave(), "", ctx)
}

/// `resonance`: `omega = omega_n = k sqrt(A_c E / rho)` for the wave's k.
pub(crate) fn build_resonance(ctx: &Context, params: &Params) -> anyhow::Result<Box<dyn Policy>> {
    params.reader("resonance", &[]).finish()?;
    let base = ctx.wave();
    let wave = Wave {
        omega: base.k * ctx.body.wave_speed(),
        ..base
    };
    FixedWave::fitted("resonance", wave, "omega_n = ", ctx)
}

impl Policy for FixedWave {
    fn name(&self) -> &str {
        self.name
    }

    fn act(&mut self, _obs: &Observation) -> Actuation {
        Actuation::Wave(self.wave)
    }

    fn describe(&self) -> String {
        let w = self.wave;
        format!(
            "{}: f0 = {} N, k = {:.4} rad/m, omega = {}{:.4} rad/s",
            self.name, w.f0, w.k, self.omega_note, w.omega
        )
    }
}
