//! `reflex`: a distributed controller without a model: every segment of the body drives its own
//! muscle from what it senses itself and what its two neighbours sense (a central pattern
//! generator of coupled phase oscillators with proprioceptive reflexes, as in models of the
//! earthworm and the lamprey). The law, its parameters and how they were tuned are in
//! `docs/feedback.md`.
//!
//! Segment `j` (a run of consecutive cells, centre `x_j`) holds a phase `phi_j`, a frequency
//! `omega_j` and a log-amplitude `a_j = ln A_j`. Each communication step it senses its own mean
//! displacement, strain and tension, whether its nodes are stuck, the work its own muscle did,
//! and its neighbours' stuck state and phases, and it sets
//!
//! ```text
//! muscle force   m_j = A_j [ -sin(phi_j) + g_s (stuck_{j+1} - stuck_{j-1}) ]
//! phase          dphi_j/dt = omega_j + K_c [sin(phi_{j-1} - phi_j - Δ) + sin(phi_{j+1} - phi_j + Δ)]
//! frequency      domega_j/dt = -K_w omega_0 (psi_j - pi/2)
//! amplitude      da_j/dt = G_m clamp(ln(M_j / M*), ±1) + G_b e_j - G_s (T_j / T_lim - 1)+
//! ```
//!
//! - the oscillators start as the travelling wave `A_0 sin(k x - omega_0 t)` (`phi_j = -k x_j`,
//!   `omega_0 = alpha k c`, `Δ = k` times the segment length) and the coupling keeps neighbours
//!   `Δ` apart;
//! - stick reflex: a segment contracts when the segment ahead of it is anchored (stuck) and
//!   extends when the one behind is, which loads the anchor backwards, the direction in which
//!   static friction holds most (`eps c_d (1 + n_F)`);
//! - resonance reflex: `psi_j`, the lag of the segment's strain behind its own oscillator
//!   (demodulated over about two periods), is driven to a quarter period, the lag at resonance;
//! - energy reflex: `M_j` is the segment's own mileage (its speed from its own displacement, over
//!   its own muscle's power scaled to the body, both low-pass filtered) and `M* = (D / J0)(1 +
//!   margin)` the task's; `e_j` is how far the segment's energy use is ahead of its share of
//!   the budget for the distance it has travelled, `(J0 l_j / L)(d_j / D) - W_j`, as a share
//!   of its whole share `J0 l_j / L`; if every segment keeps to its share, the body reaches D
//!   within J0;
//! - stress reflex (a tendon organ): a segment whose tension exceeds `T_lim = s_lim sigma_max
//!   A_c` lowers its amplitude fast.

use std::f64::consts::{FRAC_PI_2, TAU};

use crawler_physics::params::Boundary;

use crate::params::{Key, Params};
use crate::policy::{Context, Policy};
use crawler_physics::execution::{Actuation, Observation};

/// The parameters of the reflex policy (`--param KEY=VALUE`).
pub const KEYS: [Key; 13] = [
    Key {
        name: "segment_length",
        doc: "segment length, m (default 1/64)",
    },
    Key {
        name: "k",
        doc: "wave number of the pattern, rad/m (default 0: the largest of limits.k that fits the body)",
    },
    Key {
        name: "alpha",
        doc: "initial frequency as a share of the natural frequency k c (default 1)",
    },
    Key {
        name: "f0",
        doc: "initial amplitude A_0, N (default 0.05)",
    },
    Key {
        name: "coupling",
        doc: "phase coupling K_c to each neighbour, 1/s (default 20)",
    },
    Key {
        name: "stick_gain",
        doc: "stick reflex gain g_s, share of the amplitude (default 1)",
    },
    Key {
        name: "resonance_gain",
        doc: "resonance reflex gain K_w, 1/s (default 0)",
    },
    Key {
        name: "mileage_gain",
        doc: "energy reflex gain on the mileage G_m, 1/s (default 2)",
    },
    Key {
        name: "budget_gain",
        doc: "energy reflex gain on the budget G_b, 1/s (default 20)",
    },
    Key {
        name: "filter",
        doc: "time constant of the speed and power filters, s (default 0.3)",
    },
    Key {
        name: "margin",
        doc: "mileage kept above D / J0, relative (default 0.1)",
    },
    Key {
        name: "stress_share",
        doc: "stress reflex threshold s_lim, share of sigma_max (default 0.8)",
    },
    Key {
        name: "stress_gain",
        doc: "stress reflex gain G_s, 1/s (default 50)",
    },
];

