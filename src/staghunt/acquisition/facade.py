"""Facades: the walls of a prism photographed level, in layers, from the standoff that gives
the target GSD (a QGroundControl Structure Scan, for any footprint, with the site's obstacles).

- The camera flies around the prism's footprint at the standoff ``d`` (the footprint grown by
  ``d`` with mitred corners), one run per wall, facing the wall square on; at an inner corner
  both runs go on past the corner so that the corner's walls are photographed to their ends. A
  wall's layers make one capture, up the wall back and forth (one UAV per wall at a time).
- Layers: the image's vertical footprint ``V`` and the side overlap set the layer spacing
  ``V (1 - side overlap)``; the layers span the walls from the lowest ground along them to the
  prism's top. Where the lowest layer cannot fly low enough (the site's minimum height above
  ground), the gimbal pitches down so that the bottom row of the image still reaches the foot
  of the wall; where the top one cannot fly high enough (ceiling, height band), it pitches up,
  within the UAV's gimbal limits and the objective's incidence limit.
- The trigger distance along a layer is the horizontal footprint times ``1 - front overlap``.
- A position that is not safe (too near another obstacle, outside the site, under the minimum
  height) is pulled towards the wall, down to 40 % of the standoff (a finer GSD, a smaller
  footprint), and reported as moved; where no such position is safe the stretch is cut and
  reported as unreached.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from shapely.geometry import Polygon

from staghunt.acquisition.clearance import Keepout
from staghunt.acquisition.segments import CaptureSegment, ObjectivePlan, arc_length
from staghunt.acquisition.survey import BLUR_MARGIN, MARGIN, _runs
from staghunt.camera import Camera
from staghunt.task.objectives import FacadeObjective, Payload

__all__ = ["plan_facade"]

STANDOFF = 0.9
"""The walls are flown at this share of the target GSD's distance: a vehicle strays from its
reference in wind, and a photo from farther is coarser (measured in 5 m/s wind at the full
distance: 58-71 % of the patches at the target GSD, against 100 % without wind)."""
PULL = (0.9, 0.8, 0.7, 0.6, 0.5, 0.4)
"""Fractions of the standoff tried, in turn, for a position that is not safe."""
STEP_M = 1.0
"""Distance between the planned points of a layer."""


def _loop(poly: Polygon, standoff: float, reach: float, trim: float = 0.0) -> list[tuple[np.ndarray, np.ndarray]]:
    """The loop at ``standoff`` around ``poly`` (its footprint grown with mitred corners,
    counter-clockwise; a corner sharper than the mitre limit is bevelled), one run per edge, as
    points at most ``STEP_M`` apart: ``[(points (M, 2), look (M, 2)), ...]``, ``look`` the point
    of the walls each position faces: straight ahead, perpendicular to the edge, so that each
    wall is seen face on and its GSD is the same over the whole photo. One run per wall lets the
    task layer share a building's walls among UAVs; one UAV flying them in turn loses nothing.

    At an inner (reflex) corner each of the two edges runs on past the corner by ``reach`` (half
    the horizontal footprint), still facing its own wall, so that the walls' ends in the corner
    are photographed too. At an outer corner each run stops ``trim`` short of it (the wall's end
    is still in view, the corner is ``standoff`` beyond it), so that two UAVs flying the two walls
    never meet at the corner."""
    ring = poly.buffer(standoff, join_style="mitre", mitre_limit=2.0).exterior
    xy = np.asarray(ring.coords)[:-1]
    if not ring.is_ccw:
        xy = xy[::-1]
    V = len(xy)
    edges = [(xy[k], xy[(k + 1) % V]) for k in range(V)]
    unit = [(b - a) / max(float(np.hypot(*(b - a))), 1e-12) for a, b in edges]
    # a clockwise turn at vertex k (between edge k-1 and edge k) is an inner corner
    reflex = [float(unit[k - 1][0] * unit[k][1] - unit[k - 1][1] * unit[k][0]) < -1e-9 for k in range(V)]
    runs = []
    for k, (a, b) in enumerate(edges):
        e = unit[k]
        if float(np.hypot(*(b - a))) < 1e-9:
            continue
        length = float(np.hypot(*(b - a)))
        cut = min(trim, 0.25 * length)
        a2 = a - reach * e if reflex[k] else a + cut * e
        b2 = b + reach * e if reflex[(k + 1) % V] else b - cut * e
        n = max(1, math.ceil(float(np.hypot(*(b2 - a2))) / STEP_M))
        pts = a2 + (np.arange(n + 1) / n)[:, None] * (b2 - a2)
        runs.append((pts, pts + standoff * np.array([-e[1], e[0]])))  # inward: left of a counter-clockwise ring
    return runs


def plan_facade(obj: FacadeObjective, camera: Camera, payload: Payload, keep: Keepout, cruise_speed: float,
                max_blur_px: float) -> ObjectivePlan:
    """The layers around the objective's prism, flown with ``camera`` on ``payload``'s gimbal."""
    scenario = keep.scenario
    prism = next(p for p in scenario.world.prisms if p.name == obj.prism)
    poly = Polygon(prism.polygon)
    distance = STANDOFF * camera.distance_m(obj.gsd_cm)
    gsd = camera.gsd_cm(distance)
    side_fp, front_fp = camera.footprint_m(gsd)
    horizontal = front_fp if not camera.landscape else side_fp  # the image's width lies level
    vertical = side_fp if not camera.landscape else front_fp
    trigger = MARGIN * horizontal * (1.0 - obj.front_overlap)
    spacing = MARGIN * vertical * (1.0 - obj.side_overlap)
    speed = min(cruise_speed, BLUR_MARGIN * camera.speed_for_blur(gsd, max_blur_px),
                0.9 * trigger / camera.min_trigger_interval_s if camera.min_trigger_interval_s > 0 else math.inf)
    terrain = scenario.world.terrain
    wall = np.asarray(poly.exterior.coords)
    g_wall = np.asarray(terrain.height(wall[:, 0], wall[:, 1]), dtype=float)
    bottom = float(max(g_wall.min(), prism.base)) if np.isfinite(prism.base) else float(g_wall.min())
    top = float(prism.top)
    n_layers = 1 if top - bottom <= vertical else math.ceil((top - bottom - vertical) / spacing - 1e-9) + 1
    heights = ([0.5 * (bottom + top)] if n_layers == 1
               else np.linspace(bottom + 0.5 * vertical, top - 0.5 * vertical, n_layers).tolist())
    layer = _Layer(keep, camera, payload, distance, bottom, top, trigger, speed, gsd, obj.name)
    segments: list[CaptureSegment] = []
    moved: list[str] = []
    unreached: list[str] = []
    trim = scenario.costs.safe_distance + 2 * keep.radius + 1.0
    for loop_xy, near in _loop(poly, distance, 0.5 * horizontal, trim):  # wall by wall
        layers = []
        for k, zc in enumerate(heights):
            segs, m, u = layer.run(k, len(heights), zc, loop_xy, near, 0)
            layers.append(segs)
            moved.extend(m)
            unreached.extend(u)
        for seg in _serpentine(layers):
            segments.append(replace(seg, index=len(segments)))
    return ObjectivePlan(
        name=obj.name, kind="facade", segments=tuple(segments), distance_m=distance, gsd_cm=gsd,
        moved=tuple(dict.fromkeys(moved)), unreached=tuple(unreached),
        details={"layers": len(heights), "layer_z": [float(h) for h in heights], "layer_spacing_m": spacing,
                 "trigger_distance_m": trigger, "wall_bottom_z": bottom, "wall_top_z": top, "speed_ms": speed,
                 "perimeter_m": poly.length})


def _serpentine(layers: list[list[CaptureSegment]]) -> list[CaptureSegment]:
    """A wall's layers flown as one capture, bottom up, every other layer backwards, climbing at
    the wall's end from one to the next (photos go on: they are of the wall too): two UAVs never
    fly two layers of one wall at once, which would put them one layer spacing apart. A layer cut
    by an obstacle leaves the wall's layers as separate captures."""
    if any(len(segs) != 1 for segs in layers) or len(layers) < 2:
        return [s for segs in layers for s in segs]
    parts = [segs[0] if i % 2 == 0 else segs[0].reversed() for i, segs in enumerate(layers)]
    return [replace(parts[0], points=np.vstack([p.points for p in parts]), yaw=np.concatenate([p.yaw for p in parts]),
                    pitch=np.concatenate([p.pitch for p in parts]))]


