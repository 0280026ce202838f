//! `adaptive`: the constrained optimum re-solved in flight, under a supervisor that never trades
//! a gait known to finish the task for one that is not.
//!
//! It starts with the open-loop optimum for the friction it was told (the `optimal` policy,
//! certified on the task) and, every communication step,
//!
//! - feeds the plant's state to a [`FrictionEstimator`] (eps, n_F and c_v from the body's
//!   momentum and power balances, with a covariance);
//! - follows the task as the plant counts it: the distance the centre of mass has travelled and
//!   the actuator's net work;
//! - measures the gait it applies once it has settled ([`meter::Meter`]): speed, power, mileage
//!   with its standard error, largest stress.
//!
//! The supervisor ([`Role`]) keeps a *known* gait, one whose measured mileage covers the
//! remaining distance on the remaining energy (with [`AdaptiveOptions::finish_margin`]) and whose
//! stress stayed below the limit:
//!
//! - a faster plan (the worker's robust optimum, [`planner`]) is tried only if, with no progress
//!   at all during the try and the way back, the known gait could still finish (the *slack*);
//!   the try ends as soon as that stops being so, or when its own measurement does not finish or
//!   is not faster. So in a pipe whose friction does not change along the way, adaptive finishes
//!   whenever its known gait does, the open loop's gait first of all;
//! - when the gait applied does not finish (less friction than told, a pipe that changes), it
//!   tries plans of a larger mileage bound and keeps the best measured one ("rescue"); when no
//!   gait finishes by the bounds it says so and applies the gait of the largest mileage bound;
//! - a stress governor lowers the amplitude at once when the measured stress comes within half
//!   the stress margin of `sigma_max`.
//!
//! Plans are asked of a worker thread; an answer takes effect a fixed
//! [`AdaptiveOptions::latency`] of simulated time after it was asked for, so a run is
//! reproducible step for step (the in-process run equals the co-simulated one); a step waits
//! for a late answer and the waits are counted. The phase of a new wave is chosen so that the
//! muscle force does not jump. The estimates, the supervisor's state and every decision are
//! reported ([`Policy::insight`]) and recorded with the run.

mod meter;
pub mod planner;

use crossbeam_channel::{bounded, Receiver, Sender};

use crawler_models::prediction::Prediction;
use crawler_physics::execution::{Actuation, Observation};
use crawler_physics::params::{Boundary, Friction};
use crawler_physics::scenario::Task;
use crawler_physics::wave::Wave;

use crate::estimator::{Estimate, EstimatorOptions, FrictionEstimator, Sample};
use crate::params::{Key, Params};
use crate::policy::{Context, Insight, Policy};
use meter::Meter;
use planner::{Belief, Candidate, Decision, Job, Setting};

/// The parameters of the adaptive policy (`--param KEY=VALUE`).
pub const KEYS: [Key; 20] = [
    Key {
        name: "replan",
        doc: "seconds between re-plans while a known gait finishes (default 1)",
    },
    Key {
        name: "latency",
        doc: "seconds of simulated time between asking the planner and applying its answer (default 0.25; 0 is not reproducible)",
    },
    Key {
        name: "settle",
        doc: "seconds a new gait settles before it is measured (default 0: ten times rho / c_v, 1 s for the paper's body)",
    },
    Key {
        name: "measure",
        doc: "seconds a settled gait is measured before a verdict (default 0.3)",
    },
    Key {
        name: "kappa",
        doc: "standard deviations of the estimate the plans' margins cover (default 2)",
    },
    Key {
        name: "model_margin",
        doc: "relative error of the corrected model the plans' margins cover (default 0.03)",
    },
    Key {
        name: "finish_margin",
        doc: "relative energy margin a gait must keep to count as finishing (default 0.002)",
    },
    Key {
        name: "stress_margin",
        doc: "relative margin plans keep below sigma_max (default 0.05); the governor acts at half of it",
    },
    Key {
        name: "min_gain",
        doc: "smallest relative gain of predicted speed worth a try (default 0.02)",
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
        doc: "relative error of each energy row (default 0.001)",
    },
    Key {
        name: "momentum_tolerance",
        doc: "relative error of each momentum row besides the stuck nodes' (default 0.01)",
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
        doc: "prior relative standard deviation of the told c_v (default 0.001)",
    },
    Key {
        name: "viscous_known",
        doc: "1 takes c_v as told (no prior spread)",
    },
    Key {
        name: "replans",
        doc: "0 never re-plans (the open loop with the estimator running); default 1",
    },
];

