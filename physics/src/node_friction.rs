//! Per-node friction along a pipe whose friction varies: which piece of the [`FrictionMap`] each
//! node is in, the update's coefficients there, and when a node may have left its piece.
//!
//! A node takes the friction of the piece holding its world position `X = origin + u` after the
//! whole step, `lo <= X < hi`, exactly as [`FrictionMap::locate`] says; a state restored from
//! outside places every node that way from scratch. On a periodic body node 0 stands for the half
//! cells at both ends of the body, the tail's at `origin + u` and the head's a body length ahead
//! ([`Seam`]), and takes the mean of the two places' coefficients (with only the tail's place the
//! body would sit half a cell behind where it is, an error of first order in the cell size).
//! Between steps the bookkeeping is lazy but never wrong:
//!
//! - each node keeps its piece's edges as displacements rounded inwards, so `u_lo <= u < u_hi`
//!   implies that `X`, rounded as `locate` rounds it, lies in the piece (a node in the rounding band
//!   is looked up exactly);
//! - the solver reports after each step a bound on how far any node moved in it (from the fastest
//!   node's speed, with the round-off of the additions), summed into `travel`, an upper bound on any
//!   node's distance covered since the run (or the last placement) began;
//! - each block of [`LANES`] nodes has a `due` value: `travel` plus the block's smallest distance
//!   to an edge (rounded down) when it was last examined. No node of the block can have left its
//!   piece while `travel < due`; a block that falls due is examined and gets a new `due`.
//!
//! In a pipe with a few patches blocks fall due only near the patch edges. In a fine texture (or a
//! ramp, held constant every millimetre) a block falls due every few steps, and examining it costs
//! more than checking every node: when the examinations of a window of [`WINDOW`] steps (each
//! [`EXAMINE_COST`] block checks) and the lazy check's own cost ([`LAZY_COST`] block checks a
//! step) come to more than checking every block, the check turns eager for [`EAGER_STEPS`] steps
//! (every node against its edges, in the grid filter's pass while the displacements are in the
//! first-level cache), then tries the lazy check again with every block due. Both give the same
//! intervals.
//!
//! The kernel runs the chunks of [`CHUNK_BLOCKS`] blocks whose nodes all lie in one interval with
//! that interval's coefficients broadcast, as in a uniform pipe ([`NodeFriction::chunk_interval`]).

use crate::node_array::NodeArray;
use crate::pipe::FrictionMap;
use crate::simd::{F4, LANES};

/// One lazy examination of a block costs about this many eager block checks (measured with the
/// plant's benchmark in a 1 mm texture and in patches, N = 4096).
pub const EXAMINE_COST: usize = 16;

/// The lazy check's own cost per step (the bound's arithmetic, the fastest speed the kernel then
/// keeps) is about this many eager block checks: on a small body the eager check is cheaper.
pub const LAZY_COST: usize = 64;

/// Steps over which the lazy check's examinations are counted.
pub const WINDOW: u32 = 64;

/// Steps the check stays eager before it tries the lazy check again.
pub const EAGER_STEPS: u32 = 4096;

/// Blocks per chunk of [`NodeFriction::chunk_interval`].
pub const CHUNK_BLOCKS: usize = 16;

/// [`NodeFriction::chunk_interval`] of a chunk whose nodes are not all in one interval.
pub const MIXED: u32 = u32::MAX;

/// How the nodes are checked against their intervals' edges.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Check {
    /// Blocks examined when due; `examined` blocks in the `steps` steps of this window so far.
    Lazy { steps: u32, examined: usize },
    /// Every node at every step, `steps` more steps.
    Eager { steps: u32 },
}