@dataclass(frozen=True)
class _Layer:
    """What every run of a facade's layers shares."""

    keep: Keepout
    camera: Camera
    payload: Payload
    distance: float
    bottom: float
    top: float
    trigger: float
    speed: float
    gsd: float
    name: str

    def run(self, k: int, layers: int, zc: float, loop_xy: np.ndarray, near: np.ndarray, first: int
            ) -> tuple[list[CaptureSegment], list[str], list[str]]:
        """The capture segments of one run of layer ``k`` (of ``layers``) at height ``zc``, and
        the notes of what was moved and what cannot be reached."""
        keep, scenario = self.keep, self.keep.scenario
        b, ceiling = scenario.world.bounds, scenario.world.ceiling
        g = np.asarray(scenario.world.terrain.height(loop_xy[:, 0], loop_xy[:, 1]), dtype=float)
        hi = np.minimum(g + b.hmax, ceiling - keep.radius - max(keep.clearance, 0.0))
        z = np.clip(np.full(len(g), zc), g + b.hmin, hi)
        half_v = self.camera.half_fov_rad[1] if self.camera.landscape else self.camera.half_fov_rad[0]
        pitch = np.zeros(len(z))
        if k == 0:  # the foot of the wall must be in the bottom row
            need = np.arctan2(z - self.bottom, self.distance) - half_v
            pitch = np.where(need > 0, -need, pitch)
        if k == layers - 1:  # the top of the wall must be in the top row
            need = np.arctan2(self.top - z, self.distance) - half_v
            pitch = np.where(need > 0, need, pitch)
        lo, up = math.radians(self.payload.gimbal_pitch_min_deg), math.radians(self.payload.gimbal_pitch_max_deg)
        moved: list[str] = []
        unreached: list[str] = []
        if ((pitch < lo) | (pitch > up)).any():
            moved.append(f"layer {k + 1}: the gimbal's pitch limits keep some views from reaching the whole wall height")
        pitch = np.clip(pitch, lo, up)
        pts = np.column_stack([loop_xy, z])
        ok = keep.point_ok(pts)
        pulled = 0
        for f in PULL:
            bad = np.flatnonzero(~ok)
            if not len(bad):
                break
            cand = np.column_stack([near[bad] + f * (loop_xy[bad] - near[bad]), z[bad]])
            good = keep.point_ok(cand)
            pts[bad[good]] = cand[good]
            ok[bad[good]] = True
            pulled += int(good.sum())
        if pulled:
            moved.append(f"layer {k + 1}: {pulled} positions pulled towards the wall to stay clear of obstacles")
        yaw = np.arctan2(near[:, 1] - pts[:, 1], near[:, 0] - pts[:, 0])
        seg_ok = keep.segment_ok(pts) & ok[:-1] & ok[1:]
        if not seg_ok.all():
            lost = float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)[~seg_ok]))
            bad = int(np.flatnonzero(~ok)[0]) if (~ok).any() else int(np.flatnonzero(~seg_ok)[0])
            why = keep.why(pts[bad]) or "a stretch passes too near an obstacle"
            unreached.append(f"layer {k + 1}: {lost:.1f} m along a wall cannot be flown safely ({why})")
        segments = []
        for r0, r1 in _runs(seg_ok):
            chunk = pts[r0:r1 + 2]
            if arc_length(chunk)[-1] < 1e-6:
                continue
            segments.append(CaptureSegment(
                objective=self.name, kind="layer", index=first + len(segments), points=chunk,
                yaw=yaw[r0:r1 + 2].copy(), pitch=pitch[r0:r1 + 2].copy(), trigger="distance",
                trigger_distance=self.trigger, speed=self.speed, gsd_cm=self.gsd, camera=self.camera.name))
        return segments, moved, unreached
