"""The batched J_s equals a scalar transcription of the SPSO reference's MyCost (docs/model.md eq. (2))."""

from __future__ import annotations

import math

import numpy as np
import pytest

try:
    from reference_mycost import matlab_round, my_cost
except ImportError:  # tests/ imported as a package
    from tests.reference_mycost import matlab_round, my_cost
from staghunt.costs import CostModel, evaluate
from staghunt.costs.single import segment_axis_distance
from staghunt.scenario.model import CostParams, Scenario, SolverSettings
from staghunt.task import UAV, Formation, Weights
from staghunt.world import Bounds, Cylinder, Terrain, World, round_half_away

ROWS, COLS = 80, 100  # y in [1, 80], x in [1, 100]
ZMIN, ZMAX = 2.0, 27.0
THREATS = [(20.0, 20.0, 5.0), (40.0, 30.0, 4.0), (15.0, 40.0, 3.0), (50.0, 10.0, 2.0)]


def make_dem(seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0.0, 12.0, size=(ROWS, COLS)).astype(np.float32)


def reference_model(H: np.ndarray, start, goal) -> CostModel:
    """The project's model with the reference's constants."""
    team = (UAV("u", tuple(start), tuple(goal), 1.0, Weights(0.0, 5.0, 1.0, 10.0, 1.0, 1.0)),)
    world = World(
        bounds=Bounds(1.0, COLS, 1.0, ROWS, ZMIN, ZMAX),
        terrain=Terrain(elevation=H, origin=(1.0, 1.0), cell_size=1.0, sampling="nearest"),
        cylinders=tuple(Cylinder(*t) for t in THREATS),
    )
    costs = CostParams(
        danger_margin=10.0,
        safe_distance=2.0,
        turning_threshold_deg=45.0,
        climb_threshold_deg=45.0,
        desired_height=None,
        continuous_separation=False,
    )
    form = Formation(np.zeros((1, 0)), np.zeros((1, 0)), np.array([goal], float))
    m = CostModel.from_scenario(Scenario("ref", "", world, team, form, costs, SolverSettings()))
    assert m.h_ref == (ZMIN + ZMAX) / 2
    return m


def random_group(rng: np.random.Generator, P: int):
    """A start, a goal and ``P`` random paths of ``K`` free waypoints with awkward features."""
    K = int(rng.integers(2, 11))
    lo = np.array([1.0, 1.0])
    hi = np.array([COLS, ROWS], float)
    start = np.r_[rng.uniform(lo + 1, hi - 1), rng.uniform(0, ZMAX)]
    goal = np.r_[rng.uniform(lo + 1, hi - 1), rng.uniform(0, ZMAX)]
    wp = np.empty((P, K, 3))
    for p in range(P):
        if rng.random() < 0.6:  # random walk with short steps
            cur = start[:2].copy()
            for k in range(K):
                ang = rng.uniform(0, 2 * np.pi)
                cur = np.clip(cur + rng.uniform(1, 9) * np.array([np.cos(ang), np.sin(ang)]), lo, hi)
                wp[p, k, :2] = cur
        else:  # anywhere
            wp[p, :, :2] = rng.uniform(lo, hi, size=(K, 2))
        wp[p, :, 2] = rng.uniform(0, ZMAX, size=K)
        for k in range(K):
            prev = start if k == 0 else wp[p, k - 1]
            u = rng.random()
            if u < 0.08:  # repeated point
                wp[p, k] = prev
            elif u < 0.16:  # purely vertical segment
                wp[p, k, :2] = prev[:2]
            elif u < 0.24:  # a coordinate exactly on a half cell
                c = int(rng.integers(0, 2))
                wp[p, k, c] = min(math.floor(wp[p, k, c]) + 0.5, hi[c] - 0.5)
            elif u < 0.27:  # below ground / exactly on the ground
                wp[p, k, 2] = rng.choice([-0.5, 0.0])
            elif u < 0.29:
                wp[p, k, 0] = 12.5
    return start, goal, wp


def grazing_paths():
    """Hand-built paths touching obstacles at exactly d = R + r (finite: Delta each).

    C1 = (20, 20, 5), inner 6: (14,26)-(26,26) perpendicular 6; (26,26)-(26,20) perpendicular 6;
    (26,20) repeated: point at 6; (26,20)-(30,20): nearer end at 6.
    C2 = (40, 30, 4), inner 5: (41,23)-(47,31): |det((6,8),(-1,7))| / 10 = 50 / 10 = 5.
    """
    start = np.array([5.0, 30.0, 10.0])
    goal = np.array([55.0, 45.0, 10.0])
    base = [
        [14, 26, 12.5],
        [26, 26, 14.0],
        [26, 20, 14.0],
        [26, 20, 18.0],  # repeated xy: vertical segment at the grazing point
        [30, 20, 15.0],
        [41, 23, 16.0],
        [47, 31, 14.5],
    ]
    wp = np.array([base], float)
    # same path, heights shifted, and one with a waypoint nudged 1e-9 inside C1's clearance
    shifted = wp.copy()
    shifted[0, :, 2] += 3.0
    inside = wp.copy()
    inside[0, 0, 1] = 26.0 - 1e-9
    inside[0, 1, 1] = 26.0 - 1e-9
    return start, goal, np.concatenate([wp, shifted, inside])


