"""The equilibria a search found, with the selected one marked: one line per equilibrium over the
UAVs (``ln J_n`` against the UAV), so that dominance reads as "one line below another everywhere".

Used by ``staghunt plan`` (the starts of one run: ``equilibria.png``) and by
``benchmarks/equilibria.py`` (every seed of a scenario, one panel per scenario).
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from staghunt.plots.common import _LABEL, _LEGEND, _TITLE

_DOMINATED = "0.7"
_FRONT = "#1f77b4"
_SELECTED = "#d62728"


@dataclass(frozen=True)
class EquilibriaPanel:
    """One panel: a ``title``, the ``(M, N)`` costs ``J`` of the distinct equilibria, whether each
    is ``dominated`` ``(M,)``, the ``(S, N)`` costs of the ``selected`` plans (one per run) and
    the UAV ``names``."""

    title: str
    J: np.ndarray
    dominated: np.ndarray
    selected: np.ndarray
    names: tuple[str, ...]


def draw_equilibria(ax: Axes, panel: EquilibriaPanel) -> None:
    """Draw ``panel`` on ``ax``: dominated equilibria grey, undominated blue, selected red."""
    x = np.arange(1, len(panel.names) + 1)
    J = np.asarray(panel.J, dtype=float).reshape(-1, len(x))
    dominated = np.asarray(panel.dominated, dtype=bool)
    for row, d in zip(J, dominated):
        ax.plot(x, np.log(row), "-o", ms=3, lw=1.0 if d else 1.6, color=_DOMINATED if d else _FRONT,
                zorder=1 if d else 2)
    for row in np.asarray(panel.selected, dtype=float).reshape(-1, len(x)):
        ax.plot(x, np.log(row), "--", marker="D", ms=5, lw=1.2, color=_SELECTED, alpha=0.8, zorder=3)
    ax.set_xticks(x, panel.names)
    ax.set_ylabel("ln J_n", fontsize=_LABEL)
    counts = f"{len(J)} distinct equilibria, {int((~dominated).sum())} undominated"
    ax.set_title(_wrapped(f"{panel.title}: {counts}", ax), fontsize=_TITLE)
    ax.plot([], [], "-o", color=_DOMINATED, label="dominated")
    ax.plot([], [], "-o", color=_FRONT, label="undominated")
    ax.plot([], [], "--D", color=_SELECTED, label="selected")
    ax.legend(fontsize=_LEGEND, loc="best")
    ax.grid(alpha=0.3)


def _wrapped(text: str, ax: Axes) -> str:
    """``text`` broken into lines that fit the width of ``ax``'s panel (a title wider than its
    figure is cut at both ends): about 0.6 em a character."""
    width_pt = ax.figure.get_figwidth() * 72.0 * ax.get_position().width
    return "\n".join(textwrap.wrap(text, width=max(20, int(width_pt / (0.6 * _TITLE)))))


def equilibria_figure(panels: Sequence[EquilibriaPanel]) -> Figure:
    """One panel per :class:`EquilibriaPanel`, side by side."""
    fig = Figure(figsize=(6.0 * max(1, len(panels)), 4.6), layout="constrained")
    axes = fig.subplots(1, max(1, len(panels)), squeeze=False)[0]
    for ax, panel in zip(axes, panels):
        draw_equilibria(ax, panel)
    return fig
