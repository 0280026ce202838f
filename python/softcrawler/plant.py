"""The plant in process: the physics crate's execution loop, stepped from Python."""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from . import _native
from .errors import whole
from .report import Report
from .scenario import Scenario, as_scenario

State = _native.State
Observation = _native.Observation

ScenarioLike = Scenario | str | os.PathLike | Mapping[str, Any] | None


def simulate(scenario: ScenarioLike = None, *, max_episodes: int = 10_000) -> Report:
    """Runs the scenario's plant under its wave from t = 0 to its ``t_end`` (or, in task mode,
    to the step that decides the task): ``crawler-plant simulate --json``, bit for bit (the same
    execution loop). The GIL is released while it runs."""
    return Report.from_json(_native.simulate_json(as_scenario(scenario)._native,
                                                      whole("max_episodes", max_episodes)))


class Plant:
    """A run of a scenario's plant, stepped by communication steps H.

    The run is the physics crate's execution loop (the one every route runs): stepping it to the
    end without changing the actuation gives :func:`simulate`'s report bit for bit; setting an
    actuation before a step is what a controller does. ``start_wave=True`` drives the plant
    with the scenario's wave from t = 0 (as ``simulate``); ``False`` leaves it idle until
    :meth:`set_wave` or :meth:`set_field`.

    The field properties (:attr:`u`, :attr:`vel`, :attr:`tension`, :attr:`stuck`,
    :attr:`muscle_force`) are read-only NumPy arrays: Rust copies the plant's state of that
    instant once into an immutable buffer and NumPy views it without a second copy; they do not
    change when the plant steps on.
    """

    def __init__(self, scenario: ScenarioLike = None, *, start_wave: bool = True,
                 max_episodes: int = 10_000) -> None:
        self.scenario = as_scenario(scenario)
        self._p = _native.Plant(self.scenario._native, start_wave,
                                whole("max_episodes", max_episodes))

    # -- actuation --------------------------------------------------------------------------
    def set_wave(self, f0: float, k: float, omega: float, phase: float = 0.0) -> None:
        """Drives the body from the next step on with ``f0 sin(k x - omega t + phase)``: f0 in N,
        k in rad/m (it must fit a periodic body a whole number of times), omega in rad/s, phase
        in rad."""
        self._p.set_wave(float(f0), float(k), float(omega), float(phase))

    def set_field(self, force: np.ndarray) -> None:
        """Drives the body from the next step on with a muscle-force field (N, one value per cell
        at the half nodes), held over each step."""
        self._p.set_field_bytes(np.ascontiguousarray(force, dtype=np.float64).tobytes())

    # -- stepping ---------------------------------------------------------------------------
    def step(self, n: int = 1) -> int:
        """Takes up to ``n`` communication steps (fewer when the run ends); returns how many."""
        return self._p.step(whole("n", n))

    def run(self) -> int:
        """Steps to the end of the run; returns the steps taken."""
        return self._p.run()

    @property
    def finished(self) -> bool:
        """True when the run has reached its last step."""
        return self._p.finished

    @property
    def steps(self) -> int:
        """Communication steps taken."""
        return self._p.steps

    @property
    def last_step(self) -> int:
        """The run's last communication step (earlier once the task ended the run)."""
        return self._p.last_step

    @property
    def time(self) -> float:
        """Time, s."""
        return self._p.time

    @property
    def step_length(self) -> float:
        """Communication step H actually used, s."""
        return self._p.step_length

    @property
    def cells(self) -> int:
        return self._p.cells

    # -- fields -----------------------------------------------------------------------------
    @property
    def u(self) -> np.ndarray:
        """Displacement at the nodes, m."""
        return self._p.u

    @property
    def vel(self) -> np.ndarray:
        """Velocity at the nodes, m/s."""
        return self._p.vel

    @property
    def tension(self) -> np.ndarray:
        """Tension at the half nodes, N."""
        return self._p.tension

    @property
    def stuck(self) -> np.ndarray:
        """Nodes held by static friction (bool)."""
        return self._p.stuck

    @property
    def muscle_force(self) -> np.ndarray:
        """Muscle force at the half nodes now, N."""
        return self._p.muscle_force

    @property
    def outputs(self) -> dict[str, float]:
        """The last step's outputs: ``mean_speed`` (m/s), ``input_power`` (W), ``stuck_nodes``,
        ``max_stress`` (Pa), ``time_over_stress`` (s)."""
        return self._p.outputs

    @property
    def task(self) -> dict[str, Any]:
        """The task so far (outcome, distance (m), energy_used (J), ...)."""
        return self._p.task

    def observation(self) -> Observation:
        """What a controller sees now (step, time (s), u, vel, tension, stuck, mean_speed,
        input_power)."""
        return self._p.observation()

    @property
    def state_digest(self) -> str:
        """CRC-32 of the displacement and velocity bits and the step count."""
        return self._p.state_digest

    # -- state and report -------------------------------------------------------------------
    def get_state(self) -> State:
        """The run's complete state (plant, task, episode log); ``State.to_bytes()`` serialises
        it, ``State.from_bytes`` reads it back."""
        return self._p.get_state()

    def set_state(self, state: State) -> None:
        """Continues from ``state`` (of a plant of the same scenario), bit-identically."""
        self._p.set_state(state)

    def report(self) -> Report:
        """The report of the run so far (task included)."""
        return Report.from_json(self._p.report_json())

    def __repr__(self) -> str:
        return repr(self._p)
