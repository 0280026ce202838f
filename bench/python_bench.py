"""The Python package's speed, side by side with the Rust programs (docs/python.md, Performance).

Usage: .venv/bin/python bench/python_bench.py [--rounds R] [--cells N] [--t-end S]
       .venv/bin/python bench/python_bench.py --instructions [--cells N] [--t-end S]

1. `softcrawler.simulate` against `crawler-plant simulate --json --episodes`, whole run of the
   same scenario with the same output (the report with its list of up to 10 000 stick-slip
   episodes, which `simulate` returns by default), interleaved (A B A B ...): each a fresh process
   (the interpreter's start and the import included on the Python side), and `simulate` called in
   a running interpreter; the medians of the pairwise ratios.
2. Environment steps per second at the default communication step (frame_skip = 1: one
   communication step per environment step): one environment against the Rust loop's rate for
   one crawler (the plant stepped in Rust, no Python in the loop, `Plant.step(n)`), and a vector of
   64 against the Rust loop on as many threads as the machine has cores (each stepping its own
   plant), so both sides get the cores the machine really gives; the actions are fixed arrays, so
   the figures are the package's overhead, not an agent's. Short windows (--seconds), many
   interleaved rounds (--env-rounds), the median and quartiles of the per-round ratios: this
   VM's speed drifts over seconds, so only neighbouring windows compare.
3. What stepping many crawlers costs: `crawler-plant bench --plants 64` (64 plants stepped in
   turn on one thread, their states too many for the cache) against `--plants 1`, and in process
   64 `Plant`s stepped in turn by `Plant.step(1)` (Python between their steps, as in a vector)
   against one stepped so, in the same rounds.
Needs the package installed (scripts/setup-python.sh) and target/release/crawler-plant.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import threading
import time

import numpy as np

import softcrawler
from callgrind import instructions
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


def simulate_instructions(cells: int, t_end: float) -> None:
    """`simulate` against the program by instruction counts: the same on a busy or a quiet
    machine. The Python side's interpreter start, import and scenario are counted apart (the same
    command without the `simulate` call) and taken off."""
    plant = str(TARGET / "release" / "crawler-plant")
    cli, _ = instructions([plant, "simulate", "--json", "--episodes", "--cells", str(cells),
                           "--t-end", str(t_end)])
    setup = (f"import softcrawler as sc; s = sc.Scenario(cells={cells}, t_end={t_end})")
    py, _ = instructions([sys.executable, "-c", setup + "; sc.simulate(s)"])
    base, _ = instructions([sys.executable, "-c", setup])
    print(f"simulate by instructions (callgrind), {cells} cells, t_end {t_end} s:")
    print(f"  crawler-plant simulate --json --episodes, whole process: {cli / 1e6:10.1f} M")
    print(f"  python -c '...simulate(s)', whole process:              {py / 1e6:10.1f} M")
    print(f"  of which the interpreter, the import and the scenario:  {base / 1e6:10.1f} M")
    print(f"  simulate itself: {(py - base) / 1e6:.1f} M = x {(py - base) / cli:.3f} the program")


#: Communication steps every crawler takes before it is timed: the first few hundred of a run
#: from rest are cheaper (few nodes stick yet), so both sides are timed past them.
WARM_STEPS = 2000


def rate_scenario(cells: int) -> softcrawler.Scenario:
    """The paper's scenario on `cells` cells with a task no crawler finishes while timed (D =
    1 km, J0 = 1 GJ, t_end = 10^4 s): every side steps crawlers in the same regime, none resets."""
    return softcrawler.Scenario(cells=cells, t_end=1e4).with_values(
        {"task.distance": 1e3, "task.energy": 1e9})


class RustLoop:
    """Plants stepped in Rust (no Python per step), one per thread (`Plant.step` releases the
    GIL, so they run on as many cores as the machine gives)."""

    def __init__(self, cells: int, threads: int) -> None:
        self.plants = [softcrawler.Plant(rate_scenario(cells)) for _ in range(threads)]
        for p in self.plants:
            p.step(WARM_STEPS)

    def rate(self, seconds: float) -> float:
        """Communication steps per second, summed over the threads."""
        counts = [0] * len(self.plants)
        t0 = time.perf_counter()

        def work(i: int) -> None:
            while time.perf_counter() - t0 < seconds:
                counts[i] += self.plants[i].step(500)

        pool = [threading.Thread(target=work, args=(i,)) for i in range(len(self.plants))]
        for t in pool:
            t.start()
        for t in pool:
            t.join()
        return sum(counts) / (time.perf_counter() - t0)


class EnvLoop:
    """One environment (num = 1) or a vector of `num`, stepped with a fixed action (the
    scenario's wave), so the figures are the package's overhead, not an agent's."""

    def __init__(self, num: int, cells: int, frame_skip: int) -> None:
        scenario = rate_scenario(cells)
        w = scenario.wave
        action = np.array([w["f0"], w["omega"], w["k"]])
        kw = dict(action="wave", frame_skip=frame_skip)
        self.frame_skip = frame_skip
        if num == 1:
            env = SoftCrawlerEnv(scenario, **kw)
            env.reset(seed=0)
            self.crawlers, self.step = 1, lambda: env.step(action)
        else:
            vec = SoftCrawlerVectorEnv(num, scenario, **kw)
            vec.reset(seed=0)
            actions = np.tile(action, (num, 1))
            self.crawlers, self.step = num, lambda: vec.step(actions)
        for _ in range(WARM_STEPS // frame_skip):
            self.step()

    def rate(self, seconds: float) -> float:
        """Crawler communication steps per second, summed over the crawlers."""
        batch = max(1, 640 // self.crawlers)
        n = 0
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            for _ in range(batch):
                self.step()
            n += batch * self.crawlers * self.frame_skip
        return n / (time.perf_counter() - t0)


class TurnLoop:
    """`plants` plants of the scenario, each stepped one communication step per `Plant.step(1)`
    call, in turn (a vector's order, with Python between its crawlers' steps): against one plant
    stepped the same way, what 64 crawlers' states cost in the cache."""

    def __init__(self, cells: int, plants: int) -> None:
        self.plants = [softcrawler.Plant(rate_scenario(cells)) for _ in range(plants)]
        for p in self.plants:
            p.step(WARM_STEPS)

    def rate(self, seconds: float) -> float:
        n = 0
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            for p in self.plants:
                p.step(1)
            n += len(self.plants)
        return n / (time.perf_counter() - t0)


def plant_bench(cells: int, plants: int, seconds: float) -> float:
    """Cell updates per second of `crawler-plant bench` with `plants` plants stepped in turn."""
    out = subprocess.run([str(TARGET / "release" / "crawler-plant"), "bench", "--cells",
                          str(cells), "--plants", str(plants), "--seconds", str(seconds)],
                         check=True, capture_output=True, text=True).stdout
    return float(json.loads(out)["cell_updates_per_second"])


def quartiles(xs: list[float]) -> str:
    q = statistics.quantiles(xs, n=4) if len(xs) > 1 else [xs[0]] * 3
    return f"median {q[1]:.3f}, quartiles {q[0]:.3f} to {q[2]:.3f}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--cells", type=int, default=512)
    ap.add_argument("--t-end", type=float, default=20.0)
    ap.add_argument("--seconds", type=float, default=0.25,
                    help="wall time of each window of the step-rate measurements, s")
    ap.add_argument("--env-rounds", type=int, default=30,
                    help="interleaved rounds of the step-rate measurements")
    ap.add_argument("--frame-skip", type=int, default=1,
                    help="communication steps per environment step (1: every step)")
    ap.add_argument("--instructions", action="store_true",
                    help="only compare simulate with the program by instruction counts "
                         "(valgrind's callgrind), once")
    args = ap.parse_args()
    if args.instructions:
        simulate_instructions(args.cells, args.t_end)
        return 0
    print(f"python {sys.version.split()[0]}, softcrawler {softcrawler.__version__}, "
          f"{os.cpu_count()} cores (shared)")
    simulate_vs_cli(args.rounds, args.cells, args.t_end)
    # interleaved: Rust loop, one env, Rust loop on every core, vector of 64, 64 plants in
    # Rust; the medians and quartiles of the per-round ratios
    cores = os.cpu_count() or 1
    loops = [RustLoop(args.cells, 1), EnvLoop(1, args.cells, args.frame_skip),
             RustLoop(args.cells, cores), EnvLoop(64, args.cells, args.frame_skip)]
    turns = [TurnLoop(args.cells, 1), TurnLoop(args.cells, 64)]
    rust, one, rust_all, vec, p1, p64, t1, t64 = [], [], [], [], [], [], [], []
    for _ in range(args.env_rounds):
        for loop, out in zip(loops + turns, (rust, one, rust_all, vec, t1, t64)):
            out.append(loop.rate(args.seconds))
        p1.append(plant_bench(args.cells, 1, args.seconds))
        p64.append(plant_bench(args.cells, 64, args.seconds))
    r, ra, o, v = (statistics.median(x) for x in (rust, rust_all, one, vec))
    one_ratios = [x / y for x, y in zip(one, rust)]
    vec_ratios = [x / y for x, y in zip(vec, rust_all)]
    many_ratios = [x / y for x, y in zip(p64, p1)]
    turn_ratios = [x / y for x, y in zip(t64, t1)]
    print(f"communication steps per second, {args.cells} cells, frame_skip {args.frame_skip}, "
          f"{args.env_rounds} interleaved rounds of {args.seconds} s windows (medians):")
    print(f"  Rust loop, one crawler (Plant.step(500)):           {r:10.0f}")
    print(f"  one environment (env.step per step):                {o:10.0f}  "
          f"of the Rust loop's rate: {quartiles(one_ratios)} (Python's overhead per step "
          f"{100 * (1 / statistics.median(one_ratios) - 1):.1f} %)")
    print(f"  Rust loop, {cores} crawlers on {cores} threads, in all:        {ra:10.0f}  "
          f"{ra / r:.2f}x one crawler's rate")
    print(f"  vector of 64 (vec.step per step), in all:           {v:10.0f}  "
          f"of the Rust loop's rate on {cores} threads: {quartiles(vec_ratios)}")
    print(f"  Rust alone, 64 plants stepped in turn on one thread, of one plant's rate "
          f"(crawler-plant bench --plants 64 / --plants 1): {quartiles(many_ratios)}")
    print(f"  in process, 64 plants in turn by Plant.step(1), of one plant stepped so: "
          f"{quartiles(turn_ratios)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
