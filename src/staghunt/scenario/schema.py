"""The scenario file format, declared once (pydantic v2): types, required keys, ranges, defaults.

:class:`ScenarioFile` checks a parsed TOML document key by key (unknown keys, wrong types, NaN and
infinities, booleans where numbers belong and out-of-range values are all errors; integers are
accepted where floats are expected) and publishes the same rules as a JSON Schema
(:func:`json_schema`, printed by ``staghunt schema``) that editors use to check and complete
scenario files. Checks that need more than one table (a start inside an obstacle, a DEM that
must cover the site, a connected formation graph) are made by :mod:`staghunt.scenario.loader`
when it builds the :class:`~staghunt.scenario.model.Scenario`.

:func:`staghunt.scenario.validation.validate` turns pydantic's first error into a :class:`ScenarioError` of one line that
names the key path (``team[2].start[1]``, array-of-tables entries indexed from 0), the value and
what was expected. The model is the format's single source of truth: documentation is in
``docs/scenario-format.md``, the meaning of every value in ``docs/model.md``.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional

from pydantic import ConfigDict, Field, model_validator

from staghunt.scenario.errors import fmt as _fmt
from staghunt.scenario.model import CostParams, SolverSettings
from staghunt.scenario.schema_inspection import (
    CameraRef,
    InspectionTable,
    ObjectivesFile,
    ObjectiveTable,
    PayloadKeys,
    PayloadTable,
)
from staghunt.scenario.schema_base import (  # noqa: F401  (re-exported: the format's value types)
    BaseHeight, Matrix, NonNegative, Number, Polygon, Solid, Table, TopHeight, XYH, fail,
)
from staghunt.scenario.schema_dynamic import (  # noqa: F401  (re-exported: part of the format)
    EventsFile, EventTable, JibTable, LinkTable, MovingTable, SensingTable,
)
from staghunt.task import VehicleLimits
from staghunt.task.airframes import AIRFRAME_NAMES

__all__ = ["EventsFile", "ObjectivesFile", "ScenarioFile", "json_schema"]


# --------------------------------------------------------------------------------------------
# Tables (value types and the table base: staghunt.scenario.schema_base; a site that changes:
# staghunt.scenario.schema_dynamic)
# --------------------------------------------------------------------------------------------


class Site(Table):
    """The site box: x and y in metres, flight heights h in metres above ground."""

    xmin: Number
    xmax: Number
    ymin: Number
    ymax: Number
    hmin: Annotated[float, Field(ge=0, description="lowest flight height above ground (m)")]
    hmax: Annotated[float, Field(description="highest flight height above ground (m)")]

    @model_validator(mode="after")
    def _ordered(self) -> "Site":
        for lo, hi in (("xmin", "xmax"), ("ymin", "ymax")):
            a, b = getattr(self, lo), getattr(self, hi)
            if a >= b:
                raise fail(hi, f"must be greater than site.{lo} = {_fmt(a)}, got {_fmt(b)}")
        if self.hmin > self.hmax:
            raise fail("hmax", f"must be >= site.hmin = {_fmt(self.hmin)}, got {_fmt(self.hmax)}")
        return self


class Ground(Table):
    """Flat ground (height 0), a DEM grid read from a ``.npy`` or GeoTIFF file in site
    coordinates (``dem``), or a geo-referenced GeoTIFF with its CRS resampled into the site
    frame around ``[origin]`` (``geotiff``)."""

    kind: Literal["flat", "dem", "geotiff"] = "flat"
    file: Optional[str] = Field(None, description="DEM file (.npy, .tif, .tiff), relative to the scenario file")
    nodata_fill: Optional[Number] = Field(None, description="geotiff: elevation (m AMSL) used where the DEM has no data; "
        "default: no data under the site is an error")
    origin: Annotated[list[Number], Field(min_length=2, max_length=2, description="[x0, y0]: site coordinates of the "
        "grid's first cell centre")] = [0.0, 0.0]
    cell_size: Annotated[float, Field(gt=0, description="grid spacing (m)")] = 1.0
    sampling: Literal["nearest", "bilinear"] = "nearest"
    shape: Optional[list[int]] = Field(None, description="integrity check: [rows, columns] of the grid")
    dtype: Optional[str] = Field(None, description="integrity check: dtype of the grid")
    sha256: Optional[str] = Field(None, description="integrity check: SHA-256 of the grid's bytes (dem) or of the file (geotiff)")

    @model_validator(mode="after")
    def _kind_keys(self) -> "Ground":
        if self.kind == "flat":
            for key in type(self).model_fields:
                if key != "kind" and key in self.model_fields_set:
                    raise fail(key, "only used with kind = 'dem' or 'geotiff'; flat ground takes no other key than 'kind'")
        elif self.file is None:
            raise fail("file", "required key is missing")
        if self.kind == "geotiff":
            for key in ("origin", "shape", "dtype"):
                if key in self.model_fields_set:
                    raise fail(key, "not used with kind = 'geotiff' (the DEM's CRS and [origin] place the grid)")
        elif self.nodata_fill is not None:
            raise fail("nodata_fill", "only used with kind = 'geotiff'")
        return self


class Obstacle(Table):
    """A vertical cylinder from the ground up, centre (x, y), radius R (m)."""

    x: Number
    y: Number
    radius: Annotated[float, Field(gt=0)]
    name: str = ""


class PrismTable(Solid):
    """A vertical prism (building, crane tower, site cabin): a footprint polygon from ``base``
    to ``height``, both in metres above the ground (docs/model.md, "Prisms")."""

    name: str = ""
    polygon: Polygon
    base: BaseHeight = 0.0
    height: TopHeight


class BoxTable(Solid):
    """An axis-aligned box: x in [xmin, xmax], y in [ymin, ymax], from ``base`` to ``height`` m above ground."""

    name: str = ""
    xmin: Number
    xmax: Number
    ymin: Number
    ymax: Number
    base: BaseHeight = 0.0
    height: TopHeight

    @model_validator(mode="after")
    def _order(self) -> "BoxTable":
        for lo, hi in (("xmin", "xmax"), ("ymin", "ymax")):
            if getattr(self, lo) >= getattr(self, hi):
                raise fail(hi, f"must be greater than {lo} = {_fmt(getattr(self, lo))}, got {_fmt(getattr(self, hi))}")
        return self


class NoFlyTable(Table):
    """A no-fly zone: a polygon forbidden at every height."""

    name: str = ""
    polygon: Polygon


class GeoJsonTable(Table):
    """Obstacles from a GeoJSON file (lon/lat, WGS84), converted around ``[origin]``: Polygon and
    MultiPolygon features with a ``height`` (and optional ``base``) property become prisms
    (or no-fly zones with ``nofly = true``), Points with a ``radius`` become cylinders."""

    file: str = Field(description="GeoJSON file, relative to the scenario file")
    nofly: bool = Field(False, description="every polygon of the file is a no-fly zone")


class Airspace(Table):
    """Limits of the airspace."""

    ceiling: Optional[Number] = Field(None, description="altitude ceiling: absolute z in the site frame "
        "(m above the origin's altitude)")


class Fleet(PayloadKeys):
    """A team generated from a formation template (replaces [[team]])."""

    count: Annotated[int, Field(ge=1, le=64)]
    template: Literal["line", "wedge", "grid", "circle"]
    spacing: Annotated[float, Field(gt=0, description="m between neighbours of the template")]
    columns: Optional[Annotated[int, Field(ge=1)]] = Field(None, description="grid: UAVs per row; default ceil(sqrt(count))")
    heading_deg: Optional[Number] = Field(None, description="direction the formation faces, degrees counter-clockwise "
        "from east; default: team start to team goal")
    start: Optional[XYH] = Field(None, description="team start: the formation's centre")
    goal: Optional[XYH] = Field(None, description="team goal: the formation's centre")
    starts: Optional[list[XYH]] = Field(None, description="per-UAV starts instead of start")
    goals: Optional[list[XYH]] = Field(None, description="per-UAV goals instead of goal")
    radius: Annotated[float, Field(ge=0, description="body radius r (m)")]
    beta: Annotated[float, Field(ge=0)]
    weights: Annotated[list[NonNegative], Field(min_length=5, max_length=5)]

    @model_validator(mode="after")
    def _ends(self) -> "Fleet":
        for one, many in (("start", "starts"), ("goal", "goals")):
            a, b = getattr(self, one), getattr(self, many)
            if (a is None) == (b is None):
                raise fail(one, f"give exactly one of {one} (the team's) and {many} (one per UAV)")
            if b is not None and len(b) != self.count:
                raise fail(many, f"must hold count = {self.count} points, got {len(b)}")
        return self


class Uav(PayloadKeys):
    """One UAV of the team."""

    name: Optional[Annotated[str, Field(pattern=r"\S")]] = Field(None, description="default UAV<i> (1-based)")
    start: XYH
    goal: XYH
    radius: Annotated[float, Field(ge=0, description="body radius r (m)")]
    beta: Annotated[float, Field(ge=0, description="weight of the formation cost in J_n")]
    weights: Annotated[list[NonNegative], Field(min_length=5, max_length=5, description="[w1, w2, w3, w4, w5]: length, threat, "
        "height, turning, climb")]

    @model_validator(mode="after")
    def _two_ends(self) -> "Uav":
        if self.start == self.goal:
            raise fail("goal", f"equals the start {tuple(self.start)}; a path needs two ends")
        return self


class FormationTable(Table):
    """The formation graph: signed incidence matrix (N x M), edge weights (N x M), reference."""

    incidence: Matrix
    edge_weights: list[list[NonNegative]]
    reference: Optional[Matrix] = Field(None, description="N x 3 absolute [x, y, z]; default: the goals")


class Costs(Table):
    """Parameters of the cost terms (docs/model.md section 2)."""

    danger_margin: NonNegative = CostParams.danger_margin
    safe_distance: NonNegative = CostParams.safe_distance
    turning_threshold_deg: Annotated[float, Field(ge=0, le=180)] = CostParams.turning_threshold_deg
    climb_threshold_deg: Annotated[float, Field(ge=0, le=180)] = CostParams.climb_threshold_deg
    desired_height: Optional[float] = Field(CostParams.desired_height, description="h_ref (m above ground); default: "
        "middle of [hmin, hmax]")
    continuous_separation: bool = CostParams.continuous_separation
    min_clearance: NonNegative = CostParams.min_clearance


class Solver(Table):
    """Swarm settings (the budget options of ``staghunt plan`` override the first three)."""

    particles: Annotated[int, Field(ge=1)] = SolverSettings.particles
    iterations: Annotated[int, Field(ge=0)] = SolverSettings.iterations
    waypoints: Annotated[int, Field(ge=1)] = SolverSettings.waypoints
    c0: NonNegative = SolverSettings.c0
    damping: NonNegative = SolverSettings.damping
    c1: NonNegative = SolverSettings.c1
    c2: NonNegative = SolverSettings.c2
    velocity_fraction: Annotated[float, Field(gt=0, le=1)] = SolverSettings.velocity_fraction
    starts: Annotated[int, Field(ge=1, description="starts of the game method's equilibrium search")] = (
        SolverSettings.starts)


class Origin(Table):
    """Geodetic origin of the site frame (WGS84)."""

    latitude: Annotated[float, Field(ge=-90, le=90, description="degrees")]
    longitude: Annotated[float, Field(ge=-180, le=180, description="degrees")]
    altitude: Annotated[float, Field(ge=-500, le=10000, description="m above mean sea level")]


class Vehicle(Table):
    """Flight limits of the team's vehicles, and the airframe that flies them in simulation."""

    max_speed: Annotated[float, Field(gt=0, description="m/s")] = VehicleLimits.max_speed
    max_acceleration: Annotated[float, Field(gt=0, description="m/s^2")] = VehicleLimits.max_acceleration
    cruise_speed: Annotated[float, Field(gt=0, description="m/s, at most max_speed")] = VehicleLimits.cruise_speed
    airframe: Annotated[Literal[AIRFRAME_NAMES], Field(  # type: ignore[valid-type]
        description="the simulated vehicles' airframe")] = VehicleLimits.airframe

    @model_validator(mode="after")
    def _cruise(self) -> "Vehicle":
        if self.cruise_speed > self.max_speed:
            raise fail("cruise_speed", f"must not exceed vehicle.max_speed ({_fmt(self.max_speed)} m/s), "
                        f"got {_fmt(self.cruise_speed)}")
        return self





