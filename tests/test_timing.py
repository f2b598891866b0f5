"""Time-optimal synchronised timing (:mod:`staghunt.trajectory.timing`): hand-computed bounds,
limits as norms on a fine grid, shared waypoint times, merged near-duplicates."""

from __future__ import annotations

import math

import numpy as np
import pytest

from staghunt.task import VehicleLimits
from staghunt.trajectory import time_plan
from staghunt.trajectory.timing import acceleration_polyhedron, merge_waypoints, split_legs, team_chord

LIMITS = VehicleLimits(max_speed=12.0, max_acceleration=3.0, cruise_speed=5.0)


def _fine(traj, n=40001):
    t = np.linspace(0.0, traj.duration, n)
    return np.linalg.norm(traj.spline(t, 1), axis=-1), np.linalg.norm(traj.spline(t, 2), axis=-1)


def _line(direction, length, m=6):
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    return (np.array([10.0, 10.0, 20.0]) + np.linspace(0.0, length, m)[:, None] * d)[None]  # (1, m, 3)


def test_a_straight_line_takes_the_bang_bang_time():
    # From rest to rest over L = 100 m at v = 5 m/s and a = 3 m/s^2 no trajectory within the
    # limits can be faster than L / v + v / a = 21.667 s (accelerate 5/3 s, cruise, brake 5/3 s).
    L, v, a = 100.0, 5.0, 3.0
    traj = time_plan(_line([1, 0, 0], L), LIMITS)
    best = L / v + v / a
    assert best == pytest.approx(21.6667, abs=1e-3)
    assert best <= traj.duration <= 1.08 * best
    assert traj.bound == pytest.approx(best)
    speed, acc = _fine(traj)
    assert speed.max() <= v and acc.max() <= a
    assert speed.max() >= 0.95 * v  # it does cruise
    np.testing.assert_allclose(traj.spline(traj.times[[0, -1]], 1), 0.0, atol=1e-9)  # rest to rest


def test_limits_are_norms_not_per_axis():
    # Along the diagonal a per-axis limit would let the speed reach sqrt(3) * 5 = 8.66 m/s.
    traj = time_plan(_line([1, 1, 1], 150.0), LIMITS)
    speed, acc = _fine(traj)
    assert 0.95 * 5.0 <= speed.max() <= 5.0
    assert acc.max() <= 3.0
    assert traj.duration >= 150.0 / 5.0 + 5.0 / 3.0


def test_a_sharp_turn_slows_down_within_the_limits_and_keeps_the_waypoints():
    p = np.array([[[0, 0, 20], [30, 0, 20], [30, 30, 20], [0, 30, 25], [0, 60, 25]]], float)
    for spacing in (math.inf, 4.0, 1.5):
        traj = time_plan(p, LIMITS, spacing)
        speed, acc = _fine(traj)
        assert speed.max() <= 5.0 and acc.max() <= 3.0
        np.testing.assert_allclose(traj.spline(traj.times)[:, 0], p[0], atol=1e-9)
        assert np.all(np.diff(traj.times) > 0)
        assert traj.duration >= traj.bound


def test_the_team_shares_waypoint_times():
    # UAV 2 flies legs twice as long as UAV 1's: both reach their k-th point at the same time t_k,
    # and the timing is set by UAV 2 (the longest legs).
    a = np.array([[0, 0, 20], [10, 0, 20], [20, 5, 20], [30, 5, 20]], float)
    b = np.array([[0, 20, 20], [20, 20, 20], [40, 30, 20], [60, 30, 20]], float)
    traj = time_plan(np.stack([a, b]), LIMITS)
    pos = np.moveaxis(traj.spline(traj.times), 0, 1)
    np.testing.assert_allclose(pos, np.stack([a, b]), atol=1e-9)
    speed = np.linalg.norm(traj.spline(np.linspace(0, traj.duration, 20001), 1), axis=-1)  # (T, 2)
    assert speed[:, 1].max() > 0.95 * 5.0 and speed[:, 0].max() < 0.6 * 5.0
    np.testing.assert_allclose(team_chord(np.stack([a, b])), np.concatenate([[0], np.cumsum(
        np.linalg.norm(np.diff(b, axis=0), axis=-1))]))


