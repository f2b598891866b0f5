"""The comparison figure: ``J_n`` per UAV per method (box plots, log axis), the dominance matrix
(method x method) and the Nash gaps per method, and the paths of each method's best seed side by
side (top view).

It builds a :class:`matplotlib.figure.Figure` without ``pyplot`` (no global state). UAV colours
are those of the plan figures (:func:`staghunt.plots.common.uav_colour`).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch

from staghunt.analysis.compare import CompareReport, RunRecord, best_seed
from staghunt.io.atomic import atomic_file
from staghunt.plots.common import uav_colour

_METHOD_COLOURS = {
    "game": "#1b9e77",
    "paper": "#66a61e",
    "rigid": "#d95f02",
    "independent": "#7570b3",
    "weighted": "#e7298a",
}
_OTHER = ("#e6ab02", "#a6761d", "#666666", "#1f78b4")
_OBSTACLE_FACE = "#f2b705"
_OBSTACLE_EDGE = "#8a6a00"


def method_colour(method: str, index: int) -> str:
    return _METHOD_COLOURS.get(method, _OTHER[index % len(_OTHER)])


def _box_axes(fig: Figure, report: CompareReport, records: Sequence[RunRecord]) -> None:
    names = [u.name for u in report.scenario.team]
    methods = [m for m in report.methods if any(r.method == m for r in records)]
    axes = fig.subplots(1, len(names), squeeze=False)[0]
    rng = np.random.default_rng(0)  # jitter of the points only
    for n, (ax, name) in enumerate(zip(axes, names)):
        data, labels, infs = [], [], []
        for m in methods:
            v = np.array([r.J[n] for r in records if r.method == m], dtype=float)
            data.append(v[np.isfinite(v)])
            infs.append(int((~np.isfinite(v)).sum()))
            labels.append(m)
        pos = np.arange(1, len(methods) + 1)
        finite = [d if d.size else np.array([np.nan]) for d in data]
        bp = ax.boxplot(finite, positions=pos, widths=0.55, patch_artist=True, showfliers=False)
        for i, box in enumerate(bp["boxes"]):
            box.set_facecolor(method_colour(methods[i], i))
            box.set_alpha(0.35)
            box.set_edgecolor(method_colour(methods[i], i))
        for med in bp["medians"]:
            med.set_color("black")
        for i, d in enumerate(data):
            if d.size:
                x = pos[i] + rng.uniform(-0.12, 0.12, d.size)
                ax.plot(x, d, ls="none", marker="o", ms=4.5, mfc=method_colour(methods[i], i),
                        mec="black", mew=0.5, zorder=3)
        ax.set_yscale("log")
        ticks = [f"{m}\n({k}/{k + d.size} inf)" if k else m for m, k, d in zip(labels, infs, data)]
        ax.set_xticks(pos, ticks, fontsize=10)
        for lab, k in zip(ax.get_xticklabels(), infs):
            if k:
                lab.set_color("#b00020")
        ax.set_title(f"{name}: J_n per seed", fontsize=12, color=uav_colour(n))
        ax.grid(True, axis="y", which="both", alpha=0.3)
        ax.tick_params(labelsize=10)
        if n == 0:
            ax.set_ylabel("J_n (log scale)", fontsize=11)


def _game_axes(fig: Figure, report: CompareReport, records: Sequence[RunRecord]) -> None:
    """Left: the dominance matrix (seeds where the row's allocation dominates the column's).
    Right: each run's largest relative Nash gap per method (log axis; infeasible plans, whose gap
    is infinite, counted under the method's name), with epsilon drawn."""
    mat = report.data.get("dominance_matrix") or {}
    methods = [m for m in mat.get("methods", []) if any(r.method == m for r in records)]
    ax_m, ax_g = fig.subplots(1, 2, width_ratios=[1.0, 1.4])
    if methods:
        idx = [mat["methods"].index(m) for m in methods]
        counts = np.array([[mat["counts"][i][j] for j in idx] for i in idx], dtype=float)
        compared = np.array([[mat["compared"][i][j] for j in idx] for i in idx], dtype=float)
        share = np.divide(counts, compared, out=np.zeros_like(counts), where=compared > 0)
        ax_m.imshow(share, cmap="Greens", vmin=0.0, vmax=1.0)
        for i in range(len(methods)):
            for j in range(len(methods)):
                text = "-" if i == j else f"{int(counts[i, j])}/{int(compared[i, j])}"
                ax_m.text(j, i, text, ha="center", va="center", fontsize=10,
                          color="white" if share[i, j] > 0.6 else "black")
        ax_m.set_xticks(range(len(methods)), methods, rotation=30, ha="right", fontsize=10)
        ax_m.set_yticks(range(len(methods)), methods, fontsize=10)
    ax_m.set_title("row dominates column (seeds)", fontsize=11.5)
    ax_m.set_xlabel("dominated method", fontsize=10)
    ax_m.set_ylabel("dominating method", fontsize=10)

    eps = report.certify.epsilon if report.certify is not None else None
    shown = [m for m in report.methods if any(r.method == m and r.nash_gaps() is not None for r in records)]
    labels = []
    for i, m in enumerate(shown):
        gaps = np.array([float(np.max(r.nash_gaps()[1])) for r in records  # type: ignore[index]
                         if r.method == m and r.nash_gaps() is not None])
        finite = gaps[np.isfinite(gaps)]
        k = int((~np.isfinite(gaps)).sum())
        x = i + 1 + np.linspace(-0.15, 0.15, finite.size) if finite.size > 1 else np.full(finite.size, i + 1.0)
        ax_g.plot(x, np.maximum(finite, 1e-6), ls="none", marker="o", ms=5.5,
                  mfc=method_colour(m, report.methods.index(m)), mec="black", mew=0.5)
        labels.append(f"{m}\n({k} inf)" if k else m)
    ax_g.set_yscale("log")
    ax_g.set_xticks(range(1, len(shown) + 1), labels, fontsize=10)
    if eps is not None and eps > 0:
        ax_g.axhline(eps, color="#b00020", ls="--", lw=1.2, label=f"epsilon = {eps:.0%}")
        ax_g.legend(fontsize=9.5, loc="lower right")
    ax_g.set_ylabel("largest relative Nash gap of the run (floor 1e-6)", fontsize=10)
    ax_g.set_title("Nash gaps per method (one point per seed; below epsilon = equilibrium)", fontsize=11.5)
    ax_g.grid(True, axis="y", which="both", alpha=0.3)
    ax_g.tick_params(labelsize=9.5)


