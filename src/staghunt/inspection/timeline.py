"""Each UAV's mission in time: its legs, captures and hovers back to back.

A :class:`Piece` is one stretch of a UAV's flight between two instants: a leg (transit), a
capture (a segment flown with the camera working) or a hover (waiting for a window, a
team-mate, or the team's return). Legs and captures are timed time-optimally (TOPP-RA,
:func:`staghunt.trajectory.time_plan`) from rest to rest under the UAV's limits, a capture at the
segment's speed; a team leg is timed for the whole team at once (its waypoints reached
together). A :class:`Timeline` answers ``state(t)``: position, velocity, acceleration and jerk
of every UAV at ``t`` (a UAV past its last piece holds its last position).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property, lru_cache
from math import factorial

import numpy as np
from scipy.interpolate import CubicSpline, PPoly

from staghunt.acquisition.segments import CaptureSegment
from staghunt.task import VehicleLimits
from staghunt.trajectory import time_and_check, time_plan

__all__ = ["Piece", "Timeline", "capture_piece", "hover_piece", "path_piece", "team_pieces"]


@dataclass(frozen=True, eq=False)
class Piece:
    """UAV flight from ``t0`` to ``t1`` (s): ``kind`` ``"leg"``, ``"capture"`` or ``"hover"``;
    ``spline``: position in the piece's own time ``t - t0`` (``(3,)`` values; column ``column``
    of a team spline), ``None`` for a hover at ``hold``; ``points``: the geometric path
    ``(M, 3)``; for a capture, ``segment`` and the ``task`` it belongs to."""

    kind: str
    t0: float
    t1: float
    points: np.ndarray
    spline: CubicSpline | None = None
    column: int | None = None
    hold: np.ndarray | None = None
    segment: CaptureSegment | None = None
    task: int | None = None
    label: str = ""

    @property
    def duration(self) -> float:
        return self.t1 - self.t0

    def state(self, t: np.ndarray) -> np.ndarray:
        """``(4, T, 3)`` position, velocity, acceleration, jerk at times ``t`` ``(T,)`` within the piece."""
        t = np.asarray(t, dtype=float)
        if self.spline is None:
            out = np.zeros((4, len(t), 3))
            out[0] = self.hold
            return out
        x, c = self._coefficients
        tau = np.clip(t - self.t0, 0.0, x[-1])
        i = np.clip(np.searchsorted(x, tau, side="right") - 1, 0, len(x) - 2)
        s = (tau - x[i])[:, None]
        a = c[:, i]  # (degree + 1, T, 3), a[j] multiplies s**j
        out = np.zeros((4, len(t), 3))
        for nu in range(min(4, len(a))):
            acc = np.zeros((len(t), 3))
            for j in range(len(a) - 1, nu - 1, -1):  # Horner on the nu-th derivative
                acc = acc * s + a[j] * (factorial(j) // factorial(j - nu))
            out[nu] = acc
        return out

    @cached_property
    def _coefficients(self) -> tuple[np.ndarray, np.ndarray]:
        """The spline's breakpoints ``(m + 1,)`` and its power-basis coefficients in ascending
        order ``(degree + 1, m, 3)`` (this piece's column of a team spline)."""
        c = self.spline.c[::-1]
        if self.column is not None:
            c = c[:, :, self.column]
        return np.asarray(self.spline.x, dtype=float), np.ascontiguousarray(c, dtype=float)


def _spline_piece(kind: str, t0: float, points: np.ndarray, spline: CubicSpline, column: int | None, **kw) -> Piece:
    return Piece(kind, t0, t0 + float(spline.x[-1]), points, spline=spline, column=column, **kw)


def path_piece(kind: str, t0: float, points: np.ndarray, limits: VehicleLimits, **kw) -> Piece:
    """One UAV's polyline ``points`` ``(M, 3)`` from rest to rest from ``t0``, within ``limits``:
    a capture time-optimally along its points (TOPP-RA), a leg segment by segment, stopping at its
    corners (a leg round an obstacle hugs it: a curve through its corners would cut them)."""
    pts = np.asarray(points, dtype=float)
    if len(pts) < 2 or float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()) < 1e-9:
        return hover_piece(t0, t0, pts[0], **kw)
    if kind == "leg" and len(pts) > 2:
        timed = _corners(pts, min(limits.cruise_speed, limits.max_speed), limits.max_acceleration)
    else:
        timed = _timed(pts.tobytes(), len(pts), limits)
    return _spline_piece(kind, t0, pts, timed, 0, **kw)


@lru_cache(maxsize=4096)
def _timed(points: bytes, m: int, limits: VehicleLimits) -> PPoly:
    """The time-optimal timing of a polyline (given as bytes, ``m`` points), from rest to rest:
    a straight hop in closed form (speed up at the acceleration limit, cruise, slow down), a
    longer polyline by TOPP-RA. Kept, so that a re-allocation in flight times again only the legs
    that are new (its captures are the same segments)."""
    pts = np.frombuffer(points, dtype=float).reshape(m, 3)
    if m == 2:
        return _straight(pts[0], pts[1], min(limits.cruise_speed, limits.max_speed), limits.max_acceleration)
    return time_plan(pts[None], limits).spline


