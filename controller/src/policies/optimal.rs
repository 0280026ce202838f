//! `optimal`: the constrained optimal open-loop wave for this plant's body.

use crawler_plant::wave::Wave;

use crate::controller::{Actuation, Context, Controller, Observation};
use crate::optimizer::{
    BodyLength, GridSpec, ModelChoice, OptimizeReport, Problem, DEFAULT_TIE_TOLERANCE,
};
use crate::travelling_wave::TravellingWaveModel;

/// The wave that maximises the predicted speed under the scenario's task and limits, with `k`
/// restricted to the wave numbers that fit the plant's body.
#[derive(Debug, Clone)]
pub struct Optimal {
    /// The optimiser's result.
    pub report: OptimizeReport,
    wave: Wave,
    /// Plant runs that certified the constraints, if asked for.
    pub certification: Option<crate::verify::Certification>,
}

pub(crate) fn build(ctx: &Context) -> anyhow::Result<Box<dyn Controller>> {
    Ok(Box::new(plan(ctx)?))
}

/// The optimum for the plant of `ctx` (certified on the in-process plant unless the options say
/// not to).
pub(crate) fn plan(ctx: &Context) -> anyhow::Result<Optimal> {
    let problem = Problem {
        body: ctx.body,
        friction: ctx.friction,
        task: ctx.scenario.task,
        limits: ctx.scenario.limits,
        body_length: BodyLength::Fixed(ctx.length),
    };
    let model = ctx
        .options
        .model
        .unwrap_or(ModelChoice::Improved(TravellingWaveModel::default()));
    let n = ctx
        .options
        .grid
        .unwrap_or(if matches!(model, ModelChoice::Paper) {
            400
        } else {
            48
        });
    let report = problem.optimize(
        &model,
        &GridSpec {
            omega_points: n,
            k_points: n,
            refine: true,
            tie_tolerance: DEFAULT_TIE_TOLERANCE,
        },
    )?;
    let o = &report.optimum;
    let mut wave = Wave {
        f0: o.f0,
        k: o.k,
        omega: o.omega,
        phase: 0.0,
    };
    wave.validate_for_body(ctx.length, ctx.cells, ctx.boundary)?;
    // Make the constraints hold on a plant like the one driven (same body, grid and step), not
    // only in the model: lower f0 with a few in-process plant runs until they hold with a margin.
    let certification = if ctx.options.certify {
        let c = crate::verify::certify(&ctx.scenario, &problem, o, ctx.options.margin, 8)?;
        anyhow::ensure!(
            c.certified,
            "the optimum could not be certified on the plant within {} runs (last f0 = {} N)",
            c.runs.len(),
            c.f0
        );
        wave.f0 = c.f0;
        Some(c)
    } else {
        None
    };
    Ok(Optimal {
        report,
        wave,
        certification,
    })
}

impl Optimal {
    /// The wave it applies.
    pub fn wave(&self) -> Wave {
        self.wave
    }
}

impl Controller for Optimal {
    fn name(&self) -> &str {
        "optimal"
    }

    fn act(&mut self, _obs: &Observation) -> Actuation {
        Actuation::Wave(self.wave)
    }

    fn describe(&self) -> String {
        let o = &self.report.optimum;
        format!(
            "optimal ({} model): f0 = {:.4} N, k = {:.4} rad/m, omega = {:.4} rad/s (alpha = {:.3}), binding: {:?}, predicted V = {:.4e} m/s",
            self.report.model,
            o.f0,
            o.k,
            o.omega,
            o.alpha,
            o.binding,
            o.prediction.velocity.unwrap_or(f64::NAN)
        ) + &match &self.certification {
            Some(c) => format!(
                "; certified on the plant ({} runs): f0 = {:.4} N holds every constraint with {:.1} % margin",
                c.runs.len(),
                c.f0,
                100.0 * c.margin
            ),
            None => "; not certified on the plant".to_string(),
        }
    }
}
