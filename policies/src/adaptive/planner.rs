//! The robust re-plan: the improved model's constrained optimum at the estimated friction, for
//! what is left of the task, with margins that hold the constraints under the estimate's
//! uncertainty and the model's error.
//!
//! For a candidate gait `g` the model gives `V`, `P = V / M` and `sigma` at the estimate
//! `theta^`. What the plant showed under the gait being applied corrects them (`c_V`, `c_P`,
//! `c_sigma`: plant over model there, a zero-order modifier as in modifier adaptation), and the
//! bounds the plan must keep are
//!
//! ```text
//! M_lo     = c_M M(g; theta^)         (1 - kappa s_M(g) - m)      c_M = c_V / c_P
//! V_lo     = c_V V(g; theta^)         (1 - kappa s_V(g) - m)
//! sigma_hi = c_sigma sigma(g; theta^) (1 + kappa s_sigma(g) + m)
//! ```
//!
//! with `s_X(g)^2 = grad(ln X)' Sigma grad(ln X)` the relative variance the estimate's covariance
//! `Sigma` gives the metric at `g` (the gradient by finite differences of the model in `theta`),
//! `kappa` standard deviations (2 by default: a one-sided 97.7 % chance bound if the estimate is
//! Gaussian and consistent) and `m` the model's own error after the correction (3 %). The plan is
//! the fastest gait with `M_lo >= d_rem / E_av` and `sigma_hi <= (1 - m_sigma) sigma_max`: the
//! optimiser is run with the budget and the stress limit tightened by the margins found at the
//! previous answer, three times at most, until the answer keeps its own margins. When no gait
//! does, the plan is the gait of the largest `M_lo` the optimiser finds (bisection on the
//! budget), said to be short of the task.

use std::time::Instant;

use crawler_models::operating_point::OperatingPoint;
use crawler_models::optimizer::{BodyLength, GridSpec, ModelChoice, Problem};
use crawler_models::prediction::{Model, Prediction};
use crawler_models::travelling_wave::TravellingWaveModel;
use crawler_physics::params::{Body, Boundary, Friction};
use crawler_physics::scenario::{Limits, Task};
use crawler_physics::wave::Wave;

/// What does not change during a run: the problem the worker solves.
#[derive(Debug, Clone, Copy)]
pub struct Setting {
    /// Body material.
    pub body: Body,
    /// The task.
    pub task: Task,
    /// The optimiser's limits.
    pub limits: Limits,
    /// Body length, m.
    pub length: f64,
    /// Periodic body or free ends.
    pub boundary: Boundary,
    /// Cells.
    pub cells: usize,
    /// Grid points per axis.
    pub grid: usize,
    /// Standard deviations of the margins.
    pub kappa: f64,
    /// The model's relative error after the correction.
    pub model_margin: f64,
    /// Relative margin kept below `sigma_max`.
    pub stress_margin: f64,
}

/// The estimate as the planner needs it.
#[derive(Debug, Clone, Copy)]
pub struct Belief {
    /// `theta = (c_v, eps c_d, eps c_d n_F)`.
    pub theta: [f64; 3],
    /// Its covariance.
    pub cov: [[f64; 3]; 3],
    /// The told friction (its `c_d`, and a fallback).
    pub told: Friction,
}

impl Belief {
    /// The friction law of `theta` (eps >= 0, n_F in [0, 1]).
    pub fn friction(&self, theta: [f64; 3]) -> Friction {
        let cd = self.told.dry;
        let eps = (theta[1] / cd).max(0.0);
        Friction {
            viscous: theta[0].max(1e-6 * self.told.viscous),
            dry: cd,
            eps,
            n_f: if theta[1] > 1e-12 * cd {
                (theta[2] / theta[1]).clamp(0.0, 1.0)
            } else {
                self.told.n_f
            },
        }
    }
}

