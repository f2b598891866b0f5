"""Timed, synchronised trajectories of a plan, and their safety checked in time.

The team flies its planned points (start, the ``K`` free waypoints, goal; absolute site
coordinates) with **common waypoint times**: the formation cost is defined per waypoint index,
so the ``k``-th waypoints are reached together, all UAVs leave together and arrive together.
:func:`time_plan` merges near-duplicate waypoints for the whole team and times the team's
paths time-optimally under every UAV's speed (``cruise_speed``) and acceleration
(``max_acceleration``) norms with one path parameter (:mod:`staghunt.trajectory.timing`,
TOPP-RA). :func:`time_and_check` picks the smoothest geometric path whose flight in time is
safe: smooth curves through the waypoints are fastest, but may cut a corner closer to an
obstacle than the planned polyline; splitting the legs into shorter sub-legs keeps the curve
closer to the polyline at the price of slower turns.

:func:`check_in_time` samples the trajectories on one time grid (every 0.02 s) and judges them
with the one safety judge (:mod:`staghunt.safety`) at the same instant: the distance between
UAVs against ``d_s + 2 r``, the clearance to the obstacles (cylinders, prisms, no-fly zones)
and to the ground against ``min_clearance``, the headroom under the ceiling, and reports the
minima; a broken margin makes the mission unsafe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from staghunt.checks import outside_site
from staghunt.costs import CostModel
from staghunt.safety import Margins, Scene, judge
from staghunt.task import VehicleLimits
from staghunt.trajectory import timing as tm
from staghunt.trajectory.team import TeamTrajectory

MARGIN = 1e-3
"""Relative margin kept below the speed and acceleration limits."""
SAMPLE_S = 0.1
"""Largest step of the time grid of ``trajectories.csv``."""
CHECK_S = 0.02
"""Step of the time grid of :func:`check_in_time` (at cruise speed 5 m/s, 0.1 m between samples)."""
SPACINGS = (math.inf, 10.0, 4.0, 1.5)
"""Sub-leg lengths (m) :func:`time_and_check` tries, smoothest first (``inf``: the waypoints only)."""


@dataclass(frozen=True, eq=False)
class Trajectories:
    """Timed trajectories of ``N`` UAVs through ``M`` points each (the plan's ``K + 2`` points
    after merging near-duplicates).

    - ``times``: ``(M,)`` common waypoint times (s), ``times[0] = 0``.
    - ``points``: ``(N, M, 3)`` absolute site ``(x, y, z)``.
    - ``kept``: ``(M,)`` the index in the plan of each point (merged ones are missing).
    - ``spline``: one clamped :class:`CubicSpline` in time with values ``(N, 3)`` per time.
    - ``max_speed``, ``max_acceleration``: ``(N,)`` the largest found (m/s, m/s^2).
    - ``stretch``: the factor the time-optimal schedule was slowed by to meet the limits
      between TOPP-RA's grid points (1 = none).
    - ``spacing``: the longest sub-leg of the geometric path (m; ``inf``: through the
      waypoints only).
    - ``bound``: ``max_n L_n / cruise_speed + cruise_speed / max_acceleration`` (s), ``L_n``
      the length of UAV ``n``'s planned polyline: a reference a mission cannot beat by much.
    """

    times: np.ndarray
    points: np.ndarray
    kept: np.ndarray
    spline: CubicSpline
    max_speed: np.ndarray
    max_acceleration: np.ndarray
    stretch: float
    spacing: float
    bound: float

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    @property
    def merged(self) -> int:
        """How many of the plan's waypoint indices were merged into their neighbours."""
        return int(self.kept[-1] + 1 - len(self.kept))

    def grid(self, step: float = SAMPLE_S) -> np.ndarray:
        """``(T,)`` times from 0 to arrival with a step of at most ``step``."""
        n = max(1, math.ceil(self.duration / step - 1e-9))
        return np.linspace(0.0, self.duration, n + 1)

    @property
    def n_uavs(self) -> int:
        return int(self.points.shape[0])

    @property
    def span(self) -> tuple[np.ndarray, np.ndarray]:
        """Every UAV leaves at 0 and arrives at :attr:`duration` (the common timing)."""
        return np.zeros(self.n_uavs), np.full(self.n_uavs, self.duration)

    def state(self, t: np.ndarray) -> np.ndarray:
        """``(4, N, T, 3)`` position, velocity, acceleration, jerk at times ``t`` ``(T,)``
        (:class:`~staghunt.trajectory.team.TeamTrajectory`; at rest outside ``[0, duration]``)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        tc = np.clip(t, 0.0, self.duration)
        out = np.stack([np.moveaxis(self.spline(tc, d), 0, 1) for d in range(4)])
        out[1:, :, (t < 0.0) | (t > self.duration)] = 0.0
        return out

    def sample(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities ``(N, T, 3)`` at times ``t`` ``(T,)``."""
        pos = np.moveaxis(self.spline(t), 0, 1)
        vel = np.moveaxis(self.spline(t, 1), 0, 1)
        return pos, vel

    def leg_speeds(self) -> np.ndarray:
        """``(N, M - 1)`` average speed of each UAV on each leg (m/s): length / common leg time."""
        seg = np.linalg.norm(np.diff(self.points, axis=1), axis=-1)
        return seg / np.diff(self.times)[None]


def _peaks(spline: CubicSpline) -> tuple[np.ndarray, np.ndarray]:
    """``(N,)`` largest speed (2 ms grid and knots) and acceleration (at the knots: exact, a
    cubic's acceleration is linear between them)."""
    knots = spline.x
    fine = np.union1d(np.arange(0.0, knots[-1], 0.002), knots)
    speed = np.linalg.norm(spline(fine, 1), axis=-1).max(axis=0)
    acc = np.linalg.norm(spline(knots, 2), axis=-1).max(axis=0)
    return speed, acc


