"""Scenario obstacles beyond cylinders: prisms, boxes and no-fly zones from the TOML tables and
from GeoJSON files, polygons checked with shapely; and the altitude ceiling. Failures raise
:class:`ScenarioError` naming the table entry (or the GeoJSON file and feature) at fault."""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from staghunt.scenario.dem import resolve_file
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


MAX_GEOJSON_OBSTACLES = 5000
"""Most GeoJSON features that may come near the site (each is costed against every path
segment of every particle in every iteration); the others are pruned before they become obstacles."""


class _Feature:
    """One checked GeoJSON feature: its kind, name, numbers and rings in lon/lat."""

    __slots__ = ("index", "name", "where", "point", "raw", "rings", "radius", "base", "height", "nofly")

    def __init__(self, index: int, name: str, where: str) -> None:
        self.index, self.name, self.where = index, name, where
        self.point = False
        self.raw: list[tuple[Any, str]] = []  # (positions as read, what they are for messages)
        self.rings: list[np.ndarray] = []
        self.radius = self.base = self.height = 0.0
        self.nofly = False


def _json_kind(v: object) -> str:
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "a boolean"
    if isinstance(v, (int, float)):
        return "a number"
    if isinstance(v, str):
        return "a string"
    if isinstance(v, list):
        return "an array"
    return "an object" if isinstance(v, dict) else type(v).__name__


def _valid_lonlat(value: object) -> np.ndarray | None:
    """``(M, 2)`` longitudes and latitudes of ``value`` (a list of ``[lon, lat(, h)]``) if it
    converts in one go and every position is finite and in range; ``None`` otherwise (the
    caller then checks position by position, to name the bad one)."""
    try:
        a = np.array(value)
    except (ValueError, TypeError, OverflowError):
        return None
    if a.ndim != 2 or a.shape[1] not in (2, 3) or a.dtype.kind not in "fi":
        return None
    ll = a[:, :2].astype(float)
    with np.errstate(invalid="ignore"):
        if np.isfinite(ll).all() and (np.abs(ll[:, 0]) <= 180.0).all() and (np.abs(ll[:, 1]) <= 90.0).all():
            return ll
    return None



def _positions(value: Any, where: str, key: str) -> np.ndarray:
    """A GeoJSON array of positions ``[lon, lat(, alt)]`` -> ``(n, 2)`` lon/lat, checked: numbers,
    finite, longitude in [-180, 180], latitude in [-90, 90]."""
    if not isinstance(value, list) or not value:
        raise ScenarioError(f"{where}: expected an array of [longitude, latitude] positions, got {_json_kind(value)}", key)
    ll = _valid_lonlat(value)  # fast path (a city's worth of buildings): checks on the whole array
    if ll is not None:
        return ll
    out = np.empty((len(value), 2))
    for k, p in enumerate(value):
        if not isinstance(p, list) or not 2 <= len(p) <= 3 or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in p):
            raise ScenarioError(f"{where}: position {k} must be [longitude, latitude] numbers, got "
                                f"{_json_kind(p)}{'' if not isinstance(p, list) else f' of {len(p)} items'}", key)
        lon, lat = float(p[0]), float(p[1])
        if not (math.isfinite(lon) and math.isfinite(lat)):
            raise ScenarioError(f"{where}: position {k} is not finite: [{lon!r}, {lat!r}]", key)
        if not -90.0 <= lat <= 90.0:
            raise ScenarioError(f"{where}: position {k} has latitude {_fmt(lat)}, outside [-90, 90] degrees "
                                "(GeoJSON positions are [longitude, latitude])", key)
        if not -180.0 <= lon <= 180.0:
            raise ScenarioError(f"{where}: position {k} has longitude {_fmt(lon)}, outside [-180, 180] degrees", key)
        out[k] = lon, lat
    return out


def feature_list(path: Path, key: str) -> list:
    """The ``features`` list of the GeoJSON FeatureCollection at ``path`` (unchecked items); a
    missing or unreadable file, or another document, is a :class:`ScenarioError` on ``key``."""
    if not path.is_file():
        raise ScenarioError(f"no such GeoJSON file {str(path)!r}", key)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise ScenarioError(f"cannot read GeoJSON {str(path)!r}: {exc}", key) from None
    feats = doc.get("features") if isinstance(doc, dict) else None
    if not isinstance(feats, list):
        raise ScenarioError(f"{str(path)!r} is not a GeoJSON FeatureCollection", key)
    return feats


