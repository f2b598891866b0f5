"""Scenario files: TOML in, a validated frozen :class:`Scenario` out (and back to plain data).

The format is documented in ``docs/scenario-format.md``. Validation happens here, once, so the
rest of the package can trust a :class:`Scenario`. Every failure raises :class:`ScenarioError`
with one line that names the offending key path, e.g.
``team[2].start: (5.0, 50.0, 20.0) lies inside obstacle 'crane 1' (x=40, y=48, R=4) plus body
radius 1``. Array-of-tables entries (``team``, ``obstacles``) are indexed from 0 in key paths.

In the plain-data form (:func:`scenario_from_dict`, :func:`scenario_to_dict`) a key whose value
is ``None`` counts as absent, so the ``None`` that :func:`scenario_to_dict` writes for an unset
``costs.desired_height`` reads back as "use the default".
"""

from __future__ import annotations

import hashlib
import math
import numbers
import os
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import fields
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from staghunt.scenario.model import CostParams, Scenario, SolverSettings
from staghunt.task import UAV, Formation, VehicleLimits, Weights, is_connected
from staghunt.world import Bounds, Cylinder, GeoOrigin, Terrain, World

__all__ = [
    "ScenarioError",
    "builtin_names",
    "builtin_path",
    "load_scenario",
    "scenario_from_dict",
    "scenario_to_dict",
]

_BUILTIN_PACKAGE = "staghunt.scenario.builtin"

# Allowed keys of every table, in the order the documentation lists them.
TOP_KEYS = (
    "name", "description", "site", "origin", "ground", "obstacles", "team", "formation", "costs",
    "solver", "vehicle",
)
ORIGIN_KEYS = ("latitude", "longitude", "altitude")
VEHICLE_KEYS = tuple(f.name for f in fields(VehicleLimits))
SITE_KEYS = ("xmin", "xmax", "ymin", "ymax", "hmin", "hmax")
GROUND_FLAT_KEYS = ("kind",)
GROUND_DEM_KEYS = ("kind", "file", "origin", "cell_size", "sampling", "shape", "dtype", "sha256")
OBSTACLE_KEYS = ("x", "y", "radius", "name")
UAV_KEYS = ("name", "start", "goal", "radius", "beta", "weights")
FORMATION_KEYS = ("incidence", "edge_weights", "reference")
COST_KEYS = tuple(f.name for f in fields(CostParams))
SOLVER_KEYS = tuple(f.name for f in fields(SolverSettings))
GROUND_KINDS = ("flat", "dem")
SAMPLINGS = ("nearest", "bilinear")
DEM_SUFFIXES = (".npy", ".tif", ".tiff")

_MISSING: Any = object()


class ScenarioError(ValueError):
    """An invalid scenario: one human-readable line naming the offending key path.

    ``detail`` is the explanation, ``key`` the TOML key path (``None`` for file-level problems)
    and ``source`` the file the scenario came from, if any. ``str(error)`` joins them as
    ``"source: key: detail"``.
    """

    def __init__(self, detail: str, key: str | None = None, source: str | None = None) -> None:
        self.detail = detail
        self.key = key
        self.source = source
        parts = [p for p in (source, key) if p]
        super().__init__(": ".join([*parts, detail]))

    def __reduce__(self) -> tuple[Any, ...]:
        return (self.__class__, (self.detail, self.key, self.source))


# --------------------------------------------------------------------------------------------
# Built-ins and files
# --------------------------------------------------------------------------------------------


def builtin_names() -> list[str]:
    """Names of the scenarios shipped with the package (``scenario1``, ``scenario2``), sorted."""
    root = resources.files(_BUILTIN_PACKAGE)
    return sorted(p.name[: -len(".toml")] for p in root.iterdir() if p.name.endswith(".toml"))


def builtin_path(name: str) -> Path:
    """Path of the built-in scenario file ``name`` (e.g. ``"scenario1"``)."""
    if name not in builtin_names():
        raise ScenarioError(
            f"no built-in scenario {name!r}; built-in scenarios: {', '.join(builtin_names())}"
        )
    return Path(str(resources.files(_BUILTIN_PACKAGE).joinpath(f"{name}.toml")))


