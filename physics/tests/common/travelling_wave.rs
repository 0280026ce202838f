//! An independent reference for the plant's stick statistics: the periodic travelling-wave steady
//! state, solved exactly piece by piece (no time step).
//!
//! Under `A_m f = f0 sin(kx - omega t)` on a periodic body the steady state is
//! `u = W(kx - omega t) + V t`. Its material velocity `w = u_t`, as a function of
//! `eta = omega t - kx` (time at a fixed point, in radians of phase), solves
//!
//! ```text
//!     K w' + c_v w + eps c_d (s - n_F) = f0 k cos(eta),   s ∈ Sgn(w),   K = |A_c E k^2 - rho omega^2| / omega
//! ```
//!
//! marched forward in `eta` (the direction in which its homogeneous part decays). With `s` fixed
//! it is linear with the closed-form solution used below; a sliding piece ends where `w` reaches
//! zero (then the point sticks if the force `f0 k cos(eta)` lies in the static band, else it
//! reverses), a stick piece where the force leaves the band. Event times are found by bisection to
//! round-off. At exact resonance (`K = 0`) the equation is algebraic and solved in closed form.

use std::f64::consts::{PI, TAU};

/// Statistics of the steady state over one forcing period.
#[derive(Debug, Clone, Copy)]
pub struct Steady {
    /// Share of the period a point spends stuck.
    pub stuck_fraction: f64,
    /// Mean speed `V = <w>`, m/s.
    pub velocity: f64,
    /// Stick phases per period.
    pub episodes: usize,
    /// Mean stick-phase duration, s.
    pub mean_duration: f64,
}

/// The problem: friction band `band = eps c_d` (N/m), `n_f`, `c_v` (N s/m^2), drive `a = f0 k`
/// (N/m), `kappa = |A_c E k^2 - rho omega^2| / omega` (N s/m^2) and `omega` (rad/s).
pub struct Problem {
    pub band: f64,
    pub n_f: f64,
    pub cv: f64,
    pub a: f64,
    pub kappa: f64,
    pub omega: f64,
}

impl Problem {
    /// The problem of a scenario's body, friction and wave.
    pub fn of(s: &crawler_physics::Scenario) -> Self {
        let b = s.plant.body;
        let f = s.plant.friction;
        let w = s.wave;
        Self {
            band: f.band(),
            n_f: f.n_f,
            cv: f.viscous,
            a: w.f0 * w.k,
            kappa: (b.stiffness() * w.k * w.k - b.density * w.omega * w.omega).abs() / w.omega,
            omega: w.omega,
        }
    }

    /// The friction selection a point at rest needs at phase `eta`.
    fn held(&self, eta: f64) -> f64 {
        self.a * eta.cos() / self.band + self.n_f
    }

    /// The steady state.
    pub fn solve(&self) -> Steady {
        if self.kappa == 0.0 {
            self.algebraic()
        } else {
            self.march()
        }
    }

    /// `K = 0`: `c_v w = a cos(eta) - band (s - n_F)`, stuck where the force is in the band.
    fn algebraic(&self) -> Steady {
        let lo = (-1.0 - self.n_f) * self.band / self.a;
        let hi = (1.0 - self.n_f) * self.band / self.a;
        let (lo, hi) = (lo.max(-1.0), hi.min(1.0));
        let measure = if lo < hi {
            2.0 * (lo.acos() - hi.acos())
        } else {
            0.0
        };
        // integral of (cos - c) over cos > c, and over cos < c
        let above = |c: f64| {
            if c >= 1.0 {
                0.0
            } else {
                let x = c.max(-1.0).acos();
                2.0 * (x.sin() - c * x)
            }
        };
        let below = |c: f64| {
            if c <= -1.0 {
                0.0
            } else {
                let x = c.min(1.0).acos();
                -2.0 * (x.sin() + c * (PI - x))
            }
        };
        let velocity = self.a * (above(hi) + below(lo)) / (self.cv * TAU);
        let episodes = if measure > 0.0 {
            if lo > -1.0 && hi < 1.0 {
                2
            } else {
                1
            }
        } else {
            0
        };
        Steady {
            stuck_fraction: measure / TAU,
            velocity,
            episodes,
            mean_duration: if episodes > 0 {
                measure / episodes as f64 / self.omega
            } else {
                0.0
            },
        }
    }

