//! The finite-difference kernel: one internal time step of the crawler's wave equation.
//!
//! Space: `N` nodes with tensions on the half nodes between them,
//! `T_{i+1/2} = A_c E (u_{i+1} - u_i) / dx + m_{i+1/2}(t)`, where `m = A_m f` is the muscle
//! force. The net axial force on node `i` is `(T_{i+1/2} - T_{i-1/2}) / dx`, so elastic and
//! muscle forces cancel exactly in the sum over the body (momentum is only changed by friction).
//! On a periodic body the last tension wraps around to `u_0`; on a free body it is the head's end
//! face and is zero, as is the tail's (see [`Boundary`]).
//!
//! Time: staggered leapfrog (velocities at half steps), explicit in the elastic term, with the
//! viscous term centred and the Coulomb term implicit at the new velocity:
//!
//! ```text
//! rho (v⁺ - v⁻) / dt = F_i(u^n, t_n) - c_v (v⁺ + v⁻) / 2 - eps_i c_d (s - n_F,i),  s ∈ Sgn(v⁺)
//! u^{n+1} = u^n + dt v⁺
//! ```
//!
//! which is second order for smooth motion and solved per node in closed form
//! ([`crate::friction::select`]): a node whose non-friction force stays in the static band stays
//! exactly at rest. At the default Courant number `c dt / dx = 1` the elastic part is exact along
//! characteristics (see `docs/numerics.md`). The muscle force is
//! `m_{i+1/2}(t) = S_i A(t) + C_i B(t) + g_i`, with `S_i = sin(k x_{i+1/2})`,
//! `C_i = cos(k x_{i+1/2})` tabulated once per wave number and `A, B` two numbers per step, so the
//! hot loop has no trigonometry.
//!
//! Friction is uniform (one band for every node, the fast path) or follows a [`FrictionMap`] along
//! the pipe: each node then carries its own coefficients, updated whenever its world position
//! leaves the map's piece it was in.
//!
//! Stick timing: a step decides stick and slip for whole steps. A stop is decided on the velocity
//! the node would have at the step's midpoint `t_{n+1/2}` (an unbiased sample of the stopped
//! state), a release on the force at the step's start `t_n`, half a step earlier; so a discrete
//! stick phase outlasts the true one by half a step on average, which the statistics
//! ([`crate::events`]) take off. A node that lands in the static band for one step only because
//! its momentum carried it there (the force on it outside the band: a velocity reversal) is
//! marked ([`Transition::reversal`]) and gets no stick time.
//!
//! The kernel's files, by responsibility:
//! - this file: the [`Solver`] with its public API and the step that runs the three passes, and
//!   what a step reports ([`StepSums`], [`Transition`]);
//! - `tension.rs`: pass 1, the tensions at the half nodes;
//! - `nodes.rs`: pass 2, the per-node update with exact stick (four-node SIMD blocks, runs of
//!   one friction interval, the scalar node) and the stick/slip switches;
//! - `filter.rs`: pass 3, the grid filter and the displacements, and the filter's face mask;
//! - `lanes.rs`: the four-lane accumulators of passes 1 and 2 and their reductions;
//! - `reference.rs` (tests only): the step written out node by node, which the kernel must
//!   match bit for bit (`tests.rs`).

use crate::node_array::NodeArray;
use crate::node_friction::NodeFriction;
use crate::params::{Boundary, Discretisation, PlantParams};
use crate::simd::LANES;

mod filter;
mod lanes;
mod nodes;
#[cfg(test)]
mod reference;
mod tension;
#[cfg(test)]
mod tests;

/// Per-step reductions computed in the same pass as the update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepSums {
    /// Sum over nodes of the new velocity `v⁺`, m/s.
    pub sum_v: f64,
    /// Sum over nodes of the old velocity `v⁻`, m/s.
    pub sum_v_old: f64,
    /// Sum over nodes of the friction selection `s`.
    pub sum_s: f64,
    /// Sum over nodes of the Coulomb force density `eps_i c_d (s_i - n_F,i)`, N/m.
    pub friction_force: f64,
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
    /// Dissipated power density summed over nodes, `sum_i c_v vm^2 + eps_i c_d (s - n_F,i) v⁺`, W/m.
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
    /// For a stop: the force on the node was outside the static band, so only its momentum put it
    /// at rest for this step (a velocity reversal, not a stick phase, if it slides on next step).
    pub reversal: bool,
}

