"""The Python package's speed, side by side with the Rust programs (docs/python.md, Performance).

Usage: .venv/bin/python bench/python_bench.py [--rounds R] [--cells N] [--t-end S]

1. `softcrawler.simulate` against `crawler-plant simulate --json --episodes`, whole run of the
   same scenario with the same output (the report with its list of up to 10 000 stick-slip
   episodes, which `simulate` returns by default), interleaved (A B A B ...): each a fresh process
   (the interpreter's start and the import included on the Python side), and `simulate` called in
   a running interpreter; the medians of the pairwise ratios.
2. Environment steps per second at the default communication step (frame_skip = 1: one
   communication step per environment step), one environment and a vector of 64, against the
   Rust loop's own rate per crawler (the plant stepped in Rust, no Python in the loop,
   `Plant.step(n)`); the actions are fixed arrays, so the figures are the package's overhead, not an
   agent's.
Needs the package installed (scripts/setup-python.sh) and target/release/crawler-plant.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import statistics
import subprocess
import sys
import time

import numpy as np

import softcrawler
from softcrawler.env import SoftCrawlerEnv, SoftCrawlerVectorEnv

ROOT = pathlib.Path(__file__).resolve().parents[1]
TARGET = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))


def whole_run(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def simulate_vs_cli(rounds: int, cells: int, t_end: float) -> None:
    plant = str(TARGET / "release" / "crawler-plant")
    cli = [plant, "simulate", "--json", "--episodes", "--cells", str(cells), "--t-end", str(t_end)]
    py = [sys.executable, "-c",
          "import softcrawler as sc; print(sc.simulate(sc.Scenario("
          f"cells={cells}, t_end={t_end})).to_dict()['velocity'])"]
    imp = [sys.executable, "-c", "import softcrawler"]
    whole_run(cli), whole_run(py), whole_run(imp)  # warm-up
    a, b, c, inproc = [], [], [], []
    s = softcrawler.Scenario(cells=cells, t_end=t_end)
    for _ in range(rounds):
        a.append(whole_run(py))
        b.append(whole_run(cli))
        c.append(whole_run(imp))
        t0 = time.perf_counter()
        softcrawler.simulate(s)
        inproc.append(time.perf_counter() - t0)
    ratios = [x / y for x, y in zip(a, b)]
    in_ratios = [x / y for x, y in zip(inproc, b)]
    print(f"simulate, {cells} cells, t_end {t_end} s, {rounds} interleaved rounds (medians):")
    print(f"  crawler-plant simulate --json --episodes, whole process: {statistics.median(b):.3f} s")
    print(f"  python -c 'softcrawler.simulate(...)', whole process: {statistics.median(a):.3f} s "
          f"ratio {statistics.median(ratios):.3f} (min {min(ratios):.3f}, max {max(ratios):.3f})")
    print(f"  of which python -c 'import softcrawler':            {statistics.median(c):.3f} s")
    print(f"  softcrawler.simulate(...) in a running interpreter:  {statistics.median(inproc):.3f} s "
          f"ratio {statistics.median(in_ratios):.3f} (min {min(in_ratios):.3f}, "
          f"max {max(in_ratios):.3f})")


def rust_rate(cells: int, seconds: float) -> float:
    """Communication steps per second of one plant stepped in Rust (no Python per step)."""
    s = softcrawler.Scenario(cells=cells, t_end=1e4)
    p = softcrawler.Plant(s)
    p.step(200)
    n = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        n += p.step(500)
    return n / (time.perf_counter() - t0)


def env_rate(num: int, cells: int, seconds: float, frame_skip: int = 1) -> float:
    """Crawler communication steps per second of the environment, summed over the crawlers of
    a vector (num > 1) or of one environment."""
    kw = dict(action="wave", frame_skip=frame_skip, cells=cells, t_end=1e4)
    if num == 1:
        env = SoftCrawlerEnv(**kw)
        env.reset(seed=0)
        w = env.base.wave
        action = np.array([0.5, w["omega"], w["k"]])
        def run(steps: int) -> None:
            for _ in range(steps):
                if any(env.step(action)[2:4]):
                    env.reset()

        run(200)
        n = 0
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            run(100)
            n += 100 * frame_skip
        return n / (time.perf_counter() - t0)
    vec = SoftCrawlerVectorEnv(num, **kw)
    vec.reset(seed=0)
    w = softcrawler.Scenario(cells=cells).wave
    actions = np.tile([0.5, w["omega"], w["k"]], (num, 1))
    for _ in range(20):
        vec.step(actions)
    n = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        for _ in range(10):
            vec.step(actions)
        n += 10 * num * frame_skip
    return n / (time.perf_counter() - t0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--cells", type=int, default=512)
    ap.add_argument("--t-end", type=float, default=20.0)
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--frame-skip", type=int, default=1,
                    help="communication steps per environment step (1: every step)")
    args = ap.parse_args()
    print(f"python {sys.version.split()[0]}, softcrawler {softcrawler.__version__}, "
          f"{os.cpu_count()} cores (shared)")
    simulate_vs_cli(args.rounds, args.cells, args.t_end)
    # interleaved: Rust loop, one env, vector of 64, repeated; medians
    rust, one, vec = [], [], []
    for _ in range(3):
        rust.append(rust_rate(args.cells, args.seconds))
        one.append(env_rate(1, args.cells, args.seconds, args.frame_skip))
        vec.append(env_rate(64, args.cells, args.seconds, args.frame_skip))
    r, o, v = (statistics.median(x) for x in (rust, one, vec))
    cores = os.cpu_count() or 1
    print(f"communication steps per second, {args.cells} cells, frame_skip {args.frame_skip}, "
          "median of 3 interleaved rounds:")
    print(f"  Rust loop, one crawler (Plant.step(500)):   {r:10.0f}")
    print(f"  one environment (env.step per step):        {o:10.0f}  "
          f"Python's overhead per step {100 * (r / o - 1):.1f} %")
    print(f"  vector of 64 (vec.step per step), total:    {v:10.0f}  "
          f"per crawler and core {v / min(cores, 64):.0f} = {100 * v / min(cores, 64) / r:.1f} % "
          f"of the Rust loop's rate")
    return 0


if __name__ == "__main__":
    sys.exit(main())
