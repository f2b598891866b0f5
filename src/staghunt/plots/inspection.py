"""Figures of an inspection: the allocation on the site (capture segments coloured by the UAV
that flies them), the planned flight (routes on the site and every UAV's time line), and the
coverage map (photos at the target GSD per ground cell and per facade patch, planned or flown)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.patches import Polygon as PolygonPatch  # noqa: E402

from staghunt.acquisition.coverage import Photos, area_cells, facade_patches, measure_counts  # noqa: E402
from staghunt.io.atomic import atomic_file  # noqa: E402
from staghunt.plots.common import _LABEL, _TITLE, uav_colour  # noqa: E402
from staghunt.plots.site import prisms_top  # noqa: E402
from staghunt.task.objectives import AreaObjective, FacadeObjective, PointObjective  # noqa: E402

__all__ = ["allocation_figure", "coverage_figure", "plan_figure"]

_KIND_COLOUR = {"leg": "0.6", "capture": "#2ca02c", "hover": "#f2b705"}


def _save(fig: Any, path: Path) -> Path:
    with atomic_file(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return Path(path)


def _site(ax: Any, scenario: Any) -> None:
    b = scenario.world.bounds
    terrain = scenario.world.terrain
    if terrain.elevation is not None:
        x0, y0 = terrain.origin
        rows, cols = terrain.elevation.shape
        ext = (x0, x0 + (cols - 1) * terrain.cell_size, y0, y0 + (rows - 1) * terrain.cell_size)
        ax.imshow(terrain.elevation, origin="lower", extent=ext, cmap="Greys", alpha=0.35, zorder=0)
    for c in scenario.world.cylinders:
        ax.add_patch(plt.Circle((c.x, c.y), c.radius, color="#f2b705", alpha=0.7, zorder=2))
    prisms_top(ax, scenario, 0.0)
    ax.set_xlim(b.xmin, b.xmax)
    ax.set_ylim(b.ymin, b.ymax)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m, east)", fontsize=_LABEL)
    ax.set_ylabel("y (m, north)", fontsize=_LABEL)


def _objectives(ax: Any, inspection: Any) -> None:
    for o in inspection.objectives:
        if isinstance(o, AreaObjective):
            ax.add_patch(PolygonPatch(np.asarray(o.polygon), closed=True, fill=False, ec="k", ls="--", lw=1.2, zorder=3))
            ax.annotate(o.name, np.asarray(o.polygon).mean(axis=0), fontsize=8, ha="center", zorder=6)
        elif isinstance(o, PointObjective):
            ax.plot(o.x, o.y, marker="*", color="k", ms=11, zorder=6)
            ax.annotate(o.name, (o.x, o.y), xytext=(4, 4), textcoords="offset points", fontsize=8, zorder=6)


def allocation_figure(scenario: Any, captures: Any, tasks: list[Any], alloc: Any, path: Path) -> Path:
    """Top view: every capture segment in the colour of the UAV that flies it (grey: nobody)."""
    fig, ax = plt.subplots(figsize=(10, 8))
    _site(ax, scenario)
    _objectives(ax, scenario.inspection)
    owner = {v.task: (r.uav, v.way) for r in alloc.routes for v in r.visits}
    for t in tasks:
        uav, way = owner.get(t.index, (None, 0))
        p = t.ways[way].segment.points
        colour = "0.6" if uav is None else uav_colour(uav)
        if len(p) == 1:
            ax.plot(p[0, 0], p[0, 1], "o", color=colour, ms=6, zorder=5)
        else:
            ax.plot(p[:, 0], p[:, 1], color=colour, lw=1.6, zorder=4)
            ax.annotate("", p[-1, :2], p[-2, :2], arrowprops=dict(arrowstyle="->", color=colour, lw=1.2), zorder=4)
    starts = np.array([u.start for u in scenario.team])
    ax.scatter(starts[:, 0], starts[:, 1], c=[uav_colour(n) for n in range(len(starts))], marker="^", s=50, zorder=6)
    handles = [Patch(color=uav_colour(n), label=u.name) for n, u in enumerate(scenario.team)]
    ax.legend(handles=handles, fontsize=8, loc="upper left", ncol=2)
    ax.set_title(f"{scenario.name}: allocation ({alloc.method}), makespan {alloc.makespan:.0f} s, "
                 f"lower bound {alloc.lower_bound:.0f} s", fontsize=_TITLE)
    return _save(fig, path)


def plan_figure(plan: Any, path: Path) -> Path:
    """Left: every UAV's planned flight on the site (captures thick); right: its time line
    (legs, captures, hovers)."""
    fig, (ax, gx) = plt.subplots(1, 2, figsize=(17, 7.5), gridspec_kw={"width_ratios": [1.25, 1]})
    _site(ax, plan.scenario)
    _objectives(ax, plan.inspection)
    tl = plan.timeline
    ts = np.arange(0.0, tl.end + 0.5, 0.5)
    pos = tl.positions(ts)
    for n in range(tl.n):
        ax.plot(pos[n, :, 0], pos[n, :, 1], color=uav_colour(n), lw=0.8, alpha=0.8, zorder=4, label=tl.names[n])
        for p in tl.pieces[n]:
            if p.kind == "capture" and len(p.points) > 1:
                ax.plot(p.points[:, 0], p.points[:, 1], color=uav_colour(n), lw=2.4, zorder=5)
            elif p.kind == "capture":
                ax.plot(p.points[0, 0], p.points[0, 1], "o", color=uav_colour(n), ms=7, zorder=5)
        for p in tl.pieces[n]:
            gx.barh(n, p.t1 - p.t0, left=p.t0, color=_KIND_COLOUR.get(p.kind, "0.6"), edgecolor="none", height=0.6)
    ax.legend(fontsize=8, loc="upper left", ncol=2)
    ax.set_title(f"{plan.scenario.name}: planned inspection, makespan {plan.makespan:.0f} s", fontsize=_TITLE)
    gx.set_yticks(range(tl.n), tl.names)
    gx.invert_yaxis()
    gx.set_xlabel("time after take-off (s)", fontsize=_LABEL)
    gx.legend(handles=[Patch(color=c, label=k) for k, c in _KIND_COLOUR.items()], fontsize=9, loc="lower right")
    gx.set_title("time line: legs, captures, hovers", fontsize=_TITLE)
    return _save(fig, path)


def coverage_figure(scenario: Any, inspection: Any, photos: Photos, path: Path, label: str) -> Path:
    """One panel per area or facade objective: photos at the target GSD per cell (area: on the
    ground; facade: the walls unrolled, distance along the walls against height)."""
    objs = [o for o in inspection.objectives if isinstance(o, (AreaObjective, FacadeObjective))]
    if not objs:
        objs_missing = True
        fig, ax = plt.subplots(figsize=(6, 2))
        ax.text(0.5, 0.5, "no area or facade objective", ha="center")
        ax.axis("off")
        return _save(fig, path) if objs_missing else path
    cell = inspection.coverage_cell()
    cols = min(3, len(objs))
    rows = (len(objs) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(6.2 * cols, 5.2 * rows), squeeze=False)
    for ax, o in zip(axes.flat, objs):
        cam = inspection.camera_for(o)
        mine = photos.take(photos.objective == o.name)
        if isinstance(o, AreaObjective):
            surf = area_cells(o, scenario, cell)
            count = measure_counts(surf, mine, cam, scenario, o.gsd_cm)
            sc = ax.scatter(surf.points[:, 0], surf.points[:, 1], c=np.minimum(count, 15), s=2, marker="s",
                            cmap="viridis", vmin=0, vmax=15)
            ax.set_aspect("equal")
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)")
            share = float(np.mean(count >= 5)) if len(count) else 0.0
            ax.set_title(f"{o.name}: {share:.1%} of cells with >= 5 photos at <= {o.gsd_cm:g} cm/px", fontsize=10)
        else:
            surf = facade_patches(o, scenario, cell)
            count = measure_counts(surf, mine, cam, scenario, o.gsd_cm, o.max_incidence_deg)
            along = _unroll(scenario, o, surf.points)
            sc = ax.scatter(along, surf.points[:, 2], c=np.minimum(count, 15), s=2, marker="s", cmap="viridis",
                            vmin=0, vmax=15)
            ax.set_xlabel("distance along the walls (m)")
            ax.set_ylabel("z (m)")
            share = float(np.mean(count >= 1)) if len(count) else 0.0
            ax.set_title(f"{o.name}: {share:.1%} of patches at <= {o.gsd_cm:g} cm/px, <= {o.max_incidence_deg:g} deg",
                         fontsize=10)
        fig.colorbar(sc, ax=ax, label="photos at the target")
    for ax in list(axes.flat)[len(objs):]:
        ax.axis("off")
    fig.suptitle(f"{scenario.name}: coverage ({label})", fontsize=_TITLE)
    return _save(fig, path)


def _unroll(scenario: Any, o: FacadeObjective, points: np.ndarray) -> np.ndarray:
    from shapely.geometry import Point, Polygon

    prism = next(p for p in scenario.world.prisms if p.name == o.prism)
    ring = Polygon(prism.polygon).exterior
    return np.array([ring.project(Point(p[:2])) for p in points])