def load_scenario(source: str | os.PathLike[str]) -> Scenario:
    """Load and validate a scenario.

    ``source`` is a built-in name (see :func:`builtin_names`) or a path to a ``.toml`` file.
    Relative DEM paths inside the file are resolved against the file's directory. The scenario's
    name defaults to the file's stem. Raises :class:`ScenarioError` on any problem.
    """
    text = os.fspath(source)
    if isinstance(source, str) and text in builtin_names():
        path = builtin_path(text)
    else:
        path = Path(text)
        if not path.is_file():
            raise ScenarioError(
                f"no such scenario file {text!r} "
                f"(built-in scenarios: {', '.join(builtin_names())})"
            )
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"invalid TOML: {exc}", source=str(path)) from None
    except OSError as exc:
        raise ScenarioError(f"cannot read file: {exc.strerror or exc}", source=str(path)) from None
    try:
        return scenario_from_dict(data, name=path.stem, base_dir=path.parent)
    except ScenarioError as exc:
        raise ScenarioError(exc.detail, exc.key, str(path)) from None


# --------------------------------------------------------------------------------------------
# Primitive readers: each takes the value and its key path, returns a clean Python value
# --------------------------------------------------------------------------------------------


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


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
    if isinstance(value, (list, tuple, np.ndarray)):
        return "an array"
    return f"a {type(value).__name__}"


