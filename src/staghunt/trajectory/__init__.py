"""Timed, synchronised trajectories of a plan, and their safety checked in time.

Every UAV flies a cubic spline through all its planned points (start, the ``K`` free waypoints,
goal; absolute site coordinates) with **common waypoint times**: the formation cost is defined
per waypoint index, so the ``k``-th waypoints are reached together, all UAVs leave together and
arrive together. The spline (:class:`scipy.interpolate.CubicSpline`, clamped: zero velocity at
both ends) has continuous velocity and acceleration. Timing:

1. each leg ``k`` first gets the time the slowest UAV needs for it at the cruise speed (its
   longest segment / ``cruise_speed``; at least :data:`MIN_LEG_S`);
2. the whole schedule is then stretched by one factor ``s >= 1`` so that no UAV exceeds
   ``max_speed`` or ``max_acceleration`` anywhere: stretching time by ``s`` divides every
   velocity by ``s`` and every acceleration by ``s^2`` (the spline's shape is unchanged), so a
   limit the plan cannot meet is met by slowing down, never by exceeding it. The acceleration of
   a cubic spline is linear between knots, so its maximum is taken at the knots exactly; speed
   is checked on a 2 ms grid, and a margin of :data:`MARGIN` is kept.

Why scipy's splines and not a minimum-snap or time-optimal library: the team must share its
waypoint times, which minimum-snap packages (minsnap-trajectories) and TOPP-RA (toppra) time per
vehicle; a common clamped cubic spline per UAV with one global retiming gives C2 trajectories
that meet the limits exactly by construction, with a dependency the project already has.

:func:`check_in_time` samples the trajectories on one time grid (step <= 0.1 s) and checks, at
the same instant, the distance between UAVs against ``d_s + 2 r``, the obstacle clearance
against ``min_clearance`` (cylinders, prisms, no-fly zones, the ceiling), the height above
ground, and reports the minima; a broken limit makes the mission unsafe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from staghunt.checks import outside_site, plan_metrics, violations
from staghunt.costs import CostModel
from staghunt.task import VehicleLimits

MIN_LEG_S = 0.2
"""Shortest leg (s): legs where no UAV moves still take this long (the spline needs rising times)."""
MARGIN = 1e-3
"""Relative margin kept below the speed and acceleration limits."""
SAMPLE_S = 0.1
"""Largest step of the time grid of the checks and of ``trajectories.csv``."""


@dataclass(frozen=True, eq=False)
class Trajectories:
    """Timed trajectories of ``N`` UAVs through ``M = K + 2`` points each.

    - ``times``: ``(M,)`` common waypoint times (s), ``times[0] = 0``.
    - ``points``: ``(N, M, 3)`` absolute site ``(x, y, z)``.
    - ``spline``: one :class:`CubicSpline` over ``times`` with values ``(N, 3)`` per time.
    - ``max_speed``, ``max_acceleration``: ``(N,)`` the largest found (m/s, m/s^2).
    - ``stretch``: the factor the cruise-speed schedule was slowed by to meet the limits (1 = none).
    """

    times: np.ndarray
    points: np.ndarray
    spline: CubicSpline
    max_speed: np.ndarray
    max_acceleration: np.ndarray
    stretch: float

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def grid(self, step: float = SAMPLE_S) -> np.ndarray:
        """``(T,)`` times from 0 to arrival with a step of at most ``step``."""
        n = max(1, math.ceil(self.duration / step - 1e-9))
        return np.linspace(0.0, self.duration, n + 1)

    def sample(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities ``(N, T, 3)`` at times ``t`` ``(T,)``."""
        pos = np.moveaxis(self.spline(t), 0, 1)
        vel = np.moveaxis(self.spline(t, 1), 0, 1)
        return pos, vel

    def leg_speeds(self) -> np.ndarray:
        """``(N, M - 1)`` average speed of each UAV on each leg (m/s): length / common leg time."""
        seg = np.linalg.norm(np.diff(self.points, axis=1), axis=-1)
        return seg / np.diff(self.times)[None]


def _spline(times: np.ndarray, points: np.ndarray) -> CubicSpline:
    return CubicSpline(times, np.moveaxis(points, 0, 1), axis=0, bc_type="clamped")


