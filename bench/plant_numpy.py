"""The plant's stepping scheme in NumPy, for side-by-side benchmarks.

Same discretisation as physics/src/solver.rs: tensions on half nodes, leapfrog at Courant number 1
with centred viscous term, exact stick by the closed form s = clamp(b/g, -1, 1), the same per-step
reductions (max tension, max strain, power sums, sums of v, s, stuck, dissipation), stick/slip
switch detection with the reversal test on the switching nodes, and the conservative
fourth-difference grid filter on the sliding nodes (docs/numerics.md). Buffers are preallocated
and updated in place.
"""

import numpy as np


class NumpyPlant:
    def __init__(self, cells, length=1.0, area=1e-4, density=0.1, youngs=140e3, viscous=1.0, dry=1.0,
                 eps=1.0, n_f=0.5, f0=0.2, k=2 * np.pi, alpha=0.5, step=1e-3, courant=1.0, filt=0.1):
        n = cells
        self.n = n
        dx = length / n
        ae = area * youngs
        c = np.sqrt(ae / density)
        dt = courant * dx / c
        self.substeps = max(1, int(round(step / dt)))
        a = density / dt + 0.5 * viscous
        band = eps * dry
        self.dt, self.dx, self.inv_dx, self.ae = dt, dx, 1.0 / dx, ae
        self.beta = (density / dt - 0.5 * viscous) / a
        self.gamma_inv_dx = 1.0 / (a * dx)
        self.push = band * n_f / a
        self.g = band / a
        self.inv_g = 1.0 / self.g
        self.viscous, self.band, self.n_f = viscous, band, n_f
        self.f0, self.omega = f0, alpha * k * c
        xh = (np.arange(n) + 0.5) * dx
        self.S, self.C = np.sin(k * xh), np.cos(k * xh)
        self.field = np.zeros(n)
        self.filt = filt
        self.flux, self.near = np.empty(n), np.empty(n)
        self.u, self.v = np.zeros(n), np.zeros(n)
        self.flags = np.zeros(n)
        self.t_step = 0
        # scratch
        self.strain, self.T, self.dT, self.b = (np.empty(n) for _ in range(4))
        self.tmp, self.vnew, self.s, self.stuck = (np.empty(n) for _ in range(4))

    def step(self):
        t = self.t_step * self.dt
        th = self.omega * t
        a, b = self.f0 * np.cos(th), -self.f0 * np.sin(th)
        u, T, strain, tmp = self.u, self.T, self.strain, self.tmp
        # pass 1: tensions at half nodes (periodic)
        np.subtract(u[1:], u[:-1], out=strain[:-1])
        strain[-1] = u[0] - u[-1]
        strain *= self.inv_dx
        np.multiply(strain, self.ae, out=T)
        np.multiply(self.S, a, out=tmp)
        T += tmp
        np.multiply(self.C, b, out=tmp)
        T += tmp
        T += self.field
        max_t = T.max()
        max_strain = np.abs(strain, out=tmp).max()
        t_sin, t_cos = T @ self.S, T @ self.C
        # pass 2: nodes with exact stick
        dT, bf = self.dT, self.b
        np.subtract(T[1:], T[:-1], out=dT[1:])
        dT[0] = T[0] - T[-1]
        np.multiply(self.v, self.beta, out=bf)
        dT *= self.gamma_inv_dx
        bf += dT
        bf += self.push
        excess = np.abs(bf, out=tmp)
        excess -= self.g
        vnew = np.maximum(excess, 0.0, out=self.vnew)
        np.copysign(vnew, bf, out=vnew)
        s = np.multiply(bf, self.inv_g, out=self.s)
        np.clip(s, -1.0, 1.0, out=s)
        stuck = self.stuck
        stuck[:] = excess <= 0.0
        changes = np.count_nonzero(stuck != self.flags)
        vm = 0.5 * (self.v + vnew)
        dissipation = self.viscous * (vm @ vm) + self.band * ((s - self.n_f) @ vnew)
        sums = (vnew.sum(), self.v.sum(), s.sum(), stuck.sum(), dissipation, max_t, max_strain, t_sin, t_cos)
        if changes:
            # the switching nodes; a stop with the force outside the band is a reversal
            idx = np.nonzero(stuck != self.flags)[0]
            force = dT[idx] + self.push
            _reversal = stuck[idx].astype(bool) & (np.abs(force) > self.g)
        self.flags[:] = stuck
        if self.filt > 0.0:
            # F_{i+1/2} = (v_{i+2} - v_{i-1}) - 3 (v_{i+1} - v_i), zero near stuck nodes (i-2 ..= i+3)
            flux, near = self.flux, self.near
            np.subtract(np.roll(vnew, -2), np.roll(vnew, 1), out=flux)
            flux -= 3.0 * (np.roll(vnew, -1) - vnew)
            np.copyto(near, stuck)
            for shift in (1, 2, -1, -2, -3):
                np.maximum(near, np.roll(stuck, shift), out=near)
            flux *= 1.0 - near
            vnew += (-self.filt / 16.0) * (flux - np.roll(flux, 1))
        self.v[:] = vnew
        u += self.dt * vnew
        self.t_step += 1
        return sums
