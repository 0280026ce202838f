//! Pass 2 of the step: the new velocities with exact stick, node by node in closed form
//! ([`crate::friction::select_with_inverse`]), and the stick/slip switches. The whole four-node
//! blocks go through [`node_simd`] (uniform coefficients, per-node ones, or in a varying pipe
//! runs of one interval with its coefficients broadcast, [`map_runs`]); node 0 and the tail
//! through [`node_scalar`], the same operations as one lane.

use super::lanes::{lane0, NodeLanes, NodeSums};
use super::{Coefficients, Solver, Transition};
use crate::node_friction::{NodeFriction, CHUNK_BLOCKS, MIXED};
use crate::simd::{F4, LANES};

impl Solver {
    /// Pass 2: new velocities with exact stick and the stick/slip switches (the displacements
    /// follow in pass 3, `u += dt v` with the filtered velocities).
    /// `MAP`: per-node friction coefficients from the pipe's map.
    #[inline(never)]
    pub(super) fn nodes<const FRICTION: bool, const MAP: bool>(&mut self) -> NodeSums {
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
