"""Quintic team trajectories, the curves a flight flies: timed pieces spliced one after the
other (:class:`Reference`, a :class:`~staghunt.trajectory.team.TeamTrajectory`).

A piece is either

- a **timed path** (:func:`timed_path`): every UAV flies a quintic spline through its planned
  points (the switch state, the ``K`` free waypoints, the goal), each leg split into the same
  number of sub-legs of at most 3 m for the whole team, with **common waypoint times** (the
  formation is defined per waypoint index). The dense points keep the spline within about
  0.15 m of the planned polyline (a spline through the ``K + 2`` points alone cuts corners by
  1-2 m, through obstacles' clearance). The spline starts with the given velocity and
  acceleration (those of the trajectory it replaces, so a splice is continuous in position,
  velocity and acceleration) and ends at rest. Times come from a speed profile
  (:func:`knot_times`: cruise speed, slower in turns, accelerations within half the limit),
  and if a peak still breaks ``max_speed`` or ``max_acceleration`` (norms, checked on a 20 ms
  grid, on a 100 ms one until that passes) the knot intervals where it does (and their
  neighbours) are slowed down, so a sharp
  turn at the start of a re-plan slows the start, not the whole flight. A re-plan also times
  the **smooth** curve (:data:`SMOOTH_SPACING`: a quintic through the planned points alone,
  which rounds the polyline's corners instead of turning sharply at them) and flies it if it is
  sooner and keeps the acceptance's full margins (:func:`timings`); or
- a **synchronised stop** (:func:`stop_piece`): the previous piece (or any team trajectory:
  one UAV's own, for a hold) with time slowed down by one common warp ``tau(t)``,
  ``tau' = 1 - (3u^2 - 2u^3)``, ``u = (t - t_s) / T``: every UAV stays on its planned path
  (so the separations and clearances already checked still hold), and all of them come to
  rest together at the same path parameter. ``tau'' = 0`` at both ends, so position, velocity
  and acceleration are continuous; ``T`` is the shortest that keeps the acceleration within
  ``max_acceleration``. An emergency stop uses :func:`brake_warp` instead
  (the same continuity, a shorter stop).

Why scipy's ``make_interp_spline`` (k = 5) and not toppra or a minimum-snap package: the splice
needs position, velocity *and* acceleration imposed at the switch for the whole team at once
with shared knot times; a quintic interpolating B-spline takes exactly those end conditions.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass
from typing import Callable, Iterator, Literal, Sequence

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline

from staghunt.task import VehicleLimits
from staghunt.trajectory.schedule import knot_times, own_pace
from staghunt.trajectory.team import Still, TeamTrajectory, end_time
from staghunt.trajectory.timing import merge_waypoints, split_legs
from staghunt.trajectory.warp import BRAKE_RAMP, brake_warp, slow_warp

CHECK_STEP_S = 0.02
"""Grid of the speed and acceleration checks (s)."""
COARSE_STEP_S = 0.1
"""Grid of a timing's first tries (s): the peaks of a schedule far over the limits show on it as
well, for a fifth of the samples; a schedule is accepted on the :data:`CHECK_STEP_S` grid only."""
MARGIN = 0.98
"""Peaks are kept below this share of the limits (the grid may miss a peak between samples)."""
CACHED = 8
"""Answers of :meth:`Piece.state` kept per piece."""
REST_TOL = 1e-9
"""A trajectory moving less than this (m, m/s) over a stop's reach is at rest: its stop is of a
:class:`~staghunt.trajectory.team.Still` team (:func:`stop_piece`)."""


@dataclass(frozen=True, eq=False)
class Piece:
    """One piece of the reference, valid from ``t0`` (s after take-off) until the next piece
    starts; after ``t1`` the team holds the piece's last point.

    - ``kind``: ``"path"`` (a timed path), ``"stop"`` (a synchronised stop of ``base``) or
      ``"slow"`` (``base`` slowed down in sync and sped up again: :func:`slow_piece`).
    - ``spline``: for a path, a :class:`BSpline` over ``[t0, t1]`` with values ``(N, 3)``.
    - ``base``, ``duration``: for a stop, the trajectory it slows down (a piece, or any
      :class:`~staghunt.trajectory.team.TeamTrajectory`) and the warp's length ``T``; for a
      slow-down, ``base``, the length of each of its two ramps, and ``slow`` = ``(hold, factor)``
      (:func:`~staghunt.trajectory.warp.slow_warp`).
    - ``knots``: ``(M,)`` the waypoint times; ``points``: ``(N, M, 3)`` the planned points
      (a stop of a trajectory other than a piece: its positions at ``t0`` and at rest).
    - ``spacing``: for a path, the longest sub-leg its spline was put through (m;
      :data:`DENSE_SPACING`, or ``inf`` for the smooth curve through the planned points alone).
    """

    kind: Literal["path", "stop", "slow"]
    t0: float
    t1: float
    knots: np.ndarray
    points: np.ndarray
    spline: BSpline | None = None
    base: "TeamTrajectory | None" = None
    duration: float = 0.0
    brake: bool = False
    slow: tuple[float, float] = ()
    spacing: float = 0.0

    @property
    def n_uavs(self) -> int:
        return int(self.points.shape[0])

    @property
    def span(self) -> tuple[np.ndarray, np.ndarray]:
        return np.full(self.n_uavs, self.t0), np.full(self.n_uavs, self.t1)

    def warp(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A stop's (or slow-down's) ``tau, tau', tau''`` at times ``t`` ``(T,)``: the smooth
        warp of the module docstring, (``brake``) :func:`brake_warp`, or (``slow``)
        :func:`~staghunt.trajectory.warp.slow_warp`."""
        T = self.duration
        if self.slow:
            tau, d1, d2 = slow_warp(t - self.t0, T, *self.slow)
            return self.t0 + tau, d1, d2
        u = np.clip((t - self.t0) / T, 0.0, 1.0)
        if self.brake:
            tau_u, d1, d2u = brake_warp(u)
            return self.t0 + T * tau_u, d1, d2u / T
        tau = self.t0 + T * (u - u**3 + 0.5 * u**4)
        d1 = 1.0 - (3.0 * u**2 - 2.0 * u**3)
        d2 = -(6.0 * u - 6.0 * u**2) / T
        return tau, d1, d2

    def state(self, t: np.ndarray) -> np.ndarray:
        """``(4, N, T, 3)``: position, velocity, acceleration and jerk at times ``t`` ``(T,)``
        (a stop's jerk is reported as 0: the controllers used need no more than acceleration).
        Read-only: the last few answers are kept, since a team flying rows of one plan (every
        UAV its own track) asks the same times once per UAV."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        cache: dict[bytes, np.ndarray] = self.__dict__.setdefault("_answers", {})
        key = t.tobytes()
        if key in cache:
            return cache[key]
        out = self._state(t)
        out.setflags(write=False)
        if len(cache) >= CACHED:
            cache.pop(next(iter(cache)))
        cache[key] = out
        return out

    def _state(self, t: np.ndarray) -> np.ndarray:
        if self.kind == "path":
            assert self.spline is not None
            tc = np.clip(t, self.t0, self.t1)
            out = np.stack([np.moveaxis(self.spline(tc, nu=d), 0, 1) for d in range(4)])
            moving = (t <= self.t1)[None, None, :, None]
            out[1:] = np.where(moving, out[1:], 0.0)
            return out
        assert self.base is not None
        tau, d1, d2 = self.warp(t)
        last = self.__dict__.get("_last")
        if last is None:
            last = self.__dict__["_last"] = end_time(self.base)
        tau = np.minimum(tau, last)
        b = self.base.state(tau)
        at_end = (tau >= last)[None, :, None]
        vel = np.where(at_end, 0.0, b[1] * d1[None, :, None])
        acc = np.where(at_end, 0.0, b[2] * d1[None, :, None] ** 2 + b[1] * d2[None, :, None])
        return np.stack([b[0], vel, acc, np.zeros_like(vel)])


@dataclass(frozen=True, eq=False)
class Reference:
    """The pieces in flight order; piece ``i`` holds from its ``t0`` until the next one's."""

    pieces: tuple[Piece, ...]

    def piece_at(self, t: float) -> Piece:
        for p in reversed(self.pieces):
            if t >= p.t0:
                return p
        return self.pieces[0]

    @property
    def arrival(self) -> float:
        """Time the last piece comes to rest (s)."""
        last = self.pieces[-1]
        return last.t1

    @property
    def n_uavs(self) -> int:
        return self.pieces[0].n_uavs

    @property
    def span(self) -> tuple[np.ndarray, np.ndarray]:
        return np.full(self.n_uavs, self.pieces[0].t0), np.full(self.n_uavs, self.arrival)

    def state(self, t: np.ndarray) -> np.ndarray:
        """``(4, N, T, 3)`` position, velocity, acceleration, jerk at times ``t`` ``(T,)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        starts = np.array([p.t0 for p in self.pieces])
        idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(self.pieces) - 1)
        out = np.zeros((4, self.n_uavs, len(t), 3))
        for i in np.unique(idx):
            sel = idx == i
            out[:, :, sel] = self.pieces[i].state(t[sel])
        return out

    def spliced(self, piece: Piece) -> "Reference":
        """The reference with ``piece`` replacing everything from ``piece.t0`` on."""
        keep = tuple(p for p in self.pieces if p.t0 < piece.t0)
        return Reference(keep + (piece,))


def _peaks(spline: BSpline, times: np.ndarray, step: float = CHECK_STEP_S) -> tuple[np.ndarray, np.ndarray]:
    """``(M - 1,)`` each: the peak speed and acceleration (norms, over the team) of ``spline``
    on each knot interval of ``times`` ``(M,)``, sampled every ``step`` seconds."""
    t0, t1 = float(times[0]), float(times[-1])
    t = np.linspace(t0, t1, max(2, math.ceil((t1 - t0) / step) + 1))
    d1, d2 = spline(t, nu=1), spline(t, nu=2)  # (T, N, 3)
    # the root of the largest square only (a quarter of a team's timing went into norms)
    v = np.sqrt(np.einsum("tnc,tnc->tn", d1, d1).max(axis=1))  # (T,)
    a = np.sqrt(np.einsum("tnc,tnc->tn", d2, d2).max(axis=1))
    k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, times.size - 2)
    vk = np.zeros(times.size - 1)
    ak = np.zeros(times.size - 1)
    np.maximum.at(vk, k, v)
    np.maximum.at(ak, k, a)
    return vk, ak


def _quintic(times: np.ndarray, points: np.ndarray, v0: np.ndarray, a0: np.ndarray) -> BSpline:
    y = np.moveaxis(points, 0, 1)  # (M, N, 3)
    zero = np.zeros_like(v0)
    return make_interp_spline(times, y, k=5, bc_type=([(1, v0), (2, a0)], [(1, zero), (2, zero)]))


DENSE_SPACING = 3.0
"""Longest sub-leg (m) of the dense paths a timed path interpolates."""
SMOOTH_SPACING = math.inf
"""The smooth candidate of a re-plan's timing (:func:`timings`): the spline through the planned
points alone. At a corner of the polyline it swings wide instead of turning within 0.15 m of
it, so it is flown only where it keeps the acceptance's full margins, but it is not slowed to
a crawl by every corner of the game's paths (benchmarks/JOURNAL.md, "Closed loop: the smooth
curve")."""
STALL_TRIES = 3
"""Stretches in a row (on one check grid) after which a timing already longer than
:data:`STALL_STRETCH` times its first schedule, whose worst peak over its limit has not come
down to :data:`STALL_GAIN` of what it was, gives up (:func:`timed_path`). Below that stretch
the peak may dwell a few tries while it moves between intervals, and end within the limits."""
STALL_GAIN = 0.99
STALL_STRETCH = 4.0
DUPLICATE_M = 0.01
"""A point closer than this (m) to the last kept one, for every UAV, is not timed apart."""


