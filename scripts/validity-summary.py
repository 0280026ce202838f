#!/usr/bin/env python3
"""Summarises the validity map (out/sweeps/validity.parquet, made by `crawler sweep
plans/validity.toml`): where the paper's perturbation result holds within 5 %, and why it fails.

The paper's model needs gamma = asin(lam) with lam = eps C0 / (R0 alpha) = eps pi_r n_F / (zeta R0
alpha): the ratio of the drift speed eps c_d n_F / c_v to the amplitude of the body's oscillation
speed. The summary bins the points by lam and prints the paper's errors per bin, then the 5 %
region per panel, the improved model's errors and the plant's convergence estimate.

    .venv/bin/python scripts/validity-summary.py [FILE]
"""
import math
import sys

import pyarrow.parquet as pq

path = sys.argv[1] if len(sys.argv) > 1 else "out/sweeps/validity.parquet"
d = pq.read_table(path).to_pydict()
n = len(d["index"])
METRICS = ["velocity", "power", "mileage", "max_stress"]


def lam(i):
    a, z, pr = d["alpha"][i], d["zeta"][i], d["pi_r"][i]
    r0 = 1 / math.sqrt((a * a - 1) ** 2 + (z * a) ** 2)
    return d["eps"][i] * pr * d["n_f"][i] / (z * r0 * a)


def worst(model, i, metrics=METRICS):
    es = [d[f"{model}.{m}.error"][i] for m in metrics]
    if any(e is None for e in es):
        return None
    return max(abs(e) for e in es)


def pct(x):
    return "undef." if x is None else f"{100 * x:.1f} %"


print(f"{n} points; plant at {sorted(set(d['plant.cells']))} cells per wavelength")
fails = [i for i in range(n) if d["error"][i]]
print(f"failed points: {len(fails)}")

# 1. the paper's errors against lam (points where the model is defined, eps > 0)
bins = [0, 0.01, 0.03, 0.1, 0.2, 0.3, 0.5, 0.7, 0.9, 1.0]
print("\npaper model, by lam = eps pi_r n_F / (zeta R0 alpha) (drift speed / oscillation speed amplitude):")
print("| lam | points | median worst error | 90th percentile | share within 5 % | worst V | worst P | worst sigma |")
print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
for lo, hi in zip(bins, bins[1:]):
    idx = [i for i in range(n) if d["eps"][i] > 0 and d["paper.valid"][i] and lo <= lam(i) < hi]
    if not idx:
        continue
    w = sorted(worst("paper", i) for i in idx)
    within = sum(1 for x in w if x <= 0.05) / len(w)
    mx = {m: max(abs(d[f"paper.{m}.error"][i]) for i in idx) for m in ("velocity", "power", "max_stress")}
    print(f"| [{lo}, {hi}) | {len(idx)} | {pct(w[len(w) // 2])} | {pct(w[int(0.9 * (len(w) - 1))])} | "
          f"{100 * within:.0f} % | {pct(mx['velocity'])} | {pct(mx['power'])} | {pct(mx['max_stress'])} |")
inv = [i for i in range(n) if not d["paper.valid"][i]]
print(f"undefined (lam > 1): {len(inv)} points; plant stuck fraction there: median "
      f"{sorted(d['plant.stuck_fraction'][i] for i in inv)[len(inv) // 2]:.3f}" if inv else "")
val = [i for i in range(n) if d["paper.valid"][i] and d["eps"][i] > 0]
print(f"plant stuck fraction where the paper's model is defined: max {max(d['plant.stuck_fraction'][i] for i in val):.4f}")

# 2. the 5 % region per panel
ks = sorted(set(d["k"]))
f0s = sorted(set(d["f0"]))
print("\npaper model within 5 % (all of V, P, M, sigma): per panel, the alpha range at each eps, and the largest eps")
for k in ks:
    for f0 in f0s:
        idx = [i for i in range(n) if d["k"][i] == k and d["f0"][i] == f0]
        ok = [i for i in idx if (w := worst("paper", i)) is not None and w <= 0.05 and d["eps"][i] > 0]
        share = len(ok) / len([i for i in idx if d["eps"][i] > 0])
        max_eps = max((d["eps"][i] for i in ok), default=0.0)
        rng = {}
        for e in (0.05, 0.1, 0.25, 0.5, 1.0):
            at = [d["alpha"][i] for i in ok if abs(d["eps"][i] - e) < 1e-9]
            rng[e] = f"[{min(at):.2f}, {max(at):.2f}]" if at else "none"
        print(f"k = {k / math.pi:.0f} pi, f0 = {f0} N: {100 * share:.0f} % of the eps > 0 points; largest eps {max_eps:.2f}; "
              + "; ".join(f"eps {e}: alpha in {r}" for e, r in rng.items()))

# 3. the speed alone
okv = [i for i in range(n) if d["eps"][i] > 0 and d["paper.velocity.error"][i] is not None
       and abs(d["paper.velocity.error"][i]) <= 0.05]
defined = [i for i in range(n) if d["eps"][i] > 0 and d["paper.velocity.error"][i] is not None]
print(f"\npaper's V within 5 %: {len(okv)} of {len(defined)} defined points with eps > 0")

# 4. the improved model and the plant's convergence
wi = [worst("improved", i) for i in range(n)]
wi_def = [x for x in wi if x is not None]
print(f"improved model: worst error over V, P, M, sigma: median {pct(sorted(wi_def)[len(wi_def) // 2])}, "
      f"99th percentile {pct(sorted(wi_def)[int(0.99 * (len(wi_def) - 1))])}, max {pct(max(wi_def))}; "
      f"within 1 %: {100 * sum(1 for x in wi_def if x <= 0.01) / len(wi_def):.1f} %, within 5 %: "
      f"{100 * sum(1 for x in wi_def if x <= 0.05) / len(wi_def):.1f} %")
for m in METRICS + ["stuck_fraction"]:
    c = sorted(x for x in d[f"plant.{m}.conv_error"] if x is not None)
    print(f"plant {m}: convergence estimate median {c[len(c) // 2]:.1e}, 99th percentile {c[int(0.99 * (len(c) - 1))]:.1e}, max {c[-1]:.1e}")
big = [i for i in range(n) if wi[i] is not None and wi[i] > 0.05]
for i in big[:10]:
    print(f"  improved > 5 %: k = {d['k'][i] / math.pi:.0f} pi, f0 = {d['f0'][i]}, eps = {d['eps'][i]:.2f}, alpha = {d['alpha'][i]:.2f}: "
          f"{pct(wi[i])}, stuck {d['plant.stuck_fraction'][i]:.3f}/{d['improved.stuck_fraction'][i]:.3f}, conv P {d['plant.power.conv_error'][i]:.1e}")
t = sum(d["wall_time"])
print(f"\nsum of the points' wall times: {t:.0f} s ({t / n:.3f} s per point)")