/// Per-node friction coefficients along a pipe whose friction varies.
#[derive(Debug, Clone)]
pub struct NodeFriction {
    pub map: FrictionMap,
    /// The map's intervals (index 0 before the first piece) with their coefficients.
    intervals: Vec<Interval>,
    /// World position of each node at zero displacement, m.
    origin: Vec<f64>,
    /// Map interval each node is in.
    pub index: Vec<usize>,
    /// The interval's edges as displacements, rounded inwards: `u_lo <= u < u_hi` implies that
    /// the node's world position lies in the interval, m.
    u_lo: NodeArray,
    u_hi: NodeArray,
    /// `eps_i c_d / a`, m/s.
    pub g: NodeArray,
    /// `1 / g_i` (0 where `g_i = 0`), s/m.
    pub inv_g: NodeArray,
    /// `eps_i c_d n_F,i / a`, m/s.
    pub push: NodeArray,
    /// n_F where it is the same in every interval (then `push = g n_F`, one array less to read).
    pub uniform_n_f: Option<f64>,
    /// Per block of [`LANES`] nodes from node 1: no node of the block can have left its interval
    /// while `travel < due`, m.
    due: Vec<f64>,
    /// Upper bound on the distance any node has moved since the last placement, m.
    travel: f64,
    /// Upper bound on every node's `|u|`, m.
    u_bound: f64,
    check: Check,
    /// Per chunk of [`CHUNK_BLOCKS`] blocks: the interval all its nodes are in, or [`MIXED`]
    /// (the kernel runs such chunks with the interval's coefficients broadcast).
    chunk_interval: Vec<u32>,
    /// The eager check's chunks with a node outside: the first `escaped_count` entries (one slot
    /// per chunk, allocated once); `escaped_listed` while the grid filter has filled them.
    escaped: Vec<usize>,
    escaped_count: usize,
    escaped_listed: bool,
    /// False to run every chunk with per-node coefficients (the same bits; for tests).
    pub(crate) broadcast: bool,
    /// Chunks whose nodes changed interval since `chunk_interval` was last worked out.
    dirty: Vec<usize>,
    is_dirty: Vec<bool>,
    /// On a periodic body, where node 0's head half cell is.
    seam: Option<Seam>,
}

/// Node 0 of a periodic body stands for the half cells at both ends of the body: the tail's place
/// is its own, `origin[0] + u_0`; the head's is one body length ahead, `(origin[0] + L) + u_0`.
/// Node 0 takes the mean of the two places' coefficients (`g`, `push`; `inv_g = 1 / g`).
#[derive(Debug, Clone, Copy)]
struct Seam {
    /// World position of the head's place at zero displacement, `origin[0] + L`, m.
    origin: f64,
    /// Map interval the head's place is in.
    index: usize,
    /// The interval's edges as displacements of node 0, rounded inwards (as `u_lo`, `u_hi`), m.
    u_lo: f64,
    u_hi: f64,
}

/// One interval of the map with the update's coefficients worked out once.
#[derive(Debug, Clone, Copy)]
struct Interval {
    lo: f64,
    hi: f64,
    g: f64,
    inv_g: f64,
    push: f64,
}

/// Nodes `first..first + blocks * LANES` form the kernel's whole blocks of a body of `n` nodes.
pub fn whole_blocks(n: usize) -> (usize, usize) {
    (1, (n - 1) / LANES)
}

impl NodeFriction {
    /// Nodes at world positions `origin` (m) at rest; `a = rho/dt + c_v/2` (kg/(m s)) and `dry`
    /// (`c_d`, N/m) give the coefficients. `periodic_length`: on a periodic body its length `L`
    /// (m; node 0 then also feels the place `L` ahead of it, see [`Seam`]), `None` on a free one.
    pub fn new(
        map: FrictionMap,
        origin: Vec<f64>,
        a: f64,
        dry: f64,
        periodic_length: Option<f64>,
    ) -> Self {
        let n = origin.len();
        let intervals = (0..=map.pieces.len())
            .map(|j| {
                let l = map.interval(j);
                // +0.0 for a zero eps of either sign (the kernel tells stick by the sign of
                // `g - |b|`, which a -0.0 would flip for a node at rest)
                let g = l.eps * dry / a + 0.0;
                Interval {
                    lo: l.lo,
                    hi: l.hi,
                    g,
                    inv_g: if g > 0.0 { 1.0 / g } else { 0.0 },
                    push: g * l.n_f,
                }
            })
            .collect::<Vec<Interval>>();
        let n_f = map.interval(0).n_f;
        let uniform_n_f =
            (0..intervals.len()).all(|j| map.interval(j).n_f.to_bits() == n_f.to_bits());
        let chunks = whole_blocks(n).1.div_ceil(CHUNK_BLOCKS);
        let mut m = Self {
            chunk_interval: vec![MIXED; chunks],
            broadcast: true,
            escaped: vec![0; chunks],
            escaped_count: 0,
            escaped_listed: false,
            dirty: Vec::with_capacity(chunks),
            is_dirty: vec![false; chunks],
            uniform_n_f: uniform_n_f.then_some(n_f),
            map,
            intervals,
            origin,
            index: vec![0; n],
            u_lo: NodeArray::zeros(n),
            u_hi: NodeArray::zeros(n),
            g: NodeArray::zeros(n),
            inv_g: NodeArray::zeros(n),
            push: NodeArray::zeros(n),
            due: vec![f64::NEG_INFINITY; whole_blocks(n).1],
            travel: 0.0,
            u_bound: 0.0,
            check: Check::Lazy {
                steps: 0,
                examined: 0,
            },
            seam: None,
        };
        m.seam = periodic_length.map(|l| Seam {
            origin: m.origin[0] + l,
            index: 0,
            u_lo: 0.0,
            u_hi: 0.0,
        });
        m.place_all(&vec![0.0; n]);
        m
    }