/// What the worker is asked.
#[derive(Debug, Clone, Copy)]
pub struct Job {
    /// Request number.
    pub id: u64,
    /// The estimate.
    pub belief: Belief,
    /// The gait being applied.
    pub wave: Wave,
    /// Speed (m/s), power (W) and largest stress (Pa) the plant showed under it, if measured.
    pub measured: Option<[f64; 3]>,
    /// Distance left, m.
    pub distance: f64,
    /// Energy the plan may count on, J.
    pub energy: f64,
}

/// A gait with its predicted bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// The gait (phase 0).
    pub wave: Wave,
    /// Corrected speed at the estimate, m/s.
    pub speed: f64,
    /// Its lower bound, m/s.
    pub speed_lo: f64,
    /// Corrected power at the estimate, W.
    pub power: f64,
    /// Corrected mileage at the estimate and its lower bound, m/J.
    pub mileage: f64,
    /// Lower bound of the mileage, m/J.
    pub mileage_lo: f64,
    /// Upper bound of the power, W (`speed_lo / mileage_lo` would be below it).
    pub power_hi: f64,
    /// Upper bound of the largest stress, Pa.
    pub stress_hi: f64,
    /// True if `mileage_lo` covers the distance on the energy and the stress bound holds.
    pub finishes: bool,
}

/// The worker's answer.
#[derive(Debug, Clone)]
pub struct Decision {
    /// Request number.
    pub id: u64,
    /// The plan, if any.
    pub candidate: Option<Candidate>,
    /// The model's prediction for it (corrected), for the recorder.
    pub prediction: Option<Prediction>,
    /// What was done, in words.
    pub text: String,
    /// Wall time of the solve, s.
    pub seconds: f64,
}

fn rel_std(grad: &[f64; 3], cov: &[[f64; 3]; 3]) -> f64 {
    let mut v = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            v += grad[i] * cov[i][j] * grad[j];
        }
    }
    v.max(0.0).sqrt()
}

impl Setting {
    fn point(&self, friction: Friction, w: Wave) -> OperatingPoint {
        OperatingPoint {
            body: self.body,
            friction,
            wave: w,
            wavelengths: (w.k * self.length / std::f64::consts::TAU).round().max(1.0),
        }
    }

    /// `[V, P, sigma]` of the model at `theta`, if it answers.
    fn metrics(
        &self,
        model: &TravellingWaveModel,
        b: &Belief,
        theta: [f64; 3],
        w: Wave,
    ) -> Option<[f64; 3]> {
        let p = model.predict(&self.point(b.friction(theta), w));
        match (p.velocity, p.power, p.max_stress) {
            (Some(v), Some(pw), Some(s)) if v > 0.0 && pw > 0.0 && s > 0.0 => Some([v, pw, s]),
            _ => None,
        }
    }

    /// Relative standard deviations of `V`, `M` and `sigma` at `w` under the belief's covariance.
    fn spreads(&self, model: &TravellingWaveModel, b: &Belief, w: Wave) -> Option<[f64; 3]> {
        let base = self.metrics(model, b, b.theta, w)?;
        let mut grads = [[0.0; 3]; 3]; // [metric][parameter] of ln V, ln M, ln sigma
        for j in 0..3 {
            let sd = b.cov[j][j].max(0.0).sqrt();
            let h = (0.5 * sd).max(1e-6 * b.theta[j].abs().max(1e-6));
            let mut up = b.theta;
            up[j] += h;
            let mut dn = b.theta;
            dn[j] -= h;
            let (Some(a), Some(c)) = (self.metrics(model, b, up, w), self.metrics(model, b, dn, w))
            else {
                // one-sided near a boundary of the model's validity
                let a = self.metrics(model, b, up, w).unwrap_or(base);
                for (m, lnx) in [
                    (0, a[0].ln() - base[0].ln()),
                    (1, (a[0] / a[1]).ln() - (base[0] / base[1]).ln()),
                    (2, a[2].ln() - base[2].ln()),
                ] {
                    grads[m][j] = lnx / h;
                }
                continue;
            };
            for (m, lnx) in [
                (0, a[0].ln() - c[0].ln()),
                (1, (a[0] / a[1]).ln() - (c[0] / c[1]).ln()),
                (2, a[2].ln() - c[2].ln()),
            ] {
                grads[m][j] = lnx / (2.0 * h);
            }
        }
        Some([
            rel_std(&grads[0], &b.cov),
            rel_std(&grads[1], &b.cov),
            rel_std(&grads[2], &b.cov),
        ])
    }

