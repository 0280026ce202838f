//! The finite-difference kernel: one internal time step of the crawler's wave equation.
//!
//! Space: `N` nodes `x_i = i dx` on the periodic body, tensions on the half nodes
//! `x_{i+1/2}`: `T_{i+1/2} = A_c E (u_{i+1} - u_i) / dx + m_{i+1/2}(t)`, where `m = A_m f` is the
//! muscle force. The net axial force on node `i` is `(T_{i+1/2} - T_{i-1/2}) / dx`, so elastic and
//! muscle forces cancel exactly in the sum over the body (momentum is only changed by friction).
//!
//! Time: staggered leapfrog (velocities at half steps), explicit in the elastic term, with the
//! viscous term centred and the Coulomb term implicit at the new velocity:
//!
//! ```text
//! rho (v⁺ - v⁻) / dt = F_i(u^n, t_n) - c_v (v⁺ + v⁻) / 2 - eps c_d (s - n_F),  s ∈ Sgn(v⁺)
//! u^{n+1} = u^n + dt v⁺
//! ```
//!
//! which is second order for smooth motion and solved per node in closed form
//! ([`crate::friction::select`]): a node whose non-friction force stays in the static band stays
//! exactly at rest. The muscle force is `m_{i+1/2}(t) = S_i A(t) + C_i B(t) + g_i`, with
//! `S_i = sin(k x_{i+1/2})`, `C_i = cos(k x_{i+1/2})` tabulated once per wave number and
//! `A, B` two numbers per step, so the hot loop has no trigonometry.

use crate::params::{Discretisation, PlantParams};
use crate::simd::F4;

/// Per-step reductions computed in the same pass as the update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepSums {
    /// Sum over nodes of the new velocity `v⁺`, m/s.
    pub sum_v: f64,
    /// Sum over nodes of the old velocity `v⁻`, m/s.
    pub sum_v_old: f64,
    /// Sum over nodes of the friction selection `s`.
    pub sum_s: f64,
    /// Number of nodes stuck after the step.
    pub stuck: f64,
    /// Largest tension over the half nodes at `t_n`, N.
    pub max_tension: f64,
    /// Largest `|u_x|` over the half nodes at `t_n`.
    pub max_strain: f64,
    /// `sum_i T_{i+1/2} S_i` at `t_n`, N (for the input power).
    pub tension_sin: f64,
    /// `sum_i T_{i+1/2} C_i` at `t_n`, N (for the input power).
    pub tension_cos: f64,
    /// Dissipated power density summed over nodes, `sum_i c_v vm^2 + eps c_d (s - n_F) v⁺`, W/m.
    pub dissipation: f64,
}

/// A node that switched between stick and slip in the last step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transition {
    /// Node index.
    pub node: u32,
    /// True if the node is now stuck, false if it now slides.
    pub stuck: bool,
    /// The node's new velocity, m/s (0 when stuck).
    pub velocity: f64,
}

/// Constants of the update, derived from the parameters.
#[derive(Debug, Clone, Copy)]
struct Coefficients {
    inv_dx: f64,
    stiffness: f64,
    /// A_c E / dx, N/m
    stiffness_over_dx: f64,
    /// (rho/dt - c_v/2) / (rho/dt + c_v/2)
    beta: f64,
    /// 1 / (rho/dt + c_v/2) / dx
    gamma_inv_dx: f64,
    /// eps c_d n_F / (rho/dt + c_v/2), m/s
    push: f64,
    /// eps c_d / (rho/dt + c_v/2), m/s
    g: f64,
    viscous: f64,
    band: f64,
    n_f: f64,
    dt: f64,
}

