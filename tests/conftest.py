"""Fixtures shared by several test modules."""

from __future__ import annotations

import pytest

from staghunt import plan
from staghunt.io.result_json import write_result
from staghunt.scenario import load_scenario


@pytest.fixture(scope="session")
def planned(tmp_path_factory):
    """Scenario 2 planned by ``rigid`` at a small budget (feasible, safe in time), and its
    ``result.json``: ``(scenario, result, path)``."""
    scenario = load_scenario("scenario2")
    result = plan(scenario, "rigid", 1, scenario.solver.with_(particles=200, iterations=60), engine="numba")
    assert result.feasible, result.message
    path = tmp_path_factory.mktemp("plan") / "result.json"
    write_result(result, path)
    return scenario, result, path