    /// The candidate `w` with its bounds under corrections `c = [c_V, c_P, c_sigma]`.
    pub fn candidate(
        &self,
        model: &TravellingWaveModel,
        b: &Belief,
        c: [f64; 3],
        w: Wave,
        distance: f64,
        energy: f64,
    ) -> Option<Candidate> {
        let [v, p, s] = self.metrics(model, b, b.theta, w)?;
        let [sv, sm, ss] = self.spreads(model, b, w)?;
        let (k, m) = (self.kappa, self.model_margin);
        let speed = c[0] * v;
        let power = c[1] * p;
        let mileage = speed / power;
        let speed_lo = speed * (1.0 - k * sv - m).max(0.0);
        let mileage_lo = mileage * (1.0 - k * sm - m).max(0.0);
        let stress_hi = c[2] * s * (1.0 + k * ss + m);
        let power_hi = if mileage_lo > 0.0 {
            (speed / mileage_lo).max(power)
        } else {
            f64::INFINITY
        };
        Some(Candidate {
            wave: w,
            speed,
            speed_lo,
            power,
            mileage,
            mileage_lo,
            power_hi,
            stress_hi,
            finishes: mileage_lo * energy >= distance
                && stress_hi <= (1.0 - self.stress_margin) * self.task.sigma_max,
        })
    }

    /// The corrections `[c_V, c_P, c_sigma]` of the plant over the model at the gait applied.
    fn corrections(&self, model: &TravellingWaveModel, job: &Job) -> [f64; 3] {
        let mut c = [1.0; 3];
        if let (Some(m), Some(q)) = (
            job.measured,
            self.metrics(model, &job.belief, job.belief.theta, job.wave),
        ) {
            for i in 0..3 {
                if m[i] > 0.0 && m[i].is_finite() {
                    c[i] = (m[i] / q[i]).clamp(0.25, 4.0);
                }
            }
        }
        c
    }

    /// The optimiser's answer for a budget `energy` (J, model units) and stress limit
    /// `sigma_max` (Pa, model units), if feasible and fitting the body.
    fn optimum(
        &self,
        model: &TravellingWaveModel,
        friction: Friction,
        distance: f64,
        energy: f64,
        sigma_max: f64,
    ) -> Result<Wave, String> {
        let problem = Problem {
            body: self.body,
            friction,
            task: Task {
                distance,
                energy,
                sigma_max,
                ..self.task
            },
            limits: self.limits,
            body_length: BodyLength::Fixed(self.length),
        };
        let r = problem
            .optimize(
                &ModelChoice::Improved(*model),
                &GridSpec::new(self.grid, self.grid),
            )
            .map_err(|e| format!("{e}"))?;
        let o = r.optimum;
        let w = Wave {
            f0: o.f0,
            k: o.k,
            omega: o.omega,
            phase: 0.0,
        };
        w.validate_for_body(self.length, self.cells, self.boundary)
            .map_err(|e| format!("the optimum does not fit the body ({e})"))?;
        Ok(w)
    }

