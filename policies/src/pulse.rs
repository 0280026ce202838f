//! `pulse`: the scenario's wave, switched on and off every second (an intermittent gait).

use crate::{Actuation, Context, Observation, Params, Policy, Wave};

/// The wave during even seconds, no muscle force during odd ones.
pub struct Pulse {
    wave: Wave,
    cells: usize,
}

pub(crate) fn build(ctx: &Context, params: &Params) -> anyhow::Result<Box<dyn Policy>> {
    params.reader("pulse", &[]).finish()?;
    let wave = ctx.wave();
    wave.validate_for_body(ctx.length, ctx.cells, ctx.boundary)?;
    Ok(Box::new(Pulse {
        wave,
        cells: ctx.cells,
    }))
}

impl Policy for Pulse {
    fn name(&self) -> &str {
        "pulse"
    }

    fn act(&mut self, obs: &Observation) -> Actuation {
        if (obs.time as u64).is_multiple_of(2) {
            Actuation::Wave(self.wave)
        } else {
            Actuation::Field(vec![0.0; self.cells])
        }
    }
}
