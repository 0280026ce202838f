//! `optimal`: the constrained optimal open-loop wave for this plant's body.

use crawler_physics::wave::Wave;

use crate::params::{Key, Params};
use crate::policy::{Context, Policy};
use crawler_models::optimizer::{
    BodyLength, GridSpec, ModelChoice, OptimizeReport, Problem, DEFAULT_TIE_TOLERANCE,
};
use crawler_models::travelling_wave::TravellingWaveModel;
use crawler_physics::execution::{Actuation, Observation};

/// The wave that maximises the predicted speed under the scenario's task and limits, with `k`
/// restricted to the wave numbers that fit the plant's body.
#[derive(Debug, Clone)]
pub struct Optimal {
    /// The optimiser's result.
    pub report: OptimizeReport,
    wave: Wave,
    /// Plant runs that certified the constraints, if asked for.
    pub certification: Option<crawler_models::verify::Certification>,
}

/// The parameters of the optimal policy (`--param KEY=VALUE`).
pub const KEYS: [Key; 4] = [
    Key {
        name: "model",
        doc: "the model optimised: improved (default) or paper",
    },
    Key {
        name: "grid",
        doc: "grid points per axis of the search (default 48 for improved, 400 for paper)",
    },
    Key {
        name: "certify",
        doc: "true (default): lower f0 until every constraint holds on the in-process plant",
    },
    Key {
        name: "margin",
        doc: "relative margin the certification keeps on every constraint, 0 <= margin < 0.5 (default 0.005)",
    },
];

/// The optimal policy's options.
#[derive(Debug, Clone, Copy)]
pub struct OptimalOptions {
    /// The model optimised.
    pub model: ModelChoice,
    /// Grid points per axis.
    pub grid: usize,
    /// Certify the constraints on the in-process plant, lowering f0 if needed.
    pub certify: bool,
    /// Relative margin of the certification.
    pub margin: f64,
}

impl Default for OptimalOptions {
    fn default() -> Self {
        Self {
            model: ModelChoice::Improved(TravellingWaveModel::default()),
            grid: 48,
            certify: true,
            margin: crawler_models::verify::DEFAULT_MARGIN,
        }
    }
}

impl OptimalOptions {
    /// The defaults with the settings of `params` (each checked; an unknown key refused).
    pub fn from_params(params: &Params) -> anyhow::Result<Self> {
        let r = params.reader("optimal", &KEYS);
        let mut me = Self::default();
        if r.word("model", &["improved", "paper"])? == Some("paper") {
            me.model = ModelChoice::Paper;
            me.grid = 400;
        }
        if let Some(n) = r.count("grid", 2, 4096)? {
            me.grid = n;
        }
        if let Some(c) = r.switch("certify")? {
            me.certify = c;
        }
        if let Some(m) = r.finite("margin")? {
            crawler_models::verify::check_margin("parameter margin of policy optimal", m)?;
            me.margin = m;
        }
        r.finish()?;
        Ok(me)
    }
}

pub(crate) fn build(ctx: &Context, params: &Params) -> anyhow::Result<Box<dyn Policy>> {
    Ok(Box::new(plan(ctx, &OptimalOptions::from_params(params)?)?))
}

/// The optimum for the plant of `ctx` (certified on the in-process plant unless `opts` says
/// not to).
pub fn plan(ctx: &Context, opts: &OptimalOptions) -> anyhow::Result<Optimal> {
    let problem = Problem {
        body: ctx.body,
        friction: ctx.friction,
        task: ctx.scenario.task,
        limits: ctx.scenario.limits,
        body_length: BodyLength::Fixed(ctx.length),
    };
    let model = opts.model;
    let n = opts.grid;
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
    let certification = if opts.certify {
        let c = crawler_models::verify::certify(&ctx.scenario, &problem, o, opts.margin, 8)?;
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

impl Policy for Optimal {
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
