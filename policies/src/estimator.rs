//! Online estimation of the pipe's friction from what the plant sends every communication step.
//!
//! Two balances of the whole body hold exactly for the plant's scheme and involve the unknowns
//! linearly. With `theta = (c_v, eps c_d, eps c_d n_F)`, over any stretch of time:
//!
//! ```text
//! momentum:  c_v ∫V dt + eps c_d ∫a dt - eps c_d n_F ∫b dt = -rho ΔV - ∫g dt
//! energy:    c_v ∫<v²> dt + eps c_d ∫<|v|> dt - eps c_d n_F ∫V dt = ∫P dt / L - ΔE / L
//! ```
//!
//! where `V` is the body's mean speed, `a = <sgn v>` and `b` the share of sliding nodes, `g` the
//! mean friction force carried by the stuck nodes (for a node held by static friction the
//! friction force equals the elastic and muscle force on it, `dT/dx`, which the controller sees
//! in the tension field), `<v²>` and `<|v|>` node averages, `P` the actuator's input power and
//! `E = dx Σ (rho v²/2 + T²/(2 A_c E))` the body's kinetic and elastic energy. The first is the
//! momentum identity behind `V = eps c_d (n_F - <s>) / c_v` (elastic and muscle forces cancel in
//! the body sum), the second the power balance (input = viscous + dry dissipation + change of
//! stored energy). `∫V dt` and `∫P dt` are exact (the plant reports the step averages); the
//! other integrals are trapezoidal sums of the snapshots at the ends of each step, which is exact
//! for a travelling wave on a periodic body (every node average is then constant in time) and
//! accurate to the step otherwise.
//!
//! The balances are summed over windows of [`EstimatorOptions::window`] steps; each window gives
//! one row of each kind. The rows enter a Bayesian least-squares estimate with a Gaussian prior at
//! the values the controller was told and exponential forgetting of old windows (time constant
//! [`EstimatorOptions::memory`]), so the estimate follows a pipe whose friction changes along the
//! way. Each row is trusted to [`EstimatorOptions::row_tolerance`] of the sum of the magnitudes of
//! its terms; the reported uncertainty is the posterior standard deviation, inflated by the
//! observed residuals when they exceed that tolerance.
//!
//! What can be identified: in a steady gait the two balances fix two combinations of the three
//! unknowns; `c_v` then stays at its prior (it is learnt from transients and changes of gait).
//! When the body never slides backwards (strong stick-slip) the backward friction level
//! `eps c_d (1 + n_F)` does not act on the motion at all and stays at its prior too, with a
//! large uncertainty on eps and n_F: they are then not identifiable, and the estimate says so.

use crawler_physics::params::{Body, Boundary, Friction};

/// Settings of the estimator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorOptions {
    /// Communication steps per window (one momentum and one energy row each).
    pub window: u32,
    /// Forgetting time constant, s (windows older than this count `1/e` as much).
    pub memory: f64,
    /// Relative trust in each energy row: its residual's standard deviation is this share of the
    /// sum of the magnitudes of its terms.
    pub row_tolerance: f64,
    /// The same for each momentum row. Its stuck-node term is read from the tension at the step
    /// ends only, and the dry terms nearly cancel; measured on the plant, its residual is a few
    /// per cent of its terms at 512 cells and tens of per cent at 128, so it is trusted less.
    pub momentum_tolerance: f64,
    /// Prior standard deviation of `eps` (absolute).
    pub prior_eps_std: f64,
    /// Prior standard deviation of `n_F` (absolute).
    pub prior_n_f_std: f64,
    /// Prior standard deviation of `c_v`, relative to the told value (0: `c_v` is taken as known).
    pub prior_viscous_rel_std: f64,
}

impl Default for EstimatorOptions {
    fn default() -> Self {
        Self {
            window: 32,
            memory: 2.0,
            row_tolerance: 0.01,
            momentum_tolerance: 0.3,
            prior_eps_std: 1.0,
            prior_n_f_std: 0.5,
            prior_viscous_rel_std: 0.3,
        }
    }
}

impl EstimatorOptions {
    /// Checks ranges; the error names the setting.
    pub fn validate(&self) -> anyhow::Result<()> {
        anyhow::ensure!(
            (1..=100_000).contains(&self.window),
            "invalid estimator window = {}: allowed 1 to 100000 steps",
            self.window
        );
        for (name, x, zero_ok) in [
            ("memory", self.memory, false),
            ("row_tolerance", self.row_tolerance, false),
            ("momentum_tolerance", self.momentum_tolerance, false),
            ("prior_eps_std", self.prior_eps_std, false),
            ("prior_n_f_std", self.prior_n_f_std, false),
            ("prior_viscous_rel_std", self.prior_viscous_rel_std, true),
        ] {
            anyhow::ensure!(
                x.is_finite() && (x > 0.0 || (zero_ok && x == 0.0)),
                "invalid estimator {name} = {x}: allowed a finite number {}",
                if zero_ok { ">= 0" } else { "> 0" }
            );
        }
        Ok(())
    }
}

