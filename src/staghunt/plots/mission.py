"""Figures of a timed mission: speed over time and the distance to the nearest team-mate over
time, with the limits drawn (``speed.png``, ``separation.png``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from staghunt.io.atomic import atomic_file
from staghunt.plots.common import uav_colour


def _save(fig: Figure, target: Path) -> Path:
    try:
        with atomic_file(target, "wb") as fh:
            fig.savefig(fh, format="png", dpi=110)
    finally:
        fig.clear()
    return target


def save_mission_figures(traj: Any, scenario: Any, out_dir: Path) -> list[Path]:
    """Write ``speed.png`` and ``separation.png`` of the timed trajectories ``traj``."""
    t = np.linspace(0.0, traj.duration, max(200, int(traj.duration / 0.05)))
    pos = np.moveaxis(traj.spline(t), 0, 1)  # (N, T, 3)
    vel = np.moveaxis(traj.spline(t, 1), 0, 1)
    names = [u.name for u in scenario.team]
    limits = scenario.vehicle
    fig = Figure(figsize=(10, 5), layout="constrained")
    ax = fig.add_subplot()
    for n, name in enumerate(names):
        ax.plot(t, np.linalg.norm(vel[n], axis=-1), color=uav_colour(n), lw=1.6, label=name)
    ax.axhline(limits.max_speed, color="#b00020", ls="--", label=f"max speed {limits.max_speed:g} m/s")
    ax.axhline(limits.cruise_speed, color="0.4", ls=":", label=f"cruise {limits.cruise_speed:g} m/s")
    for tk in traj.times:
        ax.axvline(tk, color="0.85", lw=0.6, zorder=0)
    ax.set_xlabel("time (s); grey lines: common waypoint times")
    ax.set_ylabel("speed (m/s)")
    ax.set_title(f"{scenario.name}: speed over time ({traj.duration:.1f} s mission)")
    ax.grid(True, alpha=0.3)
    fig.legend(loc="outside right upper", fontsize=9)
    written = [_save(fig, out_dir / "speed.png")]
    N = pos.shape[0]
    fig = Figure(figsize=(10, 5), layout="constrained")
    ax = fig.add_subplot()
    if N > 1:
        d = np.linalg.norm(pos[:, None] - pos[None], axis=-1)  # (N, N, T)
        d[np.arange(N), np.arange(N)] = np.inf
        for n, name in enumerate(names):
            ax.plot(t, d[n].min(axis=0), color=uav_colour(n), lw=1.6, label=name)
    limit = scenario.costs.safe_distance + 2.0 * max(u.radius for u in scenario.team)
    ax.axhline(limit, color="#b00020", ls="--", label=f"limit d_s + 2r = {limit:g} m")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("distance to the nearest team-mate (m)")
    ax.set_title(f"{scenario.name}: separation over time (same instant)")
    ax.grid(True, alpha=0.3)
    fig.legend(loc="outside right upper", fontsize=9)
    written.append(_save(fig, out_dir / "separation.png"))
    return written
