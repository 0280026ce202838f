//! One step of the travelling-wave march, and the stick phases it counts: the inner loop of
//! [`super::TravellingWaveModel`]'s period sweep, split off it.

use crawler_physics::friction::{select, select_with_inverse};

use super::{Setup, Sweep};

/// The direction of sliding after a step that ended at velocity `w`: +1, -1, or 0 at rest.
fn direction(stuck: bool, w: f64) -> f64 {
    if stuck || w == 0.0 {
        0.0
    } else {
        w.signum()
    }
}

/// The outcome of one step of the march.
#[derive(Debug, Clone, Copy)]
pub(super) struct Step {
    /// Material velocity `w` at the end of the step, m/s.
    pub(super) w: f64,
    /// `z = w - w_p` at the end of the step, m/s.
    pub(super) z_next: f64,
    /// Mean friction selection over the step (dimensionless, in [-1, 1]).
    pub(super) s_mean: f64,
    /// The step ended stuck.
    pub(super) stuck: bool,
    /// Share of the step in which the point was at rest, in [0, 1].
    pub(super) rest_share: f64,
}

/// The constants of one period's march that its steps need.
pub(super) struct March<'a> {
    /// The period's precomputed coefficients.
    pub(super) s: &'a Setup,
    /// Friction band `eps c_d`, N/m.
    pub(super) band: f64,
    /// Viscous coefficient `c_v`, N s/m^2.
    pub(super) cv: f64,
    /// Friction asymmetry `n_F` (dimensionless).
    pub(super) n_f: f64,
}

impl March<'_> {
    /// One step of `j` while sliding in direction `dir` (+1 / -1): the exact step for constant
    /// `s`, or, if `w` changes sign inside the step, the crossing and the closed-form stick rule
    /// over the rest of it. `z`, `wp`, `wp_prev` in m/s; updates `dir` and the map's slope.
    #[inline(always)]
    pub(super) fn slide(
        &self,
        j: usize,
        z: f64,
        wp: f64,
        wp_prev: f64,
        dir: &mut f64,
        out: &mut Sweep,
    ) -> Step {
        let s = self.s;
        // Sliding: the exact step for constant s is z <- z E + z*(s) (1 - E).
        let z_new = z * s.e + if *dir > 0.0 { s.c_plus } else { s.c_minus };
        let w_trial = wp + z_new;
        if w_trial * *dir > 0.0 {
            // still sliding the same way: `dir` is left as it is (recomputing it from w
            // would put the sign of w on the step's dependency chain, a third of its time)
            out.slope *= s.e;
            return Step {
                w: w_trial,
                z_next: z_new,
                s_mean: *dir,
                stuck: false,
                rest_share: 0.0,
            };
        }
        // w changed sign inside the step: locate the crossing, continue from w = 0
        // with the closed-form stick rule over the rest of the step.
        let w_old = wp_prev + z;
        let theta = w_old / (w_old - w_trial);
        let xi_cross = s.dir * (j as f64 - 1.0 + theta) * s.h;
        let wp_cross = s.p * xi_cross.cos() + s.q * xi_cross.sin();
        let e_rest = (-s.lambda * (1.0 - theta) * s.h).exp();
        let g_rest = (1.0 - e_rest) * self.band / self.cv;
        let b = wp + e_rest * (-wp_cross) + g_rest * self.n_f;
        let sel = select(b, g_rest);
        // the end state no longer depends on z0 through this step (it restarted at w = 0)
        out.slope = 0.0;
        let rest_share = if sel.stuck { 1.0 - theta } else { 0.0 };
        out.stuck_once |= sel.stuck;
        let s_mean = theta * *dir + (1.0 - theta) * sel.s;
        *dir = direction(sel.stuck, sel.velocity);
        Step {
            w: sel.velocity,
            z_next: sel.velocity - wp,
            s_mean,
            stuck: sel.stuck,
            rest_share,
        }
    }

    /// One implicit step from rest (`dir == 0`) or at exact resonance. `held_prev`, `held_now`
    /// are the selections a point at rest needs at the step's ends (dimensionless), which time a
    /// switch inside the step. `z`, `wp` in m/s; updates `dir` and the map's slope.
    #[inline(always)]
    pub(super) fn rest(
        &self,
        z: f64,
        wp: f64,
        held_prev: f64,
        held_now: f64,
        dir: &mut f64,
        out: &mut Sweep,
    ) -> Step {
        let s = self.s;
        let b = wp + s.e * z + s.push;
        let sel = select_with_inverse(b, s.g, s.inv_g);
        out.slope = if sel.stuck { 0.0 } else { out.slope * s.e };
        out.stuck_once |= sel.stuck;
        // A switch inside the step: where the held selection crosses the band edge.
        let was_at_rest = *dir == 0.0;
        let edge_share = || {
            let edge = if held_now.abs() > 1.0 {
                held_now.signum()
            } else {
                held_prev.signum()
            };
            if held_now == held_prev {
                0.5
            } else {
                ((edge - held_prev) / (held_now - held_prev)).clamp(0.0, 1.0)
            }
        };
        let rest_share = match (was_at_rest, sel.stuck) {
            (true, true) => 1.0,
            (true, false) => edge_share(),
            (false, true) => 1.0 - edge_share(),
            (false, false) => 0.0,
        };
        *dir = direction(sel.stuck, sel.velocity);
        Step {
            w: sel.velocity,
            z_next: sel.velocity - wp,
            s_mean: sel.s,
            stuck: sel.stuck,
            rest_share,
        }
    }
}

/// The stick phases of one period, which count the stick episodes.
pub(super) struct StickRuns {
    /// Shortest stick phase counted as an episode, steps.
    min_run: f64,
    /// Current stick phase's length, steps.
    run: f64,
    /// Length of the stick phase the period began in, steps.
    first_run: Option<f64>,
    /// Some step of the period ended sliding.
    ended_first_slide: bool,
}

impl StickRuns {
    /// No stick phase yet; phases shorter than `min_run` steps are not counted.
    pub(super) fn new(min_run: f64) -> Self {
        Self {
            min_run,
            run: 0.0,
            first_run: None,
            ended_first_slide: false,
        }
    }

    /// Adds a step with `rest_share` of it at rest (in [0, 1]) that ended `stuck` or not; counts
    /// into `episodes` a stick phase that ended in it.
    pub(super) fn step(&mut self, rest_share: f64, stuck: bool, episodes: &mut usize) {
        self.run += rest_share;
        if !stuck {
            if self.run > 0.0 {
                if self.ended_first_slide {
                    if self.run >= self.min_run {
                        *episodes += 1;
                    }
                } else {
                    self.first_run = Some(self.run);
                }
            }
            self.ended_first_slide = true;
            self.run = 0.0;
        }
    }

    /// Counts into `episodes` the stick run that wraps around the period boundary (once).
    pub(super) fn finish(&self, episodes: &mut usize) {
        // A stick run that wraps around the period boundary counts once.
        let wrap = self.run + self.first_run.unwrap_or(0.0);
        if self.run > 0.0 && !self.ended_first_slide {
            // stuck for the whole period: no episode ends
        } else if wrap >= self.min_run && (self.run > 0.0 || self.first_run.is_some()) {
            *episodes += 1;
        }
    }
}
