"""The crawler of docs/physics.md §1 in PyElastica: one JSON line of metrics per run.

Usage: .venv/bin/python bench/peers/elastica_crawler.py --case paper --cells 128 [--dt-share 0.5]
           [--slip-tol 1e-6] [--static on|off] [--finite-strain] [--quick]

A straight Cosserat rod (PyElastica's CosseratRod.straight_rod) of one wavelength along x, with
the paper's cross-section (A_c = 1 cm^2, radius 5.64 mm), density 1000 kg/m^3 (rho = 0.1 kg/m)
and E = 140 kPa (A_c E = 14 N), lies on a plane under gravity g = c_d / rho, so the plane's normal
load is c_d per unit length. As PyElastica's examples do (the continuum snake):

- friction: RodPlaneContactWithAnisotropicFriction with kinetic (and, unless --static off,
  static) coefficients forward eps (1 - n_F), backward eps (1 + n_F), and slip_velocity_tol;
- the viscous film: AnalyticalLinearDamper with uniform_damping_constant c_v / rho (it damps
  each node's velocity by exp(-c_v dt / rho) per step: the drag c_v u_t per unit length);
- the muscle: a custom forcing (a NoForces subclass) adding the active tension A_m f at each
  element's centre, i.e. the force T_act(e) - T_act(e - 1) on each node;
- PositionVerlet time stepping;
- axial motion only: a GeneralConstraint holds every node's y and z and every element's
  directors (the pipe's role; without it the soft rod buckles off its line when compressed).

Two additions make it the paper's model rather than a different one (docs/peers.md):
- periodic ends: the rod's first and last nodes are one material point one wavelength apart; a
  constraint (a ConstraintBase subclass) merges them after every half step (position with the
  offset L, velocity by the mean, which with two half masses is the whole node's momentum);
- small strain: PyElastica's rod is geometrically exact, its axial tension is A_c E (e - 1) / e
  at stretch e, the paper's is A_c E (e - 1); the strain reaches 26 % at the paper's point, so the
  muscle forcing also adds the difference A_c E (e - 1)^2 / e (--finite-strain leaves it out).
The plane contact's surface tolerance is raised from 0.1 mm to the rod's radius, since a stretched
element of the volume-conserving rod thins by up to 0.6 mm and would otherwise lose contact.
"""

import argparse
import json
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import AREA, C_D, C_V, CASES, EA, RHO, WAVE_SPEED, Metrics, quick  # noqa: E402

import elastica as ea  # noqa: E402
from elastica.version import VERSION as ELASTICA_VERSION  # noqa: E402


class Crawler(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping, ea.Contact):
    pass


class PeriodicEnds(ea.ConstraintBase):
    """Node N is node 0 shifted by one wavelength along x: after each half step both take the
    mean of their positions (offset by L) and of their velocities."""

    def __init__(self, length, **kwargs):
        super().__init__(**kwargs)
        self.offset = np.array([length, 0.0, 0.0])

    def constrain_values(self, system, time):
        p = system.position_collection
        mid = 0.5 * (p[:, 0] + p[:, -1] - self.offset)
        p[:, 0] = mid
        p[:, -1] = mid + self.offset

    def constrain_rates(self, system, time):
        v = system.velocity_collection
        mid = 0.5 * (v[:, 0] + v[:, -1])
        v[:, 0] = mid
        v[:, -1] = mid


class AxialTension(ea.NoForces):
    """The muscle's active tension A_m f = f0 sin(k x - omega t) at each element's centre, plus
    (unless finite_strain) the small-strain correction A_c E (e - 1)^2 / e, as nodal forces along x."""

    def __init__(self, case, x_elements, finite_strain):
        super().__init__()
        self.case = case
        self.x = x_elements
        self.finite_strain = finite_strain

    def apply_forces(self, system, time=0.0):
        c = self.case
        tension = c.f0 * np.sin(c.k * self.x - c.omega * time) if c.f0 != 0 else np.zeros_like(self.x)
        if not self.finite_strain:
            e = system.dilatation
            tension = tension + EA * (e - 1.0) ** 2 / e
        f = system.external_forces
        f[0, :-1] += tension
        f[0, 1:] -= tension


class PlaneContact(ea.RodPlaneContactWithAnisotropicFriction):
    """PyElastica's rod-plane contact with anisotropic friction, with a surface tolerance that
    keeps a thinned (stretched) element in contact."""

    def __init__(self, surface_tol, **kwargs):
        super().__init__(**kwargs)
        self.surface_tol = np.float64(surface_tol)


