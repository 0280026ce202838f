"""The peers' table: the crawler in this project's plant, in MuJoCo and in PyElastica, against the
exact answers, as resolution and time step are refined; one command, Markdown on stdout.

Usage: .venv/bin/python bench/peers/run.py [--repeats 5] [--bin-dir DIR] [--out FILE] [--json FILE]
                                           [--cache DIR [--peers-only]]
       .venv/bin/python bench/peers/run.py --quick   # smoke run: every tool and case, short (JSON)

The project's binaries are taken from --bin-dir, else $CRAWLER_BIN_DIR, else
$CARGO_TARGET_DIR/release or target/release (build them with
`cargo build --release -p crawler-plant -p crawler-controller`). The exact answers are the
improved model's travelling-wave steady state (`crawler-controller predict --model improved
--march-steps 65536`, docs/physics.md §4) and, for the static hold, zero. Wall times: the plant's
is the whole `crawler-plant simulate` process (start-up and JSON included); the peers' is their
stepping loop only (imports, model building, numba's compilation and the metrics excluded). The
last table times each tool's cheapest row that stays within 1 % in V: medians of --repeats runs,
interleaved with the other tools'; every other row is one run. --cache DIR stores and reuses the peers' tuning and ladder
runs (keyed by the scripts' text and arguments; the whole run takes about half an hour on 2 busy cores,
most of it PyElastica's finest rows). See docs/peers.md.
"""

import argparse
import dataclasses
import hashlib
import json
import math
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import CASES, C_D, N_F, ROOT, quick  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
PY = sys.executable

# The refinement ladders (cells on the one-wavelength body; the time step follows dx, at the
# Courant number or share of dx / c given in each tool's configuration)
OURS_CELLS = [16, 32, 64, 128, 256, 512]
PEER_CELLS = [16, 32, 64, 128, 256, 512]

# Each peer's configurations: the tuning candidates (run at TUNE_CELLS on the friction-sensitive
# cases) and the tuned one that goes through the ladders. Chosen by the tuning table (docs/peers.md).
TUNE_CELLS = 64
MUJOCO_TUNING = [
    ("joint friction, MuJoCo defaults", []),
    ("joint friction, noslip 3", ["--noslip", "3"]),
    ("joint friction, solreffriction 2 dt", ["--friction-timeconst", "2dt"]),
    ("joint friction, solreffriction 2 dt, noslip 3", ["--noslip", "3", "--friction-timeconst", "2dt"]),
    ("joint friction, solreffriction 2 dt, noslip 3, solimpfriction 0.99 0.999",
     ["--noslip", "3", "--friction-timeconst", "2dt", "--friction-solimp", "0.99,0.999,0.001"]),
    ("contact, pyramidal cone", ["--friction", "contact"]),
    ("contact, elliptic, impratio 10", ["--friction", "contact", "--cone", "elliptic", "--impratio", "10"]),
    ("contact, elliptic, impratio 100", ["--friction", "contact", "--cone", "elliptic", "--impratio", "100"]),
    ("contact, elliptic, impratio 100, noslip 3", ["--friction", "contact", "--cone", "elliptic", "--impratio",
                                                   "100", "--noslip", "3"]),
]
ELASTICA_TUNING = [
    ("kinetic only (as the snake example), slip tol 1e-4", ["--static", "off", "--slip-tol", "1e-4"]),
    ("kinetic only, slip tol 1e-6", ["--static", "off", "--slip-tol", "1e-6"]),
    ("kinetic only, slip tol 1e-8", ["--static", "off", "--slip-tol", "1e-8"]),
    ("static = kinetic, slip tol 1e-4", ["--static", "on", "--slip-tol", "1e-4"]),
    ("static = kinetic, slip tol 1e-6", ["--static", "on", "--slip-tol", "1e-6"]),
    ("static = kinetic, slip tol 1e-8", ["--static", "on", "--slip-tol", "1e-8"]),
]
MUJOCO_TUNED = ("joint friction, solreffriction 2 dt, noslip 3, Courant 1",
                ["--noslip", "3", "--friction-timeconst", "2dt", "--courant", "1"])
MUJOCO_TUNED_DT = ("joint friction, solreffriction 2 dt, noslip 3, Courant 0.5",
                   ["--noslip", "3", "--friction-timeconst", "2dt", "--courant", "0.5"])