def _read_features(path: Path, key: str, nofly: bool) -> list[_Feature]:
    """Every feature of a GeoJSON FeatureCollection, checked (types, coordinates, numbers) but
    not yet placed in the site frame."""
    from staghunt.inputs import MAX_MAGNITUDE

    feats = feature_list(path, key)
    out: list[_Feature] = []
    for i, f in enumerate(feats):
        if not isinstance(f, dict):
            raise ScenarioError(f"{str(path)!r} features[{i}]: expected a Feature object, got {_json_kind(f)}", key)
        props = f.get("properties")
        props = {} if props is None else props
        if not isinstance(props, dict):
            raise ScenarioError(f"{str(path)!r} features[{i}]: 'properties' must be an object, got {_json_kind(props)}", key)
        name = str(props.get("name", f"feature {i}"))[:80]
        where = f"{str(path)!r} features[{i}] ({name!r})"
        geom = f.get("geometry")
        if not isinstance(geom, dict):
            raise ScenarioError(f"{where}: 'geometry' must be an object, got {_json_kind(geom)}", key)
        gtype = geom.get("type")
        coords = geom.get("coordinates")
        feat = _Feature(i, name, where)

        def number(prop: str, default: float | None = None, positive: bool = False,
                   props: dict = props, where: str = where) -> float:  # bound now, not at call time
            v = props.get(prop, default)
            if v is None:
                raise ScenarioError(f"{where}: the property {prop!r} is missing", key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0 or (positive and v == 0):
                raise ScenarioError(f"{where}: property {prop!r} must be a "
                                    f"{'positive' if positive else 'non-negative'} number, got {v!r}", key)
            if v > MAX_MAGNITUDE:
                raise ScenarioError(f"{where}: property {prop!r} = {float(v):.3g} is beyond the supported magnitude "
                                    f"{MAX_MAGNITUDE:.0e} m", key)
            return float(v)

        if gtype == "Point":
            feat.point = True
            feat.raw = [([coords], f"{where}: coordinates")]
            feat.radius = number("radius", positive=True)
        elif gtype in ("Polygon", "MultiPolygon"):
            polys = [coords] if gtype == "Polygon" else coords
            if not isinstance(polys, list) or not polys:
                raise ScenarioError(f"{where}: expected {gtype} coordinates, got {_json_kind(polys)}", key)
            for k, poly in enumerate(polys):
                if not isinstance(poly, list) or not poly:
                    raise ScenarioError(f"{where}: polygon {k} must be an array of rings, got {_json_kind(poly)}", key)
                feat.raw.append((poly[0], f"{where}: polygon {k} outer ring"))
            feat.nofly = nofly or props.get("nofly") is True
            if not feat.nofly:
                feat.base = number("base", 0.0)
                feat.height = number("height", positive=True)
                if feat.height <= feat.base:
                    raise ScenarioError(f"{where}: height {_fmt(feat.height)} must be above base {_fmt(feat.base)}", key)
        else:
            raise ScenarioError(f"{where}: geometry type {str(gtype)[:40]!r} is not supported "
                                "(Polygon, MultiPolygon, Point)", key)
        out.append(feat)
    _place_rings(out, key)
    return out


def _place_rings(feats: list[_Feature], key: str) -> None:
    """Convert and check every feature's positions: all at once when they are well-formed (a
    city's worth of buildings), else ring by ring to name the first bad one."""
    raw = [r for f in feats for r, _ in f.raw]
    flat = None
    if all(isinstance(r, list) and r for r in raw):
        flat = _valid_lonlat(list(itertools.chain.from_iterable(raw)))
    if flat is None:
        for f in feats:
            f.rings = [_positions(r, label, key) for r, label in f.raw]
        return
    at = 0
    for f in feats:
        f.rings = []
        for r, _ in f.raw:
            f.rings.append(flat[at:at + len(r)])
            at += len(r)


def _geojson(path: Path, key: str, nofly: bool, origin: GeoOrigin | None, terrain: Terrain,
             site: tuple[float, float, float, float] | None = None, margin: float = 0.0,
             keep: frozenset[str] = frozenset()) -> tuple[list[Prism], list[Cylinder]]:
    """Prisms and cylinders of a GeoJSON file. With ``site`` ``(xmin, xmax, ymin, ymax)``, a
    feature whose bounding box stays more than ``margin`` m (plus a Point's radius) away from the
    site box is pruned before it becomes an obstacle (it can neither touch a path nor add to a
    cost), unless its name is in ``keep``; a file none of whose features comes near the site is
    refused (longitude and latitude swapped?), as are more than :data:`MAX_GEOJSON_OBSTACLES` near it."""
    from staghunt.world.georef import lonlat_to_site

    if origin is None:
        raise ScenarioError("GeoJSON obstacles (lon/lat) need the [origin] table to place them", key)
    feats = _read_features(path, key, nofly)
    if not feats:
        return [], []
    lonlat = np.concatenate([r for f in feats for r in f.rings])
    with np.errstate(all="ignore"):
        x, y = lonlat_to_site(origin, lonlat[:, 0], lonlat[:, 1])
    xy = np.column_stack([x, y])
    sizes = [len(r) for f in feats for r in f.rings]
    rings_xy = np.split(xy, np.cumsum(sizes)[:-1])
    # Each feature's distance from the site box, from its bounding box (all features at once).
    starts = np.cumsum([0] + [sum(len(r) for r in f.rings) for f in feats])[:-1]
    with np.errstate(invalid="ignore"):
        lo, hi = np.minimum.reduceat(xy, starts, axis=0), np.maximum.reduceat(xy, starts, axis=0)
    if site is None:
        gap = np.zeros(len(feats))
    else:
        dx = np.maximum(np.maximum(site[0] - hi[:, 0], lo[:, 0] - site[1]), 0.0)
        dy = np.maximum(np.maximum(site[2] - hi[:, 1], lo[:, 1] - site[3]), 0.0)
        gap = np.hypot(dx, dy) - np.array([f.radius if f.point else 0.0 for f in feats])
        gap = np.where(np.isfinite(gap), gap, np.inf)
    near = gap <= margin
    if keep:
        near |= np.array([f.name in keep for f in feats])
    kept: list[tuple[_Feature, list[np.ndarray]]] = []
    at = 0
    for f, ok in zip(feats, near):
        if ok:
            kept.append((f, rings_xy[at:at + len(f.rings)]))
        at += len(f.rings)
    nearest = (float(gap.min()), feats[int(np.argmin(gap))])
    if not kept:
        d, f = nearest
        how = f"{d / 1000:.4g} km" if math.isfinite(d) else "beyond any site"
        raise ScenarioError(
            f"none of the {len(feats)} features of {str(path)!r} comes near the site box (the nearest, "
            f"features[{f.index}] ({f.name!r}), lies {how} from it); are longitude and latitude swapped, "
            "or is [origin] wrong?", key)
    if len(kept) > MAX_GEOJSON_OBSTACLES:
        raise ScenarioError(
            f"{len(kept)} features of {str(path)!r} come within {_fmt(margin)} m of the site box (at most "
            f"{MAX_GEOJSON_OBSTACLES}); cut the file to the site's surroundings", key)
    prisms: list[Prism] = []
    cylinders: list[Cylinder] = []
    for f, rings in kept:
        if f.point:
            px, py = rings[0][0]
            if not (math.isfinite(px) and math.isfinite(py)):
                raise ScenarioError(f"{f.where}: the point cannot be placed in the site frame", key)
            cylinders.append(Cylinder(float(px), float(py), f.radius, f.name))
            continue
        for ring in rings:
            poly = check_polygon(ring.tolist(), key, f"{f.where}: polygon")
            if f.nofly:
                prisms.append(nofly_zone(poly, f.name))
            else:
                prisms.append(make_prism(poly, f.base, f.height, terrain, f.name))
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
    # A feature farther from the site box than this cannot touch a path or add to a cost
    # (paths stay in the box; costs reach r + max(danger_margin, min_clearance) from an obstacle).
    radii = [f.fleet.radius] if f.fleet is not None else [u.radius for u in (f.team or [])]
    margin = max(radii, default=0.0) + max(f.costs.danger_margin, f.costs.min_clearance) + 1.0
    site = (f.site.xmin, f.site.xmax, f.site.ymin, f.site.ymax)
    keep = frozenset(e.name for e in f.events if e.kind == "disappear" and e.name is not None)
    for i, g in enumerate(f.geojson):
        path = Path(g.file).expanduser()
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        key = f"geojson[{i}].file"
        more, cyl = _geojson(resolve_file(path, key, "the GeoJSON file"), key, g.nofly, origin, terrain,
                             site, margin, keep)
        prisms += more
        cylinders += cyl
    ceiling = math.inf if f.airspace.ceiling is None else float(f.airspace.ceiling)
    return tuple(prisms), tuple(cylinders), ceiling
