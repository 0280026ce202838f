#!/usr/bin/env python3
"""A feedback controller in Python: the travelling wave plus a proportional stick reflex.

The counterpart of python_controller.py that closes the loop: every step it reads the plant's
stuck mask from the state and answers with a muscle-force field (one value per cell),

    m_i = f0 sin(k x_i - omega t) + gain f0 (stuck[i + 1] - stuck[i])

at the cell faces x_i = (i + 1/2) dx, t in the middle of the step. Face i lies between node i
(behind) and node i + 1 (ahead): a face contracts when the node ahead of it is anchored by static
friction and extends when the node behind it is, which loads every anchor backwards, the
direction in which static friction holds most (the earthworm's anchor-and-push). Same protocol,
same loopback-only zenoh session as python_controller.py (see there).

    .venv/bin/python examples/python_reflex_controller.py --run-id demo --f0 0.2 --alpha 0.5 --gain 0.5
"""

import argparse
import math
import os
import queue
import secrets
import sys
import threading

import msgpack
import zenoh

from python_controller import (
    PROTOCOL_VERSION,
    Credential,
    loopback_config,
    model_info,
    run_dir,
    seal,
    state_inbox,
    wait_for,
)


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
    ap.add_argument("--run-id", default="default")
    ap.add_argument("--endpoint", help="the run's endpoint (default: the unix socket in the run's private directory)")
    ap.add_argument("--credential", help="the run's credential (default: in the run's private directory)")
    ap.add_argument("--no-auth", action="store_true", help="join a plant started with --no-auth")
    ap.add_argument("--f0", type=float, default=0.2, help="wave amplitude, N")
    ap.add_argument("--alpha", type=float, default=0.5, help="omega / omega_n")
    ap.add_argument("--gain", type=float, default=0.5, help="stick reflex, a share of f0")
    ap.add_argument("--wait-timeout", type=float, default=60.0)
    args = ap.parse_args()

    endpoint = args.endpoint or f"unixsock-stream/{run_dir(args.run_id)}/zenoh.sock"
    base = f"crawler/{args.run_id}"
    my_id = secrets.token_hex(8)
    key, password = None, None
    if not args.no_auth:
        # the run's credential, as in python_controller.py (docs/security.md)
        path = args.credential or os.path.join(run_dir(args.run_id), "credential")
        if not wait_for(path, args.wait_timeout):
            print(f"python-reflex: no credential {path} (is the plant running?)", file=sys.stderr)
            return 4
        cred = Credential(path, args.run_id)
        key, password = cred.message_key(), cred.transport_password()
    session = zenoh.open(loopback_config(endpoint, password))
    info = model_info(session, base, key, args.wait_timeout)
    if info is None:
        print("python-reflex: no plant answered", file=sys.stderr)
        return 4
    if info.get("boundary") != "periodic":
        print("python-reflex: this example drives a periodic body", file=sys.stderr)
        return 1
    k = 2.0 * math.pi / info["length"]
    omega = args.alpha * (k * math.sqrt(info["area"] * info["youngs_modulus"] / info["density"]))

    states, sub = state_inbox(session, base, key, info["cells"])
    plant_gone = threading.Event()
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
            state = msgpack.unpackb(states.get(timeout=1.0))
        except queue.Empty:
            if plant_gone.is_set():
                code = 3
                break
            continue
        except Exception:  # a malformed message on the state key: ignore it
            continue
        if not isinstance(state, dict) or state.get("v") != PROTOCOL_VERSION or state.get("controller") != my_id:
            continue
        if state.get("last"):
            break
        field = reflex_field(state, info, args.f0, k, omega, args.gain)
        payload = msgpack.packb({"v": PROTOCOL_VERSION, "step": state["step"], "controller": my_id, "wave": None, "field": field})
        if key is None:
            pub.put(payload)
        else:
            pub.put(payload, attachment=seal(key, f"{base}/actuation", payload))
        answered += 1

    print(f"python-reflex: answered {answered} steps", file=sys.stderr)
    token.undeclare()
    sub.undeclare()
    live.undeclare()
    session.close()
    return code


if __name__ == "__main__":
    sys.exit(main())
