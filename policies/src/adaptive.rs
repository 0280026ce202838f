//! `adaptive`: the constrained optimum, re-solved in flight with what the plant shows.
//!
//! It starts with the open-loop optimum for the friction it was told (the `optimal` policy,
//! certified on the in-process plant) and then, every communication step,
//!
//! - feeds the plant's state to a [`FrictionEstimator`] (eps, n_F and c_v from the body's
//!   momentum and power balances, with an uncertainty);
//! - follows the task as the plant counts it: the distance the centre of mass has travelled and
//!   the actuator's net work;
//! - measures the speed, power and stress of the gait it applies once its transient has passed.
//!
//! Every [`AdaptiveOptions::replan`] seconds, and at once when the estimate moves beyond its
//! uncertainty, a worker thread re-solves the constrained optimum with the improved model at the
//! estimated friction for what is left of the task: the remaining distance on the remaining
//! energy (less a reserve), with the model's speed, power and stress scaled by what the plant
//! showed against the model's prediction for the gait being applied (which absorbs what the
//! model leaves out: free ends, a pipe whose friction varies). The answer takes effect a fixed
//! [`AdaptiveOptions::latency`] after it was asked for, so a run is reproducible step for step
//! (the in-process run equals the co-simulated one) and no step waits for the optimiser unless
//! it takes longer than that; such waits are counted and reported. The phase of the new wave is
//! chosen so that the muscle force does not jump.
//!
//! The estimates, their standard deviations, the progress and every decision are reported
//! ([`Policy::insight`]) and recorded with the run.

use std::time::Instant;

use crossbeam_channel::{bounded, Receiver, Sender};

use crawler_physics::params::{Body, Boundary, Friction};
use crawler_physics::scenario::{Limits, Task};
use crawler_physics::wave::Wave;

use crate::estimator::{Estimate, EstimatorOptions, FrictionEstimator, Sample};
use crate::params::{Key, Params};
use crate::policy::{Context, Insight, Policy};
use crawler_models::operating_point::OperatingPoint;
use crawler_models::optimizer::{BodyLength, GridSpec, ModelChoice, Problem};
use crawler_models::prediction::{Model, Prediction};
use crawler_models::travelling_wave::TravellingWaveModel;
use crawler_physics::execution::{Actuation, Observation};

/// The parameters of the adaptive policy (`--param KEY=VALUE`).
pub const KEYS: [Key; 15] = [
    Key {
        name: "replan",
        doc: "seconds between re-plans (default 2)",
    },
    Key {
        name: "latency",
        doc: "seconds of simulated time between asking the planner and applying its answer (default 1; 0 is not reproducible)",
    },
    Key {
        name: "settle",
        doc: "seconds a new gait settles before it is measured (default 1)",
    },
    Key {
        name: "reserve",
        doc: "share of the remaining energy kept in reserve when re-planning (default 0.02, below 0.5)",
    },
    Key {
        name: "trigger",
        doc: "relative change of eps (absolute of n_F) that re-plans at once when above twice its standard deviation (default 0.1)",
    },
    Key {
        name: "grid",
        doc: "grid points per axis of the re-plans' optimisation (default 16)",
    },
    Key {
        name: "report",
        doc: "seconds between reports to the recorder (default 0.5)",
    },
    Key {
        name: "window",
        doc: "communication steps per estimator window (default 32)",
    },
    Key {
        name: "memory",
        doc: "forgetting time constant of the estimator, s (default 2)",
    },
    Key {
        name: "row_tolerance",
        doc: "relative trust in each energy row (default 0.01)",
    },
    Key {
        name: "momentum_tolerance",
        doc: "relative trust in each momentum row (default 0.3)",
    },
    Key {
        name: "prior_eps_std",
        doc: "prior standard deviation of eps (default 1)",
    },
    Key {
        name: "prior_n_f_std",
        doc: "prior standard deviation of n_F (default 0.5)",
    },
    Key {
        name: "prior_viscous_rel_std",
        doc: "prior relative standard deviation of c_v (default 0.3; 0: c_v known)",
    },
    Key {
        name: "viscous_known",
        doc: "1 takes c_v as told (no prior spread)",
    },
];

