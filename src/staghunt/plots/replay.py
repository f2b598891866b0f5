"""An offline, interactive 3-D replay of a flight: one self-contained HTML page.

:func:`replay_html` turns a *flight dict* (plain JSON-able data in the site frame, metres and
seconds; see :func:`staghunt.plots.flight.flight_figures` for its layout) into a single HTML file
that needs no network at all: vanilla JavaScript draws the site, the obstacles and the team on a
``<canvas>`` with its own small perspective projection (drag: orbit, shift-drag: pan, wheel:
zoom, double-click: reset). A time slider (``#time``), a play/pause button (``#play``) and a
timeline with the replans drive it. The data is embedded as JSON in
``<script type="application/json" id="flight-data">``, coordinates rounded to the centimetre and
at most ``max_frames`` sample times (evenly subsampled, first and last kept).

The page exposes a small test API on ``window.staghuntReplay``: ``setTime(t)`` (seconds; the
nearest frame, returns its time), ``time()``, ``frame()``, ``frameCount()``, ``uavPositions()``
(site-frame ``[x, y, z]`` per UAV at the current frame, ``null`` where unknown) and
``uavScreenPositions()`` (``[px, py]`` of each UAV's dot in CSS pixels from the canvas's top-left
corner, ``null`` where not drawn) and ``footprintsShown()`` (how many photos' footprints are drawn
at the current frame: an inspection's photos taken by then, each in its UAV's colour).
"""

from __future__ import annotations

import html
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from staghunt.io.atomic import write_text_atomic
from staghunt.plots.common import _OBSTACLE_EDGE, _OBSTACLE_FACE, uav_colour
from staghunt.plots.site import _NOFLY_FACE

MAX_FRAMES = 1500
ASSETS = ("replay.css", "replay.js")
"""The page's style and script, package files beside this module, inlined into every page."""
_MOVING = "#c51b7d"  # moving / pop-up obstacles, in every flight figure


# --------------------------------------------------------------------------------------------
# data
# --------------------------------------------------------------------------------------------


def frame_indices(n_samples: int, max_frames: int = MAX_FRAMES) -> np.ndarray:
    """Indices ``(F,)`` of the samples kept: all of them if ``n_samples <= max_frames``, else
    ``max_frames`` evenly spread ones, the first and the last included."""
    if max_frames < 2:
        raise ValueError(f"max_frames must be at least 2, got {max_frames}")
    if n_samples <= max_frames:
        return np.arange(n_samples)
    return np.unique(np.round(np.linspace(0, n_samples - 1, max_frames)).astype(int))


