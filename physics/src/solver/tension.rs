//! Pass 1 of the step: the tensions at the half nodes, `T = (A_c E / dx) (u_{i+1} - u_i) + m`,
//! four at a time with their reductions ([`TensionLanes`]); the half nodes left over and a
//! periodic body's last one, which wraps around to `u_0`, in scalar code ([`tension_scalar`]).

use super::lanes::{TensionLanes, TensionSums};
use super::{Coefficients, Solver};
use crate::params::Boundary;
use crate::simd::{F4, LANES};

impl Solver {
    /// Pass 1: tensions at the half nodes, `T = (A_c E / dx) (u_{i+1} - u_i) + m`, with their
    /// reductions (four independent lanes, so the loop vectorises).
    #[inline(never)]
    pub(super) fn tensions<const FIELD: bool>(&mut self, a: f64, b: f64) -> TensionSums {
        let c = self.coef;
        let n = self.cells();
        let mut acc = TensionLanes::new();
        let (k1, va, vb) = (F4::splat(c.stiffness_over_dx), F4::splat(a), F4::splat(b));
        {
            let u = &self.u[..];
            let (here, next) = (&u[..n - 1], &u[1..]);
            let (st, ct, gf) = (
                &self.sin_table[..n - 1],
                &self.cos_table[..n - 1],
                &self.field[..n - 1],
            );
            let out = &mut self.tension[..n - 1];
            let mut it_out = out.chunks_exact_mut(LANES);
            let mut it_here = here.chunks_exact(LANES);
            let mut it_next = next.chunks_exact(LANES);
            let mut it_s = st.chunks_exact(LANES);
            let mut it_c = ct.chunks_exact(LANES);
            let mut it_g = gf.chunks_exact(LANES);
            for (((((o, h), x), s4), c4), g4) in (&mut it_out)
                .zip(&mut it_here)
                .zip(&mut it_next)
                .zip(&mut it_s)
                .zip(&mut it_c)
                .zip(&mut it_g)
            {
                let (s4, c4) = (F4::load(s4), F4::load(c4));
                let du = F4::load(x) - F4::load(h);
                let m = s4.mul_add(va, c4 * vb);
                let t = k1.mul_add(du, if FIELD { m + F4::load(g4) } else { m });
                t.store(o);
                acc.add(t, du, s4, c4);
            }
            let rest = it_out
                .into_remainder()
                .iter_mut()
                .zip(it_here.remainder())
                .zip(it_next.remainder());
            for (((o, h), x), ((s1, c1), g1)) in rest.zip(
                it_s.remainder()
                    .iter()
                    .zip(it_c.remainder())
                    .zip(it_g.remainder()),
            ) {
                *o = tension_scalar::<FIELD>(&c, *h, *x, *s1, *c1, *g1, a, b);
                acc.add_scalar(*o, x - h, *s1, *c1);
            }
        }
        let last = n - 1;
        match self.boundary {
            // The last half node wraps around to u[0].
            Boundary::Periodic => {
                let t = tension_scalar::<FIELD>(
                    &c,
                    self.u[last],
                    self.u[0],
                    self.sin_table[last],
                    self.cos_table[last],
                    self.field[last],
                    a,
                    b,
                );
                self.tension[last] = t;
                acc.add_scalar(
                    t,
                    self.u[0] - self.u[last],
                    self.sin_table[last],
                    self.cos_table[last],
                );
            }
            // The head's end face carries no tension (and so no input power).
            Boundary::Free => self.tension[last] = 0.0,
        }
        acc.finish(c.inv_dx)
    }
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn tension_scalar<const FIELD: bool>(
    c: &Coefficients,
    here: f64,
    next: f64,
    s: f64,
    co: f64,
    g: f64,
    a: f64,
    b: f64,
) -> f64 {
    let m = s.mul_add(a, co * b);
    c.stiffness_over_dx
        .mul_add(next - here, if FIELD { m + g } else { m })
}
