"""Hand-computed values for every branch of every single-UAV cost term (docs/model.md eq. (2)) and J_n."""

from __future__ import annotations

import math

import numpy as np
import pytest

from staghunt.costs import CostModel, evaluate
from staghunt.costs.single import (
    altitude_cost,
    path_length,
    segment_axis_distance,
    smoothness_terms,
    threat_cost,
    weighted_sum,
)
from staghunt.scenario.model import CostParams, Scenario, SolverSettings
from staghunt.task import UAV, Formation, Weights
from staghunt.world import Bounds, Cylinder, Terrain, World

INF = math.inf


def build_model(
    starts,
    goals,
    *,
    cylinders=(),
    terrain: Terrain | None = None,
    bounds=(-1000.0, 1000.0, -1000.0, 1000.0, 0.0, 30.0),
    weights=(1.0, 1.0, 1.0, 1.0, 1.0),
    beta=0.0,
    radius=1.0,
    danger=10.0,
    safe=2.0,
    thresholds=(0.0, 0.0),
    desired_height=None,
    continuous=False,
    incidence=None,
    edge_weights=None,
) -> CostModel:
    """A CostModel through the public dataclasses (no TOML)."""
    starts = np.asarray(starts, float)
    goals = np.asarray(goals, float)
    n = len(starts)
    team = tuple(
        UAV(f"u{i}", tuple(starts[i]), tuple(goals[i]), radius, Weights(beta, *weights))
        for i in range(n)
    )
    if incidence is None:
        incidence = np.zeros((n, 0))
        edge_weights = np.zeros((n, 0))
    form = Formation(
        incidence=np.asarray(incidence, float),
        edge_weights=np.asarray(edge_weights, float),
        reference=goals.copy(),
    )
    world = World(
        bounds=Bounds(*bounds),
        terrain=terrain if terrain is not None else Terrain(),
        cylinders=tuple(Cylinder(*c) for c in cylinders),
    )
    costs = CostParams(
        danger_margin=danger,
        safe_distance=safe,
        turning_threshold_deg=thresholds[0],
        climb_threshold_deg=thresholds[1],
        desired_height=desired_height,
        continuous_separation=continuous,
    )
    sc = Scenario("t", "", world, team, form, costs, SolverSettings())
    return CostModel.from_scenario(sc)


def one(path) -> np.ndarray:
    """A single full path as a (1, 1, n, 3) array."""
    return np.asarray(path, float)[None, None]


# --------------------------------------------------------------------------------------- length


def test_length_direct_3d():
    # (0,0,0)->(3,4,12): sqrt(9+16+144) = 13; ->(3,4,12) repeated: 0; ->(3,0,15): sqrt(16+9) = 5.
    L = path_length(one([[0, 0, 0], [3, 4, 12], [3, 4, 12], [3, 0, 15]]))
    assert L.shape == (1, 1)
    assert L[0, 0] == pytest.approx(18.0, abs=1e-12)


def test_length_uses_absolute_altitude_over_dem_and_start_goal_segments():
    # DEM cell centres at x, y in {0, 4}: g(0,0)=0, g(4,0)=3, g(0,4)=0, g(4,4)=7.
    terrain = Terrain(
        elevation=np.array([[0.0, 3.0], [0.0, 7.0]]), origin=(0.0, 0.0), cell_size=4.0
    )
    # S=(0,0,h2) -> z=2;  W1=(4,0,h2) -> z=5;  W2=(4,4,h1) -> z=8;  G=(0,4,h8) -> z=8.
    # S->W1: (4,0,3) = 5;  W1->W2: (0,4,3) = 5;  W2->G: (-4,0,0) = 4;  total 14.
    # (With heights instead of altitudes it would be 4 + sqrt(17) + sqrt(65) ~ 16.19.)
    m = build_model([[0, 0, 2]], [[0, 4, 8]], terrain=terrain, bounds=(0, 4, 0, 4, 0, 40))
    wp = np.array([[4, 0, 2], [4, 4, 1]], float)[None, None]
    c = evaluate(m, wp)
    assert c.terms[0, 0, 0] == pytest.approx(14.0, abs=1e-12)


# --------------------------------------------------------------------------------------- threats