    /// `K > 0`: march piece by piece for several periods; statistics of the last.
    fn march(&self) -> Steady {
        let lambda = self.cv / self.kappa;
        let periods = (40.0 / (TAU * lambda)).ceil().max(3.0) as usize + 1;
        let last = (periods - 1) as f64 * TAU;
        let end = periods as f64 * TAU;
        let particular = |eta: f64, s: f64| {
            -self.band * (s - self.n_f) / self.cv
                + self.a / (self.cv * self.cv + self.kappa * self.kappa)
                    * (self.cv * eta.cos() + self.kappa * eta.sin())
        };
        // integral of the particular solution from e0 to e1
        let particular_integral = |e0: f64, e1: f64, s: f64| {
            -self.band * (s - self.n_f) / self.cv * (e1 - e0)
                + self.a / (self.cv * self.cv + self.kappa * self.kappa)
                    * (self.cv * (e1.sin() - e0.sin()) - self.kappa * (e1.cos() - e0.cos()))
        };
        let h = TAU / 4096.0;
        let bisect = |f: &dyn Fn(f64) -> f64, mut x0: f64, mut x1: f64| {
            for _ in 0..200 {
                let m = 0.5 * (x0 + x1);
                if m == x0 || m == x1 {
                    break;
                }
                if (f(m) > 0.0) == (f(x0) > 0.0) {
                    x0 = m;
                } else {
                    x1 = m;
                }
            }
            x1
        };
        let (mut stuck, mut integral, mut episodes) = (0.0, 0.0, 0usize);
        // the part of [a, b] inside the last period
        let clip = |a: f64, b: f64| (a.max(last), b.min(end));
        let mut eta = 0.0;
        let mut w = 0.0;
        let mut mode = {
            let q = self.held(0.0);
            if (-1.0..=1.0).contains(&q) {
                0.0
            } else {
                q.signum()
            }
        };
        while eta < end {
            if mode == 0.0 {
                let out = |x: f64| self.held(x).abs() - 1.0;
                let mut e1 = eta;
                while e1 < end && out(e1 + h) <= 0.0 {
                    e1 += h;
                }
                let leave = if e1 >= end {
                    end
                } else {
                    bisect(&out, e1, e1 + h)
                };
                let (a, b) = clip(eta, leave);
                if b > a {
                    stuck += b - a;
                }
                if leave >= last && leave < end {
                    episodes += 1;
                }
                eta = leave;
                w = 0.0;
                mode = self.held(leave).signum();
            } else {
                let (e0, w0, s) = (eta, w, mode);
                let at = |x: f64| {
                    particular(x, s) + (w0 - particular(e0, s)) * (-lambda * (x - e0)).exp()
                };
                let mut e1 = eta;
                while e1 < end && at(e1 + h) * s > 0.0 {
                    e1 += h;
                }
                let stop = if e1 >= end {
                    end
                } else {
                    bisect(&|x| at(x) * s, e1, e1 + h)
                };
                let (a, b) = clip(e0, stop);
                if b > a {
                    integral += particular_integral(a, b, s)
                        + (w0 - particular(e0, s))
                            * ((-lambda * (a - e0)).exp() - (-lambda * (b - e0)).exp())
                            / lambda;
                }
                eta = stop.max(eta + 1e-15);
                w = 0.0;
                mode = if (-1.0..=1.0).contains(&self.held(eta)) {
                    0.0
                } else {
                    -s
                };
            }
        }
        Steady {
            stuck_fraction: stuck / TAU,
            velocity: integral / TAU,
            episodes,
            mean_duration: if episodes > 0 {
                stuck / episodes as f64 / self.omega
            } else {
                0.0
            },
        }
    }
}
