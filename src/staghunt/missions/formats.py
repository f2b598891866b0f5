"""Mission files, one function per format: each returns the file's content (text or bytes) and
writes nothing, so an export can build every file before it writes any.

Per UAV ``n`` the inputs are the planned points in WGS84, ``geo`` ``(M, 3)`` = ``(lat, lon, alt
AMSL)``, their WGS84 ellipsoid heights ``ell`` ``(M,)`` (``AMSL + N``, the EGM2008 geoid height),
the ground under each point ``ground`` ``(M,)`` (m AMSL, from the scenario's terrain model), the
leg speeds ``speeds`` ``(M - 1,)`` (m/s, the average speed that keeps the common times) and the
takeoff point ``home`` = ``(lat, lon, alt AMSL)`` of the ground under the UAV's start, with its
ellipsoid height ``home_ell``. The altitude frame (``relative``, ``amsl``, ``terrain``) is chosen
per export; :data:`FRAME_SUPPORT` says which formats have which, :data:`TARGET_LIMITS` the
published limits of each target, checked by :func:`check_limits` (all three defined in
:mod:`staghunt.missions.targets`; DJI WPML is written by :mod:`staghunt.missions.dji`; both
re-exported here).

- QGroundControl ``.plan`` and QGC WPL 110: ``relative`` = MAV_FRAME 3 (``AMSL = home altitude +
  value``), ``amsl`` = MAV_FRAME 0, ``terrain`` = MAV_FRAME 10 (height above the terrain under the
  waypoint; the takeoff item stays MAV_FRAME 3: it climbs over home, which is the ground); the
  home position itself always AMSL;
- DJI WPML: ``relative`` = ``relativeToStartPoint``; ``amsl`` = template ``EGM96`` heights,
  executed as ``WGS84`` ellipsoid heights; ``wpml:ellipsoidHeight`` and ``takeOffRefPoint``'s
  height are WGS84 ellipsoid heights in every mode; no terrain frame for waypoint routes;
- Litchi CSV: ``relative`` = ``altitudemode 0`` (above the takeoff point), ``terrain`` =
  ``altitudemode 1`` (above the ground under the waypoint); no AMSL mode;
- KML (``altitudeMode absolute``) and GeoJSON: AMSL, whatever the frame.
"""

from __future__ import annotations

import csv
import io
import json
import math
from typing import Any
from xml.sax.saxutils import escape

import numpy as np

from staghunt.missions.camera import (
    MAV_CMD_DO_MOUNT_CONTROL, MAV_CMD_DO_SET_CAM_TRIGG_DIST, MAV_CMD_IMAGE_START_CAPTURE, MAV_MOUNT_MODE_MAVLINK_TARGETING,
    CameraAction,
)
from staghunt.missions.dji import DJI_NS, dji_kmz, dji_speeds  # noqa: F401  (re-exported: one of the formats)
from staghunt.missions.targets import (  # noqa: F401  (re-exported: frames and limits of the targets)
    ALTITUDE_FRAMES, DJI_HEIGHT_MODE, DJI_SPEED_RANGE, FRAME_GLOBAL, FRAME_MISSING, FRAME_RELATIVE, FRAME_SUPPORT,
    FRAME_TERRAIN, LITCHI_ALTITUDE_MODE, LITCHI_SPEED_RANGE, MAV_FRAME, QGC_ALTITUDE_MODE, QGC_CHANGE_SPEED, QGC_LAND,
    QGC_TAKEOFF, QGC_WAYPOINT, TARGET_LIMITS, TargetLimitError, check_frame, check_limits, frame_altitudes,
)

FORMATS = ("plan", "waypoints", "kmz", "litchi", "kml", "geojson", "trajectories")
"""``plan`` (QGroundControl), ``waypoints`` (QGC WPL 110), ``kmz`` (DJI WPML), ``litchi``
(Litchi CSV): one file per UAV; ``kml``, ``geojson``, ``trajectories`` (CSV): one per team."""