/// The current estimate with its uncertainty (one standard deviation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Viscous coefficient `c_v`, N s/m^2.
    pub viscous: f64,
    /// Its standard deviation.
    pub viscous_std: f64,
    /// Dry-friction coefficient eps.
    pub eps: f64,
    /// Its standard deviation.
    pub eps_std: f64,
    /// Asymmetry n_F.
    pub n_f: f64,
    /// Its standard deviation.
    pub n_f_std: f64,
    /// Windows taken so far.
    pub windows: u64,
    /// Mean squared residual of the rows in units of their tolerance (about 1 or less when the
    /// balances hold as trusted).
    pub chi2: f64,
}

impl Estimate {
    /// The estimate as a friction law (eps >= 0 and n_F clamped to [0, 1]; `c_d` as told).
    pub fn friction(&self, told: &Friction) -> Friction {
        Friction {
            viscous: self.viscous.max(1e-6 * told.viscous),
            dry: told.dry,
            eps: self.eps.max(0.0),
            n_f: self.n_f.clamp(0.0, 1.0),
        }
    }

    /// One line: `eps = 0.301 ± 0.004, n_F = 0.698 ± 0.008, c_v = 1.00 ± 0.30 N s/m^2`.
    pub fn describe(&self) -> String {
        format!(
            "eps = {:.4} ± {:.4}, n_F = {:.4} ± {:.4}, c_v = {:.4} ± {:.4} N s/m^2 ({} windows, chi2 {:.2})",
            self.eps,
            self.eps_std,
            self.n_f,
            self.n_f_std,
            self.viscous,
            self.viscous_std,
            self.windows,
            self.chi2
        )
    }
}

/// What the estimator needs of one communication step (the plant's state at its end).
#[derive(Debug, Clone, Copy)]
pub struct Sample<'a> {
    /// Velocity at the nodes, m/s.
    pub v: &'a [f64],
    /// Tension at the half nodes, N.
    pub tension: &'a [f64],
    /// Nodes held by static friction.
    pub stuck: &'a [bool],
    /// Mean speed over the step that ended here, m/s.
    pub mean_speed: f64,
    /// Input power over the step that ended here, W.
    pub input_power: f64,
}

/// Node averages of one snapshot.
#[derive(Debug, Clone, Copy, Default)]
struct Snapshot {
    /// Mean velocity, m/s.
    mean_v: f64,
    /// `<sgn v>` over all nodes (stuck nodes count 0).
    sign: f64,
    /// Share of sliding nodes.
    sliding: f64,
    /// Mean friction force on the stuck nodes, `(1/N) Σ_stuck dT/dx`, N/m.
    stuck_force: f64,
    /// `<v²>`, m²/s².
    v2: f64,
    /// `<|v|>`, m/s.
    abs_v: f64,
    /// Kinetic + elastic energy of the body, J.
    energy: f64,
}

/// Sums over the current window.
#[derive(Debug, Clone, Copy, Default)]
struct Window {
    steps: u32,
    start: Snapshot,
    int_v: f64,
    int_sign: f64,
    int_sliding: f64,
    int_stuck_force: f64,
    int_v2: f64,
    int_abs_v: f64,
    int_power: f64,
}

type M3 = [[f64; 3]; 3];

/// The friction estimator (see the module documentation).
#[derive(Debug, Clone)]
pub struct FrictionEstimator {
    opts: EstimatorOptions,
    body: Body,
    told: Friction,
    boundary: Boundary,
    length: f64,
    dx: f64,
    step: f64,
    prior_mean: [f64; 3],
    prior_precision: [f64; 3],
    info: M3,
    rhs: [f64; 3],
    last: Option<Snapshot>,
    window: Window,
    windows: u64,
    chi2_sum: f64,
    chi2_weight: f64,
    theta: [f64; 3],
    cov: M3,
}

