"""A controller of a co-simulated run in a few lines: ``softcrawler.connect(run_id).run(policy)``.

The client is the Rust controller's (``crawler_controller::client``): it finds the run's
credential, presents its password, seals every message, joins the run and answers every state
exactly once; nothing of the wire is written again in Python. The policy is a Python object
(``act(observation)``, see :mod:`softcrawler.policy`) or a registered policy's name.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from . import _native
from .plant import ScenarioLike
from .scenario import as_scenario


@dataclass
class Connection:
    """Where a run's processes meet (as the programs' network flags)."""

    run_id: str | None = None  #: the run id (default: ``default``)
    endpoint: str | None = None  #: the run's loopback endpoint (default: the run's socket)
    credential: str | None = None  #: the run's credential file (default: the run's own)
    no_auth: bool = False  #: join a run started with ``--no-auth``
    zenoh_config: str | None = None  #: a zenoh JSON5 configuration replacing the defaults
    wait_timeout: float = 60.0  #: s to wait for the plant

    def run(self, policy: Any, *, scenario: ScenarioLike = None,
            params: Sequence[str] = ()) -> dict[str, Any]:
        """Controls the run with ``policy`` until it ends; returns the controller's final summary
        (the plant's report under ``plant``). ``scenario`` is the controller's own (task, limits,
        default wave; the plant's body and grid come from the plant). Raises
        :class:`~softcrawler.errors.RunError` (with ``exit_code``) when the run ends otherwise;
        Ctrl-C stops the controller."""
        s = None if scenario is None else as_scenario(scenario)._native
        text = _native.control(policy, self.run_id, self.endpoint, self.credential, self.no_auth,
                               self.zenoh_config, s, list(params), self.wait_timeout)
        return json.loads(text)


def connect(run_id: str | None = None, **options: Any) -> Connection:
    """The connection to run ``run_id`` (options as :class:`Connection`'s fields)."""
    return Connection(run_id=run_id, **options)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the network flags every controller of the project takes (``--run-id``,
    ``--endpoint``, ``--credential``, ``--no-auth``, ``--zenoh-config``, ``--wait-timeout``):
    ``crawler run --controller-cmd`` passes the run's to the command it starts."""
    parser.add_argument("--run-id", default=None)
    parser.add_argument("--endpoint", default=None)
    parser.add_argument("--credential", default=None)
    parser.add_argument("--no-auth", action="store_true")
    parser.add_argument("--zenoh-config", default=None)
    parser.add_argument("--wait-timeout", type=float, default=60.0)


def from_arguments(args: argparse.Namespace) -> Connection:
    """The connection the flags of :func:`add_arguments` name."""
    return Connection(run_id=args.run_id, endpoint=args.endpoint, credential=args.credential,
                      no_auth=args.no_auth, zenoh_config=args.zenoh_config,
                      wait_timeout=args.wait_timeout)

