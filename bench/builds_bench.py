#!/usr/bin/env python3
"""Two builds side by side: the plant's cell updates per second and the sweep's points per second
of this build against another (say, the commit before a refactor), interleaved run by run.

Usage: .venv/bin/python bench/builds_bench.py --baseline DIR [--bin-dir DIR] [--rounds 7]
                                             [--instructions]
DIR holds the other build's `crawler-plant` and `crawler-sweep` (its target/release). Both builds
run the same commands, in turn (A B A B ...), so that machine noise hits both alike; the table
gives medians and the median of the per-pair ratios (this build / baseline). The lockstep rate
is measured the same way by `bench/cosim_bench.py --baseline DIR`. With --instructions each command
runs once under valgrind's callgrind and its cost is the instructions it executed (all threads):
a count that does not move with the machine's load, where the wall times of a shared 2-core VM
move by 10 to 20 % from run to run.

  plant   `crawler-plant simulate` of the stick-slip case (eps = 1, f0 = 0.2 N, alpha = 0.5) at
          4096 cells for 6 s: cells x internal steps / wall time of the whole process; both
          builds must give the same state digest (checked).
  sweep   `crawler-sweep` of a plan of 16 short plant points (256 cells, 2 s, with the
          convergence check), one worker, into a fresh store: points / wall time of the whole
          process; both builds' plant columns must agree (checked on the velocity).
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from callgrind import instructions

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

PLANT = ["simulate", "--eps", "1", "--f0", "0.2", "--alpha", "0.5", "--cells", "4096",
         "--t-end", "6", "--json"]

PLAN = """name = "builds"
[set]
numerics.cells = 256
numerics.settle = 1.0
numerics.t_end = 2.0
[[axes]]
key = "friction.eps"
values = [0.1, 0.4, 0.7, 1.0]
[[axes]]
key = "actuation.alpha"
values = [0.5, 0.8, 1.1, 1.4]
[evaluate]
plant = true
"""
POINTS = 16


# With --instructions: the cost of a command is the number of instructions it executes (all its
# threads; valgrind's callgrind), not its wall time: the same on a busy or a quiet machine.
INSTRUCTIONS = False


def timed(cmd, **kw):
    """(cost, stdout) of `cmd`: wall time, s, or with --instructions the instructions executed."""
    if INSTRUCTIONS:
        return instructions(cmd, **kw)
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, **kw)
    dt = time.perf_counter() - t
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr[-2000:]}")
    return dt, p.stdout


def plant_rate(bin_dir):
    dt, out = timed([os.path.join(bin_dir, "crawler-plant"), *PLANT])
    r = json.loads(out)
    return r["cells"] * r["steps"] / dt, r["state_digest"]


def sweep_rate(bin_dir, plan):
    work = tempfile.mkdtemp(prefix="builds-bench-")
    try:
        dt, _ = timed([os.path.join(bin_dir, "crawler-sweep"), plan, "--store",
                       os.path.join(work, "store"), "--out", os.path.join(work, "out.parquet"),
                       "--jobs", "1", "--no-figures", "--no-progress"])
        velocity = None
        try:
            import pyarrow.parquet as pq
            velocity = pq.read_table(os.path.join(work, "out.parquet")).column(
                "plant.velocity").to_pylist()
        except ImportError:
            pass
        return POINTS / dt, velocity
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", required=True, help="the other build's binaries")
    ap.add_argument("--bin-dir", default=os.path.join(
        os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target")), "release"))
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--instructions", action="store_true",
                    help="count the instructions each command executes (valgrind's callgrind; "
                         "one round is enough, the count does not depend on the load): the rates "
                         "are then per instruction, not per second")
    a = ap.parse_args()
    global INSTRUCTIONS
    INSTRUCTIONS = a.instructions
    plan_dir = tempfile.mkdtemp(prefix="builds-plan-")
    plan = os.path.join(plan_dir, "builds.toml")
    with open(plan, "w") as f:
        f.write(PLAN)
    builds = {"this": a.bin_dir, "baseline": a.baseline}
    rates = {(w, b): [] for w in ("plant", "sweep") for b in builds}
    checks = {}
    for _ in range(a.rounds):
        for b, d in builds.items():
            r, digest = plant_rate(d)
            rates[("plant", b)].append(r)
            checks.setdefault(("plant", b), digest)
        for b, d in builds.items():
            r, v = sweep_rate(d, plan)
            rates[("sweep", b)].append(r)
            checks.setdefault(("sweep", b), v)
    shutil.rmtree(plan_dir, ignore_errors=True)
    print(f"| what | this build | baseline | this / baseline (median of {a.rounds} pairs) "
          "| same result |")
    print("| --- | ---: | ---: | ---: | --- |")
    per = "instruction" if a.instructions else "s"
    for what, unit in (("plant", f"cell updates/{per}"), ("sweep", f"points/{per}")):
        this, base = rates[(what, "this")], rates[(what, "baseline")]
        ratio = statistics.median(x / y for x, y in zip(this, base))
        same = checks[(what, "this")] == checks[(what, "baseline")]
        print(f"| {what} ({unit}) | {statistics.median(this):.4g} | "
              f"{statistics.median(base):.4g} | {ratio:.3f} | {'yes' if same else 'NO'} |")


if __name__ == "__main__":
    main()
