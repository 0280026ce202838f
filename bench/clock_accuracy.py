"""What an integer clock (numerics.ticks_per_second) does to the plant's accuracy, printed as the
table of docs/numerics.md ("Integer clocks").

Usage: python3 bench/clock_accuracy.py

An integer clock makes the communication step H a whole number of ticks and the internal step
dt = H / substeps, which lowers the Courant number below its target by less than one tick over H
(the plant refuses a clock that could lower it by more than 1e-5). This script runs
`crawler-plant simulate --json` at Courant numbers 1 - delta for delta from 1e-7 to 1e-2, and on a
nanosecond clock, at the operating points most sensitive to the Courant number (near and at
resonance, where the scheme's exactness along characteristics matters), and prints each metric's
change against Courant number 1, beside the change from doubling the cells (the size of the
discretisation error). It builds the release binary first (said before it runs).
"""

import json
import math
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGET = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
PLANT = os.path.join(TARGET, "release", "crawler-plant")

CASES = [
    # (label, eps, f0, k, alpha, length, cells)
    ("main job's wave (eps 0.1, f0 0.0574 N, k 8 pi, alpha 1), 128 cells per wavelength", 0.1, 0.0574, 8 * math.pi,
     1.0, 0.25, 128),
    ("near resonance (eps 0.1, f0 0.0577 N, k 8 pi, alpha 1.001), 128 cells per wavelength", 0.1, 0.0577,
     8 * math.pi, 1.001, 0.25, 128),
    ("exact resonance (eps 0.3, f0 0.3 N, k 2 pi, alpha 1), 128 cells", 0.3, 0.3, 2 * math.pi, 1.0, 1.0, 128),
    ("the paper scenario (eps 0.1, f0 0.5 N, k 2 pi, alpha 1), 512 cells", 0.1, 0.5, 2 * math.pi, 1.0, 1.0, 512),
]
DELTAS = [1e-7, 1e-6, 1e-5, 1e-3]


def scenario(eps, f0, k, alpha, length, cells, courant=None, ticks=None):
    lines = [
        'name = "clock"',
        "[body]", "area = 1e-4", "density = 0.1", "youngs_modulus = 140e3", f"length = {length!r}",
        "[friction]", "viscous = 1.0", "dry = 1.0", f"eps = {eps!r}", "n_f = 0.5",
        "[actuation]", f"f0 = {f0!r}", f"k = {k!r}", f"alpha = {alpha!r}",
        "[numerics]", f"cells = {cells}", "t_end = 10.0", "settle = 5.0", "step = 1.0e-3",
    ]
    if courant is not None:
        lines.append(f"courant = {courant!r}")
    if ticks is not None:
        lines.append(f"ticks_per_second = {ticks}")
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


def rel(a, b):
    return f"{a / b - 1:+.1e}" if b else "n/a"


def main():
    print("building the release binary (cargo build --release -p crawler-plant) ...", file=sys.stderr)
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "crawler-plant"], check=True, cwd=ROOT)
    print("| case | run | Courant number | stuck fraction | its change | V change | P change | sigma change |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for label, *point in CASES:
        base = simulate(scenario(*point))
        print(f"| {label} | Courant 1 | 1 | {100 * base['stuck_fraction']:.3f} % | | V = {base['velocity']:.6e} m/s | | |")
        runs = [(f"Courant 1 - {d:.0e}", scenario(*point, courant=1.0 - d)) for d in DELTAS]
        runs.insert(1, ("nanosecond clock", scenario(*point, ticks=1_000_000_000)))
        # the yardstick: what doubling the cells changes (the size of the discretisation error)
        *rest, cells = point
        runs.append((f"{2 * cells} cells, Courant 1", scenario(*rest, 2 * cells)))
        for name, text in runs:
            r = simulate(text)
            print(f"| | {name} | {r['parameters']['courant']:.9f} | {100 * r['stuck_fraction']:.3f} % | "
                  f"{rel(r['stuck_fraction'], base['stuck_fraction'])} | {rel(r['velocity'], base['velocity'])} | "
                  f"{rel(r['power'], base['power'])} | {rel(r['max_stress'], base['max_stress'])} |", flush=True)


if __name__ == "__main__":
    main()
