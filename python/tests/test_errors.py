"""Inputs that are not allowed raise the package's InvalidInput, naming the field, the value and
what is allowed, as the programs do."""

from __future__ import annotations

import numpy as np
import pytest

import softcrawler
from softcrawler import InvalidInput


@pytest.mark.parametrize("make, field", [
    (lambda: softcrawler.Scenario(eps=-1.0), "friction.eps"),
    (lambda: softcrawler.Scenario(n_f=1.5), "friction.n_f"),
    (lambda: softcrawler.Scenario(cells=3), "numerics.cells"),
    (lambda: softcrawler.Scenario(t_end=float("nan")), "numerics.t_end"),
    (lambda: softcrawler.Scenario(k=-1.0), "actuation.k"),
    (lambda: softcrawler.Scenario(values={"task.sigma_max": 0.0}), "task.sigma_max"),
    (lambda: softcrawler.Scenario(values={"pipe.disclose": False}), "pipe.nominal"),
    (lambda: softcrawler.Scenario(values={"limits.omega": [300.0, 10.0]}), "limits.omega"),
    (lambda: softcrawler.Scenario(values={"friction.colour": 1.0}), "friction.colour"),
    (lambda: softcrawler.Scenario(values={"numerics.cells": "many"}), "numerics.cells"),
    (lambda: softcrawler.Scenario(spin=2.0), "spin"),
])
def test_a_bad_scenario_value_names_its_field(make, field):
    with pytest.raises(InvalidInput) as e:
        make()
    assert e.value.field == field, e.value
    assert e.value.allowed and f"invalid {field}" in str(e.value)


def test_a_bad_dict_names_the_field_and_a_missing_file_the_scenario(tmp_path):
    table = softcrawler.Scenario().to_dict()
    table["body"]["density"] = -0.1
    with pytest.raises(InvalidInput) as e:
        softcrawler.Scenario(table)
    assert (e.value.field, e.value.value) == ("body.density", "-0.1")
    with pytest.raises(InvalidInput) as e:
        softcrawler.Scenario(tmp_path / "missing.toml")
    assert e.value.field == "scenario"


def test_a_bad_file_names_the_key_on_its_line(tmp_path):
    text = softcrawler._native.PAPER_TOML.replace("eps = 0.1 ", "eps = \"high\" ")
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(InvalidInput) as e:
        softcrawler.Scenario(path)
    assert e.value.field == "friction.eps" and e.value.value.startswith('"high"')


def test_bad_actuations_and_runs_name_their_field(small):
    plant = softcrawler.Plant(small)
    with pytest.raises(InvalidInput) as e:
        plant.set_wave(0.5, 7.0, 50.0)
    assert e.value.field == "wave.k"
    with pytest.raises(InvalidInput) as e:
        plant.set_field(np.zeros(5))
    assert e.value.field == "field"
    bad = np.zeros(128)
    bad[7] = np.inf
    with pytest.raises(InvalidInput) as e:
        plant.set_field(bad)
    assert e.value.field == "field[7]"
    with pytest.raises(InvalidInput) as e:
        softcrawler.predict(small, "quantum")
    assert e.value.field == "model"
    with pytest.raises(InvalidInput) as e:
        softcrawler.optimize(small, tie_tolerance=0.5)
    assert e.value.field == "tie_tolerance"
    with pytest.raises(InvalidInput) as e:
        softcrawler.run(small, "optimal", ["colour=red"])
    assert e.value.field == "params" and "colour" in e.value.allowed
    with pytest.raises(InvalidInput) as e:
        softcrawler.run(small, "optimall")
    assert e.value.field == "policy" and "optimal" in e.value.allowed


def test_a_python_policy_that_raises_stops_the_run_with_its_exception(small):
    class Broken:
        def act(self, obs):
            if obs.step == 10:
                raise ZeroDivisionError("policy bug")
            return softcrawler.Wave(0.5, 2 * np.pi, 70.0)

    with pytest.raises(ZeroDivisionError):
        softcrawler.run(small, Broken())


def test_bad_environment_options_name_their_field():
    import softcrawler.env as env

    with pytest.raises(InvalidInput) as e:
        env.SoftCrawlerEnv(action="dance", cells=64, t_end=5.2)
    assert e.value.field == "action"
    with pytest.raises(InvalidInput) as e:
        env.SoftCrawlerEnv(fields=["smell"], cells=64, t_end=5.2)
    assert e.value.field == "fields"
    with pytest.raises(InvalidInput) as e:
        env.SoftCrawlerEnv(segments=0, cells=64, t_end=5.2)
    assert e.value.field == "segments"
    with pytest.raises(InvalidInput) as e:
        env.SoftCrawlerEnv(frame_skip=0, cells=64, t_end=5.2)
    assert e.value.field == "frame_skip"


