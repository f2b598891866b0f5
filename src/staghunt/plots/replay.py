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
corner, ``null`` where not drawn).
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

_CSS = """
*{box-sizing:border-box}html,body{margin:0;height:100%}
body{font:13px/1.35 system-ui,-apple-system,"Segoe UI",Roboto,Arial,sans-serif;color:#222;background:#fafafa;
display:grid;grid-template-columns:1fr 260px;grid-template-rows:auto 1fr auto;height:100vh}
header{grid-column:1/3;padding:6px 12px;border-bottom:1px solid #ddd;background:#fff}
header h1{font-size:15px;margin:0;display:inline}header span{color:#666;margin-left:12px}
#stage{position:relative;min-height:200px;overflow:hidden}
#view{position:absolute;inset:0;width:100%;height:100%;cursor:grab;touch-action:none;background:#fff}
#side{grid-row:2/4;grid-column:2;border-left:1px solid #ddd;overflow:auto;padding:6px 10px;background:#fff}
#side h2{font-size:12px;text-transform:uppercase;letter-spacing:.05em;color:#555;margin:10px 0 4px}
#side ul{list-style:none;margin:0;padding:0}#side li{padding:1px 0;white-space:nowrap;overflow:hidden;text-overflow:ellipsis}
.sw{display:inline-block;width:10px;height:10px;border-radius:50%;margin-right:6px;vertical-align:-1px}
.num{color:#666;font-variant-numeric:tabular-nums}
#replan-list li{cursor:pointer;color:#999}#replan-list li.past{color:#222}#replan-list li.now{background:#fde7f1}
#controls{padding:6px 12px;border-top:1px solid #ddd;background:#fff}
#row{display:flex;align-items:flex-start;gap:10px}#track{flex:1;min-width:0}#time{display:block;width:100%;margin:4px 0 0}
#time-label{font-variant-numeric:tabular-nums;width:235px;text-align:right;white-space:nowrap}
#timeline{display:block;width:100%;height:34px;cursor:pointer}
button,select{font:inherit}#play{min-width:64px}
"""

_BODY = """<header><h1 id="title">__TITLE__</h1><span>drag: orbit &middot; shift-drag: pan &middot;
wheel: zoom &middot; double-click: reset view</span></header>
<div id="stage"><canvas id="view"></canvas></div>
<aside id="side"><h2>UAVs</h2><ul id="uav-list"></ul><h2>Moving obstacles</h2><ul id="moving-list"></ul>
<h2>Replans</h2><ul id="replan-list"></ul></aside>
<div id="controls"><div id="row"><button id="play" type="button">Play</button>
<div id="track"><input type="range" id="time" min="0" max="0" step="1" value="0" aria-label="time">
<canvas id="timeline" title="replans R1, R2, ... (click to seek)"></canvas></div>
<span id="time-label"></span><label>speed <select id="speed"></select></label></div></div>"""

