"""simulate and a stepped Plant give `crawler-plant simulate --json`'s report, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

import softcrawler
from conftest import ROOT, SMALL_FLAGS, run_json


def cli(plant_program: str, flags: list[str]) -> dict:
    return run_json([plant_program, "simulate", "--json", "--episodes", *flags])


def test_simulate_equals_the_plant_programs_report_bit_for_bit(plant_program, small):
    assert softcrawler.simulate(small).to_dict() == cli(plant_program, SMALL_FLAGS)


@pytest.mark.parametrize("case, flags, kwargs", [
    ("stick-slip", ["--scenario", str(ROOT / "scenarios/stick-slip.toml"), "--cells", "96",
                    "--t-end", "5.3"], dict(cells=96, t_end=5.3)),
    ("patchy, task mode", ["--scenario", str(ROOT / "scenarios/patchy-pipe.toml"), "--cells", "64",
                           "--t-end", "6", "--task"], dict(cells=64, t_end=6.0, task=True)),
    ("free body", ["--scenario", str(ROOT / "scenarios/free-body.toml"), "--cells", "160",
                   "--t-end", "5.3", "--alpha", "0.7"], dict(cells=160, t_end=5.3, alpha=0.7)),
])
def test_scenario_files_with_overrides_give_the_programs_report(plant_program, case, flags, kwargs):
    path = flags[1]
    report = softcrawler.simulate(softcrawler.Scenario(path, **kwargs))
    assert report.to_dict() == cli(plant_program, flags), case


def test_a_plant_stepped_one_and_many_steps_at_a_time_gives_the_same_report(plant_program, small):
    expected = cli(plant_program, SMALL_FLAGS)
    plant = softcrawler.Plant(small)
    while plant.step() == 1:
        pass
    assert plant.finished
    assert plant.report().to_dict() == expected
    chunked = softcrawler.Plant(small)
    taken = 0
    for n in (1, 7, 100, 3, 10_000_000):
        taken += chunked.step(n)
    assert taken == expected["macro_steps"]
    assert chunked.report().to_dict() == expected


def test_a_plant_driven_by_set_wave_equals_the_scenario_with_that_wave(plant_program, small):
    w = small.wave
    plant = softcrawler.Plant(small, start_wave=False)
    plant.set_wave(0.3, w["k"], 0.8 * w["omega"])
    plant.run()
    flags = SMALL_FLAGS + ["--f0", "0.3", "--omega", repr(0.8 * w["omega"])]
    assert plant.report().state_digest == cli(plant_program, flags)["state_digest"]


def test_fields_are_read_only_arrays_of_the_plant_at_that_instant(small):
    plant = softcrawler.Plant(small)
    plant.step(50)
    u = plant.u
    assert u.shape == (128,) and u.dtype == np.float64 and not u.flags.writeable
    assert plant.stuck.dtype == np.bool_ and plant.tension.shape == (128,)
    before = u.copy()
    plant.step(10)
    assert np.array_equal(u, before), "a field is a copy of its instant"
    assert not np.array_equal(plant.u, before)
    obs = plant.observation()
    assert obs.step == 60 and np.array_equal(obs.u, plant.u) and np.array_equal(obs.vel, plant.vel)
    assert obs.time == pytest.approx(60 * plant.step_length, rel=1e-12)
    # the mean of u moves by the reported mean speed over the step
    u0 = plant.u.mean()
    plant.step()
    assert plant.u.mean() - u0 == pytest.approx(plant.outputs["mean_speed"] * plant.step_length,
                                                rel=1e-9, abs=1e-15)
