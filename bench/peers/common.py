"""What the peers' crawlers share: the paper's body, the three cases, and the metrics.

Every peer script (mujoco_crawler.py, elastica_crawler.py) builds the same 1-D axial crawler of
docs/physics.md §1 on a periodic body of one wavelength (L = 2 pi / k = 1 m), starts it at rest
with the drive switched on at t = 0, and hands its trajectory, step by step, to `Metrics`, which
measures every tool the same way:

- V: the mean displacement's change over the averaging window divided by its length (the mean
  material velocity, eq. 1.5, exactly over the window);
- P: the work the muscle forces do on the nodes over the window, divided by its length. Over whole
  periods of a steady state this equals the mean of the actuator power (1.6) (the two differ by
  the change of a bounded quantity), and the window is a whole number of forcing periods;
- sigma: the largest tension over the faces and over the window's samples, divided by A_c;
- the stuck fraction: the share of node-time at rest. The plant's is exact (a stuck node has
  v = 0 exactly); the peers' nodes never rest exactly, so for them "at rest" means
  |v| < STUCK_SPEED_SHARE * eps c_d / c_v (the free drift speed's scale), a generous threshold
  stated in docs/peers.md.

SI units throughout: rho (kg/m), A_c E (N), c_v (N s/m^2), c_d (N/m), f0 (N), k (rad/m).
"""

import math
import os
from dataclasses import dataclass

import numpy as np

# The paper's body and pipe (docs/physics.md §1.5)
RHO = 0.1  # kg/m, linear density
AREA = 1e-4  # m^2, A_c = A_m
EA = 14.0  # N, A_c E
C_V = 1.0  # N s/m^2
C_D = 1.0  # N/m
N_F = 0.5
WAVE_SPEED = math.sqrt(EA / RHO)  # m/s

# A node is "at rest" for the peers' stuck fraction when |v| is below this share of eps c_d / c_v
STUCK_SPEED_SHARE = 1e-3

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@dataclass(frozen=True)
class Case:
    """One operating point. `load` is a uniform forward body force (N/m) that friction must hold
    (the static hold); in the model of docs/physics.md it is the same equation as n_F + load /
    (eps c_d) without the load, which is how the plant is given it."""

    name: str
    eps: float
    f0: float  # N
    k: float  # rad/m
    alpha: float
    load: float = 0.0  # N/m
    t_end: float = 10.0  # s
    settle: float = 5.0  # s: transient skipped before averaging

    @property
    def omega(self):
        return self.alpha * self.k * WAVE_SPEED

    @property
    def length(self):
        return 2 * math.pi / self.k

    @property
    def mu_forward(self):
        """Dry friction resisting forward sliding, per unit normal load: eps (1 - n_F)."""
        return self.eps * (1 - N_F)

    @property
    def mu_backward(self):
        """Dry friction resisting backward sliding, per unit normal load: eps (1 + n_F)."""
        return self.eps * (1 + N_F)

    def window(self):
        """Averaging window (t_a, t_b): a whole number of forcing periods ending at t_end (the
        whole [settle, t_end] without a drive)."""
        if self.f0 == 0 or self.omega == 0:
            return self.settle, self.t_end
        period = 2 * math.pi / self.omega
        n = math.floor((self.t_end - self.settle) / period + 1e-9)
        return self.t_end - n * period, self.t_end


# The three cases of issue 37 (static hold: a steady forward load of half the static friction's
# forward capacity eps c_d (1 - n_F), no drive; exact answer: the body never moves).
CASES = {
    "static": Case("static", eps=0.1, f0=0.0, k=2 * math.pi, alpha=1.0, load=0.5 * 0.1 * C_D * (1 - N_F),
                   settle=9.0),
    "paper": Case("paper", eps=0.1, f0=0.5, k=2 * math.pi, alpha=1.0),
    "stickslip": Case("stickslip", eps=1.0, f0=0.2, k=2 * math.pi, alpha=0.5),
}


def quick(case, t_end=1.0):
    """A short version of a case for the smoke test: the same point, `t_end` simulated, averaged
    over its second half (the static hold over its last tenth)."""
    settle = 0.9 * t_end if case.f0 == 0 else 0.5 * t_end
    return Case(case.name, case.eps, case.f0, case.k, case.alpha, case.load, t_end, settle)


