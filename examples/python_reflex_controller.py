#!/usr/bin/env python3
"""A feedback controller in Python: the travelling wave plus a proportional stick reflex.

The counterpart of python_controller.py that closes the loop: every step it reads the plant's
stuck mask from the state and answers with a muscle-force field (one value per cell),

    m_i = f0 sin(k x_i - omega t) + gain f0 (stuck[i + 1] - stuck[i])

at the cell faces x_i = (i + 1/2) dx, t in the middle of the step. Face i lies between node i
(behind) and node i + 1 (ahead): a face contracts when the node ahead of it is anchored by static
friction and extends when the node behind it is, which loads every anchor backwards, the
direction in which static friction holds most (the earthworm's anchor-and-push). Same protocol,
same loopback-only, authenticated zenoh participant as python_controller.py (see there): each
step is answered once, a resent state gets the same answer again.

    .venv/bin/python examples/python_reflex_controller.py --run-id demo --f0 0.2 --alpha 0.5 --gain 0.5
"""

import argparse
import math
import sys

from python_controller import common_arguments, control


def reflex_field(state, info, f0, k, omega, gain):
    """The muscle force at the cell faces for the plant's state (periodic body)."""
    n = info["cells"]
    dx = info["length"] / n
    t = state["time"] + 0.5 * info["step"]
    stuck = state["stuck"]
    return [
        f0 * math.sin(k * ((i + 0.5) * dx) - omega * t) + gain * f0 * (stuck[(i + 1) % n] - stuck[i])
        for i in range(n)
    ]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    common_arguments(ap)
    ap.add_argument("--f0", type=float, default=0.2, help="wave amplitude, N")
    ap.add_argument("--alpha", type=float, default=0.5, help="omega / omega_n")
    ap.add_argument("--gain", type=float, default=0.5, help="stick reflex, a share of f0")
    args = ap.parse_args()

    def act(state, info):
        if info.get("boundary") != "periodic":
            raise SystemExit("python-reflex: this example drives a periodic body")
        k = 2.0 * math.pi / info["length"]
        omega = args.alpha * (k * math.sqrt(info["area"] * info["youngs_modulus"] / info["density"]))
        return {"wave": None, "field": reflex_field(state, info, args.f0, k, omega, args.gain)}

    return control(args, "python-reflex", "python-reflex", act)


if __name__ == "__main__":
    sys.exit(main())
