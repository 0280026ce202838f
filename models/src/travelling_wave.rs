//! The improved reduced model: the exact steady state under a travelling wave on a periodic body.
//!
//! Under `A_m f = f0 sin(kx - omega t + phase)` the steady state is a travelling wave plus a drift,
//! `u = W(xi) + V t` with `xi = kx - omega t + phase` (`docs/physics.md` §4). With `y = W'` the
//! material velocity is `w = u_t = V - omega y` and the strain `u_x = k y`; substituting turns the
//! PDE into the periodic, nonsmooth ODE
//!
//! ```text
//!     kappa w' + c_v w + eps c_d (s - n_F) = f0 k cos xi,   s ∈ Sgn(w),   kappa = (A_c E k^2 - rho omega^2) / omega
//! ```
//!
//! in which `V` does not appear: the velocity profile is found on its own and `V = <w>` follows
//! from `<y> = 0` (the displacement is periodic in x). The ODE is split as `w = w_p + z`, with
//! `w_p` the exact periodic response to the cosine, and `z` integrated exactly between steps for
//! constant `s` (`z -> z*(s)` at rate `c_v / |kappa|`), marching in the direction in which the
//! homogeneous part decays. The set-valued `s` is resolved at the end of each step by the same
//! closed form as the plant ([`crawler_physics::friction::select`]), so stick phases (`w = 0`) are
//! exact; a sign change of `w` inside a step is located by interpolation and the rest of the step
//! continues from `w = 0`, so the one-period map of `z` is continuous (a contraction). Its fixed
//! point, the periodic solution, is found by bracketed regula falsi.

use std::f64::consts::TAU;

use crate::operating_point::OperatingPoint;
use crate::prediction::{Model, Prediction, Validity};

mod march;

use march::{March, StickRuns};

/// The travelling-wave model, `improved` on the command line.
#[derive(Debug, Clone, Copy)]
pub struct TravellingWaveModel {
    /// Steps per forcing period in the march.
    pub steps: usize,
    /// Shortest stick phase counted as an episode, in forcing periods.
    pub min_stick_periods: f64,
}

impl Default for TravellingWaveModel {
    fn default() -> Self {
        Self {
            steps: 1024,
            min_stick_periods: 0.005,
        }
    }
}

/// The steady profile over one period, for plots and overlays.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    /// `xi_j` of the samples, rad (marching order, taken mod 2 pi in [0, 2 pi)).
    pub xi: Vec<f64>,
    /// Material velocity `w(xi_j)`, m/s.
    pub velocity: Vec<f64>,
    /// Friction selection `s(xi_j)`.
    pub selection: Vec<f64>,
}

/// Sums over one period of the march.
#[derive(Debug, Clone, Copy, Default)]
struct Sweep {
    end_z: f64,
    /// d end_z / d z0 (0 once the period restarted from rest or from a crossing).
    slope: f64,
    /// Some step ended stuck: the rest of the period started from rest, whatever z0 was.
    stuck_once: bool,
    sum_w: f64,
    sum_s: f64,
    sum_w_cos: f64,
    /// Steps spent stuck, fractions of the steps in which a stick phase began or ended included.
    stuck: f64,
    max_tension_y: f64,
    min_w: f64,
    max_w: f64,
    episodes: usize,
}

impl TravellingWaveModel {
    fn setup(&self, op: &OperatingPoint) -> Setup {
        let w = op.wave;
        let cv = op.friction.viscous;
        let kappa =
            (op.body.stiffness() * w.k * w.k - op.body.density * w.omega * w.omega) / w.omega;
        let h = TAU / self.steps as f64;
        let denom = cv * cv + kappa * kappa;
        // w_p = P cos xi + Q sin xi solves kappa w' + c_v w = f0 k cos xi.
        let p = w.f0 * w.k * cv / denom;
        let q = w.f0 * w.k * kappa / denom;
        let e = if kappa == 0.0 {
            0.0
        } else {
            (-cv * h / kappa.abs()).exp()
        };
        let dir = if kappa < 0.0 { -1.0 } else { 1.0 };
        let g = (1.0 - e) * op.friction.band() / cv;
        let push = (1.0 - e) * op.friction.band() * op.friction.n_f / cv;
        let lambda = if kappa == 0.0 {
            f64::INFINITY
        } else {
            cv / kappa.abs()
        };
        let band = op.friction.band();
        Setup {
            inv_g: if g > 0.0 { 1.0 / g } else { 0.0 },
            c_plus: -band * (1.0 - op.friction.n_f) / cv * (1.0 - e),
            c_minus: band * (1.0 + op.friction.n_f) / cv * (1.0 - e),
            lambda,
            p,
            q,
            e,
            dir,
            g,
            push,
            h,
        }
    }

