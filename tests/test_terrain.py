"""Ground elevation: MATLAB rounding, nearest/bilinear sampling, clipping, absolute altitude."""

from __future__ import annotations

import numpy as np
import pytest

from staghunt.world import Terrain, round_half_away

# 3 rows (y) x 4 cols (x); value = 10 * row + col
GRID = np.array([[0.0, 1.0, 2.0, 3.0], [10.0, 11.0, 12.0, 13.0], [20.0, 21.0, 22.0, 23.0]])


def test_round_half_away_from_zero():
    v = np.array([-2.5, -1.5, -0.5, -0.4, -0.0, 0.4, 0.5, 1.5, 2.5, 2.4999999999999996, 12.5])
    np.testing.assert_array_equal(round_half_away(v), [-3, -2, -1, -0, 0, 0, 1, 2, 3, 2, 13])
    # NumPy's round goes to even: differs on 0.5, 2.5, -0.5, -2.5
    assert np.round(2.5) == 2.0 and round_half_away(np.array(2.5)) == 3.0
    # the largest double below 0.5 rounds to 0 (floor(v + 0.5) would give 1), both signs
    below = np.nextafter(0.5, 0.0)
    np.testing.assert_array_equal(round_half_away(np.array([below, -below])), [0.0, 0.0])
    # integers beyond 2**52 are returned unchanged (v + 0.5 is not representable there)
    big = np.array([2.0**52 + 1, -(2.0**52 + 1), 2.0**53])
    np.testing.assert_array_equal(round_half_away(big), big)


def test_flat_ground():
    t = Terrain()
    assert t.is_flat and t.extent() is None
    np.testing.assert_array_equal(t.height(np.array([1.0, 5.0]), np.array([2.0, -3.0])), [0.0, 0.0])
    np.testing.assert_array_equal(t.absolute(np.array([1.0]), np.array([2.0]), np.array([7.5])), [7.5])


def test_nearest_sampling_and_clipping():
    # MATLAB convention: origin (1, 1), cell 1 -> H(round(y), round(x)), 1-based
    t = Terrain(elevation=GRID, origin=(1.0, 1.0), cell_size=1.0, sampling="nearest")
    assert t.extent() == (1.0, 4.0, 1.0, 3.0)
    x = np.array([1.0, 2.5, 2.49, 3.5, 1.0, 4.0])
    y = np.array([1.0, 1.0, 2.5, 2.5, 3.0, 1.49])
    # (1,1)->[0,0]=0; x 2.5->col 3 -> [0,2]=2; (2.49,2.5)->[2,1]=21; (3.5,2.5)->[2,3]=23;
    # (1,3)->[2,0]=20; (4,1.49)->[0,3]=3
    np.testing.assert_array_equal(t.height(x, y), [0.0, 2.0, 21.0, 23.0, 20.0, 3.0])
    # outside the grid: the nearest edge cell
    xo = np.array([-50.0, 100.0, 0.4, 2.0, 100.0, -3.0])
    yo = np.array([2.0, 2.0, 1.0, -7.0, 100.0, -3.0])
    np.testing.assert_array_equal(t.height(xo, yo), [10.0, 13.0, 0.0, 1.0, 23.0, 0.0])
    # broadcasting
    assert t.height(np.array([[1.0], [2.0]]), np.array([1.0, 2.0, 3.0])).shape == (2, 3)


def test_nearest_with_origin_and_cell_size():
    # cell centres at x = 100, 110, 120, 130 and y = -20, -10, 0
    t = Terrain(elevation=GRID, origin=(100.0, -20.0), cell_size=10.0, sampling="nearest")
    # x 115 -> 1.5 -> col 2; y -15 -> 0.5 -> row 1; x 104.9 -> col 0; y -0.1 -> row 2
    np.testing.assert_array_equal(
        t.height(np.array([115.0, 104.9, 135.0]), np.array([-15.0, -0.1, -24.9])), [12.0, 20.0, 3.0]
    )


def test_bilinear_centres_midpoints_and_clipping():
    t = Terrain(elevation=GRID, origin=(0.0, 0.0), cell_size=2.0, sampling="bilinear")
    # at cell centres: the cell values
    for i in range(3):
        for j in range(4):
            assert t.height(np.array(2.0 * j), np.array(2.0 * i)) == pytest.approx(GRID[i, j], abs=1e-12)
    # middle of four cells: their average; (1, 1) -> (0 + 1 + 10 + 11) / 4 = 5.5
    assert t.height(np.array(1.0), np.array(1.0)) == pytest.approx(5.5, abs=1e-12)
    assert t.height(np.array(5.0), np.array(3.0)) == pytest.approx((12 + 13 + 22 + 23) / 4, abs=1e-12)
    # on an edge between two cells: their average; along x at row 2: (21 + 22) / 2
    assert t.height(np.array(3.0), np.array(4.0)) == pytest.approx(21.5, abs=1e-12)
    # a quarter of the way: g = 0.75*g00 + 0.25*g01 along x at row 0 -> 0.25
    assert t.height(np.array(0.5), np.array(0.0)) == pytest.approx(0.25, abs=1e-12)
    # outside: clipped to the edge (the last centre)
    np.testing.assert_allclose(
        t.height(np.array([-10.0, 50.0, 50.0]), np.array([-10.0, 50.0, 1.0])), [0.0, 23.0, 8.0], atol=1e-12
    )
    # float32 grids are sampled in double precision
    t32 = Terrain(elevation=GRID.astype(np.float32), origin=(0.0, 0.0), cell_size=2.0, sampling="bilinear")
    assert t32.height(np.array(1.0), np.array(1.0)).dtype == np.float64


def test_absolute_altitude_float32_grid():
    g32 = np.full((2, 2), np.float32(0.1))
    t = Terrain(elevation=g32, origin=(0.0, 0.0))
    h = np.array([0.3, 20.0])
    z = t.absolute(np.array([0.0, 1.0]), np.array([0.0, 1.0]), h)
    assert z.dtype == np.float64
    expected = [float(np.float32(0.3) + np.float32(0.1)), float(np.float32(20.0) + np.float32(0.1))]
    np.testing.assert_array_equal(z, expected)
    assert z[0] != 0.3 + float(np.float32(0.1))  # single-precision sum, not double
    # a float64 grid adds in double
    t64 = Terrain(elevation=g32.astype(np.float64), origin=(0.0, 0.0))
    np.testing.assert_array_equal(
        t64.absolute(np.array([0.0]), np.array([0.0]), np.array([0.3])), [0.3 + float(np.float32(0.1))]
    )
