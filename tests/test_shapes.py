"""Prisms, boxes, no-fly zones and the altitude ceiling: threat at the boundaries (inside,
exactly at r + c, in the danger band, beyond), the climb-over rule, and the compiled engine
against the NumPy twin on the new shapes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from staghunt.costs import evaluate
from staghunt.costs.prisms import prism_distance, prism_threat
from staghunt.world import Prism, box_polygon, prism_arrays

from test_engine import assert_costs_agree, dem, frozen, make_model, population

R_BODY = 1.0
DELTA = 10.0

SHAPES = {
    # A building (L-shaped, from the ground to 30 m), a floating box (crane jib, 25-28 m), a no-fly zone.
    "building": Prism(((40.0, 40.0), (60.0, 40.0), (60.0, 50.0), (50.0, 50.0), (50.0, 60.0), (40.0, 60.0)),
                      -np.inf, 30.0, "L"),
    "box": Prism(box_polygon(20.0, 30.0, 60.0, 64.0), 25.0, 28.0, "jib", "box"),
    "nofly": Prism(((70.0, 70.0), (90.0, 72.0), (80.0, 90.0)), -np.inf, np.inf, "nfz", "nofly"),
}


def with_prisms(model, prisms, ceiling=np.inf, clearance=0.0):
    prm, edges = prism_arrays(prisms)
    return dataclasses.replace(model, prisms=frozen(prm), prism_edges=frozen(edges), ceiling=float(ceiling),
                               min_clearance=clearance)


def one_segment_threat(prism: Prism, a, b, clearance=0.0):
    prm, edges = prism_arrays([prism])
    path = np.array([a, b], dtype=float)[None, None]  # (1, 1, 2, 3)
    d = prism_distance(path, prm, edges, np.array([R_BODY]), clearance)
    cost, depth = prism_threat(d, np.array([R_BODY]), DELTA, clearance)
    return float(d[0, 0, 0, 0]), float(cost[0, 0]), float(depth[0, 0])


@pytest.mark.parametrize("name", ["building", "box", "nofly"])
def test_threat_at_the_boundaries(name):
    prism = SHAPES[name]
    xs = [v[0] for v in prism.polygon]
    ys = [v[1] for v in prism.polygon]
    z = 26.5  # inside every shape's altitude range
    # A vertical-in-y segment east of the footprint's easternmost vertex, at gap g.
    xe = max(xs)
    ymid = ys[int(np.argmax(xs))]

    def at(gap):
        return one_segment_threat(prism, (xe + gap, ymid - 1.0, z), (xe + gap, ymid + 1.0, z))

    # inside the footprint
    cx, cy = np.mean(xs), np.mean(ys)
    d, cost, depth = one_segment_threat(prism, (cx, cy, z), (cx + 0.1, cy, z))
    assert d == 0.0 and cost == np.inf and depth == R_BODY
    # exactly at r (R = 0 for a prism): feasible, full band cost Delta
    d, cost, depth = at(R_BODY)
    assert d == pytest.approx(R_BODY, abs=1e-12) and np.isfinite(cost) and cost == pytest.approx(DELTA)
    assert depth == pytest.approx(0.0, abs=1e-12)
    # just inside r: infeasible
    d, cost, depth = at(R_BODY - 1e-6)
    assert cost == np.inf and depth > 0
    # in the band
    d, cost, depth = at(R_BODY + 4.0)
    assert cost == pytest.approx(DELTA - 4.0) and depth == 0.0
    # beyond r + Delta
    d, cost, depth = at(R_BODY + DELTA + 0.5)
    assert cost == 0.0 and depth == 0.0


def test_hard_clearance_moves_the_infeasible_boundary():
    prism = SHAPES["building"]
    seg = ((60.0 + R_BODY + 2.0, 44.0, 10.0), (60.0 + R_BODY + 2.0, 46.0, 10.0))
    assert np.isfinite(one_segment_threat(prism, *seg, clearance=1.5)[1])
    assert one_segment_threat(prism, *seg, clearance=2.5)[1] == np.inf


def test_above_the_top_is_clear_and_a_climb_is_judged_below_it():
    b = SHAPES["building"]  # top 30: band ends at 30 + r = 31
    over = one_segment_threat(b, (30.0, 50.0, 31.0), (70.0, 50.0, 31.0))
    assert over == (np.inf, 0.0, 0.0)  # exactly at top + r + c: not strictly inside the band
    just_in = one_segment_threat(b, (30.0, 50.0, 30.99), (70.0, 50.0, 30.99))
    assert just_in[1] == np.inf
    # Climbing from 20 m at x = 30 to 40 m at x = 70: below 31 m only for x < 30 + 40 * 11/20 = 52,
    # which crosses the footprint (x from 40): infeasible.
    assert one_segment_threat(b, (30.0, 45.0, 20.0), (70.0, 45.0, 40.0))[1] == np.inf
    # Climbing fast enough: below 31 m only for x < 30 + 40 * 1/20 = 32, 8 m west of the wall.
    d, cost, _ = one_segment_threat(b, (30.0, 45.0, 30.0), (70.0, 45.0, 50.0))
    assert d == pytest.approx(8.0) and cost == pytest.approx(R_BODY + DELTA - 8.0)
    # Below a floating box's base minus r: clear; the no-fly zone has no top.
    assert one_segment_threat(SHAPES["box"], (25.0, 55.0, 23.9), (25.0, 70.0, 23.9))[1] == 0.0
    assert one_segment_threat(SHAPES["nofly"], (60.0, 80.0, 1e4), (95.0, 80.0, 1e4))[1] == np.inf


def test_matches_shapely_distance():
    pytest.importorskip("shapely")
    from shapely.geometry import LineString, Polygon

    rng = np.random.default_rng(1)
    prism = SHAPES["building"]
    poly = Polygon(prism.polygon)
    for _ in range(200):
        a, b = rng.uniform(20, 80, 2), rng.uniform(20, 80, 2)
        d = one_segment_threat(prism, (*a, 5.0), (*b, 5.0))[0]
        assert d == pytest.approx(poly.distance(LineString([a, b])), abs=1e-9)


def test_ceiling():
    model = with_prisms(make_model(2), [], ceiling=30.0)
    wp = np.full((2, 2, 3, 3), 20.0)
    wp[..., :2] = [[[30.0, 30.0]]]
    wp[0, :, :, :2] = np.array([[10.0, 30.0], [10.0, 50.0], [10.0, 70.0]])
    wp[0, 1, :, 0] += 10.0
    wp[1] = wp[0]
    wp[1, 0, 1, 2] = 30.5
    c = evaluate(model, wp)
    assert np.isfinite(c.terms[0, 0, 1]) and c.violation[0, 0, 0] == 0.0
    assert c.terms[1, 0, 1] == np.inf and c.violation[1, 0, 0] == pytest.approx(0.5)


@pytest.mark.parametrize("ground", ["flat", "bilinear", "nearest-float32"])
@pytest.mark.parametrize("clearance", [0.0, 1.5])
@pytest.mark.parametrize("K", [1, 4, 10])
def test_engines_agree_on_shapes(K, clearance, ground):
    pytest.importorskip("numba")
    terrain = None if ground == "flat" else (dem("bilinear", np.float64) if ground == "bilinear"
                                             else dem("nearest", np.float32))
    model = with_prisms(make_model(3, terrain=terrain), list(SHAPES.values()), ceiling=45.0, clearance=clearance)
    wp = population(model, 96, K, seed=K)
    rng = np.random.default_rng(K)
    wp[40:60, :, :, 2] = rng.choice([23.9, 24.0, 29.0, 30.0, 31.0, 44.0, 45.0, 46.0], size=(20, 3, K))
    # Exactly at r from the building's east wall (x = 60) and at r + Delta.
    wp[60, 0, :, 0] = 61.0
    wp[61, 0, :, 0] = 71.0
    wp[60:62, 0, :, 1] = np.linspace(42.0, 48.0, K)
    wp[60:62, 0, :, 2] = 10.0
    wp[62, 2, :, 0] = np.linspace(60.0, 95.0, K)  # across the no-fly zone
    wp[62, 2, :, 1] = 80.0
    wp[63, 1, :, :] = [25.0, 62.0, 0.0]
    wp[63, 1, :, 2] = np.linspace(20.0, 35.0, K)  # climbing through the floating box
    assert_costs_agree(model, wp)
    c = evaluate(model, wp)
    assert np.isinf(c.terms[:, :, 1]).any() and (c.terms[:, :, 1] > 0).mean() > 0.2


@pytest.mark.parametrize("n", [6, 12])
@pytest.mark.parametrize("continuous", [True, False])
def test_pruned_separation_is_exact(n, continuous):
    """Past N = 4 the kernel skips pairs by bounding boxes: the same costs and decisions."""
    pytest.importorskip("numba")
    from staghunt.engine import kernels as kn

    assert n > kn.PRUNE_MIN_UAVS
    model = make_model(n, continuous=continuous)
    K = 6
    rng = np.random.default_rng(n)
    t = (np.arange(1, K + 1) / (K + 1))[None, None, :, None]
    line = model.starts[None, :, None, :] + t * (model.goals - model.starts)[None, :, None, :]
    wp = line + rng.normal(0.0, 0.5, size=(64, n, K, 3))  # converged: boxes of far pairs apart
    wp[:14] = population(model, 14, K, seed=n)
    for i, gap in enumerate((4.0, 4.0 + 1e-9, 4.0 - 1e-9, 4.0 + 1e-6, 4.0 + 2e-6)):
        wp[20 + i, 3] = wp[20 + i, 2] + np.array([gap, 0.0, 0.0])  # UAV 3 at a gap from UAV 2
    assert_costs_agree(model, wp)
    c = evaluate(model, wp)
    assert np.isinf(c.formation[20:23]).any() and np.isfinite(c.formation[30:]).any()
