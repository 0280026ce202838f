//! Four f64 lanes for the kernel: a thin wrapper over [`wide::f64x4`].
//!
//! `wide` maps each operation to one AVX instruction when the crate is built with AVX enabled
//! (the workspace targets x86-64-v3, see `.cargo/config.toml`) and to SSE2 pairs otherwise.
//! Only correctly rounded IEEE operations and exact selects are used, so every build gives the
//! same bits, and a lane computes exactly what the scalar code does. The one fused operation,
//! [`F4::mul_add`], is also correctly rounded (in software where the build has no FMA, lane by
//! lane as the scalar code's `f64::mul_add`), so the kernel uses it wherever a product is added.

use std::ops::{Add, BitAnd, BitOr, BitXor, Mul, Neg, Sub};

use wide::{f64x4, CmpGe, CmpLt, CmpNe};

/// Lanes of an [`F4`]: the kernel works on blocks of this many nodes.
pub const LANES: usize = 4;

/// Four f64 lanes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct F4(pub f64x4);

impl F4 {
    /// All lanes `x`.
    #[inline(always)]
    pub fn splat(x: f64) -> Self {
        F4(f64x4::splat(x))
    }

    /// The first four values of `x`.
    #[inline(always)]
    pub fn load(x: &[f64]) -> Self {
        // one unaligned vector load (element-wise indexing lets the compiler rebuild overlapping
        // loads from shuffles, which all queue on one port)
        let lanes: [f64; 4] = x[..4].try_into().expect("four lanes");
        F4(f64x4::new(lanes))
    }

    /// Writes the lanes to the first four values of `out`.
    #[inline(always)]
    pub fn store(self, out: &mut [f64]) {
        out[..4].copy_from_slice(&self.0.to_array());
    }

    /// The lanes.
    #[inline(always)]
    pub fn lanes(self) -> [f64; 4] {
        self.0.to_array()
    }

    /// Lane-wise `a > b ? a : b` (the `maxpd` semantics, as the scalar code).
    #[inline(always)]
    pub fn max(self, o: Self) -> Self {
        F4(self.0.fast_max(o.0))
    }

    /// Lane-wise `a < b ? a : b` (the `minpd` semantics, as the scalar code).
    #[inline(always)]
    pub fn min(self, o: Self) -> Self {
        F4(self.0.fast_min(o.0))
    }

    /// Lane-wise absolute value (clears the sign bit).
    #[inline(always)]
    pub fn abs(self) -> Self {
        F4(self.0.abs())
    }

    /// The sign bits only (`-0.0` where negative, `+0.0` elsewhere).
    #[inline(always)]
    pub fn sign(self) -> Self {
        F4(self.0 & f64x4::splat(-0.0))
    }

    /// Lane-wise `self * m + a` with one rounding (a fused multiply-add; where the build lacks
    /// the instruction, the same correctly rounded result lane by lane in software, as the scalar
    /// code's `f64::mul_add`).
    #[inline(always)]
    pub fn mul_add(self, m: Self, a: Self) -> Self {
        #[cfg(all(target_feature = "avx", target_feature = "fma"))]
        {
            F4(self.0.mul_add(m.0, a.0))
        }
        #[cfg(not(all(target_feature = "avx", target_feature = "fma")))]
        {
            let (x, m, a) = (self.lanes(), m.lanes(), a.lanes());
            F4(f64x4::new(std::array::from_fn(|l| {
                x[l].mul_add(m[l], a[l])
            })))
        }
    }

    /// Bit `l` set where lane `l`'s sign bit is set (also for -0.0 and a negative NaN).
    #[inline(always)]
    pub fn sign_bits(self) -> u8 {
        self.0.move_mask() as u8
    }

    /// Lane-wise `if sign bit of self { negative } else { otherwise }` (by the sign bit only, as
    /// `blendvpd`).
    #[inline(always)]
    pub fn select_sign(self, negative: Self, otherwise: Self) -> Self {
        #[cfg(target_feature = "avx")]
        {
            F4(self.0.blend(negative.0, otherwise.0))
        }
        #[cfg(not(target_feature = "avx"))]
        {
            let (m, n, o) = (self.lanes(), negative.lanes(), otherwise.lanes());
            F4(f64x4::new(std::array::from_fn(|l| {
                if m[l].is_sign_negative() {
                    n[l]
                } else {
                    o[l]
                }
            })))
        }
    }

    /// Horizontal sum in lane order `((l0 + l1) + l2) + l3`.
    #[inline(always)]
    pub fn sum(self) -> f64 {
        let l = self.lanes();
        ((l[0] + l[1]) + l[2]) + l[3]
    }

    /// Smallest lane (`a < b ? a : b` folded from lane 0).
    #[inline(always)]
    pub fn min_lane(self) -> f64 {
        let l = self.lanes();
        let m = if l[1] < l[0] { l[1] } else { l[0] };
        let m = if l[2] < m { l[2] } else { m };
        if l[3] < m {
            l[3]
        } else {
            m
        }
    }

    /// Largest lane (`a > b ? a : b` folded from lane 0).
    #[inline(always)]
    pub fn max_lane(self) -> f64 {
        let l = self.lanes();
        let m = if l[1] > l[0] { l[1] } else { l[0] };
        let m = if l[2] > m { l[2] } else { m };
        if l[3] > m {
            l[3]
        } else {
            m
        }
    }

    /// True if any lane is non-zero.
    #[inline(always)]
    pub fn any_nonzero(self) -> bool {
        self.0.cmp_ne(f64x4::ZERO).any()
    }

