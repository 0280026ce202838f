"""The optimiser and the improved model: Rust against NumPy, side by side.

Usage: .venv/bin/python bench/optimizer_bench.py
Runs `crawler-controller bench` (release build) and the vectorised NumPy implementation of the
same 500 x 500 paper-model grid search (bench/optimizer_numpy.py), and prints a Markdown table.
"""

import json
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(__file__))
from optimizer_numpy import grid_search  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGET = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))


def main():
    print("optimizer_bench: building crawler-controller (cargo build --release) ...", file=sys.stderr)
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "crawler-controller"], check=True, cwd=ROOT)
    exe = os.path.join(TARGET, "release", "crawler-controller")
    r = json.loads(subprocess.run([exe, "bench"], check=True, capture_output=True, text=True).stdout)
    best = float("inf")
    for _ in range(3):
        t = time.perf_counter()
        v, w, k, f0, top = grid_search()
        best = min(best, time.perf_counter() - t)
    # the same fastest cell and the same choice among the tied ones
    assert abs(top / r["paper_500_fastest"] - 1) < 1e-9, (top, r["paper_500_fastest"])
    assert abs(v / r["paper_500_velocity"] - 1) < 1e-9, (v, r["paper_500_velocity"])
    assert abs(f0 / r["paper_500_f0"] - 1) < 1e-9, (f0, r["paper_500_f0"])
    ms = lambda s: f"{1e3 * s:.1f} ms"  # noqa: E731
    us = lambda s: f"{1e6 * s:.1f} us"  # noqa: E731
    print("| measurement | Rust | NumPy | NumPy / Rust |")
    print("| --- | ---: | ---: | ---: |")
    print(f"| paper model, 500 x 500 grid, 1 thread | {ms(r['paper_500_one_thread'])} | {ms(best)} | {best / r['paper_500_one_thread']:.1f}x |")
    print(f"| paper model, 500 x 500 grid, {r['cores']} threads | {ms(r['paper_500_all_cores'])} | {ms(best)} | {best / r['paper_500_all_cores']:.1f}x |")
    print(f"| paper model, 500 x 500 grid + refinement | {ms(r['paper_500_refined'])} | | |")
    print(f"| improved model, 24 x 24 grid + refinement | {ms(r['improved_24_refined'])} | | |")
    print(f"| improved model, fixed 1 m body (co-simulation's optimal policy) | {ms(r['improved_fixed_body'])} | | |")
    print()
    print("| one improved prediction | one plant run (N = 256, 10 s) | plant / prediction |")
    print("| ---: | ---: | ---: |")
    print(f"| {us(r['improved_prediction'])} (sliding) / {us(r['improved_prediction_sticking'])} (sticking) | {ms(r['plant_run'])} | {r['speedup_vs_plant']:.0f}x |")
    print(f"\nsame optimum in both: V = {v:.6e} m/s at omega = {w:.3f} rad/s, k = {k:.4f} rad/m, f0 = {f0:.4f} N")


if __name__ == "__main__":
    main()
