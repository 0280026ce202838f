//! The four-lane accumulators of passes 1 ([`TensionLanes`]) and 2 ([`NodeLanes`]): each lane
//! sums its own nodes (scalar nodes add to lane 0), and `finish` combines the lanes into the
//! step's reductions.

use super::Coefficients;
use crate::simd::F4;

/// `x` in lane 0, zeros elsewhere (adding it changes lane 0 only, exactly: `y + 0.0 = y`).
#[inline(always)]
pub(super) fn lane0(x: f64) -> F4 {
    F4(wide::f64x4::new([x, 0.0, 0.0, 0.0]))
}

/// Accumulators of pass 1, four lanes each. Scalar tails add to lane 0.
pub(super) struct TensionLanes {
    max_tension: F4,
    max_du: F4,
    tension_sin: F4,
    tension_cos: F4,
}

pub(super) struct TensionSums {
    pub(super) max_tension: f64,
    pub(super) max_strain: f64,
    pub(super) tension_sin: f64,
    pub(super) tension_cos: f64,
}

impl TensionLanes {
    pub(super) fn new() -> Self {
        Self {
            max_tension: F4::splat(f64::NEG_INFINITY),
            max_du: F4::splat(0.0),
            tension_sin: F4::splat(0.0),
            tension_cos: F4::splat(0.0),
        }
    }

    #[inline(always)]
    pub(super) fn add(&mut self, t: F4, du: F4, s: F4, c: F4) {
        self.max_tension = t.max(self.max_tension);
        self.max_du = du.abs().max(self.max_du);
        self.tension_sin = t.mul_add(s, self.tension_sin);
        self.tension_cos = t.mul_add(c, self.tension_cos);
    }

    #[inline(always)]
    pub(super) fn add_scalar(&mut self, t: f64, du: f64, s: f64, c: f64) {
        let mut m = self.max_tension.lanes();
        m[0] = if t > m[0] { t } else { m[0] };
        self.max_tension = F4(wide::f64x4::new(m));
        let mut d = self.max_du.lanes();
        let du = du.abs();
        d[0] = if du > d[0] { du } else { d[0] };
        self.max_du = F4(wide::f64x4::new(d));
        self.tension_sin = self.tension_sin + lane0(t * s);
        self.tension_cos = self.tension_cos + lane0(t * c);
    }

    /// Combines the lanes; `max |u_x| = max |du| / dx` (scaling by a positive constant is monotonic).
    pub(super) fn finish(&self, inv_dx: f64) -> TensionSums {
        TensionSums {
            max_tension: self.max_tension.max_lane(),
            max_strain: self.max_du.max_lane() * inv_dx,
            tension_sin: self.tension_sin.sum(),
            tension_cos: self.tension_cos.sum(),
        }
    }
}

/// Accumulators of pass 2, four lanes each. Scalar nodes add to lane 0.
#[derive(Default, Clone, Copy)]
pub(super) struct NodeLanes {
    sum_v: F4,
    pub(super) sum_s: F4,
    /// sum of (v_old + v_new)^2
    sum_vm2: F4,
    /// sum of |v_new|
    sum_abs_v: F4,
    /// per-node friction: sum of `g s - push` (the Coulomb force in velocity units)
    sum_f: F4,
    /// per-node friction: sum of `(g s - push) v_new`
    sum_fv: F4,
    /// per-node friction: the largest `|v_new|`
    pub(super) max_speed: F4,
    /// per-node friction, the runs of one interval: sum of `g s - push` and `(g s - push) v_new`
    run_f: f64,
    run_fv: f64,
}

pub(super) struct NodeSums {
    pub(super) sum_v: f64,
    pub(super) sum_s: f64,
    pub(super) friction_force: f64,
    pub(super) stuck: f64,
    pub(super) dissipation: f64,
    /// With per-node friction, the largest `|v_new|`, m/s.
    pub(super) max_speed: f64,
}

impl NodeLanes {
    /// The reductions every node adds (`sum_abs_v` only with uniform friction); `speed` is
    /// `|v_new|`.
    #[inline(always)]
    pub(super) fn add<const MAP: bool>(&mut self, v_new: F4, speed: F4, v_old: F4, s: F4) {
        let vs = v_old + v_new;
        self.sum_v = self.sum_v + v_new;
        self.sum_s = self.sum_s + s;
        self.sum_vm2 = vs.mul_add(vs, self.sum_vm2);
        if !MAP {
            self.sum_abs_v = self.sum_abs_v + speed;
        }
    }

    #[inline(always)]
    pub(super) fn add_map(&mut self, v_new: F4, s: F4, g: F4, push: F4) {
        let f = g.mul_add(s, -push);
        self.sum_f = self.sum_f + f;
        self.sum_fv = f.mul_add(v_new, self.sum_fv);
    }

    /// Adds a run of `count` nodes of one interval with coefficients `g`, `push`, summed as in a
    /// uniform pipe: `sum (g s - push) = g sum s - push count` and, as `s v_new = |v_new|`,
    /// `sum (g s - push) v_new = g sum |v_new| - push sum v_new`.
    pub(super) fn add_run(&mut self, run: &NodeLanes, g: f64, push: f64, count: usize) {
        self.sum_v = self.sum_v + run.sum_v;
        self.sum_s = self.sum_s + run.sum_s;
        self.sum_vm2 = self.sum_vm2 + run.sum_vm2;
        self.max_speed = self.max_speed.max(run.max_speed);
        self.run_f += g * run.sum_s.sum() - push * count as f64;
        self.run_fv += g * run.sum_abs_v.sum() - push * run.sum_v.sum();
    }

    #[inline(always)]
    pub(super) fn add_scalar(&mut self, v_new: f64, v_old: f64, s: f64) {
        let vs = v_old + v_new;
        self.sum_v = self.sum_v + lane0(v_new);
        self.sum_s = self.sum_s + lane0(s);
        self.sum_vm2 = self.sum_vm2 + lane0(vs * vs);
        self.sum_abs_v = self.sum_abs_v + lane0(v_new.abs());
    }

    #[inline(always)]
    pub(super) fn add_map_scalar(&mut self, v_new: f64, s: f64, g: f64, push: f64) {
        let f = g * s - push;
        self.sum_f = self.sum_f + lane0(f);
        self.sum_fv = self.sum_fv + lane0(f * v_new);
    }

    /// Combines the lanes. Dissipation density summed over nodes:
    /// `c_v sum ((v⁻ + v⁺)/2)^2 + sum eps_i c_d (s - n_F,i) v⁺`, where `s v⁺ = |v⁺|` exactly;
    /// with per-node friction `eps_i c_d = a g_i` and `eps_i c_d n_F,i = a push_i`. `stuck`: the
    /// number of stuck nodes after the step.
    pub(super) fn finish(
        &self,
        c: &Coefficients,
        cells: usize,
        map: bool,
        stuck: usize,
    ) -> NodeSums {
        let sum_v = self.sum_v.sum();
        let sum_s = self.sum_s.sum();
        let viscous = 0.25 * c.viscous * self.sum_vm2.sum();
        let (coulomb, friction_force) = if map {
            (
                c.a * (self.sum_fv.sum() + self.run_fv),
                c.a * (self.sum_f.sum() + self.run_f),
            )
        } else {
            (
                c.band * (self.sum_abs_v.sum() - c.n_f * sum_v),
                c.band * (sum_s - c.n_f * cells as f64),
            )
        };
        NodeSums {
            sum_v,
            sum_s,
            friction_force,
            stuck: stuck as f64,
            dissipation: viscous + coulomb,
            max_speed: self.max_speed.max_lane(),
        }
    }
}