def _show(value: object) -> str:
    """``repr`` of a value for messages, cut to a readable length."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _fmt(v: float) -> str:
    """Compact number for messages: ``40`` rather than ``40.0``, full precision otherwise."""
    return f"{v:.12g}"


def _table(value: object, path: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise ScenarioError(f"expected a table, got {_kind(value)}", path)
    return value


def _check_keys(table: Mapping[str, Any], path: str, allowed: Sequence[str]) -> None:
    for key in table:
        if key not in allowed:
            where = _join(path, str(key))
            raise ScenarioError(f"unknown key; allowed keys here: {', '.join(allowed)}", where)


def _get(table: Mapping[str, Any], key: str, path: str, default: Any = _MISSING) -> Any:
    """``table[key]``; ``None`` counts as absent. Without a default, absence is an error."""
    value = table.get(key)
    if value is None:
        if default is _MISSING:
            raise ScenarioError("required key is missing", _join(path, key))
        return default
    return value


def _number(value: object, path: str) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ScenarioError(f"expected a number, got {_kind(value)} {_show(value)}", path)
    out = float(value)
    if not math.isfinite(out):
        raise ScenarioError(f"must be a finite number, got {out}", path)
    return out


def _integer(value: object, path: str) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise ScenarioError(f"expected an integer, got {_kind(value)} {_show(value)}", path)
    return int(value)


def _string(value: object, path: str) -> str:
    if not isinstance(value, str):
        raise ScenarioError(f"expected a string, got {_kind(value)} {_show(value)}", path)
    return value


def _boolean(value: object, path: str) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise ScenarioError(f"expected true or false, got {_kind(value)} {_show(value)}", path)
    return bool(value)


def _array(value: object, path: str, hint: str = "") -> list[Any]:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)):
        raise ScenarioError(f"expected an array, got {_kind(value)} {_show(value)}{hint}", path)
    return list(value)


def _vector(value: object, path: str, length: int, what: str) -> tuple[float, ...]:
    items = _array(value, path)
    if len(items) != length:
        raise ScenarioError(f"expected {what} ({length} numbers), got {len(items)} values", path)
    return tuple(_number(v, f"{path}[{i}]") for i, v in enumerate(items))


def _matrix(value: object, path: str) -> np.ndarray:
    """A rectangular array of arrays of finite numbers -> ``(rows, cols)`` float64 array."""
    rows = _array(value, path)
    out: list[list[float]] = []
    for i, row in enumerate(rows):
        items = _array(row, f"{path}[{i}]")
        if out and len(items) != len(out[0]):
            raise ScenarioError(
                f"rows must all have the same length; row 0 has {len(out[0])}, "
                f"row {i} has {len(items)}",
                path,
            )
        out.append([_number(v, f"{path}[{i}][{j}]") for j, v in enumerate(items)])
    ncols = len(out[0]) if out else 0
    return np.array(out, dtype=float).reshape(len(out), ncols)


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, copy=True, order="C")
    a.setflags(write=False)
    return a


def _at_least(v: float, low: float, path: str, *, strict: bool = False) -> float:
    if v < low or (strict and v == low):
        sign = ">" if strict else ">="
        raise ScenarioError(f"must be {sign} {_fmt(low)}, got {_fmt(v)}", path)
    return v


# --------------------------------------------------------------------------------------------
# Sections
# --------------------------------------------------------------------------------------------


def _read_site(data: Mapping[str, Any]) -> Bounds:
    site = _table(_get(data, "site", ""), "site")
    _check_keys(site, "site", SITE_KEYS)
    v = {k: _number(_get(site, k, "site"), f"site.{k}") for k in SITE_KEYS}
    for lo, hi in (("xmin", "xmax"), ("ymin", "ymax")):
        if v[lo] >= v[hi]:
            raise ScenarioError(
                f"must be greater than site.{lo} = {_fmt(v[lo])}, got {_fmt(v[hi])}", f"site.{hi}"
            )
    _at_least(v["hmin"], 0.0, "site.hmin")
    if v["hmin"] > v["hmax"]:
        raise ScenarioError(
            f"must be >= site.hmin = {_fmt(v['hmin'])}, got {_fmt(v['hmax'])}", "site.hmax"
        )
    return Bounds(**v)


def _read_dem_array(path: Path, key: str) -> np.ndarray:
    """Load a DEM grid from ``.npy`` or GeoTIFF; 2-D, finite, read-only, float32 or float64."""
    suffix = path.suffix.lower()
    if suffix not in DEM_SUFFIXES:
        raise ScenarioError(
            f"unsupported DEM file type {path.suffix!r} of {str(path)!r}; "
            f"use one of {', '.join(DEM_SUFFIXES)}",
            key,
        )
    if not path.is_file():
        raise ScenarioError(f"no such DEM file {str(path)!r}", key)
    try:
        if suffix == ".npy":
            raw = np.load(path, allow_pickle=False)
        else:
            try:
                import tifffile  # optional dependency, imported only when needed
            except ImportError:
                raise ScenarioError(
                    "reading a GeoTIFF DEM needs the optional 'tifffile' package: "
                    "pip install staghunt[geotiff]",
                    key,
                ) from None
            raw = tifffile.imread(path)
    except ScenarioError:
        raise
    except Exception as exc:  # corrupt file, pickled object array, unreadable TIFF...
        raise ScenarioError(f"cannot read DEM file {str(path)!r}: {exc}", key) from None
    raw = np.asarray(raw)
    if raw.ndim != 2 or raw.size == 0:
        raise ScenarioError(
            f"DEM in {str(path)!r} must be a non-empty 2-D grid, got shape {raw.shape}", key
        )
    if raw.dtype.kind not in "iuf":
        raise ScenarioError(f"DEM in {str(path)!r} must be numeric, got dtype {raw.dtype}", key)
    dtype = np.float32 if raw.dtype == np.float32 else np.float64
    grid = np.array(raw, dtype=dtype, copy=True, order="C")
    if not np.all(np.isfinite(grid)):
        bad = np.argwhere(~np.isfinite(grid))[0]
        raise ScenarioError(
            f"DEM in {str(path)!r} holds a non-finite value at row {bad[0]}, column {bad[1]}", key
        )
    grid.setflags(write=False)
    return grid


def _grid_digest(grid: np.ndarray) -> str:
    """SHA-256 of the grid's C-order bytes (dtype as stored)."""
    return hashlib.sha256(np.ascontiguousarray(grid).tobytes()).hexdigest()