def compare_group(H, start, goal, wp):
    m = reference_model(H, start, goal)
    c = evaluate(m, wp[:, None])
    stats = {"finite": 0, "inf": 0}
    for p in range(wp.shape[0]):
        full = np.vstack([start, wp[p], goal])
        ref = my_cost(full[:, 0], full[:, 1], full[:, 2], H, THREATS, ZMIN, ZMAX)
        cost, J1, J2, J3, Jt, Jc = ref
        got = c.single[p, 0]
        terms = c.terms[p, 0]
        assert math.isinf(cost) == math.isinf(got), (p, ref, terms)
        np.testing.assert_array_equal(np.isinf(terms), np.isinf([J1, J2, J3, Jt, Jc]))
        assert terms[0] == pytest.approx(J1, rel=1e-13)
        if math.isfinite(J2):
            assert abs(terms[1] - J2) <= 1e-12 * max(1.0, J2)
        if math.isfinite(J3):
            assert abs(terms[2] - J3) <= 1e-12 * max(1.0, J3)
        assert abs(terms[3] - Jt) <= 1e-12 * max(1.0, Jt)
        assert abs(terms[4] - Jc) <= 1e-12 * max(1.0, Jc)
        if math.isfinite(cost):
            assert abs(got - cost) <= 1e-12 * abs(cost), (p, got, cost)
            stats["finite"] += 1
        else:
            assert got == math.inf
            stats["inf"] += 1
    return stats, c


def test_transcription_hand_example():
    # Flat DEM.  S=(1,1,10), W=(4,5,10), G=(7,9,10); threat (7, 1, R=2): inner 3, outer 13.
    # J1 = 5 + 5; J2: seg S-W perpendicular |3*0 - 4*6| / 5 = 4.8 -> 8.2, seg W-G nearer end
    # |(3,-4)| = 5 -> 8; J3 = |10 - (0+30)/2| = 5; turning 0, climb 0.
    # cost = 5*10 + 16.2 + 10*5 = 116.2
    H = np.zeros((12, 12), np.float32)
    cost, J1, J2, J3, Jt, Jc = my_cost([1, 4, 7], [1, 5, 9], [10, 10, 10], H, [(7.0, 1.0, 2.0)], 0.0, 30.0)
    assert (J1, Jt, Jc, J3) == (10.0, 0.0, 0.0, 5.0)
    assert J2 == pytest.approx(16.2, abs=1e-12)
    assert cost == pytest.approx(116.2, abs=1e-12)
    # MATLAB rounding on halves and the 1e-8 single-precision effect of a float32 DEM
    assert [matlab_round(v) for v in (12.5, 13.5, -2.5, 0.49999999999999994)] == [13, 14, -3, 0]
    Hs = np.full((3, 3), np.float32(0.1))
    _, J1s, *_ = my_cost([1, 1], [1, 2], [0.3, 0.3], Hs, [], 0.0, 30.0)
    assert J1s == 1.0
    _, J1s, *_ = my_cost([1, 1], [1, 1], [0.0, 0.3], Hs, [], 0.0, 30.0)
    assert J1s == float(np.float32(0.3) + np.float32(0.1)) - float(np.float32(0.1))
    assert J1s != 0.3


def test_matches_reference_on_random_paths():
    H = make_dem(0)
    rng = np.random.default_rng(2024)
    totals = {"finite": 0, "inf": 0}
    n_paths = in_band = below_ground = 0
    for _ in range(12):
        start, goal, wp = random_group(rng, 20)
        stats, c = compare_group(H, start, goal, wp)
        n_paths += wp.shape[0]
        for k in totals:
            totals[k] += stats[k]
        threat = c.terms[:, 0, 1]
        in_band += int(np.sum(np.isfinite(threat) & (threat > 0)))
        below_ground += int(np.sum(np.isinf(c.terms[:, 0, 2])))
    assert n_paths >= 200
    # every branch exercised substantially
    assert totals["finite"] >= 60, totals
    assert totals["inf"] >= 20, totals
    assert in_band >= 20 and below_ground >= 3


def test_matches_reference_on_grazing_paths():
    H = make_dem(1)
    start, goal, wp = grazing_paths()
    stats, c = compare_group(H, start, goal, wp)
    # the two exact grazing paths are finite (Delta = 10 at each grazing segment: four of C1,
    # incl. the zero-length one, and one of C2); the nudged one is inf.
    assert stats == {"finite": 2, "inf": 1}
    np.testing.assert_array_equal(np.isfinite(c.single[:, 0]), [True, True, False])
    full_xy = np.vstack([start, wp[0], goal])[None, None, :, :2]
    d = segment_axis_distance(full_xy, np.array(THREATS))[0, 0]  # (segments, threats)
    np.testing.assert_array_equal(d[1:5, 0], [6.0, 6.0, 6.0, 6.0])
    assert d[6, 1] == 5.0
    assert c.terms[0, 0, 1] == c.terms[1, 0, 1] > 5 * 10.0
    assert c.violation[2, 0, 0] == pytest.approx(1e-9, rel=1e-5)


def test_half_cell_sampling_and_rounding_agree():
    H = make_dem(2)
    t = Terrain(elevation=H, origin=(1.0, 1.0), cell_size=1.0, sampling="nearest")
    for x, y in [(12.5, 7.5), (1.0, 1.0), (59.5, 49.5), (2.4999999999999996, 3.5000000000000004)]:
        assert t.height(np.array(x), np.array(y)) == H[matlab_round(y) - 1, matlab_round(x) - 1]
    v = np.array([-2.5, -1.5, -0.5, 0.5, 1.5, 2.5, 12.5, -12.5, 0.49999999999999994])
    np.testing.assert_array_equal(round_half_away(v), [matlab_round(float(a)) for a in v])
