#!/usr/bin/env python3
"""A crawler controller written in Python: it drives the plant with a travelling wave.

It needs only the `eclipse-zenoh` and `msgpack` packages (pinned in requirements.txt) and speaks
the wire protocol described in docs/protocol.md:

1. it asks the plant for its description (`crawler/<run>/model`) with a fresh random challenge,
   retrying until the plant exists, and believes only the answer that echoes the challenge (and,
   in an authenticated run, is sealed): it names the plant and the run instance;
2. it asks to join (a `Join` on `crawler/<run>/join`, again every 0.5 s) until the plant's
   states are addressed to it;
3. it answers every `State(n)` on `crawler/<run>/state` with `Actuation(n)` on
   `crawler/<run>/actuation`, each step once, until the state marked `last`.

Every message travels with an envelope in its attachment: the run instance, the sender's role
and id, and a sequence number per key (docs/protocol.md, "Envelope"); it takes a message only if
it is newer than the last one from its sender, so a replay is never acted on, and answers a
state the plant resent (no answer reached it in time) with the same actuation again.

Like every process of the project it opens zenoh loopback-only: no multicast scouting, no
listener, and an explicit connection to the run's endpoint. And like them it authenticates
(docs/security.md): it reads the run's credential (mode 0600, in the run's private directory),
presents the zenoh password derived from it, and seals its messages (HMAC-SHA256 over the key,
the envelope and the payload, in the attachment after the envelope). `--no-auth` joins a plant
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

PROTOCOL_VERSION = 3
# version, role, run instance (16 bytes), sender id (16 hex digits), sequence number (LE u64)
HEADER = struct.Struct("<BB16s16sQ")
CHALLENGE_LEN = 16
SEAL_LEN = 32


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


def seal(key, key_expr, meta, payload):
    """HMAC-SHA256 over the key expression and the envelope (each length-prefixed) and the payload."""
    k = key_expr.encode()
    data = b"crawler seal 3\0" + struct.pack("<Q", len(k)) + k + struct.pack("<Q", len(meta)) + meta + payload
    return hmac.new(key, data, hashlib.sha256).digest()


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


def wait_for(path, timeout):
    deadline = time.monotonic() + timeout
    while not os.path.exists(path):
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.1)
    return True


def common_arguments(ap):
    ap.add_argument("--run-id", default="default")
    ap.add_argument("--endpoint", help="the run's endpoint (default: the unix socket in the run's private directory)")
    ap.add_argument("--credential", help="the run's credential (default: in the run's private directory)")
    ap.add_argument("--no-auth", action="store_true", help="join a plant started with --no-auth")
    ap.add_argument("--take-over", action="store_true",
                    help="take the run over from its controller at the next step (instead of joining a run without one)")
    ap.add_argument("--wait-timeout", type=float, default=60.0)


class Participant:
    """This controller in a run: its session, its envelopes and seals, and what it believes (the
    plant that answered its challenge, the run instance, the last message taken from it)."""

    def __init__(self, args, name):
        self.name = name
        self.base = f"crawler/{args.run_id}"
        self.my_id = secrets.token_hex(8)  # 16 lowercase hex digits
        self.key, password = None, None
        endpoint = args.endpoint or f"unixsock-stream/{run_dir(args.run_id)}/zenoh.sock"
        if not args.no_auth:
            path = args.credential or os.path.join(run_dir(args.run_id), "credential")
            if not wait_for(path, args.wait_timeout):
                raise SystemExit(f"{name}: no credential {path} (is the plant running?)")
            cred = Credential(path, args.run_id)
            self.key, password = cred.message_key(), cred.transport_password()
        print(f"{name}: waiting for the plant of run {args.run_id} at {endpoint}", file=sys.stderr)
        self.session = zenoh.open(loopback_config(endpoint, password))
        self.nonce = None
        self.plant = None
        self.seq = {}
        self.lock = threading.Lock()

    def envelope(self, key_expr, payload):
        """The attachment of `payload` on `key_expr`: the header with the next sequence number of
        the key, and the seal."""
        with self.lock:
            self.seq[key_expr] = self.seq.get(key_expr, 0) + 1
            seq = self.seq[key_expr]
        meta = HEADER.pack(PROTOCOL_VERSION, ord("c"), self.nonce, self.my_id.encode(), seq)
        return meta if self.key is None else meta + seal(self.key, key_expr, meta, payload)

    def opened(self, key_expr, payload, attachment, extra=0):
        """The header fields and the `extra` bytes after them if the envelope is well formed and
        sealed (any well-formed one when unauthenticated); else None."""
        if attachment is None:
            return None
        att = attachment.to_bytes()
        meta_len = HEADER.size + extra
        if len(att) != meta_len + (0 if self.key is None else SEAL_LEN):
            return None
        meta, tag = att[:meta_len], att[meta_len:]
        if self.key is not None and not hmac.compare_digest(seal(self.key, key_expr, meta, payload), tag):
            return None
        version, role, nonce, sender, seq = HEADER.unpack(meta[: HEADER.size])
        if version != PROTOCOL_VERSION:
            return None
        return chr(role), nonce, sender.decode("ascii", "replace"), seq, meta[HEADER.size:]

    def discover(self, timeout):
        """The plant's ModelInfo from the answer that echoes a fresh challenge; learns the plant's
        id and the run instance from it. Retried until the plant answers or `timeout` s pass."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            challenge = secrets.token_bytes(CHALLENGE_LEN)
            replies = self.session.get(
                f"{self.base}/model",
                payload=challenge,
                target=zenoh.QueryTarget.ALL,
                consolidation=zenoh.ConsolidationMode.NONE,  # look at every answer: a rival cannot hide the plant's
                timeout=0.5,
            )
            for reply in replies:
                if reply.ok is None:
                    continue
                sample = reply.ok
                payload = sample.payload.to_bytes()
                opened = self.opened(str(sample.key_expr), payload, sample.attachment, CHALLENGE_LEN)
                if opened is None:
                    continue
                role, nonce, sender, _, echoed = opened
                if role != "p" or echoed != challenge:
                    continue
                info = msgpack.unpackb(payload)
                if isinstance(info, dict) and info.get("v") == PROTOCOL_VERSION:
                    self.nonce, self.plant = nonce, sender
                    return info
            time.sleep(0.2)
        return None

    def states(self, cells):
        """The plant's states that pass the arrival checks, in a bounded queue (and the
        subscriber filling it): of legal size, sealed, of this run instance, from the plant,
        each newer than the last taken."""
        states = queue.Queue(maxsize=64)  # bounded: a flood is dropped, not queued
        max_state = 37 * cells + 512  # RunLimits::state: u, vel, tension, stuck and the applied field
        key_expr = f"{self.base}/state"
        last = [0]

        def on_state(sample):
            payload = sample.payload.to_bytes()
            if len(payload) > max_state:
                return
            opened = self.opened(str(sample.key_expr), payload, sample.attachment)
            if opened is None:
                return
            role, nonce, sender, seq, _ = opened
            if role != "p" or nonce != self.nonce or sender != self.plant or seq <= last[0]:
                return  # not this run's plant, or a replay
            last[0] = seq
            try:
                states.put_nowait(payload)
            except queue.Full:
                pass

        return states, self.session.declare_subscriber(key_expr, on_state)

    def publisher(self, leaf):
        key_expr = f"{self.base}/{leaf}"
        pub = self.session.declare_publisher(key_expr, congestion_control=zenoh.CongestionControl.BLOCK, express=True)

        def put(payload):
            pub.put(payload, attachment=self.envelope(key_expr, payload))

        return put


