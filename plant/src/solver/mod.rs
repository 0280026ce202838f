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

use crate::node_array::NodeArray;
use crate::node_friction::{chunk_left, NodeFriction, CHUNK_BLOCKS, MIXED};
use crate::params::{Boundary, Discretisation, PlantParams};
use crate::simd::{F4, LANES};

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

    /// Node `i + offset` on this body: wrapped around a periodic body, `None` off a free one.
    #[inline]
    fn node_at(&self, i: usize, offset: isize) -> Option<usize> {
        let n = self.cells() as isize;
        let j = i as isize + offset;
        match self.boundary {
            Boundary::Periodic => Some(j.rem_euclid(n) as usize),
            Boundary::Free => (0..n).contains(&j).then_some(j as usize),
        }
    }

    /// Recomputes the filter's face mask for the faces whose window holds a node of `nodes`.
    fn refresh_faces(&mut self, nodes: std::ops::Range<usize>) {
        let n = self.cells();
        if self.face_open.len() != n {
            self.face_open = NodeArray::zeros(n);
            return self.refresh_faces(0..n);
        }
        // Away from the ends (every face's window i-2 ..= i+3 inside the arrays, as for most
        // switches) the faces read the stick flags directly, without wrapping indices.
        if nodes.len() < n && nodes.start >= 5 && nodes.end + 5 <= n {
            for face in nodes.start - 3..nodes.end + 2 {
                let free = !self.stuck[face - 2..=face + 3].contains(&true);
                self.face_open[face] = if free { 1.0 } else { 0.0 };
            }
            return;
        }
        let span = if nodes.len() >= n {
            0..n as isize
        } else {
            nodes.start as isize - 3..nodes.end as isize + 2
        };
        for f in span {
            let Some(face) = self.node_at(0, f) else {
                continue;
            };
            // the stencil i-1 ..= i+2 must be inside the body, and no node of i-2 ..= i+3 stuck
            let inside = (-1..=2).all(|o| self.node_at(face, o).is_some());
            let free = (-2..=3).all(|o| self.node_at(face, o).is_none_or(|j| !self.stuck[j]));
            self.face_open[face] = if inside && free { 1.0 } else { 0.0 };
        }
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
    pub fn tension_into(&self, a: f64, b: f64, out: &mut Vec<f64>) {
        let n = self.cells();
        out.clear();
        out.extend((0..n).map(|i| {
            if self.is_interior_face(i) {
                self.coef.stiffness * self.strain(i) + self.muscle(i, a, b)
            } else {
                0.0
            }
        }));
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

    /// Pass 1: tensions at the half nodes, `T = (A_c E / dx) (u_{i+1} - u_i) + m`, with their
    /// reductions (four independent lanes, so the loop vectorises).
    #[inline(never)]
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

    /// Pass 2: new velocities with exact stick and the stick/slip switches (the displacements
    /// follow in pass 3, `u += dt v` with the filtered velocities).
    /// `MAP`: per-node friction coefficients from the pipe's map.
    #[inline(never)]
    fn nodes<const FRICTION: bool, const MAP: bool>(&mut self) -> NodeSums {
        let c = self.coef;
        let n = self.cells();
        let k = NodeConstants::new(&c);
        let mut acc = NodeLanes::default();
        let whole = (n - 1) / LANES * LANES;
        // the nodes outside the whole blocks (node 0 and the tail) that switched, new flag
        let mut lone = [(0, false); LANES];
        let mut lone_count = 0;
        {
            let v = &mut self.v[..];
            let t = &self.tension[..];
            let stuck = &self.stuck[..];
            let map = if MAP { self.map.as_mut() } else { None };
            let scalar_coefficients = |map: &Option<&mut NodeFriction>, i: usize| match map {
                Some(m) => (m.g[i], m.push[i], m.inv_g[i]),
                None => (k.g.first(), k.push.first(), k.inv_g.first()),
            };
            // node 0 wraps around to the last half node (zero on a free body)
            let cf = scalar_coefficients(&map, 0);
            let now = node_scalar::<FRICTION, MAP>(&k, &mut v[0], t[0] - t[n - 1], cf, &mut acc);
            if now != stuck[0] {
                lone[lone_count] = (0, now);
                lone_count += 1;
            }
            let blocks = Blocks {
                v: &mut v[1..1 + whole],
                t_here: &t[1..1 + whole],
                t_before: &t[..whole],
                masks: &mut self.new_bits,
            };
            match map.as_deref().filter(|_| MAP) {
                None => {
                    acc = node_blocks::<FRICTION, false, false, false>(
                        &k,
                        acc,
                        blocks,
                        PerNode::default(),
                    );
                }
                Some(m) => map_runs::<FRICTION>(&k, &mut acc, m, blocks),
            }
            for i in 1 + whole..n {
                let cf = scalar_coefficients(&map, i);
                let now =
                    node_scalar::<FRICTION, MAP>(&k, &mut v[i], t[i] - t[i - 1], cf, &mut acc);
                if now != stuck[i] {
                    lone[lone_count] = (i, now);
                    lone_count += 1;
                }
            }
        }
        // the switches in node order: node 0, the blocks, the tail
        let tail = usize::from(lone_count > 0 && lone[0].0 == 0);
        if tail == 1 {
            self.record_transition(0, lone[0].1);
        }
        // the blocks whose mask changed, in order (a switch may leave its block's old mask as it
        // was, so the search goes on after the block)
        let mut from = 0;
        while let Some(b) = first_change(&self.new_bits, &self.stuck_bits, from) {
            let now = self.new_bits[b];
            let changed = now ^ self.stuck_bits[b];
            for l in 0..LANES {
                if changed >> l & 1 != 0 {
                    self.record_transition(1 + b * LANES + l, now >> l & 1 != 0);
                }
            }
            from = b + 1;
        }
        for &(i, now) in &lone[tail..lone_count] {
            self.record_transition(i, now);
        }
        acc.finish(&c, n, MAP, self.stuck_count)
    }

    /// Pass 3: the grid filter, and the displacements. With the fourth difference written as a
    /// difference of fluxes, `F_{i+1/2} = (v_{i+2} - v_{i-1}) - 3 (v_{i+1} - v_i)`, the velocity
    /// changes by `-(filter / 16) (F_{i+1/2} - F_{i-1/2})`; then `u += dt v`. A flux is zero where
    /// a stuck node lies within one node of its stencil (nodes `i-2 ..= i+3`) or the stencil
    /// leaves a free body, so stuck nodes stay exactly at rest, the kinks of the velocity
    /// at the edges of stick phases are left alone, and the sum of the velocities (the momentum)
    /// is unchanged. The Nyquist mode loses the share `filter` per step; a mode of `theta`
    /// radians per cell `filter (1 - cos theta)^2 / 4`, so resolved waves are untouched to fourth
    /// order. Returns the sum of the new velocities.
    #[inline(never)]
    fn filter(&mut self) -> f64 {
        let n = self.cells();
        if self.face_open.len() != n {
            self.refresh_faces(0..n);
        }
        let (v, open, flux) = (&self.v[..], &self.face_open[..], &mut self.flux[..]);
        let periodic = self.boundary == Boundary::Periodic;
        // Index `i` on the body (wrapped around a periodic one; on a free one the mask is zero
        // wherever the stencil leaves the body, so the clamped value is never used).
        let at = |i: isize| -> usize {
            if periodic {
                i.rem_euclid(n as isize) as usize
            } else {
                i.clamp(0, n as isize - 1) as usize
            }
        };
        // Faces 1 ..= n - 3 (stencil i-1 ..= i+2 inside the arrays) four at a time.
        let three = F4::splat(3.0);
        let m = n.saturating_sub(3) / LANES * LANES;
        let shifted = |k: usize| v[k..k + m].chunks_exact(LANES);
        let faces = flux[1..1 + m]
            .chunks_exact_mut(LANES)
            .zip(open[1..1 + m].chunks_exact(LANES))
            .zip(shifted(0).zip(shifted(1)).zip(shifted(2).zip(shifted(3))));
        for ((f, o), ((before, here), (next, after))) in faces {
            let d = (-three).mul_add(
                F4::load(next) - F4::load(here),
                F4::load(after) - F4::load(before),
            );
            (d * F4::load(o)).store(f);
        }
        let i = 1 + m;
        for j in (i..n).chain([0]) {
            let j2 = j as isize;
            let d = (-3.0f64).mul_add(v[at(j2 + 1)] - v[j], v[at(j2 + 2)] - v[at(j2 - 1)]);
            flux[j] = open[j] * d;
        }
        let k = F4::splat(-self.coef.filter / 16.0);
        let dt = F4::splat(self.coef.dt);
        let (u, v, flux) = (&mut self.u[..], &mut self.v[..], &self.flux[..]);
        let end = 1 + (n - 1) / LANES * LANES;
        // the eager check of the pipe map's edges, a chunk at a time while it is in the
        // first-level cache; without it the loop is compiled with no per-chunk work
        let sum = match self.map.as_mut().and_then(|m| m.fused_check()) {
            None => filter_chunks(k, dt, flux, v, u, end, |_, _, _| {}),
            Some(ch) => {
                let mut count = 0;
                let sum = filter_chunks(k, dt, flux, v, u, end, |c, u, r| {
                    if chunk_left(u, &ch.u_lo[r.clone()], &ch.u_hi[r]) {
                        ch.escaped[count] = c;
                        count += 1;
                    }
                });
                *ch.count = count;
                sum
            }
        };
        let i = end;
        let (kf, dtf) = (k.first(), dt.first());
        let mut tail = 0.0;
        for j in (i..n).chain([0]) {
            let before = if j == 0 { flux[n - 1] } else { flux[j - 1] };
            v[j] = kf.mul_add(flux[j] - before, v[j]);
            u[j] = dtf.mul_add(v[j], u[j]);
            tail += v[j];
        }
        sum.sum() + tail
    }

    /// Without the filter: the displacements, `u += dt v` (with it, the filter's pass moves the
    /// nodes by the filtered velocities).
    #[inline(never)]
    fn displace(&mut self) {
        let dt = F4::splat(self.coef.dt);
        let mut us = self.u.chunks_exact_mut(LANES);
        let mut vs = self.v.chunks_exact(LANES);
        for (u, v) in (&mut us).zip(&mut vs) {
            dt.mul_add(F4::load(v), F4::load(u)).store(u);
        }
        for (u, v) in us.into_remainder().iter_mut().zip(vs.remainder()) {
            *u = self.coef.dt.mul_add(*v, *u);
        }
    }

    /// Records node `i`'s switch to `stuck` (and, for a stop, whether only momentum put it at
    /// rest).
    fn record_transition(&mut self, i: usize, stuck: bool) {
        let n = self.cells();
        // Where a piece of the map has no dry friction (eps = 0) nothing holds a node: the
        // kernel's select finds `|b| <= g` for a node with exactly zero velocity and force, but
        // the node is not stuck (as the scalar select and a uniform pipe with eps = 0 say).
        if stuck && self.map.as_ref().is_some_and(|m| m.g[i] == 0.0) {
            return;
        }
        self.stuck[i] = stuck;
        if let Some(bits) = i
            .checked_sub(1)
            .and_then(|j| self.stuck_bits.get_mut(j / LANES))
        {
            let bit = 1 << ((i - 1) % LANES);
            *bits = if stuck { *bits | bit } else { *bits & !bit };
        }
        if stuck {
            self.stuck_count += 1;
        } else {
            self.stuck_count -= 1;
        }
        if self.coef.filter > 0.0 {
            self.refresh_faces(i..i + 1);
        }
        let reversal = stuck && {
            let (g, push) = match &self.map {
                Some(m) => (m.g[i], m.push[i]),
                None => (self.coef.g, self.coef.push),
            };
            let left = (i + n - 1) % n;
            let force = self
                .coef
                .gamma_inv_dx
                .mul_add(self.tension[i] - self.tension[left], push);
            force.abs() > g
        };
        self.transitions.push(Transition {
            node: i as u32,
            stuck,
            velocity: self.v[i],
            reversal,
        });
    }
}

/// The grid filter's velocity change and the displacements over the whole blocks (nodes
/// `1..end`), a chunk of [`CHUNK_BLOCKS`] blocks at a time, calling `after_chunk` after each with
/// the chunk's number, its new displacements (m) and its nodes; returns the sum of the new
/// velocities (four lanes).
#[inline(always)]
fn filter_chunks(
    k: F4,
    dt: F4,
    flux: &[f64],
    v: &mut [f64],
    u: &mut [f64],
    end: usize,
    mut after_chunk: impl FnMut(usize, &[f64], std::ops::Range<usize>),
) -> F4 {
    let mut sum = F4::default();
    let per_chunk = CHUNK_BLOCKS * LANES;
    for (c, chunk) in (1..end).step_by(per_chunk).enumerate() {
        let stop = (chunk + per_chunk).min(end);
        let blocks = flux[chunk..stop]
            .chunks_exact(LANES)
            .zip(flux[chunk - 1..stop - 1].chunks_exact(LANES))
            .zip(v[chunk..stop].chunks_exact_mut(LANES))
            .zip(u[chunk..stop].chunks_exact_mut(LANES));
        for (((f, before), vb), ub) in blocks {
            let vn = k.mul_add(F4::load(f) - F4::load(before), F4::load(vb));
            vn.store(vb);
            dt.mul_add(vn, F4::load(ub)).store(ub);
            sum = sum + vn;
        }
        after_chunk(c, &u[chunk..stop], chunk..stop);
    }
    sum
}

/// The first block at or after `from` whose stick mask differs between `a` and `b` (of one
/// length). Runs of 32 masks are compared as four 8-byte numbers at once (fixed-size loads, no
/// call), the rest and the run that differs byte by byte.
#[inline(always)]
fn first_change(a: &[u8], b: &[u8], from: usize) -> Option<usize> {
    const RUN: usize = 32;
    let (a, b) = (&a[from.min(a.len())..], &b[from.min(b.len())..]);
    let word = |x: &[u8], k: usize| u64::from_ne_bytes(x[k * 8..k * 8 + 8].try_into().unwrap());
    let mut start = 0;
    for (x, y) in a.chunks_exact(RUN).zip(b.chunks_exact(RUN)) {
        let differ = (0..RUN / 8).fold(0, |d, k| d | (word(x, k) ^ word(y, k)));
        if differ != 0 {
            break;
        }
        start += RUN;
    }
    a[start..]
        .iter()
        .zip(&b[start..])
        .position(|(x, y)| x != y)
        .map(|p| from + start + p)
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

/// The update constants, broadcast to four lanes.
#[derive(Clone, Copy)]
struct NodeConstants {
    beta: F4,
    gamma_inv_dx: F4,
    push: F4,
    g: F4,
    inv_g: F4,
}

impl NodeConstants {
    /// The same constants with the friction coefficients `g`, `push` (m/s) and `inv_g` (s/m).
    fn with_friction(&self, g: f64, push: f64, inv_g: f64) -> Self {
        Self {
            g: F4::splat(g),
            push: F4::splat(push),
            inv_g: F4::splat(inv_g),
            ..*self
        }
    }

    fn new(c: &Coefficients) -> Self {
        Self {
            beta: F4::splat(c.beta),
            gamma_inv_dx: F4::splat(c.gamma_inv_dx),
            push: F4::splat(c.push),
            g: F4::splat(c.g),
            inv_g: F4::splat(if c.g > 0.0 { 1.0 / c.g } else { 0.0 }),
        }
    }
}

/// Four nodes: `b = gamma (T_{i+1/2} - T_{i-1/2}) / dx + (beta v + eps c_d n_F / a)` (two fused
/// multiply-adds, as in [`node_scalar`] and every other sum of a product in the step), then the
/// exact stick update of [`crate::friction::select_with_inverse`], lane by lane, with the
/// friction coefficients `g`, `push`, `inv_g` of these nodes. Returns the new velocities and the
/// stick mask (bit `l` set where lane `l` is stuck).
#[inline(always)]
fn node_simd<const FRICTION: bool, const MAP: bool, const SPEED: bool>(
    k: &NodeConstants,
    v_old: F4,
    tension_difference: F4,
    g: F4,
    push: F4,
    inv_g: F4,
    acc: &mut NodeLanes,
) -> (F4, u8) {
    let zero = F4::splat(0.0);
    let one = F4::splat(1.0);
    let b = k
        .gamma_inv_dx
        .mul_add(tension_difference, k.beta.mul_add(v_old, push));
    let (v_new, speed, s, stuck) = if FRICTION {
        // the room left in the static band, `g - |b|`: its sign bit is set exactly where the
        // node slides (`|b| > g`; never -0.0, and a NaN `b` leaves it clear: no slide)
        let room = g - b.abs();
        // `-(g - |b|)` is `|b| - g` bit for bit (rounding is symmetric); `maxpd` returns its
        // second operand for a NaN or -0.0 excess: never negative, so `speed` is `|v_new|`
        let speed = (-room).max(zero);
        if SPEED {
            acc.max_speed = acc.max_speed.max(speed);
        }
        let v_new = speed | b.sign();
        // `b / g` clamped to [-1, 1], signed as `b` (`minpd` returns its second operand for NaN)
        let q = (b.abs() * inv_g).min(one) | b.sign();
        let s = room.select_sign(one | b.sign(), q);
        (v_new, speed, s, !room.sign_bits() & 0xF)
    } else {
        (b, b.abs(), zero, 0)
    };
    acc.add::<MAP>(v_new, speed, v_old, s);
    if MAP {
        acc.add_map(v_new, s, g, push);
    }
    (v_new, stuck)
}

/// The arrays of the kernel's whole four-node blocks (nodes `1 ..= whole`), all of one length;
/// `t_before` is the tension one half node to the left; `masks` receives the new stick mask of
/// each block (one per block).
struct Blocks<'a> {
    v: &'a mut [f64],
    t_here: &'a [f64],
    t_before: &'a [f64],
    masks: &'a mut [u8],
}

impl Blocks<'_> {
    /// Blocks `from..to` of these (numbered from 0 here).
    fn range(&mut self, from: usize, to: usize) -> Blocks<'_> {
        let r = from * LANES..to * LANES;
        Blocks {
            v: &mut self.v[r.clone()],
            t_here: &self.t_here[r.clone()],
            t_before: &self.t_before[r],
            masks: &mut self.masks[from..to],
        }
    }
}

