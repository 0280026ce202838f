//! Pass 3 of the step: the grid filter (a fourth difference written as a difference of fluxes,
//! closed where a stuck node is near) and the displacements `u += dt v`; and the filter's face
//! mask, kept up to date at every stick/slip switch.

use super::Solver;
use crate::node_array::NodeArray;
use crate::node_friction::{chunk_left, CHUNK_BLOCKS};
use crate::params::Boundary;
use crate::simd::{F4, LANES};

impl Solver {
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
    pub(super) fn refresh_faces(&mut self, nodes: std::ops::Range<usize>) {
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
    pub(super) fn filter(&mut self) -> f64 {
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
    pub(super) fn displace(&mut self) {
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
