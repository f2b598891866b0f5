"""The inspection of a scenario, built from its checked tables with the checks that need more
than one table: cameras named in the shipped table, objectives inside the site and clear of the
obstacles, facades of existing prisms, a GSD the site's height band and clearance can reach,
time windows a UAV can make; and an objectives file merged into a scenario's tables.

Failures raise :class:`ScenarioError` naming the key (``objectives[1].gsd_cm``)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from staghunt.camera import Camera, camera_table
from staghunt.scenario.errors import ScenarioError
from staghunt.scenario.errors import fmt as _fmt
from staghunt.scenario.schema_inspection import AreaTable, CameraTable, FacadeTable, PayloadKeys, PointTable
from staghunt.scenario.shapes import check_polygon
from staghunt.task import UAV
from staghunt.task.objectives import AreaObjective, FacadeObjective, Inspection, Objective, Payload, PointObjective
from staghunt.world import GeoOrigin, World

__all__ = ["INSPECTION_KEYS", "check_inspection_events", "inspection_from_tables", "merge_objectives",
           "objective_from_data"]

INSPECTION_KEYS = ("camera", "payload", "inspection", "objectives")
"""The top-level keys an objectives file gives (and replaces in the scenario)."""
DEFAULT_ENDURANCE_S = 1800.0
"""A UAV's flight time when none is given: 30 min (a DJI Mavic 3 Enterprise's 45 min less a
third for the reserve and the wind)."""


def _camera(ref: str | CameraTable, key: str) -> Camera:
    if isinstance(ref, str):
        table = camera_table()
        if ref not in table:
            raise ScenarioError(f"unknown camera {ref!r}; shipped cameras: {', '.join(sorted(table))} (or give a table "
                                "of sensor_width_mm, sensor_height_mm, image_width_px, image_height_px, focal_length_mm)",
                                key)
        return table[ref]
    return Camera(name=ref.name or "custom camera", sensor_width_mm=ref.sensor_width_mm,
                  sensor_height_mm=ref.sensor_height_mm, image_width_px=ref.image_width_px,
                  image_height_px=ref.image_height_px, focal_length_mm=ref.focal_length_mm,
                  landscape=ref.landscape, min_trigger_interval_s=ref.min_trigger_interval_s, exposure_s=ref.exposure_s)


def _payloads(f: Any, n: int) -> tuple[Payload, ...] | None:
    """Every UAV's payload: its own keys (``team[i]`` or ``fleet``), else the top-level
    ``[payload]``, else the top-level ``camera``; ``None`` when no camera is given anywhere."""
    per_uav: list[PayloadKeys | None] = list(f.team) if f.team is not None else [f.fleet] * n
    top = f.payload
    out = []
    for i in range(n):
        own = per_uav[i]
        where = (f"team[{i}]" if f.team is not None else "fleet")
        ref, key = None, None
        for src, k in ((own, f"{where}.camera"), (top, "payload.camera")):
            if src is not None and src.camera is not None:
                ref, key = src.camera, k
                break
        if ref is None and f.camera is not None:
            ref, key = f.camera, "camera"
        if ref is None:
            return None
        pitch = next((s.gimbal_pitch_deg for s in (own, top) if s is not None and s.gimbal_pitch_deg is not None),
                     [-90.0, 30.0])
        endurance = next((s.endurance_s for s in (own, top) if s is not None and s.endurance_s is not None),
                         DEFAULT_ENDURANCE_S)
        out.append(Payload(_camera(ref, key), float(pitch[0]), float(pitch[1]), float(endurance)))
    return tuple(out)


def _feature(path_text: str, feature: str | None, base_dir: Path | None, kind: str, key: str) -> list:
    """The coordinates of a GeoJSON feature of geometry ``kind`` (``"Polygon"`` or ``"Point"``)."""
    from staghunt.scenario.dem import resolve_file
    from staghunt.scenario.shapes import feature_list

    path = resolve_file((base_dir or Path(".")) / path_text, key, "GeoJSON file")
    feats = feature_list(path, key)
    if not feats:
        raise ScenarioError(f"{str(path)!r} is not a GeoJSON FeatureCollection with features", key)
    named = [f for f in feats if isinstance(f, dict) and (f.get("properties") or {}).get("name") == feature]
    if feature is not None and not named:
        raise ScenarioError(f"{str(path)!r} has no feature named {feature!r}", key)
    if feature is None and len(feats) != 1:
        raise ScenarioError(f"{str(path)!r} has {len(feats)} features: name one with feature = \"...\"", key)
    geom = (named or feats)[0].get("geometry") if isinstance((named or feats)[0], dict) else None
    if not isinstance(geom, dict) or geom.get("type") != kind:
        got = geom.get("type") if isinstance(geom, dict) else type(geom).__name__
        raise ScenarioError(f"{str(path)!r}: the feature must be a {kind}, got {got}", key)
    coords = geom.get("coordinates")
    return coords[0] if kind == "Polygon" and isinstance(coords, list) and coords else coords


def _lonlat(coords: Any, origin: GeoOrigin | None, key: str) -> np.ndarray:
    from staghunt.scenario.shapes import _positions
    from staghunt.world.georef import lonlat_to_site

    if origin is None:
        raise ScenarioError("a GeoJSON objective needs the scenario's [origin] to place WGS84 coordinates", key)
    ll = _positions(coords if isinstance(coords, list) and coords and isinstance(coords[0], list) else [coords],
                    "GeoJSON", key)
    x, y = lonlat_to_site(origin, ll[:, 0], ll[:, 1])
    return np.column_stack([x, y])


def _inside_solid(world: World, p: np.ndarray, tol: float = 0.5) -> str | None:
    """The obstacle whose inside holds the absolute point ``p`` by more than ``tol`` m, if any."""
    from shapely.geometry import Point, Polygon

    for c in world.cylinders:
        if math.hypot(p[0] - c.x, p[1] - c.y) < c.radius - tol:
            return f"obstacle {c.name or (c.x, c.y)!r}"
    for q in world.prisms:
        poly = Polygon(q.polygon)
        if q.base + tol < p[2] < q.top - tol and poly.contains(Point(p[0], p[1])) and \
                poly.exterior.distance(Point(p[0], p[1])) > tol:
            return f"{'no-fly zone' if q.is_nofly else 'prism'} {q.name!r}"
    return None


def _objective(t: AreaTable | FacadeTable | PointTable, i: int, world: World, origin: GeoOrigin | None,
               base_dir: Path | None, cameras: dict[str, Camera], first: Camera, payload: Payload,
               team: Sequence[UAV], clearance: float, speed: float) -> Objective:
    key = f"objectives[{i}]"
    cam = first
    if t.camera is not None:
        if t.camera not in cameras:
            raise ScenarioError(f"no UAV carries camera {t.camera!r}; the team's: {', '.join(sorted(cameras))}",
                                f"{key}.camera")
        cam = cameras[t.camera]
    b = world.bounds
    radius = max(u.radius for u in team)
    if isinstance(t, AreaTable):
        pts = t.polygon if t.polygon is not None else _lonlat(_feature(t.geojson, t.feature, base_dir, "Polygon",
                                                                      f"{key}.geojson"), origin, f"{key}.geojson")
        poly = check_polygon(pts, f"{key}.polygon")
        for v in poly:
            if not b.contains_xy(*v):
                raise ScenarioError(f"vertex ({_fmt(v[0])}, {_fmt(v[1])}) is outside the site [{_fmt(b.xmin)}, "
                                    f"{_fmt(b.xmax)}] x [{_fmt(b.ymin)}, {_fmt(b.ymax)}]", f"{key}.polygon")
        d = cam.distance_m(t.gsd_cm)
        if d < b.hmin:
            raise ScenarioError(f"gsd_cm = {_fmt(t.gsd_cm)} needs the camera {d:.3g} m above the ground with "
                                f"{cam.name!r}, below site.hmin = {_fmt(b.hmin)} m: it cannot be reached", f"{key}.gsd_cm")
        g = np.asarray(world.terrain.height(np.array([v[0] for v in poly]), np.array([v[1] for v in poly])), float)
        if np.isfinite(world.ceiling) and world.ceiling - radius - float(g.max()) < b.hmin:
            raise ScenarioError(f"the ceiling z = {_fmt(world.ceiling)} m leaves less than site.hmin = {_fmt(b.hmin)} m "
                                "above the ground under the area: no survey height is allowed", f"{key}.polygon")
        return AreaObjective(t.name, poly, t.gsd_cm, t.front_overlap, t.side_overlap, t.angle_deg, t.priority,
                             t.required, t.camera)
    if isinstance(t, FacadeTable):
        match = [q for q in world.prisms if q.name == t.prism]
        if not match:
            names = sorted({q.name for q in world.prisms if q.name and not q.is_nofly})
            raise ScenarioError(f"no prism or building named {t.prism!r}; the scenario's: {', '.join(names) or 'none'}",
                                f"{key}.prism")
        if match[0].is_nofly:
            raise ScenarioError(f"{t.prism!r} is a no-fly zone, not a structure with walls", f"{key}.prism")
        d = cam.distance_m(t.gsd_cm)
        if d < radius + clearance:
            raise ScenarioError(f"gsd_cm = {_fmt(t.gsd_cm)} needs the camera {d:.3g} m from the walls with {cam.name!r}, "
                                f"nearer than the body radius and costs.min_clearance allow ({_fmt(radius + clearance)} m)",
                                f"{key}.gsd_cm")
        return FacadeObjective(t.name, t.prism, t.gsd_cm, t.max_incidence_deg, t.front_overlap, t.side_overlap,
                               t.priority, t.required, t.camera)
    if t.geojson is not None:
        x, y = _lonlat(_feature(t.geojson, t.feature, base_dir, "Point", f"{key}.geojson"), origin, f"{key}.geojson")[0]
    else:
        x, y = float(t.x), float(t.y)
    if not b.contains_xy(x, y):
        raise ScenarioError(f"({_fmt(x)}, {_fmt(y)}) is outside the site [{_fmt(b.xmin)}, {_fmt(b.xmax)}] x "
                            f"[{_fmt(b.ymin)}, {_fmt(b.ymax)}]", f"{key}.x")
    g = float(np.asarray(world.terrain.height(np.array([x]), np.array([y])))[0])
    p = np.array([x, y, g + t.z])
    inside = _inside_solid(world, p)
    if inside is not None:
        raise ScenarioError(f"the point ({_fmt(x)}, {_fmt(y)}, {_fmt(t.z)} m above the ground) is inside {inside}; "
                            "give a point on its surface or outside", key)
    if np.isfinite(world.ceiling) and p[2] > world.ceiling:
        raise ScenarioError(f"the point is at z = {p[2]:.4g} m, above the ceiling z = {_fmt(world.ceiling)} m", f"{key}.z")
    if t.distance < radius + clearance:
        raise ScenarioError(f"distance = {_fmt(t.distance)} m is nearer than the body radius and costs.min_clearance "
                            f"allow ({_fmt(radius + clearance)} m)", f"{key}.distance")
    if t.gsd_cm is not None and cam.gsd_cm(t.distance) > t.gsd_cm * (1 + 1e-9):
        raise ScenarioError(f"distance = {_fmt(t.distance)} m gives {cam.gsd_cm(t.distance):.3g} cm/px with "
                            f"{cam.name!r}, coarser than gsd_cm = {_fmt(t.gsd_cm)}", f"{key}.distance")
    if not -payload.gimbal_pitch_max_deg - 1e-9 <= t.elevation_deg <= -payload.gimbal_pitch_min_deg + 1e-9:
        raise ScenarioError(f"elevation_deg = {_fmt(t.elevation_deg)} needs a gimbal pitch of "
                            f"{_fmt(-t.elevation_deg)} degrees, outside the gimbal's [{_fmt(payload.gimbal_pitch_min_deg)}, "
                            f"{_fmt(payload.gimbal_pitch_max_deg)}]", f"{key}.elevation_deg")
    if t.time_window is not None:
        starts = np.array([u.start for u in team], dtype=float)
        reach = float(np.hypot(starts[:, 0] - x, starts[:, 1] - y).min()) - t.distance
        earliest = max(reach, 0.0) / speed
        if t.time_window[1] - t.dwell_s * t.views < earliest:
            raise ScenarioError(f"the window ends at {_fmt(t.time_window[1])} s, but no UAV can be there and hover its "
                                f"views before {earliest + t.dwell_s * t.views:.4g} s (the nearest start is "
                                f"{reach + t.distance:.4g} m away, at vehicle.max_speed)", f"{key}.time_window")
    return PointObjective(t.name, x, y, t.z, t.distance, t.views, t.elevation_deg, t.dwell_s,
                          None if t.time_window is None else (float(t.time_window[0]), float(t.time_window[1])),
                          t.repeat_every_s, t.repeats, t.gsd_cm, t.priority, t.required, t.camera)


def inspection_from_tables(f: Any, team: Sequence[UAV], world: World, origin: GeoOrigin | None,
                           base_dir: Path | None, clearance: float, max_speed: float) -> Inspection | None:
    """The scenario's inspection (``None`` when it gives no camera and no objective)."""
    payloads = _payloads(f, len(team))
    if payloads is None:
        if f.objectives:
            raise ScenarioError("objectives need a camera: give camera = \"NAME\" (staghunt cameras lists the "
                                "shipped ones) or a [camera] table", "camera")
        return None
    cameras = {p.camera.name: p.camera for p in payloads}
    objectives: list[Objective] = []
    seen: dict[str, int] = {}
    for i, t in enumerate(f.objectives):
        if t.name in seen:
            raise ScenarioError(f"{t.name!r} is already the name of objectives[{seen[t.name]}]", f"objectives[{i}].name")
        seen[t.name] = i
        objectives.append(_objective(t, i, world, origin, base_dir, cameras, payloads[0].camera, payloads[0], team,
                                     clearance, max_speed))
    settings = f.inspection
    return Inspection(tuple(objectives), payloads,
                      max_blur_px=settings.max_blur_px if settings is not None else 0.5,
                      cell_m=settings.cell_m if settings is not None else None)


