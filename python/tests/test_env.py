"""The Gymnasium environment: check_env, the vector environment equals N single ones, seeding,
and the same execution loop and briefing as the other routes."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from conftest import ROOT

import softcrawler
from softcrawler.env import PipeFamily, SoftCrawlerEnv, SoftCrawlerVectorEnv

FAST = dict(cells=64, t_end=6.0)
FAMILY = PipeFamily(eps=(0.1, 0.6), n_f=(0.3, 0.8), eps_std=0.05, correlation=0.2)


@pytest.mark.parametrize("action", ["wave", "field"])
def test_check_env_passes(action):
    env = gym.make("SoftCrawler-v0", action=action, frame_skip=20, pipe_family=FAMILY, **FAST)
    check_env(env.unwrapped, skip_render_check=True)
    check_env(env, skip_render_check=True)


def test_the_vector_environment_equals_n_single_ones_step_for_step():
    n, seed = 5, 11
    kw = dict(action="wave", frame_skip=25, pipe_family=FAMILY, cells=64, t_end=5.2)
    vec = SoftCrawlerVectorEnv(n, **kw)
    singles = [SoftCrawlerEnv(**kw) for _ in range(n)]
    obs, _ = vec.reset(seed=seed)
    single_obs = [e.reset(seed=seed + i)[0] for i, e in enumerate(singles)]
    assert np.array_equal(obs, np.stack(single_obs))
    rng = np.random.default_rng(3)
    lo, hi = vec.single_action_space.low, vec.single_action_space.high
    done = np.zeros(n, dtype=bool)
    ended = 0
    for _ in range(300):
        actions = rng.uniform(lo, hi, size=(n, 3))
        actions[:, 0] *= 0.3
        obs, rew, term, trunc, _ = vec.step(actions)
        for i, e in enumerate(singles):
            if done[i]:
                o, _ = e.reset()  # next_step autoreset: this step resets, reward 0
                r, te, tr = 0.0, False, False
            else:
                o, r, te, tr, _ = e.step(actions[i])
            assert np.array_equal(obs[i], o) and rew[i] == r and term[i] == te and trunc[i] == tr, i
            assert vec.state_digest(i) == e.state_digest
        done = term | trunc
        ended += int(done.sum())
    assert ended > 0, "no episode ended: autoreset untested"


def test_a_seed_makes_an_episode_reproducible_and_draws_the_pipe():
    env = SoftCrawlerEnv(pipe_family=FAMILY, frame_skip=50, **FAST)
    env.reset(seed=7)
    a = env.scenario
    env.reset(seed=8)
    b = env.scenario
    env.reset(seed=7)
    assert env.scenario == a and a != b
    fr = a.plant["friction"]
    assert 0.1 <= fr["eps"] <= 0.6 and a.plant["pipe"]["features"][-1]["kind"] == "texture"
    # what the controller is told: the nominal friction, no map
    told = env.briefing
    assert not told["disclosed"] and told["friction"]["eps"] == 0.1


def test_an_episode_is_the_task_and_its_report_is_the_plants():
    env = SoftCrawlerEnv(softcrawler.Scenario(values={"task.distance": 0.02}), frame_skip=10, **FAST)
    obs, _ = env.reset(seed=0)
    ret, steps = 0.0, 0
    w = env.base.wave
    while True:
        obs, r, term, trunc, info = env.step(np.array([0.5, w["omega"], w["k"]]))
        ret += r
        steps += 1
        if term or trunc:
            break
    assert term and info["outcome"] == "reached"
    report = env.report()
    assert report.task.outcome == "reached" and report.task.distance >= 0.02
    # the reward: progress over D, minus time, plus 1 on reaching
    t = report.task.run_time
    assert ret == pytest.approx(report.task.distance / 0.02 - t / 6.0 + 1.0, rel=1e-9)
    # the sensed progress is the task's distance over D
    names = env.observation_names
    assert obs[names.index("progress")] == pytest.approx(report.task.distance / 0.02, rel=1e-12)
    assert obs[names.index("energy")] == pytest.approx(report.task.energy_used / 20.0, rel=1e-12)


@pytest.mark.parametrize("action, frame_skip", [("wave", 40), ("field", 7)])
def test_a_trained_agent_drives_the_same_run_in_the_environment_and_in_process(action, frame_skip):
    """The same object: the env's action every frame_skip steps, and an EnvPolicy run by the
    execution loop (the co-simulation's loop), give the same plant state bit for bit."""
    scenario = softcrawler.Scenario(values={"task.distance": 0.05}, eps=0.3, **FAST)
    rng = np.random.default_rng(5)
    weights = rng.normal(size=(8 if action == "field" else 3, 6 * 8 + 6)) * 0.05

    def agent(features: np.ndarray) -> np.ndarray:
        x = np.tanh(weights[:, : len(features)] @ features)
        if action == "wave":
            return np.array([0.4 + 0.2 * x[0], 60.0 + 20 * x[1], 6.3 + 3 * x[2]])
        return 0.5 * x

    env = SoftCrawlerEnv(scenario, action=action, frame_skip=frame_skip)
    obs, _ = env.reset()
    while True:
        obs, _, term, trunc, _ = env.step(agent(obs))
        if term or trunc:
            break
    policy = softcrawler.EnvPolicy(agent, action=action, frame_skip=frame_skip)
    run = softcrawler.run(env.scenario.with_values(task=True), policy)
    assert run.report.state_digest == env.state_digest
    assert run.report.to_dict() == env.report().to_dict()


@pytest.mark.parametrize("source, action", [(None, "wave"), ("free-body.toml", "field")])
def test_the_environment_senses_what_the_policys_sensor_senses_every_step_bit_for_bit(source,
                                                                                      action):
    """The environment sums the tension per segment from the plant and takes the distance from
    the task; the policy's sensor reads the observation a controller gets. Every field, segments
    of unequal length: the features each route hands the agent are the same bits."""
    path = None if source is None else str(ROOT / "scenarios" / source)
    scenario = softcrawler.Scenario(path, values={"task.distance": 0.05}, cells=67, t_end=6.0)
    fields = list(softcrawler.env.FIELDS)
    rng = np.random.default_rng(11)
    weights = rng.normal(size=(7 if action == "field" else 3, 4 * 7 + 5)) * 0.05
    seen: dict[str, list[bytes]] = {"env": [], "policy": []}

    def agent_of(route: str):
        def agent(features: np.ndarray) -> np.ndarray:
            seen[route].append(features.tobytes())
            x = np.tanh(weights @ features)
            if action == "wave":
                return np.array([0.4 + 0.2 * x[0], 60.0 + 20 * x[1], 6.3 + 3 * x[2]])
            return 0.5 * x
        return agent

    env = SoftCrawlerEnv(scenario, action=action, segments=7, fields=fields, frame_skip=3)
    obs, _ = env.reset()
    agent = agent_of("env")
    while True:
        obs, _, term, trunc, _ = env.step(agent(obs))
        if term or trunc:
            break
    policy = softcrawler.EnvPolicy(agent_of("policy"), action=action, segments=7, fields=fields,
                                   frame_skip=3)
    run = softcrawler.run(env.scenario.with_values(task=True), policy)
    assert len(seen["env"]) > 50
    assert seen["policy"] == seen["env"]
    assert run.report.state_digest == env.state_digest


@pytest.mark.parametrize("source", [None, "free-body.toml"])
@pytest.mark.parametrize("segments", [8, 7, 1])
def test_the_sensed_strain_is_each_segments_extension_over_its_faces(source, segments):
    """Segment j's strain: the sum of u[i+1] - u[i] over its faces i, in order, over (faces x dx);
    a periodic body's last face wraps around to u[0], a free body's last face has no next node.
    Checked bit for bit against that definition on a plant that has moved."""
    path = None if source is None else str(ROOT / "scenarios" / source)
    scenario = softcrawler.Scenario(path, cells=67, t_end=6.0)
    periodic = source is None
    plant = softcrawler.Plant(scenario)
    plant.step(300)
    obs = plant.observation()
    told = softcrawler._native.context(scenario._native)["scenario"]
    sensor = softcrawler._native.Sensor(told, ["strain"], segments)
    sensor.feed(obs)
    got = np.frombuffer(sensor.encode(obs), dtype=np.float64)
    u = [float(x) for x in obs.u]
    n = len(u)
    dx = scenario.discretisation["dx"]
    want = []
    for j in range(segments):
        a, b = j * n // segments, (j + 1) * n // segments
        total, faces = 0.0, 0
        for i in range(a, b):
            if i + 1 < n:
                total += u[i + 1] - u[i]
            elif periodic:
                total += u[0] - u[i]
            else:
                continue
            faces += 1
        want.append(total / (faces * dx) if faces else 0.0)
    assert [x.hex() for x in got] == [float(x).hex() for x in want]
    assert np.any(got != 0.0), "the body has moved"


@pytest.mark.parametrize("segments", [8, 7, 5, 1])
def test_the_sensed_stress_and_velocity_are_each_segments_mean_summed_in_order(segments):
    """Segment j's stress: the sum of the tension over its cells, in order, over the count and
    over A_c sigma_max; its velocity: the same mean of the node velocities. Bit for bit against
    that definition, with segments of unequal lengths (67 cells) on a plant that has moved."""
    scenario = softcrawler.Scenario(cells=67, t_end=6.0)
    plant = softcrawler.Plant(scenario)
    plant.step(300)
    obs = plant.observation()
    told = softcrawler._native.context(scenario._native)["scenario"]
    sensor = softcrawler._native.Sensor(told, ["stress", "velocity"], segments)
    sensor.feed(obs)
    got = np.frombuffer(sensor.encode(obs), dtype=np.float64)
    body, task = scenario.to_dict()["body"], scenario.to_dict()["task"]
    scale = 1.0 / (body["area"] * task["sigma_max"])
    n = len(obs.u)

    def means(values, scale=None):
        out = []
        for j in range(segments):
            a, b = j * n // segments, (j + 1) * n // segments
            total = -0.0
            for x in values[a:b]:
                total += float(x)
            m = total / (b - a)
            out.append(m * scale if scale is not None else m)
        return out

    want = means(obs.tension, scale) + means(obs.vel)
    assert [x.hex() for x in got] == [float(x).hex() for x in want]
    assert np.all(got != 0.0), "the body has moved"