ELASTICA_TUNED = ("static = kinetic, slip tol 1e-6, dt = 0.5 dx / c", ["--static", "on", "--slip-tol", "1e-6",
                                                                      "--dt-share", "0.5"])
ELASTICA_TUNED_DT = ("static = kinetic, slip tol 1e-6, dt = 0.25 dx / c", ["--static", "on", "--slip-tol", "1e-6",
                                                                          "--dt-share", "0.25"])

METRICS = {"static": ["velocity"], "paper": ["velocity", "power", "max_stress"],
           "stickslip": ["velocity", "power", "stuck_fraction"]}


def bin_dir(arg):
    if arg:
        return arg
    if os.environ.get("CRAWLER_BIN_DIR"):
        return os.environ["CRAWLER_BIN_DIR"]
    return os.path.join(os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target")), "release")


def scenario_toml(case, cells):
    """The case as a plant scenario. The static hold's load goes into n_F: with a uniform forward
    load b, c_v v + eps c_d (s - n_F) - b = c_v v + eps c_d (s - (n_F + b / (eps c_d)))."""
    n_f = N_F + case.load / (case.eps * C_D)
    return "\n".join([
        f'name = "peers-{case.name}"',
        "[body]", "area = 1e-4", "density = 0.1", "youngs_modulus = 140e3", f"length = {case.length!r}",
        "[friction]", "viscous = 1.0", f"dry = {C_D!r}", f"eps = {case.eps!r}", f"n_f = {n_f!r}",
        "[actuation]", f"f0 = {case.f0!r}", f"k = {case.k!r}", f"alpha = {case.alpha!r}",
        "[numerics]", f"cells = {cells}", f"t_end = {case.t_end!r}", f"settle = {case.settle!r}",
    ]) + "\n"


def ours(bins, case, cells):
    """`crawler-plant simulate --json` on the case: (report, whole-process wall time)."""
    with tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False) as f:
        f.write(scenario_toml(case, cells))
        path = f.name
    try:
        t = time.perf_counter()
        out = subprocess.run([os.path.join(bins, "crawler-plant"), "simulate", "--json", "--max-episodes", "0",
                              "--scenario", path], check=True, capture_output=True, text=True).stdout
        wall = time.perf_counter() - t
    finally:
        os.unlink(path)
    r = json.loads(out)
    r["finite"] = all(math.isfinite(r[m]) for m in ("velocity", "power", "max_stress"))
    return r, wall


def exact(bins, case):
    if case.f0 == 0:
        return {"velocity": 0.0}
    out = subprocess.run([os.path.join(bins, "crawler-controller"), "predict", "--model", "improved",
                          "--march-steps", "65536", "--eps", repr(case.eps), "--f0", repr(case.f0),
                          "--k", repr(case.k), "--alpha", repr(case.alpha), "--n-f", repr(N_F)],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)


CACHE = None  # --cache: a directory of peer results keyed by the scripts' text and the arguments


def peer(tool, case_name, cells, args, quick_mode=False, cached=True):
    script = {"mujoco": "mujoco_crawler.py", "pyelastica": "elastica_crawler.py"}[tool]
    cmd = [PY, os.path.join(HERE, script), "--case", case_name, "--cells", str(cells), *args]
    if quick_mode:
        cmd.append("--quick")
    path = None
    if CACHE and cached:
        h = hashlib.sha256()
        for f in (script, "common.py"):
            with open(os.path.join(HERE, f), "rb") as src:
                h.update(src.read())
        h.update(json.dumps(cmd[1:]).encode())
        path = os.path.join(CACHE, h.hexdigest() + ".json")
        if os.path.exists(path):
            with open(path) as f:
                return json.load(f)
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    r = json.loads(out.strip().splitlines()[-1])
    if path:
        os.makedirs(CACHE, exist_ok=True)
        with open(path, "w") as f:
            json.dump(r, f)
    return r


def expand(args, cells, case):
    """'2dt' in a MuJoCo friction time constant: twice the run's time step."""
    out = []
    for a in args:
        if a == "2dt":
            courant = float(args[args.index("--courant") + 1]) if "--courant" in args else 1.0
            a = repr(2 * courant * case.length / cells / math.sqrt(14.0 / 0.1))
        out.append(a)
    return out


def rel(x, ref):
    if x is None:
        return None
    if ref == 0:
        return x
    return x / ref - 1


def fmt_err(x, absolute=False):
    if x is None:
        return "n/a"
    return f"{x:.1e} m/s" if absolute else f"{100 * x:+.2f} %"