def test_threat_every_branch_single_segment():
    # Cylinder (0, 0, R=5), r = 1, Delta = 10: inner 6, outer 16. Horizontal segments y = c.
    cyl = np.array([[0.0, 0.0, 5.0]])
    r = np.array([1.0])
    cases = [
        (20.0, 0.0),  # d = 20 > 16 -> 0
        (16.0, 0.0),  # d = 16 = outer -> 16 - 16 = 0 (danger branch, boundary)
        (10.0, 6.0),  # inside the band: 16 - 10 = 6
        (6.0, 10.0),  # exactly d = R + r -> Delta = 10, finite
        (5.0, INF),  # d < R + r -> inf
    ]
    for y, expected in cases:
        xy = np.array([[-10.0, y], [10.0, y]])[None, None]
        d = segment_axis_distance(xy, cyl)
        assert d.shape == (1, 1, 1, 1)
        assert d[0, 0, 0, 0] == y
        cost, depth = threat_cost(d, cyl, r, 10.0)
        assert cost[0, 0] == expected, y
        # violation depth: positive exactly when the cost is inf (5 -> 6 - 5 = 1)
        assert depth[0, 0] == (1.0 if expected == INF else 0.0)


def test_threat_min_clearance_moves_only_the_infeasible_boundary():
    # Cylinder (0, 0, R=5), r = 1, c = 2, Delta = 10: infeasible below 8, band up to 16.
    cyl = np.array([[0.0, 0.0, 5.0]])
    r = np.array([1.0])
    for y, expected, depth in [(20.0, 0.0, 0.0), (16.0, 0.0, 0.0), (10.0, 6.0, 0.0),
                               (8.0, 8.0, 0.0), (7.5, INF, 0.5), (5.0, INF, 3.0)]:
        d = segment_axis_distance(np.array([[-10.0, y], [10.0, y]])[None, None], cyl)
        cost, dep = threat_cost(d, cyl, r, 10.0, 2.0)
        assert cost[0, 0] == expected, y
        assert dep[0, 0] == depth, y
    # a clearance wider than the danger band: infeasible inside R + r + c, free beyond it
    for y, expected in [(17.0, INF), (18.0, 0.0)]:
        d = segment_axis_distance(np.array([[-10.0, y], [10.0, y]])[None, None], cyl)
        assert threat_cost(d, cyl, r, 10.0, 12.0)[0][0, 0] == expected


def test_threat_foot_outside_zero_length_and_sums():
    # Path xy: A=(8,6) -> B=(20,6) -> B (zero-length) -> C=(20,20).
    # C1 = (0, 0, R=5): inner 6, outer 16.   C2 = (24, 9, R=2): inner 3, outer 13.
    xy = np.array([[8, 6], [20, 6], [20, 6], [20, 20]], float)[None, None]
    cyl = np.array([[0.0, 0.0, 5.0], [24.0, 9.0, 2.0]])
    d = segment_axis_distance(xy, cyl)[0, 0]  # (S=3, T=2)
    # C1, seg AB: the line y=6 would give 6, but the foot (0,6) is outside [8,20] -> |A| = 10.
    # C1, seg BB: the point B: sqrt(400+36).  C1, seg BC: foot (20,0) outside -> |B| again.
    # C2, seg AB: foot (24,6) outside -> |B - C2| = |(-4,-3)| = 5.
    # C2, seg BB: point B -> 5.   C2, seg BC: foot (20,9) inside -> 4.
    expected = np.array([[10.0, 5.0], [math.sqrt(436.0), 5.0], [math.sqrt(436.0), 4.0]])
    np.testing.assert_allclose(d, expected, rtol=0, atol=1e-12)
    cost, depth = threat_cost(d[None, None], cyl, np.array([1.0]), 10.0)
    # C1: 16 - 10 = 6, 0, 0.   C2: 13 - 5 = 8, 8, 13 - 4 = 9.   Sum = 31.
    assert cost[0, 0] == pytest.approx(31.0, abs=1e-12)
    assert depth[0, 0] == 0.0


def test_threat_radius_per_uav():
    # Same segment at d = 6 from a R=5 cylinder; UAV 0 radius 1 (d == R+r -> Delta=10),
    # UAV 1 radius 1.5 (d < 6.5 -> inf).
    xy = np.array([[[-10, 6], [10, 6]], [[-10, 6], [10, 6]]], float)[None]
    cyl = np.array([[0.0, 0.0, 5.0]])
    cost, depth = threat_cost(segment_axis_distance(xy, cyl), cyl, np.array([1.0, 1.5]), 10.0)
    assert cost[0, 0] == 10.0 and cost[0, 1] == INF
    assert depth[0, 0] == 0.0 and depth[0, 1] == pytest.approx(0.5)


