"""Where a capture may be flown: the clearance of camera positions and of the stretches between
them to the site's obstacles, and the site's box, height band and ceiling.

The same geometry as the planner's hard constraints (:mod:`staghunt.world.geometry`): a cylinder
is cleared by ``R + r + c`` from its axis, a prism or no-fly zone by ``r + c`` from its footprint
where the body is within its altitude band, the ceiling by ``r``; ``r`` is the body radius and
``c`` the scenario's minimum clearance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from staghunt.costs.single import segment_axis_distance
from staghunt.scenario.model import Scenario
from staghunt.world import cylinder_array, prism_arrays
from staghunt.world.geometry import prism_distance

__all__ = ["Keepout", "occluded", "path_clearance", "point_clearance"]


def _clearance(scenario: Scenario, a: np.ndarray, b: np.ndarray, radius: float) -> np.ndarray:
    """``(S,)`` least gap along the segments ``a[i] b[i]`` (``(S, 3)`` each)."""
    world = scenario.world
    out = np.full(len(a), np.inf)
    if not len(a):
        return out
    path = np.stack([a, b], axis=1)[None]  # (1, S, 2, 3): every segment its own two-point path
    cyl = cylinder_array(world.cylinders)
    if len(cyl):
        d = segment_axis_distance(path[..., :2], cyl)[0, :, 0]  # (S, T)
        out = np.minimum(out, (d - cyl[:, 2] - radius).min(axis=1))
    if world.prisms:
        prm, edges = prism_arrays(world.prisms)
        d = prism_distance(path, prm, edges, np.full(len(a), radius), 0.0)[0, :, 0]  # (S, Q)
        out = np.minimum(out, d.min(axis=1) - radius)
    if np.isfinite(world.ceiling):
        out = np.minimum(out, world.ceiling - np.maximum(a[:, 2], b[:, 2]) - radius)
    return out


def occluded(scenario: Scenario, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(R,)`` whether a solid prism (a building, a box; a no-fly zone hides nothing) stands
    between the points ``a`` and ``b`` (``(R, 3)`` each, absolute): the line of sight of a
    camera at ``a`` to ``b``."""
    solid = [p for p in scenario.world.prisms if not p.is_nofly]
    if not solid or not len(a):
        return np.zeros(len(a), dtype=bool)
    prm, edges = prism_arrays(solid)
    ray = np.stack([np.broadcast_to(a, np.shape(b)), b], axis=1)[None]  # (1, R, 2, 3)
    d = prism_distance(ray, prm, edges, np.zeros(len(b)), 0.0)[0, :, 0]  # (R, Q)
    return (d <= 1e-9).any(axis=1)


def path_clearance(scenario: Scenario, points: np.ndarray, radius: float) -> np.ndarray:
    """``(S,)`` least gap (m) between the body and any obstacle or the ceiling along each segment
    of ``points`` ``(S + 1, 3)`` (absolute). Negative: the body touches or enters it; ``inf``:
    nothing near."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    return _clearance(scenario, pts[:-1], pts[1:], radius)


def point_clearance(scenario: Scenario, points: np.ndarray, radius: float) -> np.ndarray:
    """``(M,)`` least gap (m) between a body at each absolute point ``(M, 3)`` and any obstacle
    or the ceiling."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    return _clearance(scenario, pts, pts, radius)


@dataclass(frozen=True, eq=False)
class Keepout:
    """The rules a capture position must meet, for a body of ``radius``: clearance of at least
    ``clearance`` (the scenario's minimum clearance plus ``margin``) to every obstacle and the
    ceiling, inside the site, and a height above ground within the site's band."""

    scenario: Scenario
    radius: float
    margin: float = 0.0

    @property
    def clearance(self) -> float:
        """The scenario's minimum clearance plus ``margin`` (a capture's room for tracking errors)."""
        return float(self.scenario.costs.min_clearance) + self.margin

    def heights(self, points: np.ndarray) -> np.ndarray:
        """``(M,)`` height above ground of absolute ``points`` ``(M, 3)``."""
        g = self.scenario.world.terrain.height(points[:, 0], points[:, 1])
        return points[:, 2] - np.asarray(g, dtype=float)

    def point_ok(self, points: np.ndarray) -> np.ndarray:
        """``(M,)`` which absolute ``points`` ``(M, 3)`` a camera may be at."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        b = self.scenario.world.bounds
        h = self.heights(pts)
        inside = ((pts[:, 0] >= b.xmin) & (pts[:, 0] <= b.xmax) & (pts[:, 1] >= b.ymin) & (pts[:, 1] <= b.ymax)
                  & (h >= b.hmin - 1e-9) & (h <= b.hmax + 1e-9))
        return inside & (point_clearance(self.scenario, pts, self.radius) >= self.clearance)

    def segment_ok(self, points: np.ndarray) -> np.ndarray:
        """``(S,)`` which segments of the polyline ``points`` ``(S + 1, 3)`` clear everything."""
        return path_clearance(self.scenario, points, self.radius) >= self.clearance

    def why(self, point: np.ndarray) -> str:
        """Plain-language reason an absolute ``point`` ``(3,)`` is refused ('' if it is not)."""
        p = np.asarray(point, dtype=float)
        b = self.scenario.world.bounds
        if not b.contains_xy(p[0], p[1]):
            return f"({p[0]:.1f}, {p[1]:.1f}) is outside the site"
        h = float(self.heights(p[None])[0])
        if h < b.hmin - 1e-9:
            return f"{h:.1f} m above ground is below site.hmin = {b.hmin:g} m"
        if h > b.hmax + 1e-9:
            return f"{h:.1f} m above ground is above site.hmax = {b.hmax:g} m"
        if np.isfinite(self.scenario.world.ceiling) and p[2] + self.radius > self.scenario.world.ceiling:
            return f"z = {p[2]:.1f} m is above the ceiling z = {self.scenario.world.ceiling:g} m (with the body radius)"
        gap = float(point_clearance(self.scenario, p[None], self.radius)[0])
        if gap < self.clearance:
            return f"clearance {gap:.2f} m to the nearest obstacle is below the required {self.clearance:g} m"
        return ""