    /// Places every node for displacements `u` (m), searching the map from scratch (a state set
    /// from outside); every block falls due at the next step.
    pub fn place_all(&mut self, u: &[f64]) {
        for (i, &x) in u.iter().enumerate() {
            let j = self.map.locate(self.origin[i] + x).index;
            self.set(i, j);
        }
        if let Some(seam) = self.seam {
            self.set_head(self.map.locate(seam.origin + u[0]).index);
        }
        self.due.fill(f64::NEG_INFINITY);
        self.travel = 0.0;
        self.u_bound = u.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
        self.settle_chunks();
    }

    /// Per chunk of [`CHUNK_BLOCKS`] blocks (of [`LANES`] nodes from node 1): the interval all its
    /// nodes are in, or [`MIXED`].
    pub fn chunk_interval(&self) -> &[u32] {
        &self.chunk_interval
    }

    /// `(g, push, inv_g)` of interval `j`: `eps c_d / a`, `eps c_d n_F / a` (m/s) and `1 / g`.
    pub fn interval_coefficients(&self, j: usize) -> (f64, f64, f64) {
        let l = self.intervals[j];
        (l.g, l.push, l.inv_g)
    }

    /// Works out `chunk_interval` again for the chunks whose nodes changed interval.
    fn settle_chunks(&mut self) {
        let (first, blocks) = whole_blocks(self.index.len());
        let end = first + blocks * LANES;
        for c in self.dirty.drain(..) {
            let start = first + c * CHUNK_BLOCKS * LANES;
            let nodes = &self.index[start..(start + CHUNK_BLOCKS * LANES).min(end)];
            let j = nodes[0];
            self.chunk_interval[c] = if self.broadcast && nodes.iter().all(|&x| x == j) {
                j as u32
            } else {
                MIXED
            };
            self.is_dirty[c] = false;
        }
    }

    /// Moves node `i` to the interval holding displacement `u`, walking from its current one.
    #[inline(always)]
    fn follow(&mut self, i: usize, u: f64) {
        if !(u >= self.u_lo[i] && u < self.u_hi[i]) {
            self.relocate(i, u);
        }
    }

    /// [`Self::follow`] for a node outside its interval's edges (or in their rounding band).
    #[inline(never)]
    fn relocate(&mut self, i: usize, u: f64) {
        let j = self.walk(self.index[i], self.origin[i] + u);
        self.set(i, j);
    }

    /// The interval holding world position `x` (m), walking from interval `j`.
    fn walk(&self, mut j: usize, x: f64) -> usize {
        let last = self.intervals.len() - 1;
        while j < last && x >= self.intervals[j].hi {
            j += 1;
        }
        while j > 0 && x < self.intervals[j].lo {
            j -= 1;
        }
        j
    }

    /// Node 0's head place ([`Seam`]) for displacement `u` (m): moved to the interval it is in now.
    fn follow_head(&mut self, u: f64) {
        if let Some(seam) = self.seam {
            if !(u >= seam.u_lo && u < seam.u_hi) {
                self.set_head(self.walk(seam.index, seam.origin + u));
            }
        }
    }