def _peaks(spline: CubicSpline, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(N,)`` largest speed (2 ms grid and knots) and acceleration (at the knots, exact)."""
    fine = np.union1d(np.arange(0.0, times[-1], 0.002), times)
    speed = np.linalg.norm(spline(fine, 1), axis=-1).max(axis=0)
    acc = np.linalg.norm(spline(times, 2), axis=-1).max(axis=0)
    return speed, acc


def time_plan(points: np.ndarray, limits: VehicleLimits) -> Trajectories:
    """Time the team's paths ``points`` ``(N, M, 3)`` (absolute site coordinates) within ``limits``."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 3 or p.shape[2] != 3 or p.shape[1] < 2:
        raise ValueError(f"points must be (N, M, 3) with M >= 2, got {p.shape}")
    for name in ("max_speed", "max_acceleration", "cruise_speed"):
        v = getattr(limits, name)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise ValueError(f"vehicle.{name} must be a finite number > 0, got {v!r}")
    legs = np.linalg.norm(np.diff(p, axis=1), axis=-1).max(axis=0)  # (M - 1,) slowest UAV's leg
    dt = np.maximum(legs / min(limits.cruise_speed, limits.max_speed), MIN_LEG_S)
    times = np.concatenate([[0.0], np.cumsum(dt)])
    spline = _spline(times, p)
    speed, acc = _peaks(spline, times)
    stretch = max(1.0, float(speed.max()) / limits.max_speed,
                  math.sqrt(float(acc.max()) / limits.max_acceleration)) * (1.0 + MARGIN)
    if stretch > 1.0 + MARGIN:
        times = times * stretch
        spline = _spline(times, p)
        speed, acc = _peaks(spline, times)
    else:
        stretch = 1.0
    return Trajectories(times=times, points=p, spline=spline, max_speed=speed,
                        max_acceleration=acc, stretch=stretch)


@dataclass(frozen=True)
class SafetyReport:
    """Minima over the sampled trajectories (metres): per UAV ``min_separation`` (to any
    team-mate at the same instant), ``min_clearance`` (obstacles), ``min_height`` (above
    ground); ``problems``: the broken limits (empty = safe); ``notes``: departures from the
    planning box that break no limit (e.g. a spline dipping below ``hmin``)."""

    times: int
    step: float
    min_separation: tuple[float, ...]
    separation_limit: tuple[float, ...]
    min_clearance: tuple[float, ...]
    required_clearance: float
    min_height: tuple[float, ...]
    problems: tuple[str, ...]
    notes: tuple[str, ...]

    @property
    def safe(self) -> bool:
        return not self.problems


def check_in_time(model: CostModel, traj: Trajectories, names: list[str], step: float = SAMPLE_S) -> SafetyReport:
    """Separation, clearance and height of the trajectories sampled every ``<= step`` seconds.

    The samples become a dense "plan" whose synchronised points are the instants, so the
    project's own checks (:func:`staghunt.checks.plan_metrics`, :func:`violations`) judge them:
    separation at the same instant, obstacles along the short segments between samples."""
    t = traj.grid(step)
    pos, _ = traj.sample(t)  # (N, T, 3)
    free = pos[:, 1:-1].copy()
    free[..., 2] = pos[:, 1:-1, 2] - model.terrain.height(free[..., 0], free[..., 1])
    if free.shape[1] == 0:
        free = pos[:, :1].copy()
        free[..., 2] -= model.terrain.height(free[..., 0], free[..., 1])
    m = plan_metrics(model, free)
    # violations() already judges obstacles against R + r + min_clearance, the ceiling, the
    # ground and the separation at every instant.
    problems = [f"in time: {v}" for v in violations(model, free, names)]
    notes = outside_site(model, free, names)
    return SafetyReport(
        times=len(t), step=float(t[1] - t[0]) if len(t) > 1 else 0.0,
        min_separation=tuple(float(v) for v in m.min_separation_waypoints),
        separation_limit=tuple(float(v) for v in m.separation_limit),
        min_clearance=tuple(float(v) for v in m.min_clearance),
        required_clearance=float(model.min_clearance),
        min_height=tuple(float(v) for v in m.min_height),
        problems=tuple(problems[:20]),
        notes=tuple(f"{x} (sampled trajectory; breaks no limit)" for x in notes[:10]),
    )