/// Per-node friction coefficients of the blocks (empty with uniform friction): `g`, `inv_g`,
/// and `push` per node, or where n_F is the same all along the map, `push = g n_f`.
#[derive(Default)]
struct PerNode<'a> {
    g: &'a [f64],
    push: &'a [f64],
    inv_g: &'a [f64],
    n_f: f64,
}

/// Pass 2 over whole four-node blocks: [`node_simd`] with the uniform coefficients of `k`, or
/// with `MAP` the per-node ones (same length as the blocks; `PUSH`: `push` from its array, else
/// `g n_f`). Stores the new velocities and the blocks' new stick masks and returns the
/// accumulators. A function of
/// its own with local accumulators, so they stay in registers.
#[inline(never)]
fn node_blocks<const FRICTION: bool, const MAP: bool, const PUSH: bool, const SPEED: bool>(
    k: &NodeConstants,
    mut acc: NodeLanes,
    blocks: Blocks,
    coefficients: PerNode,
) -> NodeLanes {
    let PerNode {
        g: gs,
        push: pushes,
        inv_g: inv_gs,
        n_f,
    } = coefficients;
    let n_f = F4::splat(n_f);
    // zipped chunks of the arrays, so the loops run without bounds checks (and the lengths are
    // checked here once, as the zips would stop at the shortest)
    let len = blocks.v.len();
    assert!(blocks.t_here.len() == len && blocks.t_before.len() == len);
    assert!(blocks.masks.len() == len / LANES);
    assert!(!MAP || (gs.len() == len && inv_gs.len() == len && (!PUSH || pushes.len() == len)));
    let nodes = blocks
        .v
        .chunks_exact_mut(LANES)
        .zip(blocks.t_here.chunks_exact(LANES))
        .zip(blocks.t_before.chunks_exact(LANES))
        .zip(blocks.masks.iter_mut());
    let mut node = |((v, t_here), t_before): ((&mut [f64], &[f64]), &[f64]),
                    mask: &mut u8,
                    (g, push, inv_g): (F4, F4, F4)| {
        let (v_new, now) = node_simd::<FRICTION, MAP, SPEED>(
            k,
            F4::load(v),
            F4::load(t_here) - F4::load(t_before),
            g,
            push,
            inv_g,
            &mut acc,
        );
        v_new.store(v);
        *mask = now;
    };
    let per_node = gs.chunks_exact(LANES).zip(inv_gs.chunks_exact(LANES));
    match (MAP, PUSH) {
        (false, _) => {
            for (arrays, mask) in nodes {
                node(arrays, mask, (k.g, k.push, k.inv_g));
            }
        }
        // `g n_F` is how the map's `push` is worked out: the same bits
        (true, false) => {
            for ((arrays, mask), (g, inv_g)) in nodes.zip(per_node) {
                let g = F4::load(g);
                node(arrays, mask, (g, g * n_f, F4::load(inv_g)));
            }
        }
        (true, true) => {
            let per_node = per_node.zip(pushes.chunks_exact(LANES));
            for ((arrays, mask), ((g, inv_g), push)) in nodes.zip(per_node) {
                node(arrays, mask, (F4::load(g), F4::load(push), F4::load(inv_g)));
            }
        }
    }
    acc
}