    /// Puts node 0's head place ([`Seam`]) in interval `j` and works out node 0's coefficients.
    fn set_head(&mut self, j: usize) {
        let l = self.intervals[j];
        if let Some(seam) = &mut self.seam {
            seam.index = j;
            (seam.u_lo, seam.u_hi) = inner_edges(&l, seam.origin);
        }
        self.set_coefficients(0);
    }

    /// The coefficients of node `i` from its interval (node 0 of a periodic body: the mean of its
    /// tail's and head's intervals, [`Seam`]).
    fn set_coefficients(&mut self, i: usize) {
        let l = self.intervals[self.index[i]];
        (self.g[i], self.inv_g[i], self.push[i]) = match self.seam.filter(|_| i == 0) {
            None => (l.g, l.inv_g, l.push),
            Some(seam) => {
                let h = self.intervals[seam.index];
                // the mean of two equal values is that value, bit for bit
                let g = 0.5 * (l.g + h.g);
                (
                    g,
                    if g > 0.0 { 1.0 / g } else { 0.0 },
                    0.5 * (l.push + h.push),
                )
            }
        };
    }

    /// eps and n_F of node `i` (node 0 of a periodic body: the mean eps of its two places and
    /// the n_F that gives the mean of their `eps n_F`).
    pub fn friction(&self, i: usize) -> (f64, f64) {
        let l = self.map.interval(self.index[i]);
        match self.seam.filter(|_| i == 0) {
            None => (l.eps, l.n_f),
            Some(seam) => {
                let h = self.map.interval(seam.index);
                if l.eps == h.eps && l.n_f == h.n_f {
                    return (l.eps, l.n_f);
                }
                let eps = 0.5 * (l.eps + h.eps);
                let n_f = if eps > 0.0 {
                    0.5 * (l.eps * l.n_f + h.eps * h.n_f) / eps
                } else {
                    0.5 * (l.n_f + h.n_f)
                };
                (eps, n_f)
            }
        }
    }

    #[inline]
    fn set(&mut self, i: usize, j: usize) {
        let l = self.intervals[j];
        self.index[i] = j;
        (self.u_lo[i], self.u_hi[i]) = inner_edges(&l, self.origin[i]);
        self.set_coefficients(i);
        // the chunk of node `i`, if it is in the kernel's whole blocks
        if i >= 1 && (i - 1) / LANES < self.due.len() {
            let c = (i - 1) / LANES / CHUNK_BLOCKS;
            if !self.is_dirty[c] {
                self.is_dirty[c] = true;
                self.dirty.push(c);
            }
        }
    }

    /// After a step that moved no node by more than `reach` plus the round-off of adding it to
    /// `u` (m; needed only while [`Self::needs_reach`]): moves the nodes that left their interval
    /// to the interval they are in now (node 0 and the nodes after the whole blocks at every step,
    /// the blocks as the check says). Returns the number of blocks the lazy check examined.
    pub fn follow_step(&mut self, u: &[f64], reach: f64) -> usize {
        let (first, blocks) = whole_blocks(u.len());
        self.follow(0, u[0]);
        self.follow_head(u[0]);
        for (i, &x) in u.iter().enumerate().skip(first + blocks * LANES) {
            self.follow(i, x);
        }
        let examined = match self.check {
            Check::Lazy { steps, examined } => {
                // The step's addition to `u` is off by at most 2^-53 of its result (counted
                // twice here, and twice again for the rounding of this line itself).
                let round_off = (self.u_bound + reach) * (2.0 * f64::EPSILON) + f64::MIN_POSITIVE;
                let bound = (reach + round_off).next_up();
                self.travel = (self.travel + bound).next_up();
                self.u_bound = (self.u_bound + bound).next_up();
                let now = self.follow_due(u);
                let (steps, examined) = (steps + 1, examined + now);
                self.check = if steps < WINDOW {
                    Check::Lazy { steps, examined }
                } else if examined * EXAMINE_COST + LAZY_COST * WINDOW as usize
                    > blocks * WINDOW as usize
                {
                    Check::Eager { steps: EAGER_STEPS }
                } else {
                    Check::Lazy {
                        steps: 0,
                        examined: 0,
                    }
                };
                now
            }
            Check::Eager { steps } => {
                // no bound on the travel is kept (the solver leaves `reach` out): back to the lazy
                // check, every block falls due and `|u|` is bounded afresh
                self.follow_all(u);
                self.check = if steps > 1 {
                    Check::Eager { steps: steps - 1 }
                } else {
                    self.due.fill(f64::NEG_INFINITY);
                    self.u_bound = u.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
                    Check::Lazy {
                        steps: 0,
                        examined: 0,
                    }
                };
                0
            }
        };
        self.settle_chunks();
        examined
    }