/// Settings of the adaptive policy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdaptiveOptions {
    /// The friction estimator.
    pub estimator: EstimatorOptions,
    /// Seconds between re-plans.
    pub replan: f64,
    /// Seconds (of simulated time) between asking the worker and applying its answer; 0 applies
    /// answers as soon as they are ready (faster, but a run is then not reproducible).
    pub latency: f64,
    /// Seconds a new gait is left to settle before its speed and power are measured.
    pub settle: f64,
    /// Share of the remaining energy kept in reserve when re-planning.
    pub reserve: f64,
    /// Relative change of eps (or absolute change of n_F) that re-plans at once, when it exceeds
    /// twice the estimate's standard deviation.
    pub trigger: f64,
    /// Grid points per axis of the re-plans' optimisation.
    pub grid: usize,
    /// Seconds between reports to the recorder.
    pub report: f64,
}

impl Default for AdaptiveOptions {
    fn default() -> Self {
        Self {
            estimator: EstimatorOptions::default(),
            replan: 2.0,
            latency: 1.0,
            settle: 1.0,
            reserve: 0.02,
            trigger: 0.1,
            grid: 16,
            report: 0.5,
        }
    }
}

impl AdaptiveOptions {
    /// The defaults with the settings of `params` (each checked; an unknown key refused).
    pub fn from_params(params: &Params) -> anyhow::Result<Self> {
        let r = params.reader("adaptive", &KEYS);
        let mut me = Self::default();
        for (key, x) in r.finite_all()? {
            me.set(key, x)?;
        }
        r.finish()?;
        me.validate()?;
        Ok(me)
    }

    /// Sets one setting by name (`viscous_known = 1` takes c_v as told: no prior spread).
    pub fn set(&mut self, key: &str, value: f64) -> anyhow::Result<()> {
        let e = &mut self.estimator;
        match key {
            "replan" => self.replan = value,
            "latency" => self.latency = value,
            "settle" => self.settle = value,
            "reserve" => self.reserve = value,
            "trigger" => self.trigger = value,
            "grid" | "window" => {
                anyhow::ensure!(
                    (1.0..=1e6).contains(&value) && value.fract() == 0.0,
                    "invalid adaptive {key} = {value}: allowed a whole number >= 1"
                );
                if key == "grid" {
                    self.grid = value as usize;
                } else {
                    e.window = value as u32;
                }
            }
            "report" => self.report = value,
            "memory" => e.memory = value,
            "row_tolerance" => e.row_tolerance = value,
            "momentum_tolerance" => e.momentum_tolerance = value,
            "prior_eps_std" => e.prior_eps_std = value,
            "prior_n_f_std" => e.prior_n_f_std = value,
            "prior_viscous_rel_std" => e.prior_viscous_rel_std = value,
            "viscous_known" => {
                if value != 0.0 {
                    e.prior_viscous_rel_std = 0.0;
                }
            }
            _ => anyhow::bail!(
                "unknown adaptive setting {key:?}: allowed {}",
                KEYS.map(|k| k.name).join(", ")
            ),
        }
        Ok(())
    }

    /// Checks every setting; the error names it.
    pub fn validate(&self) -> anyhow::Result<()> {
        self.estimator.validate()?;
        for (name, x) in [
            ("replan", self.replan),
            ("latency", self.latency),
            ("settle", self.settle),
            ("reserve", self.reserve),
            ("trigger", self.trigger),
            ("report", self.report),
        ] {
            anyhow::ensure!(
                x.is_finite() && x >= 0.0,
                "invalid adaptive {name} = {x}: allowed a finite number >= 0"
            );
        }
        anyhow::ensure!(
            self.replan > 0.0 && self.report > 0.0 && self.reserve < 0.5,
            "invalid adaptive replan = {}, report = {} or reserve = {}: allowed replan > 0, report > 0, reserve < 0.5",
            self.replan,
            self.report,
            self.reserve
        );
        anyhow::ensure!(
            (4..=400).contains(&self.grid),
            "invalid adaptive grid = {}: allowed 4 to 400 points",
            self.grid
        );
        Ok(())
    }
}

/// What the worker is asked.
#[derive(Debug, Clone)]
struct Job {
    id: u64,
    friction: Friction,
    wave: Wave,
    /// Speed (m/s), power (W) and largest stress (Pa) the plant showed under `wave`.
    measured: Option<[f64; 3]>,
    remaining_distance: f64,
    remaining_energy: f64,
}

/// The worker's answer.
#[derive(Debug, Clone)]
struct Decision {
    id: u64,
    wave: Option<Wave>,
    text: String,
    prediction: Option<Prediction>,
    seconds: f64,
}

