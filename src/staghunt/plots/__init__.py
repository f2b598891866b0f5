"""Figures: the only package of staghunt that imports matplotlib.

:mod:`.plan` draws the figures of one plan (paper Figs. 4-8), :mod:`.compare` the figure of a
method comparison, :mod:`.mission` those of a timed mission, :mod:`.flight` and
:mod:`.animation` those of a simulated flight, :mod:`.replay` its offline 3-D replay page (HTML,
with ``replay.js`` and ``replay.css`` inlined), :mod:`.common` the colours and helpers they share. Importing
``staghunt.plots`` imports matplotlib; nothing else in the package does.
"""

from staghunt.plots.common import uav_colour
from staghunt.plots.plan import (
    FIGURES,
    plot_altitude,
    plot_convergence,
    plot_paths_3d,
    plot_top_view,
    save_figures,
)

__all__ = [
    "FIGURES",
    "plot_altitude",
    "plot_convergence",
    "plot_paths_3d",
    "plot_top_view",
    "save_figures",
    "uav_colour",
]