/// Constants of the update, derived from the parameters.
#[derive(Debug, Clone, Copy)]
struct Coefficients {
    inv_dx: f64,
    stiffness: f64,
    /// A_c E / dx, N/m
    stiffness_over_dx: f64,
    /// rho/dt + c_v/2, kg/(m s)
    a: f64,
    /// (rho/dt - c_v/2) / (rho/dt + c_v/2)
    beta: f64,
    /// 1 / (rho/dt + c_v/2) / dx
    gamma_inv_dx: f64,
    /// eps c_d n_F / (rho/dt + c_v/2), m/s (uniform friction)
    push: f64,
    /// eps c_d / (rho/dt + c_v/2), m/s (uniform friction)
    g: f64,
    viscous: f64,
    band: f64,
    n_f: f64,
    dt: f64,
    /// Grid filter strength per step (the Nyquist mode's share removed), and `filter / 16`.
    filter: f64,
}

/// Displacement and velocity fields with the internal-step update.
#[derive(Debug, Clone)]
pub struct Solver {
    coef: Coefficients,
    boundary: Boundary,
    /// Uniform dry friction coefficient.
    eps: f64,
    /// Displacement `u_i` at nodes, m.
    pub u: NodeArray,
    /// Velocity `v_i` over the last internal step, m/s.
    pub v: NodeArray,
    /// Stick flags of the last internal step (set with [`Self::set_stuck`]).
    stuck: Vec<bool>,
    /// Σ v⁺ of the last step in the kernel's lane order (Σ v⁻ of the next one), m/s.
    last_sum_v: f64,
    /// `stuck` of the kernel's whole blocks packed: bit `l` of entry `b` is node `1 + 4 b + l`
    /// (the kernel reads one byte per block instead of four flags).
    stuck_bits: Vec<u8>,
    /// Number of stuck nodes, kept at every switch (so the kernel carries one reduction less).
    stuck_count: usize,
    /// The stick masks of the whole blocks after the node pass (written for every block, so the
    /// pass has no branch; the switches are the bytes that differ from `stuck_bits`).
    new_bits: Vec<u8>,
    /// True while `field` may be non-zero (general actuation).
    field_active: bool,
    /// Muscle-force field `g_i` at half nodes held over the step, N.
    pub field: NodeArray,
    sin_table: NodeArray,
    cos_table: NodeArray,
    table_k: f64,
    /// Tensions of the last step (at its start `t_n`), N.
    tension: NodeArray,
    /// Per-node friction when the pipe's friction varies.
    map: Option<NodeFriction>,
    /// Filter fluxes at the half nodes (scratch), m/s.
    flux: NodeArray,
    /// Per face: 1.0 where the filter's flux may act (no stuck node within one node of its
    /// stencil, stencil inside the body), 0.0 where not. Kept up to date at every stick/slip
    /// switch, so the filter reads one mask instead of six stick flags per face.
    face_open: NodeArray,
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
        let coef = Coefficients {
            inv_dx: 1.0 / disc.dx,
            stiffness: params.body.stiffness(),
            stiffness_over_dx: params.body.stiffness() / disc.dx,
            a,
            beta: (rho / disc.dt - 0.5 * cv) / a,
            gamma_inv_dx: 1.0 / (a * disc.dx),
            push: band * params.friction.n_f / a,
            g: band / a,
            viscous: cv,
            band,
            n_f: params.friction.n_f,
            dt: disc.dt,
            filter: params.numerics.filter,
        };
        let friction_map = params.friction_map();
        let map = (!friction_map.is_uniform()).then(|| {
            let origin = (0..n)
                .map(|i| params.pipe.start + params.boundary.node_position(i, disc.dx))
                .collect();
            let periodic_length = (params.boundary == Boundary::Periodic).then_some(params.length);
            NodeFriction::new(
                friction_map,
                origin,
                coef.a,
                params.friction.dry,
                periodic_length,
            )
        });
        Self {
            coef,
            boundary: params.boundary,
            eps: params.friction.eps,
            u: NodeArray::zeros(n),
            v: NodeArray::zeros(n),
            stuck: vec![false; n],
            stuck_bits: vec![0; (n - 1) / LANES],
            stuck_count: 0,
            new_bits: vec![0; (n - 1) / LANES],
            last_sum_v: 0.0,
            field_active: false,
            field: NodeArray::zeros(n),
            sin_table: NodeArray::zeros(n),
            cos_table: NodeArray::zeros(n),
            table_k: f64::NAN,
            tension: NodeArray::zeros(n),
            map,
            flux: NodeArray::zeros(n),
            face_open: NodeArray::default(),
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
        self.stuck_count = stuck.iter().filter(|&&s| s).count();
        for (b, bits) in self.stuck_bits.iter_mut().enumerate() {
            let lanes = &stuck[1 + b * LANES..1 + (b + 1) * LANES];
            *bits = lanes
                .iter()
                .enumerate()
                .fold(0, |m, (l, &s)| m | (u8::from(s) << l));
        }
        self.refresh_faces(0..self.cells());
    }

