"""The inspection's objectives (the task management layer's input): what must be photographed,
at which resolution, from where and when; and each UAV's payload (camera, gimbal, endurance).

Three kinds, all in the site frame (m):

- :class:`AreaObjective`: a nadir survey of a polygon at a ground sampling distance (GSD) to
  reach or beat, with front and side overlaps (QGroundControl's Survey);
- :class:`FacadeObjective`: the walls of a prism or building of the scenario, photographed level
  from a standoff that gives the GSD, in layers, within an incidence limit (a Structure Scan);
- :class:`PointObjective`: a point of interest seen from a given distance, from one or more
  viewpoints, optionally within a time window and repeated (recurring monitoring).

Every objective has a ``priority`` (higher first) and ``required``: a required objective must be
allocated or the inspection is refused; an optional one may be left out when the team's endurance
is short, lowest priority first, and is then reported as not allocated. ``camera`` names the
camera it is planned for (``None``: the first UAV's); only the UAVs carrying it fly it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, Union

from staghunt.camera.model import Camera

__all__ = ["AreaObjective", "FacadeObjective", "Inspection", "Objective", "Payload", "PointObjective"]


@dataclass(frozen=True)
class AreaObjective:
    """A nadir survey of ``polygon`` (``V`` vertices ``(x, y)``, simple, not closed) at ``gsd_cm``
    or finer, with ``front_overlap`` and ``side_overlap`` (fractions in ``[0, 1)``).
    ``angle_deg``: direction of the survey lines, counter-clockwise from east (``None``: along the
    polygon's longest extent, which needs the fewest lines)."""

    name: str
    polygon: tuple[tuple[float, float], ...]
    gsd_cm: float
    front_overlap: float = 0.75
    side_overlap: float = 0.65
    angle_deg: float | None = None
    priority: int = 1
    required: bool = True
    camera: str | None = None
    kind: Literal["area"] = "area"


@dataclass(frozen=True)
class FacadeObjective:
    """The walls of the scenario's prism ``prism`` (a building or a box) at ``gsd_cm`` or finer,
    every wall patch seen within ``max_incidence_deg`` of its normal. ``front_overlap`` is the
    overlap along a layer, ``side_overlap`` between layers (fractions in ``[0, 1)``)."""

    name: str
    prism: str
    gsd_cm: float
    max_incidence_deg: float = 60.0
    front_overlap: float = 0.75
    side_overlap: float = 0.65
    priority: int = 1
    required: bool = True
    camera: str | None = None
    kind: Literal["facade"] = "facade"


@dataclass(frozen=True)
class PointObjective:
    """A point of interest at ``(x, y)`` and ``z`` m above the ground, photographed from
    ``distance`` m by ``views`` viewpoints spread evenly around it at ``elevation_deg`` above
    its level; the UAV hovers ``dwell_s`` at each. ``time_window``: ``(t0, t1)`` s after take-off
    within which the photos must be taken (``None``: any time). ``repeat_every_s`` and
    ``repeats``: recurring monitoring, the same views again every ``repeat_every_s`` s (the
    window shifted by as much each time), ``repeats`` visits in all. ``gsd_cm``: a resolution
    to check the distance against (``None``: none)."""

    name: str
    x: float
    y: float
    z: float
    distance: float
    views: int = 1
    elevation_deg: float = 0.0
    dwell_s: float = 2.0
    time_window: tuple[float, float] | None = None
    repeat_every_s: float | None = None
    repeats: int = 1
    gsd_cm: float | None = None
    priority: int = 1
    required: bool = True
    camera: str | None = None
    kind: Literal["point"] = "point"

    def windows(self) -> list[tuple[float, float] | None]:
        """One time window per visit (``None``: no window)."""
        if self.repeats <= 1 or self.repeat_every_s is None:
            return [self.time_window]
        t0, t1 = self.time_window if self.time_window is not None else (0.0, math.inf)
        return [(t0 + k * self.repeat_every_s, t1 + k * self.repeat_every_s) for k in range(self.repeats)]


Objective = Union[AreaObjective, FacadeObjective, PointObjective]


@dataclass(frozen=True)
class Payload:
    """A UAV's inspection payload: its ``camera``, the gimbal's pitch range (degrees, -90 =
    nadir, 0 = level) and the flight time it has (``endurance_s``, s, the reserve already taken
    off)."""

    camera: Camera
    gimbal_pitch_min_deg: float = -90.0
    gimbal_pitch_max_deg: float = 30.0
    endurance_s: float = math.inf


@dataclass(frozen=True)
class Inspection:
    """The objectives and every UAV's payload (``payloads[n]`` for ``team[n]``).

    ``max_blur_px``: the motion blur a photo may have at the planned speed (the capture speed is
    lowered to keep it); ``cell_m``: the side of the ground cells and facade patches that coverage
    is measured on (``None``: from the finest target GSD, 200 px a side, clamped to 0.25-1 m)."""

    objectives: tuple[Objective, ...]
    payloads: tuple[Payload, ...]
    max_blur_px: float = 0.5
    cell_m: float | None = None

    def camera_for(self, obj: Objective) -> Camera:
        """The camera ``obj`` is planned for: the one it names, else the first UAV's."""
        if obj.camera is None:
            return self.payloads[0].camera
        return next(p.camera for p in self.payloads if p.camera.name == obj.camera)

    def payload_for(self, obj: Objective) -> Payload:
        """The first payload carrying ``obj``'s camera (its gimbal limits shape the plan)."""
        cam = self.camera_for(obj)
        return next(p for p in self.payloads if p.camera.name == cam.name)

    def objective(self, name: str) -> Objective:
        for o in self.objectives:
            if o.name == name:
                return o
        raise KeyError(name)

    def coverage_cell(self) -> float:
        if self.cell_m is not None:
            return float(self.cell_m)
        gsds = [o.gsd_cm for o in self.objectives if isinstance(o, (AreaObjective, FacadeObjective))]
        if not gsds:
            return 1.0
        return float(min(max(2.0 * min(gsds), 0.25), 1.0))