/// Displacement and velocity fields with the internal-step update.
#[derive(Debug, Clone)]
pub struct Solver {
    coef: Coefficients,
    /// Displacement `u_i` at nodes, m.
    pub u: Vec<f64>,
    /// Velocity `v_i` over the last internal step, m/s.
    pub v: Vec<f64>,
    /// Stick flags of the last internal step (set with [`Self::set_stuck`]).
    stuck: Vec<bool>,
    /// Σ v⁺ of the last step in the kernel's lane order (Σ v⁻ of the next one), m/s.
    last_sum_v: f64,
    /// 1.0 where stuck, 0.0 where sliding (the kernel's own copy of `stuck`).
    stuck_flags: Vec<f64>,
    /// Per node: 1.0 if it switched between stick and slip in the last step.
    change_marks: Vec<f64>,
    /// True while `field` may be non-zero (general actuation).
    field_active: bool,
    /// Muscle-force field `g_i` at half nodes held over the step, N.
    pub field: Vec<f64>,
    sin_table: Vec<f64>,
    cos_table: Vec<f64>,
    table_k: f64,
    tension: Vec<f64>,
    /// Nodes that switched stick/slip in the last step (cleared each step).
    pub transitions: Vec<Transition>,
}

impl Solver {
    /// A body at rest, all nodes sliding-free (not stuck), with zero muscle force.
    pub fn new(params: &PlantParams, disc: &Discretisation) -> Self {
        let n = params.numerics.cells;
        let rho = params.body.density;
        let cv = params.friction.viscous;
        let band = params.friction.band();
        let a = rho / disc.dt + 0.5 * cv;
        let g = band / a;
        let coef = Coefficients {
            inv_dx: 1.0 / disc.dx,
            stiffness: params.body.stiffness(),
            stiffness_over_dx: params.body.stiffness() / disc.dx,
            beta: (rho / disc.dt - 0.5 * cv) / a,
            gamma_inv_dx: 1.0 / (a * disc.dx),
            push: band * params.friction.n_f / a,
            g,
            viscous: cv,
            band,
            n_f: params.friction.n_f,
            dt: disc.dt,
        };
        Self {
            coef,
            u: vec![0.0; n],
            v: vec![0.0; n],
            stuck: vec![false; n],
            stuck_flags: vec![0.0; n],
            change_marks: vec![0.0; n],
            last_sum_v: 0.0,
            field_active: false,
            field: vec![0.0; n],
            sin_table: vec![0.0; n],
            cos_table: vec![0.0; n],
            table_k: f64::NAN,
            tension: vec![0.0; n],
            transitions: Vec::new(),
        }
    }

    /// Stick flags of the last internal step.
    pub fn stuck(&self) -> &[bool] {
        &self.stuck
    }

    /// Σ v over the nodes in the kernel's lane order (what the next step reports as Σ v⁻), m/s.
    pub fn velocity_sum(&self) -> f64 {
        self.last_sum_v
    }

    /// Restores the carried Σ v (from a saved state).
    pub fn set_velocity_sum(&mut self, sum: f64) {
        self.last_sum_v = sum;
    }

    /// Declares whether the field `g` may be non-zero (skipped in the kernel when it is all zero).
    pub fn set_field_active(&mut self, active: bool) {
        self.field_active = active;
    }

    /// Sets the stick flags (restoring a state).
    pub fn set_stuck(&mut self, stuck: &[bool]) {
        self.stuck.clone_from_slice(stuck);
        for (f, &s) in self.stuck_flags.iter_mut().zip(stuck) {
            *f = if s { 1.0 } else { 0.0 };
        }
    }

    /// Number of nodes.
    pub fn cells(&self) -> usize {
        self.u.len()
    }

    /// Tabulates `sin(k x_{i+1/2})` and `cos(k x_{i+1/2})` (only when `k` changes).
    pub fn set_wave_number(&mut self, k: f64, dx: f64) {
        if self.table_k == k {
            return;
        }
        for i in 0..self.cells() {
            let (s, c) = (k * (i as f64 + 0.5) * dx).sin_cos();
            self.sin_table[i] = s;
            self.cos_table[i] = c;
        }
        self.table_k = k;
    }

    /// `sin(k x_{i+1/2})` per half node (valid after [`Self::set_wave_number`]).
    pub fn sin_table(&self) -> &[f64] {
        &self.sin_table
    }

    /// `cos(k x_{i+1/2})` per half node.
    pub fn cos_table(&self) -> &[f64] {
        &self.cos_table
    }

    /// Muscle force at half node `i` for the coefficients `(a, b)` of the tables, N.
    #[inline]
    pub fn muscle(&self, i: usize, a: f64, b: f64) -> f64 {
        self.sin_table[i] * a + self.cos_table[i] * b + self.field[i]
    }

