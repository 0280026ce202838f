"""Policies: a Python object with ``act(observation)`` drives the plant in process
(:func:`run`, the execution loop) or a co-simulated plant (:func:`softcrawler.client.control`)
through the same adapter, so both give the same bits.

A policy is any object with

- ``act(observation) -> Wave | array``: called once per communication step, before the step,
  with an :class:`~softcrawler.plant.Observation` (``step``, ``time`` (s), ``u`` (m), ``vel``
  (m/s), ``tension`` (N), ``stuck``, ``mean_speed`` (m/s), ``input_power`` (W)); it returns the
  actuation over the step: a :class:`Wave` or a muscle-force field (N, one value per cell);
- optionally ``reset(context)``: called once when the run starts, with what the controller is
  told (the briefing: ``body``, ``friction`` (the nominal one when the pipe is not disclosed),
  ``length`` (m), ``boundary``, ``cells``, ``step`` H (s), ``disclosed``, ``settle`` (s)) and its
  own scenario's ``task``, ``limits``, ``wave`` and ``scenario`` (the plant as told);
- optionally ``name``.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from . import _native
from .plant import Observation, ScenarioLike
from .report import Report
from .scenario import Scenario, as_scenario


@dataclass(frozen=True)
class Wave:
    """The travelling wave ``f0 sin(k x - omega t + phase)``."""

    f0: float  #: amplitude, N
    k: float  #: wave number, rad/m
    omega: float  #: angular frequency, rad/s
    phase: float = 0.0  #: rad


class Policy(Protocol):
    def act(self, observation: Observation) -> Wave | np.ndarray: ...


def _actuation(policy: Any, observation: Observation) -> tuple[float, float, float, float] | bytes:
    """The policy's answer as the adapter takes it: a wave's four numbers or a field's bytes."""
    a = policy.act(observation)
    if isinstance(a, Wave):
        return (float(a.f0), float(a.k), float(a.omega), float(a.phase))
    if isinstance(a, tuple) and len(a) == 4 and not isinstance(a[0], (list, tuple, np.ndarray)):
        return tuple(float(x) for x in a)  # type: ignore[return-value]
    if isinstance(a, bytes):
        return a
    return np.ascontiguousarray(a, dtype=np.float64).tobytes()


@dataclass(frozen=True)
class Run:
    """An in-process closed-loop run."""

    report: Report  #: the plant's report (task included), as ``crawler-plant run`` prints it
    steps: int  #: communication steps taken


def run(scenario: ScenarioLike, policy: Any, params: Sequence[str] = ()) -> Run:
    """Runs ``policy`` against the in-process plant of ``scenario`` from t = 0 to its end (or, in
    task mode, to the step that decides the task), through the execution loop the co-simulation
    runs (the same bits as ``crawler run``). ``policy`` is a Python policy or the name of a
    registered one (``optimal``, ``adaptive``, ``reflex``, ...; ``params`` as ``KEY=VALUE``).
    The GIL is released while Rust computes (a Python policy takes it for each of its calls)."""
    text, steps = _native.run_policy(as_scenario(scenario)._native, policy, list(params))
    return Run(Report.from_json(text), steps)


def registered() -> dict[str, tuple[str, list[tuple[str, str]]]]:
    """The registered policies: name -> (what it does, [(parameter, doc)])."""
    return {n: (h, keys) for n, h, keys in _native.policies()}


class EnvPolicy:
    """An agent trained on :class:`~softcrawler.env.SoftCrawlerEnv` as a policy of any route.

    ``agent(features) -> action`` maps the environment's observation to its action. Each
    communication step this policy feeds the environment's sensor with the observation (as the
    environment does); every ``frame_skip`` steps it asks the agent and turns its action into an
    actuation with the environment's actuator, and holds it in between, as the environment does:
    the same decisions, bit for bit, in the environment, in process (:func:`run`) and against a
    co-simulated plant (:func:`softcrawler.client.control`).
    """

    def __init__(self, agent: Callable[[np.ndarray], Any], *, action: str = "wave",
                 segments: int = 8, fields: Sequence[str] = (), frame_skip: int = 1,
                 name: str = "learnt") -> None:
        self.agent = agent
        self.action = action
        self.segments = segments
        self.fields = list(fields)
        self.frame_skip = frame_skip
        self.name = name
        self._sensor: Any = None
        self._actuator: Any = None
        self._held: Any = None
        self._start: int | None = None

    def reset(self, context: dict[str, Any]) -> None:
        """Builds the sensor and the actuator for what the controller is told; the agent's own
        ``reset(context)``, if it has one, is called too."""
        told = context["scenario"]
        self._sensor = _native.Sensor(told, self.fields, self.segments)
        self._actuator = _native.Actuator(told, self.action, self.segments)
        if hasattr(self.agent, "reset"):
            self.agent.reset(context)
        self._held = None
        self._start = None

    def act(self, observation: Observation) -> Any:
        self._sensor.feed(observation)
        if self._start is None:
            self._start = observation.step
        if self._held is None or (observation.step - self._start) % self.frame_skip == 0:
            features = np.frombuffer(self._sensor.encode(observation), dtype=np.float64)
            action = np.ascontiguousarray(self.agent(features), dtype=np.float64)
            held = self._actuator.decode(action.tobytes(), observation.time)
            self._held = held if isinstance(held, bytes) else tuple(held)
        return self._held


def report_of(text: str) -> Report:
    return Report.from_dict(json.loads(text))