    /// A mask: all bits set in the lanes inside `[lo, hi)`, zero in the others (and where NaN).
    #[inline(always)]
    pub fn inside(self, lo: Self, hi: Self) -> Self {
        Self(self.0.cmp_ge(lo.0) & self.0.cmp_lt(hi.0))
    }

    /// True if every lane of a mask (a comparison's result, see [`Self::inside`]) is set.
    #[inline(always)]
    pub fn all_set(self) -> bool {
        self.0.all()
    }

    /// True if `self < o` in every lane (false where either is NaN).
    #[inline(always)]
    pub fn all_lt(self, o: Self) -> bool {
        self.0.cmp_lt(o.0).all()
    }

    /// Lane 0.
    #[inline(always)]
    pub fn first(self) -> f64 {
        self.lanes()[0]
    }
}

impl Add for F4 {
    type Output = F4;
    #[inline(always)]
    fn add(self, o: F4) -> F4 {
        F4(self.0 + o.0)
    }
}

impl Sub for F4 {
    type Output = F4;
    #[inline(always)]
    fn sub(self, o: F4) -> F4 {
        F4(self.0 - o.0)
    }
}

/// Lane-wise negation: the sign bit flipped (exact, `-0.0` for `+0.0`; not `0.0 - x`).
impl Neg for F4 {
    type Output = F4;
    #[inline(always)]
    fn neg(self) -> F4 {
        F4(self.0 ^ f64x4::splat(-0.0))
    }
}

impl Mul for F4 {
    type Output = F4;
    #[inline(always)]
    fn mul(self, o: F4) -> F4 {
        F4(self.0 * o.0)
    }
}

impl BitOr for F4 {
    type Output = F4;
    #[inline(always)]
    fn bitor(self, o: F4) -> F4 {
        F4(self.0 | o.0)
    }
}

impl BitAnd for F4 {
    type Output = F4;
    #[inline(always)]
    fn bitand(self, o: F4) -> F4 {
        F4(self.0 & o.0)
    }
}

impl BitXor for F4 {
    type Output = F4;
    #[inline(always)]
    fn bitxor(self, o: F4) -> F4 {
        F4(self.0 ^ o.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mul_add_rounds_once() {
        // (1 + 2^-30)(1 - 2^-30) - 1 = -2^-60 exactly; rounding the product first gives 0
        let (x, m) = (1.0 + 2f64.powi(-30), 1.0 - 2f64.powi(-30));
        let fused = F4::splat(x).mul_add(F4::splat(m), F4::splat(-1.0));
        assert_eq!(fused.lanes(), [-(2f64.powi(-60)); 4]);
        assert_eq!(x * m - 1.0, 0.0);
    }

    #[test]
    fn selects_match_the_scalar_semantics() {
        let a = F4(f64x4::new([1.0, -2.0, 0.0, -0.0]));
        let z = F4::splat(0.0);
        assert_eq!(a.max(z).lanes(), [1.0, 0.0, 0.0, 0.0]);
        assert_eq!(a.sign_bits(), 0b1010);
        // the sign bit of a NaN counts as it is
        let nan = F4(f64x4::new([f64::NAN, -f64::NAN, 1.0, -1.0]));
        assert_eq!(nan.sign_bits(), 0b1010);
        assert_eq!((F4::splat(1.0) | a.sign()).lanes(), [1.0, -1.0, 1.0, -1.0]);
        let negated = (-a).lanes().map(f64::to_bits);
        assert_eq!(negated, [-1.0, 2.0, -0.0, 0.0f64].map(f64::to_bits));
        // by the sign bit alone: -0.0 picks `negative`, +0.0 `otherwise`
        assert_eq!(
            a.select_sign(F4::splat(7.0), F4::splat(9.0)).lanes(),
            [9.0, 7.0, 9.0, 7.0]
        );
        assert_eq!(
            nan.select_sign(F4::splat(7.0), F4::splat(9.0)).lanes(),
            [9.0, 7.0, 9.0, 7.0]
        );
        assert_eq!(F4(f64x4::new([1.0, 5.0, -3.0, 2.0])).max_lane(), 5.0);
        assert_eq!(F4(f64x4::new([1.0, 5.0, -3.0, 2.0])).min_lane(), -3.0);
        assert!(F4(f64x4::new([0.0, 0.0, 1.0, 0.0])).any_nonzero());
        assert!(!z.any_nonzero());
        let one = F4::splat(1.0);
        assert!(F4(f64x4::new([-1.0, 0.0, 0.5, 0.999])).all_lt(one));
        let (lo, hi) = (F4::splat(-1.0), one);
        // [lo, hi): lo is inside, hi is not, in any lane; NaN is not inside
        assert!(F4(f64x4::new([-1.0, 0.0, 0.5, 0.999]))
            .inside(lo, hi)
            .all_set());
        for lane in 0..4 {
            for x in [-1.5, 1.0, f64::INFINITY, f64::NAN] {
                let mut v = [0.0; 4];
                v[lane] = x;
                let inside = F4(f64x4::new(v)).inside(lo, hi);
                assert!(!inside.all_set(), "{v:?}");
                let mask = (inside & F4::load(&[f64::from_bits(u64::MAX); 4])).lanes();
                for (l, m) in mask.iter().enumerate() {
                    assert_eq!(m.to_bits() == 0, l == lane, "{v:?}");
                }
            }
        }
        for lane in 0..4 {
            for x in [1.0, 1.5, f64::INFINITY, f64::NAN] {
                let mut v = [0.0; 4];
                v[lane] = x;
                assert!(!F4(f64x4::new(v)).all_lt(one), "{v:?}");
            }
        }
    }
}
