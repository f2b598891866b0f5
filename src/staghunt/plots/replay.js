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
function drawFootprints(k) {  // an inspection's photos taken by frame k: their frames on the surface
  let shown = 0;
  ctx.lineWidth = 0.7;
  for (const fp of (D.footprints || [])) {
    if (fp.frame > k) continue;
    const c = []; for (let i = 0; i < 4; i++) c.push([fp.corners[3 * i], fp.corners[3 * i + 1], fp.corners[3 * i + 2]]);
    const colour = U[fp.uav] ? U[fp.uav].colour : "#444";
    fillPoly(c, colour, 0.06); ctx.strokeStyle = colour; ctx.globalAlpha = 0.35; line(c, true); ctx.globalAlpha = 1;
    shown += 1;
  }
  st.footprints = shown;
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
  drawGround(); drawStatic(); drawMoving(k); drawFootprints(k); drawUavs(k);
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
  footprintsShown: () => st.footprints || 0,
});
})();