class ScenarioFile(Table):
    """A staghunt scenario (TOML): site, ground, obstacles, team, formation, costs, solver."""

    model_config = ConfigDict(title="staghunt scenario")

    name: Optional[Annotated[str, Field(pattern=r"\S")]] = Field(None, description="default: the file's stem")
    description: str = ""
    site: Site
    origin: Optional[Origin] = None
    ground: Ground = Field(default_factory=Ground)
    obstacles: list[Obstacle] = []
    prisms: list[PrismTable] = []
    boxes: list[BoxTable] = []
    nofly: list[NoFlyTable] = []
    geojson: list[GeoJsonTable] = []
    airspace: Airspace = Field(default_factory=Airspace)
    team: Optional[Annotated[list[Uav], Field(min_length=1)]] = None
    fleet: Optional[Fleet] = None
    formation: Optional[FormationTable] = Field(None, description="required for two UAVs or more")
    costs: Costs = Field(default_factory=Costs)
    solver: Solver = Field(default_factory=Solver)
    vehicle: Vehicle = Field(default_factory=Vehicle)
    moving: list[MovingTable] = []
    jibs: list[JibTable] = []
    events: list[EventTable] = []
    sensing: Optional[SensingTable] = None
    link: Optional[LinkTable] = None
    camera: Optional[CameraRef] = Field(None, description="the team's camera: a name of the shipped table or a "
                                        "table of its geometry")
    payload: Optional[PayloadTable] = Field(None, description="the team's default gimbal pitch range and endurance")
    inspection: Optional[InspectionTable] = None
    objectives: list[ObjectiveTable] = []

    @model_validator(mode="after")
    def _team_or_fleet(self) -> "ScenarioFile":
        if self.team is None and self.fleet is None:
            raise fail("team", "required key is missing (or give a [fleet])")
        if self.team is not None and self.fleet is not None:
            raise fail("fleet", "give either [[team]] entries or a [fleet], not both")
        return self


def json_schema(model: type[Table] | None = None) -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of the scenario format (or of ``EventsFile``)."""
    model = model or ScenarioFile
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", **model.model_json_schema()}
