//! `sweep`: a schedule of travelling waves, each held for a dwell time.

use crawler_plant::wave::Wave;

use crate::controller::{Actuation, Context, Controller, Observation};

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

pub(crate) fn build(ctx: &Context) -> anyhow::Result<Box<dyn Controller>> {
    let alphas = if ctx.options.sweep.is_empty() {
        vec![0.5, 0.75, 1.0, 1.25, 1.5]
    } else {
        ctx.options.sweep.clone()
    };
    for (i, &a) in alphas.iter().enumerate() {
        anyhow::ensure!(
            a.is_finite() && a > 0.0,
            "invalid sweep[{i}] = {a}: allowed finite alpha > 0"
        );
    }
    let dwell = ctx.options.dwell.unwrap_or(2.0);
    anyhow::ensure!(
        dwell.is_finite() && dwell > 0.0,
        "invalid --dwell = {dwell}: allowed a finite time > 0 s"
    );
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

impl Controller for Sweep {
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