/// The reflex policy's parameters (defaults: tuned on `scenarios/reflex-tuning.toml`, not on the
/// compared cases; see `docs/feedback.md`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReflexOptions {
    /// Segment length, m (the body gets the nearest whole number of segments, at least one cell
    /// each).
    pub segment_length: f64,
    /// Wave number of the pattern, rad/m (0: the largest of `limits.k` that fits the body).
    pub k: f64,
    /// Initial frequency as a share of the natural frequency `k c`.
    pub alpha: f64,
    /// Initial amplitude A_0, N.
    pub f0: f64,
    /// Phase coupling K_c to each neighbour, 1/s.
    pub coupling: f64,
    /// Stick reflex gain g_s (share of the amplitude).
    pub stick_gain: f64,
    /// Resonance reflex gain K_w, 1/s.
    pub resonance_gain: f64,
    /// Energy reflex gain on the mileage G_m, 1/s.
    pub mileage_gain: f64,
    /// Energy reflex gain on the budget G_b, 1/s.
    pub budget_gain: f64,
    /// Time constant of the speed and power filters, s.
    pub filter: f64,
    /// Mileage kept above D / J0 (relative).
    pub margin: f64,
    /// Stress reflex threshold s_lim (share of sigma_max).
    pub stress_share: f64,
    /// Stress reflex gain G_s, 1/s.
    pub stress_gain: f64,
}

impl Default for ReflexOptions {
    fn default() -> Self {
        Self {
            segment_length: 1.0 / 64.0,
            k: 0.0,
            alpha: 1.0,
            f0: 0.05,
            coupling: 20.0,
            stick_gain: 1.0,
            resonance_gain: 0.0,
            mileage_gain: 2.0,
            budget_gain: 20.0,
            filter: 0.3,
            margin: 0.1,
            stress_share: 0.8,
            stress_gain: 50.0,
        }
    }
}

impl ReflexOptions {
    /// The defaults with the settings of `params` (each checked; an unknown key refused).
    pub fn from_params(params: &Params) -> anyhow::Result<Self> {
        let r = params.reader("reflex", &KEYS);
        let mut me = Self::default();
        for (key, x) in r.finite_all()? {
            me.set(key, x)?;
        }
        r.finish()?;
        me.validate()?;
        Ok(me)
    }

    /// Sets one parameter by name.
    pub fn set(&mut self, key: &str, value: f64) -> anyhow::Result<()> {
        let slot = match key {
            "segment_length" => &mut self.segment_length,
            "k" => &mut self.k,
            "alpha" => &mut self.alpha,
            "f0" => &mut self.f0,
            "coupling" => &mut self.coupling,
            "stick_gain" => &mut self.stick_gain,
            "resonance_gain" => &mut self.resonance_gain,
            "mileage_gain" => &mut self.mileage_gain,
            "budget_gain" => &mut self.budget_gain,
            "filter" => &mut self.filter,
            "margin" => &mut self.margin,
            "stress_share" => &mut self.stress_share,
            "stress_gain" => &mut self.stress_gain,
            _ => anyhow::bail!(
                "unknown reflex setting {key:?}: allowed {}",
                KEYS.map(|k| k.name).join(", ")
            ),
        };
        *slot = value;
        Ok(())
    }

