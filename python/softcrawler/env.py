"""A Gymnasium environment of the paper's task: travel D on J0 without exceeding sigma_max.

``gymnasium.make("SoftCrawler-v0", scenario=...)`` (registered when this module is imported;
``gymnasium.make("softcrawler.env:SoftCrawler-v0")`` imports it) or :class:`SoftCrawlerEnv`;
:class:`SoftCrawlerVectorEnv` steps many crawlers in Rust across threads in one call
(``gymnasium.make_vec("SoftCrawler-v0", num_envs=64, vectorization_mode="vector_entry_point")``).

An episode is one run of the scenario's plant in task mode, by the physics crate's execution loop
(the loop of every other route), from t = 0 until the centre of mass has travelled D (success,
terminated), the actuator has spent J0 (failure, terminated) or the scenario's ``t_end``
(truncated). The controller is told what any controller of that scenario is told (its briefing:
the nominal friction when the pipe is not disclosed); ``env.unwrapped.briefing`` shows it. The
spaces, the sensed fields and the reward are in docs/python.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import _native
from .errors import InvalidInput, invalid, whole
from .plant import ScenarioLike
from .report import Report
from .scenario import Scenario, as_scenario

#: The fields a crawler can sense (name, what it is); per segment unless said otherwise.
FIELDS: dict[str, str] = {
    "strain": "mean strain u_x of each segment (dimensionless)",
    "stuck": "share of each segment's nodes held by static friction, in [0, 1]",
    "stress": "mean tension of each segment over A_c sigma_max",
    "velocity": "mean velocity of each segment, m/s",
    "speed": "mean speed of the body over the last step, m/s (one number)",
    "progress": "distance travelled by the centre of mass over D (one number)",
    "energy": "net actuator work so far over J0 (one number)",
    "power": "input power over the last step, W (one number)",
    "time": "time since the start over the scenario's t_end (one number)",
}
DEFAULT_FIELDS: tuple[str, ...] = ("strain", "stuck", "stress", "speed", "progress", "energy")


@dataclass(frozen=True)
class PipeFamily:
    """A randomised family of pipes (domain randomisation): each episode draws the pipe's
    friction uniformly, ``eps`` in ``eps`` and ``n_F`` in ``n_f``, and, when ``eps_std`` or
    ``n_f_std`` is positive, adds a seeded random texture (correlation length ``correlation``
    m, along the first ``extent`` m of the pipe; the seed drawn from the environment's
    generator). The pipe is not disclosed: controllers are told ``nominal`` (default: the base
    scenario's friction)."""

    eps: tuple[float, float] = (0.05, 0.5)
    n_f: tuple[float, float] = (0.3, 0.8)
    eps_std: float = 0.0
    n_f_std: float = 0.0
    correlation: float = 0.1
    extent: float = 10.0
    nominal: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        def number(v: Any) -> float:
            try:
                return float(v)
            except (TypeError, ValueError):
                return float("nan")

        for name, top, allowed in (("eps", np.inf, "two finite numbers >= 0, low <= high"),
                                   ("n_f", 1.0, "two numbers in [0, 1), low <= high")):
            pair = getattr(self, name)
            try:
                low, high = (number(x) for x in pair)
            except (TypeError, ValueError):
                low = high = float("nan")
            if not (np.isfinite(low) and np.isfinite(high) and 0 <= low <= high < top):
                raise invalid(f"pipe_family.{name}", pair, allowed)
        for name, positive in (("eps_std", False), ("n_f_std", False), ("correlation", True),
                               ("extent", True)):
            v = number(getattr(self, name))
            if not (np.isfinite(v) and (v > 0 if positive else v >= 0)):
                raise invalid(f"pipe_family.{name}", getattr(self, name),
                              "a finite number > 0, m" if positive else "a finite number >= 0")

    def sample(self, base: Scenario, rng: np.random.Generator) -> Scenario:
        """A scenario of the family, drawn with ``rng``."""
        eps = float(rng.uniform(*self.eps))
        n_f = float(rng.uniform(*self.n_f))
        seed = int(rng.integers(0, 2**63 - 1))
        fr = base.plant["friction"]
        nominal = self.nominal or (fr["eps"], fr["n_f"])
        values: dict[str, Any] = {
            "friction.eps": eps,
            "friction.n_f": n_f,
            "pipe.disclose": False,
            "pipe.nominal": {"eps": float(nominal[0]), "n_f": float(nominal[1])},
        }
        if self.eps_std > 0 or self.n_f_std > 0:
            start = float(base.plant["pipe"]["start"])
            features = list(base.to_dict().get("pipe", {}).get("features", []))
            features.append({"kind": "texture", "from": start - 1.0, "to": start + self.extent,
                              "eps_std": float(self.eps_std), "n_f_std": float(self.n_f_std),
                              "correlation": float(self.correlation), "seed": seed})
            values["pipe.features"] = features
        return base.with_values(values)


def _base(scenario: ScenarioLike, cells: int | None, t_end: float | None) -> Scenario:
    s = as_scenario(scenario)
    if cells is not None or t_end is not None:
        s = s.with_values(cells=cells, t_end=t_end)
    return s


_F64 = np.dtype(np.float64)


def _not_numbers(field: str, values: Any, e: Exception) -> InvalidInput:
    """The error of ``values`` that NumPy cannot read as float64s."""
    return invalid(field, values, f"numbers (an array of float64): {e}")


def _f64(b: bytes, shape: tuple[int, ...] | None = None) -> np.ndarray:
    a = np.frombuffer(b)  # float64, frombuffer's default (naming it costs a lookup per call)
    return a if shape is None else a.reshape(shape)


class SoftCrawlerEnv(gym.Env):
    """One crawler on the paper's task (see the module's documentation and docs/python.md).

    Arguments: ``scenario`` (a Scenario, a path, a dict or None: the paper's); ``action``:
    ``"wave"`` (``[f0 (N), omega (rad/s), k (rad/m)]``; k snapped to a wavelength that fits the
    body; phase kept continuous) or ``"field"`` (one muscle force per segment, N);
    ``segments``: segments of the sensed fields and of the field action; ``fields``: which
    sensed fields, in order (default :data:`DEFAULT_FIELDS`); ``frame_skip``: communication
    steps per environment step (the actuation is held over them; 1 = the scenario's step H);
    ``stress_weight``: the reward's weight of time above sigma_max; ``pipe_family``: a
    :class:`PipeFamily` drawn at every reset; ``cells``, ``t_end``: overrides of the scenario.
    """

    metadata = {"render_modes": []}

    def __init__(self, scenario: ScenarioLike = None, *, action: str = "wave", segments: int = 8,
                 fields: Sequence[str] | None = None, frame_skip: int = 1,
                 stress_weight: float = 10.0, pipe_family: PipeFamily | None = None,
                 cells: int | None = None, t_end: float | None = None) -> None:
        segments, frame_skip = whole("segments", segments, 1), whole("frame_skip", frame_skip, 1)
        self.base = _base(scenario, cells, t_end)
        self.pipe_family = pipe_family
        self.options = dict(action=action, segments=segments, fields=list(fields or DEFAULT_FIELDS),
                            frame_skip=frame_skip, stress_weight=stress_weight)
        self._core = _native.EnvCore(self.base._native, action, segments, self.options["fields"],
                                     frame_skip, stress_weight)
        lay = self._core.layout()
        self.observation_names: list[str] = lay["obs_names"]
        self.observation_space = gym.spaces.Box(np.array(lay["obs_low"]), np.array(lay["obs_high"]),
                                                dtype=np.float64)
        self.action_space = gym.spaces.Box(np.array(lay["act_low"]), np.array(lay["act_high"]),
                                           dtype=np.float64)
        self.step_length: float = lay["step"]
        self.scenario: Scenario = self.base

    @property
    def briefing(self) -> dict[str, Any]:
        """What the controller of this episode is told (``Scenario.briefing``)."""
        return self.scenario.briefing

    @property
    def context(self) -> dict[str, Any]:
        """What a policy of this episode is told when it starts (the ``context`` a policy's
        ``reset`` gets on every route): the briefing, the task, the limits, the wave."""
        return _native.context(self.scenario._native)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        if options and options.get("scenario") is not None:
            self.scenario = as_scenario(options["scenario"])
        elif self.pipe_family is not None:
            self.scenario = self.pipe_family.sample(self.base, self.np_random)
        else:
            self.scenario = self.base
        obs = _f64(self._core.reset(self.scenario._native))
        return obs, {"time": 0.0, "distance": 0.0, "energy_used": 0.0}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        try:  # inline: this is the hot path
            a = np.ascontiguousarray(action, _F64).tobytes()
        except (TypeError, ValueError) as e:
            raise _not_numbers("action", action, e) from None
        obs, reward, terminated, truncated, info = self._core.step(a)
        return np.frombuffer(obs), reward, terminated, truncated, info

    def report(self) -> Report:
        """The plant's report of the episode so far (task included)."""
        return Report.from_json(self._core.report_json())

    @property
    def state_digest(self) -> str:
        return self._core.state_digest


class SoftCrawlerVectorEnv(VectorEnv):
    """``num_envs`` crawlers on the task, stepped by Rust across threads in one call (the GIL
    released), with the options of :class:`SoftCrawlerEnv`. Sub-environment ``i`` reset with
    seed ``s + i`` equals a :class:`SoftCrawlerEnv` reset with that seed, step for step.
    Autoreset: ``next_step`` (Gymnasium's default): the step after an episode ended resets that
    crawler (its action is ignored, its reward is 0)."""

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, scenario: ScenarioLike = None, *, action: str = "wave",
                 segments: int = 8, fields: Sequence[str] | None = None, frame_skip: int = 1,
                 stress_weight: float = 10.0, pipe_family: PipeFamily | None = None,
                 cells: int | None = None, t_end: float | None = None) -> None:
        self.num_envs = whole("num_envs", num_envs, 1)
        segments, frame_skip = whole("segments", segments, 1), whole("frame_skip", frame_skip, 1)
        self.base = _base(scenario, cells, t_end)
        self.pipe_family = pipe_family
        fields = list(fields or DEFAULT_FIELDS)
        self._core = _native.VecCore([self.base._native] * self.num_envs, action, segments, fields,
                                     frame_skip, stress_weight)
        lay = self._core.layout()
        self.observation_names: list[str] = lay["obs_names"]
        self.single_observation_space = gym.spaces.Box(np.array(lay["obs_low"]),
                                                       np.array(lay["obs_high"]), dtype=np.float64)
        self.single_action_space = gym.spaces.Box(np.array(lay["act_low"]),
                                                  np.array(lay["act_high"]), dtype=np.float64)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.step_length: float = lay["step"]
        self._obs_dim = len(lay["obs_low"])
        self._rngs: list[np.random.Generator] = [
            gym.utils.seeding.np_random(None)[0] for _ in range(self.num_envs)]
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self.scenarios: list[Scenario] = [self.base] * self.num_envs

    def _draw(self, i: int) -> Scenario:
        if self.pipe_family is None:
            return self.base
        return self.pipe_family.sample(self.base, self._rngs[i])

    def reset(self, *, seed: int | Sequence[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        if seed is None:
            seeds: list[int | None] = [None] * self.num_envs
        elif isinstance(seed, int):
            seeds = [seed + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise invalid("seed", seed, f"one seed (or None) per environment ({self.num_envs})")
        for i, s in enumerate(seeds):
            if s is not None or self._rngs[i] is None:
                self._rngs[i] = gym.utils.seeding.np_random(s)[0]
        rows = []
        for i in range(self.num_envs):
            self.scenarios[i] = self._draw(i)
            rows.append(self._core.reset_one(i, self.scenarios[i]._native))
        self._autoreset[:] = False
        return _f64(b"".join(rows), (self.num_envs, self._obs_dim)), {}

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        try:
            a = np.ascontiguousarray(actions, _F64).tobytes()
        except (TypeError, ValueError) as e:
            raise _not_numbers("actions", actions, e) from None
        mask = (~self._autoreset).astype(np.uint8).tobytes()
        resets = np.flatnonzero(self._autoreset)
        if len(resets):
            self._core.check(a, mask)  # refused actions reset nothing
        for i in resets:
            self.scenarios[i] = self._draw(int(i))
            self._core.reset_one(int(i), self.scenarios[i]._native)
        obs, rew, term, trunc = self._core.step(a, mask)
        terminated = np.frombuffer(term, dtype=bool)
        truncated = np.frombuffer(trunc, dtype=bool)
        self._autoreset = terminated | truncated
        return (_f64(obs, (self.num_envs, self._obs_dim)), _f64(rew), terminated, truncated, {})

    def episode_info(self, i: int) -> dict[str, Any]:
        """Crawler ``i``'s episode so far: time (s), distance (m), energy_used (J), max_stress
        (Pa), time_over_sigma_max (s), outcome."""
        t, d, e, s, o, outcome = self._core.info(i)
        return {"time": t, "distance": d, "energy_used": e, "max_stress": s,
                "time_over_sigma_max": o, "outcome": outcome}

    def state_digest(self, i: int) -> str:
        return self._core.state_digest(i)


def register_envs() -> None:
    """Registers ``SoftCrawler-v0`` with Gymnasium (idempotent)."""
    if "SoftCrawler-v0" not in gym.registry:
        gym.register(id="SoftCrawler-v0", entry_point="softcrawler.env:SoftCrawlerEnv",
                     vector_entry_point="softcrawler.env:SoftCrawlerVectorEnv")


register_envs()
