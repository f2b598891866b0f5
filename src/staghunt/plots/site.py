"""The site's prisms (buildings, cranes, boxes) and no-fly zones in the plan figures: walls in
the 3-D view, footprints with their danger band in the top view."""

from __future__ import annotations

import numpy as np
from matplotlib.patches import Patch
from matplotlib.patches import Polygon as PolygonPatch

from staghunt.plots.common import _OBSTACLE_EDGE, _OBSTACLE_FACE

_NOFLY_FACE = "#d0342c"


def prisms_3d(ax: object, scenario: object, gmin: float, ztop: float) -> None:
    """Prisms (buildings, boxes) as translucent walls and roofs from their base (or the ground)
    to their top; no-fly zones as red walls over the whole height of the figure."""
    terrain = scenario.world.terrain  # type: ignore[attr-defined]
    placed: list[tuple[float, float]] = []
    for p in scenario.world.prisms:  # type: ignore[attr-defined]
        v = np.asarray(p.polygon + (p.polygon[0],), dtype=float)
        ground = np.asarray(terrain.height(v[:, 0], v[:, 1]), dtype=float)
        lo = ground if not np.isfinite(p.base) else np.full(len(v), p.base)
        hi = np.full(len(v), min(p.top, ztop))
        face, alpha = (_NOFLY_FACE, 0.12) if p.is_nofly else (_OBSTACLE_FACE, 0.45)
        ax.plot_surface(np.vstack([v[:, 0], v[:, 0]]), np.vstack([v[:, 1], v[:, 1]]),  # type: ignore[attr-defined]
                        np.vstack([lo, hi]), color=face, alpha=alpha, linewidth=0, shade=True, zorder=1)
        edge = _NOFLY_FACE if p.is_nofly else _OBSTACLE_EDGE
        ax.plot(v[:, 0], v[:, 1], hi, color=edge, lw=1.0, zorder=1.1)  # type: ignore[attr-defined]
        ax.plot(v[:, 0], v[:, 1], lo, color=edge, lw=0.8, zorder=1.1)  # type: ignore[attr-defined]
        if p.name:
            cx, cy = _free_spot(placed, v[:-1, 0].mean(), v[:-1, 1].mean(), scenario)
            ax.text(cx, cy, hi[0] + 0.03 * (ztop - gmin), p.name,  # type: ignore[attr-defined]
                    fontsize=8, ha="center", va="bottom", zorder=6,
                    bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.7))


def _free_spot(placed: list[tuple[float, float]], x: float, y: float, scenario: object) -> tuple[float, float]:
    """A label position near ``(x, y)`` at least 4 % of the site's size from the labels already
    ``placed`` (moved north step by step), recorded in ``placed``."""
    b = scenario.world.bounds  # type: ignore[attr-defined]
    step = 0.04 * max(b.xmax - b.xmin, b.ymax - b.ymin)
    while any(abs(x - px) < 2.5 * step and abs(y - py) < step for px, py in placed):
        y += step
    placed.append((x, y))
    return x, y


def prisms_top(ax: object, scenario: object, delta: float) -> list[object]:
    """Prism footprints (amber, labelled with their top height) and no-fly zones (hatched red)
    in the top view, with the danger band ``Delta`` around each footprint; legend handles."""

    prisms = scenario.world.prisms  # type: ignore[attr-defined]
    placed: list[tuple[float, float]] = []
    for p in prisms:
        v = np.asarray(p.polygon, dtype=float)
        if p.is_nofly:
            ax.add_patch(PolygonPatch(v, closed=True, facecolor=_NOFLY_FACE, alpha=0.18,  # type: ignore[attr-defined]
                                      edgecolor=_NOFLY_FACE, hatch="//", lw=1.2, zorder=2))
        else:
            ax.add_patch(PolygonPatch(v, closed=True, facecolor=_OBSTACLE_FACE, alpha=0.7,  # type: ignore[attr-defined]
                                      edgecolor=_OBSTACLE_EDGE, lw=1.2, zorder=2))
        if delta > 0:
            from shapely.geometry import Polygon as ShapelyPolygon

            ring = np.asarray(ShapelyPolygon(v).buffer(delta).exterior.coords)
            ax.plot(ring[:, 0], ring[:, 1], color=_NOFLY_FACE if p.is_nofly else _OBSTACLE_EDGE,  # type: ignore[attr-defined]
                    ls="--", lw=0.9, alpha=0.8, zorder=2)
        label = p.name or ""
        if not p.is_nofly and np.isfinite(p.top):
            label += f" (top z {p.top:.0f} m)"
        if label:
            ax.annotate(label, _free_spot(placed, v[:, 0].mean(), v[:, 1].mean(), scenario),  # type: ignore[attr-defined]
                        ha="center", va="center", fontsize=7.5, zorder=6)
    handles: list[object] = []
    if any(not p.is_nofly for p in prisms):
        handles.append(Patch(facecolor=_OBSTACLE_FACE, edgecolor=_OBSTACLE_EDGE, alpha=0.7,
                             label="building / box (footprint)"))
    if any(p.is_nofly for p in prisms):
        handles.append(Patch(facecolor=_NOFLY_FACE, edgecolor=_NOFLY_FACE, alpha=0.3, hatch="//",
                             label="no-fly zone"))
    return handles