impl FrictionEstimator {
    /// An estimator for a body of `length` m on `cells` cells stepped every `step` s, with the
    /// prior at the `told` friction.
    pub fn new(
        opts: EstimatorOptions,
        body: Body,
        told: Friction,
        boundary: Boundary,
        length: f64,
        cells: usize,
        step: f64,
    ) -> anyhow::Result<Self> {
        opts.validate()?;
        anyhow::ensure!(
            cells >= 2 && length > 0.0 && step > 0.0 && told.dry > 0.0,
            "estimator: needs at least 2 cells, a positive length, step and normal load c_d"
        );
        let cd = told.dry;
        let prior_mean = [told.viscous, told.eps * cd, told.eps * told.n_f * cd];
        let sd_v = (opts.prior_viscous_rel_std * told.viscous).max(1e-9 * told.viscous);
        let sd_1 = opts.prior_eps_std * cd;
        // eps c_d n_F: its spread from eps's and n_F's around the told values
        let sd_2 = ((opts.prior_eps_std * told.n_f).powi(2)
            + (told.eps.max(opts.prior_eps_std) * opts.prior_n_f_std).powi(2))
        .sqrt()
            * cd;
        let prior_precision = [
            1.0 / (sd_v * sd_v),
            1.0 / (sd_1 * sd_1),
            1.0 / (sd_2 * sd_2),
        ];
        let mut me = Self {
            opts,
            body,
            told,
            boundary,
            length,
            dx: length / cells as f64,
            step,
            prior_mean,
            prior_precision,
            info: [[0.0; 3]; 3],
            rhs: [0.0; 3],
            last: None,
            window: Window::default(),
            windows: 0,
            chi2_sum: 0.0,
            chi2_weight: 0.0,
            theta: prior_mean,
            cov: [[0.0; 3]; 3],
        };
        me.solve();
        Ok(me)
    }

    /// The settings.
    pub fn options(&self) -> &EstimatorOptions {
        &self.opts
    }

    fn snapshot(&self, s: &Sample) -> Snapshot {
        let n = s.v.len();
        let ae = self.body.stiffness();
        let rho = self.body.density;
        let mut out = Snapshot::default();
        let (mut e_kin, mut e_el) = (0.0, 0.0);
        let mut prev_t = match self.boundary {
            Boundary::Periodic => s.tension[n - 1],
            Boundary::Free => 0.0,
        };
        for i in 0..n {
            let v = s.v[i];
            let t = s.tension[i];
            out.mean_v += v;
            out.v2 += v * v;
            out.abs_v += v.abs();
            if s.stuck[i] {
                out.stuck_force += (t - prev_t) / self.dx;
            } else {
                out.sliding += 1.0;
                out.sign += if v > 0.0 {
                    1.0
                } else if v < 0.0 {
                    -1.0
                } else {
                    0.0
                };
            }
            e_kin += v * v;
            e_el += t * t;
            prev_t = t;
        }
        let nf = n as f64;
        out.mean_v /= nf;
        out.v2 /= nf;
        out.abs_v /= nf;
        out.stuck_force /= nf;
        out.sliding /= nf;
        out.sign /= nf;
        out.energy = self.dx * (0.5 * rho * e_kin + 0.5 * e_el / ae);
        out
    }

    /// Takes the state at the end of one communication step. Returns true when a window closed
    /// (the estimate changed).
    pub fn observe(&mut self, s: &Sample) -> bool {
        let n = s.v.len();
        if n < 2 || s.tension.len() != n || s.stuck.len() != n {
            return false;
        }
        let snap = self.snapshot(s);
        let Some(last) = self.last else {
            self.last = Some(snap);
            self.window = Window {
                start: snap,
                ..Window::default()
            };
            return false;
        };
        let h = self.step;
        let w = &mut self.window;
        w.steps += 1;
        w.int_v += h * s.mean_speed;
        w.int_power += h * s.input_power;
        w.int_sign += 0.5 * h * (last.sign + snap.sign);
        w.int_sliding += 0.5 * h * (last.sliding + snap.sliding);
        w.int_stuck_force += 0.5 * h * (last.stuck_force + snap.stuck_force);
        w.int_v2 += 0.5 * h * (last.v2 + snap.v2);
        w.int_abs_v += 0.5 * h * (last.abs_v + snap.abs_v);
        self.last = Some(snap);
        if w.steps < self.opts.window {
            return false;
        }
        let w = std::mem::replace(
            &mut self.window,
            Window {
                start: snap,
                ..Window::default()
            },
        );
        self.close_window(&w, &snap);
        true
    }