    /// Checks every parameter; the error names it.
    pub fn validate(&self) -> anyhow::Result<()> {
        for (name, x, zero_ok) in [
            ("segment_length", self.segment_length, false),
            ("k", self.k, true),
            ("alpha", self.alpha, false),
            ("f0", self.f0, false),
            ("coupling", self.coupling, true),
            ("stick_gain", self.stick_gain, true),
            ("resonance_gain", self.resonance_gain, true),
            ("mileage_gain", self.mileage_gain, true),
            ("budget_gain", self.budget_gain, true),
            ("filter", self.filter, false),
            ("margin", self.margin, true),
            ("stress_share", self.stress_share, false),
            ("stress_gain", self.stress_gain, true),
        ] {
            anyhow::ensure!(
                x.is_finite() && (x > 0.0 || (zero_ok && x == 0.0)),
                "invalid reflex {name} = {x}: allowed a finite number {}",
                if zero_ok { ">= 0" } else { "> 0" }
            );
        }
        anyhow::ensure!(
            self.margin < 1.0 && self.stress_share <= 1.0,
            "invalid reflex margin = {} or stress_share = {}: allowed margin < 1, stress_share <= 1",
            self.margin,
            self.stress_share
        );
        Ok(())
    }
}

/// One segment's state.
#[derive(Debug, Clone, Copy, Default)]
struct Segment {
    /// First face and one past the last.
    faces: (usize, usize),
    /// Length, m.
    length: f64,
    phase: f64,
    omega: f64,
    log_amp: f64,
    /// Mean displacement at the start, m.
    start: f64,
    /// Mean displacement at the last step, m.
    position: f64,
    /// Filtered speed, m/s, and power, W.
    speed: f64,
    power: f64,
    /// Work done by this segment's muscle, J.
    work: f64,
    /// Demodulated strain: in phase with cos(phi), with sin(phi).
    strain_cos: f64,
    strain_sin: f64,
    /// Share of nodes stuck.
    stuck: f64,
    /// Force applied over the last step, N.
    force: f64,
}

/// The distributed reflex controller (see the module documentation).
#[derive(Debug, Clone)]
pub struct Reflex {
    opts: ReflexOptions,
    segments: Vec<Segment>,
    boundary: Boundary,
    cells: usize,
    dx: f64,
    length: f64,
    step: f64,
    stiffness: f64,
    k: f64,
    lag: f64,
    omega0: f64,
    target_mileage: f64,
    budget_per_length: f64,
    distance: f64,
    tension_limit: f64,
    field: Vec<f64>,
    started: bool,
}

pub(crate) fn build(ctx: &Context, params: &Params) -> anyhow::Result<Box<dyn Policy>> {
    Ok(Box::new(Reflex::new(
        ctx,
        ReflexOptions::from_params(params)?,
    )?))
}

impl Reflex {
    /// The policy for the plant of `ctx` with the parameters `o`.
    pub fn new(ctx: &Context, o: ReflexOptions) -> anyhow::Result<Self> {
        o.validate()?;
        let n = ctx.cells;
        let length = ctx.length;
        let dx = length / n as f64;
        let count = ((length / o.segment_length).round() as usize).clamp(1, n);
        let k = if o.k > 0.0 {
            o.k
        } else {
            let k_max = ctx.scenario.limits.k[1];
            match ctx.boundary {
                Boundary::Periodic => {
                    let m = (k_max * length / TAU + 1e-9).floor().max(1.0);
                    TAU * m / length
                }
                Boundary::Free => k_max,
            }
        };
        let c = ctx.body.wave_speed();
        let omega0 = o.alpha * k * c;
        let wave = crawler_physics::wave::Wave {
            f0: o.f0,
            k,
            omega: omega0,
            phase: 0.0,
        };
        wave.validate_for_body(length, n, ctx.boundary)?;
        // segment j holds faces [j n / count, (j + 1) n / count)
        let segments: Vec<Segment> = (0..count)
            .map(|j| {
                let faces = (j * n / count, (j + 1) * n / count);
                let centre = 0.5
                    * (ctx.boundary.face_position(faces.0, dx)
                        + ctx.boundary.face_position(faces.1 - 1, dx));
                Segment {
                    faces,
                    length: (faces.1 - faces.0) as f64 * dx,
                    phase: -k * centre,
                    omega: omega0,
                    log_amp: o.f0.ln(),
                    ..Segment::default()
                }
            })
            .collect();
        let task = ctx.scenario.task;
        Ok(Self {
            lag: k * length / count as f64,
            opts: o,
            segments,
            boundary: ctx.boundary,
            cells: n,
            dx,
            length,
            step: ctx.step,
            stiffness: ctx.body.stiffness(),
            k,
            omega0,
            target_mileage: task.min_mileage() * (1.0 + o.margin),
            budget_per_length: task.energy / length,
            distance: task.distance,
            tension_limit: o.stress_share * task.sigma_max * ctx.body.area,
            field: vec![0.0; n],
            started: false,
        })
    }

