"""predict and optimize give the Rust programs' numbers (crawler-controller predict / optimize)."""

from __future__ import annotations

import pytest

import softcrawler
from conftest import ROOT, run_json


@pytest.mark.parametrize("model", ["paper", "improved"])
@pytest.mark.parametrize("flags, kwargs", [
    ([], {}),
    (["--eps", "0.6", "--alpha", "0.8", "--f0", "0.3"], dict(eps=0.6, alpha=0.8, f0=0.3)),
    (["--scenario", str(ROOT / "scenarios/stick-slip.toml")], None),
])
def test_predictions_equal_the_controller_programs(controller_program, model, flags, kwargs):
    scenario = (softcrawler.Scenario(flags[1]) if kwargs is None
                else softcrawler.Scenario(**kwargs))
    expected = run_json([controller_program, "predict", "--model", model, *flags])
    p = softcrawler.predict(scenario, model)
    assert p.to_dict() == expected
    assert p.model == model and (p.velocity is None) == (not p.valid)


def test_the_improved_models_march_steps_are_passed_on(controller_program):
    expected = run_json([controller_program, "predict", "--model", "improved", "--march-steps", "256"])
    assert softcrawler.predict(None, "improved", march_steps=256).to_dict() == expected


def test_the_optimum_equals_the_programs(controller_program):
    flags = ["--model", "paper", "--omega-points", "40", "--k-points", "30"]
    expected = run_json([controller_program, "optimize", "--json", *flags])
    got = softcrawler.optimize(None, "paper", omega_points=40, k_points=30)
    d = got.to_dict()
    for e in (expected, d):
        e.pop("seconds")
    assert d == expected
    o = got.optimum
    assert (o.omega, o.k, o.f0) == (expected["optimum"]["omega"], expected["optimum"]["k"],
                                    expected["optimum"]["f0"])
    assert all(m >= -1e-9 for m in o.margins.values())


def test_the_certified_optimum_equals_the_programs_on_the_same_plant(controller_program):
    flags = ["--model", "improved", "--omega-points", "8", "--k-points", "6", "--certify",
             "--cells", "64", "--t-end", "6"]
    expected = run_json([controller_program, "optimize", "--json", *flags])
    got = softcrawler.optimize(softcrawler.Scenario(cells=64, t_end=6.0), "improved",
                               omega_points=8, k_points=6, certify=True)
    d = got.to_dict()
    for e in (expected, d):
        e.pop("seconds")
    assert d == expected
    assert got.certification is not None and got.certified_f0 == expected["certification"]["f0"]
    assert got.certification["runs"], "certification runs the plant"