    /// One period of the march from `z0`. With `FULL = false` only the end state and the map's
    /// slope are computed (the solver's sweeps); with `FULL = true` every sum as well.
    fn sweep<const FULL: bool>(
        &self,
        op: &OperatingPoint,
        s: &Setup,
        z0: f64,
        mut profile: Option<&mut Profile>,
    ) -> Sweep {
        let (ch, sh) = ((s.dir * s.h).cos(), (s.dir * s.h).sin());
        let (mut c, mut sn) = (1.0f64, 0.0f64);
        let mut z = z0;
        let mut wp_prev = s.p; // w_p at xi = 0
        let w0 = wp_prev + z0;
        let mut dir = if w0 == 0.0 { 0.0 } else { w0.signum() };
        let mut out = Sweep {
            max_tension_y: f64::NEG_INFINITY,
            min_w: f64::INFINITY,
            max_w: f64::NEG_INFINITY,
            slope: 1.0,
            ..Default::default()
        };
        let march = March {
            s,
            band: op.friction.band(),
            cv: op.friction.viscous,
            n_f: op.friction.n_f,
        };
        let ae = op.body.stiffness();
        let w_wave = op.wave;
        let mut runs = StickRuns::new(self.min_stick_periods * self.steps as f64);
        // The friction selection a point at rest needs, `f0 k cos xi / (eps c_d) + n_F`: a stick
        // phase begins or ends where it crosses +-1 (used to time the switch inside its step).
        let band_f = op.friction.band();
        let held = |cos_xi: f64| {
            if band_f > 0.0 {
                w_wave.f0 * w_wave.k * cos_xi / band_f + op.friction.n_f
            } else {
                f64::INFINITY
            }
        };
        let mut held_prev = held(1.0);
        for j in 1..=self.steps {
            // rotate to xi_j = dir * j * h (resynchronise now and then to bound round-off)
            if j % 256 == 0 {
                let (a, b) = (s.dir * j as f64 * s.h).sin_cos();
                sn = a;
                c = b;
            } else {
                let nc = c * ch - sn * sh;
                sn = sn * ch + c * sh;
                c = nc;
            }
            let wp = s.p * c + s.q * sn;
            // `dir` is the direction of sliding (+1 / -1), or 0 at rest; it only changes at a
            // crossing located inside a step or when the implicit stick rule releases the point.
            let held_now = held(c);
            let step = if dir != 0.0 && s.e > 0.0 {
                march.slide(j, z, wp, wp_prev, &mut dir, &mut out)
            } else {
                // At rest (or at exact resonance, where w follows the force pointwise).
                march.rest(z, wp, held_prev, held_now, &mut dir, &mut out)
            };
            z = step.z_next;
            wp_prev = wp;
            held_prev = held_now;
            if !FULL {
                continue;
            }
            let w = step.w;
            out.sum_w += w;
            out.min_w = out.min_w.min(w);
            out.max_w = out.max_w.max(w);
            out.sum_s += step.s_mean;
            out.sum_w_cos += w * c;
            out.stuck += step.rest_share;
            runs.step(step.rest_share, step.stuck, &mut out.episodes);
            // tension without the V term: T = A_c E k y + f0 sin xi with y = (V - w) / omega
            let tension_wo_v = -ae * w_wave.k * w / w_wave.omega + w_wave.f0 * sn;
            out.max_tension_y = out.max_tension_y.max(tension_wo_v);
            if let Some(pr) = profile.as_deref_mut() {
                pr.xi.push((s.dir * j as f64 * s.h).rem_euclid(TAU));
                pr.velocity.push(w);
                pr.selection.push(step.s_mean);
            }
        }
        runs.finish(&mut out.episodes);
        out.end_z = z;
        out
    }

