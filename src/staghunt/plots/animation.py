"""The animation of a flight: a top-view GIF (matplotlib ``FuncAnimation`` + ``PillowWriter``)
drawn from the same flight dict as :mod:`staghunt.plots.flight`; everything that does not move is
drawn once as a background, each frame redraws only the moving parts."""

from __future__ import annotations

import io
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.animation import FuncAnimation, PillowWriter
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Polygon as PolygonPatch

from staghunt.io.atomic import atomic_file
from staghunt.plots.common import _LEGEND, _TITLE, uav_colour
from staghunt.plots.flight import _Flight, _circle, _common_handles, _top_static
from staghunt.plots.replay import _MOVING, frame_indices


def _rgba(fig: Figure, dpi: int) -> np.ndarray:
    """``fig`` rendered to an ``(H, W, 4)`` uint8 array at ``dpi``."""
    buf = io.BytesIO()
    fig.savefig(buf, format="rgba", dpi=dpi)
    w, h = (int(round(v * dpi)) for v in fig.get_size_inches())
    return np.frombuffer(buf.getvalue(), dtype=np.uint8).reshape(h, w, 4)


_GIF_DPI = 80


def flight_animation(flight: dict[str, Any], path: Path, fps: int = 10, max_frames: int = 200) -> Path:
    """A top-view GIF of ``flight``: trails and dots of the UAVs, references faint, moving
    obstacles while visible, the time and the last replan. At most ``max_frames`` frames (the
    samples evenly subsampled, first and last kept), ``fps`` frames per second; written
    atomically. Returns ``path``.

    Everything that does not move (axes, ticks, legend, static obstacles, references) is rendered
    once into a background image; each frame draws only the moving artists over it.
    """
    if fps < 1:
        raise ValueError(f"fps must be at least 1, got {fps}")
    f = _Flight(flight)
    idx = frame_indices(f.t.size, max(2, max_frames))
    fig = Figure(figsize=(9.5, 6.4), dpi=_GIF_DPI)  # its plain canvas draws only when a frame is saved
    fig.subplots_adjust(left=0.07, right=0.70, bottom=0.12, top=0.93)
    ax = fig.add_subplot()
    _top_static(ax, f)
    for n in range(len(f.names)):
        ax.plot(f.reference[n, :, 0], f.reference[n, :, 1], color=uav_colour(n), ls="--", lw=0.8, alpha=0.45,
                zorder=3)
    big = len(f.names) > 12
    proxies = [Line2D([], [], color=uav_colour(n), lw=1.8, marker="o", ms=5, mec="black", label=name)
               for n, name in enumerate(f.names)]
    fig.legend(handles=[*proxies, *_common_handles(f)], loc="upper left", bbox_to_anchor=(0.71, 0.93),
               fontsize=_LEGEND - (2 if big else 0), ncols=2 if big else 1)

    background = _rgba(fig, _GIF_DPI)
    for artist in [*ax.get_children(), *fig.legends]:
        artist.set_visible(False)
    fig.figimage(background, xo=0, yo=0, origin="upper", zorder=-1)

    trails, dots = [], []
    for n in range(len(f.names)):
        col = uav_colour(n)
        trails.append(ax.plot([], [], color=col, lw=1.8, zorder=4)[0])
        dots.append(ax.plot([], [], ls="none", marker="o", ms=7, mfc=col, mec="black", zorder=5)[0])
    patches: list[tuple[dict[str, Any], np.ndarray, Any]] = []
    for m in f.moving:
        patch = PolygonPatch(np.zeros((3, 2)), closed=True, facecolor=_MOVING, alpha=0.45, edgecolor=_MOVING,
                             lw=1.3, zorder=3, visible=False)
        ax.add_patch(patch)
        patches.append((m, f.visible(m), patch))
    title = fig.text(0.07, 0.955, "", fontsize=_TITLE - 1, va="bottom")
    note = fig.text(0.07, 0.015, "", color=_MOVING, fontsize=_LEGEND)

    def update(i: int) -> list[Any]:
        k = int(idx[i])
        for n, (trail, dot) in enumerate(zip(trails, dots)):
            trail.set_data(f.actual[n, : k + 1, 0], f.actual[n, : k + 1, 1])
            dot.set_data(f.actual[n, k : k + 1, 0], f.actual[n, k : k + 1, 1])
        for m, vis, patch in patches:
            patch.set_visible(bool(vis[k]))
            if vis[k]:
                if m.get("kind") == "polygon":
                    patch.set_xy(np.asarray(m["polygons"][k], float))
                else:
                    x, y = m["xy"][k]
                    patch.set_xy(_circle(float(x), float(y), float(m.get("radius", 1.0)), 32))
        title.set_text(f"{f.title}: t = {f.t[k]:.2f} s (frame {i + 1}/{idx.size})")
        past = [r for r in f.replans if r[0] <= f.t[k]]
        note.set_text(f"replan {len(past)} at {past[-1][0]:.1f} s: {past[-1][1]} → {past[-1][2]}" if past else "")
        return [*trails, *dots, *(p for _, _, p in patches), title, note]

    anim = FuncAnimation(fig, update, frames=idx.size, blit=False, repeat=False)
    target = Path(path)
    with tempfile.TemporaryDirectory(prefix="staghunt-gif-") as tmp:
        scratch = Path(tmp) / "flight.gif"
        anim.save(scratch, writer=PillowWriter(fps=fps), dpi=_GIF_DPI)
        with atomic_file(target, "wb") as fh:
            fh.write(scratch.read_bytes())
    fig.clear()
    return target
