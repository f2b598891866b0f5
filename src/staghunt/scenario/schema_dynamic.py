"""The tables of a site that changes (docs/scenario-format.md, "A site that changes"; used by
``staghunt fly``): moving cylinders, slewing crane jibs, events that make obstacles appear or
disappear, what the team senses, and :class:`EventsFile`, the file of ``staghunt fly --events``.
Part of the scenario format (:mod:`staghunt.scenario.schema`)."""

from __future__ import annotations

import math
from typing import Annotated, Literal, Optional

from pydantic import ConfigDict, Field, model_validator

from staghunt.scenario.errors import fmt as _fmt
from staghunt.scenario.schema_inspection import ObjectiveTable
from staghunt.scenario.schema_base import Number, Polygon, Solid, Table, fail

__all__ = ["MAX_MOTION_SPEED", "EventTable", "EventsFile", "JibTable", "MovingTable", "SensingTable"]

MAX_MOTION_SPEED = 50.0
"""m/s: the fastest a known motion may move (a moving obstacle along its path, a jib's far
corner): faster than anything on a site; the in-time checks' margin grows with it
(docs/model.md, section 8)."""

Seconds = Annotated[float, Field(ge=0, description="s after take-off")]
XY = Annotated[list[Number], Field(min_length=2, max_length=2, description="[x, y] in the site frame (m)")]
RepeatKind = Literal["stop", "reverse"]


class MovingTable(Table):
    """A cylinder with a known motion (a truck, a load on a hook): infinitely tall like the
    static obstacles, its axis moving along ``path`` at ``speed`` from ``start_time`` on."""

    name: Annotated[str, Field(pattern=r"\S")]
    radius: Annotated[float, Field(gt=0, description="m")]
    path: Annotated[list[XY], Field(min_length=2, description="[[x, y], ...] polyline of the axis (m)")]
    speed: Annotated[float, Field(gt=0, le=MAX_MOTION_SPEED, description="m/s along the path")]
    start_time: Seconds = 0.0
    repeat: RepeatKind = Field("stop", description="at the end: 'stop' there, or run the path back and forth ('reverse')")


class JibTable(Solid):
    """A crane jib that slews: a box ``length`` m ahead of the pivot (plus ``counter`` behind),
    ``width`` m wide, from ``base`` to ``height`` m above the ground at the pivot, turning from
    ``angle_from`` to ``angle_to`` (degrees counter-clockwise from east) at ``rate`` deg/s."""

    name: Annotated[str, Field(pattern=r"\S")]
    pivot: XY
    length: Annotated[float, Field(gt=0, description="m from the pivot to the tip")]
    counter: Annotated[float, Field(ge=0, description="m of counter-jib behind the pivot")] = 0.0
    width: Annotated[float, Field(gt=0, description="m")]
    base: Annotated[float, Field(ge=0, description="m above the ground at the pivot")]
    height: Annotated[float, Field(gt=0, description="top, m above the ground at the pivot")]
    angle_from: Annotated[float, Field(ge=-360, le=360, description="degrees, counter-clockwise from east")]
    angle_to: Annotated[float, Field(ge=-360, le=360, description="degrees")]
    rate: Annotated[float, Field(gt=0, le=90, description="deg/s; the far corner moves at most 50 m/s")]
    start_time: Seconds = 0.0
    repeat: RepeatKind = "stop"

    @model_validator(mode="after")
    def _corner_speed(self) -> "JibTable":
        reach = math.hypot(max(self.length, self.counter), 0.5 * self.width)
        if math.radians(self.rate) * reach > MAX_MOTION_SPEED:
            raise fail("rate", f"the jib's far corner ({reach:.1f} m from the pivot) would move at "
                       f"{math.radians(self.rate) * reach:.1f} m/s, above {_fmt(MAX_MOTION_SPEED)} m/s: rate must be "
                       f"<= {math.degrees(MAX_MOTION_SPEED / reach):.3g} deg/s here, got {_fmt(self.rate)}")
        return self


class TriggerTable(Table):
    """An ``appear`` that happens before its ``time`` once a UAV (``uav``, or any UAV of the team
    without it) comes ``within`` metres of the obstacle, or its trajectory would breach the
    required clearance to it within ``lead`` seconds; at least one of the two."""

    uav: Optional[Annotated[str, Field(pattern=r"\S", description="the UAV's name; absent: any UAV")]] = None
    within: Optional[Annotated[float, Field(gt=0, le=1e4, description="m, horizontally from the obstacle's outline")]] = None
    lead: Optional[Annotated[float, Field(gt=0, le=1e3, description="s: the UAV's trajectory would breach the "
                                                                   "clearance to the obstacle that soon")]] = None

    @model_validator(mode="after")
    def _one(self) -> "TriggerTable":
        if self.within is None and self.lead is None:
            raise fail("within", "required key is missing (give within, lead or both)")
        return self