    fn close_window(&mut self, w: &Window, end: &Snapshot) {
        let rho = self.body.density;
        let mom_x = [w.int_v, w.int_sign, -w.int_sliding];
        let mom_y = -rho * (end.mean_v - w.start.mean_v) - w.int_stuck_force;
        let en_x = [w.int_v2, w.int_abs_v, -w.int_v];
        let en_y = (w.int_power - (end.energy - w.start.energy)) / self.length;
        let forget = (-(w.steps as f64) * self.step / self.opts.memory).exp();
        for row in self.info.iter_mut() {
            for x in row.iter_mut() {
                *x *= forget;
            }
        }
        for x in self.rhs.iter_mut() {
            *x *= forget;
        }
        self.chi2_sum *= forget;
        self.chi2_weight *= forget;
        let rows = [
            (
                mom_x,
                mom_y,
                rho * (end.mean_v - w.start.mean_v).abs() + w.int_stuck_force.abs(),
                self.opts.momentum_tolerance,
            ),
            (
                en_x,
                en_y,
                (w.int_power.abs() + (end.energy - w.start.energy).abs()) / self.length,
                self.opts.row_tolerance,
            ),
        ];
        for (x, y, rhs_scale, tolerance) in rows {
            let terms: f64 = (0..3).map(|j| (x[j] * self.theta[j]).abs()).sum();
            let scale = tolerance * (terms + rhs_scale);
            if !(scale.is_finite() && scale > 0.0 && y.is_finite()) {
                continue;
            }
            let wgt = 1.0 / (scale * scale);
            let pred: f64 = (0..3).map(|j| x[j] * self.theta[j]).sum();
            self.chi2_sum += (y - pred).powi(2) * wgt;
            self.chi2_weight += 1.0;
            for i in 0..3 {
                self.rhs[i] += wgt * x[i] * y;
                for j in 0..3 {
                    self.info[i][j] += wgt * x[i] * x[j];
                }
            }
        }
        self.windows += 1;
        self.solve();
    }

    // 3 x 3 matrix algebra reads best with indices
    #[allow(clippy::needless_range_loop)]
    fn solve(&mut self) {
        let mut a = self.info;
        let mut b = self.rhs;
        for i in 0..3 {
            a[i][i] += self.prior_precision[i];
            b[i] += self.prior_precision[i] * self.prior_mean[i];
        }
        if let Some(inv) = invert_spd(&a) {
            let chi2 = self.chi2();
            let inflate = chi2.max(1.0);
            for i in 0..3 {
                self.theta[i] = (0..3).map(|j| inv[i][j] * b[j]).sum();
                for j in 0..3 {
                    self.cov[i][j] = inv[i][j] * inflate;
                }
            }
        }
    }

    fn chi2(&self) -> f64 {
        if self.chi2_weight > 0.0 {
            self.chi2_sum / self.chi2_weight
        } else {
            0.0
        }
    }

    /// The current estimate (the prior until the first window closes).
    pub fn estimate(&self) -> Estimate {
        let cd = self.told.dry;
        let [cv, t1, t2] = self.theta;
        let c = &self.cov;
        let eps = t1 / cd;
        let eps_std = c[1][1].max(0.0).sqrt() / cd;
        let (n_f, n_f_std) = if t1.abs() > 1e-12 * cd {
            let g1 = -t2 / (t1 * t1);
            let g2 = 1.0 / t1;
            let var = g1 * g1 * c[1][1] + 2.0 * g1 * g2 * c[1][2] + g2 * g2 * c[2][2];
            (t2 / t1, var.max(0.0).sqrt())
        } else {
            (self.told.n_f, f64::INFINITY)
        };
        Estimate {
            viscous: cv,
            viscous_std: c[0][0].max(0.0).sqrt(),
            eps,
            eps_std,
            n_f,
            n_f_std,
            windows: self.windows,
            chi2: self.chi2(),
        }
    }
}

/// The inverse of a symmetric positive definite 3 x 3 matrix (Cholesky), `None` if it is not.
#[allow(clippy::needless_range_loop)]
fn invert_spd(a: &M3) -> Option<M3> {
    let mut l = [[0.0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..=i {
            let s: f64 = a[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if !(s > 0.0 && s.is_finite()) {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    // inverse of L, then inv(A) = inv(L)^T inv(L)
    let mut li = [[0.0f64; 3]; 3];
    for i in 0..3 {
        li[i][i] = 1.0 / l[i][i];
        for j in 0..i {
            let s: f64 = (j..i).map(|k| l[i][k] * li[k][j]).sum();
            li[i][j] = -s / l[i][i];
        }
    }
    let mut inv = [[0.0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            inv[i][j] = (i.max(j)..3).map(|k| li[k][i] * li[k][j]).sum();
        }
    }
    Some(inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[allow(clippy::needless_range_loop)]
    fn the_inverse_of_a_known_matrix() {
        let a = [[4.0, 2.0, 0.6], [2.0, 5.0, 1.0], [0.6, 1.0, 3.0]];
        let inv = invert_spd(&a).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let p: f64 = (0..3).map(|k| a[i][k] * inv[k][j]).sum();
                assert!(
                    (p - if i == j { 1.0 } else { 0.0 }).abs() < 1e-14,
                    "{i}{j}: {p}"
                );
            }
        }
        assert!(invert_spd(&[[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_none());
    }
}
