"""The scenario file format, declared once (pydantic v2): types, required keys, ranges, defaults.

:class:`ScenarioFile` checks a parsed TOML document key by key (unknown keys, wrong types, NaN and
infinities, booleans where numbers belong and out-of-range values are all errors; integers are
accepted where floats are expected) and publishes the same rules as a JSON Schema
(:func:`json_schema`, printed by ``staghunt schema``) that editors use to check and complete
scenario files. Checks that need more than one table (a start inside an obstacle, a DEM that
must cover the site, a connected formation graph) are made by :mod:`staghunt.scenario.loader`
when it builds the :class:`~staghunt.scenario.model.Scenario`.

:func:`validate` turns pydantic's first error into a :class:`ScenarioError` of one line that
names the key path (``team[2].start[1]``, array-of-tables entries indexed from 0), the value and
what was expected. The model is the format's single source of truth: documentation is in
``docs/scenario-format.md``, the meaning of every value in ``docs/model.md``.
"""

from __future__ import annotations

import numbers
import types
import typing
from collections.abc import Mapping
from typing import Annotated, Any, Literal, Optional

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from staghunt.scenario.errors import ScenarioError
from staghunt.scenario.errors import fmt as _fmt
from staghunt.scenario.model import CostParams, SolverSettings
from staghunt.task import VehicleLimits

__all__ = ["ScenarioFile", "json_schema", "key_path", "plain", "validate"]


# --------------------------------------------------------------------------------------------
# Value types
# --------------------------------------------------------------------------------------------


Number = float
NonNegative = Annotated[float, Field(ge=0)]
XYH = Annotated[list[Number], Field(min_length=3, max_length=3, description="[x, y, h], h above ground (m)")]
Matrix = list[list[Number]]


def _fail(key: str, detail: str) -> PydanticCustomError:
    """A cross-field error of a table, reported at its key ``key``."""
    return PydanticCustomError("staghunt", "{detail}", {"detail": detail, "key": key})


