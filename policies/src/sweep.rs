//! `sweep`: a schedule of travelling waves, each held for a dwell time.

use crawler_physics::wave::Wave;

use crate::params::{Key, Params};
use crate::policy::{Context, Policy};
use crawler_physics::execution::{Actuation, Observation};

/// Visits `alphas` in turn, `dwell` seconds each, then holds the last. The phase is carried over
/// at each switch so the muscle force does not jump.
#[derive(Debug, Clone)]
pub struct Sweep {
    base: Wave,
    omega_n: f64,
    alphas: Vec<f64>,
    dwell: f64,
    current: usize,
    wave: Wave,
}

/// The parameters of the sweep policy (`--param KEY=VALUE`).
pub const KEYS: [Key; 2] = [
    Key {
        name: "alphas",
        doc: "the frequency ratios omega / omega_n visited in turn, separated by commas (default 0.5,0.75,1,1.25,1.5)",
    },
    Key {
        name: "dwell",
        doc: "seconds spent at each, > 0 (default 2)",
    },
];

/// The alphas and the dwell time of `params`.
fn options(params: &Params) -> anyhow::Result<(Vec<f64>, f64)> {
    let r = params.reader("sweep", &KEYS);
    let alphas = r
        .numbers("alphas", 1e-6, 1e6)?
        .unwrap_or_else(|| vec![0.5, 0.75, 1.0, 1.25, 1.5]);
    let dwell = r.number("dwell", 1e-9, 1e9)?.unwrap_or(2.0);
    r.finish()?;
    Ok((alphas, dwell))
}

/// Checks the parameters of the sweep policy.
pub(crate) fn check(params: &Params) -> anyhow::Result<()> {
    options(params).map(|_| ())
}

pub(crate) fn build(ctx: &Context, params: &Params) -> anyhow::Result<Box<dyn Policy>> {
    let (alphas, dwell) = options(params)?;
    let base = ctx.wave();
    let omega_n = base.k * ctx.body.wave_speed();
    let wave = Wave {
        omega: alphas[0] * omega_n,
        ..base
    };
    wave.validate_for_body(ctx.length, ctx.cells, ctx.boundary)?;
    Ok(Box::new(Sweep {
        base,
        omega_n,
        alphas,
        dwell,
        current: 0,
        wave,
    }))
}

impl Policy for Sweep {
    fn name(&self) -> &str {
        "sweep"
    }

    fn act(&mut self, obs: &Observation) -> Actuation {
        let target = ((obs.time / self.dwell).floor().max(0.0) as usize).min(self.alphas.len() - 1);
        if target != self.current {
            let omega = self.alphas[target] * self.omega_n;
            // keep the phase of the muscle force continuous at the switch: (w_new - w_old) t
            let phase = self.wave.phase + (omega - self.wave.omega) * obs.time;
            self.wave = Wave {
                omega,
                phase: phase.rem_euclid(std::f64::consts::TAU),
                ..self.base
            };
            self.current = target;
        }
        Actuation::Wave(self.wave)
    }

    fn describe(&self) -> String {
        format!(
            "sweep: alpha = {:?}, {} s each (omega_n = {:.3} rad/s)",
            self.alphas, self.dwell, self.omega_n
        )
    }
}