    /// Solves `job` (see the module documentation).
    pub fn solve(&self, job: &Job) -> Decision {
        let started = Instant::now();
        let model = TravellingWaveModel::default();
        let b = &job.belief;
        let c = self.corrections(&model, job);
        let friction = b.friction(b.theta);
        let mut text = format!(
            "re-plan #{}: {:.4} m left on {:.4} J; plant/model under the current gait: V x{:.4}, P x{:.4}, sigma x{:.4}",
            job.id, job.distance, job.energy, c[0], c[1], c[2]
        );
        let done = |candidate: Option<Candidate>, text: String| {
            let prediction = candidate.map(|cand| {
                let mut p = model.predict(&self.point(friction, cand.wave));
                p.model = "estimated";
                p.velocity = Some(cand.speed);
                p.power = Some(cand.power);
                p.mileage = Some(cand.mileage);
                p.max_stress = p.max_stress.map(|x| x * c[2]);
                p
            });
            Decision {
                id: job.id,
                candidate,
                prediction,
                text,
                seconds: started.elapsed().as_secs_f64(),
            }
        };
        if job.distance <= 0.0 || job.energy <= 0.0 {
            text += "; nothing to plan (distance reached or no energy left)";
            return done(None, text);
        }
        let plan = Replan {
            setting: self,
            model: &model,
            job,
            c,
            friction,
            sigma_cap: (1.0 - self.stress_margin) * self.task.sigma_max,
        };
        let Tightened {
            best,
            last_err,
            d_s,
        } = plan.tightened();
        if let Some(cand) = best.filter(|c| c.finishes) {
            text += &describe(&cand, "new gait");
            return done(Some(cand), text);
        }
        // no gait finishes by the bounds: the gait of the largest mileage bound the optimiser
        // reaches, at the smallest budget it still answers for (bisection)
        let found = plan.largest_mileage(best, d_s);
        match found {
            Some(cand) => {
                text += &format!(
                    "; no gait finishes within the bounds ({}): the gait of the largest mileage bound found",
                    if last_err.is_empty() { "margins not met".to_string() } else { last_err }
                );
                text += &describe(&cand, "gait");
                done(Some(cand), text)
            }
            None => {
                text += &format!("; no feasible gait ({last_err})");
                done(None, text)
            }
        }
    }
}

/// One re-plan's fixed inputs: the problem, the model, the job, the corrections and the
/// estimated friction.
struct Replan<'a> {
    /// The problem the worker solves.
    setting: &'a Setting,
    /// The model the optimiser uses.
    model: &'a TravellingWaveModel,
    /// The request.
    job: &'a Job,
    /// Corrections `[c_V, c_P, c_sigma]` of the plant over the model (dimensionless).
    c: [f64; 3],
    /// The friction law at the estimate.
    friction: Friction,
    /// The stress the plan may reach, `(1 - m_sigma) sigma_max`, Pa.
    sigma_cap: f64,
}

/// The optimiser's answer under margins tightened until it keeps its own.
struct Tightened {
    /// The last answer, if the optimiser and the model gave one.
    best: Option<Candidate>,
    /// Why the last try failed (empty if none did).
    last_err: String,
    /// The last relative stress margin used (dimensionless).
    d_s: f64,
}