# -------------------------------------------------------------------------------------- altitude


def test_altitude_branches():
    # h_ref = 15: |0-15| + |10-15| + |25-15| = 15 + 5 + 10 = 30; h = 0 is allowed.
    cost, depth = altitude_cost(np.array([[[0.0, 10.0, 25.0]]]), 15.0)
    assert cost[0, 0] == 30.0 and depth[0, 0] == 0.0
    cost, depth = altitude_cost(np.array([[[-0.25, 20.0]]]), 15.0)
    assert cost[0, 0] == INF and depth[0, 0] == 0.25


def test_altitude_counts_free_waypoints_only():
    # Start h = 0 and goal h = 100 are not counted; free h = (12, 21) with h_ref = (0+30)/2 = 15
    # -> 3 + 6 = 9.  A negative goal height would not be counted either.
    m = build_model([[0, 0, 0]], [[30, 0, -5]])
    assert m.h_ref == 15.0
    wp = np.array([[10, 0, 12], [20, 0, 21]], float)[None, None]
    c = evaluate(m, wp)
    assert c.terms[0, 0, 2] == 9.0
    assert c.violation[0, 0, 1] == 0.0
    # a desired height overrides the band middle: h_ref = 10 -> |12-10| + |21-10| = 2 + 11 = 13
    m2 = build_model([[0, 0, 0]], [[30, 0, 20]], desired_height=10.0)
    assert evaluate(m2, wp).terms[0, 0, 2] == 13.0


# --------------------------------------------------------------------------------------- turning


def test_turning_90_threshold_0():
    turn, climb = smoothness_terms(one([[0, 0, 0], [1, 0, 0], [1, 1, 0]]), 0.0, 0.0)
    assert turn[0, 0] == pytest.approx(90.0, abs=1e-12)
    assert climb[0, 0] == 0.0


def test_turning_threshold_counts_whole_angle():
    c30 = (1 + math.cos(math.radians(30)), math.sin(math.radians(30)), 0.0)
    c60 = (1 + math.cos(math.radians(60)), math.sin(math.radians(60)), 0.0)
    # 30-degree turn with threshold 45: 0
    t30, _ = smoothness_terms(one([[0, 0, 0], [1, 0, 0], c30]), 45.0, 45.0)
    assert t30[0, 0] == 0.0
    # 60-degree turn with threshold 45: the whole 60 (not the excess 15)
    t60, _ = smoothness_terms(one([[0, 0, 0], [1, 0, 0], c60]), 45.0, 45.0)
    assert t60[0, 0] == pytest.approx(60.0, abs=1e-10)
    # both in one path with threshold 0: 30 + 60 ... build a path turning +30 then +60 more
    p = [[0, 0, 0], [1, 0, 0], c30]
    d = math.radians(90)
    p.append((c30[0] + math.cos(d), c30[1] + math.sin(d), 0.0))
    t, _ = smoothness_terms(one(p), 0.0, 0.0)
    assert t[0, 0] == pytest.approx(90.0, abs=1e-10)  # 30 + 60
    t, _ = smoothness_terms(one(p), 45.0, 45.0)
    assert t[0, 0] == pytest.approx(60.0, abs=1e-10)  # only the 60


def test_turning_strictly_greater_at_threshold():
    # (1,0) then (1,1): atan2(1, 1) = exactly 45 degrees.
    path = one([[0, 0, 0], [1, 0, 0], [2, 1, 0]])
    assert smoothness_terms(path, 45.0, 45.0)[0][0, 0] == 0.0
    assert smoothness_terms(path, 44.999, 45.0)[0][0, 0] == 45.0
    # U-turn: 180
    assert smoothness_terms(one([[0, 0, 0], [1, 0, 0], [0, 0, 0]]), 0.0, 0.0)[0][0, 0] == 180.0


# ---------------------------------------------------------------------------------------- climb


def test_climb_change_with_thresholds():
    # Segments (1,0,0), (1,0,sqrt3), (1,0,-1): climbs 0, 60, -45 degrees; changes 60 and 105.
    path = one([[0, 0, 0], [1, 0, 0], [2, 0, math.sqrt(3)], [3, 0, math.sqrt(3) - 1]])
    turn, climb = smoothness_terms(path, 0.0, 0.0)
    assert turn[0, 0] == 0.0
    assert climb[0, 0] == pytest.approx(165.0, abs=1e-10)
    assert smoothness_terms(path, 0.0, 45.0)[1][0, 0] == pytest.approx(165.0, abs=1e-10)
    assert smoothness_terms(path, 0.0, 70.0)[1][0, 0] == pytest.approx(105.0, abs=1e-10)
    assert smoothness_terms(path, 0.0, 110.0)[1][0, 0] == 0.0