class _Table(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _none_is_absent(cls, data: Any) -> Any:
        """A known key whose value is ``None`` counts as absent (plain-data form); an unknown
        key is still reported, whatever its value."""
        if isinstance(data, Mapping):
            return {k: v for k, v in data.items() if v is not None or k not in cls.model_fields}
        return data


# --------------------------------------------------------------------------------------------
# Tables
# --------------------------------------------------------------------------------------------


class Site(_Table):
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
                raise _fail(hi, f"must be greater than site.{lo} = {_fmt(a)}, got {_fmt(b)}")
        if self.hmin > self.hmax:
            raise _fail("hmax", f"must be >= site.hmin = {_fmt(self.hmin)}, got {_fmt(self.hmax)}")
        return self


class Ground(_Table):
    """Flat ground (height 0), a DEM grid read from a ``.npy`` or GeoTIFF file in site
    coordinates (``dem``), or a geo-referenced GeoTIFF with its CRS resampled into the site
    frame around ``[origin]`` (``geotiff``)."""

    kind: Literal["flat", "dem", "geotiff"] = "flat"
    file: Optional[str] = Field(None, description="DEM file (.npy, .tif, .tiff), relative to the scenario file")
    nodata_fill: Optional[Number] = Field(None, description="geotiff: elevation (m AMSL) used where the DEM has no data; default: no data under the site is an error")
    origin: Annotated[list[Number], Field(min_length=2, max_length=2, description="[x0, y0]: site coordinates of the grid's first cell centre")] = [0.0, 0.0]
    cell_size: Annotated[float, Field(gt=0, description="grid spacing (m)")] = 1.0
    sampling: Literal["nearest", "bilinear"] = "nearest"
    shape: Optional[list[int]] = Field(None, description="integrity check: [rows, columns] of the grid")
    dtype: Optional[str] = Field(None, description="integrity check: dtype of the grid")
    sha256: Optional[str] = Field(None, description="integrity check: SHA-256 of the grid's bytes")

    @model_validator(mode="after")
    def _kind_keys(self) -> "Ground":
        if self.kind == "flat":
            for key in type(self).model_fields:
                if key != "kind" and key in self.model_fields_set:
                    raise _fail(key, "only used with kind = 'dem' or 'geotiff'; flat ground takes no other key than 'kind'")
        elif self.file is None:
            raise _fail("file", "required key is missing")
        if self.kind == "geotiff":
            for key in ("origin", "shape", "dtype", "sha256"):
                if key in self.model_fields_set:
                    raise _fail(key, "not used with kind = 'geotiff' (the DEM's CRS and [origin] place the grid)")
        elif self.nodata_fill is not None:
            raise _fail("nodata_fill", "only used with kind = 'geotiff'")
        return self


class Obstacle(_Table):
    """A vertical cylinder from the ground up, centre (x, y), radius R (m)."""

    x: Number
    y: Number
    radius: Annotated[float, Field(gt=0)]
    name: str = ""


Polygon = Annotated[
    list[Annotated[list[Number], Field(min_length=2, max_length=2)]],
    Field(min_length=3, description="[[x, y], ...] footprint vertices in the site frame (m), not closed"),
]


class PrismTable(_Table):
    """A vertical prism (building, crane tower, site cabin): a footprint polygon from ``base``
    to ``height``, both in metres above the ground (docs/model.md, "Prisms")."""

    name: str = ""
    polygon: Polygon
    base: Annotated[float, Field(ge=0, description="m above ground; 0 = from the ground")] = 0.0
    height: Annotated[float, Field(gt=0, description="top, m above ground")]

    @model_validator(mode="after")
    def _order(self) -> "PrismTable":
        if self.height <= self.base:
            raise _fail("height", f"must be above base = {_fmt(self.base)}, got {_fmt(self.height)}")
        return self


class BoxTable(_Table):
    """An axis-aligned box: x in [xmin, xmax], y in [ymin, ymax], from ``base`` to ``height`` m above ground."""

    name: str = ""
    xmin: Number
    xmax: Number
    ymin: Number
    ymax: Number
    base: Annotated[float, Field(ge=0, description="m above ground; 0 = from the ground")] = 0.0
    height: Annotated[float, Field(gt=0, description="top, m above ground")]

    @model_validator(mode="after")
    def _order(self) -> "BoxTable":
        for lo, hi in (("xmin", "xmax"), ("ymin", "ymax")):
            if getattr(self, lo) >= getattr(self, hi):
                raise _fail(hi, f"must be greater than {lo} = {_fmt(getattr(self, lo))}, got {_fmt(getattr(self, hi))}")
        if self.height <= self.base:
            raise _fail("height", f"must be above base = {_fmt(self.base)}, got {_fmt(self.height)}")
        return self


class NoFlyTable(_Table):
    """A no-fly zone: a polygon forbidden at every height."""

    name: str = ""
    polygon: Polygon


class GeoJsonTable(_Table):
    """Obstacles from a GeoJSON file (lon/lat, WGS84), converted around ``[origin]``: Polygon and
    MultiPolygon features with a ``height`` (and optional ``base``) property become prisms
    (or no-fly zones with ``nofly = true``), Points with a ``radius`` become cylinders."""

    file: str = Field(description="GeoJSON file, relative to the scenario file")
    nofly: bool = Field(False, description="every polygon of the file is a no-fly zone")


class Airspace(_Table):
    """Limits of the airspace."""

    ceiling: Optional[Number] = Field(None, description="altitude ceiling: absolute z in the site frame (m above the origin's altitude)")


class Fleet(_Table):
    """A team generated from a formation template (replaces [[team]])."""

    count: Annotated[int, Field(ge=1, le=64)]
    template: Literal["line", "wedge", "grid", "circle"]
    spacing: Annotated[float, Field(gt=0, description="m between neighbours of the template")]
    columns: Optional[Annotated[int, Field(ge=1)]] = Field(None, description="grid: UAVs per row; default ceil(sqrt(count))")
    heading_deg: Optional[Number] = Field(None, description="direction the formation faces, degrees counter-clockwise from east; default: team start to team goal")
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
                raise _fail(one, f"give exactly one of {one} (the team's) and {many} (one per UAV)")
            if b is not None and len(b) != self.count:
                raise _fail(many, f"must hold count = {self.count} points, got {len(b)}")
        return self


class Uav(_Table):
    """One UAV of the team."""

    name: Optional[Annotated[str, Field(pattern=r"\S")]] = Field(None, description="default UAV<i> (1-based)")
    start: XYH
    goal: XYH
    radius: Annotated[float, Field(ge=0, description="body radius r (m)")]
    beta: Annotated[float, Field(ge=0, description="weight of the formation cost in J_n")]
    weights: Annotated[list[NonNegative], Field(min_length=5, max_length=5, description="[w1, w2, w3, w4, w5]: length, threat, height, turning, climb")]

    @model_validator(mode="after")
    def _two_ends(self) -> "Uav":
        if self.start == self.goal:
            raise _fail("goal", f"equals the start {tuple(self.start)}; a path needs two ends")
        return self


class FormationTable(_Table):
    """The formation graph: signed incidence matrix (N x M), edge weights (N x M), reference."""

    incidence: Matrix
    edge_weights: list[list[NonNegative]]
    reference: Optional[Matrix] = Field(None, description="N x 3 absolute [x, y, z]; default: the goals")


class Costs(_Table):
    """Parameters of the cost terms (docs/model.md section 2)."""

    danger_margin: NonNegative = CostParams.danger_margin
    safe_distance: NonNegative = CostParams.safe_distance
    turning_threshold_deg: Annotated[float, Field(ge=0, le=180)] = CostParams.turning_threshold_deg
    climb_threshold_deg: Annotated[float, Field(ge=0, le=180)] = CostParams.climb_threshold_deg
    desired_height: Optional[float] = Field(CostParams.desired_height, description="h_ref (m above ground); default: middle of [hmin, hmax]")
    continuous_separation: bool = CostParams.continuous_separation
    min_clearance: NonNegative = CostParams.min_clearance


class Solver(_Table):
    """Swarm settings (the budget options of ``staghunt plan`` override the first three)."""

    particles: Annotated[int, Field(ge=1)] = SolverSettings.particles
    iterations: Annotated[int, Field(ge=0)] = SolverSettings.iterations
    waypoints: Annotated[int, Field(ge=1)] = SolverSettings.waypoints
    c0: NonNegative = SolverSettings.c0
    damping: NonNegative = SolverSettings.damping
    c1: NonNegative = SolverSettings.c1
    c2: NonNegative = SolverSettings.c2
    velocity_fraction: Annotated[float, Field(gt=0, le=1)] = SolverSettings.velocity_fraction


class Origin(_Table):
    """Geodetic origin of the site frame (WGS84)."""

    latitude: Annotated[float, Field(ge=-90, le=90, description="degrees")]
    longitude: Annotated[float, Field(ge=-180, le=180, description="degrees")]
    altitude: Annotated[float, Field(ge=-500, le=10000, description="m above mean sea level")]


class Vehicle(_Table):
    """Flight limits of the team's vehicles."""

    max_speed: Annotated[float, Field(gt=0, description="m/s")] = VehicleLimits.max_speed
    max_acceleration: Annotated[float, Field(gt=0, description="m/s^2")] = VehicleLimits.max_acceleration
    cruise_speed: Annotated[float, Field(gt=0, description="m/s, at most max_speed")] = VehicleLimits.cruise_speed

    @model_validator(mode="after")
    def _cruise(self) -> "Vehicle":
        if self.cruise_speed > self.max_speed:
            raise _fail("cruise_speed", f"must not exceed vehicle.max_speed ({_fmt(self.max_speed)} m/s), "
                        f"got {_fmt(self.cruise_speed)}")
        return self


class ScenarioFile(_Table):
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


    @model_validator(mode="after")
    def _team_or_fleet(self) -> "ScenarioFile":
        if self.team is None and self.fleet is None:
            raise _fail("team", "required key is missing (or give a [fleet])")
        if self.team is not None and self.fleet is not None:
            raise _fail("fleet", "give either [[team]] entries or a [fleet], not both")
        return self


def json_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of the scenario format."""
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", **ScenarioFile.model_json_schema()}


# --------------------------------------------------------------------------------------------
# Validation with one-line messages
# --------------------------------------------------------------------------------------------

# What a fixed-length array holds, by key; units of two-sided ranges; hints for array errors.
_VECTORS = {"start": "[x, y, h]", "goal": "[x, y, h]", "weights": "[w1, w2, w3, w4, w5]", "origin": "[x0, y0]"}
_UNITS = {"turning_threshold_deg": " degrees", "climb_threshold_deg": " degrees", "latitude": " degrees",
          "longitude": " degrees", "altitude": " m above mean sea level"}
_ARRAY_HINTS = {"team": " (write [[team]] for each UAV)", "obstacles": " (write [[obstacles]] for each obstacle)",
                "prisms": " (write [[prisms]] for each prism)", "boxes": " (write [[boxes]] for each box)",
                "nofly": " (write [[nofly]] for each zone)", "geojson": " (write [[geojson]] for each file)"}


# pydantic error type -> message ({got}: "got a string '100'"; {value}: the value itself).
_MESSAGES = {
    "missing": "required key is missing",
    "float_type": "expected a number, {got}",
    "finite_number": "must be a finite number, got {value}",
    "int_type": "expected an integer, {got}",
    "bool_type": "expected true or false, {got}",
    "string_type": "expected a string, {got}",
    "model_type": "expected a table, {got}",
    "dict_type": "expected a table, {got}",
    "model_attributes_type": "expected a table, {got}",
    "list_type": "expected an array, {got}",
    "tuple_type": "expected an array, {got}",
    "literal_error": "must be one of {expected}, got {value!r}",
    "string_pattern_mismatch": "must not be empty, got {value!r}",
}


def plain(value: Any) -> Any:
    """``value`` as plain TOML-like data: NumPy arrays and scalars become lists and Python
    scalars, tuples lists (a key whose value is ``None`` counts as absent: see ``_Table``)."""
    if isinstance(value, Mapping):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def key_path(loc: tuple[int | str, ...]) -> str:
    """``("team", 2, "start")`` -> ``"team[2].start"``."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _kind(value: object) -> str:
    """Short type description for messages (TOML vocabulary)."""
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, numbers.Integral):
        return "an integer"
    if isinstance(value, numbers.Real):
        return "a float"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, Mapping):
        return "a table"
    if isinstance(value, (list, tuple)):
        return "an array"
    return f"a {type(value).__name__}"