LITCHI_HEADER = (
    ["latitude", "longitude", "altitude(m)", "heading(deg)", "curvesize(m)", "rotationdir",
     "gimbalmode", "gimbalpitchangle"]
    + [f"action{kind}{i}" for i in range(1, 16) for kind in ("type", "param")]
    + ["altitudemode", "speed(m/s)", "poi_latitude", "poi_longitude", "poi_altitude(m)",
       "poi_altitudemode", "photo_timeinterval", "photo_distinterval"]
)
"""Litchi's documented 46 columns (the order of its mission hub export)."""


def _qgc_item(seq: int, command: int, frame: int, params: list[Any]) -> dict[str, Any]:
    return {"autoContinue": True, "command": command, "doJumpId": seq, "frame": frame,
            "params": params, "type": "SimpleItem"}


def mission_items(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray, ground: np.ndarray,
                  frame: str = "relative", actions: list[CameraAction] | None = None
                  ) -> list[tuple[int, int, list[float]]]:
    """``(command, MAV_FRAME, 7 params)``: take off to the start, then per leg a speed command and
    the leg's end point (altitudes in ``frame``), in flight order. The takeoff item is relative
    to home unless ``frame`` is ``amsl``. ``actions`` ``(M,)``: each waypoint's camera and gimbal
    (:mod:`staghunt.missions.camera`): its heading and hover in the waypoint item, the gimbal's
    pitch just before it, the camera's commands just after it."""
    alt = frame_altitudes(geo, home, ground, frame)
    f = MAV_FRAME[frame]
    t_frame, t_alt = (f, alt[0]) if frame != "terrain" else (FRAME_RELATIVE, geo[0, 2] - home[2])
    acts = actions if actions is not None else [CameraAction()] * len(geo)
    items: list[tuple[int, int, list[float]]] = [
        (QGC_TAKEOFF, t_frame, [0.0, 0.0, 0.0, math.nan, geo[0, 0], geo[0, 1], t_alt])]

    def before(a: CameraAction) -> None:
        if a.gimbal_pitch_deg is not None:
            items.append((MAV_CMD_DO_MOUNT_CONTROL, f, [float(a.gimbal_pitch_deg), 0.0, 0.0, 0.0, 0.0, 0.0,
                                                        float(MAV_MOUNT_MODE_MAVLINK_TARGETING)]))

    def after(a: CameraAction) -> None:
        if a.stop:
            items.append((MAV_CMD_DO_SET_CAM_TRIGG_DIST, f, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]))
        if a.start_distance_m is not None:
            items.append((MAV_CMD_DO_SET_CAM_TRIGG_DIST, f, [float(a.start_distance_m), 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]))
        if a.photo:
            items.append((MAV_CMD_IMAGE_START_CAPTURE, f, [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]))

    if actions is not None and (acts[0].hold_s or acts[0].heading_deg is not None):
        items.append((QGC_WAYPOINT, f, [float(acts[0].hold_s), 0.0, 0.0, _heading(acts[0]), geo[0, 0], geo[0, 1],
                                        alt[0]]))
    before(acts[0])
    after(acts[0])
    for k in range(1, len(geo)):
        before(acts[k])
        items.append((QGC_CHANGE_SPEED, f, [1.0, float(speeds[k - 1]), -1.0, 0.0, 0.0, 0.0, 0.0]))
        items.append((QGC_WAYPOINT, f, [float(acts[k].hold_s), 0.0, 0.0, _heading(acts[k]), geo[k, 0], geo[k, 1],
                                        alt[k]]))
        after(acts[k])
    return items


def _heading(a: CameraAction) -> float:
    return math.nan if a.heading_deg is None else float(a.heading_deg)


_FRAME_MODE = {FRAME_RELATIVE: 1, FRAME_GLOBAL: 2, FRAME_TERRAIN: 4}


