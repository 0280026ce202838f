"""The paper's task as a reinforcement-learning environment: softcrawler's against the same task on
PyElastica (bench/peers/elastica_env.py), side by side; Markdown on stdout.

Usage: .venv/bin/python bench/peers/env_bench.py [--cells 128] [--rounds 9] [--seconds 1.0]
                                                 [--check 2.0]

1. The same task: both environments from rest with the paper's wave as a fixed action for
   --check simulated seconds; the speed, the progress (distance / D) and the energy (work / J0)
   they observe at the end (the two crawlers are the same model: they must agree to a few parts
   in a thousand).
2. Environment steps per second at the same step (softcrawler's H at --cells): one environment
   each, and PyElastica's own stepping of the same H without the environment around it; then what a user gets from both cores: softcrawler's vector of 64 crawlers (Rust threads)
   against Gymnasium's AsyncVectorEnv of one PyElastica environment per core (processes, as
   PyElastica has no vector stepping of its own). Windows of --seconds, --rounds rounds taking the
   four in turn (this VM's speed drifts over seconds), medians; every side warmed first (numba's
   compilation and the first steps from rest excluded), on a task none finishes while timed.
Needs the venv of scripts/setup-python.sh with the package installed (`--package`).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from datetime import datetime, timezone

import gymnasium as gym
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from elastica_env import ElasticaCrawlerEnv  # noqa: E402

import softcrawler  # noqa: E402
from softcrawler.env import SoftCrawlerEnv, SoftCrawlerVectorEnv  # noqa: E402

#: D and J0 of the timed runs (none ends while timed); the task's check uses the paper's.
FAR = {"distance": 1e3, "energy": 1e9}


def ours(cells: int, far: bool) -> tuple[softcrawler.Scenario, np.ndarray]:
    s = softcrawler.Scenario(cells=cells, t_end=1e4 if far else None)
    if far:
        s = s.with_values({"task.distance": FAR["distance"], "task.energy": FAR["energy"]})
    w = s.wave
    return s, np.array([w["f0"], w["omega"], w["k"]])


def elastica(cells: int, step: float, far: bool) -> ElasticaCrawlerEnv:
    kw = dict(distance=FAR["distance"], energy=FAR["energy"], t_end=1e4) if far else {}
    return ElasticaCrawlerEnv(cells=cells, step=step, **kw)


def same_task(cells: int, seconds: float) -> list[str]:
    s, action = ours(cells, far=False)
    a = SoftCrawlerEnv(s)
    b = elastica(cells, a.step_length, far=False)
    a.reset(seed=0)
    b.reset(seed=0)
    n = int(round(seconds / a.step_length))
    for _ in range(n):
        oa, *_ = a.step(action)
        ob, *_ = b.step(action)
    rows = [f"The same task: both from rest with the paper's wave, {n} steps of H = "
            f"{a.step_length * 1e3:.4f} ms ({n * a.step_length:.3f} s), {cells} cells "
            f"(PyElastica: {b.substeps} steps of dt = {b.dt:.3e} s per H):", "",
            "| observed | softcrawler | PyElastica | difference |", "| --- | ---: | ---: | ---: |"]
    for name, x, y in zip(("speed (m/s)", "progress (distance / D)", "energy (work / J0)"),
                          oa[-3:], ob[-3:]):
        rows.append(f"| {name} | {x:.5f} | {y:.5f} | {100 * (y - x) / x:+.2f} % |")
    return rows


class Loop:
    """Something stepped with a fixed action: `crawlers` crawler steps per call."""

    def __init__(self, step, crawlers: int, warm: int) -> None:
        self.step, self.crawlers = step, crawlers
        for _ in range(warm):
            step()

    def rate(self, seconds: float) -> float:
        n = 0
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            self.step()
            n += self.crawlers
        return n / (time.perf_counter() - t0)


def loops(cells: int) -> tuple[dict[str, Loop], list]:
    cores = os.cpu_count() or 1
    s, action = ours(cells, far=True)
    one = SoftCrawlerEnv(s)
    one.reset(seed=0)
    vec = SoftCrawlerVectorEnv(64, s)
    vec.reset(seed=0)
    actions = np.tile(action, (64, 1))
    e = elastica(cells, one.step_length, far=True)
    e.reset(seed=0)
    bare = elastica(cells, one.step_length, far=True)
    bare.reset(seed=0)
    bare.drive.f0, bare.drive.omega = float(action[0]), float(action[1])

    def stepping_alone() -> None:
        for _ in range(bare.substeps):
            bare.t = bare.stepper.step(bare.sim, bare.t, bare.dt)

    h = one.step_length
    avec = gym.vector.AsyncVectorEnv([lambda: elastica(cells, h, far=True)] * cores)
    avec.reset(seed=0)
    eactions = np.tile(action, (cores, 1))
    out = {
        "softcrawler, one environment": Loop(lambda: one.step(action), 1, 2000),
        "PyElastica, one environment": Loop(lambda: e.step(action), 1, 200),
        "PyElastica's stepping alone (no observation, reward or energy meter)":
            Loop(stepping_alone, 1, 200),
        "softcrawler, vector of 64 (Rust threads)": Loop(lambda: vec.step(actions), 64, 2000 // 64),
        f"PyElastica, AsyncVectorEnv of {cores} (a process per core)":
            Loop(lambda: avec.step(eactions), cores, 200),
    }
    return out, [avec]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=128)
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--seconds", type=float, default=1.0, help="wall time of each window, s")
    ap.add_argument("--check", type=float, default=2.0, help="simulated time of the task check, s")
    a = ap.parse_args()
    if a.cells < 8 or a.cells % 8:
        ap.error(f"--cells {a.cells}: allowed a multiple of 8 (the segments), at least 8")
    if a.rounds < 1 or not a.seconds > 0 or not a.check > 0:
        ap.error("--rounds >= 1, --seconds > 0 and --check > 0 are needed")
    from elastica.version import VERSION as ELASTICA_VERSION
    print(f"`.venv/bin/python bench/peers/env_bench.py --cells {a.cells} --rounds {a.rounds} "
          f"--seconds {a.seconds} --check {a.check}`; {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores; Python {platform.python_version()}, softcrawler "
          f"{softcrawler.__version__}, PyElastica {ELASTICA_VERSION}, Gymnasium {gym.__version__}; "
          f"{datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}")
    print()
    print("\n".join(same_task(a.cells, a.check)))
    print()
    ls, closers = loops(a.cells)
    try:
        rates: dict[str, list[float]] = {k: [] for k in ls}
        for _ in range(a.rounds):
            for k, loop in ls.items():
                rates[k].append(loop.rate(a.seconds))
    finally:
        for c in closers:
            c.close()
    names = list(ls)
    print(f"Environment steps per second (crawler steps, summed over a vector's crawlers), "
          f"{a.cells} cells, one step = H, medians of {a.rounds} interleaved windows of "
          f"{a.seconds} s:")
    print()
    print("| environment | steps/s | against PyElastica's |")
    print("| --- | ---: | ---: |")
    pairs = {names[0]: names[1], names[3]: names[4]}
    for k in names:
        med = statistics.median(rates[k])
        if k in pairs:
            ratio = statistics.median(x / y for x, y in zip(rates[k], rates[pairs[k]]))
            print(f"| {k} | {med:,.0f} | x {ratio:,.0f} |")
        else:
            print(f"| {k} | {med:,.1f} | |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
