"""Scenarios: the scenario files' TOML, read and validated by the library the programs use."""

from __future__ import annotations

import copy
import os
from collections.abc import Mapping
from typing import Any

from . import _native
from .errors import InvalidInput

#: Keyword overrides, as the programs' flags (`--eps`, `--n-f`, ...): the scenario key each sets.
OVERRIDES: dict[str, str] = {
    "eps": "friction.eps",
    "n_f": "friction.n_f",
    "f0": "actuation.f0",
    "k": "actuation.k",
    "omega": "actuation.omega",
    "alpha": "actuation.alpha",
    "cells": "numerics.cells",
    "t_end": "numerics.t_end",
    "task": "task.end_run",
}

PAPER_ORIGIN = "<embedded paper.toml>"


def _assign(table: dict[str, Any], key: str, value: Any) -> None:
    """Sets the dotted `key` in `table`, creating sections; `actuation.alpha` and
    `actuation.omega` exclude each other (as the flags do)."""
    parts = key.split(".")
    if not all(parts):
        raise InvalidInput(f"invalid key = {key!r}: allowed a dotted scenario key", "key", repr(key),
                           "a dotted scenario key such as friction.eps")
    t = table
    for i, p in enumerate(parts[:-1]):
        nxt = t.setdefault(p, {})
        if not isinstance(nxt, dict):
            at = ".".join(parts[: i + 1])
            raise InvalidInput(f"invalid {key}: {at} is a value, not a section", key, repr(value),
                               f"a key inside a section ({at} is a value)")
        t = nxt
    if parts[:-1] == ["actuation"] and parts[-1] in ("alpha", "omega"):
        t.pop("omega" if parts[-1] == "alpha" else "alpha", None)
    t[parts[-1]] = value