def test_near_duplicate_waypoints_are_merged_for_the_whole_team():
    base = np.array([[0, 0, 20], [10, 0, 20], [10.2, 0.1, 20], [20, 0, 20], [20, 0, 20],
                     [30, 0, 20], [30.1, 0, 20]], float)
    other = base + [0, 20, 0]
    other[2] = other[1] + [2.0, 0, 0]  # UAV 2 moves 2 m on leg 1 -> 2: index 2 is kept
    p = np.stack([base, other])
    keep = merge_waypoints(p)
    assert keep.tolist() == [0, 1, 2, 3, 6]  # 4 duplicates 3; the goal 6 replaces 5 (0.1 m away)
    traj = time_plan(p, LIMITS)
    assert traj.kept.tolist() == keep.tolist() and traj.merged == 2
    assert np.all(np.diff(traj.times) > 0.05)  # no zero-length leg left
    np.testing.assert_allclose(traj.points[:, -1], p[:, -1])  # the goal is kept exactly
    single = np.array([[[0, 0, 20], [0.1, 0, 20], [0.2, 0, 20]]], float)
    assert merge_waypoints(single).tolist() == [0, 2]


def test_a_team_that_does_not_move_holds():
    p = np.repeat(np.array([[[5.0, 5.0, 20.0]]]), 4, axis=1)
    traj = time_plan(p, LIMITS)
    assert traj.points.shape == (1, 2, 3) and traj.duration > 0
    assert np.abs(traj.spline(np.linspace(0, traj.duration, 11), 1)).max() == 0.0


def test_split_legs_and_the_polyhedron():
    p = np.array([[[0, 0, 0], [10, 0, 0], [10, 3, 0]]], float)
    dense, index = split_legs(p, 4.0)
    assert index.tolist() == [0, 3, 4] and dense.shape == (1, 5, 3)
    np.testing.assert_allclose(dense[0, index], p[0])
    d, radius = acceleration_polyhedron()
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    assert 1.0 < radius < 1.09  # the polyhedron d . a <= 1 / R lies in the unit ball, close to it


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="finite"):
        time_plan(np.full((1, 3, 3), np.nan), LIMITS)
    with pytest.raises(ValueError, match="cruise_speed"):
        time_plan(_line([1, 0, 0], 10.0), VehicleLimits(max_speed=12.0, max_acceleration=3.0, cruise_speed=-1.0))


def test_each_uav_at_its_own_pace_when_the_teams_legs_differ():
    """Re-planned paths differ leg by leg: here UAV1 flies 30 m then 2 m, UAV2 2 m then 30 m.
    The team's common schedule gives every leg its longest UAV leg (30 m twice, and both turns
    as slow as the sharper); each UAV at its own pace (``own=True``, the sooner of
    :func:`timings`) arrives when the slower
    alone would, together, within the limits, from the start to the goals."""
    from staghunt.trajectory.quintic import DENSE_SPACING, split_legs as dense_legs, timed_path, timings
    from staghunt.trajectory.schedule import knot_times

    lim = VehicleLimits()
    a = np.array([[0.0, 0.0, 10.0], [30.0, 0.0, 10.0], [30.0, 2.0, 10.0]])
    b = np.array([[0.0, 20.0, 10.0], [0.0, 22.0, 10.0], [30.0, 22.0, 10.0]])
    pts = np.stack([a, b])
    team = timed_path(pts, 0.0, lim)
    own = timed_path(pts, 0.0, lim, own=True)
    assert timings(pts, 0.0, lim)[0].t1 == pytest.approx(own.t1)  # the sooner of the two
    alone = [timed_path(pts[n:n + 1], 0.0, lim).t1 for n in range(2)]
    assert own.t1 < 0.8 * team.t1  # measured 12.8 s against 17.3 s
    assert max(alone) < own.t1 <= max(alone) * 1.2  # 11.1 s alone (the knots of both UAVs slow each a little)
    t = np.linspace(0.0, own.t1, 2001)
    pos, vel, acc = own.state(t)[:3]
    assert np.linalg.norm(vel, axis=-1).max() <= lim.max_speed
    assert np.linalg.norm(acc, axis=-1).max() <= lim.max_acceleration * 1.001
    assert np.allclose(pos[:, 0], pts[:, 0]) and np.allclose(pos[:, -1], pts[:, -1], atol=1e-6)
    assert np.allclose(vel[:, -1], 0.0, atol=1e-6)
    # the common schedule: each of the two legs as long as its longer UAV leg, for both UAVs
    dense, _ = dense_legs(pts, DENSE_SPACING)
    assert team.t1 == pytest.approx(knot_times(dense, lim)[-1], rel=0.25)