def machine():
    model = platform.processor() or "unknown"
    if shutil.which("lscpu"):
        for line in subprocess.run(["lscpu"], capture_output=True, text=True).stdout.splitlines():
            if line.startswith("Model name:"):
                model = line.split(":", 1)[1].strip()
    cores = os.cpu_count()
    load = os.getloadavg()
    return f"{model}, {cores} cores, load average {load[0]:.2f} at the start"


def quick_run(bins, only):
    """Every tool on every case (or on `only`), short: one JSON object on stdout (for
    tests/tests/peers.rs)."""
    results = {}
    for name, case in CASES.items():
        if only and name != only:
            continue
        q = quick(case)
        # the plant averages whole forcing periods after settle (it refuses a shorter window)
        r, wall = ours(bins, dataclasses.replace(q, settle=min(q.settle, 0.8 * q.t_end)), 32)
        results[f"ours/{name}"] = {**{k: r.get(k) for k in ("velocity", "power", "max_stress", "stuck_fraction")},
                                   "finite": r["finite"]}
        results[f"exact/{name}"] = exact(bins, case)
        for tool, (_, args) in (("mujoco", MUJOCO_TUNED), ("pyelastica", ELASTICA_TUNED)):
            results[f"{tool}/{name}"] = peer(tool, name, 32, expand(args, 32, case), quick_mode=True)
    print(json.dumps(results))