/// What does not change during a run: the problem the worker solves.
#[derive(Debug, Clone, Copy)]
struct Plan {
    body: Body,
    task: Task,
    limits: Limits,
    length: f64,
    boundary: Boundary,
    cells: usize,
    grid: usize,
    reserve: f64,
}

impl Plan {
    fn solve(&self, job: &Job) -> Decision {
        let started = Instant::now();
        let model = TravellingWaveModel::default();
        let point = |w: Wave| OperatingPoint {
            body: self.body,
            friction: job.friction,
            wave: w,
            wavelengths: (w.k * self.length / std::f64::consts::TAU).round().max(1.0),
        };
        // what the plant showed against what the model says for the gait being applied
        let here = model.predict(&point(job.wave));
        let mut scale = [1.0f64; 3];
        if let (Some([v, p, s]), Some(pv), Some(pp), Some(ps)) =
            (job.measured, here.velocity, here.power, here.max_stress)
        {
            for (i, (m, q)) in [(v, pv), (p, pp), (s, ps)].into_iter().enumerate() {
                if m > 0.0 && q > 0.0 {
                    scale[i] = (m / q).clamp(0.25, 4.0);
                }
            }
        }
        let [sv, sp, ss] = scale;
        let energy = job.remaining_energy * (1.0 - self.reserve);
        let mut text = format!(
            "re-plan #{}: {:.4} m left on {:.4} J ({:.4} J after the reserve); plant/model under the current gait: V x{:.4}, P x{:.4}, sigma x{:.4}",
            job.id, job.remaining_distance, job.remaining_energy, energy, sv, sp, ss
        );
        if job.remaining_distance <= 0.0 {
            text += "; the distance is reached: keep the gait";
            return Decision {
                id: job.id,
                wave: None,
                text,
                prediction: None,
                seconds: started.elapsed().as_secs_f64(),
            };
        }
        if energy <= 0.0 {
            text += "; no energy left to plan with: keep the gait";
            return Decision {
                id: job.id,
                wave: None,
                text,
                prediction: None,
                seconds: started.elapsed().as_secs_f64(),
            };
        }
        // M_plant = (sv / sp) M_model >= D / J  <=>  M_model >= D / (J sv / sp)
        let problem = Problem {
            body: self.body,
            friction: job.friction,
            task: Task {
                distance: job.remaining_distance,
                energy: energy * sv / sp,
                sigma_max: self.task.sigma_max / ss,
                end_run: false,
            },
            limits: self.limits,
            body_length: BodyLength::Fixed(self.length),
        };
        let grid = GridSpec::new(self.grid, self.grid);
        let mut wave = None;
        let mut prediction = None;
        match problem.optimize(&ModelChoice::Improved(model), &grid) {
            Ok(r) => {
                let o = r.optimum;
                let w = Wave {
                    f0: o.f0,
                    k: o.k,
                    omega: o.omega,
                    phase: 0.0,
                };
                match w.validate_for_body(self.length, self.cells, self.boundary) {
                    Ok(()) => {
                        let mut p = o.prediction.clone();
                        p.model = "estimated";
                        p.velocity = p.velocity.map(|v| v * sv);
                        p.power = p.power.map(|x| x * sp);
                        p.mileage = p.mileage.map(|m| m * sv / sp);
                        p.max_stress = p.max_stress.map(|x| x * ss);
                        text += &format!(
                            "; new gait f0 = {:.5} N, k = {:.4} rad/m, omega = {:.4} rad/s (alpha {:.4}), binding {:?}; expected V = {:.4e} m/s, M = {:.4e} m/J",
                            w.f0,
                            w.k,
                            w.omega,
                            o.alpha,
                            o.binding,
                            p.velocity.unwrap_or(f64::NAN),
                            p.mileage.unwrap_or(f64::NAN)
                        );
                        wave = Some(w);
                        prediction = Some(p);
                    }
                    Err(e) => {
                        text += &format!("; the optimum does not fit the body ({e}): keep the gait")
                    }
                }
            }
            Err(e) => text += &format!("; no feasible gait ({e}): keep the gait"),
        }
        Decision {
            id: job.id,
            wave,
            text,
            prediction,
            seconds: started.elapsed().as_secs_f64(),
        }
    }
}

/// A request in flight.
#[derive(Debug, Clone, Copy)]
struct Pending {
    id: u64,
    /// Step at which the answer is applied (`None`: as soon as it is ready).
    apply_at: Option<u64>,
}