def merge_objectives(scenario: Mapping[str, Any], objectives: Mapping[str, Any]) -> dict[str, Any]:
    """A scenario's plain data with an objectives file's tables (``camera``, ``payload``,
    ``inspection``, ``objectives``): each one the file gives replaces the scenario's, and a
    camera or payload key it gives is every UAV's (a UAV's own key of the same name is dropped)."""
    out = dict(scenario)
    given = {k: v for k, v in objectives.items() if k in INSPECTION_KEYS}
    drop = set()
    if "camera" in given:
        drop.add("camera")
    for k in ("gimbal_pitch_deg", "endurance_s", "camera"):
        if isinstance(given.get("payload"), Mapping) and k in given["payload"]:
            drop.add(k)
    for table in ("team", "fleet"):
        v = out.get(table)
        if isinstance(v, list):
            out[table] = [{k: x for k, x in u.items() if k not in drop} if isinstance(u, Mapping) else u for u in v]
        elif isinstance(v, Mapping):
            out[table] = {k: x for k, x in v.items() if k not in drop}
    out.update(given)
    return out


def objective_from_data(data: Mapping[str, Any], scenario: Any, key: str, base_dir: Path | None = None) -> Objective:
    """An objective given as plain data (an events file's ``objective`` table) checked against
    ``scenario`` as the scenario's own objectives are (:class:`ScenarioError` naming ``key``)."""
    from pydantic import TypeAdapter, ValidationError

    from staghunt.scenario.schema_inspection import ObjectiveTable

    insp = scenario.inspection
    if insp is None:
        raise ScenarioError("an objective added in flight needs an inspection (a camera and objectives)", key)
    try:
        table = TypeAdapter(ObjectiveTable).validate_python(dict(data))
    except ValidationError as exc:
        first = exc.errors(include_url=False)[0]
        where = ".".join(str(p) for p in first["loc"][1:])
        raise ScenarioError(first["msg"], f"{key}.{where}" if where else key) from None
    if table.name in {o.name for o in insp.objectives}:
        raise ScenarioError(f"{table.name!r} is already the name of an objective", f"{key}.name")
    cameras = {p.camera.name: p.camera for p in insp.payloads}
    return _objective(table, 0, scenario.world, scenario.origin, base_dir, cameras, insp.payloads[0].camera,
                      insp.payloads[0], scenario.team, scenario.costs.min_clearance, scenario.vehicle.max_speed)


