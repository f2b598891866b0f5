"""Points of interest: viewpoints at the objective's distance, aimed at the point.

View ``i`` of ``V`` sits at azimuth ``a0 + 360 i / V`` around the point (``a0``: towards the
team's take-off area, where the UAVs come from), ``elevation_deg`` above it, ``distance`` away;
the gimbal aims at the point. A viewpoint that is not safe (too near an obstacle, outside the
site or its height band, above the ceiling) or whose line of sight a building blocks, or whose
pitch the gimbal cannot reach, turns around the point within its own sector (steps of 5 degrees,
nearest first), then tries 15 and 30 degrees higher or lower; it is reported as moved, or as
unreached when nothing works. Each visit of a recurring objective repeats the views, each with
its time window.
"""

from __future__ import annotations

import math

import numpy as np

from staghunt.acquisition.clearance import Keepout, occluded
from staghunt.acquisition.segments import CaptureSegment, ObjectivePlan
from staghunt.camera import Camera
from staghunt.task.objectives import Payload, PointObjective

__all__ = ["near_side", "plan_point", "target_of"]


def target_of(obj: PointObjective, keep: Keepout) -> np.ndarray:
    """The point's absolute position ``(3,)``."""
    g = float(np.asarray(keep.scenario.world.terrain.height(np.array([obj.x]), np.array([obj.y])))[0])
    return np.array([obj.x, obj.y, g + obj.z])


def _viewpoint(target: np.ndarray, distance: float, azimuth: float, elevation: float) -> np.ndarray:
    return target + distance * np.array([math.cos(elevation) * math.cos(azimuth),
                                         math.cos(elevation) * math.sin(azimuth), math.sin(elevation)])


def near_side(target: np.ndarray, camera: np.ndarray) -> np.ndarray:
    """Where the line of sight is checked to: half a metre short of the point, so that a point
    on a structure's surface (a crane's jib tip) is seen from its own side."""
    d = camera - target
    return target + 0.5 * d / max(float(np.linalg.norm(d)), 1e-9)


def plan_point(obj: PointObjective, camera: Camera, payload: Payload, keep: Keepout, toward: np.ndarray) -> ObjectivePlan:
    """The viewpoints of ``obj`` (every visit), ``toward`` ``(2,)`` the side the team comes from."""
    target = target_of(obj, keep)
    a0 = math.atan2(toward[1] - target[1], toward[0] - target[0])
    sector = 2.0 * math.pi / obj.views
    steps = [0.0] + [s * d for d in np.arange(5.0, 0.5 * math.degrees(sector) + 1e-9, 5.0) for s in (1, -1)]
    e0 = math.radians(obj.elevation_deg)
    lo, hi = math.radians(payload.gimbal_pitch_min_deg), math.radians(payload.gimbal_pitch_max_deg)
    views: list[tuple[np.ndarray, float, float]] = []
    moved: list[str] = []
    unreached: list[str] = []
    for i in range(obj.views):
        found = None
        for de in (0.0, 15.0, -15.0, 30.0, -30.0):
            elev = e0 + math.radians(de)
            if not (lo - 1e-9 <= -elev <= hi + 1e-9) or abs(elev) >= 0.5 * math.pi:
                continue
            for da in steps:
                az = a0 + i * sector + math.radians(da)
                p = _viewpoint(target, obj.distance, az, elev)
                if keep.point_ok(p[None])[0] and not occluded(keep.scenario, p[None], near_side(target, p)[None])[0]:
                    found = (p, az, elev, da, de)
                    break
            if found:
                break
        if found is None:
            p = _viewpoint(target, obj.distance, a0 + i * sector, e0)
            why = keep.why(p) or "every position around it has its line of sight blocked"
            unreached.append(f"view {i + 1}: no safe viewpoint {obj.distance:g} m from the point ({why})")
            continue
        p, az, elev, da, de = found
        if da or de:
            moved.append(f"view {i + 1}: turned by {da:+g} degrees and raised by {de:+g} degrees to be safe "
                         "and see the point")
        views.append((p, az + math.pi, -elev))
    segments: list[CaptureSegment] = []
    for window in obj.windows():
        for p, yaw, pitch in views:
            segments.append(CaptureSegment(
                objective=obj.name, kind="view", index=len(segments), points=p[None].copy(),
                yaw=np.array([math.remainder(yaw, 2 * math.pi)]), pitch=np.array([pitch]), trigger="points",
                trigger_distance=0.0, speed=1.0, gsd_cm=camera.gsd_cm(obj.distance), camera=camera.name,
                dwell_s=obj.dwell_s, reversible=False, window=window))
    return ObjectivePlan(name=obj.name, kind="point", segments=tuple(segments), distance_m=obj.distance,
                         gsd_cm=camera.gsd_cm(obj.distance), moved=tuple(moved), unreached=tuple(unreached),
                         details={"target": target.tolist(), "visits": len(obj.windows())})
