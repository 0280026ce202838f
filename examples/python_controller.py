#!/usr/bin/env python3
"""A crawler controller written in Python: it drives the plant with a travelling wave.

It needs only the `eclipse-zenoh` and `msgpack` packages (pinned in requirements.txt) and speaks
the wire protocol described in docs/protocol.md:

1. it asks the plant for its description (`crawler/<run>/model`), retrying until the plant exists;
2. it joins the run by declaring its liveliness token `crawler/<run>/alive/controller/<id>`;
3. it answers every `State(n)` on `crawler/<run>/state` with `Actuation(n)` on
   `crawler/<run>/actuation`, until the state marked `last`.

Like every process of the project it opens zenoh loopback-only: no multicast scouting, no
listener, and an explicit connection to the run's endpoint. And like them it authenticates
(docs/security.md): it reads the run's credential (mode 0600, in the run's private directory),
presents the zenoh password derived from it, seals its actuation (HMAC-SHA256 in the sample's
attachment) and believes only sealed states and model descriptions. `--no-auth` joins a plant
started with `--no-auth`.

    .venv/bin/python examples/python_controller.py --run-id demo --alpha 0.5
"""

import argparse
import hashlib
import hmac
import json
import math
import os
import queue
import secrets
import stat
import struct
import sys
import tempfile
import threading
import time

import msgpack
import zenoh

PROTOCOL_VERSION = 2


def run_dir(run_id):
    """The run's private directory, as the Rust programs compute it."""
    xdg = os.environ.get("XDG_RUNTIME_DIR")
    if xdg and os.path.isabs(xdg):
        return os.path.join(xdg, "crawler", run_id)
    return os.path.join(tempfile.gettempdir(), f"crawler-{os.geteuid()}", run_id)


class Credential:
    """The run's credential file and the two keys derived from its secret."""

    def __init__(self, path, run_id):
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
        try:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode) or st.st_uid != os.geteuid() or st.st_mode & 0o077:
                raise ValueError(f"{path} must be a regular file of this user with mode 0600")
            lines = os.read(fd, 4096).decode().splitlines()
        finally:
            os.close(fd)
        if len(lines) < 3 or lines[0] != "crawler-credential 1" or lines[1] != f"run {run_id}":
            raise ValueError(f"{path} is not a credential of run {run_id}")
        self.run = run_id
        self.secret = bytes.fromhex(lines[2].removeprefix("secret "))

    def derive(self, label):
        return hmac.new(self.secret, label.encode() + b"\0" + self.run.encode(), hashlib.sha256).digest()

    def transport_password(self):
        return self.derive("crawler transport password 1").hex()

    def message_key(self):
        return self.derive("crawler message key 1")


def seal(key, key_expr, payload):
    """HMAC-SHA256 over the key expression (length-prefixed) and the payload."""
    k = key_expr.encode()
    return hmac.new(key, b"crawler seal 1\0" + struct.pack("<Q", len(k)) + k + payload, hashlib.sha256).digest()


def sealed(key, sample_or_reply):
    """The payload if it carries a valid seal of this run (any payload when `key` is None)."""
    payload = sample_or_reply.payload.to_bytes()
    if key is None:
        return payload
    att = sample_or_reply.attachment
    if att is None:
        return None
    expected = seal(key, str(sample_or_reply.key_expr), payload)
    return payload if hmac.compare_digest(expected, att.to_bytes()) else None


def loopback_config(endpoint, password):
    """Peer mode, loopback only, no listener, no multicast, retrying the connection until the
    plant listens; the run's zenoh password when authenticated."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("connect/exit_on_failure", "false")
    conf.insert_json5("connect/timeout_ms", "-1")
    conf.insert_json5("scouting/multicast/enabled", "false")
    if password is not None:
        conf.insert_json5("transport/auth/usrpwd/user", '"crawler"')
        conf.insert_json5("transport/auth/usrpwd/password", json.dumps(password))
    return conf


def model_info(session, base, key, timeout):
    """The plant's (sealed) ModelInfo, retried until the plant answers or `timeout` s pass."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for reply in session.get(f"{base}/model", timeout=0.5):
            if reply.ok is not None:
                payload = sealed(key, reply.ok)
                if payload is None:
                    continue
                info = msgpack.unpackb(payload)
                if info.get("v") == PROTOCOL_VERSION:
                    return info
        time.sleep(0.2)
    return None


