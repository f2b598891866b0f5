"""Figures of a plan (paper Figs. 4-8): 3-D paths, top view, altitude and convergence.

Every function builds a fresh :class:`matplotlib.figure.Figure` without ``pyplot``, so no global
state (backend, current figure, figure registry) changes and a figure is freed as soon as it is no
longer referenced.

Each UAV keeps one colour in every figure (:func:`~staghunt.plots.common.uav_colour`); obstacles
are drawn in amber, the virtual leader of the ``rigid`` method in black, dashed.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle

from staghunt.io.atomic import atomic_file
from staghunt.plots.common import (
    _legend_handles,
    _LABEL,
    _LEADER,
    _LEGEND,
    _LINK,
    _OBSTACLE_EDGE,
    _OBSTACLE_FACE,
    _TICK,
    _TITLE,
    _edges,
    _ground_grid,
    _ground_range,
    _leader_heights,
    _names,
    _style_axes,
    _title,
    uav_colour,
)
from staghunt.plots.equilibria import EquilibriaPanel, equilibria_figure
from staghunt.plots.site import prisms_3d, prisms_top
from staghunt.result import PlanResult


# --------------------------------------------------------------------------------------------
# figures
# --------------------------------------------------------------------------------------------


def plot_paths_3d(result: PlanResult) -> Figure:
    """3-D view of the site, obstacles and the team's paths (paper Figs. 4, 6, 7).

    Cylinders rise from the ground to the top of the height band; dotted lines join the team
    at every synchronised waypoint so the formation shape can be read along the flight.
    """
    scenario = result.scenario
    b = scenario.world.bounds
    terrain = scenario.world.terrain
    paths = np.asarray(result.paths, dtype=float)
    names = _names(result)
    gmin, gmax = _ground_range(result)
    ztop = gmax + b.hmax

    fig = Figure(figsize=(10, 8), layout="constrained")
    # Fixed draw order (ground, obstacles, links, paths, markers): mplot3d's depth sorting often
    # hides a path behind a translucent cylinder it actually passes in front of.
    ax = fig.add_subplot(projection="3d", computed_zorder=False)

    # ground
    X, Y, G = _ground_grid(result)
    if terrain.elevation is None:
        ax.plot_surface(X, Y, G, color="0.85", alpha=0.25, linewidth=0, shade=False, zorder=0)
    else:
        ax.plot_surface(X, Y, G, cmap="gist_earth", alpha=0.45, linewidth=0, antialiased=True,
                        vmin=gmin - 0.2 * (gmax - gmin + 1), vmax=gmax + 0.6 * (gmax - gmin + 1),
                        zorder=0)

    # site box
    xs = (b.xmin, b.xmax)
    ys = (b.ymin, b.ymax)
    zs = (gmin, ztop)
    box = dict(color="0.6", lw=0.7, ls="-", zorder=0.5)
    for y in ys:
        for z in zs:
            ax.plot(xs, (y, y), (z, z), **box)
    for x in xs:
        for z in zs:
            ax.plot((x, x), ys, (z, z), **box)
    for x in xs:
        for y in ys:
            ax.plot((x, x), (y, y), zs, **box)

    # obstacles: translucent cylinders from the ground to the top of the height band
    theta = np.linspace(0.0, 2.0 * np.pi, 48)
    for c in scenario.world.cylinders:
        cx = c.x + c.radius * np.cos(theta)
        cy = c.y + c.radius * np.sin(theta)
        bottom = np.asarray(terrain.height(cx, cy), dtype=float)
        top = np.full_like(bottom, float(bottom.max()) + b.hmax)
        ax.plot_surface(np.vstack([cx, cx]), np.vstack([cy, cy]), np.vstack([bottom, top]),
                        color=_OBSTACLE_FACE, alpha=0.35, linewidth=0, shade=True, zorder=1)
        ax.plot(cx, cy, top, color=_OBSTACLE_EDGE, lw=1.0, zorder=1.1)
        ax.plot(cx, cy, bottom, color=_OBSTACLE_EDGE, lw=0.8, zorder=1.1)
        if c.name:
            ax.text(c.x, c.y, top[0] + 0.03 * (ztop - gmin), c.name, fontsize=9, ha="center",
                    va="bottom", color="black", zorder=6,
                    bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.7))
    prisms_3d(ax, scenario, gmin, ztop)

    # formation links at each synchronised waypoint
    for h, t in _edges(result):
        for k in range(paths.shape[1]):
            p, q = paths[h, k], paths[t, k]
            ax.plot((p[0], q[0]), (p[1], q[1]), (p[2], q[2]), color=_LINK, ls=":", lw=0.9,
                    zorder=2)

    # paths, starts and goals
    handles: list[object] = []
    for n, name in enumerate(names):
        col = uav_colour(n)
        (line,) = ax.plot(paths[n, :, 0], paths[n, :, 1], paths[n, :, 2], color=col, lw=2.0,
                          marker="o", ms=3.5, label=name, zorder=3)
        handles.append(line)
        ax.scatter(*paths[n, 0], s=70, marker="o", facecolor=col, edgecolor="black", linewidth=1.0,
                   depthshade=False, zorder=4)
        ax.scatter(*paths[n, -1], s=190, marker="*", facecolor=col, edgecolor="black",
                   linewidth=0.8, depthshade=False, zorder=4)
    if result.leader_path is not None:
        lp = np.asarray(result.leader_path, dtype=float)
        (lead,) = ax.plot(lp[:, 0], lp[:, 1], lp[:, 2], color=_LEADER, ls="--", lw=1.5,
                          marker="x", ms=4, label="virtual leader", zorder=3.5)
        handles.append(lead)

    # one "start" / "goal" label per cluster, lifted above the team
    lift = 0.16 * (ztop - gmin)
    for idx, word in ((0, "start"), (-1, "goal")):
        centre = paths[:, idx].mean(axis=0)
        ax.text(centre[0], centre[1], paths[:, idx, 2].max() + lift, word, fontsize=10.5,
                ha="center", va="bottom", weight="bold", zorder=6)

    handles += _legend_handles(result, "obstacle", alpha=0.6)
    big = len(names) > 12  # a large team: a compact legend in columns, out of the paths' way
    ax.legend(handles=handles, loc="upper left", fontsize=_LEGEND - (2 if big else 0), framealpha=0.9,
              ncol=4 if big else 1)

    ax.set_xlim(b.xmin, b.xmax)
    ax.set_ylim(b.ymin, b.ymax)
    ax.set_zlim(gmin, ztop)
    dx, dy, dz = b.xmax - b.xmin, b.ymax - b.ymin, ztop - gmin
    horizontal = max(dx, dy)
    # true proportions, but never flatter than 0.3 or taller than the horizontal extent
    ax.set_box_aspect((dx, dy, float(np.clip(dz, 0.3 * horizontal, horizontal))), zoom=1.12)
    ax.view_init(elev=28, azim=-62)
    ax.set_xlabel("x (m)", fontsize=_LABEL, labelpad=8)
    ax.set_ylabel("y (m)", fontsize=_LABEL, labelpad=8)
    ax.set_zlabel("z (m)", fontsize=_LABEL, labelpad=4)
    ax.tick_params(labelsize=_TICK)
    ax.set_title(_title(result, "Paths"), fontsize=_TITLE)
    return fig


def plot_top_view(result: PlanResult) -> Figure:
    """Top (x-y) view: obstacles with their danger margin ``R + Delta``, paths, formation shape."""
    scenario = result.scenario
    b = scenario.world.bounds
    terrain = scenario.world.terrain
    paths = np.asarray(result.paths, dtype=float)
    names = _names(result)
    delta = float(scenario.costs.danger_margin)
    keep_out = float(scenario.costs.min_clearance) + max(u.radius for u in scenario.team)

    fig = Figure(figsize=(10, 8), layout="constrained")
    ax = fig.add_subplot()
    handles: list[object] = []

    if terrain.elevation is not None:
        X, Y, G = _ground_grid(result, max_cells=200)
        cs = ax.contourf(X, Y, G, levels=12, cmap="Greys", alpha=0.35, zorder=0)
        cbar = fig.colorbar(cs, ax=ax, shrink=0.7, pad=0.01)
        cbar.set_label("ground elevation (m)", fontsize=_LABEL)
        cbar.ax.tick_params(labelsize=_TICK)

    for c in scenario.world.cylinders:
        ax.add_patch(Circle((c.x, c.y), c.radius, facecolor=_OBSTACLE_FACE,
                            edgecolor=_OBSTACLE_EDGE, alpha=0.75, lw=1.2, zorder=2))
        if delta > 0:
            ax.add_patch(Circle((c.x, c.y), c.radius + delta, fill=False, edgecolor=_OBSTACLE_EDGE,
                                ls="--", lw=1.0, alpha=0.9, zorder=2))
        ax.add_patch(Circle((c.x, c.y), c.radius + keep_out, fill=False, edgecolor="#b00020",
                            ls="-", lw=0.9, alpha=0.8, zorder=2))
        if c.name:
            ax.annotate(c.name, (c.x, c.y), ha="center", va="center", fontsize=8.5,
                        color="black", zorder=6)
    handles += prisms_top(ax, scenario, delta)

    for h, t in _edges(result):  # the formation's shape at every waypoint index k
        for k in range(paths.shape[1]):
            p, q = paths[h, k], paths[t, k]
            ax.plot((p[0], q[0]), (p[1], q[1]), color=_LINK, ls=":", lw=1.1, zorder=3)

    length = np.asarray(result.metrics.path_length, dtype=float)
    for n, name in enumerate(names):
        col = uav_colour(n)
        label = f"{name} ({length[n]:.1f} m)" if n < length.size else name
        (line,) = ax.plot(paths[n, :, 0], paths[n, :, 1], color=col, lw=2.0, marker="o", ms=4,
                          label=label, zorder=4)
        handles.append(line)
        ax.plot(*paths[n, 0, :2], ls="none", marker="o", ms=9, mfc=col, mec="black", zorder=5)
        ax.plot(*paths[n, -1, :2], ls="none", marker="*", ms=16, mfc=col, mec="black", mew=0.8,
                zorder=5)
    if result.leader_path is not None:
        lp = np.asarray(result.leader_path, dtype=float)
        (lead,) = ax.plot(lp[:, 0], lp[:, 1], color=_LEADER, ls="--", lw=1.4, marker="x", ms=5,
                          label="virtual leader", zorder=4)
        handles.append(lead)

    handles += _legend_handles(result, "obstacle (radius R)", alpha=0.75)
    if scenario.world.cylinders:
        if delta > 0:
            handles.append(Line2D([], [], color=_OBSTACLE_EDGE, ls="--", lw=1.0,
                                  label=f"danger margin R + Δ (Δ = {delta:g} m)"))
        handles.append(Line2D([], [], color="#b00020", ls="-", lw=0.9,
                              label=f"keep-out for UAV centres R + r + c ({keep_out:g} m)"))
    fig.legend(handles=handles, loc="outside right upper", fontsize=_LEGEND,
               title="path length in brackets", title_fontsize=_LEGEND)

    pad = 0.02 * max(b.xmax - b.xmin, b.ymax - b.ymin)
    ax.set_xlim(b.xmin - pad, b.xmax + pad)
    ax.set_ylim(b.ymin - pad, b.ymax + pad)
    ax.plot([b.xmin, b.xmax, b.xmax, b.xmin, b.xmin], [b.ymin, b.ymin, b.ymax, b.ymax, b.ymin],
            color="0.5", lw=0.8, zorder=1)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (m)", fontsize=_LABEL)
    ax.set_ylabel("y (m)", fontsize=_LABEL)
    _style_axes(ax)
    ax.set_title(_title(result, "Top view"), fontsize=_TITLE)
    return fig


def _profiles_coincide(heights: np.ndarray, tol: float = 0.25) -> bool:
    """Whether two of the ``(N, K + 2)`` height profiles lie within ``tol`` metres throughout."""
    for a in range(heights.shape[0]):
        for b in range(a + 1, heights.shape[0]):
            if np.all(np.abs(heights[a] - heights[b]) < tol):
                return True
    return False


def plot_altitude(result: PlanResult) -> Figure:
    """Height above ground of each UAV against the waypoint index (paper Fig. 5)."""
    scenario = result.scenario
    b = scenario.world.bounds
    heights = np.asarray(result.heights, dtype=float)
    names = _names(result)
    k = np.arange(heights.shape[1])

    fig = Figure(figsize=(9, 5.5), layout="constrained")
    ax = fig.add_subplot()
    ax.axhspan(b.hmin, b.hmax, color="tab:green", alpha=0.08, lw=0,
               label=f"height band [{b.hmin:g}, {b.hmax:g}] m")
    ax.axhline(scenario.h_ref, color="black", ls="--", lw=1.2,
               label=f"desired height {scenario.h_ref:g} m")
    # Where profiles coincide (a rigid formation keeps one height), earlier UAVs are drawn wider
    # so the identical curves show as nested bands instead of hiding each other.
    n_uav = len(names)
    scale = 1.0 if _profiles_coincide(heights) else 0.0
    for n, name in enumerate(names):
        wider = scale * (n_uav - 1 - n)
        ax.plot(k, heights[n], color=uav_colour(n), lw=2.0 + 2.0 * wider, marker="o",
                ms=5 + 2.5 * wider, label=name, zorder=2 + n)
    lead = _leader_heights(result)
    if lead is not None:
        ax.plot(np.arange(lead.size), lead, color=_LEADER, ls="--", lw=1.2, marker="x", ms=5,
                label="virtual leader", zorder=3 + n_uav)

    finite = heights[np.isfinite(heights)]
    low = min(0.0, b.hmin, float(finite.min()) if finite.size else 0.0)
    high = max(b.hmax, float(finite.max()) if finite.size else b.hmax)
    span = high - low
    ax.set_ylim(low - 0.03 * span, high + 0.05 * span)
    ax.set_xlim(-0.3, k[-1] + 0.3)
    ax.set_xticks(k)
    labels = [str(i) for i in k]
    labels[0], labels[-1] = "start", "goal"
    ax.set_xticklabels(labels)
    ax.set_xlabel("waypoint index k", fontsize=_LABEL)
    ax.set_ylabel("height above ground (m)", fontsize=_LABEL)
    _style_axes(ax)
    fig.legend(loc="outside right upper", fontsize=_LEGEND)
    title = _title(result, "Altitude")
    if scale:
        title += "\ncoinciding profiles are drawn as nested bands (widest: first UAV)"
    ax.set_title(title, fontsize=_TITLE if not scale else _TITLE - 1)
    return fig


def _positive_finite(v: np.ndarray) -> np.ndarray:
    return np.isfinite(v) & (v > 0)


def plot_convergence(result: PlanResult) -> Figure:
    """Natural log of each UAV's best cost ``J_n`` against the iteration (paper Fig. 8).

    Iterations whose best cost is still infinite (no feasible allocation yet) are left out; a
    hollow marker and a dotted vertical line show where each curve first becomes finite. For a
    single-objective method (``rigid``) the team objective the swarm minimised is added.
    """
    history = np.asarray(result.history, dtype=float)
    if history.ndim == 1:
        history = history[:, None]
    objective = np.asarray(result.objective_history, dtype=float)
    if objective.ndim == 1:
        objective = objective[:, None]
    names = _names(result)
    it = np.arange(history.shape[0])

    fig = Figure(figsize=(9, 6.5), layout="constrained")
    ax = fig.add_subplot()
    notes: list[str] = []
    first_marks: list[int] = []
    drawn: list[bool] = []

    def curve(values: np.ndarray, label: str, **style: object) -> None:
        ok = _positive_finite(values)
        if not ok.any():
            ax.plot([], [], label=f"{label}: never finite", **style)
            return
        drawn.append(True)
        first = int(np.argmax(ok))
        y = np.where(ok, np.log(np.where(ok, values, 1.0)), np.nan)
        since = f", finite from iteration {first}" if first > 0 else ""
        ax.plot(it, y, label=f"{label}: final {y[ok][-1]:.2f}{since}", **style)
        if first > 0:
            ax.plot(it[first], y[first], ls="none", marker="o", ms=8, mfc="white",
                    mec=style.get("color", "black"), mew=1.5, zorder=5)
            first_marks.append(first)

    for n, name in enumerate(names[: history.shape[1]]):
        curve(history[:, n], name, color=uav_colour(n), lw=2.0)

    same = objective.shape == history.shape and np.array_equal(objective, history, equal_nan=True)
    if objective.shape[0] == history.shape[0] and not same:
        for c in range(objective.shape[1]):
            label = ("team objective Σ J_n (virtual UAV)" if objective.shape[1] == 1
                     else f"objective {c + 1}")
            curve(objective[:, c], label, color=_LEADER, ls="--", lw=1.6)

    for first in sorted(set(first_marks)):
        ax.axvline(first, color="0.4", ls=":", lw=1.0)
    if first_marks:
        notes.append(f"first finite at iteration {min(first_marks)}")
        ax.plot([], [], ls=":", color="0.4", marker="o", mfc="white", mec="0.4",
                label="first finite cost (before it: ∞, infeasible)")

    if not drawn:
        ax.text(0.5, 0.5,
                "no finite cost in any iteration\n(every allocation found was infeasible)",
                transform=ax.transAxes, ha="center", va="center", fontsize=_LABEL, color="0.3")
        ax.set_yticks([])
    if history.shape[0] > 1:
        ax.set_xlim(0, it[-1])
    ax.set_xlabel("iteration", fontsize=_LABEL)
    ax.set_ylabel("ln J_n", fontsize=_LABEL)
    _style_axes(ax)
    n_entries = len(ax.get_legend_handles_labels()[0])
    fig.legend(loc="outside lower center", fontsize=_LEGEND, ncols=min(2, max(1, n_entries)),
               title="best cost per curve (final ln J)", title_fontsize=_LEGEND)
    sub = "natural log of each UAV's best J_n"
    if notes:
        sub += "; " + "; ".join(notes)
    ax.set_title(_title(result, "Convergence") + "\n" + sub, fontsize=_TITLE - 1)
    return fig


# --------------------------------------------------------------------------------------------
# saving
# --------------------------------------------------------------------------------------------

FIGURES: dict[str, Callable[[PlanResult], Figure]] = {
    "paths_3d.png": plot_paths_3d,
    "top_view.png": plot_top_view,
    "altitude.png": plot_altitude,
    "convergence.png": plot_convergence,
}


def _save_atomic(fig: Figure, target: Path, dpi: int) -> None:
    """Write ``fig`` to ``target`` through a temporary file in the same directory."""
    with atomic_file(target, "wb") as fh:
        fig.savefig(fh, format="png", dpi=dpi)


def plot_equilibria(result: PlanResult) -> Figure:
    """The distinct equilibria a multi-start ``game`` run found, the selected one marked."""
    eq = result.details["equilibria"]
    selected = [e["J"] for e in eq if e["selected"]]
    panel = EquilibriaPanel(_title(result, "Equilibria found"), np.array([e["J"] for e in eq]),
                            np.array([e["dominated"] for e in eq]), np.array(selected), tuple(result.uav_names))
    return equilibria_figure([panel])


def save_figures(result: PlanResult, out_dir: Path | str, dpi: int = 130) -> list[Path]:
    """Write ``paths_3d.png``, ``top_view.png``, ``altitude.png`` and ``convergence.png``, and
    ``equilibria.png`` for a multi-start ``game`` run.

    ``out_dir`` is created if needed; each file is replaced atomically. Returns the paths.
    """
    if not isinstance(dpi, int) or dpi < 10:
        raise ValueError(f"dpi must be an integer >= 10, got {dpi!r}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    makers = dict(FIGURES)
    if result.details.get("equilibria"):
        makers["equilibria.png"] = plot_equilibria
    for filename, make in makers.items():
        fig = make(result)
        try:
            target = out / filename
            _save_atomic(fig, target, dpi)
            written.append(target)
        finally:
            fig.clear()  # drop the artists now; the Figure is not registered anywhere
    return written