def test_the_soonest_timing_is_made_first_and_the_others_only_when_asked_for(monkeypatch):
    """:func:`soonest_timings` (a re-plan's candidates: two point sets, the dense and the smooth
    curve, common and own pace) yields the same pieces in the same order as timing all eight and
    sorting them by arrival, and times for the first only those whose first schedule arrives
    before it (a schedule is only ever stretched): here 4 of the 8; once ``stop()`` is true, none."""
    import staghunt.trajectory.quintic as quintic

    lim = VehicleLimits()
    a = np.array([[0.0, 0.0, 10.0], [8.0, 1.0, 10.0], [30.0, 0.0, 10.0], [40.0, 12.0, 11.0], [70.0, 10.0, 10.0]])
    b = a + [0.0, 15.0, 0.0]
    b[2] += [3.0, -2.0, 1.0]
    sets = [np.stack([a, b]), np.stack([a, b])[:, [0, 2, 3, 4]]]
    v0 = np.array([[2.0, 0.5, 0.0], [2.0, 0.0, 0.2]])
    spacings = (quintic.DENSE_SPACING, quintic.SMOOTH_SPACING)
    every = sorted(((s, quintic.timed_path(p, 3.0, lim, v0, None, own=own, spacing=sp))
                    for s, p in enumerate(sets) for sp in spacings for own in (False, True)), key=lambda c: c[1].t1)
    made = []
    stretched = quintic._stretched
    monkeypatch.setattr(quintic, "_stretched", lambda *a, **k: made.append(1) or stretched(*a, **k))
    lazy = quintic.soonest_timings(sets, 3.0, lim, v0, spacings=spacings)
    s, first = next(lazy)
    speed0 = np.linalg.norm(v0, axis=-1)
    bounds = [3.0 + quintic._schedule(p, lim, speed0, own, sp)[1][-1] for p in sets for sp in spacings
              for own in (False, True)]
    assert len(made) == sum(b < first.t1 for b in bounds) == 4 < len(every) == 8
    rest = list(lazy)
    assert len(made) == 8
    assert [s for s, _ in [(s, first)] + rest] == [s for s, _ in every]
    for (_, p), (_, q) in zip([(s, first)] + rest, every):
        assert p.t1 == q.t1 and p.spacing == q.spacing
        np.testing.assert_array_equal(p.knots, q.knots)
        np.testing.assert_array_equal(p.points, q.points)
    stopped = []  # stopped after the first: nothing more is timed or yielded
    after_first = quintic.soonest_timings(sets, 3.0, lim, v0, spacings=spacings, stop=lambda: bool(stopped))
    assert next(after_first)[1].t1 == first.t1
    stopped.append(1)
    assert list(after_first) == []
    with pytest.raises(ValueError, match="stopped at its deadline"):
        next(quintic.soonest_timings(sets, 3.0, lim, v0, spacings=spacings, stop=lambda: True))
    with pytest.raises(ValueError, match="no timing"):  # none meets the limits: the first's error
        next(quintic.soonest_timings(sets, 0.0, VehicleLimits(), np.array([[-1.77, -5.52, -2.59]] * 2), max_tries=2))