/// Settings of the adaptive policy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdaptiveOptions {
    /// The friction estimator.
    pub estimator: EstimatorOptions,
    /// Seconds between re-plans while a known gait finishes.
    pub replan: f64,
    /// Seconds (of simulated time) between asking the worker and applying its answer; 0 applies
    /// answers as soon as they are ready (faster, but a run is then not reproducible).
    pub latency: f64,
    /// Seconds a new gait is left to settle before it is measured (0: ten times `rho / c_v`).
    pub settle: f64,
    /// Seconds a settled gait is measured before a verdict.
    pub measure: f64,
    /// Standard deviations of the estimate the plans' margins cover.
    pub kappa: f64,
    /// Relative error of the corrected model the plans' margins cover.
    pub model_margin: f64,
    /// Relative energy margin a gait must keep to count as finishing.
    pub finish_margin: f64,
    /// Relative margin plans keep below `sigma_max`.
    pub stress_margin: f64,
    /// Smallest relative gain of speed worth a try.
    pub min_gain: f64,
    /// Grid points per axis of the re-plans' optimisation.
    pub grid: usize,
    /// Seconds between reports to the recorder.
    pub report: f64,
    /// False: never re-plan (the open loop, with the estimator and the meter running).
    pub replans: bool,
}

impl Default for AdaptiveOptions {
    fn default() -> Self {
        Self {
            estimator: EstimatorOptions::default(),
            replan: 1.0,
            latency: 0.25,
            settle: 0.0,
            measure: 0.3,
            kappa: 2.0,
            model_margin: 0.03,
            finish_margin: 0.002,
            stress_margin: 0.05,
            min_gain: 0.02,
            grid: 16,
            report: 0.5,
            replans: true,
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
            "measure" => self.measure = value,
            "kappa" => self.kappa = value,
            "model_margin" => self.model_margin = value,
            "finish_margin" => self.finish_margin = value,
            "stress_margin" => self.stress_margin = value,
            "min_gain" => self.min_gain = value,
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
            "viscous_known" | "replans" => {
                anyhow::ensure!(
                    value == 0.0 || value == 1.0,
                    "invalid adaptive {key} = {value}: allowed 0 or 1"
                );
                if key == "replans" {
                    self.replans = value == 1.0;
                } else if value == 1.0 {
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
            ("measure", self.measure),
            ("kappa", self.kappa),
            ("model_margin", self.model_margin),
            ("finish_margin", self.finish_margin),
            ("stress_margin", self.stress_margin),
            ("min_gain", self.min_gain),
            ("report", self.report),
        ] {
            anyhow::ensure!(
                x.is_finite() && x >= 0.0,
                "invalid adaptive {name} = {x}: allowed a finite number >= 0"
            );
        }
        for (name, x) in [
            ("replan", self.replan),
            ("report", self.report),
            ("measure", self.measure),
        ] {
            anyhow::ensure!(x > 0.0, "invalid adaptive {name} = {x}: allowed > 0");
        }
        for (name, x) in [
            ("model_margin", self.model_margin),
            ("finish_margin", self.finish_margin),
            ("stress_margin", self.stress_margin),
        ] {
            anyhow::ensure!(
                x < 0.5,
                "invalid adaptive {name} = {x}: allowed a share below 0.5"
            );
        }
        anyhow::ensure!(
            (4..=400).contains(&self.grid),
            "invalid adaptive grid = {}: allowed 4 to 400 points",
            self.grid
        );
        Ok(())
    }
}

/// What the supervisor is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// The gait applied has not been measured yet (the start, or after the stress governor).
    Unverified,
    /// The gait applied is measured to finish: the fallback of a try.
    Incumbent,
    /// A faster gait tried from the known one.
    SpeedTrial,
    /// The gait applied is measured short of the task: plans of a larger mileage are tried.
    Rescue,
    /// A gait of a larger mileage bound tried in rescue.
    RescueTrial,
}

impl Role {
    fn as_str(self) -> &'static str {
        match self {
            Role::Unverified => "unverified",
            Role::Incumbent => "finishing",
            Role::SpeedTrial => "trying a faster gait",
            Role::Rescue => "short of the task",
            Role::RescueTrial => "trying a gait of larger mileage",
        }
    }
}