def _read_ground(data: Mapping[str, Any], base_dir: Path | None, bounds: Bounds) -> Terrain:
    ground = _table(_get(data, "ground", "", {}), "ground")
    kind = _string(_get(ground, "kind", "ground", "flat"), "ground.kind")
    if kind not in GROUND_KINDS:
        raise ScenarioError(
            f"must be one of {', '.join(repr(k) for k in GROUND_KINDS)}, got {kind!r}",
            "ground.kind",
        )
    if kind == "flat":
        _check_keys(ground, "ground", GROUND_DEM_KEYS)
        for key in ground:
            if key not in GROUND_FLAT_KEYS and ground[key] is not None:
                raise ScenarioError(
                    "only used with kind = 'dem'; flat ground takes no other key than 'kind'",
                    f"ground.{key}",
                )
        return Terrain()
    _check_keys(ground, "ground", GROUND_DEM_KEYS)
    file_text = _string(_get(ground, "file", "ground"), "ground.file")
    file = Path(file_text).expanduser()
    if not file.is_absolute() and base_dir is not None:
        file = base_dir / file
    file = file.resolve()
    origin = _vector(_get(ground, "origin", "ground", [0.0, 0.0]), "ground.origin", 2, "[x0, y0]")
    cell = _at_least(
        _number(_get(ground, "cell_size", "ground", 1.0), "ground.cell_size"),
        0.0,
        "ground.cell_size",
        strict=True,
    )
    sampling = _string(_get(ground, "sampling", "ground", "nearest"), "ground.sampling")
    if sampling not in SAMPLINGS:
        raise ScenarioError(
            f"must be one of {', '.join(repr(s) for s in SAMPLINGS)}, got {sampling!r}",
            "ground.sampling",
        )
    grid = _read_dem_array(file, "ground.file")
    # Optional integrity checks (scenario_to_dict writes them).
    if ground.get("shape") is not None:
        shape = tuple(
            _integer(v, f"ground.shape[{i}]")
            for i, v in enumerate(_array(ground["shape"], "ground.shape"))
        )
        if shape != grid.shape:
            raise ScenarioError(
                f"the DEM file {str(file)!r} has shape {list(grid.shape)}, not {list(shape)}",
                "ground.shape",
            )
    if ground.get("dtype") is not None:
        dtype = _string(ground["dtype"], "ground.dtype")
        if dtype != grid.dtype.name:
            raise ScenarioError(
                f"the DEM grid has dtype {grid.dtype.name!r}, not {dtype!r}", "ground.dtype"
            )
    if ground.get("sha256") is not None:
        digest = _string(ground["sha256"], "ground.sha256")
        if digest.lower() != _grid_digest(grid):
            raise ScenarioError(
                f"the DEM grid in {str(file)!r} does not match this checksum (file changed?)",
                "ground.sha256",
            )
    terrain = Terrain(
        elevation=grid,
        origin=(origin[0], origin[1]),
        cell_size=cell,
        sampling=sampling,  # type: ignore[arg-type]
        source=str(file),
    )
    _check_dem_covers(terrain, bounds)
    return terrain


def _check_dem_covers(terrain: Terrain, b: Bounds) -> None:
    """The DEM must cover the site box: cell centres for bilinear sampling, cells for nearest."""
    extent = terrain.extent()
    assert extent is not None and terrain.elevation is not None
    x0, x1, y0, y1 = extent
    slack = 0.5 * terrain.cell_size if terrain.sampling == "nearest" else 0.0
    rows, cols = terrain.elevation.shape
    eps = 1e-9 * max(1.0, abs(b.xmin), abs(b.xmax), abs(b.ymin), abs(b.ymax))
    if x0 - slack > b.xmin + eps or x1 + slack < b.xmax - eps or (
        y0 - slack > b.ymin + eps or y1 + slack < b.ymax - eps
    ):
        what = "cells" if slack else "cell centres"
        raise ScenarioError(
            f"the DEM ({rows} rows x {cols} columns, {what} spanning "
            f"x [{_fmt(x0 - slack)}, {_fmt(x1 + slack)}], "
            f"y [{_fmt(y0 - slack)}, {_fmt(y1 + slack)}]) "
            f"does not cover the site box x [{_fmt(b.xmin)}, {_fmt(b.xmax)}], "
            f"y [{_fmt(b.ymin)}, {_fmt(b.ymax)}]; check ground.origin and ground.cell_size",
            "ground",
        )