    /// Solves the periodic problem; returns the final sweep (and fills `profile` if given).
    ///
    /// The period map `z0 -> z_end` is continuous and a contraction (slope in [0, 1)), so the
    /// residual `r(z0) = z_end - z0` is decreasing: its root is bracketed and found by Illinois
    /// regula falsi.
    fn solve(&self, op: &OperatingPoint, profile: Option<&mut Profile>) -> Option<(Setup, Sweep)> {
        let s = self.setup(op);
        let scale = (s.p.abs() + s.q.abs() + op.friction.band() / op.friction.viscous).max(1e-300);
        let tol = 1e-11 * scale;
        let r = |z0: f64| self.sweep::<false>(op, &s, z0, None).end_z - z0;
        // Newton with the sweep's slope for the first step (exact while the period only slides
        // one way or sticks), then secant steps on the residual, which is smooth between
        // switching patterns: a few sweeps. If it stops contracting, fall back to bracketed
        // regula falsi from 0.
        let mut converged = false;
        let first = self.sweep::<false>(op, &s, 0.0, None);
        let (mut z_prev, mut r_prev) = (0.0, (first.end_z, first.slope));
        let r0 = r_prev.0;
        let mut z = r0 / (1.0 - r_prev.1);
        r_prev.0 = r0;
        let mut last = r0.abs();
        if last <= tol {
            z = 0.0;
            converged = true;
        }
        // Once the iteration is about to land within the tolerance, the next sweep carries every
        // sum: if it does land, it is the answer (without a profile to fill) and the last sweep
        // is saved; if not, its end state serves the iteration all the same.
        let mut last_full = None;
        // A period that stuck somewhere ends where it would from any z0 that sticks there too:
        // the first step, z = z_end, is then the fixed point (to the last bit, as a rule).
        let mut expect_landing = first.stuck_once;
        for _ in 0..12 {
            if converged {
                break;
            }
            let sw = if expect_landing {
                self.sweep::<true>(op, &s, z, None)
            } else {
                self.sweep::<false>(op, &s, z, None)
            };
            let res = sw.end_z - z;
            if res.abs() <= tol {
                converged = true;
                last_full = expect_landing.then_some(sw);
                break;
            }
            if !(res.is_finite() && res.abs() < 0.7 * last) {
                break;
            }
            // the secant converges faster than linearly: the next residual is at most about
            // this one times the ratio by which the last step shrank it
            expect_landing = res.abs() * (res.abs() / last) <= tol;
            last = res.abs();
            let denom = res - r_prev.0;
            let next = if denom != 0.0 {
                z - res * (z - z_prev) / denom
            } else {
                z + res
            };
            z_prev = z;
            r_prev.0 = res;
            z = next;
        }
        if converged {
            let sw = match (last_full, profile) {
                (Some(sw), None) => sw,
                (_, profile) => self.sweep::<true>(op, &s, z, profile),
            };
            return sw.sum_w.is_finite().then_some((s, sw));
        }
        let mut root = 0.0;
        let r0 = r(root);
        if r0.abs() > tol {
            // Newton-like first step for a contraction with slope in [0, 1): z_end itself.
            let (mut lo, mut flo) = (0.0, r0);
            let mut hi = r0;
            let mut fhi = r(hi);
            let mut widen = 0;
            while fhi.signum() == flo.signum() && fhi.abs() > tol && widen < 60 {
                lo = hi;
                flo = fhi;
                hi += 2.0 * (hi - root).abs().max(scale * 1e-9) * flo.signum();
                fhi = r(hi);
                widen += 1;
            }
            if fhi.abs() <= tol {
                root = hi;
            } else if fhi.signum() == flo.signum() {
                return None;
            } else {
                let mut side = 0i8;
                root = lo;
                for _ in 0..200 {
                    let m = (lo * fhi - hi * flo) / (fhi - flo);
                    let fm = r(m);
                    root = m;
                    if fm.abs() <= tol || (hi - lo).abs() <= 1e-15 * scale {
                        break;
                    }
                    if fm.signum() == flo.signum() {
                        lo = m;
                        flo = fm;
                        if side == -1 {
                            fhi *= 0.5;
                        }
                        side = -1;
                    } else {
                        hi = m;
                        fhi = fm;
                        if side == 1 {
                            flo *= 0.5;
                        }
                        side = 1;
                    }
                }
            }
        }
        let sw = self.sweep::<true>(op, &s, root, profile);
        let res = sw.end_z - root;
        (res.abs() <= 1e-9 * scale && sw.sum_w.is_finite()).then_some((s, sw))
    }