    /// Re-places every node in the friction map after its displacement was set from outside.
    pub fn refresh_friction(&mut self) {
        if let Some(m) = &mut self.map {
            m.place_all(&self.u);
        }
    }

    /// `(eps, n_F)` each node feels, from the pipe's map (uniform values without one).
    pub fn node_friction(&self) -> Vec<(f64, f64)> {
        match &self.map {
            None => vec![(self.eps, self.coef.n_f); self.cells()],
            Some(m) => (0..self.cells()).map(|i| m.friction(i)).collect(),
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
            let (s, c) = (k * self.boundary.face_position(i, dx)).sin_cos();
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

    /// True if half node `i` is inside the body (always on a periodic body; on a free body every
    /// face but the head's end face, whose tension is zero).
    #[inline]
    pub fn is_interior_face(&self, i: usize) -> bool {
        self.boundary == Boundary::Periodic || i + 1 < self.cells()
    }

    /// Tension `T_{i+1/2}` for the current displacement and the muscle coefficients `(a, b)`, N.
    ///
    /// Each value is `stiffness * strain(i) + muscle(i, a, b)`, the same operations as those two
    /// functions (so the same bits), written as one pass over the interior faces and the last face
    /// apart (no index wrap or boundary test per face).
    pub fn tension_into(&self, a: f64, b: f64, out: &mut Vec<f64>) {
        let n = self.cells();
        out.clear();
        if n == 0 {
            return;
        }
        let (k, inv_dx) = (self.coef.stiffness, self.coef.inv_dx);
        let u = &self.u[..n];
        let faces = u[..n - 1]
            .iter()
            .zip(&u[1..])
            .zip(&self.sin_table[..n - 1])
            .zip(&self.cos_table[..n - 1])
            .zip(&self.field[..n - 1]);
        out.extend(
            faces.map(|((((here, next), s), c), g)| {
                k * ((next - here) * inv_dx) + (s * a + c * b + g)
            }),
        );
        let last = n - 1;
        out.push(if self.is_interior_face(last) {
            k * self.strain(last) + self.muscle(last, a, b)
        } else {
            0.0
        });
    }

    /// Strain `(u_{i+1} - u_i) / dx` at half node `i` (0 at a free end face).
    #[inline]
    pub fn strain(&self, i: usize) -> f64 {
        let n = self.cells();
        if !self.is_interior_face(i) {
            return 0.0;
        }
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
        let mut n = match (&self.map, self.coef.g > 0.0) {
            (Some(_), _) => self.nodes::<true, true>(),
            (None, true) => self.nodes::<true, false>(),
            (None, false) => self.nodes::<false, false>(),
        };
        let f = self.coef.filter;
        if f > 0.0 {
            n.sum_v = self.filter();
        } else {
            self.displace();
        }
        // The nodes take the friction of where the step leaves them (after the filter's share).
        if let Some(m) = &mut self.map {
            // `u` moved by `dt (v + dv)`, `v` the node pass's velocity and `dv` the filter's
            // change, `|dv| <= f max|v|` (the flux difference is at most 16 max|v|), plus round-off
            let reach = self.coef.dt * n.max_speed * (1.0 + f) * (1.0 + 1e-12);
            m.follow_step(&self.u, reach);
        }
        // Σ v⁻ of this step is Σ v⁺ of the last one: the same numbers summed in the same lane order.
        let sum_v_old = std::mem::replace(&mut self.last_sum_v, n.sum_v);
        StepSums {
            sum_v: n.sum_v,
            sum_v_old,
            sum_s: n.sum_s,
            friction_force: n.friction_force,
            stuck: n.stuck,
            max_tension: t.max_tension,
            max_strain: t.max_strain,
            tension_sin: t.tension_sin,
            tension_cos: t.tension_cos,
            dissipation: n.dissipation,
        }
    }
}