def _array(value: Any, shape: tuple[int | None, ...], what: str) -> np.ndarray:
    """``value`` as a float array of ``shape`` (``None``: any length); ``ValueError`` otherwise."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"flight: {what} is not a regular array of numbers") from None
    if a.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, a.shape)):
        want = "(" + ", ".join("?" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"flight: {what} has shape {a.shape}, expected {want}")
    return a


def _flat(a: np.ndarray) -> list[float | None]:
    """``a`` flattened, rounded to the centimetre, non-finite values as ``None`` (JSON null)."""
    flat = np.round(np.asarray(a, dtype=float).ravel(), 2)
    out: list[float | None] = flat.tolist()
    if not np.isfinite(flat).all():
        out = [v if np.isfinite(v) else None for v in out]
    return out


def _site(flight: dict[str, Any]) -> dict[str, float]:
    s = flight["site"]
    site = {k: float(s[k]) for k in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")}
    if not all(np.isfinite(v) for v in site.values()):
        raise ValueError("flight: the site's bounds must be finite")
    return site


def _visible(m: dict[str, Any], T: int, idx: np.ndarray) -> list[int]:
    vis = np.ones(T, dtype=bool) if m.get("visible") is None else np.asarray(m["visible"], dtype=bool)
    if vis.shape != (T,):
        raise ValueError(f"flight: moving obstacle {m.get('name', '?')!r}: visible has shape {vis.shape}, expected ({T},)")
    return vis[idx].astype(int).tolist()


def replay_data(flight: dict[str, Any], max_frames: int = MAX_FRAMES) -> dict[str, Any]:
    """The compact JSON-able data the page embeds.

    UAV tracks are flat lists ``[x0, y0, z0, x1, ...]`` of length ``3 F`` (``F`` frames kept, see
    :func:`frame_indices`), moving cylinders' ``xy`` flat ``2 F``, moving polygons' ``polygons``
    one flat ``2 V`` list per frame, ``visible`` ``F`` zeros and ones; prisms' ``base`` / ``top``
    are clipped to the site's z range; each replan gets the ``frame`` at or before its time.
    """
    site = _site(flight)
    times = _array(flight["times"], (None,), "times")
    T = times.size
    if T < 1 or not np.all(np.isfinite(times)) or np.any(np.diff(times) < 0):
        raise ValueError("flight: times must be a non-empty, finite, increasing list")
    idx = frame_indices(T, max_frames)
    kept = times[idx]
    uavs = []
    for n, u in enumerate(flight.get("uavs", [])):
        name = str(u.get("name", f"UAV{n + 1}"))
        actual = _array(u["actual"], (T, 3), f"{name}.actual")
        reference = _array(u.get("reference", u["actual"]), (T, 3), f"{name}.reference")
        uavs.append({"name": name, "radius": float(u.get("radius", 1.0)), "colour": uav_colour(n),
                     "actual": _flat(actual[idx]), "reference": _flat(reference[idx])})
    lo, hi = site["zmin"], site["zmax"]
    prisms = []
    for p in flight.get("prisms", []):
        poly = _array(p["polygon"], (None, 2), "prism polygon")
        prisms.append({"polygon": _flat(poly), "nofly": bool(p.get("nofly", False)),
                       "base": float(np.clip(p.get("base", lo), lo, hi)),
                       "top": float(np.clip(p.get("top", hi), lo, hi)),
                       "name": str(p.get("name", ""))})
    moving = []
    for k, m in enumerate(flight.get("moving", [])):
        name = str(m.get("name", f"obstacle {k + 1}"))
        item: dict[str, Any] = {"name": name, "kind": str(m.get("kind", "cylinder")),
                                "visible": _visible(m, T, idx)}
        if item["kind"] == "polygon":
            polys = _array(m["polygons"], (T, None, 2), f"{name}.polygons")
            item["polygons"] = [_flat(polys[i]) for i in idx]
            item["base"] = float(np.clip(m.get("base", lo), lo, hi))
            item["top"] = float(np.clip(m.get("top", hi), lo, hi))
        else:
            item["kind"] = "cylinder"
            item["xy"] = _flat(_array(m["xy"], (T, 2), f"{name}.xy")[idx])
            item["radius"] = float(m.get("radius", 1.0))
            item["base"] = float(np.clip(m.get("base", max(lo, 0.0)), lo, hi))
            item["top"] = float(np.clip(m.get("top", hi), lo, hi))
        moving.append(item)
    replans = []
    for r in flight.get("replans", []):
        t = float(r["time"])
        frame = int(np.clip(np.searchsorted(kept, t, side="right") - 1, 0, idx.size - 1))
        replans.append({"time": round(t, 3), "frame": frame, "trigger": str(r.get("trigger", "")),
                        "verdict": str(r.get("verdict", ""))})
    footprints = []
    for fp in flight.get("footprints", []):  # an inspection's photos: where each frame fell
        corners = _array(fp["corners"], (4, 3), "footprint corners")
        if not np.isfinite(corners).all():
            continue
        t = float(fp["t"])
        frame = int(np.clip(np.searchsorted(kept, t, side="right") - 1, 0, idx.size - 1))
        footprints.append({"frame": frame, "uav": int(fp["uav"]), "corners": _flat(corners)})
    terrain = None
    if flight.get("terrain"):
        tr = flight["terrain"]
        tx = _array(tr["x"], (None,), "terrain.x")
        ty = _array(tr["y"], (None,), "terrain.y")
        tz = _array(tr["z"], (ty.size, tx.size), "terrain.z")
        jx, iy = frame_indices(tx.size, 40), frame_indices(ty.size, 40)
        terrain = {"x": _flat(tx[jx]), "y": _flat(ty[iy]), "z": [_flat(tz[i, jx]) for i in iy]}
    return {
        "title": str(flight.get("title", "flight")),
        "site": site,
        "times": [round(float(t), 3) for t in kept],
        "uavs": uavs,
        "cylinders": [[round(float(v), 2) for v in c[:3]] for c in flight.get("cylinders", [])],
        "cylinderBase": float(np.clip(0.0, lo, hi)),
        "prisms": prisms,
        "moving": moving,
        "replans": replans,
        "footprints": footprints,
        "terrain": terrain,
        "colours": {"obstacle": _OBSTACLE_FACE, "obstacleEdge": _OBSTACLE_EDGE,
                    "nofly": _NOFLY_FACE, "moving": _MOVING},
    }


def _script_json(data: dict[str, Any]) -> str:
    """JSON safe inside a ``<script>`` element: ``<``, ``>`` and ``&`` as ``\\u`` escapes, so no
    ``</script>`` or ``<!--`` in a name can end or change the element."""
    text = json.dumps(data, separators=(",", ":"), allow_nan=False, ensure_ascii=False)
    return (text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")
            .replace("\u2028", "\\u2028").replace("\u2029", "\\u2029"))


# --------------------------------------------------------------------------------------------
# page
# --------------------------------------------------------------------------------------------

_BODY = """<header><h1 id="title">__TITLE__</h1><span>drag: orbit &middot; shift-drag: pan &middot;
wheel: zoom &middot; double-click: reset view</span></header>
<div id="stage"><canvas id="view"></canvas></div>
<aside id="side"><h2>UAVs</h2><ul id="uav-list"></ul><h2>Moving obstacles</h2><ul id="moving-list"></ul>
<h2>Replans</h2><ul id="replan-list"></ul></aside>
<div id="controls"><div id="row"><button id="play" type="button">Play</button>
<div id="track"><input type="range" id="time" min="0" max="0" step="1" value="0" aria-label="time">
<canvas id="timeline" title="replans R1, R2, ... (click to seek)"></canvas></div>
<span id="time-label"></span><label>speed <select id="speed"></select></label></div></div>"""


def _asset(name: str) -> str:
    from importlib import resources

    return resources.files("staghunt.plots").joinpath(name).read_text(encoding="utf-8")


def replay_html(flight: dict[str, Any], max_frames: int = MAX_FRAMES) -> str:
    """A self-contained HTML page (no network) replaying ``flight`` in 3-D; see the module's
    docstring for the page's controls and its ``window.staghuntReplay`` test API."""
    data = replay_data(flight, max_frames)
    title = html.escape(data["title"])
    css, js = (_asset(name) for name in ASSETS)
    return (
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
        "<link rel=\"icon\" href=\"data:,\">\n"
        f"<title>{title} · staghunt replay</title>\n<style>{css}</style>\n</head>\n<body>\n"
        + _BODY.replace("__TITLE__", title)
        + "\n<script type=\"application/json\" id=\"flight-data\">"
        + _script_json(data)
        + "</script>\n<script>"
        + js
        + "</script>\n</body>\n</html>\n"
    )


def write_replay_html(path: str | os.PathLike[str], flight: dict[str, Any],
                      max_frames: int = MAX_FRAMES) -> None:
    """Write :func:`replay_html` of ``flight`` to ``path`` atomically (UTF-8)."""
    write_text_atomic(replay_html(flight, max_frames), Path(path))