class Scenario:
    """A validated scenario (SI units throughout).

    ``Scenario()`` is the paper's (``scenarios/paper.toml``, embedded); ``Scenario(path)`` reads a
    scenario file; ``Scenario(dict)`` takes a dict shaped as a scenario file (sections ``body``,
    ``friction``, ``actuation``, ``numerics``, ``events``, ``task``, ``limits``, ``pipe``).
    Keyword overrides are the programs' flags: ``eps``, ``n_f``, ``f0`` (N), ``k`` (rad/m),
    ``omega`` (rad/s) or ``alpha``, ``cells``, ``t_end`` (s), ``task`` (task mode);
    ``values={"pipe.disclose": False, ...}`` sets any dotted key. Every value is checked by the
    scenario parser of the programs: a value that is not allowed raises
    :class:`~softcrawler.errors.InvalidInput` naming the field, the value and what is allowed.
    """

    __slots__ = ("_native", "_table", "_origin")

    def __init__(self, source: str | os.PathLike[str] | Mapping[str, Any] | Scenario | None = None,
                 /, *, values: Mapping[str, Any] | None = None, **overrides: Any) -> None:
        text: str | None = None
        if source is None:
            origin = PAPER_ORIGIN
            text = _native.PAPER_TOML
            table = _native.parse_toml(text, origin)
        elif isinstance(source, Scenario):
            origin, table = source._origin, copy.deepcopy(source._table)
        elif isinstance(source, Mapping):
            origin, table = "<dict>", copy.deepcopy(dict(source))
        elif isinstance(source, (str, os.PathLike)):
            origin = os.fspath(source)
            text = _native.read_text(origin)
            table = _native.parse_toml(text, origin)
        else:
            raise InvalidInput(f"invalid scenario = {source!r}", "scenario", repr(source),
                               "None (the paper's), a path, a dict or a Scenario")
        for name, value in overrides.items():
            key = OVERRIDES.get(name)
            if key is None:
                raise InvalidInput(f"invalid {name} = {value!r}: not an override", name, repr(value),
                                   "one of " + ", ".join(OVERRIDES) + " (or values={dotted key: value})")
            if value is not None:
                _assign(table, key, value)
        for key, value in (values or {}).items():
            _assign(table, key, value)
        if text is not None and not overrides and not values:
            native = _native.Scenario.from_toml(text, origin)
        else:
            native = _native.Scenario.from_dict(table, origin)
        self._native = native
        self._table = table
        self._origin = origin

    @classmethod
    def paper(cls) -> Scenario:
        """The paper's scenario (``scenarios/paper.toml``)."""
        return cls()

    @classmethod
    def from_toml(cls, text: str, origin: str = "<text>") -> Scenario:
        """A scenario from TOML text."""
        s = cls.__new__(cls)
        s._table = _native.parse_toml(text, origin)
        s._native = _native.Scenario.from_toml(text, origin)
        s._origin = origin
        return s

    def with_values(self, values: Mapping[str, Any] | None = None, **overrides: Any) -> Scenario:
        """A copy with dotted keys (``values``) and flag-like overrides changed."""
        return Scenario(self, values=values, **overrides)

    def with_wave(self, f0: float, k: float, omega: float, phase: float = 0.0,
                  length: float | None = None) -> Scenario:
        """A copy driven by the wave ``f0 sin(k x - omega t + phase)`` (N, rad/m, rad/s, rad); the
        body keeps its length unless ``length`` (m) is given."""
        values: dict[str, Any] = {"actuation.f0": float(f0), "actuation.k": float(k),
                                  "actuation.omega": float(omega), "actuation.phase": float(phase)}
        if length is not None:
            values["body.length"] = float(length)
        return self.with_values(values)

    # -- what it is --------------------------------------------------------------------------
    @property
    def name(self) -> str:
        """Short name."""
        return self._native.name

    @property
    def description(self) -> str:
        """One line of description."""
        return self._native.description

    @property
    def t_end(self) -> float:
        """End time of a run, s."""
        return self._native.t_end

    @property
    def cells(self) -> int:
        """Number of cells N."""
        return self._native.cells

    @property
    def length(self) -> float:
        """Body length L, m."""
        return self._native.length

    @property
    def boundary(self) -> str:
        """``"periodic"`` or ``"free"``."""
        return self._native.boundary

    @property
    def wave(self) -> dict[str, float]:
        """The travelling wave: ``f0`` (N), ``k`` (rad/m), ``omega`` (rad/s), ``phase`` (rad)."""
        return self._native.wave

    @property
    def task(self) -> dict[str, Any]:
        """The task: ``distance`` D (m), ``energy`` J0 (J), ``sigma_max`` (Pa), ``end_run``."""
        return self._native.task

    @property
    def limits(self) -> dict[str, Any]:
        """The optimiser's limits: ``omega`` [min, max] (rad/s), ``k`` (rad/m), ``f0_max`` (N),
        ``strain_max``."""
        return self._native.limits

    @property
    def plant(self) -> dict[str, Any]:
        """The resolved plant parameters (body, friction, length, boundary, pipe, numerics)."""
        return self._native.plant

    @property
    def discretisation(self) -> dict[str, Any]:
        """``dx`` (m), ``dt`` (s), ``substeps``, ``step`` H actually used (s), ``courant``."""
        return self._native.discretisation

    @property
    def briefing(self) -> dict[str, Any]:
        """What a controller of a run of this scenario is told (the physics crate's
        ``Briefing``): body, friction (the nominal one when the pipe is not disclosed), length (m),
        boundary, cells, step (s), start_time (s), last_step, settle (s), disclosed."""
        return self._native.briefing

    def to_dict(self) -> dict[str, Any]:
        """The scenario as a dict shaped as its file (a copy)."""
        return copy.deepcopy(self._table)

    def to_json(self) -> str:
        """The resolved scenario (every field, SI units) as JSON."""
        return self._native.to_json()

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Scenario) and self._native == other._native

    def __hash__(self) -> int:
        return hash(self.to_json())

    def __repr__(self) -> str:
        native = getattr(self, "_native", None)
        return repr(native) if native is not None else "Scenario(<not constructed>)"


def as_scenario(s: Scenario | str | os.PathLike[str] | Mapping[str, Any] | None) -> Scenario:
    """`s` as a Scenario (a path, a dict or None: the paper's)."""
    return s if isinstance(s, Scenario) else Scenario(s)