    /// True while the check needs the bound on the step's travel (the lazy check): the solver
    /// then keeps the fastest speed of the step.
    pub fn needs_reach(&self) -> bool {
        matches!(self.check, Check::Lazy { .. })
    }

    /// The lazy check: examines the blocks that are due; returns how many.
    fn follow_due(&mut self, u: &[f64]) -> usize {
        let blocks = self.due.len();
        let travel = self.travel;
        let mut examined = 0;
        let mut b = 0;
        while b + LANES <= blocks {
            // four blocks' due values at once: the common case is that none is due
            if !all_below(travel, &self.due[b..b + LANES]) {
                for k in b..b + LANES {
                    if is_due(travel, self.due[k]) {
                        self.examine(k, u);
                        examined += 1;
                    }
                }
            }
            b += LANES;
        }
        for k in b..blocks {
            if is_due(travel, self.due[k]) {
                self.examine(k, u);
                examined += 1;
            }
        }
        examined
    }

    /// The eager check: every node of the whole blocks against its edges, a chunk of
    /// [`CHUNK_BLOCKS`] blocks at a time, unless the grid filter has already listed the chunks
    /// with a node outside ([`Self::fused_check`]); follows the nodes of those chunks.
    fn follow_all(&mut self, u: &[f64]) {
        let (first, blocks) = whole_blocks(u.len());
        let end = first + blocks * LANES;
        let per_chunk = CHUNK_BLOCKS * LANES;
        if !self.escaped_listed {
            self.escaped_count = 0;
            for (c, start) in (first..end).step_by(per_chunk).enumerate() {
                let r = start..(start + per_chunk).min(end);
                if chunk_left(&u[r.clone()], &self.u_lo[r.clone()], &self.u_hi[r]) {
                    self.escaped[self.escaped_count] = c;
                    self.escaped_count += 1;
                }
            }
        }
        self.escaped_listed = false;
        for e in 0..self.escaped_count {
            let start = first + self.escaped[e] * per_chunk;
            for block in (start..(start + per_chunk).min(end)).step_by(LANES) {
                let r = block..block + LANES;
                if chunk_left(&u[r.clone()], &self.u_lo[r.clone()], &self.u_hi[r.clone()]) {
                    for (i, &x) in u.iter().enumerate().skip(block).take(LANES) {
                        self.follow(i, x);
                    }
                }
            }
        }
    }

    /// While the check is eager: the edges as displacements and the list of chunks with a node
    /// outside, for the grid filter to fill as it writes the displacements (its chunks of
    /// [`CHUNK_BLOCKS`] blocks from node 1 are the same); `None` while the check is lazy.
    pub fn fused_check(&mut self) -> Option<FusedCheck<'_>> {
        if !matches!(self.check, Check::Eager { .. }) {
            return None;
        }
        self.escaped_listed = true;
        Some(FusedCheck {
            u_lo: &self.u_lo,
            u_hi: &self.u_hi,
            escaped: &mut self.escaped,
            count: &mut self.escaped_count,
        })
    }

    /// Follows the nodes of block `k` if one left its interval and sets the block's new due
    /// value.
    fn examine(&mut self, k: usize, u: &[f64]) {
        let start = whole_blocks(u.len()).0 + k * LANES;
        let r = start..start + LANES;
        let x = F4::load(&u[r.clone()]);
        let edges = |m: &Self| (F4::load(&m.u_lo[r.clone()]), F4::load(&m.u_hi[r.clone()]));
        let (mut lo, mut hi) = edges(self);
        if !x.inside(lo, hi).all_set() {
            for (i, &y) in u.iter().enumerate().skip(start).take(LANES) {
                self.follow(i, y);
            }
            (lo, hi) = edges(self);
        }
        // The distances are rounded to within 2^-53 of themselves, so `slack (1 - 2^-50)` is
        // below the true smallest one; the sum is rounded down.
        let slack = (x - lo).min(hi - x).min_lane();
        self.due[k] = if slack > 0.0 {
            (self.travel + slack * (1.0 - 4.0 * f64::EPSILON)).next_down()
        } else {
            f64::NEG_INFINITY
        };
    }
}

