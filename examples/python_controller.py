#!/usr/bin/env python3
"""A crawler controller written in Python: it drives the plant with a travelling wave.

The control law is all there is here: `softcrawler.connect(...).run(policy)` is the project's
Rust controller client (it finds the run's credential, seals every message, joins the run and
answers every state exactly once; docs/protocol.md, docs/security.md). Start a plant, then:

    .venv/bin/python examples/python_controller.py --run-id demo --alpha 0.5

or let the launcher start it with the recorder: `crawler run --controller-cmd ".venv/bin/python
examples/python_controller.py --alpha 0.5"` (it adds the run's --run-id and --credential).
"""

import argparse
import math
import sys

import softcrawler
from softcrawler.client import add_arguments, from_arguments


class TravellingWave:
    """f0 sin(k x - omega t): k one wavelength per body unless given, omega = alpha k c."""

    name = "python-wave"

    def __init__(self, f0, k=None, omega=None, alpha=1.0):
        self.f0, self.k, self.omega, self.alpha = f0, k, omega, alpha

    def reset(self, context):
        body = context["body"]
        # the Rust policies' arithmetic, so the same bits: c = sqrt((A_c E) / rho)
        c = math.sqrt(body["area"] * body["youngs_modulus"] / body["density"])
        k = self.k if self.k is not None else 2.0 * math.pi / context["length"]
        omega = self.omega if self.omega is not None else self.alpha * (k * c)
        self.wave = softcrawler.Wave(f0=self.f0, k=k, omega=omega)

    def act(self, observation):
        return self.wave


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_arguments(ap)
    ap.add_argument("--f0", type=float, default=0.5, help="wave amplitude, N")
    ap.add_argument("--k", type=float, help="wave number, rad/m (default: one wavelength per body)")
    group = ap.add_mutually_exclusive_group()
    group.add_argument("--omega", type=float, help="angular frequency, rad/s")
    group.add_argument("--alpha", type=float, default=1.0, help="omega / omega_n (default 1: resonance)")
    args = ap.parse_args()
    policy = TravellingWave(args.f0, args.k, args.omega, args.alpha)
    summary = from_arguments(args).run(policy)
    print(f"python-controller: answered {summary['steps']} steps", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
