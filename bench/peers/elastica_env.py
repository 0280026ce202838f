"""The paper's task as a Gymnasium environment on the PyElastica crawler of elastica_crawler.py:
what a researcher would write to train a policy on PyElastica, for bench/peers/env_bench.py.

The same crawler (the paper's periodic body of one wavelength, Coulomb + viscous friction on a
plane, the small-strain tension; docs/peers.md), the same spaces as softcrawler's
`SoftCrawlerEnv(action="wave")` with its default fields, the same reward and ends:

- action `[f0 (N), omega (rad/s), k (rad/m)]`, clipped to the paper's limits; k is held at the
  body's one wavelength (the rod is built for it), as softcrawler snaps it;
- observation: per segment (8 equal runs of elements) the mean strain, the share of nodes at rest
  (|v| below the peers' stuck speed, common.STUCK_SPEED_SHARE) and the mean tension over
  A_c sigma_max; then the mean speed over the step, the distance travelled by the centre of mass
  over D and the muscle's net work over J0;
- reward per step: progress over D, minus the step over t_end, minus 10 x the time above
  sigma_max over t_end; +1 and terminated on reaching D, -1 and terminated on spending J0,
  truncated at t_end.

One environment step is one communication step `step` (s, softcrawler's H at the same cells by
default), taken as whole PyElastica steps of dt = dt_share dx / c (rounded so they fill it). The
muscle's work is summed over PyElastica's steps with the tension at each step's middle (its
Position Verlet takes the forces there), as common.Metrics does.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from types import SimpleNamespace

import gymnasium as gym
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import AREA, C_D, C_V, CASES, EA, STUCK_SPEED_SHARE, WAVE_SPEED  # noqa: E402
from elastica_crawler import build, parser  # noqa: E402


class ElasticaCrawlerEnv(gym.Env):
    """The paper's task (travel `distance` m on `energy` J under `sigma_max` Pa within `t_end`
    s) on PyElastica's crawler of `cells` elements; one step is `step` s."""

    metadata = {"render_modes": []}

    def __init__(self, cells: int = 128, step: float = 1e-3, dt_share: float = 0.5,
                 segments: int = 8, distance: float = 1.0, energy: float = 20.0,
                 sigma_max: float = 100e3, t_end: float = 10.0, stress_weight: float = 10.0,
                 f0_max: float = 5.0, omega: tuple[float, float] = (10.0, 300.0)) -> None:
        if cells < 4 or cells % segments:
            raise ValueError(f"cells = {cells}: allowed a multiple of segments = {segments}, >= 4")
        self.case = CASES["paper"]
        self.cells, self.segments = cells, segments
        self.dx = self.case.length / cells
        self.substeps = max(1, math.ceil(step / (dt_share * self.dx / WAVE_SPEED)))
        self.dt = step / self.substeps
        self.step_length = step
        self.distance, self.energy_budget = distance, energy
        self.sigma_max, self.t_end, self.stress_weight = sigma_max, t_end, stress_weight
        self.options = parser().parse_args(["--case", "paper", "--dt-share", str(dt_share)])
        self.stuck_speed = STUCK_SPEED_SHARE * self.case.eps * C_D / C_V  # as common.Metrics
        self.x_el = (np.arange(cells) + 0.5) * self.dx
        k = self.case.k
        self.action_space = gym.spaces.Box(np.array([0.0, omega[0], k]),
                                           np.array([f0_max, omega[1], k]), dtype=np.float64)
        n = 3 * segments + 3
        low = np.full(n, -np.inf)
        low[segments:2 * segments] = 0.0
        high = np.full(n, np.inf)
        high[segments:2 * segments] = 1.0
        self.observation_space = gym.spaces.Box(low, high, dtype=np.float64)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.drive = SimpleNamespace(f0=0.0, k=self.case.k, omega=0.0)
        self.sim, self.rod, self.stepper = build(self.case, self.cells, self.dt, self.options,
                                                 drive=self.drive)
        self.x0 = self.rod.position_collection[0, :self.cells].copy()
        self.t = np.float64(0.0)
        self.work = 0.0
        self.travelled = 0.0
        self.over = 0.0
        self.speed = 0.0
        return self._observe(), {}

    def _tension(self, x: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Each element's tension (the small-strain model's), N, and strain."""
        strain = np.diff(x) / self.dx - 1.0
        d = self.drive
        return EA * strain + d.f0 * np.sin(d.k * self.x_el - d.omega * t), strain

    def _observe(self) -> np.ndarray:
        x = self.rod.position_collection[0]
        v = self.rod.velocity_collection[0, :self.cells]
        tension, strain = self._tension(x, float(self.t))
        s = self.segments
        return np.concatenate([
            strain.reshape(s, -1).mean(axis=1),
            (np.abs(v) < self.stuck_speed).reshape(s, -1).mean(axis=1),
            tension.reshape(s, -1).mean(axis=1) / (AREA * self.sigma_max),
            [self.speed, self.travelled / self.distance, self.work / self.energy_budget]])

    def step(self, action):
        a = np.clip(np.asarray(action, dtype=np.float64), self.action_space.low,
                    self.action_space.high)
        self.drive.f0, self.drive.omega = float(a[0]), float(a[1])
        before = self.travelled
        over = 0.0
        for _ in range(self.substeps):
            x_before = self.rod.position_collection[0].copy()
            t_mid = float(self.t) + 0.5 * self.dt
            self.t = self.stepper.step(self.sim, self.t, self.dt)
            x_after = self.rod.position_collection[0]
            d = self.drive
            active = d.f0 * np.sin(d.k * self.x_el - d.omega * t_mid)
            # the nodes' muscle forces (T_e on node e, -T_e on node e + 1) times their displacements
            self.work -= float(np.sum(active * (np.diff(x_after) - np.diff(x_before))))
            tension, _ = self._tension(x_after, float(self.t))
            if tension.max() > AREA * self.sigma_max:
                over += self.dt
        self.travelled = float(np.mean(self.rod.position_collection[0, :self.cells] - self.x0))
        self.speed = (self.travelled - before) / self.step_length
        reward = (self.travelled - before) / self.distance - self.step_length / self.t_end
        reward -= self.stress_weight * over / self.t_end
        terminated = False
        if self.travelled >= self.distance:
            reward, terminated = reward + 1.0, True
        elif self.work >= self.energy_budget:
            reward, terminated = reward - 1.0, True
        truncated = not terminated and float(self.t) >= self.t_end - 0.5 * self.dt
        info = {"time": float(self.t), "distance": self.travelled, "energy_used": self.work}
        return self._observe(), reward, terminated, truncated, info


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=128)
    ap.add_argument("--seconds", type=float, default=1.0, help="simulated time to run, s")
    a = ap.parse_args()
    env = ElasticaCrawlerEnv(cells=a.cells)
    env.reset(seed=0)
    c = env.case
    action = np.array([c.f0, c.omega, c.k])
    for _ in range(int(round(a.seconds / env.step_length))):
        obs, *_ = env.step(action)
    print(dict(zip(["speed", "progress", "energy"], obs[-3:])))
    return 0


if __name__ == "__main__":
    sys.exit(main())
