"""Convergence of the plant's stick statistics and metrics, printed as the tables of docs/numerics.md.

Usage: python3 bench/stick_convergence.py [--quick]

It builds the release binaries first (cargo build --release, said before it runs), then runs
`crawler-plant simulate --json` on scenarios written to a temporary directory and
`crawler-controller predict` for the improved model's value. The travelling-wave references come
from the improved model (exact to its march) and, at exact resonance, from the closed form.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGET = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
PLANT = os.path.join(TARGET, "release", "crawler-plant")
CONTROLLER = os.path.join(TARGET, "release", "crawler-controller")


def scenario(eps, f0, k, alpha, length, cells, courant=None, filt=None, t_end=10.0):
    lines = [
        'name = "convergence"',
        "[body]", "area = 1e-4", "density = 0.1", "youngs_modulus = 140e3", f"length = {length!r}",
        "[friction]", "viscous = 1.0", "dry = 1.0", f"eps = {eps!r}", "n_f = 0.5",
        "[actuation]", f"f0 = {f0!r}", f"k = {k!r}", f"alpha = {alpha!r}",
        "[numerics]", f"cells = {cells}", f"t_end = {t_end!r}", "settle = 5.0",
    ]
    if courant is not None:
        lines.append(f"courant = {courant!r}")
    if filt is not None:
        lines.append(f"filter = {filt!r}")
    return "\n".join(lines) + "\n"


def simulate(text):
    with tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False) as f:
        f.write(text)
        path = f.name
    try:
        out = subprocess.run([PLANT, "simulate", "--json", "--max-episodes", "0", "--scenario", path],
                             check=True, capture_output=True, text=True).stdout
    finally:
        os.unlink(path)
    return json.loads(out)


def improved(eps, f0, k, alpha):
    """The improved model with a fine march (65536 steps per period): the travelling-wave steady
    state to better than 1e-4 in the stuck fraction and 1e-7 in V."""
    out = subprocess.run([CONTROLLER, "predict", "--model", "improved", "--march-steps", "65536", "--eps", str(eps),
                          "--f0", str(f0), "--k", str(k), "--alpha", str(alpha)],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def at_resonance(eps, f0, k, n_f=0.5):
    """Closed form at alpha = 1: stuck where f0 k cos(xi) lies in the static band."""
    band, a = eps, f0 * k
    lo, hi = max(-1.0, (-1 - n_f) * band / a), min(1.0, (1 - n_f) * band / a)
    return (2 * (math.acos(lo) - math.acos(hi)) if lo < hi else 0.0) / (2 * math.pi)


def pct(x):
    return f"{100 * x:.3f} %"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer resolutions")
    a = ap.parse_args()
    print("building the release binaries (cargo build --release) ...", file=sys.stderr)
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "crawler-plant", "-p", "crawler-controller"],
                   check=True, cwd=ROOT)
    k8, k2 = 8 * math.pi, 2 * math.pi
    cells = [32, 64, 128, 256, 512] if a.quick else [32, 64, 128, 256, 512, 1024, 2048]

    print("\n### The main job's point: eps = 0.1, f0 = 0.0577 N, k = 8 pi, alpha = 1.001, one wavelength\n")
    ref = improved(0.1, 0.0577, k8, 1.001)
    print(f"improved model (travelling-wave steady state): stuck fraction {pct(ref['stuck_fraction'])}, "
          f"V = {ref['velocity']:.6e} m/s, P = {ref['power']:.6e} W, sigma = {ref['max_stress']:.6e} Pa\n")
    print("| cells per wavelength | stuck, Courant 0.9 | stuck, Courant 1, no filter | stuck (default) | "
          "episodes per node per period | mean duration / period | V error | P error | sigma error |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for n in cells:
        s09 = simulate(scenario(0.1, 0.0577, k8, 1.001, 0.25, n, courant=0.9))
        s10 = simulate(scenario(0.1, 0.0577, k8, 1.001, 0.25, n, filt=0.0))
        d = simulate(scenario(0.1, 0.0577, k8, 1.001, 0.25, n))
        period = 2 * math.pi / d["parameters"]["omega"]
        print(f"| {n} | {pct(s09['stuck_fraction'])} | {pct(s10['stuck_fraction'])} | {pct(d['stuck_fraction'])} | "
              f"{d['events']['per_node_per_period']:.3f} | {d['events']['mean_duration'] / period:.4f} | "
              f"{d['velocity'] / ref['velocity'] - 1:+.2e} | {d['power'] / ref['power'] - 1:+.2e} | "
              f"{d['max_stress'] / ref['max_stress'] - 1:+.2e} |", flush=True)

    print("\n### At exact resonance: eps = 0.3, f0 = 0.3 N, k = 2 pi, alpha = 1\n")
    exact = at_resonance(0.3, 0.3, k2)
    print(f"closed form: stuck fraction {pct(exact)}\n")
    print("| cells per wavelength | Courant 0.9 | default |")
    print("| ---: | ---: | ---: |")
    for n in cells[:-1]:
        s09 = simulate(scenario(0.3, 0.3, k2, 1.0, 1.0, n, courant=0.9))
        d = simulate(scenario(0.3, 0.3, k2, 1.0, 1.0, n))
        print(f"| {n} | {pct(s09['stuck_fraction'])} | {pct(d['stuck_fraction'])} |", flush=True)

    print("\n### Long stick phases: eps = 1, f0 = 0.2 N, k = 2 pi, alpha = 0.5 (the stick-slip scenario)\n")
    ref = improved(1.0, 0.2, k2, 0.5)
    print(f"improved model: stuck fraction {pct(ref['stuck_fraction'])}, V = {ref['velocity']:.6e} m/s\n")
    print("| cells | V error, no filter | V error (default) | stuck (default) | P error | sigma error |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: |")
    for n in cells[2:]:
        s10 = simulate(scenario(1.0, 0.2, k2, 0.5, 1.0, n, filt=0.0))
        d = simulate(scenario(1.0, 0.2, k2, 0.5, 1.0, n))
        print(f"| {n} | {s10['velocity'] / ref['velocity'] - 1:+.2e} | {d['velocity'] / ref['velocity'] - 1:+.2e} | "
              f"{pct(d['stuck_fraction'])} | {d['power'] / ref['power'] - 1:+.2e} | "
              f"{d['max_stress'] / ref['max_stress'] - 1:+.2e} |", flush=True)

    print("\n### Faster than sound: eps = 0.3, f0 = 0.5 N, alpha = 2 and eps = 1, f0 = 0.2 N, alpha = 1.8 (512 cells)\n")
    print("| case | setting | V error | P error | sigma error | stuck | stuck (model) |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: |")
    for (eps, f0, alpha) in [(0.3, 0.5, 2.0), (1.0, 0.2, 1.8)]:
        ref = improved(eps, f0, k2, alpha)
        for label, kw in [("Courant 1, no filter", dict(courant=1.0, filt=0.0)), ("Courant 1", dict(courant=1.0)),
                          ("default (Courant 1/alpha)", {})]:
            d = simulate(scenario(eps, f0, k2, alpha, 1.0, 512, **kw))
            print(f"| eps {eps}, alpha {alpha} | {label} | {d['velocity'] / ref['velocity'] - 1:+.2e} | "
                  f"{d['power'] / ref['power'] - 1:+.2e} | {d['max_stress'] / ref['max_stress'] - 1:+.2e} | "
                  f"{pct(d['stuck_fraction'])} | {pct(ref['stuck_fraction'])} |", flush=True)

    print("\n### How sensitive the stuck fraction is near resonance (improved model, main point)\n")
    print("| alpha | stuck fraction |")
    print("| ---: | ---: |")
    for alpha in [1.0, 1.0001, 1.0005, 1.001, 1.002, 1.005, 1.01]:
        p = improved(0.1, 0.0577, k8, alpha)
        print(f"| {alpha} | {pct(p['stuck_fraction'])} |", flush=True)


if __name__ == "__main__":
    main()
