#!/usr/bin/env python3
"""A feedback controller in Python: the travelling wave plus a proportional stick reflex.

The counterpart of python_controller.py that closes the loop: every step it reads the plant's
stuck mask and answers with a muscle-force field (one value per cell),

    m_i = f0 sin(k x_i - omega t) + gain f0 (stuck[i + 1] - stuck[i])

at the cell faces x_i = (i + 1/2) dx, t in the middle of the step. Face i lies between node i
(behind) and node i + 1 (ahead): a face contracts when the node ahead of it is anchored by static
friction and extends when the node behind it is, which loads every anchor backwards, the
direction in which static friction holds most (the earthworm's anchor-and-push). The client is
softcrawler's (see python_controller.py).

    .venv/bin/python examples/python_reflex_controller.py --run-id demo --f0 0.2 --alpha 0.5 --gain 0.5
"""

import argparse
import math
import sys

import numpy as np

from softcrawler.client import add_arguments, from_arguments


class StickReflex:
    name = "python-stick-reflex"

    def __init__(self, f0, alpha, gain):
        self.f0, self.alpha, self.gain = f0, alpha, gain

    def reset(self, context):
        body = context["body"]
        self.n = context["cells"]
        self.dx = context["length"] / self.n
        self.step = context["step"]
        self.k = 2.0 * math.pi / context["length"]
        self.omega = self.alpha * (self.k * math.sqrt(body["area"] * body["youngs_modulus"] / body["density"]))

    def act(self, obs):
        t = obs.time + 0.5 * self.step
        stuck = obs.stuck.astype(np.float64)
        return [
            self.f0 * math.sin(self.k * ((i + 0.5) * self.dx) - self.omega * t)
            + self.gain * self.f0 * (stuck[(i + 1) % self.n] - stuck[i])
            for i in range(self.n)
        ]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_arguments(ap)
    ap.add_argument("--f0", type=float, default=0.2, help="wave amplitude, N")
    ap.add_argument("--alpha", type=float, default=0.5, help="omega / omega_n")
    ap.add_argument("--gain", type=float, default=0.5, help="stick reflex gain, share of f0")
    args = ap.parse_args()
    summary = from_arguments(args).run(StickReflex(args.f0, args.alpha, args.gain))
    print(f"python-reflex-controller: answered {summary['steps']} steps", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