/// Pass 2 over the whole blocks (nodes `1 ..= whole`) in a pipe whose friction varies, in runs of
/// chunks ([`NodeFriction::chunk_interval`]): a run whose nodes all lie in one interval of the map
/// goes through the uniform kernel with that interval's coefficients broadcast (its friction sums
/// follow from `sum s`, `sum |v|` and `sum v` as in a uniform pipe); the others read each node's
/// coefficients. Every node gets the same bits either way. Keeps the fastest speed while the map's
/// check needs it. Stores the blocks' new stick masks.
fn map_runs<const FRICTION: bool>(
    k: &NodeConstants,
    acc: &mut NodeLanes,
    m: &NodeFriction,
    mut blocks: Blocks,
) {
    let chunks = m.chunk_interval();
    let count = blocks.masks.len();
    // the fastest speed costs a reduction: only while the map's check needs it
    let speed = m.needs_reach();
    let mut c = 0;
    while c < chunks.len() {
        let j = chunks[c];
        let mut e = c + 1;
        while e < chunks.len() && chunks[e] == j {
            e += 1;
        }
        let (from, to) = (c * CHUNK_BLOCKS, (e * CHUNK_BLOCKS).min(count));
        let run = blocks.range(from, to);
        if j == MIXED {
            let r = 1 + from * LANES..1 + to * LANES;
            let per_node = PerNode {
                g: &m.g[r.clone()],
                push: &m.push[r.clone()],
                inv_g: &m.inv_g[r],
                n_f: m.uniform_n_f.unwrap_or(0.0),
            };
            *acc = match (m.uniform_n_f.is_some(), speed) {
                (true, true) => node_blocks::<FRICTION, true, false, true>(k, *acc, run, per_node),
                (true, false) => {
                    node_blocks::<FRICTION, true, false, false>(k, *acc, run, per_node)
                }
                (false, true) => node_blocks::<FRICTION, true, true, true>(k, *acc, run, per_node),
                (false, false) => {
                    node_blocks::<FRICTION, true, true, false>(k, *acc, run, per_node)
                }
            };
        } else {
            let (g, push, inv_g) = m.interval_coefficients(j as usize);
            let kj = k.with_friction(g, push, inv_g);
            let none = NodeLanes::default();
            let nodes = (to - from) * LANES;
            let sums = if speed {
                node_blocks::<FRICTION, false, false, true>(&kj, none, run, PerNode::default())
            } else {
                node_blocks::<FRICTION, false, false, false>(&kj, none, run, PerNode::default())
            };
            acc.add_run(&sums, g, push, nodes);
        }
        c = e;
    }
}