    /// Tension `T_{i+1/2}` for the current displacement and the muscle coefficients `(a, b)`, N.
    pub fn tension_into(&self, a: f64, b: f64, out: &mut Vec<f64>) {
        let n = self.cells();
        out.clear();
        out.extend((0..n).map(|i| {
            let strain = (self.u[(i + 1) % n] - self.u[i]) * self.coef.inv_dx;
            self.coef.stiffness * strain + self.muscle(i, a, b)
        }));
    }

    /// Strain `(u_{i+1} - u_i) / dx` at half node `i`.
    #[inline]
    pub fn strain(&self, i: usize) -> f64 {
        let n = self.cells();
        (self.u[(i + 1) % n] - self.u[i]) * self.coef.inv_dx
    }

    /// One internal step with muscle force `m_{i+1/2} = S_i a + C_i b + g_i` at the step's start.
    pub fn step(&mut self, a: f64, b: f64) -> StepSums {
        self.transitions.clear();
        let t = if self.field_active {
            self.tensions::<true>(a, b)
        } else {
            self.tensions::<false>(a, b)
        };
        let n = if self.coef.g > 0.0 {
            self.nodes::<true>()
        } else {
            self.nodes::<false>()
        };
        // Σ v⁻ of this step is Σ v⁺ of the last one: the same numbers summed in the same lane order.
        let sum_v_old = std::mem::replace(&mut self.last_sum_v, n.sum_v);
        StepSums {
            sum_v: n.sum_v,
            sum_v_old,
            sum_s: n.sum_s,
            stuck: n.stuck,
            max_tension: t.max_tension,
            max_strain: t.max_strain,
            tension_sin: t.tension_sin,
            tension_cos: t.tension_cos,
            dissipation: n.dissipation,
        }
    }

    /// Pass 1: tensions at the half nodes, `T = (A_c E / dx) (u_{i+1} - u_i) + m`, with their
    /// reductions (four independent lanes, so the loop vectorises).
    #[inline(always)]
    fn tensions<const FIELD: bool>(&mut self, a: f64, b: f64) -> TensionSums {
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
                let m = s4 * va + c4 * vb;
                let t = k1 * du + if FIELD { m + F4::load(g4) } else { m };
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
        // the last half node wraps around to u[0]
        let last = n - 1;
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
        acc.finish(c.inv_dx)
    }

    /// Pass 2: new velocities with exact stick, displacements, and the stick/slip switches.
    #[inline(always)]
    fn nodes<const FRICTION: bool>(&mut self) -> NodeSums {
        let c = self.coef;
        let n = self.cells();
        let k = NodeConstants::new(&c);
        let mut acc = NodeLanes::default();
        let mut changed;
        {
            let u = &mut self.u[..];
            let v = &mut self.v[..];
            let t = &self.tension[..];
            let flags = &mut self.stuck_flags[..];
            let marks = &mut self.change_marks[..];
            // node 0 wraps around to the last half node
            marks[0] = node_scalar::<FRICTION>(
                &k,
                &mut u[0],
                &mut v[0],
                t[0] - t[n - 1],
                &mut flags[0],
                &mut acc,
            );
            changed = marks[0].to_bits();
            let m = n - 1;
            let (u, v, flags, marks) = (&mut u[1..], &mut v[1..], &mut flags[1..], &mut marks[1..]);
            let (t_here, t_before) = (&t[1..], &t[..m]);
            let whole = m / LANES * LANES;
            let (u, v, flags, marks, t_here, t_before) = (
                &mut u[..m],
                &mut v[..m],
                &mut flags[..m],
                &mut marks[..m],
                &t_here[..m],
                &t_before[..m],
            );
            let mut any = F4::default();
            let mut b = 0;
            while b < whole {
                let v_old = F4::load(&v[b..b + LANES]);
                let (v_new, stuck) = node_simd::<FRICTION>(
                    &k,
                    v_old,
                    F4::load(&t_here[b..b + LANES]) - F4::load(&t_before[b..b + LANES]),
                    &mut acc,
                );
                let change = stuck ^ F4::load(&flags[b..b + LANES]);
                (F4::load(&u[b..b + LANES]) + k.dt * v_new).store(&mut u[b..b + LANES]);
                v_new.store(&mut v[b..b + LANES]);
                stuck.store(&mut flags[b..b + LANES]);
                change.store(&mut marks[b..b + LANES]);
                any = any | change;
                b += LANES;
            }
            if any.any_nonzero() {
                changed |= 1;
            }
            for i in whole..m {
                marks[i] = node_scalar::<FRICTION>(
                    &k,
                    &mut u[i],
                    &mut v[i],
                    t_here[i] - t_before[i],
                    &mut flags[i],
                    &mut acc,
                );
                changed |= marks[i].to_bits();
            }
        }
        if changed != 0 {
            let whole = n / LANES * LANES;
            for base in (0..whole).step_by(LANES) {
                if F4::load(&self.change_marks[base..base + LANES]).any_nonzero() {
                    for i in base..base + LANES {
                        self.record_transition(i);
                    }
                }
            }
            for i in whole..n {
                self.record_transition(i);
            }
        }
        acc.finish(&c)
    }