@pytest.mark.parametrize("call, field", [
    (lambda s: softcrawler.Plant(s).step(-1), "n"),
    (lambda s: softcrawler.Plant(s).step(1.5), "n"),
    (lambda s: softcrawler.Plant(s).step(2**70), "n"),
    (lambda s: softcrawler.Plant(s, max_episodes=-1), "max_episodes"),
    (lambda s: softcrawler.simulate(s, max_episodes=True), "max_episodes"),
    (lambda s: softcrawler.optimize(s, omega_points=-3), "omega_points"),
    (lambda s: softcrawler.optimize(s, k_points="many"), "k_points"),
    (lambda s: softcrawler.sweep({"points": 3}), "plan"),
    (lambda s: softcrawler.sweep("plan.toml", jobs=0), "jobs"),
])
def test_a_bad_count_or_argument_type_names_its_argument(small, call, field):
    with pytest.raises(InvalidInput) as e:
        call(small)
    assert e.value.field == field and e.value.allowed, e.value


def test_bad_environment_arguments_name_their_field_before_anything_runs():
    import softcrawler.env as env

    kw = dict(cells=64, t_end=5.2)
    for make, field in [
        (lambda: env.SoftCrawlerEnv(frame_skip=-1, **kw), "frame_skip"),
        (lambda: env.SoftCrawlerEnv(segments=2.5, **kw), "segments"),
        (lambda: env.SoftCrawlerEnv(fields=["strain", "strain"], **kw), "fields"),
        (lambda: env.SoftCrawlerVectorEnv(-1, **kw), "num_envs"),
        (lambda: env.PipeFamily(eps=(0.5, 0.1)), "pipe_family.eps"),
        (lambda: env.PipeFamily(n_f=(float("nan"), 0.5)), "pipe_family.n_f"),
        (lambda: env.PipeFamily(n_f=(0.3, 1.0)), "pipe_family.n_f"),
        (lambda: env.PipeFamily(eps_std=-0.1), "pipe_family.eps_std"),
        (lambda: env.PipeFamily(correlation=0.0), "pipe_family.correlation"),
    ]:
        with pytest.raises(InvalidInput) as e:
            make()
        assert e.value.field == field, (field, e.value)
    one = env.SoftCrawlerEnv(**kw)
    one.reset(seed=0)
    digest = one.state_digest
    with pytest.raises(InvalidInput) as e:
        one.step("fast")
    assert e.value.field == "action"
    assert one.state_digest == digest, "a refused action takes no step"
    vec = env.SoftCrawlerVectorEnv(3, **kw)
    vec.reset(seed=0)
    with pytest.raises(InvalidInput) as e:
        vec.reset(seed=[1, 2])
    assert e.value.field == "seed"
    with pytest.raises(InvalidInput) as e:
        vec.step([["fast"] * 3] * 3)
    assert e.value.field == "actions"


@pytest.mark.parametrize("options, field", [
    (dict(run_id="a*b"), "run_id"),  # a key-expression wildcard: another run's keys
    (dict(run_id="../up"), "run_id"),
    (dict(run_id="r1", endpoint="tcp/0.0.0.0:7447"), "endpoint"),  # not loopback
    (dict(run_id="r1", zenoh_config="/nonexistent/zenoh.json5"), "zenoh_config"),
    (dict(run_id="r1", wait_timeout=float("nan")), "wait_timeout"),
])
def test_bad_network_options_name_their_argument_before_any_connection(options, field):
    class Still:
        def act(self, obs):
            return softcrawler.Wave(0.0, 2 * np.pi, 10.0)

    with pytest.raises(InvalidInput) as e:
        softcrawler.connect(**options).run(Still())
    assert e.value.field == field, e.value


def test_a_refused_vector_step_steps_and_resets_no_crawler():
    import softcrawler.env as env

    vec = env.SoftCrawlerVectorEnv(4, cells=64, t_end=5.2, frame_skip=40)
    vec.reset(seed=0)
    w = vec.base.wave
    good = np.tile([0.1, w["omega"], w["k"]], (4, 1))
    good[0, 0] = 5.0  # f0_max: crawler 0 spends J0 long before the others end
    for _ in range(200):  # until a crawler's episode has ended (reset at the next step)
        vec.step(good)
        if vec._autoreset.any():
            break
    assert vec._autoreset.any()
    before = [vec.state_digest(i) for i in range(4)]
    bad = good.copy()
    bad[int(np.flatnonzero(~vec._autoreset)[0]), 1] = np.nan
    with pytest.raises(InvalidInput) as e:
        vec.step(bad)
    assert e.value.field.startswith("actions[")
    assert [vec.state_digest(i) for i in range(4)] == before, "nothing stepped, nothing reset"
    with pytest.raises(InvalidInput) as e:
        env.PipeFamily(eps=0.3)
    assert e.value.field == "pipe_family.eps"
    with pytest.raises(InvalidInput) as e:
        env.PipeFamily(extent="far")
    assert e.value.field == "pipe_family.extent"
