"""A site that changes: obstacles with a known motion, obstacles that appear or disappear, and
what the team senses. Knows nothing of UAVs' plans or solvers.

Times are seconds after take-off; positions are in the site frame (m). Two known motions:

- :class:`MovingCylinder` (a truck, a load on a hook): a vertical cylinder, infinitely tall
  like the static ones, whose axis moves along a polyline at a constant speed from
  ``start_time`` on; it waits at the first vertex before, and at the end either stops
  (``repeat = "stop"``) or runs the polyline back and forth (``"reverse"``).
- :class:`SlewingJib` (a crane jib): a box ``length`` long (plus ``counter`` behind the pivot)
  and ``width`` wide between two absolute heights, turning about a vertical axis through its
  pivot from ``angle_from`` to ``angle_to`` (degrees counter-clockwise from east) at ``rate``
  deg/s from ``start_time`` on, then holding (``"stop"``) or slewing back and forth (``"reverse"``).

:class:`Event`\\ s change the world at a given time (``appear``, ``disappear``); the planner
learns of an appeared obstacle only when a UAV comes within the :class:`Sensing` range of it,
over the radio :class:`Link`.

Sound offline treatment of known motions (docs/model.md, "A site that changes"): plans are
checked *in time* against the true positions (:func:`staghunt.safety.measure.moving_clearance`), and a conflict is
removed by re-planning with the obstacle's **swept volume over the conflict's time window**
(:meth:`Dynamics.swept`) as static obstacles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from staghunt.world.obstacles import Cylinder, Prism

Repeat = Literal["stop", "reverse"]

MAX_SWEPT_CYLINDERS = 200
"""Stand-ins of one moving cylinder over one window (:meth:`Dynamics.swept`): a fast or small
obstacle gets wider-spaced, larger ones, never more (the planner's work grows with them)."""


def _bounce(s: np.ndarray, length: float, repeat: Repeat) -> np.ndarray:
    """Arc length ``s >= 0`` folded into ``[0, length]``: clipped, or back and forth."""
    if repeat == "stop" or length <= 0:
        return np.clip(s, 0.0, length)
    period = np.mod(s, 2.0 * length)
    return np.where(period <= length, period, 2.0 * length - period)


@dataclass(frozen=True)
class MovingCylinder:
    """A vertical cylinder of ``radius`` (m) whose axis moves along ``path`` (``V >= 2`` vertices
    ``(x, y)``) at ``speed`` (m/s) from ``start_time`` (s)."""

    name: str
    radius: float
    path: tuple[tuple[float, float], ...]
    speed: float
    start_time: float = 0.0
    repeat: Repeat = "stop"

    @property
    def length(self) -> float:
        v = np.asarray(self.path, dtype=float)
        return float(np.linalg.norm(np.diff(v, axis=0), axis=1).sum())

    def xy(self, t: np.ndarray) -> np.ndarray:
        """``(T, 2)`` axis positions at times ``t`` ``(T,)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        v = np.asarray(self.path, dtype=float)
        seg = np.linalg.norm(np.diff(v, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        s = _bounce(np.maximum(t - self.start_time, 0.0) * self.speed, float(cum[-1]), self.repeat)
        return np.column_stack([np.interp(s, cum, v[:, 0]), np.interp(s, cum, v[:, 1])])

    def arc_range(self, t0: float, t1: float) -> tuple[float, float]:
        """``(lo, hi)``: the arc lengths along the path that the axis covers during ``[t0, t1]``."""
        L = self.length
        u0, u1 = (max(t - self.start_time, 0.0) * self.speed for t in (t0, max(t0, t1)))
        if self.repeat == "stop" or L <= 0:
            return min(u0, L), min(u1, L)
        if u1 - u0 >= 2.0 * L:
            return 0.0, L
        a, b = (float(_bounce(np.array([u]), L, "reverse")[0]) for u in (u0, u1))
        lo, hi = min(a, b), max(a, b)
        for k in range(math.floor(u0 / L) + 1, math.ceil(u1 / L)):  # the turns within the window
            lo, hi = (0.0, hi) if k % 2 == 0 else (lo, L)
        return lo, hi

    def cover(self, t0: float, t1: float, step: float, max_points: int = 200) -> tuple[np.ndarray, float]:
        """Cylinders covering every position of this cylinder during ``[t0, t1]``: ``(S, 2)``
        centres along the covered part of the path (:meth:`arc_range`), at most ``step`` m of
        path apart, or wider apart so that ``S <= max_points`` however fast or small the
        obstacle (plus the path's vertices in between while they are fewer than
        ``max_points``), and their common radius: ``sqrt(R^2 + (d/2)^2)`` over a straight gap
        of chord ``d``, ``R + g/2`` over a gap of ``g`` m of path with a bend in it."""
        v = np.asarray(self.path, dtype=float)
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(v, axis=0), axis=1))])
        lo, hi = self.arc_range(t0, t1)
        n = min(max(0, math.ceil((hi - lo) / max(step, 1e-9))), max(1, max_points - 1))
        s = np.linspace(lo, hi, n + 1) if n > 0 else np.array([lo])
        inner = cum[(cum > lo) & (cum < hi)]
        if len(s) + len(inner) <= max_points:
            s = np.union1d(s, inner)
        pts = np.column_stack([np.interp(s, cum, v[:, 0]), np.interp(s, cum, v[:, 1])])
        if len(s) < 2:
            return pts, float(self.radius)
        chord = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        bend = np.searchsorted(cum, s[:-1], side="right") < np.searchsorted(cum, s[1:], side="left")
        need = np.where(bend, self.radius + 0.5 * np.diff(s), np.hypot(self.radius, 0.5 * chord))
        return pts, float(need.max())


@dataclass(frozen=True)
class SlewingJib:
    """A crane jib: a box from ``counter`` m behind the pivot to ``length`` m ahead of it,
    ``width`` m wide, between absolute heights ``base < top`` (site ``z``), turning about the
    vertical axis through ``pivot`` from ``angle_from`` to ``angle_to`` (deg, counter-clockwise
    from east) at ``rate`` (deg/s) from ``start_time`` (s)."""

    name: str
    pivot: tuple[float, float]
    length: float
    width: float
    base: float
    top: float
    angle_from: float
    angle_to: float
    rate: float
    counter: float = 0.0
    start_time: float = 0.0
    repeat: Repeat = "stop"
    agl: tuple[float, float] | None = None
    """``(base, height)`` above the ground at the pivot as the scenario gave them."""

    def angle(self, t: np.ndarray) -> np.ndarray:
        """``(T,)`` jib heading (radians) at times ``t``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        sweep = abs(self.angle_to - self.angle_from)
        turned = _bounce(np.maximum(t - self.start_time, 0.0) * self.rate, sweep, self.repeat)
        sign = 1.0 if self.angle_to >= self.angle_from else -1.0
        return np.radians(self.angle_from + sign * turned)

    def polygons(self, t: np.ndarray, grow: float = 0.0) -> np.ndarray:
        """``(T, 4, 2)`` footprints at times ``t`` (counter-clockwise), each side pushed out by ``grow`` m."""
        a = self.angle(t)
        u = np.stack([np.cos(a), np.sin(a)], axis=-1)  # (T, 2) along the jib
        w = np.stack([-np.sin(a), np.cos(a)], axis=-1)  # (T, 2) across
        p = np.asarray(self.pivot, dtype=float)
        back, ahead, half = self.counter + grow, self.length + grow, 0.5 * self.width + grow
        corners = [(-back, -half), (ahead, -half), (ahead, half), (-back, half)]
        return np.stack([p + c[0] * u + c[1] * w for c in corners], axis=1)

    @property
    def tip_speed(self) -> float:
        """Largest horizontal speed of any point of the jib (m/s)."""
        far = math.hypot(max(self.length, self.counter), 0.5 * self.width)
        return math.radians(self.rate) * far


@dataclass(frozen=True)
class Trigger:
    """What makes an ``appear`` happen before its time, as the sensors' feedback sees it (every
    tick of :attr:`Sensing.rate`, true states): the UAV called ``uav`` (``None``: any UAV of the
    team) coming within ``within`` metres (horizontally) of the obstacle's outline, or within
    ``lead`` seconds of breaching its clearance on the trajectory it flies (its body closer to
    the outline than the required clearance that soon if nothing changed); 0 turns either off.
    A test of how the team answers an obstacle met a given distance or time ahead, however the
    flight was re-timed."""

    uav: str | None
    within: float = 0.0
    lead: float = 0.0

    def as_table(self) -> dict[str, str | float]:
        """The trigger as an events file writes it: only the keys it uses."""
        row = {"uav": self.uav, "within": self.within, "lead": self.lead}
        return {k: v for k, v in row.items() if v}


@dataclass(frozen=True)
class Event:
    """A change at ``time`` (s): ``appear`` adds ``shape`` (a :class:`Cylinder` or
    :class:`Prism`), at ``time`` or, with a ``trigger``, as soon as the trigger holds if that is
    sooner; ``disappear`` removes the obstacle called ``name`` (static, moving or appeared); for
    an inspection, ``uav_lost`` (the UAV called ``name`` lands where it is) and ``objective``
    (``objective``: the objective's table, as plain data, added to the inspection). A flight's
    result holds its events as flown: each triggered one at the time it appeared."""

    time: float
    kind: Literal["appear", "disappear", "uav_lost", "objective"]
    name: str
    shape: Cylinder | Prism | None = None
    objective: dict | None = None
    trigger: Trigger | None = None


@dataclass(frozen=True)
class Sensing:
    """What the planner learns in flight. ``range``: an appeared obstacle is sensed once a
    UAV's measured position is within this horizontal distance of it (m; ``inf``: at once).
    ``rate``: state feedback and planner ticks per second (Hz, >= 10). ``position_noise``,
    ``velocity_noise``: standard deviation of the fed-back position (m) and velocity (m/s)."""

    range: float = 40.0
    rate: float = 10.0
    position_noise: float = 0.0
    velocity_noise: float = 0.0


@dataclass(frozen=True)
class Link:
    """The radio between the ground station (the planner) and each UAV, both ways: every message
    takes ``delay`` (s, one way) plus ``jitter`` (s) times a standard normal draw clipped to
    [-3, 3] (at least 0), and is lost with probability ``loss``."""

    delay: float = 0.1
    jitter: float = 0.03
    loss: float = 0.01

    @property
    def worst_delay(self) -> float:
        """The longest a message that arrives can take (s)."""
        return self.delay + 3.0 * self.jitter


@dataclass(frozen=True)
class Dynamics:
    """Everything about the site that changes with time (empty by default), what the team
    senses of it and the radio it reports over."""

    moving: tuple[MovingCylinder, ...] = ()
    jibs: tuple[SlewingJib, ...] = ()
    events: tuple[Event, ...] = ()
    sensing: Sensing = field(default_factory=Sensing)
    link: Link = field(default_factory=Link)

    @property
    def empty(self) -> bool:
        return not (self.moving or self.jibs or self.events)

    @property
    def known_motion(self) -> bool:
        return bool(self.moving or self.jibs)

    def merged(self, other: "Dynamics", sensing_given: bool, link_given: bool = False) -> "Dynamics":
        """This world plus ``other``'s motions and events (an events file); ``other``'s sensing
        replaces this one's if ``sensing_given``, its link if ``link_given``."""
        events = tuple(sorted(self.events + other.events, key=lambda e: e.time))
        return Dynamics(self.moving + other.moving, self.jibs + other.jibs, events,
                        other.sensing if sensing_given else self.sensing, other.link if link_given else self.link)

    def removed(self, t: float) -> set[str]:
        """Names of the obstacles that have disappeared by time ``t``."""
        return {e.name for e in self.events if e.kind == "disappear" and e.time <= t}

    def swept(self, t0: float, t1: float, only: set[str] | None = None
              ) -> tuple[tuple[Cylinder, ...], tuple[Prism, ...]]:
        """Static stand-ins covering where the known motions (or those named in ``only``) can be
        during ``[t0, t1]``: for a moving cylinder, cylinders every ``R`` m along the part of its
        path it covers (at most :data:`MAX_SWEPT_CYLINDERS`, spaced wider when the part is longer),
        grown to cover the swept capsule (:meth:`MovingCylinder.cover`); for a jib, its box every
        5 degrees of heading, widened by the largest chord between two steps."""
        gone = self.removed(t1)
        cyl: list[Cylinder] = []
        for m in self.moving:
            if (only is not None and m.name not in only) or m.name in gone:
                continue
            pts, r = m.cover(t0, t1, m.radius, MAX_SWEPT_CYLINDERS)
            cyl.extend(Cylinder(float(x), float(y), r, f"{m.name} (swept)") for x, y in pts)
        prisms: list[Prism] = []
        for j in self.jibs:
            if (only is not None and j.name not in only) or j.name in gone:
                continue
            a0, a1 = j.angle(np.array([t0, t1]))
            turn = abs(j.rate) * max(0.0, t1 - t0)
            n = max(1, math.ceil(min(turn, 360.0) / 5.0))
            times = np.linspace(t0, t1, n + 1)
            angles = j.angle(times)
            gap = float(np.max(np.abs(np.diff(angles)), initial=0.0))
            grow = math.hypot(max(j.length, j.counter), 0.5 * j.width) * 2.0 * math.sin(0.5 * gap)
            for k, poly in enumerate(j.polygons(times, grow)):
                prisms.append(Prism(tuple(map(tuple, poly.tolist())), j.base, j.top,
                                    f"{j.name} (swept {k})", "box"))
        return tuple(cyl), tuple(prisms)


def motion_names(dyn: Dynamics) -> list[str]:
    """Names of the known motions in the order of :func:`moving_clearance`'s indices."""
    return [m.name for m in dyn.moving] + [j.name for j in dyn.jibs]


def max_motion_speed(dyn: Dynamics) -> float:
    """Fastest horizontal speed of any known motion (m/s; 0 without)."""
    return max([m.speed for m in dyn.moving] + [j.tip_speed for j in dyn.jibs], default=0.0)
