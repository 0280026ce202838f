#!/usr/bin/env python3
"""Local executor: speed-up of all workers over one, side by side in one run.

Builds crawler-sweep (release) first, then runs the same plan of short plant points with
--jobs 1 and --jobs N (N = all cores), each into a fresh store, interleaved over several trials,
and prints the median wall times and their ratio. With --validity it also times the whole
validity map (plans/validity.toml) into a fresh store, as the figure of docs/benchmarks.md.

    .venv/bin/python bench/sweep_bench.py [--trials 3] [--points 40] [--validity]
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.join(ROOT, "target", "release", "crawler-sweep")

PLAN = """name = "bench"
scenario = "{scenario}"
[set]
numerics.cells = {cells}
numerics.settle = 1.0
numerics.t_end = 2.0
actuation.k = 12.566370614359172
friction.eps = 0.5
[[axes]]
key = "actuation.alpha"
linspace = {{ start = 0.3, stop = 1.8, num = {points} }}
[evaluate]
plant = true
convergence = false
models = ["paper", "improved"]
"""


def build():
    print("building crawler-sweep (cargo build --release -p crawler-sweep) ...", file=sys.stderr)
    subprocess.run(["cargo", "build", "--release", "-p", "crawler-sweep"], cwd=ROOT, check=True)


def run(args, cwd, figures=False):
    t = time.perf_counter()
    extra = ["--no-progress"] + ([] if figures else ["--no-figures"])
    subprocess.run([BIN, *args, *extra], cwd=cwd, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=3)
    ap.add_argument("--points", type=int, default=40)
    ap.add_argument("--cells", type=int, default=1024)
    ap.add_argument("--validity", action="store_true", help="also time plans/validity.toml")
    a = ap.parse_args()
    build()
    cores = os.cpu_count() or 1
    with tempfile.TemporaryDirectory() as d:
        plan = os.path.join(d, "bench.toml")
        with open(plan, "w") as f:
            f.write(PLAN.format(scenario=os.path.join(ROOT, "scenarios", "paper.toml"),
                                cells=a.cells, points=a.points))
        times = {1: [], cores: []}
        for trial in range(a.trials):
            for jobs in (1, cores):
                store = os.path.join(d, f"store-{jobs}-{trial}")
                times[jobs].append(run([plan, "--jobs", str(jobs), "--store", store,
                                        "--out", os.path.join(d, "o.parquet")], d))
        t1, tn = statistics.median(times[1]), statistics.median(times[cores])
        print(f"{a.points} points (N = {a.cells}, k = 4 pi, 2 s each), medians of {a.trials} interleaved trials")
        print(f"| workers | wall time | points/s | speed-up |")
        print(f"| ---: | ---: | ---: | ---: |")
        print(f"| 1 | {t1:.2f} s | {a.points / t1:.2f} | 1.00 |")
        print(f"| {cores} | {tn:.2f} s | {a.points / tn:.2f} | **{t1 / tn:.2f}x** |")
        print(f"per point on one worker: {t1 / a.points:.3f} s")
        if a.validity:
            store = os.path.join(d, "validity-store")
            t = run([os.path.join(ROOT, "plans", "validity.toml"), "--store", store,
                     "--out", os.path.join(d, "validity.parquet")], ROOT, figures=True)
            print(f"validity map (plans/validity.toml, fresh store, {cores} workers): {t:.0f} s = {t / 60:.1f} min")


if __name__ == "__main__":
    main()
