//! `wave`: a fixed travelling wave.

use crawler_plant::wave::Wave;

use crate::controller::{Actuation, Context, Controller, Observation};

/// Always the same travelling wave.
#[derive(Debug, Clone)]
pub struct FixedWave {
    /// The wave.
    pub wave: Wave,
}

pub(crate) fn build(ctx: &Context) -> anyhow::Result<Box<dyn Controller>> {
    let wave = ctx.wave();
    wave.validate_for_body(ctx.length, ctx.cells, ctx.boundary)?;
    Ok(Box::new(FixedWave { wave }))
}

impl Controller for FixedWave {
    fn name(&self) -> &str {
        "wave"
    }

    fn act(&mut self, _obs: &Observation) -> Actuation {
        Actuation::Wave(self.wave)
    }

    fn describe(&self) -> String {
        let w = self.wave;
        format!(
            "wave: f0 = {} N, k = {:.4} rad/m, omega = {:.4} rad/s",
            w.f0, w.k, w.omega
        )
    }
}
