"""The recorder against the lockstep: side by side, two builds, interleaved trials.

Usage: .venv/bin/python recorder/bench/recorder_bench.py --before DIR --after DIR
           [--cells 512] [--t-end 10] [--trials 5] [--policy optimal]

DIR holds crawler-plant, crawler-controller and crawler-recorder of one build (`target/release`;
the `before` build is today's main). Each trial runs, back to back, in an order that alternates
from trial to trial: the lockstep of each build without a recorder, and with its recorder at
`--every 1`. A run is the plant (`crawler-plant run --cells N --t-end T`, the paper's scenario),
the controller (`--policy`) and, in the recorded runs, `crawler-recorder record --every 1`, over
loopback TCP, authenticated.

Per run: the lockstep rate (the plant's own count, `lockstep: N steps in S s`), and for the
recorder the states it recorded with their fields (its closing line), the fields recorded per
second of the lockstep, and its CPU time (user + system, from wait4) per state received. The
table gives medians over the trials and the median of each trial's own ratio (a trial's columns
run back to back, so its ratios cancel the machine's slow drifts).
"""

import argparse
import os
import re
import socket
import statistics
import subprocess
import sys
import tempfile
import time


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_line(path, pattern, proc, timeout=60.0):
    end = time.time() + timeout
    while time.time() < end:
        with open(path, errors="replace") as f:
            if re.search(pattern, f.read()):
                return
        if proc.poll() is not None:
            raise RuntimeError(f"process exited early; see {path}")
        time.sleep(0.02)
    raise RuntimeError(f"timed out waiting for {pattern!r} in {path}")


def wait_usage(proc, timeout):
    """Waits for proc; returns (exit code, CPU seconds user + system)."""
    end = time.time() + timeout
    while time.time() < end:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid == proc.pid:
            proc.returncode = os.waitstatus_to_exitcode(status)
            return proc.returncode, usage.ru_utime + usage.ru_stime
        time.sleep(0.02)
    proc.kill()
    raise RuntimeError("timed out")


def run(bins, a, record, work):
    """One run; returns a dict of what it measured."""
    rid = f"rb{os.getpid()}{int(time.time() * 1000) % 1000000}"
    net = ["--run-id", rid, "--endpoint", f"tcp/127.0.0.1:{free_port()}"]
    perr, berr = (os.path.join(work, f"{rid}-{p}.err") for p in ("plant", "bridge"))
    rrd = os.path.join(work, f"{rid}.rrd")
    procs = []
    try:
        plant = subprocess.Popen([os.path.join(bins, "crawler-plant"), "run", *net, "--cells", str(a.cells),
                                  "--t-end", str(a.t_end)],
                                 stdout=subprocess.DEVNULL, stderr=open(perr, "w"))
        procs.append(plant)
        wait_line(perr, "waiting for a controller", plant)
        if record:
            bridge = subprocess.Popen([os.path.join(bins, "crawler-recorder"), "record", *net, "--out", rrd,
                                       "--every", "1"], stdout=subprocess.DEVNULL, stderr=open(berr, "w"))
            procs.append(bridge)
            wait_line(berr, "plant found", bridge)
        ctl = subprocess.Popen([os.path.join(bins, "crawler-controller"), "run", *net, "--policy", a.policy],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        procs.append(ctl)
        if plant.wait(timeout=1200) != 0:
            raise RuntimeError(f"plant failed; see {perr}")
        ctl.wait(timeout=60)
        with open(perr) as f:
            m = re.search(r"lockstep: (\d+) steps in ([0-9.]+) s", f.read())
        steps, seconds = int(m.group(1)), float(m.group(2))
        out = {"rate": steps / seconds}
        if record:
            code, cpu = wait_usage(procs[1], 600)
            if code != 0:
                raise RuntimeError(f"bridge failed; see {berr}")
            with open(berr) as f:
                said = f.read()
            r = re.search(r"(\d+) states \((\d+) with fields\)", said)
            states, fields = int(r.group(1)), int(r.group(2))
            out.update(states=states, fields=fields, cpu_per_state=cpu / states,
                       fields_per_s=fields / seconds, size=os.path.getsize(rrd))
            os.remove(rrd)
        return out
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", required=True, help="bin directory of the build before")
    ap.add_argument("--after", required=True, help="bin directory of the build after")
    ap.add_argument("--cells", type=int, default=512)
    ap.add_argument("--t-end", type=float, default=10.0)
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--policy", default="optimal")
    a = ap.parse_args()
    builds = {"before": a.before, "after": a.after}
    results = {(b, r): [] for b in builds for r in (False, True)}
    with tempfile.TemporaryDirectory() as work:
        for t in range(a.trials):
            order = [(b, r) for b in builds for r in (False, True)]
            if t % 2:
                order.reverse()
            for b, r in order:
                results[(b, r)].append(run(builds[b], a, r, work))
            line = ", ".join(
                f"{b}{' + recorder' if r else ''} {results[(b, r)][-1]['rate']:.0f}/s"
                + (f" ({results[(b, r)][-1]['fields']}/{results[(b, r)][-1]['states']} with fields, "
                   f"{1e6 * results[(b, r)][-1]['cpu_per_state']:.0f} us CPU/state)" if r else "")
                for b, r in order)
            print(f"trial {t + 1}: {line}", file=sys.stderr)

    def med(b, r, key):
        return statistics.median(x[key] for x in results[(b, r)])

    def ratio(x, y, key):
        rs = sorted(p[key] / q[key] for p, q in zip(x, y))
        return statistics.median(rs), rs[0], rs[-1]

    print(f"N = {a.cells}, t_end = {a.t_end} s, --policy {a.policy}, --every 1, "
          f"medians of {a.trials} interleaved trials")
    print()
    print("| | before | after | after / before |")
    print("| --- | ---: | ---: | ---: |")
    for label, key, fmt in [("lockstep, steps/s", "rate", "{:.0f}")]:
        for r in (False, True):
            x, y = med("before", r, key), med("after", r, key)
            print(f"| {label}{' with the recorder' if r else ''} | {fmt.format(x)} | {fmt.format(y)} | "
                  f"{y / x:.2f} |")
    for label, key, scale, fmt in [("states recorded with their fields, share", None, 1, "{:.3f}"),
                                   ("fields recorded per second (states with fields / s)", "fields_per_s", 1,
                                    "{:.0f}"),
                                   ("recorder CPU time per state, us", "cpu_per_state", 1e6, "{:.1f}"),
                                   ("recording, bytes per state", None, 1, "{:.0f}")]:
        if key is None and label.startswith("states"):
            vals = [statistics.median(x["fields"] / x["states"] for x in results[(b, True)]) for b in builds]
        elif key is None:
            vals = [statistics.median(x["size"] / x["states"] for x in results[(b, True)]) for b in builds]
        else:
            vals = [scale * med(b, True, key) for b in builds]
        print(f"| {label} | {fmt.format(vals[0])} | {fmt.format(vals[1])} | {vals[1] / vals[0]:.2f} |")
    print()
    print("per-trial ratios (median, range):")
    for b in builds:
        m, lo, hi = ratio(results[(b, True)], results[(b, False)], "rate")
        print(f"  {b}: lockstep with the recorder / without: {m:.3f} ({lo:.2f} to {hi:.2f})")
    m, lo, hi = ratio(results[("before", True)], results[("after", True)], "cpu_per_state")
    print(f"  recorder CPU per state, before / after: {m:.2f}x ({lo:.2f} to {hi:.2f})")


if __name__ == "__main__":
    main()