    /// The steady velocity profile over one period.
    pub fn profile(&self, op: &OperatingPoint) -> Option<Profile> {
        let mut pr = Profile {
            xi: Vec::new(),
            velocity: Vec::new(),
            selection: Vec::new(),
        };
        self.solve(op, Some(&mut pr))?;
        Some(pr)
    }
}

#[derive(Debug, Clone, Copy)]
struct Setup {
    /// 1 / g (0 when g = 0).
    inv_g: f64,
    /// z*(s) (1 - E), z* = -eps c_d (s - n_F) / c_v, for s = +1 and s = -1.
    c_plus: f64,
    c_minus: f64,
    lambda: f64,
    p: f64,
    q: f64,
    e: f64,
    dir: f64,
    g: f64,
    push: f64,
    h: f64,
}

impl Model for TravellingWaveModel {
    fn name(&self) -> &'static str {
        "improved"
    }

    fn predict(&self, op: &OperatingPoint) -> Prediction {
        let Some((s, sw)) = self.solve(op, None) else {
            return Prediction::outside(
                "improved",
                "the periodic travelling-wave solution did not converge".into(),
            );
        };
        let m = self.steps as f64;
        let w = op.wave;
        let velocity = sw.sum_w / m;
        // P per wavelength = f0 * integral_0^{2 pi} w cos xi dxi (actuator power, eq. 7).
        let power = w.f0 * sw.sum_w_cos * s.h * op.wavelengths;
        let max_tension = sw.max_tension_y + op.body.stiffness() * w.k * velocity / w.omega;
        let stress = max_tension / op.body.area;
        // strain u_x = k y = k (V - w) / omega
        let strain = w.k / w.omega * (velocity - sw.min_w).abs().max((sw.max_w - velocity).abs());
        // The march carries w, whose swing grows with f0, to about f64::EPSILON of its largest
        // value (measured: V's error is 1 to 3 EPSILON max |w|), and V is a small mean of it.
        // Once that round-off nears the speed bound the numbers are noise (at the paper's point
        // V is 1 % off at f0 = 1e12 N and changes sign near 1e14 N; P overflows near 1e150 N).
        let round_off = 8.0 * f64::EPSILON * sw.max_w.abs().max(sw.min_w.abs());
        let bound = op.friction.speed_bound();
        if bound > 0.0 && round_off > 1e-3 * bound {
            return Prediction::outside(
                "improved",
                format!(
                    "f0 = {:e} N is too strong for f64: the round-off of the mean speed ({round_off:.1e} m/s) exceeds a thousandth of the speed bound eps c_d (1 + n_F) / c_v = {bound:.3e} m/s",
                    w.f0
                ),
            );
        }
        let numbers = [velocity, power, stress, strain, sw.stuck, sw.sum_s];
        if numbers.iter().any(|x| !x.is_finite()) {
            return Prediction::outside(
                "improved",
                format!("not representable in f64 at f0 = {:e} N (overflow)", w.f0),
            );
        }
        Prediction {
            model: "improved",
            velocity: Some(velocity),
            power: Some(power),
            mileage: Some(velocity.abs() / power),
            max_stress: Some(stress),
            max_strain: Some(strain),
            stuck_fraction: Some(sw.stuck / m),
            mean_friction_selection: Some(sw.sum_s / m),
            episodes_per_node_per_period: Some(sw.episodes as f64),
            validity: Validity::Valid,
        }
    }
}