def qgc_plan(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray, cruise: float,
             note: str = "", ground: np.ndarray | None = None, frame: str = "relative",
             actions: list[CameraAction] | None = None) -> str:
    """QGroundControl plan (JSON, ``fileType`` Plan, version 1), altitudes in ``frame``, with the
    waypoints' camera ``actions`` (:func:`mission_items`)."""
    ground = geo[:, 2] if ground is None else ground
    items = []
    for seq, (cmd, f, params) in enumerate(mission_items(geo, speeds, home, ground, frame, actions), start=1):
        p = [None if isinstance(v, float) and math.isnan(v) else float(v) for v in params]
        item = _qgc_item(seq, cmd, f, p)
        if cmd in (QGC_WAYPOINT, QGC_TAKEOFF):
            item.update({"AMSLAltAboveTerrain": None, "Altitude": p[6], "AltitudeMode": _FRAME_MODE[f]})
        items.append(item)
    plan = {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "staghunt" + (f" ({note})" if note else ""),
        "mission": {
            "version": 2,
            # PX4 (MAV_AUTOPILOT_PX4; QGC converts for ArduPilot on load), but ArduPilot (3) for the
            # terrain frame: QGC offers MAV_FRAME 10 only to non-PX4 vehicles
            "firmwareType": 3 if frame == "terrain" else 12,
            "vehicleType": 2,  # MAV_TYPE_QUADROTOR
            "cruiseSpeed": float(cruise),
            "hoverSpeed": float(cruise),
            # QGC's plan-wide altitude mode; 0 (mixed) when the takeoff item's frame differs
            "globalPlanAltitudeMode": QGC_ALTITUDE_MODE[frame] if frame != "terrain" else 0,
            "plannedHomePosition": [float(home[0]), float(home[1]), float(home[2])],
            "items": items,
        },
        "geoFence": {"version": 2, "circles": [], "polygons": []},
        "rallyPoints": {"version": 2, "points": []},
    }
    return json.dumps(plan, indent=2) + "\n"


def qgc_wpl(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray, ground: np.ndarray | None = None,
            frame: str = "relative", actions: list[CameraAction] | None = None) -> str:
    """QGC WPL 110 text (ArduPilot / Mission Planner): line 0 home (absolute), then the items
    (altitudes in ``frame``, camera ``actions`` as :func:`mission_items` places them)."""
    ground = geo[:, 2] if ground is None else ground
    lines = ["QGC WPL 110"]

    def row(seq: int, mav_frame: int, cmd: int, p: list[float], current: int = 0) -> str:
        vals = [0.0 if math.isnan(v) else v for v in p]
        fields = [str(seq), str(current), str(mav_frame), str(cmd)] + [f"{v:.8f}" for v in vals[:4]] + \
                 [f"{vals[4]:.8f}", f"{vals[5]:.8f}", f"{vals[6]:.6f}", "1"]
        return "\t".join(fields)

    lines.append(row(0, FRAME_GLOBAL, QGC_WAYPOINT, [0, 0, 0, 0, home[0], home[1], home[2]], current=1))
    for seq, (cmd, f, params) in enumerate(mission_items(geo, speeds, home, ground, frame, actions), start=1):
        lines.append(row(seq, f, cmd, params))
    return "\n".join(lines) + "\n"


LITCHI_STAY_FOR = 0
LITCHI_STAY_MAX_MS = 32000
"""Litchi's ``Stay For`` waypoint action (type 0, parameter in ms, at most 32 s each; at most
15 actions a waypoint)."""


