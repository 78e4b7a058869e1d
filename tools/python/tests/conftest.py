"""Shared fixtures of the Python package's tests (run by .ci/run after
`pip install .`; every input comes from the repository or the simulator)."""

from pathlib import Path

import pytest

import echofield

ROOT = Path(__file__).resolve().parents[3]
"""The repository root (tools/python/tests/ is three levels down)."""


LOOPS = {"loops": {"min_separation_nodes": 3}}
"""A config under which the tank's second lap closes loops with the first
(the default needs 10 rotations between the nodes of a loop, and the tank
has 10 in all)."""


@pytest.fixture(scope="session")
def tank_path() -> Path:
    """The committed tank mission: 143 s, about 10 rotations, ground truth."""
    return ROOT / "datasets" / "samples" / "tank-seed1.mcap"


@pytest.fixture(scope="session")
def tank(tank_path):
    return echofield.load_mission(tank_path)


@pytest.fixture(scope="session")
def tank_result(tank):
    return echofield.run(tank, config=LOOPS)
