//! The paper model's mileage condition in one variable: `h(z) >= K` with
//! `z = eps c_d n_F / (f0 k zeta R0 alpha)`; `h` depends on `n_F` only.

use std::f64::consts::PI;

use crate::roots::golden_max;

/// `h(z) = z^2 (n_F - 2 asin(z) / pi)`: the paper's mileage as a function of `z = g / f0`.
pub fn h(n_f: f64, z: f64) -> f64 {
    z * z * (n_f - 2.0 * z.min(1.0).asin() / PI)
}

/// The maximum of `h` on `[0, sin(pi n_F / 2)]`: `(z*, h(z*))`.
pub fn h_peak(n_f: f64) -> (f64, f64) {
    let z0 = (PI * n_f / 2.0).sin();
    golden_max(|z| h(n_f, z), 0.0, z0, 1e-13)
}

/// The root of `h(z) = target` on the rising branch `[0, z*]` (safeguarded Newton).
pub(super) fn h_root_rising(n_f: f64, target: f64, z_star: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, z_star);
    let mut z = (target / n_f).sqrt().min(z_star);
    for _ in 0..60 {
        let f = h(n_f, z) - target;
        if f > 0.0 {
            hi = z;
        } else {
            lo = z;
        }
        let d = 2.0 * z * (n_f - 2.0 * z.asin() / PI) - z * z * 2.0 / (PI * (1.0 - z * z).sqrt());
        let mut next = z - f / d;
        if !(next > lo && next < hi && next.is_finite()) {
            next = 0.5 * (lo + hi);
        }
        if (next - z).abs() <= 1e-15 * z.max(1e-300) {
            return next;
        }
        z = next;
    }
    z
}