def _paths_axes(fig: Figure, report: CompareReport, records: Sequence[RunRecord]) -> None:
    scenario = report.scenario
    b = scenario.world.bounds
    delta = float(scenario.costs.danger_margin)
    names = [u.name for u in scenario.team]
    methods = [m for m in report.methods if any(r.method == m for r in records)]
    dom = report.data.get("dominance", {})
    axes = fig.subplots(1, len(methods), squeeze=False)[0]
    for i, (ax, m) in enumerate(zip(axes, methods)):
        rec = best_seed(records, m)
        assert rec is not None
        for c in scenario.world.cylinders:
            ax.add_patch(Circle((c.x, c.y), c.radius, facecolor=_OBSTACLE_FACE,
                                edgecolor=_OBSTACLE_EDGE, alpha=0.8, lw=1.0, zorder=2))
            if delta > 0:
                ax.add_patch(Circle((c.x, c.y), c.radius + delta, fill=False, ls="--", lw=0.8,
                                    edgecolor=_OBSTACLE_EDGE, alpha=0.8, zorder=2))
        for n in range(len(names)):
            p = rec.paths[n]
            ax.plot(p[:, 0], p[:, 1], color=uav_colour(n), lw=1.8, marker="o", ms=2.5, zorder=4)
            ax.plot(p[0, 0], p[0, 1], ls="none", marker="o", ms=7, mfc=uav_colour(n), mec="black", zorder=5)
            ax.plot(p[-1, 0], p[-1, 1], ls="none", marker="*", ms=12, mfc=uav_colour(n), mec="black",
                    mew=0.6, zorder=5)
        ax.set_xlim(b.xmin, b.xmax)
        ax.set_ylim(b.ymin, b.ymax)
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, alpha=0.3)
        ax.tick_params(labelsize=9)
        ax.set_xlabel("x (m)", fontsize=10)
        if i == 0:
            ax.set_ylabel("y (m)", fontsize=10)
        lnsum = float(np.sum(np.log(rec.J))) if np.all(np.isfinite(rec.J)) else math.inf
        status = "feasible" if rec.feasible else "INFEASIBLE"
        sub = f"seed {rec.seed}, {status}"
        sub += f", sum ln J = {lnsum:.2f}" if math.isfinite(lnsum) else ""
        if m in dom:
            e = dom[m]
            sub += f"\ngame dominates it in {e['game_dominates']}/{e['compared']} seeds"
        elif m == "game" and dom:
            sub += "\n(reference of the dominance test)"
        ax.set_title(f"{m}: best seed\n{sub}", fontsize=10.5, color=method_colour(m, i))
    handles = [Line2D([], [], color=uav_colour(n), lw=2, label=name) for n, name in enumerate(names)]
    handles += [
        Line2D([], [], ls="none", marker="o", ms=7, mfc="white", mec="black", label="start"),
        Line2D([], [], ls="none", marker="*", ms=11, mfc="white", mec="black", label="goal"),
        Patch(facecolor=_OBSTACLE_FACE, edgecolor=_OBSTACLE_EDGE, label="obstacle"),
    ]
    if delta > 0:
        handles.append(Line2D([], [], ls="--", color=_OBSTACLE_EDGE, label=f"R + Δ (Δ = {delta:g} m)"))
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=9.5, frameon=False)


def plot_compare(report: CompareReport) -> Figure:
    """Box plots of ``J_n`` per UAV per method (log axis; infinite values, which a log axis
    cannot show, are counted in red under the method's name) above the paths of each method's
    best seed (least violation, then least ``sum_n ln J_n``)."""
    records = report.records
    if not records:
        raise ValueError("no finished runs to plot")
    n_uavs = len(report.scenario.team)
    n_methods = len({r.method for r in records})
    width = max(4.2 * max(n_uavs, n_methods), 10.0)
    fig = Figure(figsize=(width, 15.5), layout="constrained")
    top, middle, bottom = fig.subfigures(3, 1, height_ratios=[1.0, 1.0, 1.25])
    _box_axes(top, report, records)
    _game_axes(middle, report, records)
    _paths_axes(bottom, report, records)
    s = report.settings
    seeds = sorted({r.seed for r in records})
    fig.suptitle(
        f"{report.scenario.name}: methods compared on {len(seeds)} seed(s), {s.particles} particles x "
        f"{s.iterations} iterations (same J_n for every method)",
        fontsize=13,
    )
    return fig


def save_compare_figure(report: CompareReport, path: str | os.PathLike[str], dpi: int = 110) -> Path:
    """Draw :func:`plot_compare` and write it to ``path`` (PNG) atomically."""
    target = Path(path)
    fig = plot_compare(report)
    try:
        with atomic_file(target, "wb") as fh:
            fig.savefig(fh, format="png", dpi=dpi)
    finally:
        fig.clear()
    return target
