"""Capture segments: the stretches a UAV flies with its camera working, and the capture plan.

A :class:`CaptureSegment` is a polyline of camera positions (absolute site ``x, y, z``) with the
gimbal's yaw and pitch at each, and how the camera is triggered along it:

- ``"distance"``: a photo at the first point, then every ``trigger_distance`` metres flown,
  never faster than the camera's minimum interval (a survey line, a facade layer);
- ``"points"``: one photo at each point, hovering ``dwell_s`` there (a viewpoint).

A :class:`CapturePlan` holds every objective's segments and what planning them had to change
(a viewpoint moved, a layer pulled closer) or could not do (a stretch no safe position reaches),
so that nothing is dropped silently.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

__all__ = ["CapturePlan", "CaptureSegment", "ObjectivePlan", "arc_length"]

SegmentKind = Literal["line", "layer", "view"]


def arc_length(points: np.ndarray) -> np.ndarray:
    """``(M,)`` cumulative 3-D length along ``points`` ``(M, 3)``, starting at 0."""
    if len(points) < 2:
        return np.zeros(len(points))
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])


@dataclass(frozen=True, eq=False)
class CaptureSegment:
    """One stretch flown with the camera working, for objective ``objective``.

    - ``points``: ``(M, 3)`` camera positions (absolute site ``x, y, z``, m), in flying order;
      ``yaw``, ``pitch``: ``(M,)`` gimbal angles (rad; yaw counter-clockwise from east, pitch
      ``-pi/2`` = nadir).
    - ``trigger``: ``"distance"`` (every ``trigger_distance`` m from the first point) or
      ``"points"`` (one photo at each point after hovering ``dwell_s``).
    - ``speed``: the speed flown (m/s): at most the cruise speed, the trigger distance over the
      camera's minimum interval and the speed that keeps the motion blur in its limit.
    - ``gsd_cm``: the GSD the segment was planned for; ``camera``: the camera's name.
    - ``reversible``: it may be flown from the last point to the first.
    - ``window``: ``(t0, t1)`` s after take-off within which it must be flown (``None``: any time).
    """

    objective: str
    kind: SegmentKind
    index: int
    points: np.ndarray
    yaw: np.ndarray
    pitch: np.ndarray
    trigger: Literal["distance", "points"]
    trigger_distance: float
    speed: float
    gsd_cm: float
    camera: str
    dwell_s: float = 0.0
    reversible: bool = True
    window: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        for a in (self.points, self.yaw, self.pitch):
            a.setflags(write=False)

    @property
    def length(self) -> float:
        return float(arc_length(self.points)[-1])

    @property
    def photos(self) -> int:
        """Photos planned: one per point, or the first point then one every trigger distance."""
        if self.trigger == "points":
            return int(len(self.points))
        return int(math.floor(self.length / self.trigger_distance + 1e-9)) + 1

    @property
    def duration(self) -> float:
        """Time to fly it (s): its length at ``speed``, plus the hovers."""
        return self.length / self.speed + self.dwell_s * (len(self.points) if self.trigger == "points" else 0)

    @property
    def entry(self) -> np.ndarray:
        return self.points[0]

    @property
    def exit(self) -> np.ndarray:
        return self.points[-1]

    def reversed(self) -> "CaptureSegment":
        """The same segment flown backwards (a survey line's yaw turns by 180 degrees with the
        direction of travel; a facade layer keeps facing its wall)."""
        yaw = self.yaw[::-1].copy()
        if self.kind == "line":
            yaw = np.mod(yaw + math.pi, 2 * math.pi)
        return replace(self, points=self.points[::-1].copy(), yaw=yaw, pitch=self.pitch[::-1].copy())

    def photo_poses(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(positions (F, 3), yaw (F,), pitch (F,))`` of the planned photos (the planned
        coverage; the flown one comes from the trigger on the flown trajectory)."""
        if self.trigger == "points":
            return self.points.copy(), self.yaw.copy(), self.pitch.copy()
        s = arc_length(self.points)
        at = np.arange(self.photos) * self.trigger_distance
        at = np.minimum(at, s[-1])
        pos = np.stack([np.interp(at, s, self.points[:, c]) for c in range(3)], axis=1)
        # angles: the value at the nearest planned point (yaw jumps are not interpolated across)
        k = np.clip(np.searchsorted(s, at, side="right") - 1, 0, len(s) - 1)
        return pos, self.yaw[k].copy(), self.pitch[k].copy()


@dataclass(frozen=True, eq=False)
class ObjectivePlan:
    """The segments of one objective and what planning them changed or could not do.

    - ``segments``: in the objective's own order (survey lines across the polygon, layers
      bottom up, views around the point).
    - ``distance_m``: the camera's planned distance to the surface; ``gsd_cm``: the GSD it gives.
    - ``moved``: plain-language notes of positions moved to be safe (still capturing);
      ``unreached``: what no safe position captures (reported, never dropped silently).
    - ``qgc_photos``: the photos QGroundControl's Survey would plan for the same polygon, camera,
      GSD and overlaps (areas only; ``None`` otherwise).
    """

    name: str
    kind: str
    segments: tuple[CaptureSegment, ...]
    distance_m: float
    gsd_cm: float
    moved: tuple[str, ...] = ()
    unreached: tuple[str, ...] = ()
    qgc_photos: int | None = None
    details: dict = field(default_factory=dict)

    @property
    def photos(self) -> int:
        return sum(s.photos for s in self.segments)

    @property
    def work_s(self) -> float:
        return sum(s.duration for s in self.segments)


@dataclass(frozen=True, eq=False)
class CapturePlan:
    """Every objective's :class:`ObjectivePlan`, in the objectives' order."""

    objectives: tuple[ObjectivePlan, ...]

    def of(self, name: str) -> ObjectivePlan:
        for o in self.objectives:
            if o.name == name:
                return o
        raise KeyError(name)

    @property
    def segments(self) -> tuple[CaptureSegment, ...]:
        return tuple(s for o in self.objectives for s in o.segments)
