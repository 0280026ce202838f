"""Shared fixtures: the project's programs (to compare with), small scenarios."""

from __future__ import annotations

import json
import os
import pathlib
import subprocess

import pytest

import softcrawler

ROOT = pathlib.Path(__file__).resolve().parents[2]


def bin_dir() -> pathlib.Path:
    """Where the workspace's binaries are: $CRAWLER_BIN_DIR (set by tests/tests/python_package.rs)
    or target/release."""
    return pathlib.Path(os.environ.get("CRAWLER_BIN_DIR", ROOT / "target" / "release"))


def program(name: str) -> str:
    p = bin_dir() / name
    assert p.is_file(), f"{p} not found: build the workspace's binaries (cargo build --release --workspace --bins)"
    return str(p)


def run_json(args: list[str], **kw) -> dict:
    out = subprocess.run(args, capture_output=True, text=True, check=False, **kw)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


@pytest.fixture(scope="session")
def plant_program() -> str:
    return program("crawler-plant")


@pytest.fixture(scope="session")
def controller_program() -> str:
    return program("crawler-controller")


#: The paper's scenario, small: 128 cells, the shortest run its steady window allows.
SMALL = dict(cells=128, t_end=5.2)
SMALL_FLAGS = ["--cells", "128", "--t-end", "5.2"]


@pytest.fixture
def small() -> softcrawler.Scenario:
    return softcrawler.Scenario(**SMALL)