def control(args, name, policy, act):
    """Joins the run (or takes it over with --take-over) and answers every state addressed to this
    controller with `act(state, info)`, a dict with `wave` and `field`, each step once. Returns
    the process's exit code."""
    p = Participant(args, name)
    info = p.discover(args.wait_timeout)
    if info is None:
        print(f"{name}: no plant answered", file=sys.stderr)
        return 4
    print(f"{name}: plant {p.plant} has {info['cells']} cells", file=sys.stderr)
    states, sub = p.states(info["cells"])
    plant_gone = threading.Event()
    live = p.session.liveliness().declare_subscriber(
        f"{p.base}/alive/plant/{p.plant}",
        lambda s: plant_gone.set() if s.kind == zenoh.SampleKind.DELETE else None,
    )
    actuate = p.publisher("actuation")
    ask = p.publisher("join")
    token = p.session.liveliness().declare_token(f"{p.base}/alive/controller/{p.my_id}")
    join = msgpack.packb({"v": PROTOCOL_VERSION, "controller": p.my_id, "policy": policy,
                          "take_over": 0 if args.take_over else None})
    ask(join)
    next_join = time.monotonic() + 0.5

    answered, answer, count, code = None, None, 0, 0
    while True:
        if answered is None and time.monotonic() >= next_join:
            ask(join)  # until the plant's states are addressed to this controller
            next_join = time.monotonic() + 0.5
        try:
            payload = states.get(timeout=0.5)
        except queue.Empty:
            if plant_gone.is_set():
                print(f"{name}: the plant left the run", file=sys.stderr)
                code = 3
                break
            continue
        try:
            state = msgpack.unpackb(payload)
        except Exception as e:  # a malformed message on the state key: ignore it
            print(f"{name}: ignoring an invalid state: {e}", file=sys.stderr)
            continue
        if not isinstance(state, dict) or state.get("v") != PROTOCOL_VERSION:
            continue
        step = state["step"]
        if state.get("controller") != p.my_id:
            if answered is not None and step > answered and state.get("controller"):
                print(f"{name}: handed the run over to {state['controller']} at step {step}", file=sys.stderr)
                break
            continue
        if state.get("last"):
            break
        if answered is not None and step < answered:
            continue  # never backwards
        if answered is None or step > answered:
            actuation = {"v": PROTOCOL_VERSION, "step": step, "controller": p.my_id, **act(state, info)}
            answer, answered, count = msgpack.packb(actuation), step, count + 1
        # a state resent for the step just answered gets the same answer again
        actuate(answer)

    print(f"{name}: answered {count} steps", file=sys.stderr)
    token.undeclare()
    sub.undeclare()
    live.undeclare()
    p.session.close()
    return code


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    common_arguments(ap)
    ap.add_argument("--f0", type=float, default=0.5, help="wave amplitude, N")
    ap.add_argument("--k", type=float, help="wave number, rad/m (default: one wavelength per body)")
    group = ap.add_mutually_exclusive_group()
    group.add_argument("--omega", type=float, help="angular frequency, rad/s")
    group.add_argument("--alpha", type=float, default=1.0, help="omega / omega_n (default 1: resonance)")
    args = ap.parse_args()
    wave = {}

    def act(state, info):
        if not wave:
            # The same arithmetic as the Rust policies, so the same bits: c = sqrt((A_c E) / rho).
            c = math.sqrt(info["area"] * info["youngs_modulus"] / info["density"])
            k = args.k if args.k is not None else 2.0 * math.pi / info["length"]
            omega = args.omega if args.omega is not None else args.alpha * (k * c)
            wave.update({"f0": args.f0, "k": k, "omega": omega, "phase": 0.0})
            print(f"python-controller: wave {wave}", file=sys.stderr)
        return {"wave": wave, "field": None}

    return control(args, "python-controller", "python-wave", act)


if __name__ == "__main__":
    sys.exit(main())
