"""Every registered method through ``plan()``: shapes, budget, determinism; and what
``independent`` and ``weighted`` promise in particular."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from staghunt import api
from staghunt.costs import CostModel, evaluate
from staghunt.scenario import load_scenario
from staghunt.solvers import DESCRIPTIONS, METHODS
from staghunt.solvers.independent import solo_model

P, I, K = 10, 3, 6


def plan(*args, **kwargs):
    """``staghunt.plan`` on the NumPy reference engine (pinned when plan() offers engines)."""
    return api.plan(*args, **kwargs, engine="numpy")


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("scenario2")


@pytest.fixture(scope="module")
def settings(scenario):
    return scenario.solver.with_(particles=P, iterations=I, waypoints=K)


@pytest.fixture(scope="module")
def results(scenario, settings):
    return {m: plan(scenario, m, 3, settings) for m in METHODS}


def test_registry_has_the_five_methods():
    for name in ("game", "paper", "rigid", "independent", "weighted"):
        assert name in METHODS and DESCRIPTIONS[name]


@pytest.mark.parametrize("method", sorted(METHODS))
def test_shapes_and_history(method, results, scenario):
    r = results[method]
    N = scenario.n_uavs
    assert r.method == method
    assert r.waypoints.shape == (N, K, 3)
    assert r.paths.shape == (N, K + 2, 3)
    assert r.history.shape == (I + 1, N)
    assert r.objective_history.shape[0] == I + 1
    # As for every method, the last history row is the plan's J_n (team cost model).
    np.testing.assert_array_equal(r.history[-1], r.costs.total[0])


@pytest.mark.parametrize("method", sorted(METHODS))
def test_same_budget_in_path_evaluations(method, results, scenario):
    """Fair budget: particles x (iterations + 1) joint evaluations of N paths, counted as N
    single-UAV path evaluations each (independent: N one-UAV runs of the same size; game: at
    most that, it stops early once its best-response rounds have converged)."""
    budget = P * (I + 1) * scenario.n_uavs
    if method == "game":
        assert 0 < results[method].evaluations <= budget
    else:
        assert results[method].evaluations == budget


@pytest.mark.parametrize("method", sorted(METHODS))
def test_seeded_runs_repeat_and_seeds_differ(method, results, scenario, settings):
    again = plan(scenario, method, 3, settings)
    np.testing.assert_array_equal(again.waypoints, results[method].waypoints)
    np.testing.assert_array_equal(again.history, results[method].history)
    np.testing.assert_array_equal(again.objective_history, results[method].objective_history)
    other = plan(scenario, method, 4, settings)
    assert not np.array_equal(other.waypoints, results[method].waypoints)


# ------------------------------------------------------------------------------------------------
# independent
# ------------------------------------------------------------------------------------------------


def test_solo_model_cost_is_the_single_uav_cost(results, scenario):
    model = CostModel.from_scenario(scenario)
    wp = results["paper"].waypoints
    team = evaluate(model, wp[None])
    for n in range(scenario.n_uavs):
        solo = solo_model(model, n)
        assert solo.n_uavs == 1 and solo.mu.shape == (1, 0)
        c = evaluate(solo, wp[None, n : n + 1])
        assert c.formation[0, 0] == 0.0
        assert c.total[0, 0] == team.single[0, n]


def test_independent_reports_own_costs_then_team_cost(results):
    r = results["independent"]
    own = r.objective_history
    assert own.shape == r.history.shape
    # Each UAV's own best J_s never gets worse, and ends at the plan's J_s.
    assert np.all(np.diff(own, axis=0) <= 0)
    np.testing.assert_array_equal(own[-1], r.costs.single[0])
    np.testing.assert_array_equal(r.history[:-1], own[:-1])


def test_independent_ignores_the_team(scenario, settings, results):
    """Changing the formation weights (beta) and the formation graph changes nothing."""
    team = tuple(dataclasses.replace(u, weights=dataclasses.replace(u.weights, beta=0.0))
                 for u in scenario.team)
    other = dataclasses.replace(scenario, team=team)
    r = plan(other, "independent", 3, settings)
    np.testing.assert_array_equal(r.waypoints, results["independent"].waypoints)


def test_independent_progress_spans_all_runs(scenario, settings):
    seen = []
    plan(scenario, "independent", 0, settings, lambda it, total, best: seen.append((it, total)))
    N = scenario.n_uavs
    assert [t for _, t in seen] == [N * I] * (N * I)
    assert [it for it, _ in seen] == list(range(1, N * I + 1))


# ------------------------------------------------------------------------------------------------
# weighted
# ------------------------------------------------------------------------------------------------


def test_weighted_minimises_the_team_sum(results):
    r = results["weighted"]
    assert r.objective_history.shape == (I + 1, 1)
    finite = np.all(np.isfinite(r.history), axis=1)
    np.testing.assert_allclose(r.objective_history[finite, 0], r.history[finite].sum(axis=1), rtol=1e-12)
    if finite.all():
        assert np.all(np.diff(r.objective_history[:, 0]) <= 0)
