"""Long run: 10^6 lockstep steps with the bridge attached; resident memory of every process.

Usage: .venv/bin/python bench/long_run.py [--steps 1000000] [--cells 256] [--every 1] [--keep]

Starts plant, bridge (recording every `--every`-th step) and the `wave` controller over a unix
socket, samples VmRSS of the three processes from /proc once a second, and prints the RSS after
the first 10 % of the steps (warm: every buffer has reached its working size) against the largest
RSS seen after that, per process. Growth below 10 % means flat memory. The recording is deleted
afterwards unless `--keep` is given (at N = 256 and --every 1 it is about 6 GB).
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGET = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
REL = os.path.join(TARGET, "release")


def rss_kib(pid):
    try:
        with open(f"/proc/{pid}/status") as f:
            m = re.search(r"VmRSS:\s+(\d+) kB", f.read())
            return int(m.group(1)) if m else None
    except OSError:
        return None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=1_000_000)
    ap.add_argument("--cells", type=int, default=256)
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--keep", action="store_true")
    a = ap.parse_args()
    print("long_run: building plant, controller and bridge (cargo build --release) ...", file=sys.stderr)
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "crawler-plant", "-p", "crawler-controller",
                    "-p", "crawler-recorder"], check=True, cwd=ROOT)
    work = tempfile.mkdtemp(prefix="crawler-long-")
    run = f"long{os.getpid()}"
    net = ["--run-id", run, "--endpoint", f"unixsock-stream/{work}/run.sock"]
    rrd = os.path.join(work, "long.rrd")
    errs = {r: open(os.path.join(work, f"{r}.err"), "w+") for r in ("plant", "bridge", "controller")}
    procs = {}
    samples = {r: [] for r in errs}  # (seconds since the controller started, KiB)
    try:
        procs["plant"] = subprocess.Popen(
            [os.path.join(REL, "crawler-plant"), "run", *net, "--cells", str(a.cells),
             "--t-end", str(a.steps * 1e-3), "--wait-timeout", "120"],
            stdout=subprocess.DEVNULL, stderr=errs["plant"])
        procs["bridge"] = subprocess.Popen(
            [os.path.join(REL, "crawler-recorder"), "record", *net, "--out", rrd, "--every", str(a.every),
             "--no-footer"],  # flat memory: the footer's index grows with the run
            stdout=subprocess.DEVNULL, stderr=errs["bridge"])
        deadline = time.time() + 60
        while "plant found" not in open(errs["bridge"].name).read():
            if time.time() > deadline:
                raise RuntimeError("the bridge did not find the plant")
            time.sleep(0.05)
        procs["controller"] = subprocess.Popen(
            [os.path.join(REL, "crawler-controller"), "run", *net, "--policy", "wave"],
            stdout=subprocess.DEVNULL, stderr=errs["controller"])
        t0 = time.time()
        while procs["plant"].poll() is None:
            now = time.time() - t0
            for r, p in procs.items():
                k = rss_kib(p.pid)
                if k is not None and p.poll() is None:
                    samples[r].append((now, k))
            time.sleep(1.0)
        wall = time.time() - t0
        for r in ("controller", "bridge"):
            procs[r].wait(timeout=120)
        codes = {r: p.returncode for r, p in procs.items()}
        size = os.path.getsize(rrd) if os.path.exists(rrd) else 0
        errs["plant"].seek(0)
        lock = re.search(r"lockstep: .*", errs["plant"].read())
        errs["bridge"].seek(0)
        btail = errs["bridge"].read().strip().splitlines()[-1:]
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.kill()
                p.wait()
        if not a.keep and os.path.exists(rrd):
            os.remove(rrd)
    print(f"{a.steps} steps at N = {a.cells}, bridge --every {a.every}: {wall:.0f} s wall, exit codes {codes}")
    print(f"plant: {lock.group(0) if lock else '?'}")
    print(f"bridge: {btail[0] if btail else '?'}; recording {size / 1e9:.2f} GB"
          + (f" kept at {rrd}" if a.keep else " (deleted)"))
    print()
    print("| process | RSS at 10 % of the run (MiB) | largest RSS after that (MiB) | growth |")
    print("| --- | ---: | ---: | ---: |")
    for r, s in samples.items():
        if len(s) < 3:
            print(f"| {r} | too few samples | | |")
            continue
        warm = wall * 0.1
        base = next(k for t, k in s if t >= warm)
        peak = max(k for t, k in s if t >= warm)
        print(f"| {r} | {base / 1024:.1f} | {peak / 1024:.1f} | {100 * (peak - base) / base:+.1f} % |")
    print()
    print("RSS (MiB) at each tenth of the run:")
    for r, s in samples.items():
        row = []
        for i in range(1, 11):
            near = [k for t, k in s if t <= wall * i / 10]
            row.append(f"{near[-1] / 1024:.0f}" if near else "-")
        print(f"  {r:<10} " + " ".join(f"{x:>5}" for x in row))
    if any(c != 0 for c in codes.values()):
        sys.exit(f"a process failed; logs in {work}")


if __name__ == "__main__":
    main()
