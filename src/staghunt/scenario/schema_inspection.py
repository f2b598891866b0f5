"""The inspection's tables of the scenario format (docs/scenario-format.md, "Inspections"): the
camera (a name from the shipped table or the five numbers of QGroundControl's CameraCalc), the
payload (gimbal pitch range, endurance), the objectives (areas, facades, points of interest) and
the capture settings; also the objectives file (``--objectives FILE``) that carries the same
tables apart from a scenario."""

from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

from pydantic import ConfigDict, Field, model_validator

from staghunt.scenario.errors import fmt as _fmt
from staghunt.scenario.schema_base import Number, Polygon, Table, fail

__all__ = ["AreaTable", "CameraRef", "CameraTable", "FacadeTable", "InspectionTable", "ObjectiveTable", "ObjectivesFile",
           "PayloadKeys", "PayloadTable", "PointTable"]

Fraction = Annotated[float, Field(ge=0, lt=1, description="a share in [0, 1)")]
Gsd = Annotated[float, Field(gt=0, le=1000, description="ground sampling distance to reach or beat (cm/px)")]
Name = Annotated[str, Field(pattern=r"\S", max_length=200)]


class CameraTable(Table):
    """A camera given by its geometry (QGroundControl's CameraMetaData fields)."""

    name: Optional[Name] = Field(None, description="default: 'custom camera'")
    sensor_width_mm: Annotated[float, Field(gt=0, le=200)]
    sensor_height_mm: Annotated[float, Field(gt=0, le=200)]
    image_width_px: Annotated[int, Field(ge=16, le=200000)]
    image_height_px: Annotated[int, Field(ge=16, le=200000)]
    focal_length_mm: Annotated[float, Field(gt=0, le=2000)]
    min_trigger_interval_s: Annotated[float, Field(ge=0, le=3600)] = 0.0
    landscape: bool = Field(True, description="the image's long side across the direction of travel")
    exposure_s: Annotated[float, Field(gt=0, le=10, description="shutter time for the motion blur")] = 1e-3


CameraRef = Union[Annotated[str, Field(pattern=r"\S", description="a camera of the shipped table "
                                       "(staghunt cameras)")], CameraTable]
PitchRange = Annotated[list[Number], Field(min_length=2, max_length=2,
                                           description="[lowest, highest] gimbal pitch (degrees; -90 = nadir, 0 = level)")]


class PayloadKeys(Table):
    """The payload keys a UAV entry, a fleet or the top-level [payload] table may give."""

    camera: Optional[CameraRef] = None
    gimbal_pitch_deg: Optional[PitchRange] = None
    endurance_s: Optional[Annotated[float, Field(gt=0, le=86400, description="flight time available, reserve "
                                                 "already taken off (s)")]] = None

    @model_validator(mode="after")
    def _pitch(self) -> "PayloadKeys":
        check_pitch(self.gimbal_pitch_deg)
        return self


class PayloadTable(PayloadKeys):
    """The team's default payload (a UAV's own keys win)."""


def check_pitch(p: list[float] | None) -> None:
    """A gimbal pitch range must be ``[lowest, highest]`` within ``[-180, 180]`` degrees."""
    if p is not None and not (-180 <= p[0] < p[1] <= 180):
        raise fail("gimbal_pitch_deg", f"must be [lowest, highest] with -180 <= lowest < highest <= 180, "
                   f"got [{_fmt(p[0])}, {_fmt(p[1])}]")


class _Objective(Table):
    name: Name
    priority: Annotated[int, Field(ge=0, le=1000, description="higher first when endurance is short")] = 1
    required: bool = Field(True, description="false: may be left out (reported) when the team cannot do everything")
    camera: Optional[Annotated[str, Field(pattern=r"\S")]] = Field(None, description="the camera (by name) it is "
                                                                    "planned for; default: the first UAV's")


