"""The report of a run, as the programs print it with ``--json`` (one report whichever route ran
the run: simulate, a stepped Plant, a policy in process, the co-simulation)."""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Episode:
    """A stick phase of one node."""

    node: int  #: node index
    start: float  #: time the node came to rest, s
    end: float  #: time it started sliding again, s
    duration: float  #: end - start, s
    direction: int  #: +1 it left forwards (towards the head), -1 backwards


@dataclass(frozen=True)
class Events:
    """Stick-slip statistics of the steady window."""

    count: int  #: episodes that ended in the window
    per_node_per_period: float  #: episodes per node per forcing period
    mean_duration: float  #: mean episode duration, s
    min_duration: float  #: shortest stick phase counted, s
    episodes: list[Episode]  #: the episodes (at most max_episodes)
    episodes_truncated: bool  #: True if the list was cut


@dataclass(frozen=True)
class Window:
    """The averaging window."""

    start: float  #: s
    end: float  #: s
    periods: float  #: forcing periods (averaging blocks) in it
    steady: bool  #: whole periods after the last change of actuation (else run averages)
    whole_run: bool  #: the run ended before its transient (a task reached early)


@dataclass(frozen=True)
class Parameters:
    """Resolved parameters (SI); the wave fields describe the actuation at the end (None under a
    field)."""

    area: float  #: A_c, m^2
    density: float  #: rho, kg/m
    youngs_modulus: float  #: E, Pa
    viscous: float  #: c_v, N s/m^2
    dry: float  #: c_d, N/m
    eps: float  #: dry friction coefficient
    n_f: float  #: asymmetry n_F
    length: float  #: L, m
    f0: float | None  #: N
    k: float | None  #: rad/m
    omega: float | None  #: rad/s
    alpha: float | None  #: omega / omega_n
    phase: float | None  #: rad
    omega_n: float | None  #: rad/s
    zeta: float | None  #: paper's zeta
    pi_r: float | None  #: paper's pi_r
    wave_speed: float  #: c, m/s
    step: float  #: communication step H, s
    courant: float  #: c dt / dx
    dx: float  #: m
    cells_per_wavelength: float | None
    boundary: str  #: "periodic" or "free"
    filter: float  #: grid filter strength per step
    friction_map: bool  #: the pipe's friction varies along it
    settle: float  #: transient skipped, s


@dataclass(frozen=True)
class TaskReport:
    """How a run did against its task (SI)."""

    outcome: str  #: "reached", "energy exhausted", "stress exceeded" or "time up"
    distance_target: float  #: D, m
    distance: float  #: distance the centre of mass travelled, m
    time_to_distance: float | None  #: s
    energy_budget: float  #: J0, J
    energy_used: float  #: net actuator work, J
    energy_at_distance: float | None  #: J
    energy_exhausted_at: float | None  #: s
    sigma_max: float  #: Pa
    max_stress: float  #: Pa
    time_over_sigma_max: float  #: s
    stress_tolerance: float  #: time above sigma_max the task tolerates, s
    stress_exceeded_at: float | None  #: when the tolerance was exceeded, s from the task's start
    run_time: float  #: s


@dataclass(frozen=True)
class Report:
    """The report of a run (``crawler-plant simulate --json``), SI units."""

    scenario: str  #: scenario name
    velocity: float  #: steady mean speed V, m/s
    power: float  #: steady input power P, W
    mileage: float  #: |V| / P, m/J
    max_stress: float  #: sup T / A_c over the window, Pa
    max_strain: float  #: max |u_x| over the window
    stuck_fraction: float  #: share of node-time stuck
    mean_friction_selection: float  #: <s>, stuck points included
    dissipation: float  #: dissipated power, W
    identity_velocity: float  #: eps c_d (n_F - <s>) / c_v, m/s
    momentum_residual: float  #: relative residual of the discrete momentum balance
    events: Events
    window: Window
    cells: int
    dt: float  #: internal step, s
    steps: int  #: internal steps taken
    macro_steps: int  #: communication steps taken
    t_end: float  #: end time, s
    state_digest: str  #: CRC-32 of the final u and v bits: equal digests, identical runs
    parameters: Parameters
    task: TaskReport | None  #: how the run did against its task (None if not followed)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Report:
        """The report of its JSON object."""
        e = dict(d["events"])
        e["episodes"] = [Episode(**x) for x in e["episodes"]]
        return cls(**{**d, "events": Events(**e), "window": Window(**d["window"]),
                      "parameters": Parameters(**d["parameters"]),
                      "task": TaskReport(**d["task"]) if d.get("task") else None})

    @classmethod
    def from_json(cls, text: str) -> Report:
        return cls.from_dict(json.loads(text))

    def to_dict(self) -> dict[str, Any]:
        """The report as the JSON object the programs print (``--json``)."""
        return dataclasses.asdict(self)
