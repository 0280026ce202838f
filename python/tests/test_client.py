"""A Python policy controls a co-simulated plant through the Rust client (credential, seals,
join, exactly-once answers) and gives the in-process run's trajectory bit for bit."""

from __future__ import annotations

import json
import math
import os
import subprocess

import numpy as np
import pytest

import softcrawler
from conftest import SMALL, SMALL_FLAGS


class StickReflex:
    """The wave at the faces plus a stick reflex (examples/python_reflex_controller.py)."""

    name = "pytest-reflex"

    def reset(self, context):
        b = context["body"]
        self.n, self.step = context["cells"], context["step"]
        self.dx = context["length"] / self.n
        self.k = 2 * math.pi / context["length"]
        self.omega = 0.5 * self.k * math.sqrt(b["area"] * b["youngs_modulus"] / b["density"])
        self.calls = 0

    def act(self, obs):
        self.calls += 1
        x = (np.arange(self.n) + 0.5) * self.dx
        s = obs.stuck.astype(np.float64)
        return 0.2 * np.sin(self.k * x - self.omega * (obs.time + 0.5 * self.step)) \
            + 0.1 * (np.roll(s, -1) - s)


def agent(features):
    return np.array([0.3 + 0.1 * math.tanh(features[-1]), 60.0, 6.3])


def co_simulate(plant_program, tmp_path, monkeypatch, policy, flags):
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    run_id = f"pytest-client-{os.getpid()}-{len(list(tmp_path.iterdir()))}"
    endpoint = f"unixsock-stream/{tmp_path}/z.sock"
    env = dict(os.environ, XDG_RUNTIME_DIR=str(tmp_path))
    plant = subprocess.Popen(
        [plant_program, "run", "--run-id", run_id, "--endpoint", endpoint, "--json", "--episodes",
         "--checkpoint", str(tmp_path / "plant.ckpt"), "--wait-timeout", "60", *flags],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        summary = softcrawler.connect(run_id, endpoint=endpoint, wait_timeout=60).run(policy)
        out, err = plant.communicate(timeout=120)
    finally:
        if plant.poll() is None:
            plant.kill()
            plant.wait()
    assert plant.returncode == 0, err
    return summary, json.loads(out)


def test_a_python_policy_drives_the_co_simulated_plant_as_the_in_process_one(
        plant_program, tmp_path, monkeypatch):
    policy = StickReflex()
    summary, plant = co_simulate(plant_program, tmp_path, monkeypatch, policy, SMALL_FLAGS)
    assert summary["steps"] == plant["macro_steps"] == policy.calls
    assert summary["policy"] == "pytest-reflex"
    local = softcrawler.run(softcrawler.Scenario(**SMALL), StickReflex())
    assert plant["state_digest"] == local.report.state_digest
    assert summary["plant"]["state_digest"] == plant["state_digest"]


def test_a_trained_agent_drives_the_co_simulated_plant_as_in_the_environment(
        plant_program, tmp_path, monkeypatch):
    from softcrawler.env import SoftCrawlerEnv

    flags = SMALL_FLAGS + ["--task"]
    policy = softcrawler.EnvPolicy(agent, action="wave", frame_skip=30)
    _, plant = co_simulate(plant_program, tmp_path, monkeypatch, policy, flags)
    env = SoftCrawlerEnv(softcrawler.Scenario(**SMALL), frame_skip=30)
    obs, _ = env.reset()
    while True:
        obs, _, term, trunc, _ = env.step(agent(obs))
        if term or trunc:
            break
    assert plant["state_digest"] == env.state_digest


def test_a_registered_policy_runs_through_the_client_too(plant_program, tmp_path, monkeypatch):
    _, plant = co_simulate(plant_program, tmp_path, monkeypatch, "wave", SMALL_FLAGS)
    assert plant["state_digest"] == softcrawler.simulate(softcrawler.Scenario(**SMALL)).state_digest


def test_no_plant_is_a_run_error_with_the_timeout_exit_code(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    with pytest.raises(softcrawler.RunError) as e:
        softcrawler.connect("pytest-nobody", no_auth=True,
                            endpoint=f"unixsock-stream/{tmp_path}/none.sock",
                            wait_timeout=1.0).run(StickReflex())
    assert e.value.exit_code == 4 or e.value.exit_code is not None
