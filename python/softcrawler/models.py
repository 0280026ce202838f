"""The reduced models and the constrained optimiser (``crawler_models``), as
``crawler-controller predict`` and ``crawler-controller optimize --json`` compute them."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

from . import _native
from .errors import whole
from .plant import ScenarioLike
from .scenario import as_scenario

DEFAULT_MARGIN: float = _native.DEFAULT_MARGIN
DEFAULT_TIE_TOLERANCE: float = _native.DEFAULT_TIE_TOLERANCE


@dataclass(frozen=True)
class Prediction:
    """A model's steady state at an operating point (None where it has no answer)."""

    model: str  #: "paper" or "improved"
    velocity: float | None  #: mean speed V, m/s
    power: float | None  #: input power, W
    mileage: float | None  #: |V| / P, m/J
    max_stress: float | None  #: sup T / A_c, Pa
    max_strain: float | None  #: max |u_x|
    stuck_fraction: float | None  #: share of node-time stuck
    mean_friction_selection: float | None  #: <s>
    episodes_per_node_per_period: float | None
    valid: bool  #: whether the model applies
    reason: str | None  #: why not, if not
    extra: dict[str, Any] = field(default_factory=dict)  #: alpha, zeta, pi_r, terms, ...

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Prediction:
        names = [f for f in cls.__dataclass_fields__ if f not in ("valid", "reason", "extra")]
        v = d.get("validity", {})
        return cls(**{n: d.get(n) for n in names}, valid=v.get("status") == "valid",
                   reason=v.get("reason"),
                   extra={k: x for k, x in d.items() if k not in names and k != "validity"})

    def to_dict(self) -> dict[str, Any]:
        names = [f for f in self.__dataclass_fields__ if f not in ("valid", "reason", "extra")]
        d = {n: getattr(self, n) for n in names}
        d["validity"] = ({"status": "valid"} if self.valid
                         else {"status": "outside_validity", "reason": self.reason})
        d.update(self.extra)
        return d


def predict(scenario: ScenarioLike = None, model: str = "improved", *,
            march_steps: int | None = None) -> Prediction:
    """The steady state the ``model`` ("paper" or "improved") predicts at the scenario's wave;
    ``march_steps``: the improved model's steps per forcing period (default 1024)."""
    return Prediction.from_dict(json.loads(
        _native.predict_json(as_scenario(scenario)._native, model, march_steps)))


@dataclass(frozen=True)
class Optimum:
    """The constrained optimum: the wave and the model's prediction there."""

    omega: float  #: rad/s
    k: float  #: rad/m
    alpha: float  #: omega / omega_n
    f0: float  #: N
    wavelengths: float  #: wavelengths on the body
    binding: str  #: the binding constraint
    prediction: Prediction
    margins: dict[str, float]  #: relative margin of each constraint (>= 0: holds)


@dataclass(frozen=True)
class Optimization:
    """The result of :func:`optimize` (``crawler-controller optimize --json``)."""

    model: str
    optimum: Optimum
    seconds: float  #: wall time of the search, s
    verification: dict[str, Any] | None  #: the plant at the optimum (``verify=True``)
    certification: dict[str, Any] | None  #: ``certify=True``: the certified f0 and its runs
    raw: dict[str, Any]  #: everything (grid, cells, tie-break, task, limits)

    @property
    def certified_f0(self) -> float | None:
        """The certified amplitude, N (None without ``certify``)."""
        return None if self.certification is None else self.certification["f0"]

    def to_dict(self) -> dict[str, Any]:
        return dict(self.raw)


def optimize(scenario: ScenarioLike = None, model: str = "paper", *,
             omega_points: int | None = None, k_points: int | None = None,
             fixed_body: bool = False, refine: bool = True,
             tie_tolerance: float = DEFAULT_TIE_TOLERANCE, verify: bool = False,
             certify: bool = False, margin: float = DEFAULT_MARGIN,
             max_runs: int = 10) -> Optimization:
    """Maximises the speed subject to the scenario's task (mileage >= D / J0, stress <=
    sigma_max) and limits (strain, f0, omega and k ranges) with ``model``. ``verify`` runs the
    plant at the optimum; ``certify`` lowers f0 with plant runs until every constraint holds on
    the plant with ``margin`` to spare. The GIL is released while it runs."""
    d = json.loads(_native.optimize_json(
        as_scenario(scenario)._native, model,
        None if omega_points is None else whole("omega_points", omega_points),
        None if k_points is None else whole("k_points", k_points), fixed_body, refine,
        tie_tolerance, verify, certify, margin, whole("max_runs", max_runs)))
    o = d["optimum"]
    opt = Optimum(omega=o["omega"], k=o["k"], alpha=o["alpha"], f0=o["f0"],
                  wavelengths=o["wavelengths"], binding=str(o["binding"]),
                  prediction=Prediction.from_dict(o["prediction"]), margins=o["margins"])
    return Optimization(model=d["model"], optimum=opt, seconds=d["seconds"],
                        verification=d.get("verification"), certification=d.get("certification"),
                        raw=d)