/// The adaptive policy (see the module documentation).
pub struct Adaptive {
    opts: AdaptiveOptions,
    told: Friction,
    task: Task,
    area: f64,
    step: f64,
    wave: Wave,
    estimator: FrictionEstimator,
    /// Friction the current gait was planned with.
    planned_with: Friction,
    start_position: Option<f64>,
    distance: f64,
    energy: f64,
    /// Since the gait changed: the time it changed, and sums of V dt, P dt, time, max stress
    /// after it settled.
    gait_since: f64,
    gait_sums: [f64; 4],
    jobs: Sender<Job>,
    answers: Receiver<Decision>,
    pending: Option<Pending>,
    next_id: u64,
    last_plan_time: f64,
    next_report: f64,
    late: u64,
    replans: u64,
    insight: Option<Insight>,
    last_prediction: Option<Prediction>,
    initial: String,
}

pub(crate) fn build(ctx: &Context, params: &Params) -> anyhow::Result<Box<dyn Policy>> {
    Ok(Box::new(Adaptive::new(
        ctx,
        AdaptiveOptions::from_params(params)?,
    )?))
}

impl Adaptive {
    /// The policy for the plant of `ctx`: the certified open-loop optimum for the told friction
    /// to start with, the estimator, and the worker thread.
    pub fn new(ctx: &Context, opts: AdaptiveOptions) -> anyhow::Result<Self> {
        opts.validate()?;
        let optimal = crate::optimal::plan(ctx, &crate::optimal::OptimalOptions::default())?;
        let initial = Policy::describe(&optimal);
        let wave = optimal.wave();
        let estimator = FrictionEstimator::new(
            opts.estimator,
            ctx.body,
            ctx.friction,
            ctx.boundary,
            ctx.length,
            ctx.cells,
            ctx.step,
        )?;
        let plan = Plan {
            body: ctx.body,
            task: ctx.scenario.task,
            limits: ctx.scenario.limits,
            length: ctx.length,
            boundary: ctx.boundary,
            cells: ctx.cells,
            grid: opts.grid,
            reserve: opts.reserve,
        };
        let (jobs, job_rx) = bounded::<Job>(1);
        let (answer_tx, answers) = bounded::<Decision>(1);
        std::thread::Builder::new()
            .name("adaptive-planner".into())
            .spawn(move || {
                for job in job_rx {
                    if answer_tx.send(plan.solve(&job)).is_err() {
                        break;
                    }
                }
            })?;
        Ok(Self {
            opts,
            told: ctx.friction,
            task: ctx.scenario.task,
            area: ctx.body.area,
            step: ctx.step,
            wave,
            estimator,
            planned_with: ctx.friction,
            start_position: None,
            distance: 0.0,
            energy: 0.0,
            gait_since: 0.0,
            gait_sums: [0.0; 4],
            jobs,
            answers,
            pending: None,
            next_id: 1,
            last_plan_time: 0.0,
            next_report: 0.0,
            late: 0,
            replans: 0,
            insight: None,
            last_prediction: Some(Prediction {
                model: "estimated",
                ..optimal.report.optimum.prediction.clone()
            }),
            initial,
        })
    }

    /// The current estimate.
    pub fn estimate(&self) -> Estimate {
        self.estimator.estimate()
    }

    /// Decisions that had to be waited for (the worker was late).
    pub fn late_decisions(&self) -> u64 {
        self.late
    }

    fn track(&mut self, obs: &Observation) {
        let mean = obs.u.iter().sum::<f64>() / obs.u.len() as f64;
        match self.start_position {
            None => self.start_position = Some(mean),
            Some(start) => {
                self.distance = mean - start;
                self.energy += obs.input_power * self.step;
                if obs.time - self.gait_since >= self.opts.settle {
                    let h = self.step;
                    let stress =
                        obs.tension.iter().fold(f64::NEG_INFINITY, |m, &t| m.max(t)) / self.area;
                    let s = &mut self.gait_sums;
                    s[0] += obs.mean_speed * h;
                    s[1] += obs.input_power * h;
                    s[2] += h;
                    s[3] = s[3].max(stress);
                }
            }
        }
        self.estimator.observe(&Sample {
            v: obs.vel,
            tension: obs.tension,
            stuck: obs.stuck,
            mean_speed: obs.mean_speed,
            input_power: obs.input_power,
        });
    }

    fn measured(&self) -> Option<[f64; 3]> {
        let s = self.gait_sums;
        (s[2] >= 0.5).then(|| [s[0] / s[2], s[1] / s[2], s[3]])
    }