def _read_obstacles(data: Mapping[str, Any]) -> tuple[Cylinder, ...]:
    items = _array(
        _get(data, "obstacles", "", []), "obstacles", " (write [[obstacles]] for each obstacle)"
    )
    out = []
    for i, item in enumerate(items):
        path = f"obstacles[{i}]"
        t = _table(item, path)
        _check_keys(t, path, OBSTACLE_KEYS)
        x = _number(_get(t, "x", path), f"{path}.x")
        y = _number(_get(t, "y", path), f"{path}.y")
        r = _number(_get(t, "radius", path), f"{path}.radius")
        _at_least(r, 0.0, f"{path}.radius", strict=True)
        name = _string(_get(t, "name", path, ""), f"{path}.name")
        out.append(Cylinder(x=x, y=y, radius=r, name=name))
    return tuple(out)


def _read_team(data: Mapping[str, Any]) -> tuple[UAV, ...]:
    items = _array(_get(data, "team", ""), "team", " (write [[team]] for each UAV)")
    if not items:
        raise ScenarioError("the team needs at least one UAV ([[team]] entry)", "team")
    team: list[UAV] = []
    seen: dict[str, int] = {}
    for i, item in enumerate(items):
        path = f"team[{i}]"
        t = _table(item, path)
        _check_keys(t, path, UAV_KEYS)
        name = _string(_get(t, "name", path, f"UAV{i + 1}"), f"{path}.name")
        if not name.strip():
            raise ScenarioError("must not be empty", f"{path}.name")
        if name in seen:
            raise ScenarioError(
                f"{name!r} is already the name of team[{seen[name]}]", f"{path}.name"
            )
        seen[name] = i
        start = _vector(_get(t, "start", path), f"{path}.start", 3, "[x, y, h]")
        goal = _vector(_get(t, "goal", path), f"{path}.goal", 3, "[x, y, h]")
        radius = _number(_get(t, "radius", path), f"{path}.radius")
        _at_least(radius, 0.0, f"{path}.radius")
        beta = _at_least(_number(_get(t, "beta", path), f"{path}.beta"), 0.0, f"{path}.beta")
        w = _vector(_get(t, "weights", path), f"{path}.weights", 5, "[w1, w2, w3, w4, w5]")
        for j, wj in enumerate(w):
            _at_least(wj, 0.0, f"{path}.weights[{j}]")
        if start == goal:
            raise ScenarioError(f"equals the start {start}; a path needs two ends", f"{path}.goal")
        team.append(
            UAV(
                name=name,
                start=(start[0], start[1], start[2]),
                goal=(goal[0], goal[1], goal[2]),
                radius=radius,
                weights=Weights(beta, w[0], w[1], w[2], w[3], w[4]),
            )
        )
    return tuple(team)


def _check_team_in_world(team: Sequence[UAV], world: World, costs: CostParams) -> None:
    """Starts and goals inside the site box, clear of obstacles, and apart from each other."""
    b = world.bounds
    for end in ("start", "goal"):
        for i, u in enumerate(team):
            p: tuple[float, float, float] = getattr(u, end)
            key = f"team[{i}].{end}"
            if not (b.contains_xy(p[0], p[1]) and b.hmin <= p[2] <= b.hmax):
                raise ScenarioError(
                    f"{p} of {u.name!r} lies outside the site box "
                    f"x [{_fmt(b.xmin)}, {_fmt(b.xmax)}], "
                    f"y [{_fmt(b.ymin)}, {_fmt(b.ymax)}], h [{_fmt(b.hmin)}, {_fmt(b.hmax)}]",
                    key,
                )
            for k, c in enumerate(world.cylinders):
                if math.hypot(p[0] - c.x, p[1] - c.y) < c.radius + u.radius:
                    label = repr(c.name) if c.name else f"obstacles[{k}]"
                    raise ScenarioError(
                        f"{p} of {u.name!r} lies inside obstacle {label} "
                        f"(x={_fmt(c.x)}, y={_fmt(c.y)}, R={_fmt(c.radius)}) "
                        f"plus body radius {_fmt(u.radius)}",
                        key,
                    )
        pts = np.array([getattr(u, end) for u in team], dtype=float)
        z = world.terrain.absolute(pts[:, 0], pts[:, 1], pts[:, 2])
        absolute = np.column_stack([pts[:, 0], pts[:, 1], z])
        for i in range(len(team)):
            for j in range(i + 1, len(team)):
                dist = float(np.linalg.norm(absolute[i] - absolute[j]))
                limit = costs.safe_distance + 2.0 * max(team[i].radius, team[j].radius)
                if dist <= limit:
                    raise ScenarioError(
                        f"{team[j].name!r} {end} is {_fmt(dist)} m from {team[i].name!r} {end} "
                        f"(team[{i}].{end}); it must be more than costs.safe_distance + 2 * radius "
                        f"= {_fmt(limit)} m",
                        f"team[{j}].{end}",
                    )