    #[inline]
    fn record_transition(&mut self, i: usize) {
        if self.change_marks[i].to_bits() != 0 {
            let stuck = self.stuck_flags[i] != 0.0;
            self.stuck[i] = stuck;
            self.transitions.push(Transition {
                node: i as u32,
                stuck,
                velocity: self.v[i],
            });
        }
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
    let m = s * a + co * b;
    c.stiffness_over_dx * (next - here) + if FIELD { m + g } else { m }
}

/// The update constants, broadcast to four lanes.
struct NodeConstants {
    beta: F4,
    gamma_inv_dx: F4,
    push: F4,
    g: F4,
    inv_g: F4,
    dt: F4,
}

impl NodeConstants {
    fn new(c: &Coefficients) -> Self {
        Self {
            beta: F4::splat(c.beta),
            gamma_inv_dx: F4::splat(c.gamma_inv_dx),
            push: F4::splat(c.push),
            g: F4::splat(c.g),
            inv_g: F4::splat(if c.g > 0.0 { 1.0 / c.g } else { 0.0 }),
            dt: F4::splat(c.dt),
        }
    }
}

/// Four nodes: `b = beta v + gamma (T_{i+1/2} - T_{i-1/2}) / dx + eps c_d n_F / a`, then the exact
/// stick update of [`crate::friction::select_with_inverse`], lane by lane. Returns the new
/// velocities and the stick flags (1.0 stuck, 0.0 sliding).
#[inline(always)]
fn node_simd<const FRICTION: bool>(
    k: &NodeConstants,
    v_old: F4,
    tension_difference: F4,
    acc: &mut NodeLanes,
) -> (F4, F4) {
    let zero = F4::splat(0.0);
    let one = F4::splat(1.0);
    let b = k.beta * v_old + k.gamma_inv_dx * tension_difference + k.push;
    let (v_new, s, stuck) = if FRICTION {
        let excess = b.abs() - k.g;
        let v_new = excess.max(zero) | b.sign();
        let q = (b * k.inv_g).min(one).max(F4::splat(-1.0));
        let s = excess.select_le(zero, q, one | b.sign());
        (v_new, s, excess.le_as_one(zero))
    } else {
        (b, zero, zero)
    };
    acc.add(v_new, v_old, s, stuck);
    (v_new, stuck)
}

/// One node, the same operations as one lane of [`node_simd`]; returns the change mark.
#[inline(always)]
fn node_scalar<const FRICTION: bool>(
    k: &NodeConstants,
    u: &mut f64,
    v: &mut f64,
    tension_difference: f64,
    flag: &mut f64,
    acc: &mut NodeLanes,
) -> f64 {
    let v_old = *v;
    let b = k.beta.first() * v_old + k.gamma_inv_dx.first() * tension_difference + k.push.first();
    let (v_new, s, stuck) = if FRICTION {
        let sel = crate::friction::select_with_inverse(b, k.g.first(), k.inv_g.first());
        (sel.velocity, sel.s, if sel.stuck { 1.0 } else { 0.0 })
    } else {
        (b, 0.0, 0.0)
    };
    acc.add_scalar(v_new, v_old, s, stuck);
    let change = f64::from_bits(stuck.to_bits() ^ flag.to_bits());
    *flag = stuck;
    *v = v_new;
    *u += k.dt.first() * v_new;
    change
}

/// Lanes of the reductions: independent accumulators so the loops vectorise.
const LANES: usize = 4;

/// `x` in lane 0, zeros elsewhere (adding it changes lane 0 only, exactly: `y + 0.0 = y`).
#[inline(always)]
fn lane0(x: f64) -> F4 {
    F4(wide::f64x4::new([x, 0.0, 0.0, 0.0]))
}

/// Accumulators of pass 1, four lanes each. Scalar tails add to lane 0.
struct TensionLanes {
    max_tension: F4,
    max_du: F4,
    tension_sin: F4,
    tension_cos: F4,
}

struct TensionSums {
    max_tension: f64,
    max_strain: f64,
    tension_sin: f64,
    tension_cos: f64,
}

impl TensionLanes {
    fn new() -> Self {
        Self {
            max_tension: F4::splat(f64::NEG_INFINITY),
            max_du: F4::splat(0.0),
            tension_sin: F4::splat(0.0),
            tension_cos: F4::splat(0.0),
        }
    }

