"""Area surveys: nadir lines over a polygon, terrain-following at the target GSD.

From the objective and the camera (QGroundControl's CameraCalc, :mod:`staghunt.camera`):
the distance to the ground ``d`` gives the GSD, the footprint ``W x F`` (across x along the
track) gives the line spacing ``s = W (1 - side overlap)`` and the trigger distance
``t = F (1 - front overlap)``.

Where the lines go (docs/model.md, section 9):

- Lines run along ``angle_deg`` (default: the long side of the polygon's minimum rotated
  rectangle). They are placed so that a cell on the polygon's side edge is inside the footprint
  of two lines (the first line ``max(W/2 - s, 0)`` inside the edge, then every ``s`` or less),
  and each line is extended by half a trigger distance beyond the polygon at both ends (up to
  three quarters where the terrain falls away under it: the frame's far edge then sees coarser), so that
  the last cells along a line are seen by as many photos as the overlap gives; QGroundControl's
  Survey starts its lines at an arbitrary phase and stops them at the edge, which leaves the
  edges with fewer photos (:func:`qgc_photos` counts what it would take).
- Terrain following: along each line the camera flies ``d`` above the lowest ground within its
  footprint (so that no ground in a photo is seen coarser than the target GSD), lowered where
  needed so that it climbs at most ``max_climb_deg``. Each line's trigger distance, and the
  spacing to the next line, come from the footprint at the least height above the ground under
  the line, so that the overlaps hold where the ground rises: on hilly ground this costs photos
  that QGroundControl's constant height above the ground under the camera does not take (and
  its photos then see the ground below the camera's sides coarser than the target).
- A line stretch where the camera cannot be (inside or too near an obstacle or a no-fly zone,
  outside the site or its height band) is cut out and reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from shapely.geometry import LineString, MultiLineString, Polygon
from shapely.geometry.base import BaseGeometry

from staghunt.acquisition.clearance import Keepout
from staghunt.acquisition.segments import CaptureSegment, ObjectivePlan
from staghunt.camera import Camera
from staghunt.task.objectives import AreaObjective

__all__ = ["line_angle", "plan_area", "qgc_photo_poses", "qgc_photos", "qgc_transects"]

RELIEF_FRACTION = 1.0
"""Share of the footprint (centred, along and across) whose lowest ground sets the height: the
whole footprint, so that no ground in a photo lies deeper than the target GSD's distance (measured
on the hilly built-in site: 0.75 leaves 7 % of the cells with fewer than five photos at the target)."""
MAX_CLIMB_DEG = 30.0
"""Steepest climb or descent along a survey line."""
STEP_M = 5.0
"""Longest distance between the planned points of a line."""
MARGIN = 0.97
"""Trigger distances and line spacings are planned at this share of what the overlaps allow, so
that the overlaps still hold on the flown trajectory (a distance trigger fires up to one
simulation step late, tracking and wind move the photos)."""
BLUR_MARGIN = 0.95
"""Captures are planned at this share of the speed that keeps the blur within its limit: the
vehicles overshoot a planned speed by up to 4 % on the built-in inspections (0.52 px flown for
0.50 px planned without it)."""


def line_angle(poly: Polygon) -> float:
    """Direction (rad, counter-clockwise from east) of the long side of the minimum rotated
    rectangle of ``poly``: the lines that need the fewest turns."""
    rect = np.asarray(poly.minimum_rotated_rectangle.exterior.coords)[:4]
    e = np.diff(np.vstack([rect, rect[:1]]), axis=0)
    k = int(np.argmax(np.hypot(e[:, 0], e[:, 1])))
    return float(math.atan2(e[k, 1], e[k, 0]))


def _frame(angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors along the lines and across them (to the left)."""
    u = np.array([math.cos(angle), math.sin(angle)])
    return u, np.array([-u[1], u[0]])


def _pieces(geom: BaseGeometry) -> list[LineString]:
    if geom.is_empty:
        return []
    if isinstance(geom, LineString):
        return [geom]
    if isinstance(geom, MultiLineString):
        return list(geom.geoms)
    return [g for g in getattr(geom, "geoms", []) if isinstance(g, LineString)]