class EventTable(Table):
    """A change at ``time``: ``appear`` (a cylinder ``x``, ``y``, ``radius`` through the whole
    height band, or a ``polygon``, a no-fly zone unless ``height`` makes it a prism from
    ``base``), unknown to the plan until a UAV senses it, and with a ``trigger`` sooner, as soon
    as the UAV it names (or any) comes ``within`` metres or ``lead`` seconds of it; ``disappear``
    (the obstacle ``name``); for an inspection, ``uav_lost`` (the UAV ``uav`` lands where it is) and ``objective`` (an
    objective table added in flight)."""

    time: Seconds
    kind: Literal["appear", "disappear", "uav_lost", "objective"]
    name: Optional[Annotated[str, Field(pattern=r"\S")]] = Field(None, description="appear: default 'pop-up <i>'; "
        "disappear: required")
    x: Optional[Number] = None
    y: Optional[Number] = None
    radius: Optional[Annotated[float, Field(gt=0, description="m")]] = None
    polygon: Optional[Polygon] = None
    base: Optional[Annotated[float, Field(ge=0, description="m above ground (polygon)")]] = None
    height: Optional[Annotated[float, Field(gt=0, description="top, m above ground (polygon); absent: a no-fly zone")]] = None
    uav: Optional[Annotated[str, Field(pattern=r"\S", description="uav_lost: the UAV's name")]] = None
    objective: Optional[ObjectiveTable] = Field(None, description="objective: the objective added")
    trigger: Optional[TriggerTable] = Field(None, description="appear: sooner than time, once a UAV is this close (m or s)")

    @model_validator(mode="after")
    def _shape(self) -> "EventTable":
        given = {k for k in ("x", "y", "radius", "polygon", "base", "height", "name", "uav", "objective", "trigger")
                 if getattr(self, k) is not None}
        own = {"uav_lost": "uav", "objective": "objective"}
        if self.kind in own:
            key = own[self.kind]
            if key not in given:
                raise fail(key, f"required key is missing (kind = '{self.kind}')")
            if given - {key}:
                raise fail(sorted(given - {key})[0], f"not used with kind = '{self.kind}'")
            return self
        for key in ("uav", "objective"):
            if key in given:
                raise fail(key, f"not used with kind = '{self.kind}'")
        given -= {"name"}
        if self.kind == "disappear":
            if self.name is None:
                raise fail("name", "required key is missing (the obstacle that disappears)")
            if given:
                raise fail(sorted(given)[0], "not used with kind = 'disappear'")
            return self
        circle = {"x", "y", "radius"}
        given -= {"trigger"}
        if self.polygon is None:
            missing = sorted(circle - given)
            if missing:
                raise fail(missing[0], "required key is missing (or give a polygon)")
            if given & {"base", "height"}:
                raise fail(sorted(given & {"base", "height"})[0], "only used with a polygon")
        else:
            if given & circle:
                raise fail(sorted(given & circle)[0], "give either x, y and radius or a polygon, not both")
            if self.base is not None and self.height is None:
                raise fail("height", "required with base")
            if self.height is not None and self.height <= (self.base or 0.0):
                raise fail("height", f"must be above base = {_fmt(self.base or 0.0)}, got {_fmt(self.height)}")
        return self


class SensingTable(Table):
    """What the planner learns in flight."""

    range: Annotated[float, Field(gt=0, description="m: an appeared obstacle is sensed once a UAV "
        "is this close (horizontally)")] = 40.0
    rate: Annotated[float, Field(ge=10, le=100, description="Hz: state feedback and planner ticks")] = 10.0
    position_noise: Annotated[float, Field(ge=0, le=10, description="m, standard deviation of the fed-back positions")] = 0.0
    velocity_noise: Annotated[float, Field(ge=0, le=10, description="m/s, standard deviation of the fed-back velocities")] = 0.0


class LinkTable(Table):
    """The radio between the ground station and each UAV (both ways)."""

    delay: Annotated[float, Field(ge=0, le=10, description="s, one way")] = 0.1
    jitter: Annotated[float, Field(ge=0, le=10, description="s, standard deviation added to the delay")] = 0.03
    loss: Annotated[float, Field(ge=0, lt=1, description="share of messages lost")] = 0.01


class EventsFile(Table):
    """An events file (``staghunt fly --events FILE``): what changes in flight, added to the
    scenario's own (its [sensing] and [link] replace the scenario's)."""

    model_config = ConfigDict(title="staghunt events")

    events: list[EventTable] = []
    moving: list[MovingTable] = []
    jibs: list[JibTable] = []
    sensing: Optional[SensingTable] = None
    link: Optional[LinkTable] = None