def _read_formation(data: Mapping[str, Any], team: Sequence[UAV], terrain: Terrain) -> Formation:
    n = len(team)
    goals = np.array([u.goal for u in team], dtype=float)
    default_ref = np.column_stack(
        [goals[:, 0], goals[:, 1], terrain.absolute(goals[:, 0], goals[:, 1], goals[:, 2])]
    )
    raw = _get(data, "formation", "", None)
    if raw is None:
        if n >= 2:
            raise ScenarioError(
                f"required for a team of {n} UAVs (give incidence and edge_weights)", "formation"
            )
        empty = np.zeros((n, 0))
        return Formation(_frozen(empty), _frozen(empty), _frozen(default_ref))
    t = _table(raw, "formation")
    _check_keys(t, "formation", FORMATION_KEYS)
    inc = _matrix(_get(t, "incidence", "formation"), "formation.incidence")
    if inc.shape[0] != n:
        raise ScenarioError(
            f"must have one row per UAV ({n} rows, N x M), got {inc.shape[0]} rows",
            "formation.incidence",
        )
    m = inc.shape[1]
    for e in range(m):
        col = inc[:, e]
        ok = (
            np.all(np.isin(col, (-1.0, 0.0, 1.0)))
            and np.count_nonzero(col == 1.0) == 1
            and np.count_nonzero(col == -1.0) == 1
        )
        if not ok:
            raise ScenarioError(
                f"column {e} (edge {e}) is [{', '.join(_fmt(v) for v in col)}]; each column "
                f"must hold exactly one +1 (head) and one -1 (tail), the rest 0",
                "formation.incidence",
            )
    mu = _matrix(_get(t, "edge_weights", "formation"), "formation.edge_weights")
    if mu.shape != inc.shape:
        raise ScenarioError(
            f"must have the incidence matrix's shape {n} x {m}, got {mu.shape[0]} x {mu.shape[1]}",
            "formation.edge_weights",
        )
    if np.any(mu < 0):
        i, e = np.argwhere(mu < 0)[0]
        raise ScenarioError(
            f"must be >= 0, got {_fmt(mu[i, e])}", f"formation.edge_weights[{i}][{e}]"
        )
    if n >= 2 and not is_connected(inc):
        raise ScenarioError(
            "the formation graph is not connected; every UAV must be linked to the others "
            "through edges",
            "formation.incidence",
        )
    ref_raw = _get(t, "reference", "formation", None)
    if ref_raw is None:
        ref = default_ref
    else:
        ref = _matrix(ref_raw, "formation.reference")
        if ref.shape != (n, 3):
            raise ScenarioError(
                f"must be N x 3 = {n} x 3 ([x, y, z] per UAV, absolute), got "
                f"{ref.shape[0]} x {ref.shape[1]}",
                "formation.reference",
            )
    return Formation(incidence=_frozen(inc), edge_weights=_frozen(mu), reference=_frozen(ref))


def _read_costs(data: Mapping[str, Any]) -> CostParams:
    t = _table(_get(data, "costs", "", {}), "costs")
    _check_keys(t, "costs", COST_KEYS)
    d = CostParams()
    margin = _number(_get(t, "danger_margin", "costs", d.danger_margin), "costs.danger_margin")
    safe = _number(_get(t, "safe_distance", "costs", d.safe_distance), "costs.safe_distance")
    _at_least(margin, 0.0, "costs.danger_margin")
    _at_least(safe, 0.0, "costs.safe_distance")
    thresholds = {}
    for key in ("turning_threshold_deg", "climb_threshold_deg"):
        v = _number(_get(t, key, "costs", getattr(d, key)), f"costs.{key}")
        if not 0.0 <= v <= 180.0:
            raise ScenarioError(f"must lie in [0, 180] degrees, got {_fmt(v)}", f"costs.{key}")
        thresholds[key] = v
    desired = _get(t, "desired_height", "costs", None)
    desired_h = None if desired is None else _number(desired, "costs.desired_height")
    cont = _boolean(
        _get(t, "continuous_separation", "costs", d.continuous_separation),
        "costs.continuous_separation",
    )
    clearance = _number(_get(t, "min_clearance", "costs", d.min_clearance), "costs.min_clearance")
    _at_least(clearance, 0.0, "costs.min_clearance")
    return CostParams(
        danger_margin=margin,
        safe_distance=safe,
        desired_height=desired_h,
        continuous_separation=cont,
        min_clearance=clearance,
        **thresholds,
    )