def qgc_transects(polygon: Polygon, angle: float, spacing: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """QGroundControl Survey's transects (``SurveyComplexItem``): lines every ``spacing`` from an
    offset fixed by the bounding box, each spanning the two farthest crossings of the polygon
    (``[(start (2,), end (2,)), ...]``); one line through the centre when fewer than two cross."""
    u, v = _frame(angle)
    xy = np.asarray(polygon.exterior.coords)
    cu, cv = xy @ u, xy @ v
    centre = 0.5 * (np.array([cu.min(), cv.min()]) + np.array([cu.max(), cv.max()]))
    half = 0.5 * (max(cu.max() - cu.min(), cv.max() - cv.min()) + 2000.0)
    out = []
    for off in np.arange(centre[1] - half, centre[1] + half, spacing):
        a = (centre[0] - half) * u + off * v
        b = (centre[0] + half) * u + off * v
        hit = polygon.exterior.intersection(LineString([a, b]))
        # every crossing, a line along an edge included (QGroundControl meets the edges at its ends)
        pts = np.array([c for g in getattr(hit, "geoms", [hit]) if not g.is_empty for c in g.coords]).reshape(-1, 2)
        if len(pts) < 2:
            continue
        s = pts @ u
        out.append((pts[int(np.argmin(s))], pts[int(np.argmax(s))]))
    if len(out) < 2:
        a = (centre[0] - half) * u + centre[1] * v
        b = (centre[0] + half) * u + centre[1] * v
        inter = polygon.intersection(LineString([a, b]))
        c = np.asarray(inter.coords) if not inter.is_empty and hasattr(inter, "coords") else np.zeros((0, 2))
        out = [(c[0], c[-1])] if len(c) >= 2 else out
    return out


def qgc_photos(polygon: Polygon, angle: float, spacing: float, trigger: float) -> int:
    """Photos QGroundControl's Survey plans: ``ceil(length / trigger)`` per transect
    (:func:`qgc_transects`; no turnaround photos)."""
    return max(1, sum(math.ceil(float(np.linalg.norm(b - a)) / trigger - 1e-9) for a, b in qgc_transects(polygon, angle,
                                                                                                         spacing)))


def qgc_photo_poses(polygon: Polygon, angle: float, spacing: float, trigger: float, distance: float,
                    terrain: object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where QGroundControl's Survey takes its photos over ``terrain`` with terrain following:
    ``ceil(length / trigger)`` per transect from its start, each ``distance`` above the ground
    under the camera, nadir, the image's height axis along the line: ``(positions (F, 3), yaw (F,),
    pitch (F,))``. To measure what its plan covers on the same ground (its estimate assumes level
    ground)."""
    pos, yaw = [], []
    for k, (a, b) in enumerate(qgc_transects(polygon, angle, spacing)):
        if k % 2:
            a, b = b, a
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / trigger - 1e-9))
        d = (b - a) / max(float(np.linalg.norm(b - a)), 1e-9)
        xy = a + np.outer(np.arange(n) * trigger, d)
        g = np.asarray(terrain.height(xy[:, 0], xy[:, 1]), dtype=float)  # type: ignore[attr-defined]
        pos.append(np.column_stack([xy, g + distance]))
        yaw.append(np.full(n, math.atan2(d[1], d[0])))
    p = np.vstack(pos)
    return p, np.concatenate(yaw), np.full(len(p), -0.5 * math.pi)


def _ground_reference(keep: Keepout, xy: np.ndarray, u: np.ndarray, v: np.ndarray,
                      half_along: float, half_across: float) -> np.ndarray:
    """``(M,)`` lowest ground within the central ``2 half_along x 2 half_across`` rectangle of the
    footprint around each of ``xy`` ``(M, 2)`` (5 x 5 samples)."""
    a = np.linspace(-half_along, half_along, 5)
    c = np.linspace(-half_across, half_across, 5)
    off = a[:, None, None] * u + c[None, :, None] * v  # (5, 5, 2)
    pts = xy[:, None, None, :] + off[None]
    g = keep.scenario.world.terrain.height(pts[..., 0], pts[..., 1])
    return np.asarray(g, dtype=float).reshape(len(xy), -1).min(axis=1)


def _limit_climb(s: np.ndarray, z: np.ndarray, max_climb_deg: float) -> np.ndarray:
    """The highest profile at or below ``z`` whose slope stays within ``max_climb_deg``."""
    k = math.tan(math.radians(max_climb_deg))
    return np.min(z[None, :] + k * np.abs(s[:, None] - s[None, :]), axis=1)


@dataclass
class _Line:
    """One survey line at across-track offset ``offset``: its pieces (inside the polygon, extended
    at both ends) as arc positions ``s`` and camera points ``pts``, and the least depth (m)
    between the camera and the ground under it."""

    offset: float
    pieces: list[tuple[np.ndarray, np.ndarray]]
    min_depth: float


def _profile(keep: Keepout, poly: Polygon, u: np.ndarray, v: np.ndarray, off: float, distance: float,
             footprint: tuple[float, float], extend: float, relief_fraction: float, max_climb_deg: float) -> _Line:
    xy = np.asarray(poly.exterior.coords)
    cu = xy @ u
    reach = (cu.max() - cu.min()) + 2.0 * extend + 10.0
    a = (cu.min() - reach) * u + off * v
    b = (cu.max() + reach) * u + off * v
    pieces, depth = [], math.inf
    side, front = footprint
    for piece in _pieces(poly.intersection(LineString([a, b]))):
        p = np.asarray(piece.coords)
        s0, s1 = sorted((float(p[0] @ u), float(p[-1] @ u)))
        s0, s1 = s0 - extend, s1 + extend
        n = max(2, math.ceil((s1 - s0) / min(STEP_M, extend)) + 1)
        s = np.linspace(s0, s1, n)
        pts_xy = s[:, None] * u + off * v
        g_ref = _ground_reference(keep, pts_xy, u, v, 0.5 * relief_fraction * front, 0.5 * relief_fraction * side)
        z = _limit_climb(s - s0, g_ref + distance, max_climb_deg)
        pts = np.column_stack([pts_xy, z])
        depth = min(depth, float(keep.heights(pts).min()))
        pieces.append((s, pts))
    return _Line(off, pieces, depth)


def plan_area(obj: AreaObjective, camera: Camera, keep: Keepout, cruise_speed: float, max_blur_px: float,
              relief_fraction: float = RELIEF_FRACTION, max_climb_deg: float = MAX_CLIMB_DEG) -> ObjectivePlan:
    """The survey lines of ``obj`` flown with ``camera`` by a body the ``keep`` rules hold.

    Each line's trigger distance, and the spacing to the next line, come from the footprint at
    the least depth under the line (terrain following keeps the camera at most ``d`` above the
    ground it sees, so nearer where the ground rises): the overlaps hold everywhere. Without an
    ``angle_deg`` the lines run along the polygon's long side or across it, whichever needs fewer
    photos (on hilly ground the slope, not only the shape, decides)."""
    if obj.angle_deg is not None:
        return _plan_area(obj, math.radians(obj.angle_deg), camera, keep, cruise_speed, max_blur_px, relief_fraction,
                          max_climb_deg)
    long_side = line_angle(Polygon(obj.polygon))
    plans = [_plan_area(obj, a, camera, keep, cruise_speed, max_blur_px, relief_fraction, max_climb_deg)
             for a in (long_side, long_side + 0.5 * math.pi)]
    return min(plans, key=lambda p: (len(p.unreached), p.photos))


def _plan_area(obj: AreaObjective, angle: float, camera: Camera, keep: Keepout, cruise_speed: float,
               max_blur_px: float, relief_fraction: float, max_climb_deg: float) -> ObjectivePlan:
    poly = Polygon(obj.polygon)
    u, v = _frame(angle)
    bounds = keep.scenario.world.bounds
    distance = min(camera.distance_m(obj.gsd_cm), bounds.hmax)
    gsd = camera.gsd_cm(distance)
    nominal = camera.footprint_m(gsd)
    trigger_nominal = camera.trigger_distance_m(gsd, obj.front_overlap)
    cv = np.asarray(poly.exterior.coords) @ v
    vmin, vmax = float(cv.min()), float(cv.max())

    def line(off: float) -> _Line:
        """The line at ``off``, extended beyond the polygon by half a trigger distance over level
        ground, up to three quarters where the terrain under it falls 10 % of ``d`` or more below
        the camera's nadir height (the frame's far edge then sees the ground coarser)."""
        first = _profile(keep, poly, u, v, off, distance, nominal, 0.5 * trigger_nominal, relief_fraction, max_climb_deg)
        relief = max(0.0, min(1.0, (distance - first.min_depth) / (0.1 * distance)))
        if relief == 0.0:
            return first
        return _profile(keep, poly, u, v, off, distance, nominal, (0.5 + 0.25 * relief) * trigger_nominal,
                        relief_fraction, max_climb_deg)

    def side_at(depth: float) -> float:
        return MARGIN * camera.footprint_m(camera.gsd_cm(depth))[0]

    def inset(depth: float) -> float:
        """How far inside an edge the outermost line goes: a cell on the edge is then in the
        footprints of two lines (side overlap of 50 % or more)."""
        w = side_at(depth)
        return min(max(0.5 * w - w * (1.0 - obj.side_overlap), 0.0), 0.5 * (vmax - vmin))

    lines: list[_Line] = []
    first = line(vmin + inset(distance))
    first = line(vmin + inset(first.min_depth))
    lines.append(first)
    while True:  # evenly over what is left, at the spacing the shallower of two lines allows
        last = lines[-1]
        end = vmax - inset(last.min_depth)
        if last.offset >= end - 1e-6:
            break
        step = side_at(last.min_depth) * (1.0 - obj.side_overlap)
        nxt = line(last.offset + (end - last.offset) / math.ceil((end - last.offset) / step - 1e-9))
        depth = min(last.min_depth, nxt.min_depth)
        end = vmax - inset(depth)
        step = side_at(depth) * (1.0 - obj.side_overlap)
        k = math.ceil((end - last.offset) / step - 1e-9)
        lines.append(line(last.offset + (end - last.offset) / k))
        if k == 1:
            break

    segments: list[CaptureSegment] = []
    unreached: list[str] = []
    moved: list[str] = []
    triggers: list[float] = []
    for i, ln in enumerate(lines):
        trigger = MARGIN * camera.trigger_distance_m(camera.gsd_cm(ln.min_depth), obj.front_overlap)
        triggers.append(trigger)
        speed = min(cruise_speed, BLUR_MARGIN * camera.speed_for_blur(camera.gsd_cm(ln.min_depth), max_blur_px),
                    0.9 * trigger / camera.min_trigger_interval_s
                    if camera.min_trigger_interval_s > 0 else math.inf)
        for s, pts in ln.pieces:
            n = len(s)
            low = keep.heights(pts) < bounds.hmin
            if low.any():  # only where the terrain rises sharply under the line
                pts[low, 2] += bounds.hmin - keep.heights(pts[low])
                moved.append(f"line {i + 1}: {int(low.sum())} points raised to site.hmin above the ground")
            ok = keep.point_ok(pts)
            seg_ok = keep.segment_ok(pts) & ok[:-1] & ok[1:]
            runs = _runs(seg_ok)
            if len(runs) != 1 or runs[0] != (0, n - 2):
                lost = float(np.sum(np.diff(s)[~seg_ok]))
                bad = int(np.flatnonzero(~ok)[0]) if (~ok).any() else int(np.flatnonzero(~seg_ok)[0])
                why = keep.why(pts[bad]) or "a stretch passes too near an obstacle"
                unreached.append(f"line {i + 1}: {lost:.1f} m cannot be flown safely ({why})")
            for r0, r1 in runs:
                chunk = pts[r0:r1 + 2]
                segments.append(CaptureSegment(
                    objective=obj.name, kind="line", index=len(segments), points=chunk,
                    yaw=np.full(len(chunk), angle), pitch=np.full(len(chunk), -0.5 * math.pi),
                    trigger="distance", trigger_distance=trigger, speed=speed, gsd_cm=gsd, camera=camera.name))
    # lawnmower order: every other line reversed
    ordered = tuple(seg if k % 2 == 0 else seg.reversed() for k, seg in enumerate(segments))
    offsets = [ln.offset for ln in lines]
    return ObjectivePlan(
        name=obj.name, kind="area", segments=ordered, distance_m=distance, gsd_cm=gsd, moved=tuple(moved),
        unreached=tuple(unreached), qgc_photos=qgc_photos(poly, angle, camera.line_spacing_m(obj.gsd_cm, obj.side_overlap),
                                                           camera.trigger_distance_m(obj.gsd_cm, obj.front_overlap)),
        details={"angle_deg": math.degrees(angle), "lines": len(lines),
                 "line_spacing_m": [float(b - a) for a, b in zip(offsets, offsets[1:])],
                 "trigger_distance_m": triggers, "footprint_m": list(nominal), "area_m2": poly.area,
                 "min_depth_m": min(ln.min_depth for ln in lines)})


def _runs(ok: np.ndarray) -> list[tuple[int, int]]:
    """``[(first, last), ...]`` index ranges of the runs of ``True`` in ``ok``."""
    out: list[tuple[int, int]] = []
    start = None
    for i, flag in enumerate(ok):
        if flag and start is None:
            start = i
        elif not flag and start is not None:
            out.append((start, i - 1))
            start = None
    if start is not None:
        out.append((start, len(ok) - 1))
    return out
