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
    let excess = b.abs() - g;
    if excess > 0.0 || g <= 0.0 {
        let sign = if b > 0.0 {
            1.0
        } else if b < 0.0 {
            -1.0
        } else {
            0.0
        };
        Selection {
            velocity: b - g * sign,
            s: sign,
            stuck: false,
        }
    } else {
        Selection {
            velocity: 0.0,
            s: b / g,
            stuck: true,
        }
    }
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
