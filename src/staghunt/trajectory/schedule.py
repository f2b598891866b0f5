"""Schedules of a team's dense paths: the waypoint times a timed path
(:func:`staghunt.trajectory.quintic.timed_path`) puts its quintic spline through.

:func:`knot_times` gives the whole team one schedule (cruise speed, slower in turns, speed
changes within :data:`SCHEDULE_SHARE` of the acceleration limit); :func:`own_pace` lets every
UAV keep its own and wait out its lead over the slowest, all arriving together.
"""

from __future__ import annotations

import math

import numpy as np

from staghunt.task import VehicleLimits

SCHEDULE_SHARE = 0.5
"""Share of ``max_acceleration`` :func:`knot_times` plans with: its turns' lateral acceleration
and its speed changes (the rest is the spline's, between the knots). A re-plan's lead-in is the
stopping distance at this share (:func:`staghunt.flight.known.lead_in`)."""


def knot_times(points: np.ndarray, limits: VehicleLimits, v0: float = 0.0) -> np.ndarray:
    """``(M,)`` waypoint times (from 0) of the team's dense paths ``points`` ``(N, M, 3)``.

    The team's speed ``u`` at each point is that of its fastest UAV on the adjacent leg. It is
    capped by the cruise speed and, at a turn, by ``sqrt(a_t rho)`` with ``rho`` the turn's
    radius (the mean adjacent leg length over the turning angle, for every UAV) and
    ``a_t = max_acceleration`` x :data:`SCHEDULE_SHARE`; a forward and a backward pass then keep
    the speed changes within ``a_t`` (from ``v0`` at the start to rest at the end); a leg takes
    ``2 L / (u_k + u_{k+1})`` (its longest UAV leg ``L``)."""
    seg = np.diff(points, axis=1)  # (N, M - 1, 3)
    length = np.linalg.norm(seg, axis=-1)  # (N, M - 1)
    L = length.max(axis=0)
    a_t = SCHEDULE_SHARE * limits.max_acceleration
    cap = np.full(L.size + 1, min(limits.cruise_speed, limits.max_speed))
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = seg / length[..., None]
        cos = np.clip(np.nansum(unit[:, :-1] * unit[:, 1:], axis=-1), -1.0, 1.0)  # (N, M - 2)
        # a UAV that stays put on a leg (its team-mates fly it) has no direction there, so no
        # turn: counted as one (a right angle of radius 0), it capped the team at a crawl
        moving = (length[:, :-1] > 0.0) & (length[:, 1:] > 0.0)
        angle = np.where(moving, np.arccos(cos), 0.0)
        rho = 0.5 * (length[:, :-1] + length[:, 1:]) / angle
    turn_cap = np.sqrt(a_t * np.where(angle > 1e-6, rho, np.inf)).min(axis=0)
    cap[1:-1] = np.minimum(cap[1:-1], turn_cap)
    cap[0], cap[-1] = min(cap[0], max(v0, 0.0)), 0.0
    u = cap.copy()
    for k in range(1, u.size):
        u[k] = min(u[k], math.sqrt(u[k - 1] ** 2 + 2 * a_t * L[k - 1]))
    for k in range(u.size - 2, -1, -1):
        u[k] = min(u[k], math.sqrt(u[k + 1] ** 2 + 2 * a_t * L[k]))
    dt = np.maximum(2.0 * L / np.maximum(u[:-1] + u[1:], 0.2), 1e-3)
    return np.concatenate([[0.0], np.cumsum(dt)])


MIN_KNOTS = 6
"""Knots of :func:`own_pace`'s schedule, at least (a quintic with its end conditions needs them)."""
MIN_KNOT_S = 0.3
"""Seconds between two knots of :func:`own_pace`'s team schedule, at least (closer ones merged)."""


def own_pace(dense: np.ndarray, limits: VehicleLimits, speed0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Knot times ``(M',)`` (from 0) and points ``(N, M', 3)`` of the team's dense paths ``dense``
    ``(N, M, 3)``, each UAV at its own pace (``speed0`` ``(N,)``: its speed at the start).

    :func:`knot_times` gives the whole team one schedule, each leg as long as its slowest UAV's
    and each turn as slow as its sharpest: for a formation's parallel paths that is each UAV's
    own, but paths re-planned from a moving state differ leg by leg, and the team's schedule
    came to up to 4.7x the slowest UAV's own (benchmarks/JOURNAL.md, "Closed loop: why stops and
    extra time stayed").
    Here every UAV keeps its own schedule (:func:`knot_times` of its path alone) and waits out
    its lead over the slowest along a smoothstep (its start and its arrival untouched: all
    arrive together); the team's knots are the union of the UAVs' (closer than
    :data:`MIN_KNOT_S` merged), every UAV's points at them interpolated along its own path,
    so its own corners stay knots."""
    N = dense.shape[0]
    tau = np.stack([knot_times(dense[n:n + 1], limits, float(speed0[n])) for n in range(N)])  # (N, M)
    end = tau[:, -1]
    total = float(end.max())
    x = tau / np.maximum(end, 1e-9)[:, None]
    t = tau + (total - end)[:, None] * (x * x * (3.0 - 2.0 * x))  # (N, M) on the team's clock
    grid = np.unique(t)
    grid = grid[np.r_[True, np.diff(grid) > MIN_KNOT_S]]
    grid[-1] = total
    if grid.size < MIN_KNOTS:
        grid = np.linspace(0.0, total, MIN_KNOTS)
    pts = np.stack([np.stack([np.interp(grid, t[n], dense[n, :, c]) for c in range(3)], axis=-1)
                    for n in range(N)])
    return grid, pts
