"""Co-simulation throughput: lockstep against a bare zenoh ping-pong, with and without the bridge,
with and without authentication.

Usage: .venv/bin/python bench/cosim_bench.py [--cells 256] [--steps 20000] [--trials 3]
                                            [--policies adaptive,reflex] [--baseline DIR]
Builds the binaries it runs first (`cargo build --release`, said on stderr; a no-op when fresh).

All in one run, interleaved trial by trial so that machine noise hits every column alike:
  ping-pong   `transport/examples/pingpong.rs`: the plant's session settings (router, express,
              blocking congestion control, callback into a channel), a State-sized message out and
              an Actuation-sized message back, over loopback TCP;
  lockstep    `crawler-plant run` + `crawler-controller run --policy wave` over loopback TCP;
  + bridge    the same with `crawler-recorder record --every 1` attached (every state recorded);
  no auth     lockstep with `--no-auth` on both processes: no zenoh password, no message seals
              (every other column is authenticated, the default);
  policies    lockstep with each feedback controller of `--policies` (`adaptive`: estimator on
              every state, re-optimisation on a worker thread; `reflex`: the distributed law on
              every node) instead of the open-loop `wave`, against the lockstep column;
  baseline    with `--baseline DIR`: the lockstep of the `crawler-plant` and `crawler-controller`
              in DIR (another build, e.g. the one before a protocol change), interleaved with this
              build's lockstep trial by trial; the table gives this build's rate as a share of it.
Rates are the plant's own count (`lockstep: N steps in S s`, printed after the run). The table
gives medians over the trials, the ratios, and the recording's bytes per recorded step against
the raw field data (u and v as f64, 16 N bytes).
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

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGET = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
REL = os.path.join(TARGET, "release")
# An Actuation with a wave, as the Rust controller sends it (named-field MessagePack).
ACTUATION_BYTES = 106


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_line(path, pattern, proc, timeout=30.0):
    end = time.time() + timeout
    while time.time() < end:
        with open(path, errors="replace") as f:
            if re.search(pattern, f.read()):
                return
        if proc.poll() is not None:
            raise RuntimeError(f"process exited early; see {path}")
        time.sleep(0.02)
    raise RuntimeError(f"timed out waiting for {pattern!r} in {path}")


def pingpong(size, seconds):
    ep = f"tcp/127.0.0.1:{free_port()}"
    exe = os.path.join(REL, "examples", "pingpong")
    pong = subprocess.Popen([exe, "pong", "--endpoint", ep, "--seconds", str(seconds)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(0.3)
        out = subprocess.run([exe, "ping", "--endpoint", ep, "--size", str(size), "--reply",
                              str(ACTUATION_BYTES), "--seconds", str(seconds)],
                             check=True, capture_output=True, text=True, timeout=seconds + 60).stdout
        m = re.search(r'"per_second":([0-9.eE+-]+)', out)
        return float(m.group(1))
    finally:
        pong.kill()
        pong.wait()


def lockstep(cells, steps, bridge, work, auth=True, policy="wave", exe_dir=None):
    """Returns (steps per second, bytes per state, rrd bytes, (states recorded, of which with fields));
    the plant and the controller are those of `exe_dir` (default: this build)."""
    exe_dir = exe_dir or REL
    run = f"bench{os.getpid()}{int(time.time() * 1000) % 100000}"
    ep = f"tcp/127.0.0.1:{free_port()}"
    t_end = steps * 1e-3
    net = ["--run-id", run, "--endpoint", ep] + ([] if auth else ["--no-auth"])
    perr = os.path.join(work, f"{run}-plant.err")
    berr = os.path.join(work, f"{run}-bridge.err")
    rrd = os.path.join(work, f"{run}.rrd")
    procs = []
    try:
        plant = subprocess.Popen([os.path.join(exe_dir, "crawler-plant"), "run", *net, "--cells", str(cells),
                                  "--t-end", str(t_end)],
                                 stdout=subprocess.DEVNULL, stderr=open(perr, "w"))
        procs.append(plant)
        wait_line(perr, "waiting for a controller", plant)
        if bridge:
            b = subprocess.Popen([os.path.join(REL, "crawler-recorder"), "record", *net, "--out", rrd,
                                  "--every", "1"], stdout=subprocess.DEVNULL, stderr=open(berr, "w"))
            procs.append(b)
            wait_line(berr, "plant found", b)
        ctl = subprocess.Popen([os.path.join(exe_dir, "crawler-controller"), "run", *net, "--policy", policy],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        procs.append(ctl)
        if plant.wait(timeout=600) != 0:
            raise RuntimeError(f"plant failed; see {perr}")
        ctl.wait(timeout=60)
        with open(perr) as f:
            m = re.search(r"lockstep: (\d+) steps in ([0-9.]+) s \(\d+ steps/s, (\d+) bytes per state\)", f.read())
        rate = int(m.group(1)) / float(m.group(2))
        state_bytes = int(m.group(3))
        size = recorded = None
        if bridge:
            if procs[1].wait(timeout=60) != 0:
                raise RuntimeError(f"bridge failed; see {berr}")
            with open(berr) as f:
                r = re.search(r"(\d+) states \((\d+) with fields\)", f.read())
            recorded = (int(r.group(1)), int(r.group(2)))
            size = os.path.getsize(rrd)
            os.remove(rrd)
        return rate, state_bytes, size, recorded
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()


def build():
    print("cosim_bench: building the binaries it runs (cargo build --release; a no-op when fresh)",
          file=sys.stderr)
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "crawler-plant", "-p", "crawler-controller",
                    "-p", "crawler-recorder", "-p", "crawler-transport", "--bins", "--examples"],
                   check=True, cwd=ROOT)


def baseline_only(a):
    """This build's lockstep against the build in `a.baseline`, trial by trial, alternating order."""
    if not a.baseline:
        raise SystemExit("--baseline-only needs --baseline DIR")
    build()
    new, old = [], []
    with tempfile.TemporaryDirectory() as work:
        lockstep(a.cells, 6000, False, work)  # warm-up
        lockstep(a.cells, 6000, False, work, exe_dir=a.baseline)
        for t in range(a.trials):
            for which in ("new", "old") if t % 2 == 0 else ("old", "new"):
                if which == "new":
                    new.append(lockstep(a.cells, a.steps, False, work)[0])
                else:
                    old.append(lockstep(a.cells, a.steps, False, work, exe_dir=a.baseline)[0])
            print(f"trial {t + 1}: this build {new[-1]:.0f}/s, baseline {old[-1]:.0f}/s, "
                  f"ratio {new[-1] / old[-1]:.3f}", file=sys.stderr)
    ratios = sorted(x / y for x, y in zip(new, old))
    print(f"N = {a.cells}, {a.steps} steps per run, authenticated lockstep (wave), loopback TCP, "
          f"{a.trials} trials interleaved")
    print()
    print("| build | lockstep, steps/s (median) | range |")
    print("| --- | ---: | --- |")
    print(f"| this build | {statistics.median(new):.0f} | {min(new):.0f} to {max(new):.0f} |")
    print(f"| {a.baseline} | {statistics.median(old):.0f} | {min(old):.0f} to {max(old):.0f} |")
    print()
    print(f"per-trial ratio this build / baseline: median {statistics.median(ratios):.3f} "
          f"({ratios[0]:.3f} to {ratios[-1]:.3f}, {len(ratios)} trials)")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cells", type=int, default=256)
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--trials", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=4.0, help="duration of each ping-pong")
    ap.add_argument("--policies", default="adaptive,reflex",
                    help="feedback policies timed against wave (comma-separated; empty: none)")
    ap.add_argument("--baseline", help="a directory with another build's crawler-plant and crawler-controller "
                                       "to time side by side with this build's lockstep")
    ap.add_argument("--baseline-only", action="store_true",
                    help="time only this build's lockstep against --baseline's, interleaved (alternating which "
                         "goes first), and print their table")
    a = ap.parse_args()
    if a.baseline_only:
        return baseline_only(a)
    policies = [p for p in a.policies.split(",") if p]
    build()
    pp, bare, withb, noauth, sizes, full, base = [], [], [], [], [], [], []
    by_policy = {p: [] for p in policies}
    with tempfile.TemporaryDirectory() as work:
        _, state_bytes, _, _ = lockstep(a.cells, 6000, False, work)  # warm-up; learns the state size
        for t in range(a.trials):
            pp.append(pingpong(state_bytes, a.seconds))
            # with and without authentication back to back, in alternating order
            for auth in (True, False) if t % 2 == 0 else (False, True):
                (bare if auth else noauth).append(lockstep(a.cells, a.steps, False, work, auth=auth)[0])
            if a.baseline:
                base.append(lockstep(a.cells, a.steps, False, work, exe_dir=a.baseline)[0])
            for p in policies if t % 2 == 0 else reversed(policies):
                by_policy[p].append(lockstep(a.cells, a.steps, False, work, policy=p)[0])
            rate, _, size, recorded = lockstep(a.cells, a.steps, True, work)
            withb.append(rate)
            states, with_fields = recorded
            sizes.append(size / states)
            full.append(with_fields == states)
            print(f"trial {t + 1}: ping-pong {pp[-1]:.0f}/s, lockstep {bare[-1]:.0f}/s, "
                  f"with bridge {withb[-1]:.0f}/s, {sizes[-1]:.0f} B per state "
                  f"(fields recorded for {with_fields} of {states} states), "
                  f"lockstep without authentication {noauth[-1]:.0f}/s"
                  + "".join(f", {p} {by_policy[p][-1]:.0f}/s" for p in policies), file=sys.stderr)
    mp, mb, mw, mn, ms = (statistics.median(x) for x in (pp, bare, withb, noauth, sizes))
    raw = 16 * a.cells
    print(f"N = {a.cells}, {a.steps} steps per run, State message {state_bytes} B, "
          f"Actuation {ACTUATION_BYTES} B, medians of {a.trials} trials, loopback TCP")
    print()
    print("| | rate (steps or round trips / s) | ratio |")
    print("| --- | ---: | ---: |")
    print(f"| bare zenoh ping-pong, same payloads | {mp:.0f} | 1.00 |")
    print(f"| lockstep plant + controller | {mb:.0f} | {mb / mp:.2f} of ping-pong |")
    print(f"| lockstep + bridge recording every step | {mw:.0f} | {mw / mb:.2f} of lockstep |")
    print(f"| lockstep without authentication (--no-auth) | {mn:.0f} | "
          f"authenticated lockstep is {mb / mn:.3f} of it |")
    if a.baseline:
        mbase = statistics.median(base)
        print(f"| lockstep of the build in {a.baseline} | {mbase:.0f} | "
              f"this build's lockstep is {mb / mbase:.3f} of it |")
    for p in policies:
        mp_ = statistics.median(by_policy[p])
        print(f"| lockstep with the `{p}` controller | {mp_:.0f} | {mp_ / mb:.3f} of lockstep (`wave`) |")
    # Each trial runs the compared columns back to back, so a trial's own ratio cancels the
    # machine's slow drifts; their median is steadier than the ratio of the medians.
    print()
    print("per-trial ratios (median, range):")
    pairs = [("authenticated / --no-auth", bare, noauth)]
    if a.baseline:
        pairs.append((f"this build / {a.baseline}", bare, base))
    pairs += [(f"{p} / wave", by_policy[p], bare) for p in policies]
    for name, x, y in pairs:
        r = sorted(a / b for a, b in zip(x, y))
        print(f"  {name}: {statistics.median(r):.3f} ({r[0]:.2f} to {r[-1]:.2f}, {len(r)} trials)")
    print()
    whole = [s for s, f in zip(sizes, full) if f]
    if whole:
        mf = statistics.median(whole)
        print(f"recording: {mf:.0f} B per state in the {len(whole)} trial(s) that recorded every field; "
              f"raw u, v fields 16 N = {raw} B; ratio {mf / raw:.2f}")
    else:
        print(f"recording: {ms:.0f} B per state, but the recorder decimated the fields in every trial "
              f"(it fell behind), so there is no ratio to the raw fields")


if __name__ == "__main__":
    main()