impl Replan<'_> {
    /// Runs the optimiser with the budget and the stress limit tightened by the margins found
    /// at the previous answer, three times at most, until the answer finishes by its bounds.
    fn tightened(&self) -> Tightened {
        let (model, job, c) = (self.model, self.job, self.c);
        let b = &job.belief;
        // margins start from those of the gait applied, then from each answer's own
        let (mut d_m, mut d_s) = match self.setting.spreads(model, b, job.wave) {
            Some([_, sm, ss]) => (
                self.setting.kappa * sm + self.setting.model_margin,
                self.setting.kappa * ss + self.setting.model_margin,
            ),
            None => (self.setting.model_margin, self.setting.model_margin),
        };
        let mut last_err = String::new();
        let mut best: Option<Candidate> = None;
        for _ in 0..3 {
            let energy = job.energy * (c[0] / c[1]) * (1.0 - d_m).max(0.05);
            let sigma = self.sigma_cap / (c[2] * (1.0 + d_s));
            match self
                .setting
                .optimum(model, self.friction, job.distance, energy, sigma)
            {
                Ok(w) => {
                    let Some(cand) =
                        self.setting
                            .candidate(model, b, c, w, job.distance, job.energy)
                    else {
                        last_err = "the model has no prediction at the optimum".into();
                        break;
                    };
                    best = Some(cand);
                    if cand.finishes {
                        break;
                    }
                    let [_, sm, ss] = self.setting.spreads(model, b, w).unwrap_or([0.0; 3]);
                    d_m = d_m.max(self.setting.kappa * sm + self.setting.model_margin) + 0.01;
                    d_s = d_s.max(self.setting.kappa * ss + self.setting.model_margin) + 0.01;
                }
                Err(e) => {
                    last_err = e;
                    break;
                }
            }
        }
        Tightened {
            best,
            last_err,
            d_s,
        }
    }

    /// The candidate the optimiser gives for the budget `e` (J, model units) under the stress
    /// margin `d_s` (relative), if any.
    fn try_budget(&self, e: f64, d_s: f64) -> Option<Candidate> {
        let sigma = self.sigma_cap / (self.c[2] * (1.0 + d_s));
        let w = self
            .setting
            .optimum(self.model, self.friction, self.job.distance, e, sigma)
            .ok()?;
        self.setting.candidate(
            self.model,
            &self.job.belief,
            self.c,
            w,
            self.job.distance,
            self.job.energy,
        )
    }

    /// The candidate of the largest mileage bound among `best` and the optimiser's answers at
    /// the budgets it still answers for, down to the smallest (bisection), under the stress
    /// margin `d_s` (relative).
    fn largest_mileage(&self, best: Option<Candidate>, d_s: f64) -> Option<Candidate> {
        let (job, c) = (self.job, self.c);
        let try_budget = |e: f64| self.try_budget(e, d_s);
        let mut found = best;
        let start = job.energy * c[0] / c[1];
        let (mut lo, mut hi) = (None, None);
        if let Some(cand) = try_budget(start) {
            found = better(found, Some(cand));
            hi = Some(start);
            let mut e = start;
            for _ in 0..12 {
                e *= 0.5;
                match try_budget(e) {
                    Some(cand) => {
                        found = better(found, Some(cand));
                        hi = Some(e);
                    }
                    None => {
                        lo = Some(e);
                        break;
                    }
                }
            }
        } else {
            lo = Some(start);
            let mut e = start;
            for _ in 0..12 {
                e *= 2.0;
                if let Some(cand) = try_budget(e) {
                    found = better(found, Some(cand));
                    hi = Some(e);
                    break;
                }
                lo = Some(e);
            }
        }
        if let (Some(mut lo), Some(mut hi)) = (lo, hi) {
            for _ in 0..8 {
                let mid = 0.5 * (lo + hi);
                match try_budget(mid) {
                    Some(cand) => {
                        found = better(found, Some(cand));
                        hi = mid;
                    }
                    None => lo = mid,
                }
            }
        }
        found
    }
}

fn better(a: Option<Candidate>, b: Option<Candidate>) -> Option<Candidate> {
    match (a, b) {
        (Some(x), Some(y)) => Some(if y.mileage_lo > x.mileage_lo { y } else { x }),
        (x, None) => x,
        (None, y) => y,
    }
}

fn describe(c: &Candidate, what: &str) -> String {
    let w = c.wave;
    format!(
        "; {what} f0 = {:.5} N, k = {:.4} rad/m, omega = {:.4} rad/s: V = {:.4e} m/s (>= {:.4e}), M = {:.4e} m/J (>= {:.4e}), sigma <= {:.4e} Pa",
        w.f0, w.k, w.omega, c.speed, c.speed_lo, c.mileage, c.mileage_lo, c.stress_hi
    )
}