def check_inspection_events(scenario: Any, events: Sequence[Any], source: str = "events") -> list[Any]:
    """The inspection's events checked: a ``uav_lost`` names a UAV of the team (once), an
    ``objective`` is a valid objective of the scenario; returns the events with each objective
    converted (its ``objective`` the :class:`Objective`). :class:`ScenarioError` naming the event."""
    from dataclasses import replace

    names = [u.name for u in scenario.team]
    lost: set[str] = set()
    out = []
    for i, e in enumerate(events):
        if getattr(e, "trigger", None) is not None:
            raise ScenarioError("an inspection's obstacles appear at their time: a trigger is flown by "
                                "`staghunt fly` only", f"events[{i}].trigger")
        if e.kind == "uav_lost":
            if e.name not in names:
                raise ScenarioError(f"no UAV named {e.name!r}; the team: {', '.join(names)}", f"events[{i}].uav")
            if e.name in lost:
                raise ScenarioError(f"{e.name!r} is lost twice", f"events[{i}].uav")
            lost.add(e.name)
        elif e.kind == "objective":
            e = replace(e, objective=objective_from_data(e.objective, scenario, f"events[{i}].objective"))
        out.append(e)
    if len(lost) >= len(names):
        raise ScenarioError("every UAV of the team is lost: nobody is left to finish the inspection", "events")
    return out
