"""Formation error (eq. 5, both forms), collision (eq. 6), formation cost (eq. 7), separation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from staghunt.costs import CostModel, evaluate, formation_cost
from staghunt.costs.formation import (
    formation_errors,
    nearest_segment_distance,
    nearest_waypoint_distance,
)
from staghunt.scenario.model import CostParams, Scenario, SolverSettings
from staghunt.task import (
    UAV,
    Formation,
    Weights,
    formation_error_edges,
    formation_error_quadratic,
    is_connected,
)
from staghunt.world import Bounds, Terrain, World

PAPER_D = np.array([[1, 1, 0], [-1, 0, 1], [0, -1, -1]], float)
PAPER_MU = np.array([[1, 1, 0], [1, 0, 1], [0, 1, 1]], float)
PAPER_GOALS = np.array([[85, 88.66, 20], [80, 80, 20], [90, 80, 20]], float)


def paper_formation() -> Formation:
    return Formation(incidence=PAPER_D, edge_weights=PAPER_MU, reference=PAPER_GOALS)


def random_connected(rng: np.random.Generator, n: int, extra: int) -> Formation:
    """Random spanning tree plus ``extra`` edges, random orientation and weights."""
    edges = [(i, int(rng.integers(0, i))) for i in range(1, n)]
    while len(edges) < n - 1 + extra:
        a, b = rng.choice(n, size=2, replace=False)
        if (a, b) not in edges and (b, a) not in edges:
            edges.append((int(a), int(b)))
    D = np.zeros((n, len(edges)))
    for e, (a, b) in enumerate(edges):
        if rng.random() < 0.5:
            a, b = b, a
        D[a, e], D[b, e] = 1.0, -1.0
    mu = rng.uniform(0.0, 3.0, size=(n, len(edges)))
    mu[rng.random(mu.shape) < 0.3] = 0.0
    return Formation(incidence=D, edge_weights=mu, reference=rng.normal(scale=20, size=(n, 3)))


def build_model(starts, goals, formation=None, *, radius=1.0, safe=2.0, continuous=False, beta=1.0):
    starts = np.asarray(starts, float)
    goals = np.asarray(goals, float)
    n = len(starts)
    if formation is None:
        formation = Formation(np.zeros((n, 0)), np.zeros((n, 0)), goals.copy())
    team = tuple(
        UAV(f"u{i}", tuple(starts[i]), tuple(goals[i]), radius, Weights(beta, 1, 1, 1, 1, 1))
        for i in range(n)
    )
    world = World(Bounds(-1000, 1000, -1000, 1000, 0, 30), Terrain())
    costs = CostParams(safe_distance=safe, continuous_separation=continuous)
    return CostModel.from_scenario(
        Scenario("t", "", world, team, formation, costs, SolverSettings())
    )


# ------------------------------------------------------------------------------------- eq. 5


@pytest.mark.parametrize("which", ["paper", "random5"])
def test_both_forms_agree_translation_invariant_zero_at_reference(which):
    rng = np.random.default_rng(11)
    f = paper_formation() if which == "paper" else random_connected(rng, 5, 3)
    n = f.incidence.shape[0]
    assert is_connected(f.incidence)
    pos = rng.normal(scale=30.0, size=(50, 7, n, 3))  # any leading batch axes
    e1 = formation_error_edges(pos, f)
    e2 = formation_error_quadratic(pos, f)
    assert e1.shape == (50, 7, n)
    np.testing.assert_allclose(e1, e2, rtol=1e-10, atol=1e-8)
    assert np.all(e1 >= 0) and np.all(e1 > 0)  # random positions are never in shape
    # translation invariance
    shifted = pos + rng.normal(scale=100.0, size=(50, 7, 1, 3))
    np.testing.assert_allclose(formation_error_edges(shifted, f), e1, rtol=1e-9, atol=1e-7)
    np.testing.assert_allclose(formation_error_quadratic(shifted, f), e1, rtol=1e-9, atol=1e-6)
    # zero at the reference shape, wherever it is translated
    at_ref = f.reference + np.array([3.0, -7.0, 11.0])
    np.testing.assert_allclose(formation_error_edges(at_ref, f), 0.0, atol=1e-20)
    np.testing.assert_allclose(formation_error_quadratic(at_ref, f), 0.0, atol=1e-9)
    # the batched cost engine (costs.formation) agrees with the task-level edge form
    heads, tails = f.heads_tails()
    ref = f.reference
    wp = np.moveaxis(pos, 1, 2)  # (P, N, K, 3)
    E = formation_errors(wp, heads, tails, ref[heads] - ref[tails], f.edge_weights)
    np.testing.assert_allclose(E, np.moveaxis(e1, 1, 2), rtol=1e-12)


def test_hand_value_paper_graph():
    # Reference (0,0,0), (1,0,0), (0,1,0); positions (0,0,0), (2,0,0), (0,1,1).
    # e0 = 0->1 (head 0, tail 1): (0-2, 0, 0) - (-1, 0, 0) = (-1, 0, 0)  -> 1
    # e1 = 0->2: (0, -1, -1) - (0, -1, 0) = (0, 0, -1)                   -> 1
    # e2 = 1->2: (2, -1, -1) - (1, -1, 0) = (1, 0, -1)                   -> 2
    # E1 = e0 + e1 = 2;  E2 = e0 + e2 = 3;  E3 = e1 + e2 = 3.
    f = Formation(PAPER_D, PAPER_MU, np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float))
    pos = np.array([[0, 0, 0], [2, 0, 0], [0, 1, 1]], float)
    np.testing.assert_allclose(formation_error_edges(pos, f), [2.0, 3.0, 3.0], atol=1e-14)
    np.testing.assert_allclose(formation_error_quadratic(pos, f), [2.0, 3.0, 3.0], atol=1e-12)
    # weights scale the edges: mu_1 = (2, 0.5, 0) -> 2*1 + 0.5*1 = 2.5
    mu = PAPER_MU.copy()
    mu[0] = [2.0, 0.5, 0.0]
    f2 = Formation(PAPER_D, mu, f.reference)
    assert formation_error_edges(pos, f2)[0] == pytest.approx(2.5)
    assert formation_error_quadratic(pos, f2)[0] == pytest.approx(2.5)


def test_formation_cost_sums_over_free_waypoints():
    # Two UAVs, edge 0->1, reference = goals -> P_0,r - P_1,r = (0, -50, 0).
    # K = 2: waypoint diffs (0,-40,0) and (0,-53,0) -> dev (0,10,0), (0,-3,0) -> 100 + 9 = 109
    # each (mu = 1 for both); the start and goal are not counted.
    f = Formation(np.array([[1.0], [-1.0]]), np.ones((2, 1)), np.array([[40, 0, 10], [40, 50, 10]], float))
    m = build_model([[0, 0, 10], [0, 90, 10]], [[40, 0, 10], [40, 50, 10]], f)
    wp = np.array([[[[10, 0, 10], [20, 0, 10]], [[10, 40, 10], [20, 53, 10]]]], float)
    c = evaluate(m, wp)
    np.testing.assert_allclose(c.formation, [[109.0, 109.0]], atol=1e-10)


# ------------------------------------------------------------------------------------- eq. 6


@pytest.mark.parametrize(
    "gap, is_inf",
    [(3.0, True), (4.0, True), (4.000001, False), (10.0, False)],
)
def test_collision_threshold_at_waypoint(gap, is_inf):
    # r = 1, d_s = 2 -> limit d_s + 2r = 4; "<=" is a collision (exactly 4 too).
    m = build_model([[0, 0, 10], [0, 100, 10]], [[50, 0, 10], [50, 100, 10]], safe=2.0)
    wp = np.array([[[[25, 50, 10], [30, 0, 10]], [[25, 50 + gap, 10], [30, 100, 10]]]], float)
    jf, deficit = formation_cost(m, np.concatenate(
        [m.starts[None, :, None], wp, m.goals[None, :, None]], axis=2))
    if is_inf:
        assert np.all(jf == math.inf)
        assert np.all(deficit > 0)
        assert deficit[0, 0] == pytest.approx(max(4.0 - gap, 1e-9))
    else:
        assert np.all(np.isfinite(jf)) and np.all(deficit == 0)
    c = evaluate(m, wp)
    assert np.all((c.formation == math.inf) == is_inf)
    assert np.all((c.violation[..., 2] > 0) == is_inf)


def test_nearest_waypoint_distance():
    # Two UAVs: distances 3 at waypoint 0 and 30 at waypoint 1.
    wp = np.array([[[[0, 0, 10], [0, 0, 10]], [[3, 0, 10], [30, 0, 10]]]], float)
    near = nearest_waypoint_distance(wp)
    np.testing.assert_allclose(near, [[[3.0, 30.0], [3.0, 30.0]]])
    # three UAVs: nearest is the minimum over team-mates
    wp3 = np.array([[[[0, 0, 0]], [[5, 0, 0]], [[0, 12, 0]]]], float)
    np.testing.assert_allclose(nearest_waypoint_distance(wp3)[0, :, 0], [5.0, 5.0, 12.0])


def test_crossing_between_waypoints_is_caught_by_segment_check():
    # A: start (0,-20) -> (0,0) -> (10,0) -> goal (10,-20)
    # B: start (10,20) -> (10,0) -> (0,0) -> goal (0,20)
    # At both waypoints they are 10 apart (> limit 4); between them they meet at (5, 0).
    starts = [[0, -20, 10], [10, 20, 10]]
    goals = [[10, -20, 10], [0, 20, 10]]
    wp = np.array([[[[0, 0, 10], [10, 0, 10]], [[10, 0, 10], [0, 0, 10]]]], float)
    abs_path = np.concatenate(
        [np.array(starts, float)[None, :, None], wp, np.array(goals, float)[None, :, None]], axis=2
    )
    np.testing.assert_allclose(nearest_waypoint_distance(wp), 10.0)
    seg = nearest_segment_distance(abs_path)  # (1, 2, 3)
    np.testing.assert_allclose(seg[0, :, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(seg[0, :, 0], 10.0)  # (0,-20+20t) vs (10,20-20t): min at t=1
    np.testing.assert_allclose(seg[0, :, 2], 10.0)
    waypoint_only = evaluate(build_model(starts, goals, continuous=False), wp)
    assert np.all(np.isfinite(waypoint_only.formation))
    assert np.all(waypoint_only.violation == 0)
    continuous = evaluate(build_model(starts, goals, continuous=True), wp)
    assert np.all(continuous.formation == math.inf)
    np.testing.assert_allclose(continuous.violation[0, :, 2], 4.0)  # limit 4 - closest 0


def test_segment_distance_parallel_and_static():
    # Parallel motion 3 apart: constant 3; static (both segments zero-length) -> the point distance.
    path = np.array([[[[0, 0, 0], [10, 0, 0], [10, 0, 0]], [[0, 3, 0], [10, 3, 0], [10, 3, 0]]]], float)
    np.testing.assert_allclose(nearest_segment_distance(path), 3.0)
    # closest approach inside a segment: A (0,0)->(10,0), B (0,10)->(10,-10) relative (0,10)->(0,-10)
    path = np.array([[[[0, 0, 0], [10, 0, 0]], [[0, 10, 0], [10, -10, 0]]]], float)
    np.testing.assert_allclose(nearest_segment_distance(path), 0.0, atol=1e-12)
    path = np.array([[[[0, 0, 0], [10, 0, 0]], [[0, 10, 2], [10, -10, 2]]]], float)
    np.testing.assert_allclose(nearest_segment_distance(path), 2.0, atol=1e-12)


def test_single_uav_has_zero_formation_cost():
    m = build_model([[0, 0, 10]], [[50, 0, 10]], continuous=True, beta=5.0)
    assert m.mu.shape == (1, 0)
    wp = np.random.default_rng(0).uniform(0, 30, size=(6, 1, 4, 3))
    c = evaluate(m, wp)
    np.testing.assert_array_equal(c.formation, 0.0)
    np.testing.assert_array_equal(c.violation[..., 2], 0.0)
    np.testing.assert_array_equal(c.total, c.single)
    assert np.all(nearest_waypoint_distance(wp) == math.inf)
