//! The step written out node by node in plain scalar code, with the reductions summed in node
//! order: what the kernel must match bit for bit (the test in `tests.rs`). Tests only.

use super::{Solver, StepSums};
use crate::node_friction::NodeFriction;
use crate::params::Boundary;

/// One step of the scheme written out node by node, without the kernel's four-node blocks,
/// runs of one interval, packed stick masks, kept face masks or lazy map bookkeeping: the
/// tensions, the exact stick update with each node's friction where it stands, the grid
/// filter, then the displacements `u += dt v`. `origin`: each node's world position at zero
/// displacement, m; `length`: the body's, m (node 0 of a periodic body takes the mean
/// coefficients of its place and the place one body length ahead). Returns the new
/// `(u, v, stuck)` and the step's reductions summed in node order.
pub(super) fn reference_step(
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
                let (tail, head) = (at(m, origin[0] + u[0]), at(m, (origin[0] + length) + u[0]));
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
pub(super) struct ReferenceSums {
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
    pub(super) fn differences(&self, k: &StepSums) -> Vec<String> {
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