class AreaTable(_Objective):
    """A nadir survey of a polygon (site frame), or of a GeoJSON Polygon feature (WGS84)."""

    kind: Literal["area"]
    polygon: Optional[Polygon] = None
    geojson: Optional[Annotated[str, Field(pattern=r"\S", description="GeoJSON file (WGS84) holding the polygon")]] = None
    feature: Optional[Name] = Field(None, description="the feature's 'name' property (default: the file's only feature)")
    gsd_cm: Gsd
    front_overlap: Fraction = 0.75
    side_overlap: Fraction = 0.65
    angle_deg: Optional[Annotated[float, Field(ge=-360, le=360, description="line direction, counter-clockwise "
                                               "from east; default: along the polygon's long side")]] = None

    @model_validator(mode="after")
    def _one_shape(self) -> "AreaTable":
        if (self.polygon is None) == (self.geojson is None):
            raise fail("polygon", "give exactly one of polygon (site frame) and geojson (a file)")
        return self


class FacadeTable(_Objective):
    """The walls of a prism or building of the scenario."""

    kind: Literal["facade"]
    prism: Name
    gsd_cm: Gsd
    max_incidence_deg: Annotated[float, Field(gt=0, lt=90)] = 60.0
    front_overlap: Fraction = 0.75
    side_overlap: Fraction = 0.65


class PointTable(_Objective):
    """A point of interest seen from a given distance (site frame, or a GeoJSON Point feature)."""

    kind: Literal["point"]
    x: Optional[Number] = None
    y: Optional[Number] = None
    geojson: Optional[Annotated[str, Field(pattern=r"\S", description="GeoJSON file (WGS84) holding the point")]] = None
    feature: Optional[Name] = None
    z: Annotated[float, Field(ge=0, le=10000, description="m above the ground")]
    distance: Annotated[float, Field(gt=0, le=10000, description="m from the point to the camera")]
    views: Annotated[int, Field(ge=1, le=36)] = 1
    elevation_deg: Annotated[float, Field(ge=-80, le=80, description="viewpoints' elevation above the point")] = 0.0
    dwell_s: Annotated[float, Field(ge=0, le=3600, description="hover at each viewpoint")] = 2.0
    time_window: Optional[Annotated[list[Annotated[float, Field(ge=0, le=1e6)]], Field(min_length=2, max_length=2,
                                    description="[t0, t1] s after take-off")]] = None
    repeat_every_s: Optional[Annotated[float, Field(gt=0, le=1e6)]] = None
    repeats: Annotated[int, Field(ge=1, le=100)] = 1
    gsd_cm: Optional[Gsd] = None

    @model_validator(mode="after")
    def _where_when(self) -> "PointTable":
        if self.geojson is None and (self.x is None or self.y is None):
            raise fail("x", "give x and y (site frame) or geojson (a file)")
        if self.geojson is not None and (self.x is not None or self.y is not None):
            raise fail("geojson", "give either x and y or geojson, not both")
        if self.time_window is not None:
            t0, t1 = self.time_window
            if t1 <= t0:
                raise fail("time_window", f"must end after it starts, got [{_fmt(t0)}, {_fmt(t1)}]")
            if t1 - t0 < self.dwell_s * self.views:
                raise fail("time_window", f"lasts {_fmt(t1 - t0)} s, less than the {_fmt(self.dwell_s * self.views)} s "
                           f"of hovering its {self.views} views need (dwell_s = {_fmt(self.dwell_s)})")
        if self.repeats > 1 and self.repeat_every_s is None:
            raise fail("repeat_every_s", f"required with repeats = {self.repeats}")
        return self


ObjectiveTable = Annotated[Union[AreaTable, FacadeTable, PointTable], Field(discriminator="kind")]


class InspectionTable(Table):
    """Capture settings."""

    max_blur_px: Annotated[float, Field(gt=0, le=100, description="motion blur allowed at the planned speed")] = 0.5
    cell_m: Optional[Annotated[float, Field(gt=0.01, le=50, description="side of the coverage cells and patches")]] = None


class ObjectivesFile(Table):
    """An objectives file (``--objectives FILE``): an inspection for a scenario. Its tables
    replace the scenario's own."""

    model_config = ConfigDict(title="staghunt objectives")

    camera: Optional[CameraRef] = None
    payload: Optional[PayloadTable] = None
    inspection: Optional[InspectionTable] = None
    objectives: Annotated[list[ObjectiveTable], Field(min_length=1)]
