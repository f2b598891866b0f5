"""Where a photo's frame falls: its four corners projected on the surface it was taken of (the
ground under a photo that looks down, the wall ahead of a level one), for the replay page and the
coverage figures."""

from __future__ import annotations

import math

import numpy as np
from shapely.geometry import LineString, Point, Polygon

from staghunt.acquisition.coverage import Photos
from staghunt.camera import Camera
from staghunt.camera.projection import camera_axes, sensor_extent
from staghunt.scenario.model import Scenario

__all__ = ["footprints"]


def _wall(scenario: Scenario, p: np.ndarray, yaw: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The first wall (of a solid prism) straight ahead of ``p`` along ``yaw``: ``(point, outward normal)``."""
    d = np.array([math.cos(yaw), math.sin(yaw)])
    ray = LineString([p[:2], p[:2] + 2000.0 * d])
    best = None
    for q in scenario.world.prisms:
        if q.is_nofly:
            continue
        ring = Polygon(q.polygon).exterior
        hit = ring.intersection(ray)
        if hit.is_empty:
            continue
        dist = Point(p[:2]).distance(hit)
        if best is None or dist < best[0]:
            best = (dist, q)
    if best is None:
        return None
    dist, q = best
    at = p[:2] + dist * d
    ring = Polygon(q.polygon).exterior
    s = ring.project(Point(at))
    a = np.asarray(ring.interpolate(max(s - 0.5, 0.0)).coords[0])
    b = np.asarray(ring.interpolate(min(s + 0.5, ring.length)).coords[0])
    e = (b - a) / max(float(np.linalg.norm(b - a)), 1e-9)
    n = np.array([e[1], -e[0], 0.0])
    if np.dot(n[:2], d) > 0:
        n = -n
    return np.array([at[0], at[1], p[2]]), n


def footprints(photos: Photos, camera: Camera, scenario: Scenario) -> np.ndarray:
    """``(F, 4, 3)`` the corners of each photo's frame on its surface (``nan`` where a corner ray
    misses it: a photo of the sky)."""
    out = np.full((len(photos), 4, 3), np.nan)
    w, h = sensor_extent(camera)
    F = camera.focal_length_mm
    terrain = scenario.world.terrain
    for i in range(len(photos)):
        c, yaw, pitch = photos.position[i], float(photos.yaw[i]), float(photos.pitch[i])
        f, r, u = camera_axes(np.array(yaw), np.array(pitch))
        dirs = np.array([f + (sx * 0.5 * w / F) * r + (sy * 0.5 * h / F) * u
                         for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
        plane = None
        if pitch > -math.radians(45.0):
            plane = _wall(scenario, c, yaw)
        if plane is None:
            g = float(np.asarray(terrain.height(c[:1], c[1:2]))[0])
            if f[2] < -1e-6:  # refine on the ground where the optical axis meets it
                hit = c + f * (g - c[2]) / f[2]
                g = float(np.asarray(terrain.height(hit[:1], hit[1:2]))[0])
            plane = (np.array([c[0], c[1], g]), np.array([0.0, 0.0, 1.0]))
        point, normal = plane
        denom = dirs @ normal
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((point - c) @ normal) / denom
        ok = (t > 0) & np.isfinite(t)
        out[i, ok] = c + t[ok, None] * dirs[ok]
    return out