def test_climb_strictly_greater_at_threshold():
    # climbs 0, 45, 0: changes exactly 45 and 45.
    path = one([[0, 0, 0], [1, 0, 0], [2, 0, 1], [3, 0, 1]])
    assert smoothness_terms(path, 0.0, 0.0)[1][0, 0] == 90.0
    assert smoothness_terms(path, 0.0, 45.0)[1][0, 0] == 0.0


def test_vertical_segment_uses_nearest_nonzero_projection():
    # P0=(0,0,0) P1=(1,0,0) P2=(1,0,2) (vertical) P3=(1,2,2).
    # Vertex P1: s1 = (0,0) -> forward to s2 = (0,2). Turn (1,0)->(0,2) = 90.
    #   climb1 = atan2(0, 1) = 0; climb2 = atan2(dz(s1)=2, |s2|=2) = 45 -> change 45.
    # Vertex P2: s1 -> backward to s0 = (1,0). Turn 90.
    #   climb1 = atan2(dz(s1)=2, |s0|=1) = 63.43494882; climb2 = 0 -> change 63.43494882.
    # (Using the vertical segment itself would give climb 90 on both sides: changes 90 + 90.)
    path = one([[0, 0, 0], [1, 0, 0], [1, 0, 2], [1, 2, 2]])
    a = math.degrees(math.atan2(2.0, 1.0))
    turn, climb = smoothness_terms(path, 0.0, 0.0)
    assert turn[0, 0] == pytest.approx(180.0, abs=1e-10)
    assert climb[0, 0] == pytest.approx(45.0 + a, abs=1e-10)
    # threshold 45: the change of exactly 45 does not count, 63.43 does
    turn, climb = smoothness_terms(path, 45.0, 45.0)
    assert turn[0, 0] == pytest.approx(180.0, abs=1e-10)
    assert climb[0, 0] == pytest.approx(a, abs=1e-10)
    # threshold 70: nothing counts but the two 90-degree turns
    turn, climb = smoothness_terms(path, 70.0, 70.0)
    assert turn[0, 0] == pytest.approx(180.0, abs=1e-10) and climb[0, 0] == 0.0


def test_no_nonzero_projection_backward_side():
    # P0=(0,0,0) P1=(0,0,3) (vertical first segment) P2=(1,0,3) P3=(2,0,3).
    # Vertex P1: nothing before s0 -> zero stays: turn atan2(0, 0) = 0; climb1 = atan2(3, 0) = 90,
    #   climb2 = 0 -> 90.  Vertex P2: straight and level -> 0.
    turn, climb = smoothness_terms(one([[0, 0, 0], [0, 0, 3], [1, 0, 3], [2, 0, 3]]), 0.0, 0.0)
    assert turn[0, 0] == 0.0 and climb[0, 0] == 90.0
    # downwards: climb1 = -90 -> change 90 as well
    turn, climb = smoothness_terms(one([[0, 0, 3], [0, 0, 0], [1, 0, 0]]), 0.0, 0.0)
    assert turn[0, 0] == 0.0 and climb[0, 0] == 90.0
    # a repeated first point (dz = 0): climb1 = atan2(0, 0) = 0; climb2 = atan2(1, 1) = 45
    turn, climb = smoothness_terms(one([[0, 0, 0], [0, 0, 0], [1, 0, 1]]), 0.0, 0.0)
    assert turn[0, 0] == 0.0 and climb[0, 0] == 45.0


def test_no_nonzero_projection_any_direction_is_turning_zero():
    # The zero projection (0, 0) against (-1, -2): the 2-D dot is -0.0 + -0.0 = -0.0, and
    # atan2(0, -0.0) = 180 degrees; the reference's 3-D dot (z components +0) gives +0 -> 0.
    # Vertex P1: turn 0, climbs atan2(0, 0) = 0 and atan2(0, sqrt5) = 0.
    # Vertex P2: (-1,-2) -> (-1,-2) straight.
    path = one([[5, 5, 1], [5, 5, 1], [4, 3, 1], [3, 1, 1]])
    turn, climb = smoothness_terms(path, 0.0, 0.0)
    assert turn[0, 0] == 0.0 and climb[0, 0] == 0.0
    # same at the end of the path (forward side): (-1,-1) then a repeated goal -> turn 0
    path = one([[5, 5, 1], [4, 4, 1], [3, 3, 1], [3, 3, 1]])
    turn, climb = smoothness_terms(path, 0.0, 0.0)
    assert turn[0, 0] == 0.0 and climb[0, 0] == 0.0
    # a vertical first segment going down then west-south: turn 0, climb |-90 - 0| = 90
    path = one([[5, 5, 4], [5, 5, 1], [4, 4, 1]])
    turn, climb = smoothness_terms(path, 0.0, 0.0)
    assert turn[0, 0] == 0.0 and climb[0, 0] == 90.0


