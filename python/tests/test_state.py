"""A run's state survives get/set and bytes, and continues bit-identically."""

from __future__ import annotations

import pytest

import softcrawler


def test_a_run_continued_from_its_serialised_state_is_the_run_never_stopped(small):
    whole = softcrawler.Plant(small)
    whole.run()
    first = softcrawler.Plant(small)
    first.step(2_000)
    data = first.get_state().to_bytes()
    state = softcrawler.State.from_bytes(data)
    assert state.step == 2_000
    second = softcrawler.Plant(small)
    second.set_state(state)
    assert second.steps == 2_000 and second.state_digest == first.state_digest
    second.run()
    assert second.report().to_dict() == whole.report().to_dict()


def test_a_state_can_rewind_a_plant(small):
    plant = softcrawler.Plant(small)
    plant.step(100)
    state = plant.get_state()
    plant.step(100)
    digest = plant.state_digest
    plant.set_state(state)
    assert plant.steps == 100
    plant.step(100)
    assert plant.state_digest == digest


def test_a_damaged_state_is_refused_with_its_field_named(small):
    data = bytearray(softcrawler.Plant(small).get_state().to_bytes())
    data[len(data) // 2] ^= 0xFF
    with pytest.raises(softcrawler.InvalidInput) as e:
        softcrawler.State.from_bytes(bytes(data))
    assert e.value.field == "state"


def test_a_state_of_another_scenario_is_refused(small):
    other = softcrawler.Plant(softcrawler.Scenario(cells=128, t_end=5.2, eps=0.3))
    with pytest.raises(softcrawler.InvalidInput) as e:
        softcrawler.Plant(small).set_state(other.get_state())
    assert e.value.field == "state.params"