def _check_limits(limits: VehicleLimits) -> None:
    for name in ("max_speed", "max_acceleration", "cruise_speed"):
        v = getattr(limits, name)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise ValueError(f"vehicle.{name} must be a finite number > 0, got {v!r}")


def time_plan(points: np.ndarray, limits: VehicleLimits, spacing: float = math.inf) -> Trajectories:
    """Time the team's paths ``points`` ``(N, M, 3)`` (absolute site coordinates) within
    ``limits``: speed <= ``min(cruise_speed, max_speed)`` and acceleration <=
    ``max_acceleration`` as norms, time-optimal for the common path (module docstring).
    ``spacing``: split every leg into sub-legs of at most this length first (m)."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 3 or p.shape[2] != 3 or p.shape[1] < 2 or not np.all(np.isfinite(p)):
        raise ValueError(f"points must be finite (N, M, 3) with M >= 2, got shape {p.shape}")
    _check_limits(limits)
    if not (spacing > 0):
        raise ValueError(f"spacing must be > 0, got {spacing!r}")
    v_max = min(limits.cruise_speed, limits.max_speed)
    lengths = np.linalg.norm(np.diff(p, axis=1), axis=-1).sum(axis=1)  # (N,)
    bound = float(lengths.max()) / v_max + v_max / limits.max_acceleration
    kept = tm.merge_waypoints(p)
    wp = p[:, kept]
    if len(kept) < 2 or float(tm.team_chord(wp)[-1]) <= 0.0:  # nobody moves: hold
        times = tm.hold_times()
        wp = p[:, [0, -1]]
        kept = np.array([0, p.shape[1] - 1])
        spline = tm.team_spline(times, np.moveaxis(wp, 0, 1))
        zero = np.zeros(p.shape[0])
        return Trajectories(times=times, points=wp, kept=kept, spline=spline, max_speed=zero,
                            max_acceleration=zero, stretch=1.0, spacing=spacing, bound=bound)
    dense, index = (wp, np.arange(wp.shape[1])) if math.isinf(spacing) else tm.split_legs(wp, spacing)
    t, q, at = tm.parameterise(dense, v_max, limits.max_acceleration)
    spline = tm.team_spline(t, q)
    speed, acc = _peaks(spline)
    stretch = max(1.0, float(speed.max()) / v_max,
                  math.sqrt(float(acc.max()) / limits.max_acceleration)) * (1.0 + MARGIN)
    if stretch > 1.0 + MARGIN:
        t = t * stretch
        spline = tm.team_spline(t, q)
        speed, acc = _peaks(spline)
    else:
        stretch = 1.0
    return Trajectories(times=t[at[index]], points=wp, kept=kept, spline=spline, max_speed=speed,
                        max_acceleration=acc, stretch=stretch, spacing=spacing, bound=bound)


def time_and_check(model: CostModel, points: np.ndarray, limits: VehicleLimits,
                   names: list[str]) -> tuple[Trajectories, SafetyReport]:
    """The smoothest timing of :data:`SPACINGS` whose flight in time is safe, with its report;
    if none is, the last (closest to the polyline) with its problems."""
    for spacing in SPACINGS:
        traj = time_plan(points, limits, spacing)
        safety = check_in_time(model, traj, names)
        if safety.safe:
            break
    return traj, safety


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


def check_in_time(model: CostModel, traj: TeamTrajectory, names: list[str], step: float = CHECK_S) -> SafetyReport:
    """Separation, clearance, ground and ceiling of the trajectories sampled every ``<= step``
    seconds (:func:`check_positions`)."""
    t0, t1 = float(np.min(traj.span[0])), float(np.max(traj.span[1]))
    t = np.linspace(t0, t1, max(2, math.ceil((t1 - t0) / step - 1e-9) + 1))
    return check_positions(model, traj.state(t)[0], names, float(t[1] - t[0]))


def check_positions(model: CostModel, pos: np.ndarray, names: list[str], step: float) -> SafetyReport:
    """Separation, clearance, ground and ceiling of every UAV's positions ``pos`` ``(N, T, 3)``
    (absolute) sampled at the same ``T`` instants, ``step`` seconds apart, judged by the one
    safety judge (:func:`staghunt.safety.judge`) with the model's required margins (its hard
    clearance to obstacles and to the ground, ``d_s`` between UAVs); departures from the
    planning box are notes."""
    times = np.arange(pos.shape[1]) * step
    margins = Margins(float(model.min_clearance), float(model.safe_distance), float(model.min_clearance), 0.0)
    verdict = judge(Scene.of_arrays(model.terrain, model.ceiling, model.cylinders, model.prisms, model.prism_edges),
                    np.asarray(model.radius, dtype=float), times, pos, margins, names)
    free = pos.copy()
    free[..., 2] -= model.terrain.height(free[..., 0], free[..., 1])
    notes = outside_site(model, free[:, 1:-1] if free.shape[1] > 2 else free[:, :1], names)
    return SafetyReport(
        times=pos.shape[1], step=step,
        min_separation=tuple(float(v) for v in verdict.min_separation),
        separation_limit=tuple(float(v) for v in model.safe_distance + 2.0 * np.asarray(model.radius)),
        min_clearance=tuple(float(v) for v in verdict.min_clearance),
        required_clearance=float(model.min_clearance),
        min_height=tuple(float(v) for v in verdict.min_ground + np.asarray(model.radius)),
        problems=tuple(f"in time: {p}" for p in verdict.problems(names)),
        notes=tuple(f"{x} (sampled trajectory; breaks no limit)" for x in notes[:10]),
    )