def test_no_nonzero_projection_forward_side():
    # P0=(0,0,0) P1=(1,0,0) P2=(1,0,5) (vertical) P3=(1,0,5) (repeated).
    # Vertex P1: s1, s2 both zero -> the last examined (s2, zero) stays: turn 0;
    #   climb2 = atan2(dz(s1)=5, 0) = 90, climb1 = 0 -> 90.
    # Vertex P2: backward -> s0 = (1,0): climb1 = atan2(5, 1) = 78.69006753; forward: s2 zero stays,
    #   climb2 = atan2(0, 0) = 0 -> 78.69006753; turn 0.
    turn, climb = smoothness_terms(one([[0, 0, 0], [1, 0, 0], [1, 0, 5], [1, 0, 5]]), 0.0, 0.0)
    assert turn[0, 0] == 0.0
    assert climb[0, 0] == pytest.approx(90.0 + math.degrees(math.atan2(5.0, 1.0)), abs=1e-10)


def test_smoothness_uses_absolute_altitudes():
    # Level in h but the ground steps up by 1 at x >= 1.5: absolute climbs 0, 45, 0 -> 90.
    terrain = Terrain(elevation=np.array([[0.0, 0.0, 1.0, 1.0]]), origin=(0.0, 0.0))
    m = build_model([[0, 0, 5]], [[3, 0, 5]], terrain=terrain, bounds=(0, 3, 0, 0, 0, 30))
    c = evaluate(m, np.array([[1, 0, 5], [2, 0, 5]], float)[None, None])
    assert c.terms[0, 0, 3] == 0.0
    assert c.terms[0, 0, 4] == pytest.approx(90.0, abs=1e-10)
    # length: 1 + sqrt(2) + 1
    assert c.terms[0, 0, 0] == pytest.approx(2 + math.sqrt(2), abs=1e-12)


# ---------------------------------------------------------------------------------- weighted sum


def test_weighted_sum_zero_weight_drops_inf():
    w = np.array([[2.0, 1.0, 0.0, 1.0, 0.5]])
    t = np.array([[[3.0, 4.0, INF, 5.0, 6.0]]])
    with np.errstate(all="raise"):
        s = weighted_sum(w, t)
    # 2*3 + 4 + 0 + 5 + 3 = 18, no NaN
    assert s[0, 0] == 18.0
    assert weighted_sum(np.array([[2.0, 1.0, 1e-9, 1.0, 0.5]]), t)[0, 0] == INF


def test_evaluate_hand_example_single():
    # Flat ground, S=(0,0,10), W=(3,4,10), G=(6,8,10); cylinder (6, 0, R=2), r=1, Delta=10
    # (inner 3, outer 13).  Length 5 + 5 = 10.  Threat: seg S-W, foot of (6,0) at t=3.6/5 inside,
    # d = |3*0 - 4*6| / 5 = 4.8 -> 8.2; seg W-G, foot outside (t<0) -> |W - C| = 5 -> 8; sum 16.2.
    # Altitude |10 - 15| = 5.  Turning 0, climb 0.
    # J_s with w = (1,2,3,4,5): 10 + 32.4 + 15 = 57.4.
    m = build_model(
        [[0, 0, 10]], [[6, 8, 10]], cylinders=[(6.0, 0.0, 2.0)], weights=(1, 2, 3, 4, 5)
    )
    c = evaluate(m, np.array([[[[3.0, 4.0, 10.0]]]]))
    np.testing.assert_allclose(c.terms[0, 0], [10.0, 16.2, 5.0, 0.0, 0.0], atol=1e-12)
    assert c.single[0, 0] == pytest.approx(57.4, abs=1e-12)
    assert c.formation[0, 0] == 0.0 and c.total[0, 0] == pytest.approx(57.4, abs=1e-12)
    assert np.all(c.violation == 0)