    /// Strain at face `i` (0 at a free body's end face).
    fn strain(&self, u: &[f64], i: usize) -> f64 {
        let n = self.cells;
        if self.boundary == Boundary::Free && i + 1 == n {
            return 0.0;
        }
        (u[(i + 1) % n] - u[i]) / self.dx
    }

    /// Mean displacement of the nodes of a segment (nodes with the segment's face indices).
    fn mean_u(u: &[f64], s: &Segment) -> f64 {
        u[s.faces.0..s.faces.1].iter().sum::<f64>() / (s.faces.1 - s.faces.0) as f64
    }

    fn sense(&mut self, obs: &Observation) {
        let h = self.step;
        let ae = self.stiffness;
        let o = self.opts;
        let a_f = (h / o.filter).min(1.0);
        let a_d = (h * self.omega0 / (2.0 * TAU)).min(1.0);
        for j in 0..self.segments.len() {
            let s = self.segments[j];
            let (lo, hi) = s.faces;
            let mut strain = 0.0;
            let mut stuck = 0usize;
            for i in lo..hi {
                strain += self.strain(obs.u, i);
                stuck += usize::from(obs.stuck[i]);
            }
            let count = (hi - lo) as f64;
            strain /= count;
            let position = Self::mean_u(obs.u, &s);
            let seg = &mut self.segments[j];
            if self.started {
                let speed = (position - seg.position) / h;
                seg.speed += a_f * (speed - seg.speed);
            } else {
                seg.start = position;
            }
            seg.position = position;
            seg.stuck = stuck as f64 / count;
            // strain against the segment's own oscillator (the strain of the muscle alone is
            // -m / A_c E = (A / A_c E) sin(phi): in phase with sin)
            let (sin, cos) = seg.phase.sin_cos();
            let norm = strain * ae / seg.log_amp.exp();
            seg.strain_sin += a_d * (norm * sin - seg.strain_sin);
            seg.strain_cos += a_d * (norm * cos - seg.strain_cos);
        }
    }

    fn advance(&mut self, obs: &Observation) {
        let h = self.step;
        let o = self.opts;
        let count = self.segments.len();
        let periodic = self.boundary == Boundary::Periodic;
        let phases: Vec<f64> = self.segments.iter().map(|s| s.phase).collect();
        let stuck: Vec<f64> = self.segments.iter().map(|s| s.stuck).collect();
        let neighbour = |j: usize, d: isize| -> Option<usize> {
            let i = j as isize + d;
            if (0..count as isize).contains(&i) {
                Some(i as usize)
            } else if periodic && count > 1 {
                Some(i.rem_euclid(count as isize) as usize)
            } else {
                None
            }
        };
        let ae = self.stiffness;
        for j in 0..count {
            let behind = neighbour(j, -1);
            let ahead = neighbour(j, 1);
            // stress reflex: own largest tension at the step's end
            let tension = {
                let s = &self.segments[j];
                (s.faces.0..s.faces.1)
                    .map(|i| ae * self.strain(obs.u, i) + s.force)
                    .fold(f64::NEG_INFINITY, f64::max)
            };
            let s = &mut self.segments[j];
            // phase: own frequency and the pull of the neighbours towards a lag of Δ
            let mut dphi = s.omega;
            if let Some(b) = behind {
                dphi += o.coupling * (phases[b] - phases[j] - self.lag).sin();
            }
            if let Some(a) = ahead {
                dphi += o.coupling * (phases[a] - phases[j] + self.lag).sin();
            }
            s.phase = (s.phase + h * dphi).rem_euclid(TAU);
            // resonance reflex: the strain's lag behind the oscillator towards a quarter period
            if o.resonance_gain > 0.0 {
                let lag = (-s.strain_cos).atan2(s.strain_sin);
                s.omega -= h * o.resonance_gain * self.omega0 * (lag - FRAC_PI_2);
                s.omega = s.omega.clamp(0.5 * self.omega0, 1.5 * self.omega0);
            }
            // energy reflex: own mileage against the task's, own energy against its share
            let power = s.power.max(0.0) * self.length / s.length;
            let mileage_error = if s.speed > 0.0 && power > 0.0 {
                (s.speed / power / self.target_mileage)
                    .ln()
                    .clamp(-1.0, 1.0)
            } else if s.speed <= 0.0 && power > 0.0 {
                -1.0
            } else {
                0.0
            };
            let share = self.budget_per_length * s.length;
            let travelled = s.position - s.start;
            let budget = (share * travelled / self.distance * (1.0 - o.margin) - s.work) / share;
            let mut da = o.mileage_gain * mileage_error + o.budget_gain * budget;
            if tension > self.tension_limit {
                da -= o.stress_gain * (tension / self.tension_limit - 1.0);
            }
            s.log_amp = (s.log_amp + h * da).clamp((1e-4f64).ln(), (5.0f64).ln());
        }
        // forces for the next step at the middle of the step (the field is held over it)
        for j in 0..count {
            let s = self.segments[j];
            let reflex = match (neighbour(j, 1), neighbour(j, -1)) {
                (Some(a), Some(b)) => stuck[a] - stuck[b],
                (Some(a), None) => stuck[a],
                (None, Some(b)) => -stuck[b],
                (None, None) => 0.0,
            };
            let amp = s.log_amp.exp();
            let mid = s.phase + 0.5 * h * s.omega;
            self.segments[j].force = amp * (-mid.sin() + o.stick_gain * reflex);
        }
    }

