"""Spherical path encoding (docs/model.md eqs. (13), (14)) and the PSO operators."""

from __future__ import annotations

import math

import numpy as np
import pytest

from staghunt.encoding import decode, encode, search_space
from staghunt.solvers.pso import position_step, velocity_step

LO = np.array([0.0, 0.0, 0.0])
HI = np.array([10.0, 10.0, 10.0])
S = np.array([[5.0, 5.0, 5.0]])


def dec(steps, starts=S, lo=LO, hi=HI):
    """Decode one swarm's single particle given as a list of (rho, psi, phi)."""
    return decode(np.asarray(steps, float)[None, None], starts, lo, hi)[0, 0]


def test_decode_unit_directions():
    # phi = 0, psi = 0: +rho along x
    np.testing.assert_array_equal(dec([[2.0, 0.0, 0.0]]), [[7.0, 5.0, 5.0]])
    # phi = pi/2: +y
    np.testing.assert_allclose(dec([[2.0, 0.0, math.pi / 2]]), [[5.0, 7.0, 5.0]], atol=1e-15)
    # psi = pi/2: +h
    np.testing.assert_allclose(dec([[2.0, math.pi / 2, 0.3]]), [[5.0, 5.0, 7.0]], atol=1e-15)
    # phi = pi/4, psi = 0: (sqrt2, sqrt2); then psi = -pi/6 along x: (rho cos30, 0, -rho sin30)
    out = dec([[2.0, 0.0, math.pi / 4], [2.0, -math.pi / 6, 0.0]])
    s2 = math.sqrt(2.0)
    np.testing.assert_allclose(
        out, [[5 + s2, 5 + s2, 5.0], [5 + s2 + math.sqrt(3.0), 5 + s2, 4.0]], atol=1e-14
    )


def test_decode_clamps_after_every_step():
    # x: 8 -> 8 + 5 = 13, clamped to 10 -> 10 - 5 = 5.   A clipped cumulative sum would give
    # clip(8 + 5) = 10, then clip(8 + 5 - 5) = 8.
    start = np.array([[8.0, 5.0, 5.0]])
    out = dec([[5.0, 0.0, 0.0], [5.0, 0.0, math.pi]], starts=start)
    np.testing.assert_allclose(out[:, 0], [10.0, 5.0], atol=1e-14)
    steps = np.array([[5.0, 0.0, 0.0], [-5.0, 0.0, 0.0]])
    cumsum_clipped = np.clip(start + np.cumsum(steps, axis=0), LO, HI)
    assert cumsum_clipped[1, 0] == 8.0 and out[1, 0] != cumsum_clipped[1, 0]
    # the height is clamped too: down 20 -> 0, then up 3 -> 3
    out = dec([[20.0, -math.pi / 2, 0.0], [3.0, math.pi / 2, 0.0]])
    np.testing.assert_allclose(out[:, 2], [0.0, 3.0], atol=1e-14)
    np.testing.assert_allclose(out[:, :2], 5.0, atol=1e-14)


def test_decode_per_swarm_boxes_and_batch():
    # Two swarms with their own boxes (N, 3); two particles.
    starts = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    lo = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    hi = np.array([[3.0, 3.0, 3.0], [100.0, 100.0, 100.0]])
    x = np.zeros((2, 2, 1, 3))
    x[..., 0] = 10.0  # rho 10 along +x
    out = decode(x, starts, lo, hi)
    np.testing.assert_allclose(out[:, 0, 0], [[3.0, 0.0, 0.0]] * 2)
    np.testing.assert_allclose(out[:, 1, 0], [[11.0, 1.0, 1.0]] * 2)


def test_search_space_paper_uav1():
    s = np.array([[15.0, 18.66, 20.0]])
    g = np.array([[85.0, 88.66, 20.0]])
    sp = search_space(s, g, 10)
    rho_max = 2 * math.hypot(70.0, 70.0) / 10  # 14 sqrt 2 = 19.79898987
    phi0 = math.atan2(70.0, 70.0)  # pi / 4
    np.testing.assert_allclose(sp.lower, [[0.0, -math.pi / 4, phi0 - math.pi / 4]], atol=1e-15)
    np.testing.assert_allclose(sp.upper, [[rho_max, math.pi / 4, phi0 + math.pi / 4]], rtol=1e-15)
    np.testing.assert_allclose(sp.vmax, 0.5 * (sp.upper - sp.lower), rtol=1e-15)
    assert sp.upper[0, 0] == pytest.approx(19.798989873223331, rel=1e-14)
    assert sp.lower[0, 2] == pytest.approx(0.0, abs=1e-15)
    assert sp.upper[0, 2] == pytest.approx(math.pi / 2, rel=1e-15)
    # a 3-D displacement counts in |G - S|; azimuth of a westward goal is near pi
    sp2 = search_space(np.array([[50.0, 0.0, 0.0]]), np.array([[20.0, 0.0, 40.0]]), 5)
    assert sp2.upper[0, 0] == pytest.approx(2 * 50.0 / 5)
    assert sp2.lower[0, 2] == pytest.approx(math.pi - math.pi / 4)
    # samples fall in the ranges
    x = sp.sample(np.random.default_rng(0), 100, 10)
    assert x.shape == (100, 1, 10, 3)
    assert np.all(x >= sp.lower[None, :, None]) and np.all(x <= sp.upper[None, :, None])