def test_zero_weight_keeps_constraint_in_violation():
    # w3 = 0 and h < 0: the altitude term is inf, J_s stays finite, the violation says 0.5 m.
    m = build_model([[0, 0, 10]], [[20, 0, 10]], weights=(1, 1, 0, 1, 1))
    c = evaluate(m, np.array([[[[10.0, 0.0, -0.5]]]]))
    assert c.terms[0, 0, 2] == INF
    assert np.isfinite(c.single[0, 0]) and np.isfinite(c.total[0, 0])
    assert c.violation[0, 0, 1] == 0.5


def test_total_beta_zero_with_infinite_formation_cost():
    # Two UAVs at the same waypoint: J_f = inf.  beta = 0 -> J = J_s, finite; violation > 0.
    starts = [[0, 0, 10], [0, 50, 10]]
    goals = [[40, 0, 10], [40, 50, 10]]
    wp = np.array([[[[20, 25, 10]], [[20, 25, 10]]]], float)  # (1, 2, 1, 3)
    for cont in (False, True):
        m = build_model(starts, goals, beta=0.0, continuous=cont)
        c = evaluate(m, wp)
        assert np.all(c.formation == INF)
        with np.errstate(all="raise"):
            assert np.all(np.isfinite(c.total))
        np.testing.assert_array_equal(c.total, c.single)
        assert np.all(c.violation[0, :, 2] > 0)
        assert np.all(c.total_violation > 0)
    m = build_model(starts, goals, beta=2.0)
    assert np.all(evaluate(m, wp).total == INF)


def test_total_adds_beta_times_formation():
    # Two UAVs, one edge 0 -> 1, mu = 1 for both; reference = goals: difference (0, -50, 0).
    # Waypoint positions (20, 0, 10) and (20, 40, 10): difference (0, -40, 0) -> dev (0, 10, 0),
    # E = 100 for both.  beta = 3: J = J_s + 300.
    m = build_model(
        [[0, 0, 10], [0, 50, 10]],
        [[40, 0, 10], [40, 50, 10]],
        beta=3.0,
        incidence=[[1.0], [-1.0]],
        edge_weights=[[1.0], [1.0]],
    )
    c = evaluate(m, np.array([[[[20, 0, 10]], [[20, 40, 10]]]], float))
    np.testing.assert_allclose(c.formation, [[100.0, 100.0]], atol=1e-9)
    np.testing.assert_allclose(c.total, c.single + 300.0, rtol=1e-14)


# ------------------------------------------------------------------------------------ violation


def test_violation_zero_iff_costs_finite_random():
    rng = np.random.default_rng(7)
    starts = [[5, 5, 10], [5, 15, 10], [15, 5, 10]]
    goals = [[95, 95, 10], [90, 95, 10], [95, 90, 10]]
    m = build_model(
        starts,
        goals,
        cylinders=[(40.0, 40.0, 4.0), (70.0, 60.0, 3.0)],
        bounds=(0, 100, 0, 100, 0, 30),
        beta=1.0,
        radius=0.5,
        safe=1.0,
        continuous=True,
        incidence=[[1, 1, 0], [-1, 0, 1], [0, -1, -1]],
        edge_weights=[[1, 1, 0], [1, 0, 1], [0, 1, 1]],
    )
    P, K = 400, 4
    wp = rng.uniform([0, 0, -2], [100, 100, 30], size=(P, 3, K, 3))
    # inject near-collisions (waypoint and between waypoints) in a third of the population
    j = rng.random(P) < 0.33
    wp[j, 1] = wp[j, 0] + rng.normal(scale=1.0, size=(j.sum(), K, 3))
    c = evaluate(m, wp)
    feasible = np.all(np.isfinite(c.terms), axis=-1) & np.isfinite(c.formation)
    clean = np.all(c.violation == 0, axis=-1)
    np.testing.assert_array_equal(clean, feasible)
    assert feasible.any() and (~feasible).any()
    assert np.all(c.violation >= 0)
    # component by component
    np.testing.assert_array_equal(c.violation[..., 0] > 0, c.terms[..., 1] == INF)
    np.testing.assert_array_equal(c.violation[..., 1] > 0, c.terms[..., 2] == INF)
    np.testing.assert_array_equal(c.violation[..., 2] > 0, c.formation == INF)
    for k in range(3):
        assert (c.violation[..., k] > 0).any()
    assert not np.isnan(c.total).any()
    np.testing.assert_array_equal(np.isfinite(c.total), feasible)
