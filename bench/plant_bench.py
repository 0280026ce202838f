"""Cell updates per second of the plant's stepping loop: Rust against NumPy, side by side.

Usage: .venv/bin/python bench/plant_bench.py [--seconds S] [--cells 256,4096,65536]
Runs `crawler-plant bench` (release build) and the NumPy implementation of the same scheme
(bench/plant_numpy.py) on the stick-slip case eps = 1, f0 = 0.2 N, alpha = 0.5, single thread.
"""

import argparse
import json
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(__file__))
from plant_numpy import NumpyPlant  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGET = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
CASE = ["--eps", "1", "--f0", "0.2", "--alpha", "0.5"]


def numpy_rate(cells, seconds):
    p = NumpyPlant(cells)
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < 0.1 * seconds:
        p.step()
    steps = 0
    t0 = time.perf_counter()
    while True:
        for _ in range(16):
            p.step()
        steps += 16
        el = time.perf_counter() - t0
        if el >= seconds:
            break
    return cells * steps / el


def rust_rate(cells, seconds):
    exe = os.path.join(TARGET, "release", "crawler-plant")
    out = subprocess.run([exe, "bench", "--cells", str(cells), "--seconds", str(seconds)] + CASE,
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)["cell_updates_per_second"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--cells", default="256,4096,65536")
    a = ap.parse_args()
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "crawler-plant-node"], check=True, cwd=ROOT)
    print("| N | Rust (cell updates/s) | NumPy (cell updates/s) | Rust / NumPy |")
    print("| ---: | ---: | ---: | ---: |")
    for n in [int(x) for x in a.cells.split(",")]:
        r, p = rust_rate(n, a.seconds), numpy_rate(n, a.seconds)
        print(f"| {n} | {r:.3e} | {p:.3e} | {r / p:.1f}x |", flush=True)


if __name__ == "__main__":
    main()
