"""The swept stand-ins of a moving cylinder (``staghunt.world.dynamic``): they cover every
position the obstacle takes over the window, bends and turn-backs included, and stay at most
``MAX_SWEPT_CYLINDERS`` however fast or small the obstacle (a speed of 1e9 m/s once asked for
11,714,449,758 of them, 87 GiB)."""

from __future__ import annotations

import numpy as np
import pytest

from staghunt.world.dynamic import MAX_SWEPT_CYLINDERS, Dynamics, MovingCylinder


def uncovered(m: MovingCylinder, t0: float, t1: float) -> int:
    """How many points of the obstacle's rim, sampled finely over ``[t0, t1]``, lie outside every
    stand-in of :meth:`Dynamics.swept`."""
    cyl, _ = Dynamics(moving=(m,)).swept(t0, t1)
    assert 1 <= len(cyl) <= MAX_SWEPT_CYLINDERS
    t = np.linspace(t0, t1, 2001)
    angles = np.linspace(0.0, 2 * np.pi, 12, endpoint=False)
    rim = (m.xy(t)[:, None] + m.radius * np.stack([np.cos(angles), np.sin(angles)], -1)).reshape(-1, 2)
    centres = np.array([[c.x, c.y] for c in cyl])
    radius = np.array([c.radius for c in cyl])
    d = np.hypot(rim[:, None, 0] - centres[None, :, 0], rim[:, None, 1] - centres[None, :, 1])
    return int(np.count_nonzero(~(d <= radius[None] + 1e-9).any(axis=1)))


@pytest.mark.parametrize("repeat", ["stop", "reverse"])
def test_stand_ins_cover_bends_and_turn_backs(repeat):
    path = ((0.0, 0.0), (10.0, 0.0), (10.0, 6.0), (2.0, 9.0))  # two bends, 24.5 m
    rng = np.random.default_rng(40)
    for _ in range(20):
        radius, speed = float(rng.uniform(0.2, 3.0)), float(rng.uniform(0.5, 50.0))
        m = MovingCylinder("truck", radius, path, speed, start_time=float(rng.uniform(0, 2)), repeat=repeat)
        t0 = float(rng.uniform(0, 3))
        assert uncovered(m, t0, t0 + float(rng.uniform(0.1, 4.0))) == 0


def test_fast_or_tiny_obstacles_get_few_larger_stand_ins():
    path = ((0.0, 0.0), (40.0, 0.0), (40.0, 30.0))
    for radius, speed in [(2.0, 50.0), (1e-9, 2.0), (1e-3, 50.0)]:
        m = MovingCylinder("truck", radius, path, speed, repeat="reverse")
        cyl, _ = Dynamics(moving=(m,)).swept(0.0, 600.0)
        assert len(cyl) <= MAX_SWEPT_CYLINDERS
        assert uncovered(m, 0.0, 600.0) == 0
    # Back and forth many times within the window: the whole path, once.
    m = MovingCylinder("truck", 2.0, path, 50.0, repeat="reverse")
    assert m.arc_range(0.0, 600.0) == (0.0, 70.0)
    cyl, _ = Dynamics(moving=(m,)).swept(0.0, 600.0)
    centres = np.array([[c.x, c.y] for c in cyl])
    assert centres.min(axis=0).tolist() == [0.0, 0.0] and centres.max(axis=0).tolist() == [40.0, 30.0]


def test_arc_range_of_a_window():
    m = MovingCylinder("t", 1.0, ((0.0, 0.0), (10.0, 0.0)), 2.0, start_time=1.0, repeat="reverse")
    assert m.arc_range(0.0, 1.0) == (0.0, 0.0)  # waiting at the first vertex
    assert m.arc_range(2.0, 4.0) == (2.0, 6.0)
    assert m.arc_range(5.0, 8.0) == (6.0, 10.0)  # turns back at 10 m (t = 6 s), 8 m at t = 8 s
    assert m.arc_range(5.0, 12.0) == (0.0, 10.0)  # both ends within the window
    stop = MovingCylinder("t", 1.0, ((0.0, 0.0), (10.0, 0.0)), 2.0, start_time=1.0)
    assert stop.arc_range(5.0, 100.0) == (8.0, 10.0)
    assert stop.arc_range(50.0, 1e9) == (10.0, 10.0)