def _read_origin(data: Mapping[str, Any]) -> GeoOrigin | None:
    raw = _get(data, "origin", "", None)
    if raw is None:
        return None
    t = _table(raw, "origin")
    _check_keys(t, "origin", ORIGIN_KEYS)
    lat = _number(_get(t, "latitude", "origin"), "origin.latitude")
    lon = _number(_get(t, "longitude", "origin"), "origin.longitude")
    alt = _number(_get(t, "altitude", "origin"), "origin.altitude")
    if not -90.0 <= lat <= 90.0:
        raise ScenarioError(f"must lie in [-90, 90] degrees, got {_fmt(lat)}", "origin.latitude")
    if not -180.0 <= lon <= 180.0:
        raise ScenarioError(f"must lie in [-180, 180] degrees, got {_fmt(lon)}", "origin.longitude")
    if not -500.0 <= alt <= 10000.0:
        raise ScenarioError(f"must lie in [-500, 10000] m above mean sea level, got {_fmt(alt)}",
                            "origin.altitude")
    return GeoOrigin(latitude=lat, longitude=lon, altitude=alt)


def _read_vehicle(data: Mapping[str, Any]) -> VehicleLimits:
    t = _table(_get(data, "vehicle", "", {}), "vehicle")
    _check_keys(t, "vehicle", VEHICLE_KEYS)
    d = VehicleLimits()
    values = {}
    for key in VEHICLE_KEYS:
        v = _number(_get(t, key, "vehicle", getattr(d, key)), f"vehicle.{key}")
        values[key] = _at_least(v, 0.0, f"vehicle.{key}", strict=True)
    if values["cruise_speed"] > values["max_speed"]:
        raise ScenarioError(
            f"must not exceed vehicle.max_speed ({_fmt(values['max_speed'])} m/s), got "
            f"{_fmt(values['cruise_speed'])}", "vehicle.cruise_speed")
    return VehicleLimits(**values)


def _read_solver(data: Mapping[str, Any]) -> SolverSettings:
    t = _table(_get(data, "solver", "", {}), "solver")
    _check_keys(t, "solver", SOLVER_KEYS)
    d = SolverSettings()

    def integer(key: str, low: int) -> int:
        v = _integer(_get(t, key, "solver", getattr(d, key)), f"solver.{key}")
        if v < low:
            raise ScenarioError(f"must be >= {low}, got {v}", f"solver.{key}")
        return v

    def real(key: str) -> float:
        v = _number(_get(t, key, "solver", getattr(d, key)), f"solver.{key}")
        return _at_least(v, 0.0, f"solver.{key}")

    frac = _number(
        _get(t, "velocity_fraction", "solver", d.velocity_fraction), "solver.velocity_fraction"
    )
    if not 0.0 < frac <= 1.0:
        raise ScenarioError(f"must lie in (0, 1], got {_fmt(frac)}", "solver.velocity_fraction")
    return SolverSettings(
        particles=integer("particles", 1),
        iterations=integer("iterations", 0),
        waypoints=integer("waypoints", 1),
        c0=real("c0"),
        damping=real("damping"),
        c1=real("c1"),
        c2=real("c2"),
        velocity_fraction=frac,
    )


# --------------------------------------------------------------------------------------------
# Public conversions
# --------------------------------------------------------------------------------------------


