#!/usr/bin/env python3
"""A crawler controller written in Python: it drives the plant with a travelling wave.

It needs only the `eclipse-zenoh` and `msgpack` packages (pinned in requirements.txt) and speaks
the wire protocol described in docs/protocol.md:

1. it asks the plant for its description (`crawler/<run>/model`), retrying until the plant exists;
2. it joins the run by declaring its liveliness token `crawler/<run>/alive/controller/<id>`;
3. it answers every `State(n)` on `crawler/<run>/state` with `Actuation(n)` on
   `crawler/<run>/actuation`, until the state marked `last`.

Like every process of the project it opens zenoh loopback-only: no multicast scouting, a listener
on 127.0.0.1 only, and an explicit connection to the run's endpoint.

    .venv/bin/python examples/python_controller.py --run-id demo --alpha 0.5
"""

import argparse
import json
import math
import queue
import secrets
import sys
import tempfile
import threading
import time

import msgpack
import zenoh

PROTOCOL_VERSION = 1


def loopback_config(endpoint):
    """Peer mode, loopback only, no multicast, retrying the connection until the plant listens."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("connect/exit_on_failure", "false")
    conf.insert_json5("connect/timeout_ms", "-1")
    conf.insert_json5("scouting/multicast/enabled", "false")
    return conf


def model_info(session, base, timeout):
    """The plant's ModelInfo, retried until the plant answers or `timeout` seconds pass."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for reply in session.get(f"{base}/model", timeout=0.5):
            if reply.ok is not None:
                info = msgpack.unpackb(reply.ok.payload.to_bytes())
                if info.get("v") == PROTOCOL_VERSION:
                    return info
        time.sleep(0.2)
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--run-id", default="default")
    ap.add_argument("--endpoint", help="the run's endpoint (default: unixsock-stream/<tmp>/crawler-<run-id>.sock)")
    ap.add_argument("--f0", type=float, default=0.5, help="wave amplitude, N")
    ap.add_argument("--k", type=float, help="wave number, rad/m (default: one wavelength per body)")
    group = ap.add_mutually_exclusive_group()
    group.add_argument("--omega", type=float, help="angular frequency, rad/s")
    group.add_argument("--alpha", type=float, default=1.0, help="omega / omega_n (default 1: resonance)")
    ap.add_argument("--wait-timeout", type=float, default=60.0)
    args = ap.parse_args()

    endpoint = args.endpoint or f"unixsock-stream/{tempfile.gettempdir()}/crawler-{args.run_id}.sock"
    base = f"crawler/{args.run_id}"
    my_id = secrets.token_hex(8)
    session = zenoh.open(loopback_config(endpoint))

    print(f"python-controller: waiting for the plant of run {args.run_id} at {endpoint}", file=sys.stderr)
    info = model_info(session, base, args.wait_timeout)
    if info is None:
        print("python-controller: no plant answered", file=sys.stderr)
        return 4

    # The same arithmetic as the Rust policies, so the same bits: c = sqrt((A_c E) / rho).
    c = math.sqrt(info["area"] * info["youngs_modulus"] / info["density"])
    k = args.k if args.k is not None else 2.0 * math.pi / info["length"]
    omega = args.omega if args.omega is not None else args.alpha * (k * c)
    wave = {"f0": args.f0, "k": k, "omega": omega, "phase": 0.0}
    print(f"python-controller: plant has {info['cells']} cells; wave {wave}", file=sys.stderr)

    states = queue.Queue()
    plant_gone = threading.Event()
    sub = session.declare_subscriber(f"{base}/state", lambda s: states.put(s.payload.to_bytes()))
    live = session.liveliness().declare_subscriber(
        f"{base}/alive/plant/*", lambda s: plant_gone.set() if s.kind == zenoh.SampleKind.DELETE else None
    )
    pub = session.declare_publisher(
        f"{base}/actuation", congestion_control=zenoh.CongestionControl.BLOCK, express=True
    )
    token = session.liveliness().declare_token(f"{base}/alive/controller/{my_id}")

    answered, code = 0, 0
    while True:
        try:
            payload = states.get(timeout=1.0)
        except queue.Empty:
            if plant_gone.is_set():
                print("python-controller: the plant left the run", file=sys.stderr)
                code = 3
                break
            continue
        try:
            state = msgpack.unpackb(payload)
        except Exception as e:  # a malformed message on the state key: ignore it
            print(f"python-controller: ignoring an invalid state: {e}", file=sys.stderr)
            continue
        if not isinstance(state, dict) or state.get("v") != PROTOCOL_VERSION:
            continue
        if state.get("controller") != my_id:
            if state.get("controller"):
                print(f"python-controller: the run already has controller {state['controller']}", file=sys.stderr)
                code = 1
                break
            continue
        if state.get("last"):
            break
        actuation = {"v": PROTOCOL_VERSION, "step": state["step"], "controller": my_id, "wave": wave, "field": None}
        pub.put(msgpack.packb(actuation))
        answered += 1

    print(f"python-controller: answered {answered} steps", file=sys.stderr)
    token.undeclare()
    sub.undeclare()
    live.undeclare()
    session.close()
    return code


if __name__ == "__main__":
    sys.exit(main())