/// One node, the same operations as one lane of [`node_simd`]; returns whether it is stuck.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn node_scalar<const FRICTION: bool, const MAP: bool>(
    k: &NodeConstants,
    v: &mut f64,
    tension_difference: f64,
    (g, push, inv_g): (f64, f64, f64),
    acc: &mut NodeLanes,
) -> bool {
    let v_old = *v;
    let b = k
        .gamma_inv_dx
        .first()
        .mul_add(tension_difference, k.beta.first().mul_add(v_old, push));
    let (v_new, s, stuck) = if FRICTION {
        let sel = crate::friction::select_with_inverse(b, g, inv_g);
        (sel.velocity, sel.s, sel.stuck)
    } else {
        (b, 0.0, false)
    };
    acc.add_scalar(v_new, v_old, s);
    if MAP {
        acc.add_map_scalar(v_new, s, g, push);
        acc.max_speed = acc.max_speed.max(lane0(v_new.abs()));
    }
    *v = v_new;
    stuck
}

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
        self.tension_sin = t.mul_add(s, self.tension_sin);
        self.tension_cos = t.mul_add(c, self.tension_cos);
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
#[derive(Default, Clone, Copy)]
struct NodeLanes {
    sum_v: F4,
    sum_s: F4,
    /// sum of (v_old + v_new)^2
    sum_vm2: F4,
    /// sum of |v_new|
    sum_abs_v: F4,
    /// per-node friction: sum of `g s - push` (the Coulomb force in velocity units)
    sum_f: F4,
    /// per-node friction: sum of `(g s - push) v_new`
    sum_fv: F4,
    /// per-node friction: the largest `|v_new|`
    max_speed: F4,
    /// per-node friction, the runs of one interval: sum of `g s - push` and `(g s - push) v_new`
    run_f: f64,
    run_fv: f64,
}

