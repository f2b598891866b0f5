"""Figures of a simulated (closed-loop) flight, from a plain *flight dict*.

The flight dict (site frame, metres, seconds) holds ``title``; ``site`` (``xmin`` ... ``zmax``);
``times`` ``(T,)``; ``uavs``, each with ``name``, ``radius``, ``actual`` ``(T, 3)`` (the simulated
vehicle) and ``reference`` ``(T, 3)`` (what it tracks); static ``cylinders`` ``[[x, y, R], ...]``
(from z = 0 to ``zmax``) and ``prisms`` (``polygon`` ``(V, 2)``, absolute ``base`` / ``top``,
``nofly``); ``moving`` obstacles (``kind`` ``"cylinder"`` with ``radius`` and ``xy`` ``(T, 2)``,
or ``"polygon"`` with ``base``, ``top`` and ``polygons`` ``(T, V, 2)``; ``visible`` ``(T,)``);
``replans`` (``time``, ``trigger``, ``verdict``); optional ``terrain`` (``x`` ``(J,)``, ``y``
``(I,)``, ``z`` ``(I, J)``) and ``separation_limit`` (m).

:func:`flight_figures` writes five PNGs (:func:`staghunt.plots.animation.flight_animation` a
top-view GIF from the same dict). Like the other
figures they use no ``pyplot`` (no global matplotlib state) and are written atomically.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch
from matplotlib.patches import Polygon as PolygonPatch

from staghunt.plots.common import (
    _LABEL,
    _LEGEND,
    _OBSTACLE_EDGE,
    _OBSTACLE_FACE,
    _TITLE,
    _style_axes,
    uav_colour,
)
from staghunt.plots.mission import _save
from staghunt.plots.replay import _MOVING, _array, _site
from staghunt.plots.site import _NOFLY_FACE

FLIGHT_FIGURES = ("flight_3d.png", "flight_top.png", "flight_altitude.png", "flight_tracking.png",
                  "flight_separation.png")


# --------------------------------------------------------------------------------------------
# data
# --------------------------------------------------------------------------------------------


class _Flight:
    """The flight dict as arrays: ``t`` ``(T,)``, ``actual`` / ``reference`` ``(N, T, 3)``."""

    def __init__(self, flight: dict[str, Any]) -> None:
        self.raw = flight
        self.title = str(flight.get("title", "flight"))
        self.site = _site(flight)
        self.t = _array(flight["times"], (None,), "times")
        T = self.t.size
        uavs = flight.get("uavs", [])
        self.names = [str(u.get("name", f"UAV{n + 1}")) for n, u in enumerate(uavs)]
        self.actual = np.stack([_array(u["actual"], (T, 3), f"{nm}.actual")
                                for nm, u in zip(self.names, uavs)]) if uavs else np.zeros((0, T, 3))
        self.reference = np.stack([_array(u.get("reference", u["actual"]), (T, 3), f"{nm}.reference")
                                   for nm, u in zip(self.names, uavs)]) if uavs else np.zeros((0, T, 3))
        self.moving = list(flight.get("moving", []))
        self.replans = [(float(r["time"]), str(r.get("trigger", "")), str(r.get("verdict", "")))
                        for r in flight.get("replans", [])]

    def visible(self, m: dict[str, Any]) -> np.ndarray:
        """``(T,)`` booleans: when obstacle ``m`` is there."""
        v = m.get("visible")
        return np.ones(self.t.size, dtype=bool) if v is None else np.asarray(v, dtype=bool)

    def at(self, time: float) -> np.ndarray:
        """``(N, 3)`` actual positions at ``time`` (linear interpolation)."""
        return np.stack([[np.interp(time, self.t, a[:, d]) for d in range(3)] for a in self.actual]) \
            if len(self.names) else np.zeros((0, 3))

    def zlim(self, value: Any, default: float) -> float:
        return float(np.clip(default if value is None else float(value), self.site["zmin"], self.site["zmax"]))


def _fig_title(f: _Flight, what: str) -> str:
    return f"{what}: {f.title}"


def _replan_lines(ax: Axes, f: _Flight) -> None:
    """Dotted vertical lines at the replans, labelled R1, R2, ... along the top."""
    for j, (t, _, _) in enumerate(f.replans):
        ax.axvline(t, color=_MOVING, ls=":", lw=1.1, zorder=1)
        if len(f.replans) <= 20:
            ax.text(t, 1.0, f" R{j + 1}", transform=ax.get_xaxis_transform(), color=_MOVING,
                    fontsize=8, ha="left", va="top")


def _replan_handles(f: _Flight) -> list[Any]:
    """The legend entry of :func:`_replan_lines` (none without replans)."""
    return [Line2D([], [], color=_MOVING, ls=":", lw=1.1, label="replan")] if f.replans else []


def _legend(fig: Figure, handles: list[Any], n_uavs: int) -> None:
    big = n_uavs > 12
    fig.legend(handles=handles, loc="outside right upper", fontsize=_LEGEND - (1.5 if big else 0),
               ncols=2 if big else 1)


def _common_handles(f: _Flight) -> list[Any]:
    h: list[Any] = [Line2D([], [], color="0.3", ls="--", lw=1.0, label="reference (dashed)")]
    if f.replans:
        h.append(Line2D([], [], ls="none", marker="X", ms=8, mfc=_MOVING, mec="white", label="replan"))
    if f.raw.get("cylinders") or any(not p.get("nofly") for p in f.raw.get("prisms", [])):
        h.append(Patch(facecolor=_OBSTACLE_FACE, edgecolor=_OBSTACLE_EDGE, alpha=0.6, label="static obstacle"))
    if any(p.get("nofly") for p in f.raw.get("prisms", [])):
        h.append(Patch(facecolor=_NOFLY_FACE, edgecolor=_NOFLY_FACE, alpha=0.3, hatch="//", label="no-fly zone"))
    if f.moving:
        h.append(Patch(facecolor=_MOVING, edgecolor=_MOVING, alpha=0.35, label="moving / pop-up obstacle"))
    return h


# --------------------------------------------------------------------------------------------
# figures
# --------------------------------------------------------------------------------------------


def _walls(ax: Any, xy: np.ndarray, lo: float, hi: float, face: str, edge: str, alpha: float) -> None:
    """A prism over the ``(V, 2)`` footprint ``xy`` from ``lo`` to ``hi`` in a 3-D axes."""
    v = np.vstack([xy, xy[:1]])
    ax.plot_surface(np.vstack([v[:, 0], v[:, 0]]), np.vstack([v[:, 1], v[:, 1]]),
                    np.vstack([np.full(len(v), lo), np.full(len(v), hi)]), color=face, alpha=alpha,
                    linewidth=0, shade=True, zorder=1)
    for z in (lo, hi):
        ax.plot(v[:, 0], v[:, 1], np.full(len(v), z), color=edge, lw=0.9, zorder=1.1)


def _circle(x: float, y: float, r: float, n: int = 48) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    return np.stack([x + r * np.cos(a), y + r * np.sin(a)], axis=1)


def _first(vis: np.ndarray) -> int | None:
    return int(np.argmax(vis)) if vis.any() else None


def plot_flight_3d(f: _Flight) -> Figure:
    """3-D view: site box, static obstacles, moving ones where they first appear (their track on
    the ground), actual paths (solid), references (dashed) and the team at each replan (X)."""
    s = f.site
    fig = Figure(figsize=(10, 8), layout="constrained")
    ax = fig.add_subplot(projection="3d", computed_zorder=False)
    terrain = f.raw.get("terrain")
    if terrain:
        X, Y = np.meshgrid(np.asarray(terrain["x"], float), np.asarray(terrain["y"], float))
        ax.plot_surface(X, Y, np.asarray(terrain["z"], float), cmap="gist_earth", alpha=0.4, linewidth=0, zorder=0)
    else:
        X, Y = np.meshgrid([s["xmin"], s["xmax"]], [s["ymin"], s["ymax"]])
        ax.plot_surface(X, Y, np.full_like(X, s["zmin"]), color="0.85", alpha=0.25, linewidth=0, shade=False, zorder=0)
    for x in (s["xmin"], s["xmax"]):
        for y in (s["ymin"], s["ymax"]):
            ax.plot((x, x), (y, y), (s["zmin"], s["zmax"]), color="0.6", lw=0.7, zorder=0.5)
    for z in (s["zmin"], s["zmax"]):
        ax.plot([s["xmin"], s["xmax"], s["xmax"], s["xmin"], s["xmin"]],
                [s["ymin"], s["ymin"], s["ymax"], s["ymax"], s["ymin"]], z, color="0.6", lw=0.7, zorder=0.5)
    base = f.zlim(0.0, 0.0)
    for c in f.raw.get("cylinders", []):
        _walls(ax, _circle(*c[:3]), base, s["zmax"], _OBSTACLE_FACE, _OBSTACLE_EDGE, 0.3)
    for p in f.raw.get("prisms", []):
        nofly = bool(p.get("nofly"))
        _walls(ax, np.asarray(p["polygon"], float), f.zlim(p.get("base"), s["zmin"]), f.zlim(p.get("top"), s["zmax"]),
               _NOFLY_FACE if nofly else _OBSTACLE_FACE, _NOFLY_FACE if nofly else _OBSTACLE_EDGE, 0.12 if nofly else 0.4)
    for m in f.moving:
        vis = f.visible(m)
        k = _first(vis)
        if k is None:
            continue
        if m.get("kind") == "polygon":
            foot = np.asarray(m["polygons"][k], float)
            _walls(ax, foot, f.zlim(m.get("base"), s["zmin"]), f.zlim(m.get("top"), s["zmax"]), _MOVING, _MOVING, 0.35)
            top = f.zlim(m.get("top"), s["zmax"])
        else:
            xy = np.asarray(m["xy"], float)
            top = f.zlim(m.get("top"), s["zmax"])
            _walls(ax, _circle(xy[k, 0], xy[k, 1], float(m.get("radius", 1.0))), f.zlim(m.get("base"), base), top,
                   _MOVING, _MOVING, 0.3)
            track = np.where(vis[:, None], xy, np.nan)
            ax.plot(track[:, 0], track[:, 1], np.full(len(track), s["zmin"]), color=_MOVING, ls=":", lw=1.2, zorder=1.2)
            foot = xy[k : k + 1]
        ax.text(*foot.mean(axis=0), top, str(m.get("name", "")) + (f" (from {f.t[k]:.1f} s)" if k else ""),
                color=_MOVING, fontsize=8.5,
                ha="center", va="bottom", zorder=6)
    handles: list[Any] = []
    for n, name in enumerate(f.names):
        col = uav_colour(n)
        a, r = f.actual[n], f.reference[n]
        ax.plot(r[:, 0], r[:, 1], r[:, 2], color=col, ls="--", lw=1.0, alpha=0.8, zorder=2)
        (line,) = ax.plot(a[:, 0], a[:, 1], a[:, 2], color=col, lw=1.8, label=name, zorder=3)
        handles.append(line)
        ax.scatter(*a[0], s=50, marker="o", facecolor=col, edgecolor="black", depthshade=False, zorder=4)
        ax.scatter(*a[-1], s=140, marker="*", facecolor=col, edgecolor="black", linewidth=0.7, depthshade=False, zorder=4)
    for j, (t, _, _) in enumerate(f.replans):
        pos = f.at(t)
        if pos.size:
            ax.scatter(pos[:, 0], pos[:, 1], pos[:, 2], s=55, marker="X", color=_MOVING, edgecolor="white",
                       linewidth=0.6, depthshade=False, zorder=5)
            if len(f.replans) <= 15:
                ax.text(*pos.mean(axis=0) + [0, 0, 0.06 * (s["zmax"] - s["zmin"])], f"R{j + 1}", color=_MOVING,
                        fontsize=9, weight="bold", ha="center", zorder=6)
    _legend(fig, handles + _common_handles(f), len(f.names))
    dx, dy, dz = s["xmax"] - s["xmin"], s["ymax"] - s["ymin"], s["zmax"] - s["zmin"]
    ax.set_xlim(s["xmin"], s["xmax"])
    ax.set_ylim(s["ymin"], s["ymax"])
    ax.set_zlim(s["zmin"], s["zmax"])
    ax.set_box_aspect((dx, dy, float(np.clip(dz, 0.3 * max(dx, dy), max(dx, dy)))), zoom=1.05)
    ax.view_init(elev=28, azim=-62)
    for set_label, name in ((ax.set_xlabel, "x (m)"), (ax.set_ylabel, "y (m)"), (ax.set_zlabel, "z (m)")):
        set_label(name, fontsize=_LABEL)
    ax.set_title(_fig_title(f, "Flight"), fontsize=_TITLE)
    return fig


def _top_static(ax: Axes, f: _Flight) -> None:
    """Site outline, terrain contours, static cylinders and prisms on a top view."""
    s = f.site
    terrain = f.raw.get("terrain")
    if terrain:
        ax.contourf(np.asarray(terrain["x"], float), np.asarray(terrain["y"], float),
                    np.asarray(terrain["z"], float), levels=12, cmap="Greys", alpha=0.3, zorder=0)
    ax.plot([s["xmin"], s["xmax"], s["xmax"], s["xmin"], s["xmin"]],
            [s["ymin"], s["ymin"], s["ymax"], s["ymax"], s["ymin"]], color="0.5", lw=0.8, zorder=1)
    for x, y, r in (c[:3] for c in f.raw.get("cylinders", [])):
        ax.add_patch(Circle((x, y), r, facecolor=_OBSTACLE_FACE, edgecolor=_OBSTACLE_EDGE, alpha=0.75, lw=1.1, zorder=2))
    for p in f.raw.get("prisms", []):
        v = np.asarray(p["polygon"], float)
        if p.get("nofly"):
            ax.add_patch(PolygonPatch(v, closed=True, facecolor=_NOFLY_FACE, alpha=0.18, edgecolor=_NOFLY_FACE,
                                      hatch="//", lw=1.1, zorder=2))
        else:
            ax.add_patch(PolygonPatch(v, closed=True, facecolor=_OBSTACLE_FACE, alpha=0.7, edgecolor=_OBSTACLE_EDGE,
                                      lw=1.1, zorder=2))
    pad = 0.02 * max(s["xmax"] - s["xmin"], s["ymax"] - s["ymin"])
    ax.set_xlim(s["xmin"] - pad, s["xmax"] + pad)
    ax.set_ylim(s["ymin"] - pad, s["ymax"] + pad)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (m)", fontsize=_LABEL)
    ax.set_ylabel("y (m)", fontsize=_LABEL)
    _style_axes(ax)


def plot_flight_top(f: _Flight) -> Figure:
    """Top view: obstacles, moving obstacles' tracks with their footprint when they appear (solid)
    and at their last sample (dotted), actual paths, references (dashed), replan points."""
    # A fixed layout: the constrained one loses the y label of an equal-aspect axes beside a tall legend.
    fig = Figure(figsize=(11, 8))
    fig.subplots_adjust(left=0.07, right=0.74, bottom=0.07, top=0.93)
    ax = fig.add_subplot()
    _top_static(ax, f)
    for m in f.moving:
        vis = f.visible(m)
        k = _first(vis)
        if k is None:
            continue
        last = int(len(vis) - 1 - np.argmax(vis[::-1]))
        if m.get("kind") == "polygon":
            polys = np.asarray(m["polygons"], float)
            for i in np.unique(np.linspace(k, last, 6).round().astype(int))[1:-1]:
                ax.add_patch(PolygonPatch(polys[i], closed=True, fill=False, edgecolor=_MOVING, alpha=0.3, lw=0.8, zorder=3))
            first, end = polys[k], polys[last]
        else:
            xy = np.asarray(m["xy"], float)
            track = np.where(vis[:, None], xy, np.nan)
            ax.plot(track[:, 0], track[:, 1], color=_MOVING, ls="--", lw=1.2, zorder=3)
            rad = float(m.get("radius", 1.0))
            first, end = _circle(xy[k, 0], xy[k, 1], rad), _circle(xy[last, 0], xy[last, 1], rad)
        ax.add_patch(PolygonPatch(first, closed=True, facecolor=_MOVING, alpha=0.35, edgecolor=_MOVING, lw=1.3, zorder=3))
        ax.add_patch(PolygonPatch(end, closed=True, fill=False, edgecolor=_MOVING, ls=":", lw=1.3, zorder=3))
        ax.annotate(str(m.get("name", "")) + (f" appears {f.t[k]:.1f} s" if k else ""), first.mean(axis=0),
                    ha="center", va="bottom", fontsize=8.5, color=_MOVING, zorder=6, xytext=(0, 8), textcoords="offset points")
    handles: list[Any] = []
    for n, name in enumerate(f.names):
        col = uav_colour(n)
        a, r = f.actual[n], f.reference[n]
        ax.plot(r[:, 0], r[:, 1], color=col, ls="--", lw=1.0, alpha=0.8, zorder=4)
        (line,) = ax.plot(a[:, 0], a[:, 1], color=col, lw=1.8, label=name, zorder=4)
        handles.append(line)
        ax.plot(*a[0, :2], ls="none", marker="o", ms=8, mfc=col, mec="black", zorder=5)
        ax.plot(*a[-1, :2], ls="none", marker="*", ms=14, mfc=col, mec="black", mew=0.8, zorder=5)
    for j, (t, _, _) in enumerate(f.replans):
        pos = f.at(t)
        if pos.size:
            ax.plot(pos[:, 0], pos[:, 1], ls="none", marker="X", ms=9, mfc=_MOVING, mec="white", zorder=6)
            if len(f.replans) <= 15:
                ax.annotate(f"R{j + 1}", pos[0, :2], xytext=(5, 5), textcoords="offset points", color=_MOVING,
                            fontsize=9, weight="bold", zorder=7)
    big = len(f.names) > 12
    fig.legend(handles=handles + _common_handles(f), loc="upper left", bbox_to_anchor=(0.75, 0.93),
               fontsize=_LEGEND - (1.5 if big else 0), ncols=2 if big else 1)
    ax.set_title(_fig_title(f, "Top view"), fontsize=_TITLE)
    return fig


def plot_flight_altitude(f: _Flight) -> Figure:
    """Altitude z of each UAV against time (reference dashed), replans as dotted lines."""
    fig = Figure(figsize=(10, 5), layout="constrained")
    ax = fig.add_subplot()
    for n, name in enumerate(f.names):
        ax.plot(f.t, f.reference[n, :, 2], color=uav_colour(n), ls="--", lw=1.0, alpha=0.8)
        ax.plot(f.t, f.actual[n, :, 2], color=uav_colour(n), lw=1.6, label=name)
    _replan_lines(ax, f)
    ax.set_xlabel("time (s)", fontsize=_LABEL)
    ax.set_ylabel("altitude z (m)", fontsize=_LABEL)
    _style_axes(ax)
    _legend(fig, [*ax.get_legend_handles_labels()[0], *_common_handles(f)[:1], *_replan_handles(f)], len(f.names))
    ax.set_title(_fig_title(f, "Altitude"), fontsize=_TITLE)
    return fig


def plot_flight_tracking(f: _Flight) -> Figure:
    """Tracking error ``|actual - reference|`` of each UAV against time, replans as dotted lines."""
    fig = Figure(figsize=(10, 5), layout="constrained")
    ax = fig.add_subplot()
    err = np.linalg.norm(f.actual - f.reference, axis=-1)  # (N, T)
    for n, name in enumerate(f.names):
        ax.plot(f.t, err[n], color=uav_colour(n), lw=1.5, label=f"{name} (max {np.nanmax(err[n]):.2f} m)")
    _replan_lines(ax, f)
    ax.set_ylim(bottom=0)
    ax.set_xlabel("time (s)", fontsize=_LABEL)
    ax.set_ylabel("tracking error |actual - reference| (m)", fontsize=_LABEL)
    _style_axes(ax)
    _legend(fig, [*ax.get_legend_handles_labels()[0], *_replan_handles(f)], len(f.names))
    ax.set_title(_fig_title(f, "Tracking error"), fontsize=_TITLE)
    return fig


def least_separation(actual: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least pairwise distance ``(T,)`` of the ``(N, T, 3)`` positions and the pair ``(T, 2)``
    that attains it (``inf`` and ``-1`` for fewer than two UAVs)."""
    N, T = actual.shape[:2]
    if N < 2:
        return np.full(T, np.inf), np.full((T, 2), -1)
    a, b = np.triu_indices(N, 1)
    d = np.linalg.norm(actual[a] - actual[b], axis=-1)  # (P, T)
    best = np.argmin(np.where(np.isnan(d), np.inf, d), axis=0)
    return d[best, np.arange(T)], np.stack([a[best], b[best]], axis=1)


