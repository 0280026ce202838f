"""The crawler of docs/physics.md §1 in MuJoCo: one JSON line of metrics per run.

Usage: .venv/bin/python bench/peers/mujoco_crawler.py --case paper --cells 128 [--courant 1]
           [--friction joint|contact] [--noslip 0] [--cone pyramidal|elliptic] [--impratio 1]
           [--friction-timeconst S] [--friction-solimp D0,D1,W] [--quick]

The body is a chain of N point masses (rho dx each), each on its own slide joint along x, so a
joint's position is the node's displacement u_i. Neighbours are joined by fixed tendons
q_{i+1} - q_i (the last one q_0 - q_{N-1}: a periodic body of one wavelength) with stiffness
A_c E / dx and rest length 0, so the tendon tension is exactly A_c E (u_{i+1} - u_i) / dx. The
muscle is a motor on each tendon (gear -1, so its control is the active tension A_m f at the
face), driven open loop through mujoco.rollout. The viscous film is joint damping c_v dx
(implicit in MuJoCo's Euler integrator). Dry friction, two ways:

- joint (default): MuJoCo's dry joint friction, frictionloss = eps c_d dx, a soft constraint
  with a symmetric band +-eps c_d dx per node;
- contact: each node is also free to move vertically and carries a small sphere resting on a
  floor plane under gravity c_d / rho, with Coulomb friction coefficient eps (cone, impratio and
  noslip as given).

MuJoCo's friction is symmetric; the paper's asymmetry is the constant forward force
eps c_d n_F per unit length (F = c_v v + eps c_d s - eps c_d n_F, docs/physics.md (1.3)), given
as a gravity component along x, g_x = (eps c_d n_F + load) / rho. The static hold's load goes
in the same component. See docs/peers.md.
"""

import argparse
import json
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import C_D, C_V, CASES, EA, N_F, RHO, WAVE_SPEED, Metrics, active_tension, quick  # noqa: E402

import mujoco  # noqa: E402
from mujoco import rollout  # noqa: E402


def model_xml(case, cells, dt, a):
    dx = case.length / cells
    gx = (case.eps * C_D * N_F + case.load) / RHO
    contact = a.friction == "contact"
    radius = 0.4 * dx
    gz = -C_D / RHO if contact else 0.0
    fric_attr = ""
    if not contact:
        fric_attr = f'frictionloss="{case.eps * C_D * dx!r}"'
        if a.friction_timeconst is not None:
            fric_attr += f' solreffriction="{a.friction_timeconst!r} 1"'
        if a.friction_solimp is not None:
            fric_attr += f' solimpfriction="{a.friction_solimp.replace(",", " ")}"'
    bodies = []
    for i in range(cells):
        z = radius if contact else 0.0
        joints = f'<joint name="j{i}" type="slide" axis="1 0 0" damping="{C_V * dx!r}" {fric_attr}/>'
        if contact:
            joints += f'<joint name="z{i}" type="slide" axis="0 0 1"/>'
            geom = (f'<geom type="sphere" size="{radius!r}" contype="1" conaffinity="0" condim="3" '
                    f'friction="{case.eps!r} 0 0" mass="0"/>')
        else:
            geom = ""
        bodies.append(f'<body name="n{i}" pos="{i * dx!r} 0 {z!r}">{joints}'
                      f'<inertial pos="0 0 0" mass="{RHO * dx!r}" diaginertia="1e-9 1e-9 1e-9"/>{geom}</body>')
    tendons, motors = [], []
    for i in range(cells):
        j = (i + 1) % cells
        tendons.append(f'<fixed name="t{i}" stiffness="{EA / dx!r}" springlength="0">'
                       f'<joint joint="j{j}" coef="1"/><joint joint="j{i}" coef="-1"/></fixed>')
        motors.append(f'<motor tendon="t{i}" gear="-1"/>')
    # a contact's friction is the larger of its two geoms' (MuJoCo's mixing rule): the floor gets eps too
    floor = (f'<geom name="floor" type="plane" size="0 0 1" contype="0" conaffinity="1" '
             f'friction="{case.eps!r} 0 0"/>') if contact else ""
    option = (f'<option timestep="{dt!r}" integrator="Euler" solver="{a.solver}" tolerance="{a.tolerance!r}" '
              f'iterations="{a.iterations}" gravity="{gx!r} 0 {gz!r}" cone="{a.cone}" impratio="{a.impratio!r}" '
              f'noslip_iterations="{a.noslip}"/>')
    return (f'<mujoco model="crawler">{option}<worldbody>{floor}{"".join(bodies)}</worldbody>'
            f'<tendon>{"".join(tendons)}</tendon><actuator>{"".join(motors)}</actuator></mujoco>')


