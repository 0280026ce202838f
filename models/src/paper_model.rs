//! The paper's leading-order perturbation model (Sec. III-IV, eqs. 27-34, Appendix II),
//! written in the physically consistent sign convention of `docs/physics.md` §2.4 and §3.
//!
//! Nondimensional model: `mu_tt = mu_xx + cos(chi - alpha tau) - zeta mu_t - eps pi_r (s - n_F)`.
//! Leading order `mu0 = -R0 cos(xi) + eps C1 tau`, `xi = chi - alpha tau - phi0` (a phase of pi
//! against the paper's eq. 27, which carries the sign slip of eq. 14). First order:
//! `mu1 = sum_n R_n cos(n xi - phi_n)`, the response to the square wave
//! `-pi_r (sgn(eps C1 - R0 alpha sin xi) - 2 gamma / pi)`. Unlike the paper's eq. (40) the
//! square wave keeps its factor `pi_r` (it multiplies the friction term in eq. 14).

use serde::Serialize;
use std::f64::consts::PI;

use crate::operating_point::OperatingPoint;
use crate::prediction::{Model, Prediction, Validity};

/// The analytic quantities of the paper at one operating point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PaperTerms {
    /// `alpha = omega / omega_n`.
    pub alpha: f64,
    /// `zeta = c_v / (k sqrt(rho A_c E))`.
    pub zeta: f64,
    /// `pi_r = c_d / (f0 k)`.
    pub pi_r: f64,
    /// `R0 = 1 / sqrt((alpha^2 - 1)^2 + (zeta alpha)^2)`.
    pub r0: f64,
    /// `phi0 = atan2(zeta alpha, alpha^2 - 1)` in (0, pi) (`docs/physics.md` §7, item 2).
    pub phi0: f64,
    /// `C0 = pi_r n_F / zeta`.
    pub c0: f64,
    /// `eps C0 / (R0 alpha)`: `gamma` exists only if this is <= 1.
    pub gamma_argument: f64,
    /// `gamma = asin(eps C0 / (R0 alpha))`, `None` outside the model's validity.
    pub gamma: Option<f64>,
    /// `C1 = (pi_r / zeta)(n_F - 2 gamma / pi)`: the nondimensional drift rate.
    pub c1: Option<f64>,
}

impl PaperTerms {
    /// The terms at `op`.
    pub fn at(op: &OperatingPoint) -> Self {
        let alpha = op.alpha();
        let zeta = op.zeta();
        let pi_r = op.pi_r();
        let r0 = r0(alpha, zeta);
        let phi0 = (zeta * alpha).atan2(alpha * alpha - 1.0);
        let n_f = op.friction.n_f;
        let c0 = pi_r * n_f / zeta;
        let arg = op.friction.eps * c0 / (r0 * alpha);
        let gamma = (arg.is_finite() && arg <= 1.0).then(|| arg.asin());
        let c1 = gamma.map(|g| pi_r / zeta * (n_f - 2.0 * g / PI));
        Self {
            alpha,
            zeta,
            pi_r,
            r0,
            phi0,
            c0,
            gamma_argument: arg,
            gamma,
            c1,
        }
    }

    /// Why the model does not apply, if it does not.
    pub fn validity(&self) -> Validity {
        if self.gamma.is_some() {
            Validity::Valid
        } else {
            Validity::OutsideValidity(format!(
                "outside the model's validity: eps C0 / (R0 alpha) = {:.4} > 1, so gamma = asin(...) is undefined \
                 (the drift exceeds the oscillation: the body no longer slides backwards and partly sticks)",
                self.gamma_argument
            ))
        }
    }
}

/// Resonance factor `R0 = 1 / sqrt((alpha^2 - 1)^2 + (zeta alpha)^2)`.
pub fn r0(alpha: f64, zeta: f64) -> f64 {
    1.0 / ((alpha * alpha - 1.0).powi(2) + (zeta * alpha).powi(2)).sqrt()
}

/// Fourier coefficients `(a_n, b_n)` of the square wave `sgn(sin gamma - sin xi)`
/// (= the paper's Appendix II coefficients times `(-1)^n`, the consistent sign).
pub fn square_wave_coefficients(gamma: f64, n: u32) -> (f64, f64) {
    let nf = n as f64;
    let sign = if n.is_multiple_of(2) { 1.0 } else { -1.0 };
    let a = 2.0 / (PI * nf) * ((nf * (gamma + PI)).sin() + (nf * gamma).sin());
    let b = 2.0 / (PI * nf) * ((nf * gamma).cos() - (nf * (gamma + PI)).cos());
    (sign * a, sign * b)
}

/// `(R_n, phi_n)` of `mu1 = sum_n R_n cos(n xi - phi_n)`.
pub fn first_order_harmonic(t: &PaperTerms, n: u32) -> Option<(f64, f64)> {
    let gamma = t.gamma?;
    let (a, b) = square_wave_coefficients(gamma, n);
    let nf = n as f64;
    // (d_tt - d_xx + zeta d_t) on e^{i n xi} = n^2 (1 - alpha^2) - i n alpha zeta
    let (dr, di) = (nf * nf * (1.0 - t.alpha * t.alpha), -nf * t.alpha * t.zeta);
    // amplitude = -pi_r (a - i b) / (dr + i di) =: R e^{-i phi}
    let (nr, ni) = (-t.pi_r * a, t.pi_r * b);
    let den = dr * dr + di * di;
    let (re, im) = ((nr * dr + ni * di) / den, (ni * dr - nr * di) / den);
    Some(((re * re + im * im).sqrt(), -im.atan2(re)))
}

