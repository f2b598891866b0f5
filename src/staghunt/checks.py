"""Independent checks of a plan: clearances, separations (at waypoints and along segments),
formation error, and a plain-language list of violated constraints."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from staghunt.costs.formation import (
    formation_errors,
    nearest_segment_distance,
    nearest_waypoint_distance,
)
from staghunt.costs.model import CostModel, full_paths, to_absolute
from staghunt.errors import FieldError
from staghunt.world.geometry import prism_distance
from staghunt.costs.single import segment_axis_distance


@dataclass(frozen=True, eq=False)
class Metrics:
    """Per-UAV checks of one team plan (``N`` UAVs, ``K`` free waypoints); metres.

    - ``path_length``: ``(N,)`` 3-D length of the full path.
    - ``min_clearance``: ``(N,)`` least horizontal gap between the UAV's body and any cylinder
      along its segments: ``d_axis - R - r`` (negative = collision; ``inf`` without obstacles);
      for a prism or no-fly zone ``d - r``, ``d`` the horizontal distance to its footprint of the
      part of a segment within ``(base - r, top + r)`` (docs/model.md 2.2); and the height left
      under the ceiling.
    - ``min_separation_waypoints``: ``(N,)`` least distance to a team-mate at the synchronised
      points (start, free waypoints, goal); ``min_separation_segments``: ``(N,)`` the same for
      the closest approach along synchronised linear segments (``inf`` when alone).
    - ``separation_limit``: ``(N,)`` ``d_s + 2 r_n``; a separation ``<=`` it is a collision.
    - ``formation_error``: ``(N, K)`` eq. 5 at each free waypoint (without the collision ``inf``);
      ``formation_rms``: ``(N,)`` ``sqrt(mean_k E_n(k))``.
    - ``min_height``: ``(N,)`` least height above ground of the free waypoints.
    """

    path_length: np.ndarray
    min_clearance: np.ndarray
    min_separation_waypoints: np.ndarray
    min_separation_segments: np.ndarray
    separation_limit: np.ndarray
    formation_error: np.ndarray
    formation_rms: np.ndarray
    min_height: np.ndarray

    @property
    def obstacle_free(self) -> bool:
        return bool(np.all(self.min_clearance >= 0))

    @property
    def collision_free_waypoints(self) -> bool:
        """Obstacles cleared, above ground, and team-mates apart at the waypoints (the paper's check)."""
        return (
            self.obstacle_free
            and bool(np.all(self.min_height >= 0))
            and bool(np.all(self.min_separation_waypoints > self.separation_limit))
        )

    @property
    def collision_free_continuous(self) -> bool:
        """As :attr:`collision_free_waypoints`, with separation along the whole segments."""
        return self.collision_free_waypoints and bool(
            np.all(self.min_separation_segments > self.separation_limit)
        )


def plan_metrics(model: CostModel, waypoints: np.ndarray) -> Metrics:
    """Metrics of free waypoints ``(N, K, 3)`` (``(x, y, h)``)."""
    path = full_paths(model, waypoints[None])  # (1, N, K+2, 3)
    abs_path = to_absolute(model.terrain, path)
    seg = np.diff(abs_path[0], axis=1)
    length = np.sqrt((seg**2).sum(-1)).sum(-1)
    if model.cylinders.shape[0]:
        dist = segment_axis_distance(path[..., :2], model.cylinders)[0]  # (N, S, T)
        gap = dist - model.cylinders[:, 2] - model.radius[:, None, None]
        clearance = gap.min(axis=(1, 2))
    else:
        clearance = np.full(model.n_uavs, np.inf)
    if model.prisms.shape[0]:
        # Prisms: horizontal gap between the body and the footprint, over the part of each
        # segment within the prism's altitude range grown by r (docs/model.md).
        pd = prism_distance(abs_path, model.prisms, model.prism_edges, model.radius, 0.0)[0]
        clearance = np.minimum(clearance, (pd - model.radius[:, None, None]).min(axis=(1, 2)))
    if np.isfinite(model.ceiling):
        clearance = np.minimum(clearance, (model.ceiling - abs_path[0, :, :, 2]).min(axis=-1))
    E = formation_errors(abs_path[:, :, 1:-1], model.heads, model.tails, model.ref_diff, model.mu)[0]
    return Metrics(
        path_length=length,
        min_clearance=clearance,
        min_separation_waypoints=nearest_waypoint_distance(abs_path)[0].min(axis=-1),
        min_separation_segments=nearest_segment_distance(abs_path)[0].min(axis=-1),
        separation_limit=model.safe_distance + 2.0 * model.radius,
        formation_error=E,
        formation_rms=np.sqrt(E.mean(axis=-1)),
        min_height=waypoints[..., 2].min(axis=-1),
    )


def violations(model: CostModel, waypoints: np.ndarray, names: list[str]) -> list[str]:
    """Plain-language list of the hard constraints a plan ``(N, K, 3)`` violates (empty if none)."""
    out: list[str] = []
    path = full_paths(model, waypoints[None])
    abs_path = to_absolute(model.terrain, path)
    if model.cylinders.shape[0]:
        dist = segment_axis_distance(path[..., :2], model.cylinders)[0]
        inner = model.cylinders[:, 2] + model.radius[:, None, None] + model.min_clearance
        what = "body radius" + (f" and min clearance {model.min_clearance:g} m"
                                if model.min_clearance > 0 else "")
        for n, s, t in zip(*np.nonzero(dist < inner)):
            cx, cy, R = model.cylinders[t]
            out.append(
                f"{names[n]} segment {s} passes {inner[n, 0, t] - dist[n, s, t]:.3g} m inside "
                f"obstacle {t + 1} (x={cx:g}, y={cy:g}, R={R:g}) plus {what}"
            )
    if model.prisms.shape[0]:
        pd = prism_distance(abs_path, model.prisms, model.prism_edges, model.radius, model.min_clearance)[0]
        inner = model.radius[:, None, None] + model.min_clearance
        for n, s, q in zip(*np.nonzero(pd < inner)):
            out.append(f"{names[n]} segment {s} passes {inner[n, 0, 0] - pd[n, s, q]:.3g} m inside "
                       f"prism {q + 1} (footprint plus body radius and min clearance)")
    if np.isfinite(model.ceiling):
        for n, k in zip(*np.nonzero(abs_path[0, :, :, 2] > model.ceiling)):
            out.append(f"{names[n]} point {k} is {abs_path[0, n, k, 2] - model.ceiling:.3g} m above "
                       f"the ceiling z = {model.ceiling:g} m")
    for n, k in zip(*np.nonzero(waypoints[..., 2] < 0)):
        out.append(f"{names[n]} waypoint {k + 1} is {-waypoints[n, k, 2]:.3g} m below ground")
    limit = model.safe_distance + 2.0 * model.radius
    if model.n_uavs > 1:
        near = nearest_segment_distance(abs_path)[0]  # (N, S)
        for n, s in zip(*np.nonzero(near <= limit[:, None])):
            out.append(
                f"{names[n]} comes within {near[n, s]:.3g} m of a team-mate on segment {s} "
                f"(limit d_s + 2r = {limit[n]:g} m)"
            )
    return out


def outside_site(model: CostModel, waypoints: np.ndarray, names: list[str]) -> list[str]:
    """Plain-language list of the free waypoints ``(N, K, 3)`` (``(x, y, h)``) that leave the
    site box (x, y within the site, h within ``[hmin, hmax]`` above ground); empty if none.

    The planner's decoding keeps every waypoint inside the box; hand-made paths may not."""
    lower, upper = np.asarray(model.lower, dtype=float), np.asarray(model.upper, dtype=float)
    out: list[str] = []
    labels = ("x", "y", "h")
    wp = np.asarray(waypoints, dtype=float)
    with np.errstate(invalid="ignore"):
        low, high = wp < lower, wp > upper
    for n, k, c in zip(*np.nonzero(low | high)):
        v = wp[n, k, c]
        side, limit = ("below", lower[c]) if low[n, k, c] else ("above", upper[c])
        bound = {("x", "below"): "xmin", ("x", "above"): "xmax", ("y", "below"): "ymin",
                 ("y", "above"): "ymax", ("h", "below"): "hmin", ("h", "above"): "hmax"}[(labels[c], side)]
        out.append(f"{names[n]} waypoint {k + 1} leaves the site box: {labels[c]} = {v:.6g} is {side} "
                   f"site.{bound} = {limit:g}")
    return out


def check_inside_site(model: CostModel, waypoints: np.ndarray, names: list[str], source: str | None = None) -> None:
    """Refuse a plan that the site does not hold: a :class:`~staghunt.errors.FieldError` (field
    ``waypoints``) naming the first waypoint outside the site box (:func:`outside_site`) and
    ``source``, the file the plan comes from (certify, fly: no search, no flight for it)."""
    outside = outside_site(model, waypoints, names)
    if outside:
        where = f"{source}: uavs: " if source else ""
        more = f" (and {len(outside) - 1} more)" if len(outside) > 1 else ""
        raise FieldError(f"{where}{outside[0]}{more}", "waypoints")