/// A measured gait.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Known {
    /// The gait.
    pub wave: Wave,
    /// Measured speed, m/s.
    pub speed: f64,
    /// Measured power, W.
    pub power: f64,
    /// Lower bound of the measured mileage, m/J.
    pub mileage_lo: f64,
    /// Largest stress measured, Pa.
    pub stress: f64,
    /// Energy stored in the body under it (kinetic and elastic), J.
    pub stored: f64,
}

/// A decision of the supervisor, for the log and the tests.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// A faster gait was tried.
    SpeedTrial,
    /// A tried gait was kept.
    Kept,
    /// A tried gait was given up and the known gait taken back.
    Reverted,
    /// The gait applied was found short of the task.
    Short,
    /// A gait of a larger mileage bound was tried.
    RescueTrial,
    /// No gait finishes by the plans' bounds: the one of the largest mileage bound applied.
    GaveUp,
    /// The stress governor lowered the amplitude.
    Governor,
}

/// A request in flight.
#[derive(Debug, Clone, Copy)]
struct Pending {
    id: u64,
    /// Step at which the answer is applied (`None`: as soon as it is ready).
    apply_at: Option<u64>,
    /// The role it was asked in (an answer finding another role is dropped).
    role: Role,
}

/// The adaptive policy (see the module documentation).
pub struct Adaptive {
    opts: AdaptiveOptions,
    told: Friction,
    task: Task,
    area: f64,
    step: f64,
    settle: f64,
    wave: Wave,
    estimator: FrictionEstimator,
    meter: Meter,
    role: Role,
    known: Option<Known>,
    /// Tried gaits that were given up: the gait and its measured speed.
    failed: Vec<(Wave, f64)>,
    start_position: Option<f64>,
    distance: f64,
    energy: f64,
    stored: f64,
    jobs: Sender<Job>,
    answers: Receiver<Decision>,
    pending: Option<Pending>,
    next_id: u64,
    last_request: f64,
    rescue_asked: bool,
    next_report: f64,
    late: u64,
    replans: u64,
    events: Vec<(f64, Event)>,
    insight: Option<Insight>,
    notes: Vec<String>,
    last_prediction: Option<Prediction>,
    initial: String,
    elastic: f64,
    density: f64,
    dx: f64,
    boundary: Boundary,
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
        let settle = if opts.settle > 0.0 {
            opts.settle
        } else {
            10.0 * ctx.body.density / ctx.friction.viscous.max(1e-9)
        };
        let setting = Setting {
            body: ctx.body,
            task: ctx.scenario.task,
            limits: ctx.scenario.limits,
            length: ctx.length,
            boundary: ctx.boundary,
            cells: ctx.cells,
            grid: opts.grid,
            kappa: opts.kappa,
            model_margin: opts.model_margin,
            stress_margin: opts.stress_margin,
        };
        let (jobs, job_rx) = bounded::<Job>(1);
        let (answer_tx, answers) = bounded::<Decision>(1);
        std::thread::Builder::new()
            .name("adaptive-planner".into())
            .spawn(move || {
                for job in job_rx {
                    if answer_tx.send(setting.solve(&job)).is_err() {
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
            settle,
            wave,
            estimator,
            meter: Meter::new(0.0, settle),
            role: Role::Unverified,
            known: None,
            failed: Vec::new(),
            start_position: None,
            distance: 0.0,
            energy: 0.0,
            stored: 0.0,
            jobs,
            answers,
            pending: None,
            next_id: 1,
            last_request: f64::NEG_INFINITY,
            rescue_asked: false,
            next_report: 0.0,
            late: 0,
            replans: 0,
            events: Vec::new(),
            insight: None,
            notes: Vec::new(),
            last_prediction: Some(Prediction {
                model: "estimated",
                ..optimal.report.optimum.prediction.clone()
            }),
            initial,
            elastic: ctx.body.stiffness(),
            density: ctx.body.density,
            dx: ctx.length / ctx.cells as f64,
            boundary: ctx.boundary,
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

    /// The supervisor's decisions so far, with their times (s).
    pub fn events(&self) -> &[(f64, Event)] {
        &self.events
    }

    /// What the supervisor is doing.
    pub fn role(&self) -> Role {
        self.role
    }

    /// The gait known to finish (or, short of the task, the best measured one).
    pub fn known(&self) -> Option<Known> {
        self.known
    }

    fn remaining(&self) -> (f64, f64) {
        (
            (self.task.distance - self.distance).max(0.0),
            self.task.energy - self.energy,
        )
    }

    /// True if a gait of measured mileage bound `mileage_lo` and stress `stress` finishes.
    fn finishes(&self, mileage_lo: f64, stress: f64) -> bool {
        let (d, e) = self.remaining();
        mileage_lo > 0.0
            && e >= d / mileage_lo * (1.0 + self.opts.finish_margin)
            && stress <= (1.0 - 0.5 * self.opts.stress_margin) * self.task.sigma_max
    }

    /// Energy to spare beyond what taking the known gait back and finishing with it needs, with
    /// no progress while it settles.
    fn slack(&self, k: &Known) -> f64 {
        let (d, e) = self.remaining();
        e - (k.power * self.settle + k.stored) - d / k.mileage_lo * (1.0 + self.opts.finish_margin)
    }

    fn track(&mut self, obs: &Observation) {
        let n = obs.u.len();
        let mean = obs.u.iter().sum::<f64>() / n as f64;
        let stress = obs.tension.iter().fold(f64::NEG_INFINITY, |m, &t| m.max(t)) / self.area;
        let (mut kin, mut el) = (0.0, 0.0);
        for i in 0..n {
            kin += obs.vel[i] * obs.vel[i];
            el += obs.tension[i] * obs.tension[i];
        }
        self.stored = self.dx * (0.5 * self.density * kin + 0.5 * el / self.elastic);
        match self.start_position {
            None => self.start_position = Some(mean),
            Some(start) => {
                self.distance = mean - start;
                self.energy += obs.input_power * self.step;
                self.meter.observe(
                    obs.time,
                    self.step,
                    obs.mean_speed,
                    obs.input_power,
                    stress,
                    self.stored,
                );
            }
        }
        self.estimator.observe(&Sample {
            v: obs.vel,
            tension: obs.tension,
            stuck: obs.stuck,
            mean_speed: obs.mean_speed,
            input_power: obs.input_power,
        });
        let _ = self.boundary;
    }

    fn note(&mut self, time: f64, event: Option<Event>, text: String) {
        if let Some(e) = event {
            self.events.push((time, e));
        }
        self.notes.push(format!("t = {time:.3} s: {text}"));
    }

    /// Applies `w` from `obs.time` on, with the muscle force's phase continuous.
    fn apply(&mut self, mut w: Wave, obs: &Observation) {
        // the muscle force f0 sin(k x - omega t + phase) keeps its phase at this instant
        w.phase = if w.k == self.wave.k {
            (self.wave.phase + (w.omega - self.wave.omega) * obs.time)
                .rem_euclid(std::f64::consts::TAU)
        } else {
            self.wave.phase
        };
        self.wave = w;
        self.meter = Meter::new(obs.time, self.settle);
    }

    fn known_of_meter(&self) -> Option<Known> {
        let m = &self.meter;
        Some(Known {
            wave: self.wave,
            speed: m.speed()?,
            power: m.power()?,
            mileage_lo: m.mileage_lo(self.opts.kappa)?,
            stress: m.peak(),
            stored: m.stored(),
        })
    }

    fn same_gait(a: &Wave, b: &Wave) -> bool {
        (a.f0, a.k, a.omega) == (b.f0, b.k, b.omega)
    }

    /// The stress governor: the measured stress within half the margin of `sigma_max`.
    fn govern(&mut self, obs: &Observation) {
        let stress = self.meter.last_stress();
        let limit = (1.0 - 0.5 * self.opts.stress_margin) * self.task.sigma_max;
        // (a NaN stress does not govern)
        if stress.partial_cmp(&limit) != Some(std::cmp::Ordering::Greater) {
            return;
        }
        let back = self
            .known
            .filter(|k| !Self::same_gait(&k.wave, &self.wave) && k.stress < limit);
        match (self.role, back) {
            (Role::SpeedTrial | Role::RescueTrial, Some(k)) => {
                let role = if self.role == Role::SpeedTrial {
                    Role::Incumbent
                } else {
                    Role::Rescue
                };
                self.failed.push((self.wave, 0.0));
                self.apply(k.wave, obs);
                self.role = role;
                self.note(
                    obs.time,
                    Some(Event::Governor),
                    format!("stress {stress:.4e} Pa near sigma_max: the known gait taken back"),
                );
            }
            _ => {
                let scale = (1.0 - self.opts.stress_margin) * self.task.sigma_max / stress;
                let w = Wave {
                    f0: self.wave.f0 * scale,
                    ..self.wave
                };
                self.apply(w, obs);
                self.known = None;
                self.role = Role::Unverified;
                self.note(
                    obs.time,
                    Some(Event::Governor),
                    format!(
                        "stress {stress:.4e} Pa near sigma_max: amplitude lowered to {:.5} N",
                        w.f0
                    ),
                );
            }
        }
    }

    /// Ends a speed trial whose way back would need the rest.
    fn guard(&mut self, obs: &Observation) {
        if self.role != Role::SpeedTrial {
            return;
        }
        let Some(k) = self.known else { return };
        if self.slack(&k) > 0.0 {
            return;
        }
        self.failed
            .push((self.wave, self.meter.speed().unwrap_or(0.0)));
        self.apply(k.wave, obs);
        self.role = Role::Incumbent;
        self.note(
            obs.time,
            Some(Event::Reverted),
            "the try ended: the way back to the known gait needs the rest of the energy".into(),
        );
    }

    /// The verdict on the gait applied, once measured.
    fn verdict(&mut self, obs: &Observation) {
        if !self.meter.verdict_due(obs.time, self.opts.measure) {
            return;
        }
        let Some(here) = self.known_of_meter() else {
            return;
        };
        self.rescue_asked = false;
        let finishes = self.finishes(here.mileage_lo, here.stress);
        let (d, e) = self.remaining();
        let summary = format!(
            "measured V = {:.4e} m/s, P = {:.4e} W, M >= {:.4e} m/J, sigma <= {:.4e} Pa; {:.4} m left need {:.4} J of {:.4} J",
            here.speed,
            here.power,
            here.mileage_lo,
            here.stress,
            d,
            d / here.mileage_lo,
            e
        );
        match self.role {
            Role::Unverified | Role::Incumbent | Role::Rescue => {
                let was = self.role;
                if finishes {
                    self.known = Some(here);
                    self.role = Role::Incumbent;
                    if was != Role::Incumbent {
                        self.note(obs.time, None, format!("the gait finishes: {summary}"));
                    }
                } else {
                    self.known = Some(here);
                    self.role = Role::Rescue;
                    if was != Role::Rescue {
                        self.note(
                            obs.time,
                            Some(Event::Short),
                            format!("the gait is short of the task: {summary}"),
                        );
                    }
                }
            }
            Role::SpeedTrial => {
                let k = self.known.expect("a try has a known gait");
                if finishes && here.speed > k.speed {
                    self.known = Some(here);
                    self.role = Role::Incumbent;
                    self.note(
                        obs.time,
                        Some(Event::Kept),
                        format!("the faster gait finishes and is kept: {summary}"),
                    );
                } else {
                    self.failed.push((self.wave, here.speed));
                    self.apply(k.wave, obs);
                    self.role = Role::Incumbent;
                    self.note(
                        obs.time,
                        Some(Event::Reverted),
                        format!(
                            "the try is given up ({}): {summary}",
                            if finishes {
                                "not faster"
                            } else {
                                "it would not finish"
                            }
                        ),
                    );
                }
            }
            Role::RescueTrial => {
                let k = self.known.expect("a try has a known gait");
                if finishes || here.mileage_lo > k.mileage_lo {
                    self.known = Some(here);
                    self.role = if finishes {
                        Role::Incumbent
                    } else {
                        Role::Rescue
                    };
                    self.note(
                        obs.time,
                        Some(Event::Kept),
                        format!(
                            "the gait of larger mileage is kept ({}): {summary}",
                            if finishes {
                                "it finishes"
                            } else {
                                "still short"
                            }
                        ),
                    );
                } else {
                    self.failed.push((self.wave, here.speed));
                    self.apply(k.wave, obs);
                    self.role = Role::Rescue;
                    self.note(
                        obs.time,
                        Some(Event::Reverted),
                        format!("the tried gait's mileage is no larger; the best known gait taken back: {summary}"),
                    );
                }
            }
        }
    }

    fn tabu(&self, c: &Candidate) -> bool {
        self.failed.iter().any(|(w, speed)| {
            w.k == c.wave.k
                && (w.omega - c.wave.omega).abs() <= 0.01 * w.omega
                && c.wave.f0 >= 0.97 * w.f0
                && c.speed <= speed.max(0.0) * (1.0 + self.opts.min_gain)
        })
    }

    fn maybe_request(&mut self, obs: &Observation) {
        if !self.opts.replans || self.pending.is_some() || self.distance >= self.task.distance {
            return;
        }
        let Some(k) = self.known else { return };
        let (d, e) = self.remaining();
        let energy = match self.role {
            Role::Incumbent => {
                if obs.time - self.last_request < self.opts.replan {
                    return;
                }
                // room for a try that lasts at least until its verdict
                let slack = self.slack(&k);
                if slack <= k.power * (self.settle + self.opts.measure) {
                    return;
                }
                e - k.power * self.settle - k.stored
            }
            Role::Rescue => {
                if self.rescue_asked {
                    return;
                }
                e - k.power * self.settle - k.stored
            }
            _ => return,
        };
        let est = self.estimator.estimate();
        let measured = if Self::same_gait(&k.wave, &self.wave) {
            Some([k.speed, k.power, k.stress])
        } else {
            None
        };
        let job = Job {
            id: self.next_id,
            belief: Belief {
                theta: est.theta,
                cov: est.cov,
                told: self.told,
            },
            wave: self.wave,
            measured,
            distance: d,
            energy: energy / (1.0 + self.opts.finish_margin),
        };
        if self.jobs.try_send(job).is_ok() {
            let latency = (self.opts.latency / self.step).round() as u64;
            self.pending = Some(Pending {
                id: self.next_id,
                apply_at: (self.opts.latency > 0.0).then(|| obs.step + latency.max(1)),
                role: self.role,
            });
            self.next_id += 1;
            self.last_request = obs.time;
            if self.role == Role::Rescue {
                self.rescue_asked = true;
            }
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
        let mut text = format!("{} (solved in {:.3} s)", decision.text, decision.seconds);
        let Some(k) = self.known else { return };
        if p.role != self.role {
            text += &format!("; dropped: the supervisor is now {}", self.role.as_str());
            self.note(obs.time, None, text);
            return;
        }
        let cap = (1.0 - self.opts.stress_margin) * self.task.sigma_max;
        match (self.role, decision.candidate) {
            (_, None) => text += "; the gait is kept",
            (Role::Incumbent, Some(c)) => {
                let slack = self.slack(&k);
                let why_not = if !c.finishes {
                    Some("it would not finish by its bounds".to_string())
                } else if c.speed <= k.speed * (1.0 + self.opts.min_gain) {
                    Some(format!(
                        "its predicted speed {:.4e} m/s is not {} % above the known {:.4e} m/s",
                        c.speed,
                        100.0 * self.opts.min_gain,
                        k.speed
                    ))
                } else if c.stress_hi > cap {
                    Some("its stress bound is above the margin".into())
                } else if slack <= c.power_hi * (self.settle + self.opts.measure) {
                    Some(format!(
                        "the slack ({slack:.4} J) does not pay for a try until its verdict"
                    ))
                } else if self.tabu(&c) {
                    Some("a gait as strong was tried and given up".into())
                } else {
                    None
                };
                match why_not {
                    Some(w) => text += &format!("; not tried: {w}"),
                    None => {
                        self.apply(c.wave, obs);
                        self.role = Role::SpeedTrial;
                        self.events.push((obs.time, Event::SpeedTrial));
                        text += &format!("; tried (slack {slack:.4} J)");
                        self.last_prediction = decision.prediction;
                    }
                }
            }
            (Role::Rescue, Some(c)) => {
                if c.mileage_lo > k.mileage_lo * 1.005 && c.stress_hi <= cap && !self.tabu(&c) {
                    self.apply(c.wave, obs);
                    self.role = Role::RescueTrial;
                    self.events.push((obs.time, Event::RescueTrial));
                    if !c.finishes {
                        self.events.push((obs.time, Event::GaveUp));
                    }
                    text += "; tried";
                    self.last_prediction = decision.prediction;
                } else {
                    text += &format!(
                        "; not tried: its mileage bound {:.4e} m/J is not above the known {:.4e} m/J",
                        c.mileage_lo, k.mileage_lo
                    );
                }
            }
            _ => text += "; dropped",
        }
        self.note(obs.time, None, text);
    }

    fn report(&mut self, obs: &Observation) -> Insight {
        let e = self.estimator.estimate();
        self.next_report = obs.time + self.opts.report;
        let mut text = format!(
            "adaptive at t = {:.3} s ({}): {}; progress {:.4} of {} m on {:.4} of {} J",
            obs.time,
            self.role.as_str(),
            e.describe(),
            self.distance,
            self.task.distance,
            self.energy,
            self.task.energy
        );
        for n in self.notes.drain(..) {
            text += "; ";
            text += &n;
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
        if self.distance < self.task.distance {
            self.govern(obs);
            self.guard(obs);
            self.verdict(obs);
            self.maybe_apply(obs);
            self.maybe_request(obs);
        }
        if !self.notes.is_empty() || obs.time >= self.next_report {
            self.insight = Some(self.report(obs));
        }
        Actuation::Wave(self.wave)
    }

    fn describe(&self) -> String {
        format!(
            "adaptive: starts with {}; re-plans with the estimated friction (margins {} standard deviations + {} % model), tries a faster gait only while the known one could still finish (latency {} s, settle {:.3} s)",
            self.initial,
            self.opts.kappa,
            100.0 * self.opts.model_margin,
            self.opts.latency,
            self.settle
        )
    }

    fn insight(&mut self) -> Option<Insight> {
        self.insight.take()
    }
}