_JS = r"""
(() => {
"use strict";
const D = JSON.parse(document.getElementById("flight-data").textContent);
const S = D.site, times = D.times, F = times.length, U = D.uavs, C = D.colours;
const $ = (id) => document.getElementById(id);
const view = $("view"), ctx = view.getContext("2d"), slider = $("time"), label = $("time-label");
const playBtn = $("play"), speedSel = $("speed"), tl = $("timeline"), tctx = tl.getContext("2d");
const T0 = times[0], T1 = times[F - 1];
const st = {frame: 0, playing: false, playT: T0, last: null, w: 1, h: 1, tw: 1, screen: []};
const centre = [(S.xmin + S.xmax) / 2, (S.ymin + S.ymax) / 2, (S.zmin + S.zmax) / 2];
const span = Math.hypot(S.xmax - S.xmin, S.ymax - S.ymin, S.zmax - S.zmin) || 1;
const home = {yaw: -62 * Math.PI / 180, pitch: 28 * Math.PI / 180, dist: 1.45 * span, target: centre.slice()};
let cam = {...home, target: centre.slice()}, B = null;
const clamp = (v, a, b) => Math.min(b, Math.max(a, v));
const fmt = (v, d = 1) => (v === null || !isFinite(v)) ? "–" : v.toFixed(d);

function basis() {
  const cp = Math.cos(cam.pitch), sp = Math.sin(cam.pitch), cy = Math.cos(cam.yaw), sy = Math.sin(cam.yaw);
  const t = cam.target, eye = [t[0] + cam.dist * cp * cy, t[1] + cam.dist * cp * sy, t[2] + cam.dist * sp];
  B = {eye, fwd: [-cp * cy, -cp * sy, -sp], right: [-sy, cy, 0], up: [-sp * cy, -sp * sy, cp],
       f: 0.5 * Math.min(st.w, st.h) / Math.tan(20 * Math.PI / 180), near: 0.01 * span};
}
function project(x, y, z) {  // site frame -> [px, py, depth] or null (behind the camera / unknown)
  if (x === null || y === null || z === null) return null;
  const dx = x - B.eye[0], dy = y - B.eye[1], dz = z - B.eye[2];
  const d = dx * B.fwd[0] + dy * B.fwd[1] + dz * B.fwd[2];
  if (!(d > B.near)) return null;
  const r = dx * B.right[0] + dy * B.right[1], u = dx * B.up[0] + dy * B.up[1] + dz * B.up[2];
  return [st.w / 2 + B.f * r / d, st.h / 2 - B.f * u / d, d];
}
function line(pts, close) {  // pts: [[x, y, z] | null, ...]; breaks the line at gaps
  ctx.beginPath();
  let pen = false, first = null;
  for (const p of pts) {
    const q = p ? project(p[0], p[1], p[2]) : null;
    if (!q) { pen = false; continue; }
    if (pen) ctx.lineTo(q[0], q[1]); else { ctx.moveTo(q[0], q[1]); if (!first) first = q; }
    pen = true;
  }
  if (close && first && pen) ctx.lineTo(first[0], first[1]);
  ctx.stroke();
}
function fillPoly(pts, colour, alpha) {
  const q = pts.map((p) => project(p[0], p[1], p[2]));
  if (q.some((v) => !v)) return;
  ctx.save(); ctx.globalAlpha = alpha; ctx.fillStyle = colour; ctx.beginPath();
  q.forEach((v, i) => i ? ctx.lineTo(v[0], v[1]) : ctx.moveTo(v[0], v[1]));
  ctx.closePath(); ctx.fill(); ctx.restore();
}
function pairs(flat) { const out = []; for (let i = 0; i + 1 < flat.length; i += 2) out.push([flat[i], flat[i + 1]]); return out; }
function prism(xy, base, top, edge, face, alpha) {  // xy: [[x, y], ...] footprint
  if (xy.some((p) => p[0] === null || p[1] === null)) return;
  fillPoly(xy.map((p) => [p[0], p[1], top]), face, alpha);
  ctx.strokeStyle = edge;
  line(xy.map((p) => [p[0], p[1], base]), true);
  line(xy.map((p) => [p[0], p[1], top]), true);
  for (const p of xy) line([[p[0], p[1], base], [p[0], p[1], top]]);
}
function circle(x, y, r, n) { const out = []; for (let i = 0; i < n; i++) { const a = 2 * Math.PI * i / n; out.push([x + r * Math.cos(a), y + r * Math.sin(a)]); } return out; }
function cylinder(x, y, r, base, top, edge, face, alpha) {
  const c = circle(x, y, r, 40);
  fillPoly(c.map((p) => [p[0], p[1], top]), face, alpha);
  ctx.strokeStyle = edge;
  line(c.map((p) => [p[0], p[1], base]), true);
  line(c.map((p) => [p[0], p[1], top]), true);
  for (let i = 0; i < 40; i += 5) line([[c[i][0], c[i][1], base], [c[i][0], c[i][1], top]]);
}
function text(s, x, y, colour, align) {
  ctx.font = "12px system-ui,sans-serif"; ctx.textAlign = align || "left"; ctx.textBaseline = "middle";
  ctx.lineWidth = 3; ctx.strokeStyle = "rgba(255,255,255,0.85)"; ctx.strokeText(s, x, y);
  ctx.fillStyle = colour; ctx.fillText(s, x, y);
}
function niceStep(range) { const raw = range / 8, p = Math.pow(10, Math.floor(Math.log10(raw))); for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p; return 10 * p; }
const at = (flat, k, dim) => (flat[dim * k] === null ? null : Array.from({length: dim}, (_, j) => flat[dim * k + j]));

function drawGround() {
  const z = S.zmin, g = niceStep(Math.max(S.xmax - S.xmin, S.ymax - S.ymin));
  fillPoly([[S.xmin, S.ymin, z], [S.xmax, S.ymin, z], [S.xmax, S.ymax, z], [S.xmin, S.ymax, z]], "#e9ecef", 0.6);
  ctx.lineWidth = 0.6; ctx.strokeStyle = "#d3d7db";
  for (let x = Math.ceil(S.xmin / g) * g; x <= S.xmax; x += g) line([[x, S.ymin, z], [x, S.ymax, z]]);
  for (let y = Math.ceil(S.ymin / g) * g; y <= S.ymax; y += g) line([[S.xmin, y, z], [S.xmax, y, z]]);
  if (D.terrain) {
    const t = D.terrain; ctx.strokeStyle = "rgba(120,100,70,0.45)";
    t.z.forEach((row, i) => line(row.map((v, j) => [t.x[j], t.y[i], v])));
    t.x.forEach((x, j) => line(t.z.map((row, i) => [x, t.y[i], row[j]])));
  }
  ctx.lineWidth = 1; ctx.strokeStyle = "#9aa0a6";
  for (const zz of [S.zmin, S.zmax]) line([[S.xmin, S.ymin, zz], [S.xmax, S.ymin, zz], [S.xmax, S.ymax, zz], [S.xmin, S.ymax, zz]], true);
  for (const [x, y] of [[S.xmin, S.ymin], [S.xmax, S.ymin], [S.xmax, S.ymax], [S.xmin, S.ymax]]) line([[x, y, S.zmin], [x, y, S.zmax]]);
  for (let x = Math.ceil(S.xmin / g) * g; x <= S.xmax; x += g) { const q = project(x, S.ymin, z); if (q) text(String(+x.toFixed(6)), q[0], q[1] + 10, "#666", "center"); }
  for (let y = Math.ceil(S.ymin / g) * g; y <= S.ymax; y += g) { if (y === S.ymin) continue; const q = project(S.xmax, y, z); if (q) text(String(+y.toFixed(6)), q[0] + 6, q[1] + 6, "#666"); }
  const off = 0.1 * Math.max(S.xmax - S.xmin, S.ymax - S.ymin);
  for (const [s, p] of [["x (m)", [(S.xmin + S.xmax) / 2, S.ymin - off, z]],
                        ["y (m)", [S.xmax + off, (S.ymin + S.ymax) / 2, z]],
                        ["z " + fmt(S.zmax, 0) + " m", [S.xmin, S.ymin, S.zmax]]]) {
    const q = project(...p); if (q) text(s, q[0], q[1], "#444", "center");
  }
}
function drawStatic() {
  ctx.lineWidth = 1;
  for (const [x, y, r] of D.cylinders) cylinder(x, y, r, D.cylinderBase, S.zmax, C.obstacleEdge, C.obstacle, 0.25);
  for (const p of D.prisms) {
    const edge = p.nofly ? C.nofly : C.obstacleEdge, face = p.nofly ? C.nofly : C.obstacle;
    prism(pairs(p.polygon), p.base, p.top, edge, face, p.nofly ? 0.1 : 0.3);
  }
}
function drawMoving(k) {
  ctx.lineWidth = 1.6;
  for (const m of D.moving) {
    if (m.kind === "cylinder") {  // the track so far, on the ground
      const track = []; for (let i = 0; i <= k; i++) track.push(m.visible[i] ? [m.xy[2 * i], m.xy[2 * i + 1], S.zmin] : null);
      ctx.save(); ctx.setLineDash([3, 4]); ctx.strokeStyle = C.moving; ctx.globalAlpha = 0.6; line(track); ctx.restore();
    }
    if (!m.visible[k]) continue;
    let anchor = null;
    if (m.kind === "cylinder") {
      const p = at(m.xy, k, 2); if (!p) continue;
      cylinder(p[0], p[1], m.radius, m.base, m.top, C.moving, C.moving, 0.25); anchor = [p[0], p[1], m.top];
    } else {
      const xy = pairs(m.polygons[k]); prism(xy, m.base, m.top, C.moving, C.moving, 0.35);
      if (xy.length && xy[0][0] !== null) anchor = [xy.reduce((s, p) => s + p[0], 0) / xy.length, xy.reduce((s, p) => s + p[1], 0) / xy.length, m.top];
    }
    const q = anchor && project(...anchor); if (q) text(m.name, q[0], q[1] - 10, C.moving, "center");
  }
}
function drawUavs(k) {
  ctx.save(); ctx.lineWidth = 1.2; ctx.setLineDash([5, 4]); ctx.globalAlpha = 0.35;
  for (const u of U) { ctx.strokeStyle = u.colour; const pts = []; for (let i = 0; i < F; i++) pts.push(at(u.reference, i, 3)); line(pts); }
  ctx.restore(); ctx.lineWidth = 2.2;
  for (const u of U) { ctx.strokeStyle = u.colour; const pts = []; for (let i = 0; i <= k; i++) pts.push(at(u.actual, i, 3)); line(pts); }
  ctx.lineWidth = 1.5; ctx.strokeStyle = C.moving;
  D.replans.forEach((r, j) => { if (r.frame > k) return; for (const u of U) { const p = at(u.actual, r.frame, 3), q = p && project(...p);
    if (q) { ctx.beginPath(); ctx.moveTo(q[0] - 4, q[1] - 4); ctx.lineTo(q[0] + 4, q[1] + 4); ctx.moveTo(q[0] + 4, q[1] - 4); ctx.lineTo(q[0] - 4, q[1] + 4); ctx.stroke(); } } });
  const dots = U.map((u, n) => { const p = at(u.actual, k, 3); return {n, u, p, q: p && project(...p)}; });
  st.screen = dots.map((d) => d.q ? [d.q[0], d.q[1]] : null);
  ctx.lineWidth = 0.8; ctx.strokeStyle = "rgba(0,0,0,0.35)";
  for (const d of dots) if (d.p) line([d.p, [d.p[0], d.p[1], S.zmin]]);
  dots.filter((d) => d.q).sort((a, b) => b.q[2] - a.q[2]).forEach((d) => {
    const r = clamp(B.f * d.u.radius / d.q[2], 4.5, 14);
    ctx.beginPath(); ctx.arc(d.q[0], d.q[1], r, 0, 2 * Math.PI); ctx.fillStyle = d.u.colour; ctx.fill();
    ctx.lineWidth = 1.2; ctx.strokeStyle = "#111"; ctx.stroke();
    text(d.u.name, d.q[0] + r + 3, d.q[1] - r, d.u.colour);
  });
}
function lastReplan(k) { let j = -1; D.replans.forEach((r, i) => { if (r.frame <= k) j = i; }); return j; }
function drawTimeline() {
  const w = st.tw, h = 34, pad = 8, x = (t) => pad + (w - 2 * pad) * (T1 > T0 ? (t - T0) / (T1 - T0) : 0);
  tctx.clearRect(0, 0, w, h); tctx.strokeStyle = "#bbb"; tctx.lineWidth = 1;
  tctx.beginPath(); tctx.moveTo(pad, 8); tctx.lineTo(w - pad, 8); tctx.stroke();
  tctx.font = "11px system-ui,sans-serif"; tctx.textBaseline = "top"; tctx.textAlign = "center";
  D.replans.forEach((r, j) => {
    const px = x(r.time); tctx.fillStyle = C.moving;
    tctx.beginPath(); tctx.moveTo(px, 10); tctx.lineTo(px - 5, 2); tctx.lineTo(px + 5, 2); tctx.closePath(); tctx.fill();
    tctx.fillText("R" + (j + 1), px, 14);
  });
  const cx = x(times[st.frame]); tctx.strokeStyle = "#1f77b4"; tctx.lineWidth = 2;
  tctx.beginPath(); tctx.moveTo(cx, 0); tctx.lineTo(cx, h); tctx.stroke();
  tctx.fillStyle = "#666"; tctx.textAlign = "left"; tctx.fillText(fmt(T0) + " s", 0, 24); tctx.textAlign = "right"; tctx.fillText(fmt(T1) + " s", w, 24);
}
function updateSide(k) {
  U.forEach((u, n) => {
    const p = at(u.actual, k, 3), r = at(u.reference, k, 3);
    const e = p && r ? Math.hypot(p[0] - r[0], p[1] - r[1], p[2] - r[2]) : null;
    uavItems[n].textContent = "z " + fmt(p && p[2]) + " m · err " + fmt(e, 2) + " m";
  });
  D.moving.forEach((m, i) => {
    const seen = m.visible.slice(0, k + 1).some((v) => v);
    movingItems[i].textContent = m.visible[k] ? "visible" : (seen ? "gone" : "not yet");
  });
  const j = lastReplan(k);
  replanItems.forEach((li, i) => { li.className = (i < j ? "past" : "") + (i === j ? " past now" : ""); });
}
function render() {
  const dpr = window.devicePixelRatio || 1, k = st.frame;
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0); ctx.clearRect(0, 0, st.w, st.h);
  ctx.lineJoin = "round"; basis();
  drawGround(); drawStatic(); drawMoving(k); drawUavs(k);
  const j = lastReplan(k);
  text("t = " + fmt(times[k], 2) + " s", 10, 16, "#222");
  if (j >= 0) text("last replan R" + (j + 1) + " at " + fmt(D.replans[j].time, 2) + " s: " + D.replans[j].trigger + " → " + D.replans[j].verdict, 10, 34, C.moving);
  label.textContent = "t = " + fmt(times[k], 2) + " s / " + fmt(T1, 2) + " s  (" + (k + 1) + "/" + F + ")";
  if (String(slider.value) !== String(k)) slider.value = String(k);
  drawTimeline(); updateSide(k);
}
function setFrame(k) { st.frame = clamp(Math.round(k), 0, F - 1); render(); }
function nearestFrame(t) {
  let lo = 0, hi = F - 1;
  while (hi - lo > 1) { const mid = (lo + hi) >> 1; if (times[mid] <= t) lo = mid; else hi = mid; }
  return Math.abs(times[hi] - t) < Math.abs(t - times[lo]) ? hi : lo;
}
function frameAtOrBefore(t) { let k = nearestFrame(t); if (times[k] > t && k > 0) k -= 1; return k; }
function resize() {
  const dpr = window.devicePixelRatio || 1, r = view.parentElement.getBoundingClientRect();
  st.w = Math.max(1, r.width); st.h = Math.max(1, r.height);
  view.width = Math.round(st.w * dpr); view.height = Math.round(st.h * dpr);
  st.tw = Math.max(1, tl.clientWidth); tl.width = Math.round(st.tw * dpr); tl.height = Math.round(34 * dpr);
  tctx.setTransform(dpr, 0, 0, dpr, 0, 0); render();
}
function play(on) {
  st.playing = on; playBtn.textContent = on ? "Pause" : "Play";
  if (!on) return;
  if (st.frame >= F - 1) st.frame = 0;
  st.playT = times[st.frame]; st.last = null; requestAnimationFrame(tick);
}
function tick(ts) {
  if (!st.playing) return;
  if (st.last !== null) st.playT += (ts - st.last) / 1000 * Number(speedSel.value);
  st.last = ts;
  const k = frameAtOrBefore(st.playT);
  if (k !== st.frame) setFrame(k);
  if (st.playT >= T1) { setFrame(F - 1); play(false); return; }
  requestAnimationFrame(tick);
}
function seekTimeline(e) {
  const r = tl.getBoundingClientRect(), f = clamp((e.clientX - r.left - 8) / Math.max(1, r.width - 16), 0, 1);
  play(false); setFrame(nearestFrame(T0 + f * (T1 - T0)));
}
function li(list, html, colour) { const el = document.createElement("li"); if (colour) { const s = document.createElement("span"); s.className = "sw"; s.style.background = colour; el.append(s); }
  el.append(html); const n = document.createElement("span"); n.className = "num"; el.append(" ", n); $(list).append(el); return {el, n}; }
const uavItems = U.map((u) => li("uav-list", u.name, u.colour).n);
const movingItems = D.moving.map((m) => li("moving-list", m.name + " (" + m.kind + ")", C.moving).n);
const replanItems = D.replans.map((r, j) => { const it = li("replan-list", "R" + (j + 1) + " " + fmt(r.time, 2) + " s: " + r.trigger + " → " + r.verdict);
  it.el.title = it.el.textContent; it.el.addEventListener("click", () => { play(false); setFrame(r.frame); }); return it.el; });
if (!D.uavs.length) li("uav-list", "none");
if (!D.moving.length) li("moving-list", "none");
if (!D.replans.length) li("replan-list", "none");
for (const s of [0.5, 1, 2, 5, 10, 20, 50]) { const o = document.createElement("option"); o.value = String(s); o.textContent = s + "×"; speedSel.append(o); }
speedSel.value = String([1, 2, 5, 10, 20, 50].find((s) => (T1 - T0) / s <= 40) || 50);
slider.max = String(F - 1);
slider.addEventListener("input", () => { play(false); setFrame(Number(slider.value)); });
playBtn.addEventListener("click", () => play(!st.playing));
let drag = null;
view.addEventListener("pointerdown", (e) => { view.setPointerCapture(e.pointerId); view.style.cursor = "grabbing";
  drag = {x: e.clientX, y: e.clientY, yaw: cam.yaw, pitch: cam.pitch, target: cam.target.slice(), pan: e.shiftKey || e.button === 2}; });
view.addEventListener("pointermove", (e) => {
  if (!drag) return;
  const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
  if (drag.pan) { const s = cam.dist / B.f; cam.target = [0, 1, 2].map((i) => drag.target[i] - s * (dx * B.right[i] - dy * B.up[i])); }
  else { cam.yaw = drag.yaw - dx * 0.008; cam.pitch = clamp(drag.pitch + dy * 0.008, -0.2, 1.55); }
  render();
});
const stopDrag = () => { drag = null; view.style.cursor = "grab"; };
view.addEventListener("pointerup", stopDrag); view.addEventListener("pointercancel", stopDrag);
view.addEventListener("contextmenu", (e) => e.preventDefault());
view.addEventListener("wheel", (e) => { e.preventDefault(); cam.dist = clamp(cam.dist * Math.exp(e.deltaY * 0.0012), 0.15 * span, 10 * span); render(); }, {passive: false});
view.addEventListener("dblclick", () => { cam = {...home, target: home.target.slice()}; render(); });
let tlDrag = false;
tl.addEventListener("pointerdown", (e) => { tlDrag = true; tl.setPointerCapture(e.pointerId); seekTimeline(e); });
tl.addEventListener("pointermove", (e) => { if (tlDrag) seekTimeline(e); });
tl.addEventListener("pointerup", () => { tlDrag = false; });
window.addEventListener("resize", resize);
resize();
window.staghuntReplay = Object.freeze({
  setTime: (t) => { play(false); setFrame(nearestFrame(Number(t))); return times[st.frame]; },
  time: () => times[st.frame],
  frame: () => st.frame,
  frameCount: () => F,
  uavPositions: () => U.map((u) => at(u.actual, st.frame, 3)),
  uavScreenPositions: () => st.screen.map((p) => p && p.slice()),
});
})();
"""


def replay_html(flight: dict[str, Any], max_frames: int = MAX_FRAMES) -> str:
    """A self-contained HTML page (no network) replaying ``flight`` in 3-D; see the module's
    docstring for the page's controls and its ``window.staghuntReplay`` test API."""
    data = replay_data(flight, max_frames)
    title = html.escape(data["title"])
    return (
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
        "<link rel=\"icon\" href=\"data:,\">\n"
        f"<title>{title} · staghunt replay</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
        + _BODY.replace("__TITLE__", title)
        + "\n<script type=\"application/json\" id=\"flight-data\">"
        + _script_json(data)
        + "</script>\n<script>"
        + _JS
        + "</script>\n</body>\n</html>\n"
    )


def write_replay_html(path: str | os.PathLike[str], flight: dict[str, Any],
                      max_frames: int = MAX_FRAMES) -> None:
    """Write :func:`replay_html` of ``flight`` to ``path`` atomically (UTF-8)."""
    write_text_atomic(replay_html(flight, max_frames), Path(path))