def wait_for(path, timeout):
    deadline = time.monotonic() + timeout
    while not os.path.exists(path):
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.1)
    return True


def state_inbox(session, base, key, cells):
    """The plant's states, checked at arrival, in a bounded queue; and the subscriber filling it."""
    states = queue.Queue(maxsize=64)  # bounded: a flood is dropped, not queued
    max_state = 37 * cells + 512  # RunLimits::state: u, vel, tension, stuck and the applied field

    def on_state(sample):
        # size first, then the seal: only the run's plant can have sent it
        if len(sample.payload) <= max_state:
            payload = sealed(key, sample)
            if payload is not None:
                try:
                    states.put_nowait(payload)
                except queue.Full:
                    pass

    return states, session.declare_subscriber(f"{base}/state", on_state)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--run-id", default="default")
    ap.add_argument("--endpoint", help="the run's endpoint (default: the unix socket in the run's private directory)")
    ap.add_argument("--credential", help="the run's credential (default: in the run's private directory)")
    ap.add_argument("--no-auth", action="store_true", help="join a plant started with --no-auth")
    ap.add_argument("--f0", type=float, default=0.5, help="wave amplitude, N")
    ap.add_argument("--k", type=float, help="wave number, rad/m (default: one wavelength per body)")
    group = ap.add_mutually_exclusive_group()
    group.add_argument("--omega", type=float, help="angular frequency, rad/s")
    group.add_argument("--alpha", type=float, default=1.0, help="omega / omega_n (default 1: resonance)")
    ap.add_argument("--wait-timeout", type=float, default=60.0)
    args = ap.parse_args()

    endpoint = args.endpoint or f"unixsock-stream/{run_dir(args.run_id)}/zenoh.sock"
    base = f"crawler/{args.run_id}"
    my_id = secrets.token_hex(8)
    key, password = None, None
    if not args.no_auth:
        path = args.credential or os.path.join(run_dir(args.run_id), "credential")
        if not wait_for(path, args.wait_timeout):
            print(f"python-controller: no credential {path} (is the plant running?)", file=sys.stderr)
            return 4
        cred = Credential(path, args.run_id)
        key, password = cred.message_key(), cred.transport_password()
    session = zenoh.open(loopback_config(endpoint, password))

    print(f"python-controller: waiting for the plant of run {args.run_id} at {endpoint}", file=sys.stderr)
    info = model_info(session, base, key, args.wait_timeout)
    if info is None:
        print("python-controller: no plant answered", file=sys.stderr)
        return 4

    # The same arithmetic as the Rust policies, so the same bits: c = sqrt((A_c E) / rho).
    c = math.sqrt(info["area"] * info["youngs_modulus"] / info["density"])
    k = args.k if args.k is not None else 2.0 * math.pi / info["length"]
    omega = args.omega if args.omega is not None else args.alpha * (k * c)
    wave = {"f0": args.f0, "k": k, "omega": omega, "phase": 0.0}
    print(f"python-controller: plant has {info['cells']} cells; wave {wave}", file=sys.stderr)

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
        payload = msgpack.packb(actuation)
        if key is None:
            pub.put(payload)
        else:
            pub.put(payload, attachment=seal(key, f"{base}/actuation", payload))
        answered += 1

    print(f"python-controller: answered {answered} steps", file=sys.stderr)
    token.undeclare()
    sub.undeclare()
    live.undeclare()
    session.close()
    return code


if __name__ == "__main__":
    sys.exit(main())