/// Interval `l`'s edges as displacements of a node at world position `o` at rest, rounded
/// inwards: `u_lo <= u < u_hi` implies that the rounded `o + u` lies in `[lo, hi)`, m.
fn inner_edges(l: &Interval, o: f64) -> (f64, f64) {
    // `u >= u_lo >= lo - o` gives `o + u >= lo`, so the rounded sum is `>= lo`;
    // `u < u_hi <= pred(hi) - o` gives `o + u < pred(hi)`, so the rounded sum is `< hi`.
    let lo = if l.lo.is_finite() {
        (l.lo - o).next_up()
    } else {
        f64::NEG_INFINITY
    };
    let hi = if l.hi.is_finite() {
        (l.hi.next_down() - o).next_down()
    } else {
        f64::INFINITY
    };
    (lo, hi)
}

/// The eager check done in another pass over the displacements (see
/// [`NodeFriction::fused_check`]).
pub struct FusedCheck<'a> {
    /// The edges of each node's interval as displacements, m.
    pub u_lo: &'a [f64],
    pub u_hi: &'a [f64],
    /// Chunks with a node outside: the first `count` entries.
    pub escaped: &'a mut [usize],
    pub count: &'a mut usize,
}

/// True if a node of the chunk `u` (whole blocks of [`LANES`] nodes) lies outside its interval
/// `[lo, hi)` (the blocks' masks are combined and tested once).
#[inline(always)]
pub fn chunk_left(u: &[f64], lo: &[f64], hi: &[f64]) -> bool {
    let mut inside = F4::load(&[f64::from_bits(u64::MAX); LANES]);
    let blocks = u
        .chunks_exact(LANES)
        .zip(lo.chunks_exact(LANES))
        .zip(hi.chunks_exact(LANES));
    for ((x, l), h) in blocks {
        inside = inside & F4::load(x).inside(F4::load(l), F4::load(h));
    }
    !inside.all_set()
}

/// True unless `travel < due` (so also where either is NaN).
#[inline(always)]
fn is_due(travel: f64, due: f64) -> bool {
    travel.partial_cmp(&due) != Some(std::cmp::Ordering::Less)
}