def plot_flight_separation(f: _Flight) -> Figure:
    """Least distance between any two UAVs against time, the limit (if given) dashed red."""
    fig = Figure(figsize=(10, 5), layout="constrained")
    ax = fig.add_subplot()
    d, pair = least_separation(f.actual)
    limit = f.raw.get("separation_limit")
    if np.isfinite(d).any():
        ax.plot(f.t, d, color="black", lw=1.6, label="least pairwise distance")
        k = int(np.nanargmin(np.where(np.isfinite(d), d, np.nan)))
        who = f"{f.names[pair[k, 0]]}–{f.names[pair[k, 1]]}"
        ax.plot(f.t[k], d[k], ls="none", marker="o", ms=7, mfc="white", mec="black", zorder=5,
                label=f"minimum {d[k]:.2f} m ({who}) at {f.t[k]:.1f} s")
        ax.set_ylim(bottom=0)
        if limit is not None:
            ax.fill_between(f.t, d, float(limit), where=d < float(limit), color="#b00020", alpha=0.25, lw=0)
    else:
        ax.text(0.5, 0.5, "fewer than two UAVs: no separation", transform=ax.transAxes, ha="center",
                va="center", fontsize=_LABEL, color="0.3")
    if limit is not None:
        ax.axhline(float(limit), color="#b00020", ls="--", label=f"limit {float(limit):g} m")
    _replan_lines(ax, f)
    ax.set_xlabel("time (s)", fontsize=_LABEL)
    ax.set_ylabel("least distance between two UAVs (m)", fontsize=_LABEL)
    _style_axes(ax)
    _legend(fig, [*ax.get_legend_handles_labels()[0], *_replan_handles(f)], 0)
    ax.set_title(_fig_title(f, "Separation"), fontsize=_TITLE)
    return fig


_MAKERS = (plot_flight_3d, plot_flight_top, plot_flight_altitude, plot_flight_tracking, plot_flight_separation)


def flight_figures(flight: dict[str, Any], out_dir: Path) -> list[Path]:
    """Write ``flight_3d.png``, ``flight_top.png``, ``flight_altitude.png``,
    ``flight_tracking.png`` and ``flight_separation.png`` of ``flight`` into ``out_dir`` (created
    if needed; each file replaced atomically). Returns the five paths in that order."""
    f = _Flight(flight)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return [_save(make(f), out / name) for name, make in zip(FLIGHT_FIGURES, _MAKERS)]
