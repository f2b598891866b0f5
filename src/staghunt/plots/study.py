"""The figures of a sweep (``staghunt sweep``), drawn from its results table (one row per task,
:mod:`staghunt.study.sweep`), without ``pyplot``:

- :func:`beta_tradeoff_figure`: per UAV, the formation cost ``J_f`` against the single cost
  ``J_s`` of every feasible plan, coloured by beta, with the Pareto front (neither cost can be
  lowered without raising the other) marked;
- :func:`convergence_figure`: per UAV, the median and quartiles over seeds of ``ln J_n`` of the
  best allocation per iteration, one band per method.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from staghunt.io.atomic import atomic_file
from staghunt.plots.common import _LABEL, _LEGEND, _TITLE

_METHOD_COLOURS = {"game": "#1b9e77", "paper": "#66a61e", "rigid": "#d95f02", "independent": "#7570b3",
                   "weighted": "#e7298a"}
_OTHER = ("#e6ab02", "#a6761d", "#666666", "#1f78b4")
_MARKERS = ("o", "s", "^", "D", "v", "P")


def _method_colour(method: str, index: int) -> str:
    return _METHOD_COLOURS.get(method, _OTHER[index % len(_OTHER)])


def pareto_front(points: np.ndarray) -> np.ndarray:
    """``(P,)`` bool: the points of ``(P, 2)`` (both coordinates minimised) that no other point
    dominates (at most as large in both, smaller in one). Non-finite points are never on it."""
    pts = np.asarray(points, dtype=float)
    ok = np.all(np.isfinite(pts), axis=1)
    front = np.zeros(len(pts), dtype=bool)
    for i in np.flatnonzero(ok):
        le = np.all(pts[ok] <= pts[i], axis=1)
        lt = np.any(pts[ok] < pts[i], axis=1)
        front[i] = not np.any(le & lt)
    return front


def _beta_column(columns: list[str]) -> str | None:
    if "beta" in columns:
        return "beta"
    return next((c for c in columns if c.startswith("uav.") and c.endswith(".beta")), None)


def _rows(table: Any) -> dict[str, list[Any]]:
    return table.to_pydict() if hasattr(table, "to_pydict") else dict(table)


def beta_tradeoff_figure(table: Any, scenario: str | None = None) -> Figure:
    """One panel per UAV: ``J_f`` (x) against ``J_s`` (y) of every feasible row of ``scenario``
    (default: the first), coloured by the beta column (``beta``, else the first ``uav.<i>.beta``),
    one marker per method; the Pareto front of each panel ringed and joined. Raises
    ``ValueError`` when the table has no beta column or no feasible row."""
    data = _rows(table)
    column = _beta_column(list(data))
    if column is None:
        raise ValueError("the sweep has no beta in its [grid]: no trade-off along beta to draw")
    scenario = scenario if scenario is not None else data["scenario"][0]
    keep = [i for i, (s, st) in enumerate(zip(data["scenario"], data["status"])) if s == scenario and st == "feasible"]
    if not keep:
        raise ValueError(f"no feasible plan of {scenario!r} to draw")
    J_s = np.array([data["J_s"][i] for i in keep], dtype=float)  # (R, N)
    J_f = np.array([data["J_f"][i] for i in keep], dtype=float)
    beta = np.array([data[column][i] for i in keep], dtype=float)  # (R,)
    methods = [data["method"][i] for i in keep]
    order = list(dict.fromkeys(methods))
    N = J_s.shape[1]
    fig = Figure(figsize=(4.2 * N + 1.2, 4.4), layout="constrained")
    axes = fig.subplots(1, N, squeeze=False)[0]
    norm = Normalize(vmin=float(beta.min()), vmax=float(beta.max()) if beta.max() > beta.min() else float(beta.min()) + 1)
    cmap = colormaps["viridis"]
    for n, ax in enumerate(axes):
        pts = np.stack([J_f[:, n], J_s[:, n]], axis=1)
        for j, m in enumerate(order):
            sel = np.array([mm == m for mm in methods])
            ax.scatter(pts[sel, 0], pts[sel, 1], c=beta[sel], cmap=cmap, norm=norm, s=28,
                       marker=_MARKERS[j % len(_MARKERS)], edgecolors="none", alpha=0.85)
        front = pareto_front(pts)
        f = pts[front]
        f = f[np.argsort(f[:, 0])]
        ax.step(f[:, 0], f[:, 1], where="post", color="black", lw=1.0, alpha=0.7)
        ax.scatter(f[:, 0], f[:, 1], s=70, facecolors="none", edgecolors="black", lw=1.1)
        ax.set_xlabel("formation cost $J_f$", fontsize=_LABEL)
        if n == 0:
            ax.set_ylabel("single cost $J_s$", fontsize=_LABEL)
        ax.set_title(f"UAV {n + 1}", fontsize=_LABEL)
        ax.grid(alpha=0.3)
    bar = fig.colorbar(axes[-1].collections[0], ax=list(axes), shrink=0.85)
    bar.set_label(column, fontsize=_LABEL)
    handles = [Line2D([], [], ls="", marker=_MARKERS[j % len(_MARKERS)], color="0.4", label=m) for j, m in enumerate(order)]
    handles.append(Line2D([], [], ls="-", marker="o", mfc="none", color="black", label="Pareto front"))
    axes[0].legend(handles=handles, fontsize=_LEGEND, loc="best")
    fig.suptitle(f"Trade-off along {column}: {scenario} ({len(keep)} feasible plans)", fontsize=_TITLE)
    return fig


def convergence_figure(table: Any, scenario: str | None = None) -> Figure:
    """One panel per UAV: median (line) and quartiles (band) over the rows of each method of
    ``ln J_n`` of the best allocation per iteration (``history``, ``(iterations + 1, N)`` per
    row; rows of another length than the method's most common one are left out)."""
    data = _rows(table)
    scenario = scenario if scenario is not None else data["scenario"][0]
    keep = [i for i, (s, st) in enumerate(zip(data["scenario"], data["status"]))
            if s == scenario and st != "error" and data["history"][i]]
    if not keep:
        raise ValueError(f"no plan of {scenario!r} with a history to draw")
    methods = list(dict.fromkeys(data["method"][i] for i in keep))
    N = len(data["history"][keep[0]][0])
    fig = Figure(figsize=(4.2 * N, 4.0), layout="constrained")
    axes = fig.subplots(1, N, squeeze=False, sharey=False)[0]
    for j, m in enumerate(methods):
        hs = [np.asarray(data["history"][i], dtype=float) for i in keep if data["method"][i] == m]
        lengths = [len(h) for h in hs]
        common = max(set(lengths), key=lengths.count)
        H = np.stack([h for h in hs if len(h) == common])  # (S, T, N)
        with np.errstate(divide="ignore", invalid="ignore"):
            lnH = np.log(H)
        lnH[~np.isfinite(lnH)] = np.nan
        q1, med, q3 = np.nanpercentile(lnH, [25, 50, 75], axis=0)  # (T, N) each
        t = np.arange(common)
        colour = _method_colour(m, j)
        for n, ax in enumerate(axes):
            ax.plot(t, med[:, n], color=colour, lw=1.6, label=f"{m} ({len(H)} runs)")
            ax.fill_between(t, q1[:, n], q3[:, n], color=colour, alpha=0.25, lw=0)
    for n, ax in enumerate(axes):
        ax.set_xlabel("iteration", fontsize=_LABEL)
        ax.set_title(f"UAV {n + 1}", fontsize=_LABEL)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(r"$\ln J_n$ (median, quartiles)", fontsize=_LABEL)
    axes[0].legend(fontsize=_LEGEND)
    fig.suptitle(f"Convergence over seeds: {scenario}", fontsize=_TITLE)
    return fig


def _save(fig: Figure, path: Path, dpi: int = 110) -> Path:
    with atomic_file(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=dpi)
    return path


def save_study_figures(table: Any, out_dir: str | os.PathLike[str]) -> list[Path]:
    """Write ``beta_tradeoff.png`` (when the sweep varies a beta) and ``convergence.png`` into
    ``out_dir``, for the table's first scenario (``-<scenario>`` suffixed files for the others);
    returns the paths written."""
    out = Path(out_dir)
    data = _rows(table)
    scenarios = list(dict.fromkeys(data["scenario"]))
    written: list[Path] = []
    for k, s in enumerate(scenarios):
        suffix = "" if k == 0 else f"-{''.join(c if c.isalnum() or c in '-_' else '_' for c in s)}"
        if _beta_column(list(data)) is not None:
            try:
                written.append(_save(beta_tradeoff_figure(data, s), out / f"beta_tradeoff{suffix}.png"))
            except ValueError:
                pass
        written.append(_save(convergence_figure(data, s), out / f"convergence{suffix}.png"))
    return written