def build(case, cells, dt, a, drive=None):
    """The crawler of `case` on `cells` elements, stepped by `dt` s, with the options `a` (this
    script's flags): (simulator, rod, stepper). `drive` (anything with f0, k and omega, read at
    every step; default: the case) is the muscle's wave."""
    length = case.length
    dx = length / cells
    radius = math.sqrt(AREA / math.pi)
    sim = Crawler()
    rod = ea.CosseratRod.straight_rod(
        cells, np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), length, radius,
        RHO / AREA, youngs_modulus=EA / AREA)
    sim.append(rod)
    sim.constrain(rod).using(PeriodicEnds, length=length)
    # axial motion only, as in a pipe: no lateral or vertical motion, no rotation (unconstrained, the
    # soft rod buckles off its line under the wave's compression)
    sim.constrain(rod).using(
        ea.GeneralConstraint, constrained_position_idx=tuple(range(cells + 1)),
        constrained_director_idx=tuple(range(cells)),
        translational_constraint_selector=np.array([False, True, True]),
        rotational_constraint_selector=np.array([True, True, True]))
    g = C_D / RHO
    sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=np.array([case.load / RHO, 0.0, -g]))
    x_el = (np.arange(cells) + 0.5) * dx
    sim.add_forcing_to(rod).using(AxialTension, case=drive or case, x_elements=x_el,
                                  finite_strain=a.finite_strain)
    plane = ea.Plane(plane_origin=np.array([0.0, 0.0, -radius]), plane_normal=np.array([0.0, 0.0, 1.0]))
    sim.append(plane)
    kinetic = np.array([case.mu_forward, case.mu_backward, case.mu_backward])
    static = kinetic.copy() if a.static == "on" else np.zeros(3)
    sim.detect_contact_between(rod, plane).using(
        PlaneContact, surface_tol=radius, k=a.contact_k, nu=a.contact_nu, slip_velocity_tol=a.slip_tol,
        static_mu_array=static, kinetic_mu_array=kinetic)
    sim.dampen(rod).using(ea.AnalyticalLinearDamper, uniform_damping_constant=C_V / RHO, time_step=dt)
    sim.finalize()
    return sim, rod, ea.PositionVerlet()


def run(case, cells, dt_share, a):
    dt = dt_share * (case.length / cells) / WAVE_SPEED
    sim, rod, stepper = build(case, cells, dt, a)
    x0 = rod.position_collection[0, :cells].copy()
    metrics = Metrics(case, cells, dt, force_at=0.5)  # PositionVerlet's forces are taken mid-step
    nsteps = int(round(case.t_end / dt))
    chunk = 1000
    ts = np.empty(chunk)
    us = np.empty((chunk, cells))
    vs = np.empty((chunk, cells))
    metrics.feed(np.zeros(1), np.zeros((1, cells)), np.zeros((1, cells)))
    t = np.float64(0.0)
    elapsed = 0.0
    j = 0
    start = None
    for n in range(nsteps):
        t = stepper.step(sim, t, dt)
        if start is None:  # the first step compiles numba's kernels (on a fresh install): not timed
            start = time.perf_counter()
        ts[j] = (n + 1) * dt
        us[j] = rod.position_collection[0, :cells] - x0
        vs[j] = rod.velocity_collection[0, :cells]
        j += 1
        if j == chunk or n == nsteps - 1:
            elapsed += time.perf_counter() - start
            metrics.feed(ts[:j], us[:j], vs[:j])
            if not metrics.finite:
                break
            j = 0
            start = time.perf_counter()
    return metrics.result(), elapsed, dt


def parser():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=sorted(CASES), required=True)
    ap.add_argument("--cells", type=int, default=128, help="elements on the one-wavelength rod")
    ap.add_argument("--dt-share", type=float, default=0.5, help="time step as a share of dx / c")
    ap.add_argument("--slip-tol", type=float, default=1e-6, help="slip_velocity_tol, m/s")
    ap.add_argument("--static", choices=["on", "off"], default="on",
                    help="static friction coefficients equal to the kinetic ones (on) or zero (off)")
    ap.add_argument("--contact-k", type=float, default=1.0, help="plane contact stiffness (penetration spring)")
    ap.add_argument("--contact-nu", type=float, default=1e-6, help="plane contact damping")
    ap.add_argument("--finite-strain", action="store_true",
                    help="leave PyElastica's geometrically exact tension as it is (not the paper's model)")
    ap.add_argument("--quick", action="store_true", help="1 s simulated instead of 10 s (smoke test)")
    return ap


def main():
    a = parser().parse_args()
    if a.cells < 4:
        sys.exit(f"--cells {a.cells}: at least 4 elements needed")
    if not 0 < a.dt_share <= 2:
        sys.exit(f"--dt-share {a.dt_share}: must be in (0, 2]")
    case = CASES[a.case]
    if a.quick:
        case = quick(case)
    metrics, wall, dt = run(case, a.cells, a.dt_share, a)
    out = {"tool": "pyelastica", "version": ELASTICA_VERSION, "case": case.name, "cells": a.cells, "dt": dt,
           "config": {k: v for k, v in vars(a).items() if k not in ("case", "cells", "quick")},
           "wall_time": wall, **metrics}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