def litchi_rows(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray, ground: np.ndarray,
                frame: str = "relative", durations: np.ndarray | None = None,
                min_leg: float = TARGET_LIMITS["litchi"]["leg_m"][0], actions: list[CameraAction] | None = None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The waypoints as Litchi's CSV writes them for ``frame``: ``(index (W,), altitude (W,),
    speed (W,), hold_ms (W,))``.

    A planned point closer than ``min_leg`` (0.6 m, DJI's minimum between waypoints) to the one
    before is a hold (the UAV waits for its team): it is merged into that waypoint, which gets a
    ``Stay For`` of the leg's duration (``durations`` ``(M - 1,)`` s), so the timing is kept.
    ``index``: the planned point each waypoint is; altitudes above the takeoff point
    (``relative``) or the ground under the waypoint (``terrain``); speed of the leg that leaves
    it (the last repeats the one before)."""
    if frame not in LITCHI_ALTITUDE_MODE:
        check_frame("litchi", frame)
    alt = frame_altitudes(geo, home, ground, frame)
    speeds = np.asarray(speeds, dtype=float)
    dt = np.zeros(len(geo) - 1) if durations is None else np.asarray(durations, dtype=float)
    legs = np.linalg.norm(np.diff(_local_metres(geo), axis=0), axis=-1)  # (M - 1,)
    index, hold, leave = [0], [0.0], [0]
    for k in range(1, len(geo)):
        if legs[k - 1] < min_leg and (actions is None or actions[k].empty):
            hold[-1] += float(dt[k - 1]) * 1000.0
            leave[-1] = k
        else:
            index.append(k)
            hold.append(0.0)
            leave.append(k)
    idx = np.array(index)
    spd = speeds[np.minimum(np.array(leave), len(geo) - 2)]
    return idx, alt[idx], spd, np.array(hold)


def _local_metres(geo: np.ndarray) -> np.ndarray:
    """``(M, 3)`` east, north, up metres of ``geo`` ``(M, 3)`` from its first point (flat earth:
    for the 0.6 m test between neighbouring waypoints)."""
    lat0 = math.radians(float(geo[0, 0]))
    r = 6371008.8
    return np.column_stack([np.radians(geo[:, 1] - geo[0, 1]) * r * math.cos(lat0),
                            np.radians(geo[:, 0] - geo[0, 0]) * r, geo[:, 2] - geo[0, 2]])


def litchi_legs(geo: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``(W - 1,)`` metres between the consecutive written waypoints ``geo[index]``."""
    return np.linalg.norm(np.diff(_local_metres(geo[index]), axis=0), axis=-1)


def litchi_csv(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray, ground: np.ndarray | None = None,
               frame: str = "relative", durations: np.ndarray | None = None,
               actions: list[CameraAction] | None = None) -> str:
    """Litchi mission CSV: the planned points (holds merged, :func:`litchi_rows`), altitude in
    ``frame`` (``altitudemode`` 0 above the takeoff point, 1 above ground), heading along the
    next leg (or the camera's, :mod:`staghunt.missions.camera`), speed of the leg that starts
    there, holds as ``Stay For`` actions, the camera's tilt, photos and distance interval."""
    ground = geo[:, 2] if ground is None else ground
    idx, alt, spd, hold = litchi_rows(geo, speeds, home, ground, frame, durations, actions=actions)
    acts = [CameraAction()] * len(geo) if actions is None else actions
    interval = _litchi_intervals([acts[i] for i in idx])
    mode = LITCHI_ALTITUDE_MODE[frame]
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(LITCHI_HEADER)
    pts = geo[idx]
    W = len(pts)
    for k in range(W):
        a, b = (k, k + 1) if k + 1 < W else (max(k - 1, 0), k)
        dlat = math.radians(pts[b, 0] - pts[a, 0])
        dlon = math.radians(pts[b, 1] - pts[a, 1]) * math.cos(math.radians(pts[a, 0]))
        heading = (math.degrees(math.atan2(dlon, dlat)) + 360.0) % 360.0
        a = acts[idx[k]]
        if a.heading_deg is not None:
            heading = float(a.heading_deg)
        actions = ["-1", "0"] * 15
        slot = 0
        if a.gimbal_pitch_deg is not None:
            actions[0:2] = [str(LITCHI_TILT_CAMERA), f"{a.gimbal_pitch_deg:.0f}"]
            slot = 1
        ms = int(round(hold[k] + 1000.0 * a.hold_s))
        while ms > 0:
            if slot == 15:
                raise TargetLimitError(f"Litchi: a hold of {hold[k] / 1000:.1f} s needs more than 15 Stay For actions")
            chunk = min(ms, LITCHI_STAY_MAX_MS)
            actions[2 * slot:2 * slot + 2] = [str(LITCHI_STAY_FOR), str(chunk)]
            ms -= chunk
            slot += 1
        if a.photo:
            if slot == 15:
                raise TargetLimitError("Litchi: no action slot left for the photo (15 actions a waypoint)")
            actions[2 * slot:2 * slot + 2] = [str(LITCHI_TAKE_PHOTO), "0"]
        gimbal = ["2", f"{a.gimbal_pitch_deg:.0f}"] if a.gimbal_pitch_deg is not None else ["0", "0"]
        row = [f"{pts[k, 0]:.8f}", f"{pts[k, 1]:.8f}", f"{alt[k]:.2f}",
               f"{heading:.1f}", "0", "0"] + gimbal + actions
        row += [str(mode), f"{spd[k]:.2f}", "0", "0", "0", "0", "-1",
                f"{interval[k]:.2f}" if interval[k] > 0 else "-1"]
        w.writerow(row)
    return out.getvalue()


LITCHI_TAKE_PHOTO = 1
LITCHI_TILT_CAMERA = 5


def _litchi_intervals(acts: list[CameraAction]) -> list[float]:
    """``photo_distinterval`` of each written waypoint: the distance of the capture it is in (from
    the waypoint that starts it to the one before the one that stops it), else 0."""
    out, current = [], 0.0
    for a in acts:
        if a.stop:
            current = 0.0
        if a.start_distance_m is not None:
            current = float(a.start_distance_m)
        out.append(current)
    return out



def team_kml(geos: list[np.ndarray], names: list[str], note: str = "") -> str:
    """KML 2.2: one LineString per UAV, ``altitudeMode`` absolute (AMSL), ``lon,lat,alt``."""
    marks = []
    for geo, name in zip(geos, names):
        coords = " ".join(f"{p[1]:.8f},{p[0]:.8f},{p[2]:.3f}" for p in geo)
        marks.append(f"<Placemark><name>{escape(name)}</name><LineString><altitudeMode>absolute"
                     f"</altitudeMode><coordinates>{coords}</coordinates></LineString></Placemark>")
    title = "staghunt mission" + (f" ({note})" if note else "")
    return ('<?xml version="1.0" encoding="UTF-8"?>\n<kml xmlns="http://www.opengis.net/kml/2.2">'
            f"<Document><name>{escape(title)}</name>{''.join(marks)}</Document></kml>\n")


def team_geojson(geos: list[np.ndarray], names: list[str], times: np.ndarray, note: str = "") -> str:
    """GeoJSON FeatureCollection (RFC 7946): one LineString per UAV, ``[lon, lat, alt AMSL]``."""
    features = []
    for geo, name in zip(geos, names):
        features.append({
            "type": "Feature",
            "geometry": {"type": "LineString",
                         "coordinates": [[round(float(p[1]), 9), round(float(p[0]), 9), round(float(p[2]), 3)]
                                         for p in geo]},
            "properties": {"name": name, "altitude": "metres above mean sea level",
                           "times_s": [round(float(t), 3) for t in times],
                           **({"warning": note} if note else {})},
        })
    return json.dumps({"type": "FeatureCollection", "features": features}, indent=1) + "\n"


def trajectories_csv(t: np.ndarray, pos: np.ndarray, vel: np.ndarray) -> str:
    """``t,uav,x,y,z,vx,vy,vz`` (site frame, metres, m/s; ``uav`` 1..N), all UAVs on one grid."""
    out = io.StringIO()
    out.write("t,uav,x,y,z,vx,vy,vz\n")
    N = pos.shape[0]
    for i, ti in enumerate(t):
        for n in range(N):
            p, v = pos[n, i], vel[n, i]
            out.write(f"{ti:.3f},{n + 1},{p[0]:.4f},{p[1]:.4f},{p[2]:.4f},{v[0]:.4f},{v[1]:.4f},{v[2]:.4f}\n")
    return out.getvalue()