def test_encode_decode_round_trip():
    rng = np.random.default_rng(3)
    starts = np.array([[15.0, 18.66, 20.0], [80.0, 10.0, 5.0], [50.0, 90.0, 10.0]])
    goals = np.array([[85.0, 88.66, 20.0], [10.0, 12.0, 15.0], [48.0, 10.0, 10.0]])  # NE, W, S
    K = 6
    sp = search_space(starts, goals, K)
    x = sp.sample(rng, 200, K)
    lo = np.array([-1000.0, -1000.0, -1000.0])
    hi = np.array([1000.0, 1000.0, 1000.0])
    wp = decode(x, starts, lo, hi)
    assert np.all(np.abs(wp) < 900)  # no clamping happened
    back = encode(wp, starts, sp)
    np.testing.assert_allclose(back, x, rtol=0, atol=1e-9)
    # and decode(encode(wp)) gives the same waypoints
    np.testing.assert_allclose(decode(back, starts, lo, hi), wp, atol=1e-9)


def test_encode_out_of_range_is_clipped():
    # A step of length 100 straight up from the start: rho clipped to rho_max, psi to pi/4.
    starts = np.array([[0.0, 0.0, 0.0]])
    goals = np.array([[10.0, 0.0, 0.0]])
    sp = search_space(starts, goals, 2)  # rho_max = 10
    wp = np.array([[[[0.0, 0.0, 100.0], [0.0, 0.0, 100.0]]]])
    x = encode(wp, starts, sp)
    np.testing.assert_allclose(x[0, 0, 0], [10.0, math.pi / 4, 0.0], atol=1e-15)
    # zero step: rho 0, psi 0, phi at the range centre
    np.testing.assert_allclose(x[0, 0, 1], [0.0, 0.0, 0.0], atol=1e-15)


# ------------------------------------------------------------------------------------ PSO steps


def test_position_step_clamps_and_mirrors_only_out_of_range():
    lower = np.array([[0.0, -1.0, 2.0]])
    upper = np.array([[10.0, 1.0, 3.0]])
    X = np.array([[[[5.0, 0.0, 2.5], [9.0, 0.5, 2.5]]]])  # (P=1, N=1, K=2, 3)
    V = np.array([[[[2.0, -3.0, 0.5], [1.0, 0.25, -1.0]]]])
    Xn, Vn = position_step(X, V, lower, upper)
    # k=0: 7 in range; 0-3 = -3 < -1 -> -1, v -> +3; 2.5+0.5 = 3 == upper (inside) -> kept.
    # k=1: 9+1 = 10 == upper -> kept; 0.75 in range; 2.5-1 = 1.5 < 2 -> 2, v -> +1.
    np.testing.assert_array_equal(Xn, [[[[7.0, -1.0, 3.0], [10.0, 0.75, 2.0]]]])
    np.testing.assert_array_equal(Vn, [[[[2.0, 3.0, 0.5], [1.0, 0.25, 1.0]]]])
    assert X[0, 0, 0, 0] == 5.0  # inputs untouched


def test_velocity_step_hand_formula_and_vmax():
    rng = np.random.default_rng(5)
    P, N, K = 4, 2, 3
    X = rng.normal(size=(P, N, K, 3))
    V = rng.normal(size=(P, N, K, 3))
    pb = rng.normal(size=(P, N, K, 3))
    gb = rng.normal(size=(N, K, 3))
    r1 = rng.random((P, N, K, 3))
    r2 = rng.random((P, N, K, 3))
    vmax = np.array([[0.5, 1.0, 100.0], [2.0, 0.1, 100.0]])
    out = velocity_step(X, V, pb, gb, 0.7, 1.5, 1.2, r1, r2, vmax)
    for p in range(P):
        for n in range(N):
            for k in range(K):
                for c in range(3):
                    v = (
                        0.7 * V[p, n, k, c]
                        + 1.5 * r1[p, n, k, c] * (pb[p, n, k, c] - X[p, n, k, c])
                        + 1.2 * r2[p, n, k, c] * (gb[n, k, c] - X[p, n, k, c])
                    )
                    v = min(max(v, -vmax[n, c]), vmax[n, c])
                    assert out[p, n, k, c] == pytest.approx(v, rel=1e-14, abs=1e-15)
    # the limit is actually reached somewhere and the unlimited component is untouched
    assert np.any(np.abs(out[..., 0]) == 0.5) or np.any(np.abs(out[..., 0]) == 2.0)
    assert np.all(np.abs(out[:, 1, :, 1]) <= 0.1)
    # scalar r1 = r2 = 0: pure inertia
    np.testing.assert_allclose(
        velocity_step(X, V, pb, gb, 0.5, 1.5, 1.5, 0.0, 0.0, np.full((N, 3), 1e9)), 0.5 * V
    )