def _show(value: object) -> str:
    """``repr`` of a value for messages, cut to a readable length."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _table_at(loc: tuple[int | str, ...]) -> type[BaseModel] | None:
    """The table model that holds the key at ``loc`` (``None`` if there is none)."""
    model: Any = ScenarioFile
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        model = _model_in(model.model_fields[part].annotation)
        if model is None:
            return None
    return model


def _model_in(annotation: Any) -> type[BaseModel] | None:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = _model_in(arg)
        if found is not None:
            return found
    return None


def _field_bounds(loc: tuple[int | str, ...]) -> dict[str, float]:
    """The ``ge``/``gt``/``le``/``lt`` bounds declared on the field at ``loc``."""
    table = _table_at(tuple(p for p in loc if isinstance(p, str)))
    name = next((p for p in reversed(loc) if isinstance(p, str)), None)
    if table is None or name not in table.model_fields:
        return {}
    bounds: dict[str, float] = {}

    def collect(meta: Any) -> None:
        for kind in ("ge", "gt", "le", "lt"):
            if getattr(meta, kind, None) is not None:
                bounds[kind] = getattr(meta, kind)

    info = table.model_fields[name]
    for meta in info.metadata:
        collect(meta)
    if not bounds:  # bounds on the items of a list: list[Annotated[float, Field(ge=0)]]
        for arg in _walk(info.annotation):
            for meta in getattr(arg, "__metadata__", ()):
                collect(meta)
                for inner in getattr(meta, "metadata", ()):
                    collect(inner)
    return bounds


def _walk(annotation: Any) -> list[Any]:
    out = [annotation]
    for arg in typing.get_args(annotation):
        if not isinstance(arg, (types.NoneType, str)):
            out += _walk(arg)
    return out


def _range(value: Any, loc: tuple[int | str, ...]) -> str:
    b = _field_bounds(loc)
    lo = ("(", b["gt"]) if "gt" in b else ("[", b["ge"]) if "ge" in b else None
    hi = (")", b["lt"]) if "lt" in b else ("]", b["le"]) if "le" in b else None
    got = f"got {_fmt(value)}"
    if lo and hi:
        name = next((p for p in reversed(loc) if isinstance(p, str)), "")
        return f"must lie in {lo[0]}{_fmt(lo[1])}, {_fmt(hi[1])}{hi[0]}{_UNITS.get(name, '')}, {got}"
    if lo:
        return f"must be {'>' if lo[0] == '(' else '>='} {_fmt(lo[1])}, {got}"
    assert hi is not None
    return f"must be {'<' if hi[0] == ')' else '<='} {_fmt(hi[1])}, {got}"


def _message(err: Any) -> tuple[str, str]:
    """(key path, detail) of one pydantic error."""
    loc: tuple[int | str, ...] = tuple(err["loc"])
    kind, value, ctx = err["type"], err.get("input"), err.get("ctx") or {}
    name = next((p for p in reversed(loc) if isinstance(p, str)), "")
    got = f"got {_kind(value)} {_show(value)}"
    if kind == "staghunt":
        return key_path((*loc, ctx["key"])), str(ctx["detail"])
    if kind == "extra_forbidden":
        table = _table_at(loc)
        allowed = ", ".join(table.model_fields) if table is not None else ""
        return key_path(loc), f"unknown key; allowed keys here: {allowed}"
    if kind in _MESSAGES:
        hint = _ARRAY_HINTS.get(str(loc[-1]), "") if kind == "list_type" else ""
        return key_path(loc), _MESSAGES[kind].format(got=got, value=value, expected=ctx.get("expected")) + hint
    if kind in ("too_short", "too_long"):
        if loc == ("team",):
            return "team", "the team needs at least one UAV ([[team]] entry)"
        n = ctx.get("min_length") if kind == "too_short" else ctx.get("max_length")
        what = _VECTORS.get(name)
        expect = f"{what} ({n} numbers)" if what else f"{'at least' if kind == 'too_short' else 'at most'} {n} entries"
        return key_path(loc), f"expected {expect}, got {len(value) if hasattr(value, '__len__') else value} values"
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        return key_path(loc), _range(value, loc)
    return key_path(loc), f"{err['msg']}, {got}"  # not expected: pydantic's own words


def validate(data: Any) -> ScenarioFile:
    """Check plain data (:func:`plain` of a parsed TOML document) against the format; raise
    :class:`ScenarioError` naming the first problem found."""
    if not isinstance(data, Mapping):
        raise ScenarioError(f"expected a table, got {_kind(data)}")
    try:
        return ScenarioFile.model_validate(data)
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
        # An unknown key first: a misspelt key also shows as a missing one.
        first = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
        key, detail = _message(first)
        raise ScenarioError(detail, key or None) from None