/// The paper's model (eqs. 30-34).
#[derive(Debug, Clone, Copy, Default)]
pub struct PaperModel {
    /// Harmonics kept in the first-order reconstruction.
    pub harmonics: u32,
}

impl PaperModel {
    /// Eq. (31): `V = eps c_d / c_v (n_F - 2 gamma / pi)`, m/s.
    pub fn velocity(op: &OperatingPoint) -> Option<f64> {
        let t = PaperTerms::at(op);
        t.gamma
            .map(|g| op.friction.band() / op.friction.viscous * (op.friction.n_f - 2.0 * g / PI))
    }

    /// Eq. (32): `P = pi R0 f0^2 omega sin(phi0) / (k A_c E)` per wavelength, times the
    /// wavelengths on the body, W. Equals `pi zeta alpha R0^2 f0^2 omega / (k A_c E)`.
    pub fn power(op: &OperatingPoint) -> f64 {
        let t = PaperTerms::at(op);
        let w = op.wave;
        PI * t.r0 * w.f0 * w.f0 * w.omega * t.phi0.sin() / (w.k * op.body.stiffness())
            * op.wavelengths
    }

    /// Leading-order stress amplitude from definition (4): `(f0 / A_c) R0 alpha sqrt(alpha^2 + zeta^2)`, Pa.
    pub fn max_stress(op: &OperatingPoint) -> f64 {
        let t = PaperTerms::at(op);
        op.wave.f0 / op.body.area * t.r0 * t.alpha * (t.alpha * t.alpha + t.zeta * t.zeta).sqrt()
    }

    /// Eq. (30) as printed: `f0 / (A_c E) R0 alpha sqrt(1 + (c_v / (rho omega_n))^2)`. Dimensionally a
    /// strain (`docs/physics.md` §3.4); times E it agrees with [`Self::max_stress`] only at resonance.
    pub fn stress_eq30(op: &OperatingPoint) -> f64 {
        let t = PaperTerms::at(op);
        let ratio = op.friction.viscous / (op.body.density * op.omega_n());
        op.wave.f0 / op.body.stiffness() * t.r0 * t.alpha * (1.0 + ratio * ratio).sqrt()
    }

    /// Leading-order strain amplitude `max |u_x| = u_c k R0 = f0 R0 / (A_c E)`.
    pub fn max_strain(op: &OperatingPoint) -> f64 {
        op.wave.f0 * PaperTerms::at(op).r0 / op.body.stiffness()
    }

    /// Eq. (34): the speed at resonance, `eps c_d / c_v (n_F - 2 asin(eps pi_r n_F) / pi)`, m/s.
    pub fn resonance_velocity(op: &OperatingPoint) -> Option<f64> {
        let arg = op.friction.eps * op.pi_r() * op.friction.n_f;
        (arg <= 1.0).then(|| {
            op.friction.band() / op.friction.viscous * (op.friction.n_f - 2.0 * arg.asin() / PI)
        })
    }

    /// The reconstructed displacement `u = u_c (mu0 + eps mu1)` at `(x, t)` (m, s), with the drift
    /// counted from `t = 0`; `None` outside the model's validity.
    pub fn displacement(&self, op: &OperatingPoint, x: f64, t: f64) -> Option<f64> {
        let terms = PaperTerms::at(op);
        let c1 = terms.c1?;
        let w = op.wave;
        let tau = op.omega_n() * t;
        let xi = w.k * x - w.omega * t + w.phase - terms.phi0;
        let mut mu = -terms.r0 * xi.cos() + op.friction.eps * c1 * tau;
        for n in 1..=self.harmonics {
            let (rn, phin) = first_order_harmonic(&terms, n)?;
            mu += op.friction.eps * rn * (n as f64 * xi - phin).cos();
        }
        Some(op.u_c() * mu)
    }
}

impl Model for PaperModel {
    fn name(&self) -> &'static str {
        "paper"
    }

    fn predict(&self, op: &OperatingPoint) -> Prediction {
        let terms = PaperTerms::at(op);
        let validity = terms.validity();
        let Some(velocity) = Self::velocity(op) else {
            let Validity::OutsideValidity(reason) = validity else {
                unreachable!()
            };
            return Prediction {
                max_stress: Some(Self::max_stress(op)).filter(|x| x.is_finite()),
                power: Some(Self::power(op)).filter(|x| x.is_finite()),
                ..Prediction::outside("paper", reason)
            };
        };
        let power = Self::power(op);
        let (stress, strain) = (Self::max_stress(op), Self::max_strain(op));
        if ![velocity, power, stress, strain]
            .iter()
            .all(|x| x.is_finite())
        {
            return Prediction::outside(
                "paper",
                format!(
                    "not representable in f64 at f0 = {:e} N (overflow)",
                    op.wave.f0
                ),
            );
        }
        Prediction {
            model: "paper",
            velocity: Some(velocity),
            power: Some(power),
            mileage: Some(velocity.abs() / power),
            max_stress: Some(stress),
            max_strain: Some(strain),
            stuck_fraction: Some(0.0),
            mean_friction_selection: terms.gamma.map(|g| 2.0 * g / PI),
            episodes_per_node_per_period: Some(0.0),
            validity,
        }
    }
}