struct NodeSums {
    sum_v: f64,
    sum_s: f64,
    friction_force: f64,
    stuck: f64,
    dissipation: f64,
    /// With per-node friction, the largest `|v_new|`, m/s.
    max_speed: f64,
}

impl NodeLanes {
    /// The reductions every node adds (`sum_abs_v` only with uniform friction); `speed` is
    /// `|v_new|`.
    #[inline(always)]
    fn add<const MAP: bool>(&mut self, v_new: F4, speed: F4, v_old: F4, s: F4) {
        let vs = v_old + v_new;
        self.sum_v = self.sum_v + v_new;
        self.sum_s = self.sum_s + s;
        self.sum_vm2 = vs.mul_add(vs, self.sum_vm2);
        if !MAP {
            self.sum_abs_v = self.sum_abs_v + speed;
        }
    }

    #[inline(always)]
    fn add_map(&mut self, v_new: F4, s: F4, g: F4, push: F4) {
        let f = g.mul_add(s, -push);
        self.sum_f = self.sum_f + f;
        self.sum_fv = f.mul_add(v_new, self.sum_fv);
    }

    /// Adds a run of `count` nodes of one interval with coefficients `g`, `push`, summed as in a
    /// uniform pipe: `sum (g s - push) = g sum s - push count` and, as `s v_new = |v_new|`,
    /// `sum (g s - push) v_new = g sum |v_new| - push sum v_new`.
    fn add_run(&mut self, run: &NodeLanes, g: f64, push: f64, count: usize) {
        self.sum_v = self.sum_v + run.sum_v;
        self.sum_s = self.sum_s + run.sum_s;
        self.sum_vm2 = self.sum_vm2 + run.sum_vm2;
        self.max_speed = self.max_speed.max(run.max_speed);
        self.run_f += g * run.sum_s.sum() - push * count as f64;
        self.run_fv += g * run.sum_abs_v.sum() - push * run.sum_v.sum();
    }

    #[inline(always)]
    fn add_scalar(&mut self, v_new: f64, v_old: f64, s: f64) {
        let vs = v_old + v_new;
        self.sum_v = self.sum_v + lane0(v_new);
        self.sum_s = self.sum_s + lane0(s);
        self.sum_vm2 = self.sum_vm2 + lane0(vs * vs);
        self.sum_abs_v = self.sum_abs_v + lane0(v_new.abs());
    }

    #[inline(always)]
    fn add_map_scalar(&mut self, v_new: f64, s: f64, g: f64, push: f64) {
        let f = g * s - push;
        self.sum_f = self.sum_f + lane0(f);
        self.sum_fv = self.sum_fv + lane0(f * v_new);
    }

