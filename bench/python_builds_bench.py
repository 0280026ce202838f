#!/usr/bin/env python3
"""Two builds of the Python package side by side: the environment's step rate against the Rust
loop's, each build in its own process, their windows alternated round by round.

Usage: .venv/bin/python bench/python_builds_bench.py [--rounds 20] [--mode one|vec] DIR [DIR ...]

Each DIR holds a copy of an installed `softcrawler` package (the directory that contains the
package's folder: e.g. `cp -r .venv/lib/python3.11/site-packages/softcrawler /tmp/a/` after one
`scripts/setup-python.sh --package`, and /tmp/b/ after the other). Each build's process builds
the loops of bench/python_bench.py once (the same scenario, warm-up and task) and, at every
round, times its Rust loop, its environment (`one`: one environment against one crawler; `vec`:
a vector of 64 against a crawler per core) and its Rust loop again in 0.25 s windows; the
processes take their turns in a shuffled order per round, so that this VM's drift over seconds
hits every build alike. Printed: per build, the median and quartiles of its environment's rate
over its neighbouring Rust loop's.
"""

from __future__ import annotations

import argparse
import os
import random
import statistics
import subprocess
import sys
import time
from pathlib import Path

BENCH = Path(__file__).resolve().parent

CHILD = r"""
import os, sys
sys.path.insert(0, sys.argv[2])
import python_bench as pb
cores = os.cpu_count() or 1
if sys.argv[1] == "vec":
    rust, env = pb.RustLoop(512, cores), pb.EnvLoop(64, 512, 1)
else:
    rust, env = pb.RustLoop(512, 1), pb.EnvLoop(1, 512, 1)
print("ready", flush=True)
for _ in sys.stdin:
    a = rust.rate(0.25)
    b = env.rate(0.25)
    c = rust.rate(0.25)
    print(b / ((a + c) / 2), flush=True)
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dirs", nargs="+", help="directories holding a softcrawler package each")
    ap.add_argument("--rounds", type=int, default=20)
    ap.add_argument("--mode", choices=["one", "vec"], default="one")
    args = ap.parse_args()
    for d in args.dirs:
        if not (Path(d) / "softcrawler" / "__init__.py").is_file():
            ap.error(f"{d}: no softcrawler package in it (expected {d}/softcrawler/__init__.py)")
    procs = []
    try:
        for d in args.dirs:
            env = dict(os.environ, PYTHONPATH=d)
            p = subprocess.Popen([sys.executable, "-c", CHILD, args.mode, str(BENCH)],
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
            procs.append(p)
            if p.stdout.readline().strip() != "ready":
                raise SystemExit(f"{d}: the benchmark's process did not start")
        ratios: dict[str, list[float]] = {d: [] for d in args.dirs}
        for _ in range(args.rounds):
            turn = list(zip(args.dirs, procs))
            random.shuffle(turn)
            for d, p in turn:
                time.sleep(0.05)  # the other processes' pool threads go idle
                p.stdin.write("go\n")
                p.stdin.flush()
                ratios[d].append(float(p.stdout.readline()))
    finally:
        for p in procs:
            p.kill()
            p.wait()
    what = "one environment / one crawler" if args.mode == "one" else \
        "vector of 64 / a crawler per core"
    print(f"{what}, Rust loop's rate, {args.rounds} rounds of 0.25 s windows:")
    for d in args.dirs:
        q = statistics.quantiles(ratios[d], n=4)
        print(f"  {d}: median {q[1]:.3f}, quartiles {q[0]:.3f} to {q[2]:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
