"""Scenario files: TOML in, a validated frozen :class:`Scenario` out (and back to plain data).

The format is documented in ``docs/scenario-format.md`` and declared in
:mod:`staghunt.scenario.schema` (types, required keys, ranges, defaults). This module parses the
TOML, has the schema check it, then builds the :class:`Scenario`, making the checks that involve
more than one table (starts and goals inside the site and clear of obstacles and of each other,
the formation matrices against the team, a DEM that covers the site). Every failure raises
:class:`ScenarioError` with one line that names the offending key path, e.g.
``team[2].start: (5.0, 50.0, 20.0) lies inside obstacle 'crane 1' (x=40, y=48, R=4) plus body
radius 1``. Array-of-tables entries (``team``, ``obstacles``) are indexed from 0 in key paths.

In the plain-data form (:func:`scenario_from_dict`, :func:`scenario_to_dict`) a key whose value
is ``None`` counts as absent, so the ``None`` that :func:`scenario_to_dict` writes for an unset
``costs.desired_height`` reads back as "use the default".
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from staghunt.scenario.dem import (
    check_dem_covers,
    file_digest,
    grid_digest,
    read_dem_array,
    read_geotiff_terrain,
    resolve_file,
)
from staghunt.scenario.errors import ScenarioError, fmt
from staghunt.scenario.model import CostParams, Scenario, SolverSettings
from staghunt.task import UAV, Formation, VehicleLimits, Weights, is_connected
from staghunt.world import Bounds, Cylinder, GeoOrigin, Terrain, World, prism_arrays
from staghunt.world.geometry import prism_distance

if TYPE_CHECKING:
    from staghunt.scenario.schema import Fleet, FormationTable, Ground, Uav

__all__ = [
    "ScenarioError",
    "builtin_names",
    "builtin_path",
    "load_scenario",
    "scenario_from_dict",
]

_BUILTIN_PACKAGE = "staghunt.scenario.builtin"


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


def load_scenario(source: str | os.PathLike[str], objectives: str | os.PathLike[str] | None = None) -> Scenario:
    """Load and validate a scenario.

    ``source`` is a built-in name (see :func:`builtin_names`) or a path to a ``.toml`` file.
    Relative DEM paths inside the file are resolved against the file's directory. The scenario's
    name defaults to the file's stem. ``objectives``: an objectives file (TOML) whose tables
    replace the scenario's camera, payload, capture settings and objectives
    (:func:`staghunt.scenario.objectives_file.with_objectives`; its relative GeoJSON paths are
    resolved against its own directory). Raises :class:`ScenarioError` on any problem.
    """
    from staghunt.inputs import clip, describe_path, parse_toml, read_text

    text = os.fspath(source)
    if isinstance(source, str) and text in builtin_names():
        path = builtin_path(text)
    else:
        path = Path(text)
        if not text or describe_path(text).startswith("no such file"):
            raise ScenarioError(
                f"no such scenario file {clip(repr(text))} "
                f"(built-in scenarios: {', '.join(builtin_names())})"
            )
    try:  # read once: a FIFO (<(cat scenario.toml)) has no second chance
        data = parse_toml(read_text(path, "scenario file (TOML)"), str(path))
    except ValueError as exc:
        raise ScenarioError(str(exc)) from None
    if objectives is not None:
        from staghunt.scenario.objectives_file import with_objectives

        return with_objectives(data, objectives, name=path.stem, base_dir=path.parent, source=str(path))
    try:
        return scenario_from_dict(data, name=path.stem, base_dir=path.parent)
    except ScenarioError as exc:
        raise ScenarioError(exc.detail, exc.key, str(path)) from None


# --------------------------------------------------------------------------------------------
# Conversion of the checked tables, with the checks across tables
# --------------------------------------------------------------------------------------------


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, copy=True, order="C")
    a.setflags(write=False)
    return a


def _matrix(rows: list[list[float]], path: str) -> np.ndarray:
    """A rectangular array of arrays of numbers -> ``(rows, cols)`` float64 array."""
    for i, row in enumerate(rows):
        if len(row) != len(rows[0]):
            raise ScenarioError(
                f"rows must all have the same length; row 0 has {len(rows[0])}, "
                f"row {i} has {len(row)}",
                path,
            )
    ncols = len(rows[0]) if rows else 0
    return np.array(rows, dtype=float).reshape(len(rows), ncols)


def _terrain(ground: Ground, base_dir: Path | None, bounds: Bounds, origin: GeoOrigin | None = None) -> Terrain:
    if ground.kind == "flat":
        return Terrain()
    assert ground.file is not None
    file = Path(ground.file).expanduser()
    if not file.is_absolute() and base_dir is not None:
        file = base_dir / file
    file = resolve_file(file, "ground.file", "the DEM file")
    if ground.kind == "geotiff":
        if origin is None:
            raise ScenarioError("kind = 'geotiff' needs the [origin] table (the site frame's geodetic origin)",
                                "ground.kind")
        terrain = read_geotiff_terrain(file, origin, bounds, ground.cell_size, ground.sampling,
                                       ground.nodata_fill, "ground.file")
        assert terrain.georef is not None
        if ground.sha256 is not None and ground.sha256.lower() != file_digest(file, "ground.file"):
            raise ScenarioError(
                f"the GeoTIFF {str(file)!r} does not match this checksum (file changed?)", "ground.sha256")
        return terrain
    grid = read_dem_array(file, "ground.file")
    # Optional integrity checks (scenario_to_dict writes them).
    if ground.shape is not None and tuple(ground.shape) != grid.shape:
        raise ScenarioError(
            f"the DEM file {str(file)!r} has shape {list(grid.shape)}, not {list(ground.shape)}",
            "ground.shape",
        )
    if ground.dtype is not None and ground.dtype != grid.dtype.name:
        raise ScenarioError(
            f"the DEM grid has dtype {grid.dtype.name!r}, not {ground.dtype!r}", "ground.dtype"
        )
    if ground.sha256 is not None and ground.sha256.lower() != grid_digest(grid):
        raise ScenarioError(
            f"the DEM grid in {str(file)!r} does not match this checksum (file changed?)",
            "ground.sha256",
        )
    terrain = Terrain(
        elevation=grid,
        origin=(ground.origin[0], ground.origin[1]),
        cell_size=ground.cell_size,
        sampling=ground.sampling,
        source=str(file),
    )
    check_dem_covers(terrain, bounds)
    return terrain


def _team(items: Sequence[Uav]) -> tuple[UAV, ...]:
    team: list[UAV] = []
    seen: dict[str, int] = {}
    for i, u in enumerate(items):
        name = u.name if u.name is not None else f"UAV{i + 1}"
        if name in seen:
            raise ScenarioError(f"{name!r} is already the name of team[{seen[name]}]", f"team[{i}].name")
        seen[name] = i
        w = u.weights
        team.append(
            UAV(
                name=name,
                start=(u.start[0], u.start[1], u.start[2]),
                goal=(u.goal[0], u.goal[1], u.goal[2]),
                radius=u.radius,
                weights=Weights(u.beta, w[0], w[1], w[2], w[3], w[4]),
            )
        )
    return tuple(team)


def _fleet(fleet: Fleet, costs: CostParams) -> tuple[tuple[UAV, ...], Formation]:
    """The team and formation graph of a ``[fleet]`` template (:mod:`staghunt.task.templates`)."""
    from staghunt.task.templates import graph_matrices, place, template_edges, template_offsets

    n = fleet.count
    limit = costs.safe_distance + 2.0 * fleet.radius
    offsets = template_offsets(fleet.template, n, fleet.spacing, fleet.columns)
    if n > 1:
        d = np.hypot(*(offsets[:, None] - offsets[None]).transpose(2, 0, 1))
        d[np.arange(n), np.arange(n)] = np.inf
        if d.min() <= limit:
            raise ScenarioError(
                f"{n} UAVs in a {fleet.template} at spacing {fmt(fleet.spacing)} m come {fmt(float(d.min()))} m "
                f"apart; it must be more than costs.safe_distance + 2 * radius = {fmt(limit)} m",
                "fleet.spacing")
    if fleet.start is not None and fleet.goal is not None:
        start, goal = np.asarray(fleet.start, float), np.asarray(fleet.goal, float)
        heading = (math.radians(fleet.heading_deg) if fleet.heading_deg is not None
                   else math.atan2(goal[1] - start[1], goal[0] - start[0]))
        starts, goals = place(offsets, start, heading), place(offsets, goal, heading)
    else:
        starts = np.asarray(fleet.start if fleet.starts is None else fleet.starts, float).reshape(-1, 3)
        goals = np.asarray(fleet.goal if fleet.goals is None else fleet.goals, float).reshape(-1, 3)
        if fleet.starts is None:
            starts = np.repeat(starts, n, axis=0)
        if fleet.goals is None:
            goals = np.repeat(goals, n, axis=0)
        heading = math.radians(fleet.heading_deg) if fleet.heading_deg is not None else math.atan2(
            goals[:, 1].mean() - starts[:, 1].mean(), goals[:, 0].mean() - starts[:, 0].mean())
    w = fleet.weights
    team = tuple(
        UAV(name=f"UAV{i + 1}", start=(float(starts[i, 0]), float(starts[i, 1]), float(starts[i, 2])),
            goal=(float(goals[i, 0]), float(goals[i, 1]), float(goals[i, 2])), radius=fleet.radius,
            weights=Weights(fleet.beta, w[0], w[1], w[2], w[3], w[4]))
        for i in range(n))
    inc, mu = graph_matrices(n, template_edges(fleet.template, n, fleet.columns))
    ref = place(offsets, np.zeros(3), heading)  # the level template at the heading
    return team, Formation(incidence=_frozen(inc), edge_weights=_frozen(mu), reference=_frozen(ref))


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
                    f"x [{fmt(b.xmin)}, {fmt(b.xmax)}], "
                    f"y [{fmt(b.ymin)}, {fmt(b.ymax)}], h [{fmt(b.hmin)}, {fmt(b.hmax)}]",
                    key,
                )
            for k, c in enumerate(world.cylinders):
                if math.hypot(p[0] - c.x, p[1] - c.y) < c.radius + u.radius:
                    label = repr(c.name) if c.name else f"obstacles[{k}]"
                    raise ScenarioError(
                        f"{p} of {u.name!r} lies inside obstacle {label} "
                        f"(x={fmt(c.x)}, y={fmt(c.y)}, R={fmt(c.radius)}) "
                        f"plus body radius {fmt(u.radius)}",
                        key,
                    )
        pts = np.array([getattr(u, end) for u in team], dtype=float)
        z = world.terrain.absolute(pts[:, 0], pts[:, 1], pts[:, 2])
        absolute = np.column_stack([pts[:, 0], pts[:, 1], z])
        _check_points_clear(team, world, absolute, end)
        for i in range(len(team)):
            for j in range(i + 1, len(team)):
                dist = float(np.linalg.norm(absolute[i] - absolute[j]))
                limit = costs.safe_distance + 2.0 * max(team[i].radius, team[j].radius)
                if dist <= limit:
                    raise ScenarioError(
                        f"{team[j].name!r} {end} is {fmt(dist)} m from {team[i].name!r} {end} "
                        f"(team[{i}].{end}); it must be more than costs.safe_distance + 2 * radius "
                        f"= {fmt(limit)} m",
                        f"team[{j}].{end}",
                    )


def _check_points_clear(team: Sequence[UAV], world: World, absolute: np.ndarray, end: str) -> None:
    """Starts or goals ``absolute`` ``(N, 3)`` outside every prism and no-fly zone (grown by the
    body radius, as the cost model judges them) and below the ceiling."""
    if world.prisms:
        prm, edges = prism_arrays(world.prisms)
        radius = np.array([u.radius for u in team], dtype=float)
        path = np.repeat(absolute[None, :, None, :], 2, axis=2)  # (1, N, 2, 3): a point
        d = prism_distance(path, prm, edges, radius, 0.0)[0, :, 0]  # (N, Q)
        for i, q in zip(*np.nonzero(d < radius[:, None])):
            p, u = world.prisms[q], team[i]
            what = "no-fly zone" if p.is_nofly else "obstacle"
            label = repr(p.name) if p.name else f"prism {q}"
            raise ScenarioError(
                f"{getattr(u, end)} of {u.name!r} lies inside {what} {label} plus body radius {fmt(u.radius)}",
                f"team[{i}].{end}")
    if math.isfinite(world.ceiling):
        for i in np.nonzero(absolute[:, 2] > world.ceiling)[0]:
            raise ScenarioError(
                f"{team[i].name!r} {end} is at z = {fmt(float(absolute[i, 2]))} m, above the ceiling "
                f"airspace.ceiling = {fmt(world.ceiling)} m", f"team[{i}].{end}")


def _formation(table: FormationTable | None, team: Sequence[UAV], terrain: Terrain) -> Formation:
    n = len(team)
    goals = np.array([u.goal for u in team], dtype=float)
    default_ref = np.column_stack(
        [goals[:, 0], goals[:, 1], terrain.absolute(goals[:, 0], goals[:, 1], goals[:, 2])]
    )
    if table is None:
        if n >= 2:
            raise ScenarioError(
                f"required for a team of {n} UAVs (give incidence and edge_weights)", "formation"
            )
        empty = np.zeros((n, 0))
        return Formation(_frozen(empty), _frozen(empty), _frozen(default_ref))
    inc = _matrix(table.incidence, "formation.incidence")
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
                f"column {e} (edge {e}) is [{', '.join(fmt(v) for v in col)}]; each column "
                f"must hold exactly one +1 (head) and one -1 (tail), the rest 0",
                "formation.incidence",
            )
    mu = _matrix(table.edge_weights, "formation.edge_weights")
    if mu.shape != inc.shape:
        raise ScenarioError(
            f"must have the incidence matrix's shape {n} x {m}, got {mu.shape[0]} x {mu.shape[1]}",
            "formation.edge_weights",
        )
    if n >= 2 and not is_connected(inc):
        raise ScenarioError(
            "the formation graph is not connected; every UAV must be linked to the others "
            "through edges",
            "formation.incidence",
        )
    ref = default_ref
    if table.reference is not None:
        ref = _matrix(table.reference, "formation.reference")
        if ref.shape != (n, 3):
            raise ScenarioError(
                f"must be N x 3 = {n} x 3 ([x, y, z] per UAV, absolute), got "
                f"{ref.shape[0]} x {ref.shape[1]}",
                "formation.reference",
            )
    return Formation(incidence=_frozen(inc), edge_weights=_frozen(mu), reference=_frozen(ref))


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
    from staghunt.scenario.validation import plain, validate

    from staghunt.inputs import check_magnitudes

    data = plain(data)
    try:
        check_magnitudes(data)
    except ValueError as exc:
        raise ScenarioError(str(exc)) from None
    f = validate(data)
    scenario_name = f.name if f.name is not None else name
    if not scenario_name.strip():
        raise ScenarioError("must not be empty", "name")
    from staghunt.scenario.shapes import world_shapes

    bounds = Bounds(**f.site.model_dump())
    origin = None if f.origin is None else GeoOrigin(**f.origin.model_dump())
    terrain = _terrain(f.ground, base_dir, bounds, origin)
    cylinders = tuple(Cylinder(x=o.x, y=o.y, radius=o.radius, name=o.name) for o in f.obstacles)
    prisms, more_cylinders, ceiling = world_shapes(f, terrain, origin, base_dir)
    world = World(bounds=bounds, terrain=terrain, cylinders=cylinders + more_cylinders, prisms=prisms,
                  ceiling=ceiling)
    costs = CostParams(**f.costs.model_dump())
    if f.fleet is not None:
        team, fleet_formation = _fleet(f.fleet, costs)
        try:
            _check_team_in_world(team, world, costs)
        except ScenarioError as exc:
            raise ScenarioError(
                f"{f.fleet.count} UAVs in a {f.fleet.template} at spacing {fmt(f.fleet.spacing)} m do not fit "
                f"the site: {exc.key}: {exc.detail}", "fleet") from None
        formation = fleet_formation if f.formation is None else _formation(f.formation, team, terrain)
    else:
        assert f.team is not None
        team = _team(f.team)
        _check_team_in_world(team, world, costs)
        formation = _formation(f.formation, team, terrain)
    from staghunt.scenario.dynamics import check_names, check_take_off, dynamics_from_tables

    dynamics, _, _ = dynamics_from_tables(f, world, [u.name for u in team])
    check_names(dynamics, world)
    check_take_off(dynamics, team, world)
    from staghunt.scenario.inspection import inspection_from_tables

    vehicle = VehicleLimits(**f.vehicle.model_dump())
    inspection = inspection_from_tables(f, team, world, origin, base_dir, costs.min_clearance, vehicle.max_speed)
    return Scenario(
        name=scenario_name,
        description=f.description,
        world=world,
        team=team,
        formation=formation,
        costs=costs,
        solver=SolverSettings(**f.solver.model_dump()),
        origin=origin,
        vehicle=vehicle,
        dynamics=dynamics,
        inspection=inspection,
    )