def ladder(bins, max_cells, peers_only=False):
    """Every refinement row: (tool, setting, case, cells, runner); a runner returns (result, wall)."""
    rows = []
    for name, case in CASES.items():
        static = name == "static"
        for cells in [] if peers_only else ([32, 128, 512] if static else OURS_CELLS):
            rows.append(("ours", "crawler-plant defaults (Courant 1, filter 0.1)", name, cells,
                         lambda case=case, cells=cells: ours(bins, case, cells)))
        for tool, configs in (("mujoco", ((MUJOCO_TUNED, 512), (MUJOCO_TUNED_DT, 256))),
                              ("pyelastica", ((ELASTICA_TUNED, 512), (ELASTICA_TUNED_DT, 256)))):
            for (label, args), top in configs[:1] if static else configs:
                for cells in ([32, 128] if static else [c for c in PEER_CELLS if c <= min(top, max_cells)]):
                    def run(tool=tool, name=name, cells=cells, args=args, case=case, cached=True):
                        r = peer(tool, name, cells, expand(args, cells, case), cached=cached)
                        return r, r["wall_time"]
                    rows.append((tool, label, name, cells, run))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5,
                    help="timed runs of each tool's cheapest row within 1 %% in V (median; interleaved)")
    ap.add_argument("--bin-dir", help="directory holding crawler-plant and crawler-controller")
    ap.add_argument("--out", help="also write the Markdown here")
    ap.add_argument("--json", help="write every run's raw results here")
    ap.add_argument("--max-cells", type=int, default=512, help="finest resolution of the peers' ladders")
    ap.add_argument("--quick", action="store_true", help="smoke run of every tool and case (JSON on stdout)")
    ap.add_argument("--case", choices=sorted(CASES), help="with --quick: this case only")
    ap.add_argument("--cache", help="reuse the peers' ladder and tuning results stored in this directory "
                                    "(keyed by the scripts' text and arguments; the timed runs are always fresh)")
    ap.add_argument("--peers-only", action="store_true", help="with --cache: only fill the cache with the peers' runs")
    a = ap.parse_args()
    global CACHE
    CACHE = a.cache
    if a.peers_only:
        if not a.cache:
            sys.exit("--peers-only needs --cache DIR")
        for name in ("static", "stickslip"):
            for tool, table in (("mujoco", MUJOCO_TUNING), ("pyelastica", ELASTICA_TUNING)):
                for label, args in table:
                    peer(tool, name, TUNE_CELLS, expand(args, TUNE_CELLS, CASES[name]))
        for tool, label, name, cells, runner in ladder(None, a.max_cells, peers_only=True):
            r, wall = runner()
            log(f"{tool} | {label} | {name} | {cells}: V = {r.get('velocity')} ({wall:.3f} s)")
        return
    bins = bin_dir(a.bin_dir)
    for b in ("crawler-plant", "crawler-controller"):
        if not os.access(os.path.join(bins, b), os.X_OK):
            sys.exit(f"{os.path.join(bins, b)} not found: build with `cargo build --release -p crawler-plant "
                     f"-p crawler-controller`, or pass --bin-dir / set CRAWLER_BIN_DIR")
    if a.repeats < 1:
        sys.exit(f"--repeats {a.repeats}: at least 1")
    if a.max_cells < 32:
        sys.exit(f"--max-cells {a.max_cells}: at least 32")
    if a.quick:
        quick_run(bins, a.case)
        return
    started = datetime.now(timezone.utc)
    mach = machine()
    exacts = {name: exact(bins, case) for name, case in CASES.items()}

    # 1. tuning, at TUNE_CELLS, on the friction-sensitive cases (static hold and stick-slip), once
    tuning = []
    for name in ("static", "stickslip"):
        case = CASES[name]
        for tool, table in (("mujoco", MUJOCO_TUNING), ("pyelastica", ELASTICA_TUNING)):
            for label, args in table:
                r = peer(tool, name, TUNE_CELLS, expand(args, TUNE_CELLS, case))
                tuning.append((tool, label, name, r))
                log(f"tuning {tool} | {label} | {name}: V = {r.get('velocity')}")

    # 2. the ladders, each row once (the results are deterministic)
    rows = ladder(bins, a.max_cells)
    results, walls = [], []
    for tool, label, name, cells, runner in rows:
        r, wall = runner()
        results.append(r)
        walls.append(wall)
        log(f"{tool} | {label} | {name} | {cells}: V = {r.get('velocity')} ({wall:.3f} s)")

    # 3. each tool's cheapest row from which on its setting stays within 1 % in V at every finer
    #    resolution of the ladder (a coarse row that is within 1 % by luck does not count), else its
    #    closest row; timed --repeats times, interleaved
    picks = {}
    for name in ("paper", "stickslip"):
        for tool in ("ours", "mujoco", "pyelastica"):
            cand = [i for i, row in enumerate(rows) if row[0] == tool and row[2] == name]
            err = {i: (abs(rel(results[i]["velocity"], exacts[name]["velocity"]))
                       if results[i].get("finite", True) else math.inf) for i in cand}
            settled = []
            for i in cand:
                finer = [j for j in cand if rows[j][1] == rows[i][1] and rows[j][3] >= rows[i][3]]
                if all(err[j] <= 0.01 for j in finer):
                    settled.append(i)
            if settled:
                picks[(name, tool)] = (min(settled, key=lambda i: walls[i]), True)
            elif cand:
                picks[(name, tool)] = (min(cand, key=lambda i: err[i]), False)
    timed = {key: [] for key in picks}
    for rep in range(a.repeats):
        for key, (i, _) in picks.items():
            _, wall = rows[i][4](cached=False) if rows[i][0] != "ours" else rows[i][4]()
            timed[key].append(wall)
            log(f"[{rep + 1}/{a.repeats}] {key}: {wall:.3f} s")

    md = render(a, mach, started, exacts, tuning, rows, results, walls, picks, timed)
    print(md)
    if a.out:
        with open(a.out, "w") as f:
            f.write(md)
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"machine": mach, "started": started.isoformat(), "exact": exacts,
                       "tuning": [{"tool": t, "config": l, "case": c, "result": r} for t, l, c, r in tuning],
                       "rows": [{"tool": t, "config": l, "case": c, "cells": n, "result": results[i],
                                 "wall_time": walls[i]} for i, (t, l, c, n, _) in enumerate(rows)],
                       "timed": [{"case": k[0], "tool": k[1], "row": picks[k][0], "wall_times": v}
                                 for k, v in timed.items()]}, f, indent=1)


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def render(a, mach, started, exacts, tuning, rows, results, walls, picks, timed):
    ex = exacts
    cmd = " ".join([".venv/bin/python bench/peers/run.py", *sys.argv[1:]])
    out = [f"Command: `{cmd}`; machine: {mach}; "
           f"date: {started.strftime('%Y-%m-%d %H:%M UTC')}. Every row's wall time is one run; the last table's "
           f"are medians of {a.repeats} interleaved runs."
           + (" The peers' tuning and ladder rows (their wall times too) were read from --cache, stored by earlier "
              "runs of the same scripts; the last table's runs are fresh." if a.cache else ""), "",
           f"Exact answers (improved model, 65536 march steps per period): paper's point V = "
           f"{ex['paper']['velocity']:.6e} m/s, P = {ex['paper']['power']:.6e} W, sigma = "
           f"{ex['paper']['max_stress']:.6e} Pa; stick-slip V = {ex['stickslip']['velocity']:.6e} m/s, P = "
           f"{ex['stickslip']['power']:.6e} W, stuck fraction {100 * ex['stickslip']['stuck_fraction']:.3f} %; "
           f"static hold: V = 0."]
    out += ["", f"### Tuning the peers' friction ({TUNE_CELLS} cells; MuJoCo at Courant 1, PyElastica at dt = 0.5 dx / c)",
            "", "| tool | friction setting | static hold: drift after 10 s (m/s) | stick-slip: V error | "
            "stick-slip: stuck fraction | stick-slip: stepping wall time (s) |",
            "| --- | --- | ---: | ---: | ---: | ---: |"]
    by = {(t, l, c): r for t, l, c, r in tuning}
    for tool, table in (("mujoco", MUJOCO_TUNING), ("pyelastica", ELASTICA_TUNING)):
        for label, _ in table:
            s, k = by[(tool, label, "static")], by[(tool, label, "stickslip")]
            drift = f"{s['velocity']:.2e}" if s.get("finite") else "blew up"
            if k.get("finite"):
                ve = fmt_err(rel(k["velocity"], ex["stickslip"]["velocity"]))
                st = f"{100 * k['stuck_fraction']:.1f} %"
            else:
                ve = st = "blew up"
            out.append(f"| {tool} | {label} | {drift} | {ve} | {st} | {k['wall_time']:.2f} |")

    titles = {"static": "Static hold (eps = 0.1, forward load 0.025 N/m: half the forward static band; no drive)",
              "paper": "The paper's point (eps = 0.1, f0 = 0.5 N, k = 2 pi, alpha = 1)",
              "stickslip": "Stick-slip (eps = 1, f0 = 0.2 N, k = 2 pi, alpha = 0.5)"}
    for name in CASES:
        metrics = METRICS[name]
        heads = {"velocity": "V error" if name != "static" else "drift V over 9-10 s (m/s)", "power": "P error",
                 "max_stress": "sigma error", "stuck_fraction": "stuck fraction (exact)"}
        out += ["", f"### {titles[name]}", "",
                "| tool | setting | cells | dt (s) | " + " | ".join(heads[m] for m in metrics) + " | wall time (s) |",
                "| --- | --- | ---: | ---: | " + " | ".join("---:" for _ in metrics) + " | ---: |"]
        for i, (tool, label, cname, cells, _) in enumerate(rows):
            if cname != name:
                continue
            r = results[i]
            dt = r.get("dt") or r.get("parameters", {}).get("dt")
            cols = []
            for m in metrics:
                if not r.get("finite", True):
                    cols.append("blew up")
                elif r.get(m) is None:
                    cols.append("n/a")
                elif name == "static":
                    cols.append(f"{r[m]:.2e}")
                elif m == "stuck_fraction":
                    cols.append(f"{100 * r[m]:.2f} % ({100 * ex[name][m]:.2f} %)")
                else:
                    cols.append(fmt_err(rel(r[m], ex[name][m])))
            dts = f"{dt:.2e}" if dt else "n/a"
            out.append(f"| {tool} | {label} | {cells} | {dts} | " + " | ".join(cols) + f" | {walls[i]:.3f} |")

    out += ["", f"### Time to 1 % in V (each tool's cheapest row that stays within 1 % at every finer resolution "
            f"of its setting; medians of {a.repeats} interleaved runs)",
            "", "| case | tool | setting | cells | V error | wall time (s) | ratio to ours |",
            "| --- | --- | --- | ---: | ---: | ---: | ---: |"]
    for name in ("paper", "stickslip"):
        ours_key = (name, "ours")
        ours_w = statistics.median(timed[ours_key]) if ours_key in timed and picks[ours_key][1] else None
        for tool in ("ours", "mujoco", "pyelastica"):
            if (name, tool) not in picks:
                continue
            i, ok = picks[(name, tool)]
            w = statistics.median(timed[(name, tool)])
            e = rel(results[i]["velocity"], ex[name]["velocity"])
            cells = f"{rows[i][3]}" if ok else f"never within 1 % (closest: {rows[i][3]})"
            ratio = f"{w / ours_w:.0f}x" if ours_w and ok and tool != "ours" else ("1x" if tool == "ours" else "n/a")
            out.append(f"| {name} | {tool} | {rows[i][1]} | {cells} | {fmt_err(e)} | {w:.3f} | {ratio} |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    main()