    /// Combines the lanes. Dissipation density summed over nodes:
    /// `c_v sum ((v⁻ + v⁺)/2)^2 + sum eps_i c_d (s - n_F,i) v⁺`, where `s v⁺ = |v⁺|` exactly;
    /// with per-node friction `eps_i c_d = a g_i` and `eps_i c_d n_F,i = a push_i`. `stuck`: the
    /// number of stuck nodes after the step.
    fn finish(&self, c: &Coefficients, cells: usize, map: bool, stuck: usize) -> NodeSums {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper's plant on `cells` cells in a pipe with the `[pipe]` section `pipe`.
    fn piped(pipe: &str, cells: usize) -> Solver {
        let p = paper_with(pipe, cells, Boundary::Periodic);
        Solver::new(&p, &p.discretisation().unwrap())
    }

    /// The paper's plant parameters on `cells` cells with `boundary`, in a pipe with the
    /// `[pipe]` section `pipe`.
    fn paper_with(pipe: &str, cells: usize, boundary: Boundary) -> PlantParams {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../scenarios/paper.toml"
        ))
        .unwrap()
            + pipe;
        let s = crate::Scenario::from_toml(&text, "<test>", &Default::default()).unwrap();
        let mut p = s.plant.clone();
        p.numerics.cells = cells;
        p.boundary = boundary;
        p
    }

    /// One step of the scheme written out node by node, without the kernel's four-node blocks,
    /// runs of one interval, packed stick masks, kept face masks or lazy map bookkeeping: the
    /// tensions, the exact stick update with each node's friction where it stands, the grid
    /// filter, then the displacements `u += dt v`. `origin`: each node's world position at zero
    /// displacement, m; `length`: the body's, m (node 0 of a periodic body takes the mean
    /// coefficients of its place and the place one body length ahead). Returns the new
    /// `(u, v, stuck)` and the step's reductions summed in node order.
    fn reference_step(
        s: &Solver,
        origin: &[f64],
        length: f64,
        a: f64,
        b: f64,
    ) -> (Vec<f64>, Vec<f64>, Vec<bool>, ReferenceSums) {
        let c = s.coef;
        let n = s.cells();
        let periodic = s.boundary == Boundary::Periodic;
        let (mut u, mut v) = (s.u.to_vec(), s.v.to_vec());
        let t: Vec<f64> = (0..n)
            .map(|i| {
                if i == n - 1 && !periodic {
                    return 0.0;
                }
                let m = s.sin_table[i].mul_add(a, s.cos_table[i] * b);
                let m = if s.field_active { m + s.field[i] } else { m };
                c.stiffness_over_dx.mul_add(u[(i + 1) % n] - u[i], m)
            })
            .collect();
        let mut sums = ReferenceSums::default();
        // the free body's head face carries no tension and is left out of the reductions
        for i in 0..if periodic { n } else { n - 1 } {
            let du = u[(i + 1) % n] - u[i];
            sums.max_tension = sums.max_tension.max(t[i]);
            sums.max_strain = sums.max_strain.max(du.abs());
            sums.tension_sin.add(t[i] * s.sin_table[i]);
            sums.tension_cos.add(t[i] * s.cos_table[i]);
        }
        sums.max_strain *= c.inv_dx;
        let mut stuck = vec![false; n];
        for i in 0..n {
            let at = |m: &NodeFriction, x: f64| m.interval_coefficients(m.map.locate(x).index);
            let (g, push, inv_g) = match &s.map {
                Some(m) if i == 0 && periodic => {
                    let (tail, head) =
                        (at(m, origin[0] + u[0]), at(m, (origin[0] + length) + u[0]));
                    let g = 0.5 * (tail.0 + head.0);
                    (
                        g,
                        0.5 * (tail.1 + head.1),
                        if g > 0.0 { 1.0 / g } else { 0.0 },
                    )
                }
                Some(m) => at(m, origin[i] + u[i]),
                None => (c.g, c.push, if c.g > 0.0 { 1.0 / c.g } else { 0.0 }),
            };
            let bb = c
                .gamma_inv_dx
                .mul_add(t[i] - t[(i + n - 1) % n], c.beta.mul_add(v[i], push));
            let sel = crate::friction::select_with_inverse(bb, g, inv_g);
            // the kernel may sum the two parts of the Coulomb force apart (`g sum s - push N`)
            let (held, pushed) = (c.a * g * sel.s, c.a * push);
            let force = held - pushed;
            sums.sum_v_old.add(v[i]);
            sums.sum_s.add(sel.s);
            sums.friction_force.add(force);
            sums.friction_force.scale += held.abs() + pushed.abs();
            sums.dissipation
                .add(0.25 * c.viscous * (v[i] + sel.velocity).powi(2));
            sums.dissipation.add(force * sel.velocity);
            sums.dissipation.scale += (held.abs() + pushed.abs()) * sel.velocity.abs();
            sums.stuck += usize::from(sel.stuck);
            v[i] = sel.velocity;
            stuck[i] = sel.stuck;
        }
        if c.filter > 0.0 {
            let at = |i: isize| -> Option<usize> {
                let n = n as isize;
                if periodic {
                    Some(i.rem_euclid(n) as usize)
                } else {
                    (0..n).contains(&i).then_some(i as usize)
                }
            };
            let flux: Vec<f64> = (0..n as isize)
                .map(|f| {
                    let inside = (-1..=2).all(|o| at(f + o).is_some());
                    let free = (-2..=3).all(|o| at(f + o).is_none_or(|j| !stuck[j]));
                    // the mask multiplies (so a closed face's flux is a zero of either sign); off
                    // a free body's ends the stencil reads the end node
                    let open = if inside && free { 1.0 } else { 0.0 };
                    let w = |o: isize| v[(f + o).clamp(0, n as isize - 1) as usize];
                    let w = |o: isize| at(f + o).map_or_else(|| w(o), |j| v[j]);
                    open * (-3.0f64).mul_add(w(1) - w(0), w(2) - w(-1))
                })
                .collect();
            let k = -c.filter / 16.0;
            for i in 0..n {
                v[i] = k.mul_add(flux[i] - flux[(i + n - 1) % n], v[i]);
            }
        }
        for i in 0..n {
            u[i] = c.dt.mul_add(v[i], u[i]);
            sums.sum_v.add(v[i]);
        }
        (u, v, stuck, sums)
    }

    /// A sum with the sum of its terms' magnitudes (the scale of its round-off).
    #[derive(Debug, Default, Clone, Copy)]
    struct Sum {
        value: f64,
        scale: f64,
    }

    impl Sum {
        fn add(&mut self, x: f64) {
            self.value += x;
            self.scale += x.abs();
        }

        /// True if `x` equals this sum to the round-off of either order of summation.
        fn matches(&self, x: f64) -> bool {
            (x - self.value).abs() <= 1e-12 * self.scale + 1e-300
        }
    }

    /// The reductions of [`StepSums`], summed in node order.
    #[derive(Debug, Clone, Copy)]
    struct ReferenceSums {
        sum_v: Sum,
        sum_v_old: Sum,
        sum_s: Sum,
        friction_force: Sum,
        dissipation: Sum,
        stuck: usize,
        max_tension: f64,
        max_strain: f64,
        tension_sin: Sum,
        tension_cos: Sum,
    }

    impl Default for ReferenceSums {
        fn default() -> Self {
            Self {
                sum_v: Sum::default(),
                sum_v_old: Sum::default(),
                sum_s: Sum::default(),
                friction_force: Sum::default(),
                dissipation: Sum::default(),
                stuck: 0,
                max_tension: f64::NEG_INFINITY,
                max_strain: 0.0,
                tension_sin: Sum::default(),
                tension_cos: Sum::default(),
            }
        }
    }

    impl ReferenceSums {
        /// The fields of `k` that differ from these beyond round-off (maxima exactly).
        fn differences(&self, k: &StepSums) -> Vec<String> {
            let sums = [
                ("sum_v", self.sum_v, k.sum_v),
                ("sum_v_old", self.sum_v_old, k.sum_v_old),
                ("sum_s", self.sum_s, k.sum_s),
                ("friction_force", self.friction_force, k.friction_force),
                ("dissipation", self.dissipation, k.dissipation),
                ("tension_sin", self.tension_sin, k.tension_sin),
                ("tension_cos", self.tension_cos, k.tension_cos),
            ];
            let exact = [
                ("stuck", self.stuck as f64, k.stuck),
                ("max_tension", self.max_tension, k.max_tension),
                ("max_strain", self.max_strain, k.max_strain),
            ];
            sums.iter()
                .filter(|(_, r, x)| !r.matches(*x))
                .map(|(name, r, x)| format!("{name}: kernel {x:e}, reference {:e}", r.value))
                .chain(
                    exact
                        .iter()
                        .filter(|(_, r, x)| r.to_bits() != x.to_bits())
                        .map(|(name, r, x)| format!("{name}: kernel {x:e}, reference {r:e}")),
                )
                .collect()
        }
    }

    #[test]
    fn the_kernel_gives_the_bits_of_the_scheme_written_out_node_by_node() {
        // bodies of whole four-node blocks and of one to three nodes more, both ends, uniform
        // and textured pipes, with and without a muscle-force field
        let texture = "\n[pipe]\n[[pipe.features]]\nkind = \"texture\"\nfrom = -1.0\nto = 3.0\n\
                       eps_std = 0.3\nn_f_std = 0.05\ncorrelation = 0.01\nseed = 9\n";
        // a patch wide enough for runs of chunks in one interval
        let patch =
            "\n[pipe]\n[[pipe.features]]\nkind = \"patch\"\nfrom = 0.2\nto = 0.7\neps = 0.3\n";
        let (mut transitions, mut runs) = (0, 0);
        for cells in [9, 10, 11, 12, 13, 67, 130, 263] {
            for boundary in [Boundary::Periodic, Boundary::Free] {
                for (pipe, field, filter) in [
                    ("", false, true),
                    (texture, false, true),
                    (patch, false, true),
                    ("", true, true),
                    (texture, false, false),
                ] {
                    let mut p = paper_with(pipe, cells, boundary);
                    if !filter {
                        p.numerics.filter = 0.0;
                    }
                    let disc = p.discretisation().unwrap();
                    let mut s = Solver::new(&p, &disc);
                    let origin: Vec<f64> = (0..cells)
                        .map(|i| p.pipe.start + boundary.node_position(i, disc.dx))
                        .collect();
                    s.set_wave_number(2.0 * std::f64::consts::PI, disc.dx);
                    if field {
                        for (i, g) in s.field.iter_mut().enumerate() {
                            *g = 0.2 * (i as f64 * 0.7).sin();
                        }
                        s.set_field_active(true);
                    }
                    let case = format!(
                        "{cells} cells, {boundary:?}, pipe {pipe:?}, field {field}, filter {filter}"
                    );
                    for step in 0..3000 {
                        let w = step as f64 * 2e-3;
                        let (a, b) = (w.sin() * 0.6, w.cos() * 0.6);
                        let (u, v, stuck, sums) = reference_step(&s, &origin, p.length, a, b);
                        let before = s.stuck.clone();
                        let kernel = s.step(a, b);
                        let wrong = sums.differences(&kernel);
                        assert!(wrong.is_empty(), "{case}, step {step}: {wrong:?}");
                        let bits = |x: &[f64]| x.iter().map(|y| y.to_bits()).collect::<Vec<_>>();
                        assert_eq!(bits(&s.u), bits(&u), "{case}, step {step}: u");
                        assert_eq!(bits(&s.v), bits(&v), "{case}, step {step}: v");
                        assert_eq!(s.stuck, stuck, "{case}, step {step}: stuck");
                        // the switches, in node order, each with its new state
                        let switched: Vec<(u32, bool)> = (0..cells)
                            .filter(|&i| before[i] != stuck[i])
                            .map(|i| (i as u32, stuck[i]))
                            .collect();
                        let reported: Vec<(u32, bool)> =
                            s.transitions.iter().map(|t| (t.node, t.stuck)).collect();
                        assert_eq!(reported, switched, "{case}, step {step}: switches");
                        transitions += switched.len();
                    }
                    if let Some(m) = &s.map {
                        runs += m.chunk_interval().iter().filter(|&&j| j != MIXED).count();
                    }
                }
            }
        }
        assert!(transitions > 1000, "{transitions} stick/slip switches");
        assert!(
            runs > 0,
            "no chunk ran with its interval's coefficients broadcast"
        );
    }

    #[test]
    fn the_first_changed_mask_is_found_at_every_place_and_from_every_start() {
        // lengths around the 32-mask runs; one or two changed masks anywhere, and none
        for len in [0, 1, 31, 32, 33, 64, 95, 100] {
            let old: Vec<u8> = (0..len).map(|i| (i * 7 % 16) as u8).collect();
            let naive = |new: &[u8], from: usize| (from..len).find(|&i| new[i] != old[i]);
            let mut cases = vec![vec![]];
            for i in 0..len {
                cases.push(vec![i]);
                cases.push(vec![i, (i + 33) % len]);
            }
            for changed in cases {
                let mut new = old.clone();
                for &i in &changed {
                    new[i] ^= 1 << (i % 4);
                }
                for from in 0..=len + 1 {
                    assert_eq!(
                        first_change(&new, &old, from),
                        naive(&new, from),
                        "len {len}, changed {changed:?}, from {from}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_block_tells_stick_from_slip_as_the_scalar_select_at_the_band_edge_and_for_nan() {
        let g: f64 = 0.3;
        let (up, down) = (
            f64::from_bits(g.to_bits() + 1),
            f64::from_bits(g.to_bits() - 1),
        );
        let bs = [
            g,
            -g,
            up,
            -up,
            down,
            -down,
            0.0,
            1e300,
            -5.0,
            f64::NAN,
            -f64::NAN,
            1e-300,
        ];
        let one = F4::splat(1.0);
        let k = NodeConstants {
            beta: one,
            gamma_inv_dx: one,
            push: F4::splat(0.0),
            g: F4::splat(g),
            inv_g: F4::splat(1.0 / g),
        };
        let zero = F4::splat(0.0);
        for b4 in bs.chunks_exact(LANES) {
            // `b = 1 * 0 + 1 * 0 + push` is `push` bit for bit (no -0.0 among them)
            let push = F4::load(b4);
            let mut acc = NodeLanes::default();
            let (v, mask) =
                node_simd::<true, false, false>(&k, zero, zero, k.g, push, k.inv_g, &mut acc);
            for (l, &b) in b4.iter().enumerate() {
                let sel = crate::friction::select_with_inverse(b, g, 1.0 / g);
                assert_eq!(v.lanes()[l].to_bits(), sel.velocity.to_bits(), "b = {b:e}");
                assert_eq!(mask >> l & 1 != 0, sel.stuck, "b = {b:e}");
                assert_eq!(acc.sum_s.lanes()[l].to_bits(), sel.s.to_bits(), "b = {b:e}");
            }
            // a node is stuck exactly when it has no slide velocity, and then only
            for (l, &b) in b4.iter().enumerate() {
                let stuck = mask >> l & 1 != 0;
                assert_eq!(stuck, v.lanes()[l] == 0.0, "b = {b:e}");
                assert_eq!(stuck, b.abs() <= g || b.is_nan(), "b = {b:e}");
            }
        }
    }

    /// The paper's plant on 256 cells in a pipe whose eps (and with `n_f_std > 0` n_F) varies.
    fn textured(n_f_std: f64) -> Solver {
        piped(
            &format!(
                "\n[pipe]\n[[pipe.features]]\nkind = \"texture\"\nfrom = -1.0\nto = 3.0\n\
                 eps_std = 0.1\nn_f_std = {n_f_std:?}\ncorrelation = 0.002\nseed = 4\n"
            ),
            256,
        )
    }

    #[test]
    fn runs_of_one_interval_give_the_bits_of_per_node_coefficients() {
        // patches wide and narrow (one of n_F too), so that the body has long runs of one
        // interval and chunks that straddle an edge
        let pipe = "\n[pipe]\n\
            [[pipe.features]]\nkind = \"patch\"\nfrom = 0.3\nto = 0.6\neps = 0.3\n\
            [[pipe.features]]\nkind = \"patch\"\nfrom = 0.71\nto = 0.7105\neps = 0.02\n\
            [[pipe.features]]\nkind = \"patch\"\nfrom = 0.75\nto = 1.2\nn_f = 0.0\n";
        let mut runs = piped(pipe, 1024);
        runs.set_wave_number(2.0 * std::f64::consts::PI, 1.0 / 1024.0);
        let mut per_node = runs.clone();
        per_node.map.as_mut().unwrap().broadcast = false;
        per_node.refresh_friction();
        let chunks = |s: &Solver| {
            let c = s.map.as_ref().unwrap().chunk_interval();
            (c.iter().filter(|&&j| j != MIXED).count(), c.len())
        };
        assert_eq!(chunks(&per_node).0, 0);
        let (mut transitions, mut backward) = (0, 0);
        for n in 0..20_000 {
            let (a, b) = ((n as f64 * 1e-3).sin() * 0.5, (n as f64 * 1e-3).cos() * 0.5);
            let (x, y) = (runs.step(a, b), per_node.step(a, b));
            backward += runs.v.iter().filter(|&&v| v < 0.0).count();
            assert_eq!(runs.u, per_node.u, "step {n}");
            assert_eq!(runs.v, per_node.v, "step {n}");
            assert_eq!(runs.stuck, per_node.stuck, "step {n}");
            // the sums are summed in another order: equal to round-off of the band's scale,
            // the Coulomb force sum a g_i (N/m summed over the nodes) and its power
            let band: f64 = runs.map.as_ref().unwrap().g.iter().sum::<f64>() * runs.coef.a;
            let speed = runs.v.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
            let close = |p: f64, q: f64, scale: f64| (p - q).abs() <= 1e-12 * scale;
            assert!(
                close(x.friction_force, y.friction_force, band),
                "step {n}: {x:?} {y:?}"
            );
            assert!(close(
                x.dissipation,
                y.dissipation,
                band * speed + x.dissipation.abs()
            ));
            assert!(close(x.sum_s, y.sum_s, runs.cells() as f64));
            transitions += runs.transitions.len();
        }
        let (uniform, all) = chunks(&runs);
        assert!(
            uniform > all / 2 && uniform < all,
            "{uniform} of {all} chunks in one interval"
        );
        assert!(transitions > 100, "{transitions} stick/slip switches");
        // nodes slid both ways (so `sum |v|` and `sum v` differ)
        assert!(backward > 1000, "{backward} node steps backwards");
    }

    #[test]
    fn computing_push_from_a_uniform_n_f_gives_the_bits_of_reading_it() {
        let mut computed = textured(0.0);
        assert!(computed.map.as_ref().unwrap().uniform_n_f.is_some());
        let mut read = computed.clone();
        read.map.as_mut().unwrap().uniform_n_f = None;
        let mut transitions = 0;
        for n in 0..20_000 {
            let (a, b) = ((n as f64 * 1e-3).sin() * 0.3, (n as f64 * 1e-3).cos() * 0.3);
            let (x, y) = (computed.step(a, b), read.step(a, b));
            assert_eq!(x.dissipation.to_bits(), y.dissipation.to_bits(), "step {n}");
            assert_eq!(x.friction_force.to_bits(), y.friction_force.to_bits());
            transitions += computed.transitions.len();
        }
        let bits = |s: &Solver| {
            s.u.iter()
                .chain(&s.v)
                .map(|x| x.to_bits())
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&computed), bits(&read));
        assert!(transitions > 100, "{transitions} stick/slip switches");
        // and a map whose n_F varies reads its push
        assert!(textured(0.05).map.unwrap().uniform_n_f.is_none());
    }
}