def _corners(points: np.ndarray, v: float, acc: float) -> PPoly:
    """Rest to rest along each segment of a polyline in turn (a stop at every corner): it never
    cuts a corner, as a leg round an obstacle must not."""
    polys, t = [], 0.0
    for a, b in zip(points[:-1], points[1:]):
        if float(np.linalg.norm(b - a)) < 1e-9:
            continue
        p = _straight(a, b, v, acc)
        polys.append((t, p))
        t += float(p.x[-1])
    breaks = np.concatenate([[0.0]] + [t0 + p.x[1:] for t0, p in polys])
    c = np.concatenate([p.c for _, p in polys], axis=1)
    return PPoly(c, breaks)


def _straight(a: np.ndarray, b: np.ndarray, v: float, acc: float) -> PPoly:
    """Rest to rest along the segment ``a b``: a trapezoidal speed profile (triangular when too
    short to reach ``v``) as a piecewise quadratic in time, values ``(1, 3)`` like a team spline's."""
    length = float(np.linalg.norm(b - a))
    u = (b - a) / length
    ta = v / acc
    if acc * ta * ta > length:  # never reaches v
        ta = (length / acc) ** 0.5
        v = acc * ta
    tc = max((length - acc * ta * ta) / v, 0.0)
    s1 = 0.5 * acc * ta * ta
    # arc length s(t) per interval: s_i + v_i (t - t_i) + a_i / 2 (t - t_i)^2
    pieces = [(ta, 0.5 * acc, 0.0, 0.0)] + ([(tc, 0.0, v, s1)] if tc > 1e-9 else []) + [(ta, -0.5 * acc, v, s1 + v * tc)]
    breaks = np.concatenate([[0.0], np.cumsum([p[0] for p in pieces])])
    coef_s = np.array([[p[1] for p in pieces], [p[2] for p in pieces], [p[3] for p in pieces]])  # (3 powers, intervals)
    c = coef_s[:, :, None, None] * u[None, None, None, :]  # (3, intervals, 1, 3)
    c[2] += a[None, None, :]
    return PPoly(c, breaks)


def capture_piece(t0: float, segment: CaptureSegment, limits: VehicleLimits, task: int) -> Piece:
    """A capture segment flown at its speed from ``t0`` (a viewpoint: a hover of ``dwell_s``)."""
    if segment.trigger == "points" and len(segment.points) == 1:
        return hover_piece(t0, t0 + segment.dwell_s, segment.points[0], kind="capture", segment=segment, task=task)
    capped = replace(limits, cruise_speed=min(limits.cruise_speed, segment.speed))
    return path_piece("capture", t0, segment.points, capped, segment=segment, task=task)


def hover_piece(t0: float, t1: float, at: np.ndarray, kind: str = "hover", **kw) -> Piece:
    at = np.asarray(at, dtype=float)
    return Piece(kind, t0, t1, at[None].copy(), hold=at.copy(), **kw)


def team_pieces(t0: float, points: np.ndarray, limits: VehicleLimits, label: str, model: object | None = None
                ) -> list[Piece]:
    """The team's paths ``points`` ``(n, M, 3)`` timed together from ``t0``: one piece per UAV.
    With the leg's cost ``model``, the smoothest timing whose flight is safe in time
    (:func:`staghunt.trajectory.time_and_check`: a curve through the waypoints may overshoot a
    waypoint one UAV repeats while the others move; shorter sub-legs keep it on the polyline)."""
    pts = np.asarray(points, dtype=float)
    if model is None:
        traj = time_plan(pts, limits)
    else:
        traj, _ = time_and_check(model, pts, limits, [f"UAV{i + 1}" for i in range(len(pts))])
    return [_spline_piece("leg", t0, points[i], traj.spline, i, label=label) for i in range(len(points))]


@dataclass(frozen=True, eq=False)
class Timeline:
    """Every UAV's pieces, back to back from 0 (``pieces[n]``)."""

    pieces: tuple[tuple[Piece, ...], ...]
    names: tuple[str, ...]
    details: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.pieces)

    @property
    def end(self) -> float:
        return max((p[-1].t1 for p in self.pieces if p), default=0.0)

    @cached_property
    def _starts(self) -> tuple[np.ndarray, ...]:
        return tuple(np.array([p.t0 for p in pieces]) for pieces in self.pieces)

    def ends(self) -> np.ndarray:
        """``(N,)`` when each UAV's last piece ends."""
        return np.array([p[-1].t1 if p else 0.0 for p in self.pieces])

    def state(self, t: np.ndarray) -> np.ndarray:
        """``(4, N, T, 3)`` every UAV's position, velocity, acceleration and jerk at ``t`` ``(T,)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        out = np.zeros((4, self.n, len(t), 3))
        for n, pieces in enumerate(self.pieces):
            starts = self._starts[n]
            which = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(pieces) - 1)
            for i in np.unique(which):
                sel = which == i
                out[:, n, sel] = pieces[i].state(t[sel])
            past = t > pieces[-1].t1
            if past.any():
                last = pieces[-1].state(np.array([pieces[-1].t1]))[0, 0]
                out[0, n, past] = last
                out[1:, n, past] = 0.0
        return out

    def positions(self, t: np.ndarray) -> np.ndarray:
        """``(N, T, 3)`` positions at ``t``."""
        return self.state(t)[0]