    #[inline(always)]
    fn add(&mut self, t: F4, du: F4, s: F4, c: F4) {
        self.max_tension = t.max(self.max_tension);
        self.max_du = du.abs().max(self.max_du);
        self.tension_sin = self.tension_sin + t * s;
        self.tension_cos = self.tension_cos + t * c;
    }

    #[inline(always)]
    fn add_scalar(&mut self, t: f64, du: f64, s: f64, c: f64) {
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
    fn finish(&self, inv_dx: f64) -> TensionSums {
        TensionSums {
            max_tension: self.max_tension.max_lane(),
            max_strain: self.max_du.max_lane() * inv_dx,
            tension_sin: self.tension_sin.sum(),
            tension_cos: self.tension_cos.sum(),
        }
    }
}

/// Accumulators of pass 2, four lanes each. Scalar nodes add to lane 0.
#[derive(Default)]
struct NodeLanes {
    sum_v: F4,
    sum_s: F4,
    stuck: F4,
    /// sum of (v_old + v_new)^2
    sum_vm2: F4,
    /// sum of |v_new|
    sum_abs_v: F4,
}

struct NodeSums {
    sum_v: f64,
    sum_s: f64,
    stuck: f64,
    dissipation: f64,
}

impl NodeLanes {
    #[inline(always)]
    fn add(&mut self, v_new: F4, v_old: F4, s: F4, stuck: F4) {
        let vs = v_old + v_new;
        self.sum_v = self.sum_v + v_new;
        self.sum_s = self.sum_s + s;
        self.stuck = self.stuck + stuck;
        self.sum_vm2 = self.sum_vm2 + vs * vs;
        self.sum_abs_v = self.sum_abs_v + v_new.abs();
    }

    #[inline(always)]
    fn add_scalar(&mut self, v_new: f64, v_old: f64, s: f64, stuck: f64) {
        let vs = v_old + v_new;
        self.sum_v = self.sum_v + lane0(v_new);
        self.sum_s = self.sum_s + lane0(s);
        self.stuck = self.stuck + lane0(stuck);
        self.sum_vm2 = self.sum_vm2 + lane0(vs * vs);
        self.sum_abs_v = self.sum_abs_v + lane0(v_new.abs());
    }

    /// Combines the lanes. Dissipation density summed over nodes:
    /// `c_v sum ((v⁻ + v⁺)/2)^2 + eps c_d sum (s - n_F) v⁺`, where `s v⁺ = |v⁺|` exactly.
    fn finish(&self, c: &Coefficients) -> NodeSums {
        let sum_v = self.sum_v.sum();
        NodeSums {
            sum_v,
            sum_s: self.sum_s.sum(),
            stuck: self.stuck.sum(),
            dissipation: 0.25 * c.viscous * self.sum_vm2.sum()
                + c.band * (self.sum_abs_v.sum() - c.n_f * sum_v),
        }
    }
}
