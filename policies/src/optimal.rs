//! `optimal`: the constrained optimal open-loop wave for this plant's body.
//!
//! The optimiser maximises the improved model's speed under the task's mileage and stress and
//! the limits' strain and amplitude, with `k` restricted to the wave numbers that fit the body.
//! Its answer is then certified on the task ([`crate::certify`]): the plant the controller is
//! told, driven from rest by the wave, must travel `D` within `J0` and every limit with the
//! margin; the amplitude is lowered until it does. The verdict does not depend on the
//! scenario's `t_end`.
//!
//! When the pipe is disclosed with a friction map (the oracle of `crawler compare`: the
//! open-loop optimum given the true pipe), the optimiser is given the map's mean friction over
//! the way the body will touch (`eps` and `eps n_F` averaged over `[start, start + L + D]`) and
//! the certification drives the plant in the mapped pipe.

use crawler_physics::params::Friction;
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
    /// Plant runs that certified the task, if asked for.
    pub certification: Option<crate::certify::TaskCertification>,
    /// The friction the optimiser was given.
    pub friction: Friction,
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
        doc: "true (default): lower f0 until the task holds on the in-process plant from rest",
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

/// The friction the optimiser is given for the pipe of `ctx`: the told friction, or with a
/// disclosed friction map its mean over the way the body will touch.
pub fn planning_friction(ctx: &Context) -> Friction {
    let p = &ctx.scenario.plant;
    if !p.pipe.disclose || p.pipe.is_uniform() {
        return ctx.friction;
    }
    let map = p.friction_map();
    let from = p.pipe.start;
    let to = from + ctx.length + ctx.scenario.task.distance.max(0.0);
    let n = (((to - from) / 1e-3).ceil() as usize).clamp(1, 1 << 20);
    let (mut eps, mut eps_nf) = (0.0, 0.0);
    for i in 0..n {
        let (e, nf) = map.at(from + (i as f64 + 0.5) * (to - from) / n as f64);
        eps += e;
        eps_nf += e * nf;
    }
    Friction {
        eps: eps / n as f64,
        n_f: if eps > 0.0 {
            eps_nf / eps
        } else {
            ctx.friction.n_f
        },
        ..ctx.friction
    }
}

/// The optimum for the plant of `ctx` (certified on the task on the in-process plant unless
/// `opts` says not to).
pub fn plan(ctx: &Context, opts: &OptimalOptions) -> anyhow::Result<Optimal> {
    let friction = planning_friction(ctx);
    let problem = Problem {
        body: ctx.body,
        friction,
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
    // Make the task hold on a plant like the one driven (same body, grid and step, from rest),
    // not only in the model: lower f0 with a few in-process task runs until it holds with a
    // margin.
    let certification = if opts.certify {
        let horizon = crate::certify::horizon(&ctx.scenario, o.prediction.velocity);
        // Not certified within the runs (a limit the plant breaks from rest for every f0 tried,
        // e.g. a stress limit below the start-up transient): the lowest f0 tried is applied and
        // the description says so; the task's outcome then tells what happened.
        let c = crate::certify::certify(&ctx.scenario, wave, opts.margin, horizon, 8)?;
        wave.f0 = c.f0;
        Some(c)
    } else {
        None
    };
    Ok(Optimal {
        report,
        wave,
        certification,
        friction,
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
            "optimal ({} model, eps = {:.4}, n_F = {:.4}): f0 = {:.4} N, k = {:.4} rad/m, omega = {:.4} rad/s (alpha = {:.3}), binding: {:?}, predicted V = {:.4e} m/s",
            self.report.model,
            self.friction.eps,
            self.friction.n_f,
            o.f0,
            o.k,
            o.omega,
            o.alpha,
            o.binding,
            o.prediction.velocity.unwrap_or(f64::NAN)
        ) + &match &self.certification {
            Some(c) if !c.certified => format!(
                "; NOT certified on the task from rest ({} plant runs of up to {:.0} s broke a limit or the task with {:.1} % margin): the lowest f0 tried, {:.5} N, is applied",
                c.runs.len(),
                c.horizon,
                100.0 * c.margin,
                c.f0
            ),
            Some(c) => format!(
                "; certified on the task from rest ({} plant runs of up to {:.0} s): f0 = {:.5} N travels D on {:.4} J, every limit with {:.1} % margin",
                c.runs.len(),
                c.horizon,
                c.f0,
                c.certified_run().map_or(f64::NAN, |r| r.energy),
                100.0 * c.margin
            ),
            None => "; not certified on the plant".to_string(),
        }
    }
}
