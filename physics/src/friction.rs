//! Asymmetric Coulomb + viscous friction with true stick.
//!
//! The friction force per unit length is `F(v) = c_v v + eps c_d (s - n_F)` with the selection
//! `s ∈ Sgn(v)`, where `Sgn` is set-valued: `{sign v}` for `v != 0` and `[-1, 1]` at `v = 0`.
//! A point at rest therefore stays at rest while the other forces on it lie in
//! `[-eps c_d (1 + n_F), eps c_d (1 - n_F)]`.
//!
//! Every implicit update in this project (the plant's time step, the reduced model's march)
//! reduces to the same scalar problem, solved here in closed form (no iteration):
//!
//! ```text
//!     w = b - g s,   s ∈ Sgn(w),   g >= 0
//! ```
//!
//! with `b` the velocity the point would have without Coulomb friction and `g` the velocity the
//! Coulomb force can remove in one step. Its unique solution is `s = clamp(b / g, -1, 1)`,
//! `w = b - g s`: the point sticks (`w = 0` exactly) when `|b| <= g`.

/// Solution of `w = b - g s, s ∈ Sgn(w)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Selection {
    /// New velocity, exactly `0.0` when stuck (units of `b`).
    pub velocity: f64,
    /// Friction selection `s` in `[-1, 1]`; inside the interval only when stuck.
    pub s: f64,
    /// True when the point is at rest (static friction holds it).
    pub stuck: bool,
}

/// Solves `w = b - g s, s ∈ Sgn(w)` for `g > 0` exactly; for `g == 0`, returns `w = b, s = sign b`.
#[inline(always)]
pub fn select(b: f64, g: f64) -> Selection {
    select_with_inverse(b, g, if g > 0.0 { 1.0 / g } else { 0.0 })
}

/// [`select`] with `inv_g = 1 / g` precomputed (0 when `g == 0`), written with selects only
/// so that loops over many points vectorise: `w = copysign(max(|b| - g, 0), b)`, and
/// `s = clamp(b / g, -1, 1)` while stuck, `s = sign(b)` exactly while sliding.
/// The plant's kernel performs exactly these operations.
#[inline(always)]
pub fn select_with_inverse(b: f64, g: f64, inv_g: f64) -> Selection {
    if g <= 0.0 {
        let s = if b > 0.0 {
            1.0
        } else if b < 0.0 {
            -1.0
        } else {
            0.0
        };
        return Selection {
            velocity: b,
            s,
            stuck: false,
        };
    }
    let excess = b.abs() - g;
    let slide = if excess > 0.0 { excess } else { 0.0 };
    let velocity = slide.copysign(b);
    // `b / g` clamped to [-1, 1] (1 for a NaN `b`), signed as `b`
    let q = (b.abs() * inv_g).min(1.0).copysign(b);
    // stuck exactly when it has no slide velocity (a NaN `b` included)
    let stuck = slide == 0.0;
    let s = if stuck { q } else { 1.0f64.copysign(b) };
    Selection { velocity, s, stuck }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sticks_inside_band_and_slides_outside() {
        let r = select(0.3, 0.5);
        assert!(r.stuck);
        assert_eq!(r.velocity, 0.0);
        assert!((r.s - 0.6).abs() < 1e-15);
        let r = select(0.8, 0.5);
        assert!(!r.stuck);
        assert!((r.velocity - 0.3).abs() < 1e-15);
        assert_eq!(r.s, 1.0);
        let r = select(-0.8, 0.5);
        assert!((r.velocity + 0.3).abs() < 1e-15);
        assert_eq!(r.s, -1.0);
    }

    #[test]
    fn solution_satisfies_the_inclusion() {
        for i in -200..=200 {
            let b = i as f64 * 0.01;
            let g = 0.7;
            let r = select(b, g);
            assert!((r.velocity - (b - g * r.s)).abs() < 1e-14);
            assert!((-1.0..=1.0).contains(&r.s));
            if r.velocity != 0.0 {
                assert_eq!(r.s, r.velocity.signum());
            }
        }
    }
}
