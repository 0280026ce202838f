"""Cell updates per second of the plant's stepping loop: Rust against NumPy, side by side.

Usage: .venv/bin/python bench/plant_bench.py [--seconds S] [--cells 256,4096,65536] [--map]
Runs `crawler-plant bench` (release build; it builds it first with cargo and says so) and the
NumPy implementation of the same scheme (bench/plant_numpy.py) on the stick-slip case eps = 1,
f0 = 0.2 N, alpha = 0.5, single thread. With --map it also runs the plant in a pipe with a friction
map, interleaved with the uniform pipe, and prints the map's cost. Two maps change eps by at most
1e-9 (the physics is the uniform pipe's to that, so the ratio is the cost of the per-node map
alone; a map of exactly eps = 1 would be compiled into the uniform pipe and cost nothing): ten
patches of eps = 1 + 1e-12 (nodes rarely cross a piece edge) and a texture held every millimetre
(eps = 1 +- 1e-9; some node crosses a piece edge every few steps). Two change the physics as well:
ten patches of eps = 1.5 (more stick) and a texture of eps = 1 +- 0.05 every millimetre.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
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


def rust_rate(cells, seconds, scenario=None):
    exe = os.path.join(TARGET, "release", "crawler-plant")
    extra = ["--scenario", scenario] if scenario else []
    out = subprocess.run([exe, "bench", "--cells", str(cells), "--seconds", str(seconds)] + CASE + extra,
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)["cell_updates_per_second"]


def patches(eps):
    return "".join(f"[[pipe.features]]\nkind = \"patch\"\nfrom = {0.5 * j + 0.5}\nto = {0.5 * j + 0.75}\n"
                   f"eps = {eps}\n" for j in range(10))



def texture(std):
    return ("[[pipe.features]]\nkind = \"texture\"\nfrom = -2.0\nto = 10.0\n"
            f"eps_std = {std}\ncorrelation = 0.05\nseed = 1\n")


def scenario_with_pipe(features):
    paper = open(os.path.join(ROOT, "scenarios", "paper.toml")).read()
    f = tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False)
    f.write(paper + "\n[pipe]\n" + features)
    f.close()
    return f.name


MAPS = {
    "patches": patches(1.0 + 1e-12),
    "texture": texture(1e-9),
    "patches of eps 1.5": patches(1.5),
    "texture of eps 1 +- 0.05": texture(0.05),
}


def map_cost(cells, seconds, runs=5):
    """Median over interleaved runs of uniform / map cell-update rates."""
    files = {k: scenario_with_pipe(v) for k, v in MAPS.items()}
    ratios = {k: [] for k in files}
    try:
        for _ in range(runs):
            for k, path in files.items():
                uniform = rust_rate(cells, seconds)
                mapped = rust_rate(cells, seconds, path)
                ratios[k].append(uniform / mapped)
    finally:
        for path in files.values():
            os.unlink(path)
    return {k: sorted(v)[len(v) // 2] for k, v in ratios.items()}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--cells", default="256,4096,65536")
    ap.add_argument("--map", action="store_true", help="also measure the cost of a friction map")
    a = ap.parse_args()
    print("building crawler-plant (cargo build --release -p crawler-plant) ...", file=sys.stderr)
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "crawler-plant"], check=True, cwd=ROOT)
    print("| N | Rust (cell updates/s) | NumPy (cell updates/s) | Rust / NumPy |")
    print("| ---: | ---: | ---: | ---: |")
    for n in [int(x) for x in a.cells.split(",")]:
        r, p = rust_rate(n, a.seconds), numpy_rate(n, a.seconds)
        print(f"| {n} | {r:.3e} | {p:.3e} | {r / p:.1f}x |", flush=True)
    if a.map:
        print("\ntime per cell update with a map / uniform pipe (medians of 5 interleaved runs)\n")
        print("| N | ten patches, eps kept (machinery) | texture every 1 mm, eps kept (machinery) "
              "| ten patches of eps 1.5 | texture of eps 1 +- 0.05 |")
        print("| ---: | ---: | ---: | ---: | ---: |")
        for n in [int(x) for x in a.cells.split(",")]:
            c = map_cost(n, a.seconds)
            print(f"| {n} | " + " | ".join(f"{c[k]:.3f}" for k in MAPS) + " |", flush=True)


if __name__ == "__main__":
    main()