/// True if `x < due[l]` in each of the first [`LANES`] lanes.
#[inline(always)]
fn all_below(x: f64, due: &[f64]) -> bool {
    F4::splat(x).all_lt(F4::load(due))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipe::{patch, Feature, Pipe};

    /// 1024 nodes 1 mm apart from 0 m; patches at [0.1, 0.3) and two ulps wide at 0.3 m.
    fn patches() -> NodeFriction {
        let pipe = Pipe {
            features: vec![
                patch(0.1, 0.3, 0.5),
                patch(0.3, 0.3f64.next_up().next_up(), 0.7),
            ],
            ..Default::default()
        };
        let map = pipe.compile(0.1, 0.5);
        assert_eq!(map.pieces.len(), 3);
        let origin = (0..1024).map(|i| i as f64 * 1e-3).collect();
        NodeFriction::new(map, origin, 2.0, 1.0, None)
    }

    /// The intervals `locate` gives for every node.
    fn located(m: &NodeFriction, u: &[f64]) -> Vec<usize> {
        u.iter()
            .enumerate()
            .map(|(i, x)| m.map.locate(m.origin[i] + x).index)
            .collect()
    }

    #[test]
    fn inward_edges_agree_with_locate_at_every_rounding() {
        let mut m = patches();
        // displacements within a few ulps of every edge, on both sides
        for i in 0..m.origin.len() {
            for j in 1..m.intervals.len() {
                let edge = m.intervals[j].lo - m.origin[i];
                let mut x = edge;
                for _ in 0..8 {
                    x = x.next_down();
                }
                for _ in 0..16 {
                    m.follow(i, x);
                    assert_eq!(m.index[i], m.map.locate(m.origin[i] + x).index, "{i} {x:e}");
                    if x >= m.u_lo[i] && x < m.u_hi[i] {
                        let at = m.origin[i] + x;
                        let l = m.intervals[m.index[i]];
                        assert!(l.lo <= at && at < l.hi, "{i} {x:e}");
                    }
                    x = x.next_up();
                }
            }
        }
    }

    #[test]
    fn a_block_is_examined_before_any_node_can_leave_its_piece() {
        // the nodes move by up to the bound each step, 0.1 m one way and back, across the edges at
        // 0.1 and 0.3 m; the lazy check must agree with locate after every step
        let mut m = patches();
        let n = 1024;
        let mut u = vec![0.0; n];
        let speed = 2e-4;
        let mut examined = 0;
        for step in 0..4000 {
            let dir = if (step / 500) % 2 == 0 { 1.0 } else { -1.0 };
            for (i, x) in u.iter_mut().enumerate() {
                // nodes move at different speeds, none faster than `speed`
                *x += dir * speed * (0.5 + 0.5 * ((i * 7 + step) % 11) as f64 / 10.0);
            }
            examined += m.follow_step(&u, speed);
            assert_eq!(m.index, located(&m, &u), "step {step}");
            assert!(m.needs_reach(), "step {step}: the check turned eager");
        }
        // and it is lazy: far fewer block examinations than blocks times steps
        let blocks = whole_blocks(n).1;
        assert!(
            examined < blocks * 4000 / 4,
            "{examined} of {}",
            blocks * 4000
        );
        assert!(examined > 0);
    }

    #[test]
    fn a_fine_map_turns_the_check_eager_and_back_and_both_agree_with_locate() {
        // a ramp held constant every millimetre under nodes 1 mm apart: each node is within half
        // a millimetre of an edge, so blocks fall due every few steps
        let pipe = Pipe {
            features: vec![Feature::Ramp {
                from: -0.5,
                to: 1.5,
                eps: Some([0.1, 0.9]),
                n_f: None,
            }],
            ..Default::default()
        };
        let origin = (0..1024).map(|i| i as f64 * 1e-3).collect();
        let mut m = NodeFriction::new(pipe.compile(0.1, 0.5), origin, 2.0, 1.0, None);
        let mut u = vec![0.0; 1024];
        let (mut lazy, mut eager, mut switches) = (0, 0, 0);
        let speed = 2e-4;
        for step in 0..9000 {
            let dir = if (step / 500) % 2 == 0 { 1.0 } else { -1.0 };
            for (i, x) in u.iter_mut().enumerate() {
                *x += dir * speed * (0.5 + 0.5 * ((i * 7 + step) % 11) as f64 / 10.0);
            }
            let was = matches!(m.check, Check::Eager { .. });
            m.follow_step(&u, speed);
            assert_eq!(m.index, located(&m, &u), "step {step}");
            match m.check {
                Check::Eager { .. } => eager += 1,
                Check::Lazy { .. } => lazy += 1,
            }
            switches += usize::from(was != matches!(m.check, Check::Eager { .. }));
        }
        // lazy for a window, eager for EAGER_STEPS, lazy again, eager again, lazy again
        assert!(eager >= EAGER_STEPS as usize, "{eager} eager steps");
        assert!(lazy >= 2 * WINDOW as usize, "{lazy} lazy steps");
        assert!(switches >= 4, "{switches} switches");
    }

    #[test]
    fn a_step_longer_than_reported_is_caught_only_by_a_placement() {
        // the check relies on the reported bound: a node that jumps further than it is missed
        // (which is why a state set from outside places every node from scratch)
        let mut m = patches();
        let mut u = vec![0.0; 1024];
        m.follow_step(&u, 0.0);
        u[20] += 0.15; // node 20 at 0.02 m jumps over the edge at 0.1 m to 0.17 m
        m.follow_step(&u, 1e-6);
        assert_ne!(m.index, located(&m, &u));
        m.place_all(&u);
        assert_eq!(m.index, located(&m, &u));
    }
}