def _schedule(points: np.ndarray, limits: VehicleLimits, speed0: np.ndarray, own: bool,
              spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """The dense points ``(N, M, 3)`` a timed path of ``points`` ``(N, M0, 3)`` interpolates and
    their first schedule ``(M,)`` (from 0), before any stretch (:func:`timed_path`; ``speed0``
    ``(N,)``: the UAVs' speeds at the start)."""
    # Points within DUPLICATE_M of the last kept one for every UAV are dropped (the exporter's
    # rule, at a centimetre): a run of millimetre legs (waypoints slid together) otherwise
    # makes the spline swing wildly. Nobody moving: the start and the goal, a hold.
    keep = merge_waypoints(points, DUPLICATE_M)
    dense, _ = split_legs(points[:, keep], spacing)
    if own and points.shape[0] > 1:
        base, dense = own_pace(dense, limits, speed0)
        return dense, base
    return dense, knot_times(dense, limits, float(speed0.max()))


def timed_path(points: np.ndarray, t0: float, limits: VehicleLimits,
               v0: np.ndarray | None = None, a0: np.ndarray | None = None,
               max_tries: int = 20, max_stretch: float = math.inf, own: bool = False,
               spacing: float = DENSE_SPACING) -> Piece:
    """Time the team's paths ``points`` ``(N, M, 3)`` (absolute; ``points[:, 0]`` the state at
    ``t0``) starting with velocities ``v0`` and accelerations ``a0`` ``(N, 3)`` (default rest).

    The paths are densified (:func:`~staghunt.trajectory.timing.split_legs`, sub-legs of at most
    ``spacing`` m; ``inf``: not at all), timed by :func:`knot_times`, interpolated by a
    quintic spline with the start and end conditions, and, if a peak on the check grid still
    breaks a limit, the knot intervals where it does (and their neighbours) are stretched.
    Raises ``ValueError`` if no schedule whose duration is at most ``max_stretch`` times the
    first one meets the limits within ``max_tries``, or, past :data:`STALL_STRETCH`, as soon
    as :data:`STALL_TRIES` stretches in a row leave the worst peak where it was (the imposed
    start itself breaks them: a UAV moving at speed cannot turn sharply at once, whatever the
    schedule after; stretched on regardless, its interval doubled every try, and the twenty
    tries' sampling of an ever longer curve took 20 s for one UAV, 114 s for eight).
    ``own``: every UAV at its own pace (:func:`own_pace`), not the team's common one."""
    p = np.asarray(points, dtype=float)
    N = p.shape[0]
    v0 = np.zeros((N, 3)) if v0 is None else np.asarray(v0, dtype=float)
    a0 = np.zeros((N, 3)) if a0 is None else np.asarray(a0, dtype=float)
    dense, base = _schedule(p, limits, np.linalg.norm(v0, axis=-1), own, spacing)
    return _stretched(dense, base, t0, limits, v0, a0, max_tries, max_stretch, spacing)


def _stretched(dense: np.ndarray, base: np.ndarray, t0: float, limits: VehicleLimits, v0: np.ndarray,
               a0: np.ndarray, max_tries: int, max_stretch: float, spacing: float) -> Piece:
    """:func:`timed_path` from its dense points ``(N, M, 3)`` and first schedule ``(M,)``: the
    schedule stretched where a limit is broken until none is."""
    v_lim = MARGIN * limits.max_speed
    # The switch state's own acceleration cannot be undone by a slower schedule.
    a_lim = max(MARGIN * limits.max_acceleration, 1.02 * float(np.linalg.norm(a0, axis=-1).max()))
    dt = np.diff(base)
    total = float(base[-1])
    stretch = 1.0
    step = COARSE_STEP_S
    worst: list[float] = []  # the worst peak over its limit, per try on this grid
    for _ in range(max_tries):
        times = t0 + np.concatenate([[0.0], np.cumsum(dt)])
        spline = _quintic(times, dense, v0, a0)
        vk, ak = _peaks(spline, times, step)
        v, a = float(vk.max()), float(ak.max())
        if v <= v_lim and a <= a_lim and step > CHECK_STEP_S:  # passes coarsely: check it finely
            step, worst = CHECK_STEP_S, []
            vk, ak = _peaks(spline, times, step)
            v, a = float(vk.max()), float(ak.max())
        if v <= v_lim and a <= a_lim:
            return Piece("path", float(times[0]), float(times[-1]), times, dense, spline=spline, spacing=spacing)
        # Slow down where a limit is broken (and one interval on each side), not everywhere: a
        # sharp turn at the start of a re-plan slows the start, not the whole flight.
        over = np.maximum(vk / v_lim, np.sqrt(ak / a_lim))
        worst.append(float(over.max()))
        if stretch > STALL_STRETCH and len(worst) > STALL_TRIES and worst[-1] > STALL_GAIN * worst[-1 - STALL_TRIES]:
            break
        factor = np.where(over > 1.0, np.clip(over, 1.05, 2.0), 1.0)
        factor = np.maximum(factor, np.maximum(np.r_[factor[1:], 1.0], np.r_[1.0, factor[:-1]]))
        dt = dt * factor
        stretch = float(dt.sum()) / total
        if stretch > max_stretch:
            break
    raise ValueError(f"no timing of the new paths keeps speed <= {limits.max_speed:g} m/s and "
                     f"acceleration <= {limits.max_acceleration:g} m/s^2 (peaks {v:.3g} m/s, "
                     f"{a:.3g} m/s^2 after a stretch of {stretch:.3g})")


def soonest_timings(point_sets: Sequence[np.ndarray], t0: float, limits: VehicleLimits,
                    v0: np.ndarray | None = None, a0: np.ndarray | None = None, max_tries: int = 20,
                    max_stretch: float = math.inf, spacings: tuple[float, ...] = (DENSE_SPACING,),
                    stop: Callable[[], bool] | None = None) -> Iterator[tuple[int, Piece]]:
    """Every :func:`timed_path` of each of the teams' paths ``point_sets`` (each ``(N, M, 3)``)
    at each of ``spacings``, on the team's common schedule and with each UAV at its own pace
    (:func:`own_pace`; one UAV: the first only), that meets the limits, as ``(index in
    point_sets, piece)``, soonest first (ties: in the order of ``point_sets``, ``spacings``,
    common before own); ``ValueError`` (the first one's in that order) if none does.

    A timing is made only when it could still come before the next to yield: a schedule is only
    ever stretched, so its first schedule's arrival bounds its piece's from below, and timings
    are made in the order of those bounds. A caller that takes the first piece that passes its
    checks times only what it needs (the soonest piece is usually the first timed); exhausted,
    the same pieces in the same order as timing them all and sorting. ``stop()`` true before a
    timing: none is made, nor another yielded (``ValueError`` if none was)."""
    first = np.asarray(point_sets[0], dtype=float)
    v0 = np.zeros((first.shape[0], 3)) if v0 is None else np.asarray(v0, dtype=float)
    a0 = np.zeros_like(v0) if a0 is None else np.asarray(a0, dtype=float)
    speed0 = np.linalg.norm(v0, axis=-1)
    untimed: list[tuple[float, int, int, float, np.ndarray, np.ndarray]] = []  # bound, order, set, spacing, dense, schedule
    for s, points in enumerate(point_sets):
        for spacing in spacings:
            for own in (False, True)[: 2 if first.shape[0] > 1 else 1]:
                dense, base = _schedule(np.asarray(points, dtype=float), limits, speed0, own, spacing)
                bound = t0 + float(np.cumsum(np.diff(base))[-1])  # the first try's arrival, as _stretched sums it
                untimed.append((bound, len(untimed), s, spacing, dense, base))
    untimed.sort(key=lambda v: (v[0], v[1]))
    timed: list[tuple[float, int, int, Piece]] = []  # a heap: arrival, order, set, piece
    errors: dict[int, ValueError] = {}
    yielded = False
    while untimed or timed:
        if stop is not None and stop():
            if not yielded:
                raise ValueError("the timing was stopped at its deadline")
            return
        if timed and (not untimed or timed[0][:2] < untimed[0][:2]):
            _, _, s, piece = heapq.heappop(timed)
            yielded = True
            yield s, piece
            continue
        _, order, s, spacing, dense, base = untimed.pop(0)
        try:
            piece = _stretched(dense, base, t0, limits, v0, a0, max_tries, max_stretch, spacing)
        except ValueError as exc:
            errors[order] = exc
            continue
        heapq.heappush(timed, (piece.t1, order, s, piece))
    if not yielded:
        raise errors[min(errors)]


def timings(points: np.ndarray, t0: float, limits: VehicleLimits, v0: np.ndarray | None = None,
            a0: np.ndarray | None = None, max_tries: int = 20, max_stretch: float = math.inf,
            spacings: tuple[float, ...] = (DENSE_SPACING,)) -> list[Piece]:
    """The team's paths :func:`timed_path` at each of ``spacings``, on the team's common schedule
    and with each UAV at its own pace (:func:`own_pace`; one UAV: the first only), those that
    meet the limits, soonest first (``ValueError``: none does): :func:`soonest_timings`, all."""
    return [piece for _, piece in soonest_timings([points], t0, limits, v0, a0, max_tries, max_stretch, spacings)]


def _planned(base: TeamTrajectory, t_s: float, here: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The knots and planned points a warp of ``base`` from ``t_s`` carries: a piece's own, or
    (any other team trajectory) ``t_s`` and the positions ``here`` ``(N, T, 3)`` there."""
    if isinstance(base, Piece):
        return base.knots, base.points
    return np.array([t_s]), here[:, :1]


def stop_piece(ref: TeamTrajectory, t_s: float, limits: VehicleLimits, brake: bool = False) -> Piece:
    """A synchronised stop starting at ``t_s``: ``ref`` (of a :class:`Reference`, the piece
    flown at ``t_s``) slowed down to rest with one common time warp (module docstring;
    ``brake``: :func:`brake_warp`, the shortest stop, for emergencies), as short as
    ``max_acceleration`` allows."""
    base = ref.piece_at(t_s) if isinstance(ref, Reference) else ref
    if isinstance(base, Piece) and base.kind == "stop":  # already stopping: keep that stop
        return base
    last = end_time(base)
    peak = 1.0 / (1.0 - BRAKE_RAMP) if brake else 1.5  # peak deceleration x T / v
    v0 = float(np.linalg.norm(base.state(np.array([t_s]))[1], axis=-1).max())
    # the stop flies the base up to T / 2 on (tau(T) - t_s = T / 2 for both warps): its speed there
    reach = min(last, t_s + 0.5 * peak * max(v0, 1.0) / (MARGIN * limits.max_acceleration) + 1.0)
    t = np.linspace(t_s, max(reach, t_s), max(2, math.ceil((reach - t_s) / CHECK_STEP_S) + 1))
    s = base.state(t)
    v = float(np.linalg.norm(s[1], axis=-1).max())
    if not isinstance(base, Piece) and v < REST_TOL and float(np.abs(s[0] - s[0][:, :1]).max()) < REST_TOL:
        # at rest all the way: the stop of a still team, not of the history that brought it there
        # (a stop of a stop of ... wraps every earlier one, and evaluating it recurses as deep)
        base = Still(s[0][:, 0].copy(), t_s)
    T = max(0.5, peak * v / (MARGIN * limits.max_acceleration))
    knots, points = _planned(base, t_s, s[0])
    for _ in range(30):
        piece = Piece("stop", t_s, t_s + T, knots, points, base=base, duration=T, brake=brake)
        grid = np.linspace(t_s, t_s + T, max(2, math.ceil(T / CHECK_STEP_S) + 1))
        peak = float(np.linalg.norm(piece.state(grid)[2], axis=-1).max())
        if peak <= limits.max_acceleration:
            return piece
        T *= 1.1
    return piece


def slow_piece(ref: TeamTrajectory, t_s: float, limits: VehicleLimits, delay: float, factor: float) -> Piece | None:
    """``ref`` (of a :class:`Reference`, the piece flown at ``t_s``) flown on the same paths from
    ``t_s``, arriving ``delay`` seconds later: its time slowed in sync to ``factor`` of its pace
    and sped up again (:func:`~staghunt.trajectory.warp.slow_warp`; every UAV stays on its path
    and the team keeps its relative timing), each ramp as short as ``max_acceleration`` allows
    and at least 0.5 s. ``None`` if ``ref`` ends before the slow-down is over."""
    base = ref.piece_at(t_s) if isinstance(ref, Reference) else ref
    last = end_time(base)
    span = delay / (1.0 - factor)  # ramp + hold
    t = np.linspace(t_s, min(last, t_s + span + 1.0), max(2, math.ceil(min(last - t_s, span + 1.0) / CHECK_STEP_S) + 1))
    s = base.state(t)
    v = float(np.linalg.norm(s[1], axis=-1).max())
    ramp = max(0.5, 1.5 * (1.0 - factor) * v / (MARGIN * limits.max_acceleration))
    knots, points = _planned(base, t_s, s[0])
    while ramp <= span:
        piece = Piece("slow", t_s, last + delay, knots, points, base=base, duration=ramp, slow=(span - ramp, factor))
        end = t_s + ramp + span  # the warp's end; the base then goes on `delay` behind its time
        if end - delay > last:
            return None
        grid = np.linspace(t_s, end, max(2, math.ceil((end - t_s) / CHECK_STEP_S) + 1))
        if float(np.linalg.norm(piece.state(grid)[2], axis=-1).max()) <= limits.max_acceleration:
            return piece
        ramp *= 1.1
    return None