def run(case, cells, courant, a, chunk=2000):
    """Simulates `case` and returns (metrics dict, wall time of the stepping in s)."""
    dx = case.length / cells
    dt = courant * dx / WAVE_SPEED
    model = mujoco.MjModel.from_xml_string(model_xml(case, cells, dt, a))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    nstate = mujoco.mj_stateSize(model, spec)
    state0 = np.empty(nstate)
    mujoco.mj_getState(model, data, state0, spec)
    nq = model.nq
    # the slide joints along x are qpos[0], qpos[2], ... with the contact model, qpos[0..N) without
    ix = np.array([model.jnt_qposadr[model.joint(f"j{i}").id] for i in range(cells)])
    vx = np.array([model.jnt_dofadr[model.joint(f"j{i}").id] for i in range(cells)])
    x_faces = (np.arange(cells) + 0.5) * dx
    metrics = Metrics(case, cells, dt)
    nsteps = int(round(case.t_end / dt))
    done = 0
    elapsed = 0.0
    t0 = np.zeros(1)
    metrics.feed(t0, np.zeros((1, cells)), np.zeros((1, cells)))
    while done < nsteps:
        m = min(chunk, nsteps - done)
        times = (done + np.arange(m)) * dt  # each step's start time: controls held over the step
        control = active_tension(case, x_faces, times)[None, :, :]
        start = time.perf_counter()
        state, _ = rollout.rollout(model, data, state0[None, :], control, nstep=m)
        elapsed += time.perf_counter() - start
        st = state[0]
        state0 = st[-1].copy()
        # state = [time, qpos, qvel, ...]
        t = st[:, 0]
        u = st[:, 1 + ix]
        v = st[:, 1 + nq + vx]
        metrics.feed(t, u, v)
        done += m
        if not metrics.finite:
            break
    return metrics.result(), elapsed, dt


def parser():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=sorted(CASES), required=True)
    ap.add_argument("--cells", type=int, default=128, help="nodes on the one-wavelength body")
    ap.add_argument("--courant", type=float, default=1.0, help="c dt / dx")
    ap.add_argument("--friction", choices=["joint", "contact"], default="joint")
    ap.add_argument("--solver", choices=["Newton", "CG", "PGS"], default="Newton")
    ap.add_argument("--tolerance", type=float, default=1e-10)
    ap.add_argument("--iterations", type=int, default=100)
    ap.add_argument("--noslip", type=int, default=0, help="noslip_iterations")
    ap.add_argument("--cone", choices=["pyramidal", "elliptic"], default="pyramidal")
    ap.add_argument("--impratio", type=float, default=1.0)
    ap.add_argument("--friction-timeconst", type=float, default=None,
                    help="solreffriction time constant of the joints' dry friction, s (MuJoCo's default 0.02)")
    ap.add_argument("--friction-solimp", default=None, help="solimpfriction dmin,dmax,width (default 0.9,0.95,0.001)")
    ap.add_argument("--quick", action="store_true", help="1 s simulated instead of 10 s (smoke test)")
    return ap


def main():
    a = parser().parse_args()
    if a.cells < 4:
        sys.exit(f"--cells {a.cells}: at least 4 nodes needed")
    if not 0 < a.courant <= 2:
        sys.exit(f"--courant {a.courant}: must be in (0, 2]")
    case = CASES[a.case]
    if a.quick:
        case = quick(case)
    metrics, wall, dt = run(case, a.cells, a.courant, a)
    out = {"tool": "mujoco", "version": mujoco.__version__, "case": case.name, "cells": a.cells, "dt": dt,
           "config": {k: v for k, v in vars(a).items() if k not in ("case", "cells", "quick")},
           "wall_time": wall, **metrics}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
