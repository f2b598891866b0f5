"""Coverage: what a set of photos shows of each objective, at which resolution.

Surfaces are sampled in square elements of ``cell`` metres: ground **cells** inside an area's
polygon (on the DEM, with its normal) and **patches** on a facade's walls (from the ground to the
prism's top). A photo *images an element at the target* when the element is in its frame, faces
the camera, no prism stands between them, its GSD in that photo (the longest side of one pixel's
footprint, :func:`staghunt.camera.projection.surface_gsd`) is at or below the objective's target
and, for a facade, its incidence is within the limit.

Reported per objective (:class:`Coverage`): the share of elements imaged at the target at least
once and at least ``min_images`` times, the images per element, the best GSD and incidence, the
front and side overlaps reached between the photos (from their positions and the footprint at
their distance to the surface, as QGroundControl defines them) and the motion blur at the speed
each photo was taken.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree
from shapely import contains_xy
from shapely.geometry import LineString, Point, Polygon

from staghunt.acquisition.clearance import occluded
from staghunt.acquisition.views import near_side
from staghunt.camera import Camera
from staghunt.camera.projection import project, surface_gsd
from staghunt.scenario.model import Scenario
from staghunt.task.objectives import AreaObjective, FacadeObjective, Inspection, PointObjective

__all__ = ["Coverage", "Photos", "Surface", "area_cells", "facade_patches", "measure", "measure_counts",
           "measure_inspection"]

MIN_IMAGES = 5
"""Images per element the survey target asks for."""


@dataclass(frozen=True, eq=False)
class Surface:
    """``C`` surface elements of side ``cell`` (m) of objective ``objective``: centres ``points
    (C, 3)`` (absolute), unit ``normals (C, 3)``; ``details``: ``{"prism": name}`` for a facade."""

    objective: str
    kind: str
    points: np.ndarray
    normals: np.ndarray
    cell: float
    details: dict = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Photos:
    """``F`` photos: time ``t (F,)`` (s), ``uav (F,)`` index, camera ``position (F, 3)``
    (absolute), gimbal ``yaw``/``pitch (F,)`` (rad), ``speed (F,)`` (m/s) when taken,
    ``objective (F,)`` and ``segment (F,)`` they were taken for (``""``/``-1``: none)."""

    t: np.ndarray
    uav: np.ndarray
    position: np.ndarray
    yaw: np.ndarray
    pitch: np.ndarray
    speed: np.ndarray
    objective: np.ndarray
    segment: np.ndarray

    def __len__(self) -> int:
        return int(len(self.t))

    def take(self, mask: np.ndarray) -> "Photos":
        return Photos(*(getattr(self, f)[mask] for f in ("t", "uav", "position", "yaw", "pitch", "speed",
                                                         "objective", "segment")))

    @staticmethod
    def empty() -> "Photos":
        z = np.zeros(0)
        return Photos(z, z.astype(int), np.zeros((0, 3)), z, z, z, z.astype(str), z.astype(int))

    @staticmethod
    def concat(parts: list["Photos"]) -> "Photos":
        parts = [p for p in parts if len(p)]
        if not parts:
            return Photos.empty()
        return Photos(*(np.concatenate([getattr(p, f) for p in parts]) for f in
                        ("t", "uav", "position", "yaw", "pitch", "speed", "objective", "segment")))


@dataclass(frozen=True)
class Coverage:
    """The coverage of one objective by a set of photos (see the module's docstring)."""

    objective: str
    kind: str
    elements: int
    cell_m: float
    target_gsd_cm: float | None
    imaged_share: float
    target_share: float
    min_images_share: float
    min_images: int
    images_per_element: dict
    best_gsd_cm: dict
    incidence_deg: dict
    front_overlap: dict
    side_overlap: dict
    blur_px: dict
    photos: int
    details: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        out = dict(self.__dict__)
        return out


def area_cells(obj: AreaObjective, scenario: Scenario, cell: float) -> Surface:
    """Ground cells of side ``cell`` whose centre lies in the area's polygon, on the DEM."""
    poly = Polygon(obj.polygon)
    x0, y0, x1, y1 = poly.bounds
    xs = np.arange(x0 + 0.5 * cell, x1, cell)
    ys = np.arange(y0 + 0.5 * cell, y1, cell)
    X, Y = np.meshgrid(xs, ys)
    inside = contains_xy(poly, X, Y)
    x, y = X[inside], Y[inside]
    terrain = scenario.world.terrain
    z = np.asarray(terrain.height(x, y), dtype=float)
    h = 0.5 * cell
    gx = (np.asarray(terrain.height(x + h, y), float) - np.asarray(terrain.height(x - h, y), float)) / cell
    gy = (np.asarray(terrain.height(x, y + h), float) - np.asarray(terrain.height(x, y - h), float)) / cell
    n = np.column_stack([-gx, -gy, np.ones_like(gx)])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return Surface(obj.name, "area", np.column_stack([x, y, z]), n, cell)


def facade_patches(obj: FacadeObjective, scenario: Scenario, cell: float) -> Surface:
    """Wall patches of side ``cell`` of the objective's prism, from the ground to its top."""
    prism = next(p for p in scenario.world.prisms if p.name == obj.prism)
    poly = np.asarray(prism.polygon, dtype=float)
    if Polygon(poly).exterior.is_ccw is False:
        poly = poly[::-1]
    terrain = scenario.world.terrain
    pts, nrm = [], []
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        e = b - a
        length = float(np.hypot(*e))
        if length < 1e-9:
            continue
        out = np.array([e[1], -e[0]]) / length  # outward for a counter-clockwise ring
        s = np.arange(0.5 * cell, length, cell)
        xy = a + np.outer(s / length, e)
        g = np.asarray(terrain.height(xy[:, 0], xy[:, 1]), dtype=float)
        base = np.maximum(g, prism.base) if np.isfinite(prism.base) else g
        for k in range(len(xy)):
            zs = np.arange(base[k] + 0.5 * cell, prism.top, cell)
            pts.append(np.column_stack([np.full(len(zs), xy[k, 0]), np.full(len(zs), xy[k, 1]), zs]))
            nrm.append(np.tile([out[0], out[1], 0.0], (len(zs), 1)))
    return Surface(obj.name, "facade", np.vstack(pts), np.vstack(nrm), cell, {"prism": obj.prism})


def _stats(v: np.ndarray) -> dict:
    v = np.asarray(v, dtype=float)
    v = v[np.isfinite(v)]
    if not len(v):
        return {"min": None, "p5": None, "median": None, "mean": None, "p95": None, "max": None}
    return {"min": float(v.min()), "p5": float(np.percentile(v, 5)), "median": float(np.median(v)),
            "mean": float(v.mean()), "p95": float(np.percentile(v, 95)), "max": float(v.max())}


def _depths(surface: Surface, photos: Photos, scenario: Scenario) -> np.ndarray:
    """``(F,)`` each photo's distance to the surface it is for: the height above the ground
    under it (area), the horizontal distance to the walls (facade)."""
    pos = photos.position
    if surface.kind == "area":
        return pos[:, 2] - np.asarray(scenario.world.terrain.height(pos[:, 0], pos[:, 1]), dtype=float)
    prism = next(p for p in scenario.world.prisms if p.name == surface.details["prism"])
    ring = Polygon(prism.polygon).exterior
    far = 10.0 * max(ring.length, 1.0)
    out = np.empty(len(pos))
    for i, (p, yaw) in enumerate(zip(pos, photos.yaw)):  # along the view, to the first wall it meets
        ray = LineString([p[:2], p[:2] + far * np.array([math.cos(yaw), math.sin(yaw)])])
        hit = ring.intersection(ray)
        out[i] = Point(p[:2]).distance(hit) if not hit.is_empty else ring.distance(Point(p[:2]))
    return out


def _overlaps(photos: Photos, camera: Camera, kind: str, depth: np.ndarray, target: tuple[float, float]
              ) -> tuple[dict, dict]:
    """Front and side overlaps between the photos, as QGroundControl defines them, with the
    footprint at each photo's distance to the surface: front, between consecutive photos of one
    segment (the distance flown over the footprint along the track; pairs across a facade's
    corner, where the view turns by more than 15 degrees, are left out); side, between a photo and
    the nearest photo of another segment (an area's neighbouring line: the horizontal distance
    over the footprint across the track); a facade's neighbouring layer: the least height
    difference (over 0.5 m) to another photo less than half a footprint away along the walls,
    over the vertical footprint."""
    pos = photos.position
    across, along = np.array([camera.footprint_m(camera.gsd_cm(max(d, 1e-3))) for d in depth]).reshape(-1, 2).T
    if kind == "facade" and camera.landscape:  # level photos: the image's width lies along the walls
        across, along = along, across
    fronts, sides = [], []
    key = photos.uav.astype(np.int64) * 100000 + photos.segment.astype(np.int64)
    for k in np.unique(key):
        idx = np.flatnonzero(key == k)
        idx = idx[np.argsort(photos.t[idx], kind="stable")]
        if len(idx) >= 2:
            step = np.linalg.norm(np.diff(pos[idx, :2], axis=0), axis=1)
            turn = np.abs(np.angle(np.exp(1j * np.diff(photos.yaw[idx]))))
            straight = turn < math.radians(15.0)  # a facade's corner: two walls, no overlap to speak of
            fronts.append((1.0 - step / np.minimum(along[idx[:-1]], along[idx[1:]]))[straight])
        others = np.flatnonzero(key != k)
        if not len(others):
            continue
        if kind == "area":
            dist, _ = cKDTree(pos[others, :2]).query(pos[idx, :2])
            sides.append(1.0 - dist / across[idx])
    if kind == "facade":  # the next layer: any photo up or down the wall, less than half a footprint along it
        tree = cKDTree(pos[:, :2])
        for i in range(len(pos)):
            near = np.asarray(tree.query_ball_point(pos[i, :2], 0.5 * along[i]), dtype=np.intp)
            dz = np.abs(pos[near, 2] - pos[i, 2])
            dz = dz[dz > 0.5]
            if len(dz):
                sides.append(np.array([1.0 - float(dz.min()) / across[i]]))
    out = []
    for vals, want in ((fronts, target[0]), (sides, target[1])):
        v = np.concatenate(vals) if vals else np.zeros(0)
        v = v[np.isfinite(v)]
        out.append({"pairs": int(len(v)), "target": want,
                    "reached_share": float(np.mean(v >= want - 1e-9)) if len(v) else None, **_stats(v)})
    return out[0], out[1]


def _counts(surface: Surface, photos: Photos, camera: Camera, scenario: Scenario, target_gsd_cm: float,
            max_incidence_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per element ``(C,)``: photos imaging it at the target, photos imaging it at all, its best
    GSD and its least incidence among the photos at the target."""
    C = len(surface.points)
    count = np.zeros(C, dtype=np.int64)
    seen = np.zeros(C, dtype=np.int64)
    best = np.full(C, np.inf)
    inc_best = np.full(C, np.inf)
    if not len(photos) or not C:
        return count, seen, best, inc_best
    tree = cKDTree(surface.points)
    hx, hy = camera.half_fov_rad
    diag = math.atan(math.hypot(math.tan(hx), math.tan(hy)))
    # the farthest an element at the target GSD can be: its depth over cos(half diagonal)
    reach = camera.distance_m(target_gsd_cm) / math.cos(diag) * 1.05 + surface.cell
    for f in range(len(photos)):
        cam = photos.position[f]
        idx = np.asarray(tree.query_ball_point(cam, reach), dtype=np.intp)
        if not len(idx):
            continue
        p = surface.points[idx]
        _, _, _, inside = project(camera, p, cam, photos.yaw[f], photos.pitch[f])
        idx, p = idx[inside], p[inside]
        if not len(idx):
            continue
        gsd, inc = surface_gsd(camera, p, surface.normals[idx], cam, photos.yaw[f], photos.pitch[f])
        facing = inc < 90.0
        idx, p, gsd, inc = idx[facing], p[facing], gsd[facing], inc[facing]
        lift = p + 0.05 * surface.normals[idx]
        visible = ~occluded(scenario, np.broadcast_to(cam, p.shape), lift)
        idx, gsd, inc = idx[visible], gsd[visible], inc[visible]
        seen[idx] += 1
        good = (gsd <= target_gsd_cm * (1 + 1e-9)) & (inc <= max_incidence_deg + 1e-9)
        count[idx[good]] += 1
        np.minimum.at(best, idx, gsd)
        np.minimum.at(inc_best, idx[good], inc[good])
    return count, seen, best, inc_best


def measure_counts(surface: Surface, photos: Photos, camera: Camera, scenario: Scenario, target_gsd_cm: float,
                   max_incidence_deg: float = 90.0) -> np.ndarray:
    """``(C,)`` photos imaging each element at the target (the coverage map)."""
    return _counts(surface, photos, camera, scenario, target_gsd_cm, max_incidence_deg)[0]


def measure(surface: Surface, photos: Photos, camera: Camera, scenario: Scenario, target_gsd_cm: float,
            max_incidence_deg: float = 90.0, min_images: int = MIN_IMAGES,
            overlaps: tuple[float, float] | None = None) -> Coverage:
    """The coverage of ``surface`` by ``photos`` taken with ``camera``."""
    C = len(surface.points)
    count, seen, best, inc_best = _counts(surface, photos, camera, scenario, target_gsd_cm, max_incidence_deg)
    depth = _depths(surface, photos, scenario)
    front, side = _overlaps(photos, camera, surface.kind, depth, overlaps or (0.0, 0.0))
    blur = photos.speed * camera.exposure_s / (camera.gsd_cm(np.maximum(depth, 1e-3)) / 100.0)
    return Coverage(
        objective=surface.objective, kind=surface.kind, elements=C, cell_m=surface.cell, target_gsd_cm=target_gsd_cm,
        imaged_share=float(np.mean(seen > 0)) if C else 0.0,
        target_share=float(np.mean(count > 0)) if C else 0.0,
        min_images_share=float(np.mean(count >= min_images)) if C else 0.0, min_images=min_images,
        images_per_element=_stats(count), best_gsd_cm=_stats(best), incidence_deg=_stats(inc_best),
        front_overlap=front, side_overlap=side, blur_px=_stats(blur), photos=len(photos))


def measure_inspection(inspection: Inspection, scenario: Scenario, photos: Photos, cameras: dict[str, Camera]
                       ) -> list[dict]:
    """The coverage of every objective of ``inspection`` by ``photos`` (those taken for it),
    as plain JSON-able dictionaries in the objectives' order."""
    cell = inspection.coverage_cell()
    out: list[dict] = []
    for obj in inspection.objectives:
        mine = photos.take(photos.objective == obj.name)
        cam = cameras[obj.name]
        if isinstance(obj, AreaObjective):
            cov = measure(area_cells(obj, scenario, cell), mine, cam, scenario, obj.gsd_cm,
                          overlaps=(obj.front_overlap, obj.side_overlap))
            out.append(cov.as_dict())
        elif isinstance(obj, FacadeObjective):
            cov = measure(facade_patches(obj, scenario, cell), mine, cam, scenario, obj.gsd_cm,
                          obj.max_incidence_deg, min_images=1, overlaps=(obj.front_overlap, obj.side_overlap))
            out.append(cov.as_dict())
        else:
            out.append(point_coverage(obj, scenario, mine, cam))
    return out


def point_coverage(obj: PointObjective, scenario: Scenario, photos: Photos, camera: Camera) -> dict:
    """A point of interest: the photos that hold it in frame, unoccluded, from ``distance`` or
    nearer, and when (within the window of each visit)."""
    g = float(np.asarray(scenario.world.terrain.height(np.array([obj.x]), np.array([obj.y])))[0])
    target = np.array([obj.x, obj.y, g + obj.z])
    ok_times: list[float] = []
    for f in range(len(photos)):
        cam = photos.position[f]
        _, _, depth, inside = project(camera, target[None], cam, photos.yaw[f], photos.pitch[f])
        near = float(np.linalg.norm(target - cam)) <= obj.distance * 1.05 + 0.5
        if inside[0] and near and not occluded(scenario, cam[None], near_side(target, cam)[None])[0]:
            ok_times.append(float(photos.t[f]))
    visits = obj.windows()
    done = []
    for w in visits:
        lo, hi = (w if w is not None else (-math.inf, math.inf))
        done.append(sum(lo - 1e-6 <= t <= hi + 1e-6 for t in ok_times))
    need = obj.views
    return {"objective": obj.name, "kind": "point", "photos": len(photos), "photos_on_target": len(ok_times),
            "visits": len(visits), "views_per_visit": need, "photos_per_visit": done,
            "visits_done": int(sum(d >= need for d in done)), "target_share": float(np.mean([d >= need for d in done])),
            "times": ok_times, "gsd_cm": camera.gsd_cm(obj.distance)}