def test_a_uav_that_waits_while_its_team_mate_moves_does_not_slow_the_team_to_a_crawl():
    """A plan where one UAV stays put for a leg while its team-mate flies (a re-plan around a
    known motion made such a plan: benchmarks/replan.py, scenario-2 episode 12, timed to 418 s
    for 150 m routes). Its zero-length legs have no direction, hence no turn: the team's common
    schedule is not capped at a crawl there, and stays within the limits."""
    from staghunt.trajectory.quintic import DENSE_SPACING, split_legs as dense_legs, timed_path
    from staghunt.trajectory.schedule import knot_times

    lim = VehicleLimits()
    a = np.array([[0.0, 0.0, 10.0], [30.0, 0.0, 10.0], [60.0, 0.0, 10.0]])
    b = np.array([[0.0, 20.0, 10.0], [0.0, 20.0, 10.0], [30.0, 20.0, 10.0]])  # waits, then flies
    pts = np.stack([a, b])
    dense, _ = dense_legs(pts, DENSE_SPACING)
    alone = timed_path(a[None], 0.0, lim).t1
    assert knot_times(dense, lim)[-1] <= 1.01 * knot_times(dense[:1], lim)[-1]  # the mover's own schedule
    team = timed_path(pts, 0.0, lim)
    assert team.t1 < 2.0 * alone  # before: b's still legs counted as right-angle turns of radius 0
    t = np.linspace(0.0, team.t1, 4001)
    pos, vel, acc = team.state(t)[:3]
    assert np.linalg.norm(vel, axis=-1).max() <= lim.max_speed
    assert np.linalg.norm(acc, axis=-1).max() <= lim.max_acceleration * 1.001
    assert np.allclose(pos[:, -1], pts[:, -1], atol=1e-6)


def test_a_timing_the_start_itself_breaks_gives_up_once_stretching_stops_helping():
    """A UAV at 6.4 m/s whose path turns back 2 cm ahead: no schedule after the start meets the
    limits. With no bound on the stretch, the timing doubled the start's interval every try and
    gave up after the twentieth at a stretch of 4e5 (20 s for one UAV, sampling a curve days
    long); past four times its first schedule, it now gives up once three stretches in a row
    leave the worst peak where it was."""
    import re

    from staghunt.trajectory.quintic import STALL_STRETCH, STALL_TRIES, timed_path

    pts = np.array([[[0.0, 0.0, 10.0], [-0.01, 0.0, 10.02], [0.9, 0.57, 10.82], [-3.2, -0.6, 7.95],
                     [-0.24, -8.76, 7.29], [-10.03, -24.57, -2.67]]])
    with pytest.raises(ValueError, match="after a stretch of") as err:
        timed_path(pts, 0.0, VehicleLimits(), np.array([[-1.77, -5.52, -2.59]]))
    stretch = float(re.search(r"after a stretch of ([0-9.e+]+)", str(err.value)).group(1))
    assert stretch < STALL_STRETCH * 2.0 ** (STALL_TRIES + 1)


