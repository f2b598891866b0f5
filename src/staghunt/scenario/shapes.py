"""Scenario obstacles beyond cylinders: prisms, boxes and no-fly zones from the TOML tables and
from GeoJSON files, polygons checked with shapely; and the altitude ceiling. Failures raise
:class:`ScenarioError` naming the table entry (or the GeoJSON file and feature) at fault."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from staghunt.scenario.errors import ScenarioError
from staghunt.scenario.errors import fmt as _fmt
from staghunt.world import Cylinder, GeoOrigin, Prism, Terrain, box_polygon

if TYPE_CHECKING:
    from staghunt.scenario.schema import ScenarioFile


def check_polygon(points: Sequence[Sequence[float]], key: str, what: str = "polygon") -> tuple[tuple[float, float], ...]:
    """A simple polygon with a positive area, as ``(x, y)`` vertex tuples without a closing
    repeat of the first vertex; shapely names the problem otherwise."""
    from shapely.geometry import Polygon
    from shapely.validation import explain_validity

    pts = [(float(p[0]), float(p[1])) for p in points]
    if len(pts) > 1 and pts[0] == pts[-1]:
        pts = pts[:-1]
    if len(pts) < 3:
        raise ScenarioError(f"{what} needs at least 3 distinct vertices, got {len(pts)}", key)
    if not all(math.isfinite(v) for p in pts for v in p):
        raise ScenarioError(f"{what} has a non-finite coordinate", key)
    v = np.asarray(pts) - pts[0]
    if np.linalg.matrix_rank(v, tol=1e-9 * max(1.0, float(np.abs(v).max()))) < 2:
        raise ScenarioError(f"{what} is empty (zero area): its vertices are collinear or repeated", key)
    poly = Polygon(pts)
    if not poly.is_valid or poly.area <= 0.0:
        raise ScenarioError(f"{what} is not a simple polygon: {explain_validity(poly)}", key)
    return tuple(pts)


def _ground_range(terrain: Terrain, polygon: Sequence[tuple[float, float]]) -> tuple[float, float]:
    """Least and greatest ground height at a footprint's vertices and centroid."""
    v = np.asarray(polygon, dtype=float)
    x = np.append(v[:, 0], v[:, 0].mean())
    y = np.append(v[:, 1], v[:, 1].mean())
    g = np.asarray(terrain.height(x, y), dtype=float)
    return float(g.min()), float(g.max())


def make_prism(polygon: tuple[tuple[float, float], ...], base: float, height: float, terrain: Terrain,
               name: str, kind: str = "prism") -> Prism:
    """A prism from heights above the ground: ``base = 0`` reaches down to the ground (no lower
    limit), else its absolute base is ``base`` above the lowest ground under the footprint; the
    absolute top is ``height`` above the highest ground under it (docs/model.md)."""
    lo, hi = _ground_range(terrain, polygon)
    abs_base = -math.inf if base == 0.0 else lo + base
    return Prism(polygon, abs_base, hi + height, name, kind, (float(base), float(height)))  # type: ignore[arg-type]


def nofly_zone(polygon: tuple[tuple[float, float], ...], name: str) -> Prism:
    return Prism(polygon, -math.inf, math.inf, name, "nofly")


def _geojson(path: Path, key: str, nofly: bool, origin: GeoOrigin | None, terrain: Terrain
             ) -> tuple[list[Prism], list[Cylinder]]:
    from staghunt.world.georef import lonlat_to_site

    if origin is None:
        raise ScenarioError("GeoJSON obstacles (lon/lat) need the [origin] table to place them", key)
    if not path.is_file():
        raise ScenarioError(f"no such GeoJSON file {str(path)!r}", key)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ScenarioError(f"cannot read GeoJSON {str(path)!r}: {exc}", key) from None
    feats = doc.get("features") if isinstance(doc, dict) else None
    if not isinstance(feats, list):
        raise ScenarioError(f"{str(path)!r} is not a GeoJSON FeatureCollection", key)
    prisms: list[Prism] = []
    cylinders: list[Cylinder] = []
    for i, f in enumerate(feats):
        geom = (f or {}).get("geometry") or {}
        props: dict[str, Any] = (f or {}).get("properties") or {}
        name = str(props.get("name", f"feature {i}"))
        where = f"{str(path)!r} features[{i}] ({name!r})"
        gtype = geom.get("type")

        def number(prop: str, default: float | None = None, positive: bool = False) -> float:
            v = props.get(prop, default)
            if v is None:
                raise ScenarioError(f"{where}: the property {prop!r} is missing", key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0 or (positive and v == 0):
                raise ScenarioError(f"{where}: property {prop!r} must be a {'positive' if positive else 'non-negative'} number, got {v!r}", key)
            return float(v)

        try:
            if gtype == "Point":
                lon, lat = geom["coordinates"][:2]
                x, y = lonlat_to_site(origin, np.array([lon]), np.array([lat]))
                cylinders.append(Cylinder(float(x[0]), float(y[0]), number("radius", positive=True), name))
                continue
            if gtype == "Polygon":
                rings = [geom["coordinates"][0]]
            elif gtype == "MultiPolygon":
                rings = [p[0] for p in geom["coordinates"]]
            else:
                raise ScenarioError(f"{where}: geometry type {gtype!r} is not supported (Polygon, MultiPolygon, Point)", key)
            for ring in rings:
                ll = np.asarray(ring, dtype=float)[:, :2]
                x, y = lonlat_to_site(origin, ll[:, 0], ll[:, 1])
                poly = check_polygon(np.column_stack([x, y]).tolist(), key, f"{where}: polygon")
                if nofly or props.get("nofly") is True:
                    prisms.append(nofly_zone(poly, name))
                    continue
                base = number("base", 0.0)
                height = number("height", positive=True)
                if height <= base:
                    raise ScenarioError(f"{where}: height {_fmt(height)} must be above base {_fmt(base)}", key)
                prisms.append(make_prism(poly, base, height, terrain, name))
        except ScenarioError:
            raise
        except (KeyError, IndexError, TypeError, ValueError) as exc:
            raise ScenarioError(f"{where}: malformed coordinates ({exc})", key) from None
    return prisms, cylinders


def world_shapes(f: ScenarioFile, terrain: Terrain, origin: GeoOrigin | None, base_dir: Path | None
                 ) -> tuple[tuple[Prism, ...], tuple[Cylinder, ...], float]:
    """Prisms (tables ``prisms``, ``boxes``, ``nofly``, then GeoJSON files), extra cylinders (GeoJSON
    points) and the ceiling (``inf`` if none) of a checked scenario file."""
    prisms: list[Prism] = []
    cylinders: list[Cylinder] = []
    for i, p in enumerate(f.prisms):
        poly = check_polygon(p.polygon, f"prisms[{i}].polygon")
        prisms.append(make_prism(poly, p.base, p.height, terrain, p.name))
    for bx in f.boxes:
        prisms.append(make_prism(box_polygon(bx.xmin, bx.xmax, bx.ymin, bx.ymax), bx.base, bx.height,
                                 terrain, bx.name, "box"))
    for i, z in enumerate(f.nofly):
        prisms.append(nofly_zone(check_polygon(z.polygon, f"nofly[{i}].polygon"), z.name))
    for i, g in enumerate(f.geojson):
        path = Path(g.file).expanduser()
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        more, cyl = _geojson(path.resolve(), f"geojson[{i}].file", g.nofly, origin, terrain)
        prisms += more
        cylinders += cyl
    ceiling = math.inf if f.airspace.ceiling is None else float(f.airspace.ceiling)
    return tuple(prisms), tuple(cylinders), ceiling
