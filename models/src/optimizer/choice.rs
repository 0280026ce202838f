//! One grid cell: the largest amplitude `f0` the constraints allow at `(omega, k)`, and which
//! constraint binds (the paper model's closed form, or bracketed root finding for any model).

use std::f64::consts::PI;

use crate::paper_model::r0;
use crate::prediction::Prediction;
use crate::roots::{brent, golden_max};

use super::outcome::binding_name;
use super::paper_mileage::{h, h_peak, h_root_rising};
use super::{Binding, Choice, Infeasibility, Infeasible, ModelChoice, Problem};

impl Problem {
    /// The largest feasible `f0` at `(omega, k)` under `model`, or why there is none.
    pub fn choose(&self, model: &ModelChoice, omega: f64, k: f64) -> Result<Choice, Infeasible> {
        match model {
            ModelChoice::Paper => self.choose_paper(omega, k),
            ModelChoice::Improved(_) => self.choose_generic(model, omega, k),
        }
    }

    fn choose_paper(&self, omega: f64, k: f64) -> Result<Choice, Infeasible> {
        let peak = h_peak(self.friction.n_f);
        self.choose_paper_with(omega, k, peak, &self.mileage_root(k, peak))
    }

    /// The mileage condition of the paper's model at wave number `k`: `(K, z_a)`, with `z_a` the
    /// rising root of `h(z) = K`. `K = (D/J0) c_v P(f0 = 1) g^2 / (eps c_d)` depends on `k` only
    /// (`docs/physics.md` §5.2), so a grid solves it once per row of k.
    pub(super) fn mileage_root(&self, k: f64, peak: (f64, f64)) -> (f64, Option<f64>) {
        let f = self.friction;
        let band = f.band();
        let op = self.point(k * self.body.wave_speed(), k, 1.0);
        let (alpha, zeta) = (op.alpha(), op.zeta());
        let r0 = r0(alpha, zeta);
        let g = band * f.n_f / (k * zeta * r0 * alpha);
        let p = PI * zeta * alpha * r0 * r0 * op.wave.omega / (k * self.body.stiffness())
            * op.wavelengths;
        let kk = self.task.min_mileage() * f.viscous * p * g * g / band;
        let (z_star, h_star) = peak;
        (
            kk,
            (kk <= h_star && kk.is_finite()).then(|| h_root_rising(f.n_f, kk, z_star)),
        )
    }

    /// [`Self::choose_paper`] with the peak of `h`, which depends on `n_F` only, computed once.
    pub(super) fn choose_paper_with(
        &self,
        omega: f64,
        k: f64,
        peak: (f64, f64),
        row: &(f64, Option<f64>),
    ) -> Result<Choice, Infeasible> {
        let op = self.point(omega, k, 1.0);
        let (alpha, zeta) = (op.alpha(), op.zeta());
        let r0 = r0(alpha, zeta);
        let ae = self.body.stiffness();
        let f = self.friction;
        let band = f.band();
        if band * f.n_f <= 0.0 {
            return Err(Infeasible::new(
                Infeasibility::NoForwardMotion,
                "no forward motion is possible: eps c_d n_F = 0",
            ));
        }
        // caps
        let f_stress = self.task.sigma_max * self.body.area
            / (r0 * alpha * (alpha * alpha + zeta * zeta).sqrt());
        let f_strain = self.limits.strain_max * ae / r0;
        let (mut cap, mut binding) = (self.limits.f0_max, Binding::F0Max);
        if f_stress < cap {
            cap = f_stress;
            binding = Binding::Stress;
        }
        if f_strain < cap {
            cap = f_strain;
            binding = Binding::Strain;
        }
        // mileage in z = g / f0
        let g = band * f.n_f / (k * zeta * r0 * alpha);
        // P at f0 = 1 N: eq. (32), pi zeta alpha R0^2 omega / (k A_c E) per wavelength
        let p = PI * zeta * alpha * r0 * r0 * omega / (k * ae) * op.wavelengths;
        let (kk, z_root) = *row;
        let h_star = peak.1;
        if kk > h_star {
            return Err(Infeasible::new(
                Infeasibility::Mileage,
                format!(
                    "mileage: the best amplitude gives M = {:.4e} m/J < D/J0 = {:.4e} m/J",
                    h_star * band / (f.viscous * p * g * g),
                    self.task.min_mileage()
                ),
            ));
        }
        let z_a = z_root.expect("feasible rows have a root");
        let z_cap = g / cap;
        let z = if z_a > z_cap {
            binding = Binding::Mileage;
            z_a
        } else {
            z_cap
        };
        // z must also lie below the falling root of h = K (mileage) and below 1 (validity).
        if h(f.n_f, z) < kk * (1.0 - 1e-9) || z > 1.0 {
            return Err(Infeasible::new(
                Infeasibility::of(binding),
                format!(
                    "{}: the amplitude it allows ({:.4} N) is too small to meet the mileage D/J0 with forward motion",
                    binding_name(binding),
                    cap
                ),
            ));
        }
        let velocity = band / f.viscous * (f.n_f - 2.0 * z.asin() / PI);
        Ok(Choice {
            f0: g / z,
            binding,
            velocity,
        })
    }

