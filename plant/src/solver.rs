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

use crate::friction::select;
use crate::params::{Discretisation, PlantParams};

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
    /// Stick flags of the last internal step.
    pub stuck: Vec<bool>,
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
            field: vec![0.0; n],
            sin_table: vec![0.0; n],
            cos_table: vec![0.0; n],
            table_k: f64::NAN,
            tension: vec![0.0; n],
            transitions: Vec::new(),
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
        let c = self.coef;
        let n = self.cells();
        self.transitions.clear();

        // Pass 1: tensions at the half nodes (reads u, writes the scratch array).
        let mut max_tension = f64::NEG_INFINITY;
        let mut max_strain = 0.0f64;
        let mut tension_sin = 0.0;
        let mut tension_cos = 0.0;
        {
            let u = &self.u[..];
            let (st, ct, gf) = (&self.sin_table[..], &self.cos_table[..], &self.field[..]);
            let tension = &mut self.tension[..];
            let mut tension_at = |i: usize, next: f64| {
                let strain = (next - u[i]) * c.inv_dx;
                let t = c.stiffness * strain + (st[i] * a + ct[i] * b + gf[i]);
                tension[i] = t;
                max_tension = max_tension.max(t);
                max_strain = max_strain.max(strain.abs());
                tension_sin += t * st[i];
                tension_cos += t * ct[i];
            };
            for i in 0..n - 1 {
                tension_at(i, u[i + 1]);
            }
            tension_at(n - 1, u[0]);
        }

        // Pass 2: velocities with exact stick, then displacements.
        let mut sum_v = 0.0;
        let mut sum_v_old = 0.0;
        let mut sum_s = 0.0;
        let mut stuck_count = 0.0;
        let mut dissipation = 0.0;
        let mut prev_t = self.tension[n - 1];
        for i in 0..n {
            let t = self.tension[i];
            let v_old = self.v[i];
            let b_free = c.beta * v_old + c.gamma_inv_dx * (t - prev_t) + c.push;
            prev_t = t;
            let sel = select(b_free, c.g);
            let (v_new, s, stuck) = (sel.velocity, sel.s, sel.stuck);
            let vm = 0.5 * (v_old + v_new);
            dissipation += c.viscous * vm * vm + c.band * (s - c.n_f) * v_new;
            sum_v += v_new;
            sum_v_old += v_old;
            sum_s += s;
            if stuck {
                stuck_count += 1.0;
            }
            if stuck != self.stuck[i] {
                self.stuck[i] = stuck;
                self.transitions.push(Transition {
                    node: i as u32,
                    stuck,
                    velocity: v_new,
                });
            }
            self.v[i] = v_new;
            self.u[i] += c.dt * v_new;
        }
        StepSums {
            sum_v,
            sum_v_old,
            sum_s,
            stuck: stuck_count,
            max_tension,
            max_strain,
            tension_sin,
            tension_cos,
            dissipation,
        }
    }
}