    fn moved(&self, e: &Estimate) -> bool {
        let p = self.planned_with;
        let d_eps = (e.eps - p.eps).abs();
        let d_nf = (e.n_f - p.n_f).abs();
        (d_eps > self.opts.trigger * p.eps.max(0.01) && d_eps > 2.0 * e.eps_std)
            || (d_nf > self.opts.trigger && d_nf > 2.0 * e.n_f_std)
    }

    fn maybe_request(&mut self, obs: &Observation) {
        if self.pending.is_some() || self.distance >= self.task.distance {
            return;
        }
        let e = self.estimator.estimate();
        let due = obs.time - self.last_plan_time >= self.opts.replan && self.measured().is_some();
        let moved =
            e.windows > 0 && self.moved(&e) && obs.time - self.gait_since >= self.opts.settle;
        if !(due || moved) {
            return;
        }
        let job = Job {
            id: self.next_id,
            friction: e.friction(&self.told),
            wave: self.wave,
            measured: self.measured(),
            remaining_distance: self.task.distance - self.distance,
            remaining_energy: self.task.energy - self.energy,
        };
        if self.jobs.try_send(job).is_ok() {
            let latency = (self.opts.latency / self.step).round() as u64;
            self.pending = Some(Pending {
                id: self.next_id,
                apply_at: (self.opts.latency > 0.0).then(|| obs.step + latency.max(1)),
            });
            self.next_id += 1;
            self.last_plan_time = obs.time;
            self.planned_with = e.friction(&self.told);
        }
    }

    fn maybe_apply(&mut self, obs: &Observation) {
        let Some(p) = self.pending else { return };
        let decision = match p.apply_at {
            Some(at) if obs.step < at => return,
            Some(_) => match self.answers.try_recv() {
                Ok(d) => d,
                Err(_) => {
                    self.late += 1;
                    match self.answers.recv() {
                        Ok(d) => d,
                        Err(_) => {
                            self.pending = None;
                            return;
                        }
                    }
                }
            },
            None => match self.answers.try_recv() {
                Ok(d) => d,
                Err(_) => return,
            },
        };
        self.pending = None;
        if decision.id != p.id {
            return;
        }
        self.replans += 1;
        let mut text = format!(
            "t = {:.3} s: {} (solved in {:.3} s)",
            obs.time, decision.text, decision.seconds
        );
        if let Some(mut w) = decision.wave {
            // the muscle force f0 sin(k x - omega t + phase) keeps its phase at this instant
            w.phase = (self.wave.phase + (w.omega - self.wave.omega) * obs.time)
                .rem_euclid(std::f64::consts::TAU);
            if w.k != self.wave.k {
                w.phase = self.wave.phase;
            }
            let changed = (w.f0, w.k, w.omega) != (self.wave.f0, self.wave.k, self.wave.omega);
            if changed {
                self.wave = w;
                self.gait_since = obs.time;
                self.gait_sums = [0.0; 4];
                text += "; applied";
            }
            self.last_prediction = decision.prediction;
        }
        self.insight = Some(self.report(obs, text));
    }

    fn report(&mut self, obs: &Observation, decision: String) -> Insight {
        let e = self.estimator.estimate();
        self.next_report = obs.time + self.opts.report;
        let mut text = format!(
            "adaptive at t = {:.3} s: {}; progress {:.4} of {} m on {:.4} of {} J",
            obs.time,
            e.describe(),
            self.distance,
            self.task.distance,
            self.energy,
            self.task.energy
        );
        if !decision.is_empty() {
            text += "; ";
            text += &decision;
        }
        if self.late > 0 {
            text += &format!("; {} decisions were late", self.late);
        }
        Insight {
            text,
            prediction: self.last_prediction.clone(),
        }
    }
}

impl Policy for Adaptive {
    fn name(&self) -> &str {
        "adaptive"
    }

    fn act(&mut self, obs: &Observation) -> Actuation {
        self.track(obs);
        self.maybe_apply(obs);
        self.maybe_request(obs);
        if self.insight.is_none() && obs.time >= self.next_report {
            self.insight = Some(self.report(obs, String::new()));
        }
        Actuation::Wave(self.wave)
    }

    fn describe(&self) -> String {
        format!(
            "adaptive: starts with {}; re-plans every {} s with the estimated friction (latency {} s)",
            self.initial, self.opts.replan, self.opts.latency
        )
    }

    fn insight(&mut self) -> Option<Insight> {
        self.insight.take()
    }
}