def test_a_slow_down_keeps_the_paths_and_continuity_and_arrives_exactly_its_delay_later():
    """:func:`slow_piece` on a straight team flight at cruise: hand-checked warp (``tau'`` at the
    hold is the factor, the delay is ``(1 - factor)(ramp + hold)``), positions on the same paths
    at the warped time, no jump at the splice, the acceleration limit kept, rest at the end."""
    from staghunt.trajectory.quintic import Reference, slow_piece, timed_path
    from staghunt.trajectory.warp import slow_warp

    s = np.array([0.0, 0.5, 1.0, 2.0, 3.0, 3.5, 4.0, 9.0])
    tau, d1, d2 = slow_warp(s, 1.0, 2.0, 0.25)  # ramp 1 s, hold 2 s, a quarter of the pace
    np.testing.assert_allclose(d1, [1.0, 0.625, 0.25, 0.25, 0.25, 0.625, 1.0, 1.0])
    np.testing.assert_allclose(d2[[0, 2, 3, 4, 6, 7]], 0.0, atol=1e-12)
    assert d2[1] == pytest.approx(-0.75 * 1.5) and d2[5] == pytest.approx(0.75 * 1.5)  # 6 x (1 - x) / ramp
    # behind by (1 - 0.25)(1/2 + 2 + 1/2) = 2.25 s once it is over; 0.75 x (1/2 - (1/8 - 1/32)) at 0.5 s
    np.testing.assert_allclose(tau[[6, 7]], s[[6, 7]] - 2.25)
    assert tau[1] == pytest.approx(0.5 - 0.75 * (0.125 - 0.03125))
    pts = np.array([[[5, 15, 12], [30, 15, 12], [55, 15, 12]], [[5, 23, 12], [30, 23, 12], [55, 23, 12]]], float)
    ref = Reference((timed_path(pts, 0.0, LIMITS),))
    piece = slow_piece(ref, 3.0, LIMITS, 3.0, 0.25)
    assert piece is not None and piece.kind == "slow"
    new = ref.spliced(piece)
    assert new.arrival == pytest.approx(ref.arrival + 3.0)
    t = np.linspace(3.0, new.arrival, 3001)
    here = new.state(t)
    np.testing.assert_allclose(here[0], ref.state(np.minimum(piece.warp(t)[0], ref.arrival))[0], atol=1e-9)
    before, after = ref.state(np.array([3.0])), new.state(np.array([3.0]))
    np.testing.assert_allclose(after[:3], before[:3], atol=1e-9)  # position, velocity, acceleration
    assert np.linalg.norm(here[2], axis=-1).max() <= LIMITS.max_acceleration
    assert np.linalg.norm(here[1][:, -1], axis=-1).max() == 0.0
    ramp, (hold, factor) = piece.duration, piece.slow
    during = (t > 3.0 + ramp) & (t < 3.0 + ramp + hold)
    base_speed = np.linalg.norm(ref.state(piece.warp(t[during])[0])[1], axis=-1)
    np.testing.assert_allclose(np.linalg.norm(here[1][:, during], axis=-1), factor * base_speed, rtol=1e-9)
    assert base_speed.min() > 4.0  # cruising there: the team goes on at a quarter of that, never hovering
    assert slow_piece(ref, 3.0, LIMITS, 30.0, 0.25) is None  # the flight ends before such a slow-down is over


def test_turn_backs_counts_the_points_after_the_lead_in_that_turn_a_uav_back():
    """A re-plan's paths: the switch position, the lead-in's end (point 1), then the game's
    waypoints. UAV2's first two waypoints lie behind its lead-in's end (it would turn back by
    more than 90 degrees there); its third and UAV1's all lie ahead: drop two. At most
    ``most``; never the goal; none when nobody turns back."""
    from staghunt.trajectory.timing import turn_backs

    a = np.array([[0.0, 0.0, 10.0], [8.0, 0.0, 10.0], [12.0, 1.0, 10.0], [16.0, 2.0, 10.0],
                  [20.0, 3.0, 10.0], [40.0, 3.0, 10.0]])
    b = np.array([[0.0, 10.0, 10.0], [8.0, 10.0, 10.0], [7.0, 13.0, 10.0], [6.0, 16.0, 10.0],
                  [10.0, 19.0, 10.0], [40.0, 13.0, 10.0]])
    pts = np.stack([a, b])  # (2, 6, 3)
    assert turn_backs(pts, 1, 3) == 2  # (7, 13) and (6, 16) lie behind x = 8; (10, 19) does not
    assert turn_backs(pts, 1, 1) == 1
    assert turn_backs(pts[:1], 1, 3) == 0
    back = pts.copy()
    back[1, 2:5, 0] = 5.0  # every waypoint of UAV2 behind: the goal is kept
    assert turn_backs(back, 1, 10) == 3