    pub(super) fn choose_generic(
        &self,
        model: &ModelChoice,
        omega: f64,
        k: f64,
    ) -> Result<Choice, Infeasible> {
        let pred = |f0: f64| model.predict(&self.point(omega, k, f0));
        let tol = 1e-7 * self.limits.f0_max;
        let mut cap = self.limits.f0_max;
        let mut binding = Binding::F0Max;
        let top = pred(cap);
        let stress_at = |p: &Prediction| p.max_stress.unwrap_or(f64::INFINITY);
        let strain_at = |p: &Prediction| p.max_strain.unwrap_or(f64::INFINITY);
        if stress_at(&top) > self.task.sigma_max {
            cap = brent(
                |f0| stress_at(&pred(f0)) - self.task.sigma_max,
                0.0,
                cap,
                tol,
            )
            .ok_or_else(|| {
                Infeasible::new(
                    Infeasibility::Stress,
                    "stress: no amplitude meets sigma_max",
                )
            })?;
            binding = Binding::Stress;
        }
        let at_cap = pred(cap);
        if strain_at(&at_cap) > self.limits.strain_max {
            cap = brent(
                |f0| strain_at(&pred(f0)) - self.limits.strain_max,
                0.0,
                cap,
                tol,
            )
            .ok_or_else(|| {
                Infeasible::new(
                    Infeasibility::Strain,
                    "strain: no amplitude meets strain_max",
                )
            })?;
            binding = Binding::Strain;
        }
        let req = self.task.min_mileage();
        let mileage = |f0: f64| {
            let p = pred(f0);
            match (p.velocity, p.mileage) {
                (Some(v), Some(m)) if v > 0.0 && m.is_finite() => m,
                _ => 0.0,
            }
        };
        let mut f0 = cap;
        if mileage(cap) < req {
            let (f_peak, m_peak) = golden_max(mileage, 1e-3 * cap, cap, 1e-4 * cap);
            if m_peak < req {
                return Err(Infeasible::new(
                    Infeasibility::Mileage,
                    format!(
                        "mileage: the best amplitude at or below {:.4} N ({}) gives M = {:.4e} m/J < D/J0 = {:.4e} m/J",
                        cap,
                        binding_name(binding),
                        m_peak,
                        req
                    ),
                ));
            }
            f0 = brent(|f| mileage(f) - req, f_peak, cap, tol).ok_or_else(|| {
                Infeasible::new(Infeasibility::Mileage, "mileage: root not bracketed")
            })?;
            binding = Binding::Mileage;
        }
        let p = pred(f0);
        let velocity = p.velocity.ok_or_else(|| {
            Infeasible::new(Infeasibility::ModelUndefined, "model has no speed here")
        })?;
        if velocity <= 0.0 {
            return Err(Infeasible::new(
                Infeasibility::NoForwardMotion,
                "no forward motion at the allowed amplitude",
            ));
        }
        Ok(Choice {
            f0,
            binding,
            velocity,
        })
    }
}