    /// Sets the field from the segments' forces and charges each segment the work of the change
    /// (the plant's accounting of a muscle-force jump, face by face).
    fn apply(&mut self, obs: &Observation) {
        let ae = self.stiffness;
        let h = self.step;
        let a_f = (h / self.opts.filter).min(1.0);
        let n = self.cells;
        for j in 0..self.segments.len() {
            let (lo, hi) = self.segments[j].faces;
            let new = self.segments[j].force;
            let mut work = 0.0;
            for i in lo..hi {
                let m = if self.boundary == Boundary::Free && i + 1 == n {
                    0.0 // the head's end face carries no tension
                } else {
                    new
                };
                let old = self.field[i];
                work += (self.strain(obs.u, i) + 0.5 * (old + m) / ae) * (m - old);
                self.field[i] = m;
            }
            work *= self.dx;
            let s = &mut self.segments[j];
            s.work += work;
            s.power += a_f * (work / h - s.power);
        }
    }
}

impl Policy for Reflex {
    fn name(&self) -> &str {
        "reflex"
    }

    fn act(&mut self, obs: &Observation) -> Actuation {
        if obs.u.len() != self.cells {
            return Actuation::Field(self.field.clone());
        }
        self.sense(obs);
        if self.started {
            self.advance(obs);
        } else {
            for s in self.segments.iter_mut() {
                s.force = s.log_amp.exp() * -(s.phase + 0.5 * self.step * s.omega).sin();
            }
            self.started = true;
        }
        self.apply(obs);
        Actuation::Field(self.field.clone())
    }

    fn describe(&self) -> String {
        let o = &self.opts;
        format!(
            "reflex: {} segments, k = {:.4} rad/m, omega_0 = {:.4} rad/s (alpha {}), A_0 = {} N, coupling {} 1/s, stick gain {}, resonance gain {} 1/s, energy gains {} and {} 1/s (mileage >= {:.4e} m/J), stress reflex above {} sigma_max",
            self.segments.len(),
            self.k,
            self.omega0,
            o.alpha,
            o.f0,
            o.coupling,
            o.stick_gain,
            o.resonance_gain,
            o.mileage_gain,
            o.budget_gain,
            self.target_mileage,
            o.stress_share
        )
    }
}

impl Reflex {
    /// Mean amplitude, N, and mean frequency, rad/s, over the segments (for reports and tests).
    pub fn mean_amplitude_and_frequency(&self) -> (f64, f64) {
        let n = self.segments.len() as f64;
        (
            self.segments.iter().map(|s| s.log_amp.exp()).sum::<f64>() / n,
            self.segments.iter().map(|s| s.omega).sum::<f64>() / n,
        )
    }
}
