"""Time to a converged answer at the main job's point, whole process on one core, side by side.

Usage: python3 bench/converged_answer.py [--trials 3]

It builds the release binaries first (cargo build --release, said before it runs). The point is
the main job's wave before the optimiser's ridge tie-break (eps = 0.1, f0 = 0.0577 N, k = 8 pi,
alpha = 1.001, 10 s simulated), where stick phases are short and hard to resolve. Each run is
`crawler-plant simulate` as a whole process pinned to one core (`taskset -c 0`), timed wall
clock, medians of interleaved trials. "Converged" means V, P and sigma within 0.5 % and the stuck
fraction within 10 % of the travelling-wave steady state (the improved model with a fine march).
Compared: the default scheme (Courant number 1 and the grid filter) at the shipped resolution (128
cells per wavelength: one wavelength, and the main job's 1 m body of four), and the scheme the
plant used before (Courant number 0.9, no filter) at 4096 cells per wavelength, where its stuck
fraction first came within 10 % when the numerics were reworked.
"""

import argparse
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from stick_convergence import PLANT, ROOT, improved, scenario  # noqa: E402

import json  # noqa: E402


def run(text):
    """Whole-process wall time (s) and the JSON report of one simulate run on one core."""
    with tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False) as f:
        f.write(text)
        path = f.name
    pin = ["taskset", "-c", "0"] if shutil.which("taskset") else []
    try:
        t = time.perf_counter()
        out = subprocess.run([*pin, PLANT, "simulate", "--json", "--max-episodes", "0", "--scenario", path],
                             check=True, capture_output=True, text=True).stdout
        return time.perf_counter() - t, json.loads(out)
    finally:
        os.unlink(path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=3)
    a = ap.parse_args()
    print("building the release binaries (cargo build --release) ...", file=sys.stderr)
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "crawler-plant", "-p", "crawler-controller"],
                   check=True, cwd=ROOT)
    eps, f0, k, alpha = 0.1, 0.0577, 8 * math.pi, 1.001
    wl = 2 * math.pi / k
    ref = improved(eps, f0, k, alpha)
    cases = [
        ("default (Courant 1), 128 cells, one wavelength", scenario(eps, f0, k, alpha, wl, 128), 1),
        ("default (Courant 1), 512 cells, the main job's 1 m body", scenario(eps, f0, k, alpha, 4 * wl, 512), 4),
        ("before: Courant 0.9, no filter, 4096 cells, one wavelength",
         scenario(eps, f0, k, alpha, wl, 4096, courant=0.9, filt=0.0), 1),
    ]
    times = {name: [] for name, _, _ in cases}
    reports = {}
    for _ in range(a.trials):
        for name, text, _ in cases:
            t, r = run(text)
            times[name].append(t)
            reports[name] = r
    print(f"improved model: stuck fraction {100 * ref['stuck_fraction']:.3f} %, V = {ref['velocity']:.6e} m/s, "
          f"P = {ref['power']:.6e} W, sigma = {ref['max_stress']:.6e} Pa; medians of {a.trials} trials\n")
    print("| run | wall time (s) | V error | P error | sigma error | stuck fraction (error) | converged |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | --- |")
    for name, _, wavelengths in cases:
        r = reports[name]
        # P is the input power over the whole body: per wavelength, as the model's
        per = {"velocity": 1, "power": wavelengths, "max_stress": 1}
        errs = [r[key] / per[key] / ref[key] - 1 for key in ("velocity", "power", "max_stress")]
        stuck = r["stuck_fraction"] / ref["stuck_fraction"] - 1
        ok = all(abs(e) <= 5e-3 for e in errs) and abs(stuck) <= 0.1
        print(f"| {name} | {statistics.median(times[name]):.3f} | "
              + " | ".join(f"{e:+.2e}" for e in errs)
              + f" | {100 * r['stuck_fraction']:.3f} % ({100 * stuck:+.1f} %) | {'yes' if ok else 'no'} |")


if __name__ == "__main__":
    main()
