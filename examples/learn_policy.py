#!/usr/bin/env python3
"""A learnt feedback policy for the paper's task, searched with CMA-ES on the Gymnasium
environment and compared honestly with `optimal`, `adaptive` and `reflex`.

The policy (`PacingAgent`) sees what a real crawler senses (the environment's fields `stuck`,
`stress`, `speed`, `progress`, `energy` over 4 segments) every `FRAME_SKIP` communication steps and
commands a travelling wave (the scenario's wave number):

    g     = [1, progress - energy, speed / 0.1 m/s, mean stuck share, largest stress share]
    f0    = f0_max sigmoid(theta[0:5] . g)                   (N)
    omega = (0.2 + 1.8 sigmoid(theta[5:10] . g)) k c          (rad/s)

`progress - energy` is how far the crawler is ahead of its budget (distance over D minus energy
over J0): ahead, it may push harder; behind, it must save. The ten numbers theta are searched
with CMA-ES (the `cma` package) on a family of *training* pipes only: the paper's crawler (128
cells) in pipes whose friction is drawn uniformly, eps in [0.15, 0.5] and n_F in [0.3, 0.6], with
a seeded random texture (std 0.05, correlation 0.2 m), never disclosed. None of `crawler
compare`'s cases is in the family (nominal: eps 0.1 / n_F 0.5; mismatch: 0.3 / 0.7; patchy: dry
patches of 0.8; free: free ends; stick-slip: eps 1), so every case of the evaluation is unseen.

    .venv/bin/python examples/learn_policy.py train                # ~4 min here; prints theta
    .venv/bin/python examples/learn_policy.py evaluate             # the table of docs/python.md
    .venv/bin/python examples/learn_policy.py control --run-id R   # a co-simulated run

`evaluate` runs every policy in process through the execution loop the co-simulation runs (the
same bits as `crawler run --task --t-end 60`), at each case's own resolution. `control` drives a
co-simulated plant with the same object: `crawler run --task --t-end 60 --controller-cmd
".venv/bin/python examples/learn_policy.py control"`.
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import sys
import time

import numpy as np

import softcrawler
from softcrawler.client import add_arguments, from_arguments
from softcrawler.env import PipeFamily, SoftCrawlerVectorEnv

ROOT = pathlib.Path(__file__).resolve().parents[1]
FIELDS = ("stuck", "stress", "speed", "progress", "energy")
SEGMENTS = 4
FRAME_SKIP = 20
#: found by `learn_policy.py train` (the defaults: seed 1, 20 generations of 10 candidates, each
#: scored on the same 8 training pipes; 229 s here); see docs/python.md
THETA = [-0.2846, 1.6966, 0.8543, -2.0714, 2.7667, -2.3578, 4.1324, 0.2459, -3.2941, 0.6776]
TRAINING = PipeFamily(eps=(0.15, 0.5), n_f=(0.3, 0.6), eps_std=0.05, correlation=0.2, extent=5.0,
                      nominal=(0.1, 0.5))
CASES = {
    "nominal": "scenarios/paper.toml",
    "mismatch": "scenarios/mismatch.toml",
    "patchy": "scenarios/patchy-pipe.toml",
    "free": "scenarios/free-body.toml",
    "stick-slip": "scenarios/stick-slip.toml",
}


def sigmoid(x: float) -> float:
    return 1.0 / (1.0 + math.exp(-max(-50.0, min(50.0, x))))


class PacingAgent:
    """The learnt policy: the environment's features in, a wave out (see the module's doc)."""

    def __init__(self, theta) -> None:
        self.theta = np.asarray(theta, dtype=np.float64)

    def reset(self, context) -> None:
        body = context["body"]
        self.c = math.sqrt(body["area"] * body["youngs_modulus"] / body["density"])
        self.k = context["wave"]["k"]
        self.f0_max = context["limits"]["f0_max"]

    def __call__(self, features: np.ndarray) -> np.ndarray:
        stuck = features[0:SEGMENTS].mean()
        stress = features[SEGMENTS:2 * SEGMENTS].max()
        speed, progress, energy = features[2 * SEGMENTS:]
        g = np.array([1.0, progress - energy, speed / 0.1, stuck, stress])
        f0 = self.f0_max * sigmoid(float(self.theta[0:5] @ g))
        alpha = 0.2 + 1.8 * sigmoid(float(self.theta[5:10] @ g))
        return np.array([f0, alpha * (self.k * self.c), self.k])


def policy(theta) -> softcrawler.EnvPolicy:
    return softcrawler.EnvPolicy(PacingAgent(theta), action="wave", segments=SEGMENTS,
                                 fields=FIELDS, frame_skip=FRAME_SKIP, name="learnt")


def training_base() -> softcrawler.Scenario:
    return softcrawler.Scenario(ROOT / "scenarios/reflex-tuning.toml", cells=128, t_end=40.0)


def fitness(thetas: list[np.ndarray], pipes: int, seed: int) -> np.ndarray:
    """Mean episode return of every theta over the same `pipes` training pipes, all crawlers
    stepped together by the vector environment."""
    n = len(thetas) * pipes
    vec = SoftCrawlerVectorEnv(n, training_base(), action="wave", segments=SEGMENTS,
                               fields=FIELDS, frame_skip=FRAME_SKIP, pipe_family=TRAINING)
    obs, _ = vec.reset(seed=[seed + (i % pipes) for i in range(n)])
    agents = []
    for i in range(n):
        a = PacingAgent(thetas[i // pipes])
        a.reset(softcrawler._native.context(vec.scenarios[i]._native))
        agents.append(a)
    returns = np.zeros(n)
    done = np.zeros(n, dtype=bool)
    while not done.all():
        actions = np.stack([agents[i](obs[i]) for i in range(n)])
        obs, rew, term, trunc, _ = vec.step(actions)
        returns += np.where(done, 0.0, rew)
        done |= term | trunc
    return returns.reshape(len(thetas), pipes).mean(axis=1)


def train(args) -> None:
    import cma

    es = cma.CMAEvolutionStrategy(np.zeros(10), 1.0,
                                  {"popsize": args.popsize, "seed": args.seed, "verbose": -9})
    started = time.perf_counter()
    for g in range(args.generations):
        thetas = es.ask()
        f = fitness([np.asarray(t) for t in thetas], args.pipes, 1000 * args.seed)
        es.tell(thetas, list(-f))
        best = es.result.xbest
        print(f"generation {g + 1:2d}: best return {f.max():+.4f}, mean {f.mean():+.4f} "
              f"({time.perf_counter() - started:.0f} s)", file=sys.stderr)
    theta = [round(float(x), 4) for x in es.result.xbest]
    print(json.dumps({"theta": theta, "return": float(-es.result.fbest)}))


def row(case: str, name: str, report: softcrawler.Report, wall: float) -> dict:
    t = report.task
    energy = t.energy_at_distance if t.energy_at_distance is not None else t.energy_used
    travelled = t.distance_target if t.energy_at_distance is not None else t.distance
    return {"case": case, "policy": name, "outcome": t.outcome,
            "time_to_distance": t.time_to_distance, "energy": energy, "distance": t.distance,
            "mileage": travelled / energy if energy > 0 else None, "peak_stress": t.max_stress,
            "time_over": t.time_over_sigma_max, "wall": wall, "digest": report.state_digest}


def table(rows: list[dict]) -> str:
    f = lambda x, p: "-" if x is None else f"{x:.{p}f}"  # noqa: E731
    lines = ["| case | policy | outcome | time to D (s) | energy used (J) | distance (m) | "
             "mileage (m/J) | peak stress (kPa) | time above sigma_max (s) |",
             "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        out = "**reached**" if r["outcome"] == "reached" else r["outcome"]
        lines.append(f"| {r['case']} | {r['policy']} | {out} | {f(r['time_to_distance'], 2)} | "
                     f"{f(r['energy'], 2)} | {f(r['distance'], 3)} | {f(r['mileage'], 4)} | "
                     f"{f(r['peak_stress'] / 1e3, 1)} | {f(r['time_over'], 3)} |")
    return "\n".join(lines)


def evaluate(args) -> None:
    theta = json.loads(pathlib.Path(args.theta).read_text())["theta"] if args.theta else THETA
    rows = []
    for case in args.cases.split(","):
        scenario = softcrawler.Scenario(ROOT / CASES[case], t_end=60.0, task=True)
        for name in args.policies.split(","):
            started = time.perf_counter()
            p = policy(theta) if name == "learnt" else name
            run = softcrawler.run(scenario, p)
            rows.append(row(case, name, run.report, time.perf_counter() - started))
            r = rows[-1]
            print(f"{case} / {name}: {r['outcome']} ({r['wall']:.1f} s of wall time)",
                  file=sys.stderr)
    md = table(rows)
    print(md)
    if args.out:
        out = pathlib.Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(md + "\n")
        out.with_suffix(".json").write_text(json.dumps(rows, indent=1) + "\n")


def control(args) -> int:
    theta = json.loads(pathlib.Path(args.theta).read_text())["theta"] if args.theta else THETA
    summary = from_arguments(args).run(policy(theta))
    print(f"learnt: answered {summary['steps']} steps", file=sys.stderr)
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train", help="search theta with CMA-ES on the training pipes")
    t.add_argument("--generations", type=int, default=20)
    t.add_argument("--popsize", type=int, default=10)
    t.add_argument("--pipes", type=int, default=8, help="training pipes per evaluation")
    t.add_argument("--seed", type=int, default=1)
    e = sub.add_parser("evaluate", help="the learnt policy against optimal, adaptive, reflex")
    e.add_argument("--theta", help="a JSON file {\"theta\": [...]} (default: the one found)")
    e.add_argument("--cases", default=",".join(CASES))
    e.add_argument("--policies", default="learnt,optimal,adaptive,reflex")
    e.add_argument("--out", default="out/learnt/table.md")
    c = sub.add_parser("control", help="control a co-simulated run with the learnt policy")
    c.add_argument("--theta")
    add_arguments(c)
    args = ap.parse_args()
    if args.command == "train":
        train(args)
    elif args.command == "evaluate":
        evaluate(args)
    else:
        return control(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