def active_tension(case, x_faces, t):
    """A_m f at the faces x_faces (m) and times t (s): shape (len(t), len(x_faces)), N."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    return case.f0 * np.sin(case.k * x_faces[None, :] - case.omega * t[:, None])


class Metrics:
    """Measures V, P, sigma and the stuck fraction from a trajectory fed in chunks of samples.

    feed(t, u, v) takes the times (m,) of consecutive samples and the nodes' displacements and
    velocities (m, N) at those times; the samples must be the simulator's own steps (the muscle's
    work is summed over them, with the force the tool applied during each step: evaluated
    `force_at` steps after the step's start). The periodic body's nodes sit at x_i = i dx, the faces at (i + 1/2) dx.
    """

    def __init__(self, case, n_nodes, dt, force_at=0.0):
        self.case = case
        self.force_at = force_at  # when in a step the tool evaluates the muscle force, as a share of dt
        self.n = n_nodes
        self.dx = case.length / n_nodes
        self.x_faces = (np.arange(n_nodes) + 0.5) * self.dx
        self.dt = dt
        self.t_a, self.t_b = case.window()
        self.stuck_speed = STUCK_SPEED_SHARE * case.eps * C_D / C_V
        self.mean_u_a = None
        self.mean_u_b = None
        self.work = 0.0
        self.max_tension = -math.inf
        self.stuck = 0
        self.samples = 0
        self.prev = None  # (t, u) of the last sample fed
        self.finite = True
        self.u_end = None

    def _in(self, t):
        tol = 0.5 * self.dt
        return (t >= self.t_a - tol) & (t <= self.t_b + tol)

    def feed(self, t, u, v):
        t = np.asarray(t, dtype=float)
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(v))):
            self.finite = False
            return
        tol = 0.5 * self.dt
        for j in np.nonzero(np.abs(t - self.t_a) <= tol)[0][:1]:
            self.mean_u_a, self.time_a = float(np.mean(u[j])), float(t[j])
        for j in np.nonzero(np.abs(t - self.t_b) <= tol)[0][:1]:
            self.mean_u_b, self.time_b = float(np.mean(u[j])), float(t[j])
        inside = self._in(t)
        if self.case.f0 != 0 and np.any(inside):
            # muscle force on each node at each sample: T_act(i + 1/2) - T_act(i - 1/2)
            ti, ui, vi = t[inside], u[inside], v[inside]
            ta = active_tension(self.case, self.x_faces, ti)
            tension = EA * (np.roll(ui, -1, axis=1) - ui) / self.dx + ta
            self.max_tension = max(self.max_tension, float(tension.max()))
            self.stuck += int(np.count_nonzero(np.abs(vi) < self.stuck_speed))
            self.samples += vi.size
        # work of the muscle forces over each step (t_n, t_n+1] inside the window, force at t_n
        if self.case.f0 != 0:
            ts = t if self.prev is None else np.concatenate([[self.prev[0]], t])
            us = u if self.prev is None else np.concatenate([self.prev[1][None, :], u])
            if len(ts) > 1:
                start = ts[:-1]
                sel = (start >= self.t_a - 0.5 * self.dt) & (start < self.t_b - 0.5 * self.dt)
                if np.any(sel):
                    ta = active_tension(self.case, self.x_faces, start[sel] + self.force_at * self.dt)
                    force = ta - np.roll(ta, 1, axis=1)
                    du = (us[1:] - us[:-1])[sel]
                    self.work += float(np.sum(force * du))
        self.prev = (float(t[-1]), np.array(u[-1]))
        self.u_end = np.array(u[-1])

    def result(self):
        """A dict of the metrics (None where not measured); `finite` false if the run blew up."""
        if not self.finite or self.mean_u_a is None or self.mean_u_b is None:
            return {"finite": False}
        span = self.time_b - self.time_a
        out = {
            "finite": True,
            "velocity": (self.mean_u_b - self.mean_u_a) / span,
            "displacement_end": float(np.mean(self.u_end)),
            "max_abs_displacement_end": float(np.max(np.abs(self.u_end))),
        }
        if self.case.f0 != 0:
            out["power"] = self.work / span
            out["max_stress"] = self.max_tension / AREA
            out["stuck_fraction"] = self.stuck / max(self.samples, 1)
        return out