def scenario_from_dict(
    data: Mapping[str, Any], *, name: str, base_dir: Path | None = None
) -> Scenario:
    """Validate plain data (a parsed TOML document, or :func:`scenario_to_dict`'s output).

    ``name`` is used when ``data`` has no ``name`` key; ``base_dir`` anchors a relative
    ``ground.file`` (``None``: the current directory). Raises :class:`ScenarioError`.
    """
    data = _table(data, "")
    _check_keys(data, "", TOP_KEYS)
    scenario_name = _string(_get(data, "name", "", name), "name")
    if not scenario_name.strip():
        raise ScenarioError("must not be empty", "name")
    description = _string(_get(data, "description", "", ""), "description")
    bounds = _read_site(data)
    terrain = _read_ground(data, base_dir, bounds)
    cylinders = _read_obstacles(data)
    world = World(bounds=bounds, terrain=terrain, cylinders=cylinders)
    costs = _read_costs(data)
    solver = _read_solver(data)
    team = _read_team(data)
    _check_team_in_world(team, world, costs)
    formation = _read_formation(data, team, terrain)
    return Scenario(
        name=scenario_name,
        description=description,
        world=world,
        team=team,
        formation=formation,
        costs=costs,
        solver=solver,
        origin=_read_origin(data),
        vehicle=_read_vehicle(data),
    )


def _floats(a: np.ndarray) -> list[Any]:
    return np.asarray(a, dtype=float).tolist()


def scenario_to_dict(scenario: Scenario) -> dict[str, Any]:
    """The scenario as plain JSON-able data in the TOML layout (all defaults filled in).

    A DEM appears as a reference to its file (absolute path) with its shape, dtype, SHA-256,
    origin, cell size and sampling, not as the grid. ``scenario_from_dict`` of the result
    rebuilds an equal scenario (its DEM read again from the file and checked against the
    shape, dtype and checksum).
    """
    w = scenario.world
    b = w.bounds
    terrain = w.terrain
    ground: dict[str, Any]
    if terrain.elevation is None:
        ground = {"kind": "flat"}
    else:
        ground = {
            "kind": "dem",
            "file": terrain.source,
            "origin": [float(terrain.origin[0]), float(terrain.origin[1])],
            "cell_size": float(terrain.cell_size),
            "sampling": terrain.sampling,
            "shape": [int(s) for s in terrain.elevation.shape],
            "dtype": terrain.elevation.dtype.name,
            "sha256": _grid_digest(terrain.elevation),
        }
    c = scenario.costs
    s = scenario.solver
    f = scenario.formation
    o = scenario.origin
    return {
        "name": scenario.name,
        "description": scenario.description,
        "site": {k: float(getattr(b, k)) for k in SITE_KEYS},
        "ground": ground,
        "obstacles": [
            {"x": float(o.x), "y": float(o.y), "radius": float(o.radius), "name": o.name}
            for o in w.cylinders
        ],
        "team": [
            {
                "name": u.name,
                "start": [float(v) for v in u.start],
                "goal": [float(v) for v in u.goal],
                "radius": float(u.radius),
                "beta": float(u.weights.beta),
                "weights": _floats(u.weights.as_array()),
            }
            for u in scenario.team
        ],
        "formation": {
            "incidence": np.asarray(f.incidence).astype(int).tolist(),
            "edge_weights": _floats(f.edge_weights),
            "reference": _floats(f.reference),
        },
        "costs": {
            "danger_margin": float(c.danger_margin),
            "safe_distance": float(c.safe_distance),
            "turning_threshold_deg": float(c.turning_threshold_deg),
            "climb_threshold_deg": float(c.climb_threshold_deg),
            "desired_height": None if c.desired_height is None else float(c.desired_height),
            "continuous_separation": bool(c.continuous_separation),
            "min_clearance": float(c.min_clearance),
        },
        "solver": {
            "particles": int(s.particles),
            "iterations": int(s.iterations),
            "waypoints": int(s.waypoints),
            "c0": float(s.c0),
            "damping": float(s.damping),
            "c1": float(s.c1),
            "c2": float(s.c2),
            "velocity_fraction": float(s.velocity_fraction),
        },
        "origin": None if o is None else {
            "latitude": float(o.latitude), "longitude": float(o.longitude), "altitude": float(o.altitude)
        },
        "vehicle": {k: float(getattr(scenario.vehicle, k)) for k in VEHICLE_KEYS},
    }
