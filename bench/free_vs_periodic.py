"""How far the periodic idealisation is from a free body: V, P per metre, sigma and the stuck
fraction at the paper's point (eps = 0.1, f0 = 0.5 N, k = 2 pi, alpha = 1) for bodies with 1, 2, 4
and 8 wavelengths, printed as the table of docs/scenarios.md.

Usage: python3 bench/free_vs_periodic.py [--alpha A]
It builds the release binaries first (cargo build --release, said before it runs).
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


def simulate(boundary, waves, alpha, cells_per_wave=256, t_end=15.0):
    text = "\n".join([
        'name = "free-vs-periodic"',
        "[body]", "area = 1e-4", "density = 0.1", "youngs_modulus = 140e3",
        f"length = {float(waves)!r}", f'boundary = "{boundary}"',
        "[friction]", "viscous = 1.0", "dry = 1.0", "eps = 0.1", "n_f = 0.5",
        "[actuation]", "f0 = 0.5", f"k = {2 * math.pi!r}", f"alpha = {alpha!r}",
        "[numerics]", f"cells = {cells_per_wave * waves}", f"t_end = {t_end!r}", "settle = 10.0",
    ]) + "\n"
    with tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False) as f:
        f.write(text)
        path = f.name
    try:
        out = subprocess.run([PLANT, "simulate", "--json", "--max-episodes", "0", "--scenario", path],
                             check=True, capture_output=True, text=True).stdout
    finally:
        os.unlink(path)
    return json.loads(out)


def predict(model, alpha):
    out = subprocess.run([CONTROLLER, "predict", "--model", model, "--eps", "0.1", "--f0", "0.5",
                          "--alpha", str(alpha)], check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--alpha", type=float, default=1.0)
    a = ap.parse_args()
    print("building the release binaries (cargo build --release) ...", file=sys.stderr)
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "crawler-plant", "-p", "crawler-controller"],
                   check=True, cwd=ROOT)
    paper, improved = predict("paper", a.alpha), predict("improved", a.alpha)
    periodic = simulate("periodic", 1, a.alpha)
    print(f"paper's point, alpha = {a.alpha}: periodic plant V = {periodic['velocity']:.5e} m/s, "
          f"P = {periodic['power']:.4e} W per metre, sigma = {periodic['max_stress']:.4e} Pa, "
          f"stuck {100 * periodic['stuck_fraction']:.2f} %; paper model V = {paper.get('velocity') or float('nan'):.5e}, "
          f"improved model V = {improved['velocity']:.5e}\n")
    print("| wavelengths on the free body | V (m/s) | vs periodic | P per metre (W/m) | vs periodic | "
          "sigma (Pa) | vs periodic | stuck fraction |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for waves in [1, 2, 4, 8]:
        r = simulate("free", waves, a.alpha)
        p = r["power"] / waves
        print(f"| {waves} | {r['velocity']:.5e} | {r['velocity'] / periodic['velocity'] - 1:+.1%} | {p:.4e} | "
              f"{p / periodic['power'] - 1:+.1%} | {r['max_stress']:.4e} | "
              f"{r['max_stress'] / periodic['max_stress'] - 1:+.1%} | {100 * r['stuck_fraction']:.2f} % |", flush=True)


if __name__ == "__main__":
    main()
