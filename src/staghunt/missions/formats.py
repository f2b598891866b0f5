"""Mission files, one function per format: each returns the file's content (text or bytes) and
writes nothing, so an export can build every file before it writes any.

Per UAV ``n`` the inputs are the planned points in WGS84, ``geo`` ``(M, 3)`` = ``(lat, lon, alt
AMSL)``, their WGS84 ellipsoid heights ``ell`` ``(M,)`` (``AMSL + N``, the EGM2008 geoid height),
the ground under each point ``ground`` ``(M,)`` (m AMSL, from the scenario's terrain model), the
leg speeds ``speeds`` ``(M - 1,)`` (m/s, the average speed that keeps the common times) and the
takeoff point ``home`` = ``(lat, lon, alt AMSL)`` of the ground under the UAV's start, with its
ellipsoid height ``home_ell``. The altitude frame (``relative``, ``amsl``, ``terrain``) is chosen
per export; :data:`FRAME_SUPPORT` says which formats have which, :data:`TARGET_LIMITS` the
published limits of each target, checked by :func:`check_limits`.

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
import zipfile
from typing import Any
from xml.sax.saxutils import escape

import numpy as np

from staghunt.errors import FieldError

FORMATS = ("plan", "waypoints", "kmz", "litchi", "kml", "geojson", "trajectories")
"""``plan`` (QGroundControl), ``waypoints`` (QGC WPL 110), ``kmz`` (DJI WPML), ``litchi``
(Litchi CSV): one file per UAV; ``kml``, ``geojson``, ``trajectories`` (CSV): one per team."""

QGC_WAYPOINT = 16
QGC_LAND = 21
QGC_TAKEOFF = 22
QGC_CHANGE_SPEED = 178
FRAME_GLOBAL = 0
FRAME_RELATIVE = 3
FRAME_TERRAIN = 10
ALTITUDE_FRAMES = ("relative", "amsl", "terrain")
MAV_FRAME = {"relative": FRAME_RELATIVE, "amsl": FRAME_GLOBAL, "terrain": FRAME_TERRAIN}
QGC_ALTITUDE_MODE = {"relative": 1, "amsl": 2, "terrain": 4}
"""QGroundControl's ``AltitudeMode`` of a plan item (its ``AltMode`` enum: 0 mixed, 1 relative,
2 absolute, 3 calculated above terrain (sent as absolute), 4 terrain frame)."""
DJI_HEIGHT_MODE = {"relative": ("relativeToStartPoint", "relativeToStartPoint"), "amsl": ("EGM96", "WGS84")}
"""``(template.kml heightMode, waylines.wpml executeHeightMode)`` per frame."""
LITCHI_ALTITUDE_MODE = {"relative": 0, "terrain": 1}

FRAME_SUPPORT: dict[str, dict[str, str]] = {
    "plan": {"relative": "MAV_FRAME 3, AltitudeMode 1", "amsl": "MAV_FRAME 0, AltitudeMode 2",
             "terrain": "MAV_FRAME 10, AltitudeMode 4 (takeoff item MAV_FRAME 3)"},
    "waypoints": {"relative": "MAV_FRAME 3", "amsl": "MAV_FRAME 0",
                  "terrain": "MAV_FRAME 10 (takeoff item MAV_FRAME 3)"},
    "kmz": {"relative": "heightMode relativeToStartPoint, executeHeightMode relativeToStartPoint",
            "amsl": "heightMode EGM96, executeHeightMode WGS84 (ellipsoid heights)"},
    "litchi": {"relative": "altitudemode 0 (above the takeoff point)",
               "terrain": "altitudemode 1 (above the ground under each waypoint)"},
}
"""What each per-UAV format writes for each altitude frame; a frame not listed does not exist
in that format and is refused."""
FRAME_MISSING = {
    ("kmz", "terrain"): "DJI WPML has no terrain frame for waypoint routes (aboveGroundLevel is "
                        "FlightHub 2 only, realTimeFollowSurface is for mapping templates only)",
    ("litchi", "amsl"): "Litchi has no AMSL altitude mode (altitudemode 0 is above the takeoff "
                        "point, 1 above ground)",
}

TARGET_LIMITS: dict[str, dict[str, Any]] = {
    "plan": {"target": "QGroundControl, PX4", "max_items": 500,
             "source": "PX4 dataman NUM_MISSIONS_SUPPORTED = 500 mission items on flight "
                       "controllers (PX4-Autopilot PR 18827)"},
    "waypoints": {"target": "ArduPilot (Mission Planner, MAVProxy)", "max_items": 700,
                  "source": "about 700 items fit a Pixhawk's mission storage; ArduPilot "
                            "overwrites the last item when full (ArduPilot issues 2391, 7254)"},
    "kmz": {"target": "DJI WPML (Pilot 2, FlightHub 2)", "min_waypoints": 2, "max_waypoints": 65535,
            "speed_m_s": (1.0, 15.0),
            "source": "waypointSpeed 1-15 m/s (DJI WPML common elements); 2-65535 waypoints "
                      "(DJI MSDK WaypointV2 MISSION_COUNT_TOO_FEW / OVER_RANGE)"},
    "litchi": {"target": "Litchi (DJI SDK waypoint missions)", "min_waypoints": 2, "max_waypoints": 99,
               "speed_m_s": (0.0, 15.0), "altitude_m": (-200.0, 500.0), "leg_m": (0.6, 1999.0),
               "route_m": 30000.0, "max_hold_ms": 15 * 32000,
               "source": "Litchi CSV altitude -200..500 m, speed 0..15 m/s (0 = cruise speed); "
                         "DJI SDK: 2-99 waypoints a mission, 0.6-1999 m between waypoints, "
                         "30 km a mission, 15 actions a waypoint, Stay For 0-32 s"},
}
"""The published limits of each target, one dict per per-UAV format: counts (``max_items``:
MAVLink mission items including home; ``min_waypoints``/``max_waypoints``), ranges (``speed_m_s``,
``altitude_m`` in the file's own frame, ``leg_m`` between consecutive waypoints) and totals
(``route_m``). A file that breaks one is refused (:class:`TargetLimitError`); speeds below a
DJI minimum are raised to it (the leg is flown faster, never slower than planned)."""
DJI_SPEED_RANGE = TARGET_LIMITS["kmz"]["speed_m_s"]
LITCHI_SPEED_RANGE = TARGET_LIMITS["litchi"]["speed_m_s"]


class TargetLimitError(FieldError):
    """A mission file would break a published limit of its target (``field``: ``formats``) or
    use a frame it lacks (``altitude_frame``)."""

    def __init__(self, message: str, field: str = "formats") -> None:
        super().__init__(message, field)


def check_frame(fmt: str, frame: str) -> None:
    """Raise :class:`TargetLimitError` if ``fmt`` has no ``frame``."""
    if fmt in FRAME_SUPPORT and frame not in FRAME_SUPPORT[fmt]:
        others = ", ".join(FRAME_SUPPORT[fmt])
        raise TargetLimitError(f"{fmt}: no altitude frame {frame}: {FRAME_MISSING[(fmt, frame)]}; "
                               f"use {others}, or leave {fmt} out of the formats", "altitude_frame")


def check_limits(fmt: str, file: str, *, waypoints: int, items: int | None = None,
                 speeds: np.ndarray | None = None, altitudes: np.ndarray | None = None,
                 legs: np.ndarray | None = None, holds_ms: np.ndarray | None = None) -> None:
    """Raise :class:`TargetLimitError` (one line naming ``file``, the limit and the value) if the
    file breaks one of :data:`TARGET_LIMITS` ``[fmt]``: ``waypoints`` and MAVLink ``items``
    counts, ``speeds`` ``(L,)`` m/s as written, ``altitudes`` ``(W,)`` m in the file's frame,
    ``legs`` ``(W - 1,)`` 3-D distances between consecutive waypoints (m), ``holds_ms`` ``(W,)``
    Litchi ``Stay For`` time at each waypoint (ms)."""
    lim = TARGET_LIMITS.get(fmt)
    if lim is None:
        return
    target = lim["target"]

    def refuse(what: str) -> None:
        raise TargetLimitError(f"{file}: {what} ({target}); not exported")

    if "max_items" in lim and items is not None and items > lim["max_items"]:
        refuse(f"{items} mission items, at most {lim['max_items']}")
    if "min_waypoints" in lim and waypoints < lim["min_waypoints"]:
        refuse(f"{waypoints} waypoints, at least {lim['min_waypoints']}")
    if "max_waypoints" in lim and waypoints > lim["max_waypoints"]:
        refuse(f"{waypoints} waypoints, at most {lim['max_waypoints']}")
    if "speed_m_s" in lim and speeds is not None and len(speeds):
        lo, hi = lim["speed_m_s"]
        if float(np.max(speeds)) > hi + 1e-9:
            refuse(f"leg speed {float(np.max(speeds)):.2f} m/s, at most {hi:g} m/s")
    if "altitude_m" in lim and altitudes is not None and len(altitudes):
        lo, hi = lim["altitude_m"]
        for v in (float(np.min(altitudes)), float(np.max(altitudes))):
            if not lo <= v <= hi:
                refuse(f"altitude {v:.1f} m, must lie in [{lo:g}, {hi:g}] m")
    if "leg_m" in lim and legs is not None and len(legs):
        lo, hi = lim["leg_m"]
        k = int(np.argmin(legs)) if float(np.min(legs)) < lo else int(np.argmax(legs))
        if not lo <= float(legs[k]) <= hi:
            refuse(f"{float(legs[k]):.2f} m between waypoints {k + 1} and {k + 2}, must lie in [{lo:g}, {hi:g}] m")
    if "max_hold_ms" in lim and holds_ms is not None and len(holds_ms) and float(np.max(holds_ms)) > lim["max_hold_ms"]:
        refuse(f"a hold of {float(np.max(holds_ms)) / 1000:.1f} s at one waypoint, at most "
               f"{lim['max_hold_ms'] / 1000:g} s (15 Stay For actions of 32 s)")
    if "route_m" in lim and legs is not None and float(np.sum(legs)) > lim["route_m"]:
        refuse(f"route {float(np.sum(legs)):.0f} m long, at most {lim['route_m']:g} m")


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


def frame_altitudes(geo: np.ndarray, home: np.ndarray, ground: np.ndarray, frame: str) -> np.ndarray:
    """``(M,)`` the altitudes of ``geo`` ``(M, 3)`` in ``frame``: above ``home`` (``relative``),
    AMSL (``amsl``) or above ``ground`` ``(M,)`` under each point (``terrain``)."""
    if frame == "relative":
        return geo[:, 2] - home[2]
    if frame == "amsl":
        return geo[:, 2].copy()
    if frame == "terrain":
        return geo[:, 2] - np.asarray(ground, dtype=float)
    raise ValueError(f"unknown altitude frame {frame!r}; choose from {', '.join(ALTITUDE_FRAMES)}")


def mission_items(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray, ground: np.ndarray,
                  frame: str = "relative") -> list[tuple[int, int, list[float]]]:
    """``(command, MAV_FRAME, 7 params)``: take off to the start, then per leg a speed command and
    the leg's end point (altitudes in ``frame``), in flight order. The takeoff item is relative
    to home unless ``frame`` is ``amsl``."""
    alt = frame_altitudes(geo, home, ground, frame)
    f = MAV_FRAME[frame]
    t_frame, t_alt = (f, alt[0]) if frame != "terrain" else (FRAME_RELATIVE, geo[0, 2] - home[2])
    items: list[tuple[int, int, list[float]]] = [
        (QGC_TAKEOFF, t_frame, [0.0, 0.0, 0.0, math.nan, geo[0, 0], geo[0, 1], t_alt])]
    for k in range(1, len(geo)):
        items.append((QGC_CHANGE_SPEED, f, [1.0, float(speeds[k - 1]), -1.0, 0.0, 0.0, 0.0, 0.0]))
        items.append((QGC_WAYPOINT, f, [0.0, 0.0, 0.0, math.nan, geo[k, 0], geo[k, 1], alt[k]]))
    return items


_FRAME_MODE = {FRAME_RELATIVE: 1, FRAME_GLOBAL: 2, FRAME_TERRAIN: 4}


def qgc_plan(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray, cruise: float,
             note: str = "", ground: np.ndarray | None = None, frame: str = "relative") -> str:
    """QGroundControl plan (JSON, ``fileType`` Plan, version 1), altitudes in ``frame``."""
    ground = geo[:, 2] if ground is None else ground
    items = []
    for seq, (cmd, f, params) in enumerate(mission_items(geo, speeds, home, ground, frame), start=1):
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
            frame: str = "relative") -> str:
    """QGC WPL 110 text (ArduPilot / Mission Planner): line 0 home (absolute), then the items
    (altitudes in ``frame``)."""
    ground = geo[:, 2] if ground is None else ground
    lines = ["QGC WPL 110"]

    def row(seq: int, mav_frame: int, cmd: int, p: list[float], current: int = 0) -> str:
        vals = [0.0 if math.isnan(v) else v for v in p]
        fields = [str(seq), str(current), str(mav_frame), str(cmd)] + [f"{v:.8f}" for v in vals[:4]] + \
                 [f"{vals[4]:.8f}", f"{vals[5]:.8f}", f"{vals[6]:.6f}", "1"]
        return "\t".join(fields)

    lines.append(row(0, FRAME_GLOBAL, QGC_WAYPOINT, [0, 0, 0, 0, home[0], home[1], home[2]], current=1))
    for seq, (cmd, f, params) in enumerate(mission_items(geo, speeds, home, ground, frame), start=1):
        lines.append(row(seq, f, cmd, params))
    return "\n".join(lines) + "\n"


LITCHI_STAY_FOR = 0
LITCHI_STAY_MAX_MS = 32000
"""Litchi's ``Stay For`` waypoint action (type 0, parameter in ms, at most 32 s each; at most
15 actions a waypoint)."""


def litchi_rows(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray, ground: np.ndarray,
                frame: str = "relative", durations: np.ndarray | None = None,
                min_leg: float = TARGET_LIMITS["litchi"]["leg_m"][0]
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
        if legs[k - 1] < min_leg:
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
               frame: str = "relative", durations: np.ndarray | None = None) -> str:
    """Litchi mission CSV: the planned points (holds merged, :func:`litchi_rows`), altitude in
    ``frame`` (``altitudemode`` 0 above the takeoff point, 1 above ground), heading along the
    next leg, speed of the leg that starts there, holds as ``Stay For`` actions."""
    ground = geo[:, 2] if ground is None else ground
    idx, alt, spd, hold = litchi_rows(geo, speeds, home, ground, frame, durations)
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
        actions = ["-1", "0"] * 15
        ms, slot = int(round(hold[k])), 0
        while ms > 0:
            if slot == 15:
                raise TargetLimitError(f"Litchi: a hold of {hold[k] / 1000:.1f} s needs more than 15 Stay For actions")
            chunk = min(ms, LITCHI_STAY_MAX_MS)
            actions[2 * slot:2 * slot + 2] = [str(LITCHI_STAY_FOR), str(chunk)]
            ms -= chunk
            slot += 1
        row = [f"{pts[k, 0]:.8f}", f"{pts[k, 1]:.8f}", f"{alt[k]:.2f}",
               f"{heading:.1f}", "0", "0", "0", "0"] + actions
        row += [str(mode), f"{spd[k]:.2f}", "0", "0", "0", "0", "-1", "-1"]
        w.writerow(row)
    return out.getvalue()


def _dji_config(home: np.ndarray, home_ell: float, speed: float) -> str:
    return (
        "<wpml:missionConfig>"
        "<wpml:flyToWaylineMode>safely</wpml:flyToWaylineMode>"
        "<wpml:finishAction>noAction</wpml:finishAction>"
        "<wpml:exitOnRCLost>executeLostAction</wpml:exitOnRCLost>"
        "<wpml:executeRCLostAction>hover</wpml:executeRCLostAction>"
        "<wpml:takeOffSecurityHeight>20</wpml:takeOffSecurityHeight>"
        f"<wpml:takeOffRefPoint>{home[0]:.8f},{home[1]:.8f},{home_ell:.3f}</wpml:takeOffRefPoint>"
        f"<wpml:globalTransitionalSpeed>{speed:.2f}</wpml:globalTransitionalSpeed>"
        "<wpml:droneInfo><wpml:droneEnumValue>68</wpml:droneEnumValue>"
        "<wpml:droneSubEnumValue>0</wpml:droneSubEnumValue></wpml:droneInfo>"
        "</wpml:missionConfig>"
    )


DJI_NS = ('xmlns="http://www.opengis.net/kml/2.2" '
          'xmlns:wpml="http://www.dji.com/wpmz/1.0.2"')


def dji_speeds(speeds: np.ndarray) -> np.ndarray:
    """``(M,)`` waypoint speeds as written: each leg's speed, raised to DJI's 1 m/s minimum (the
    last waypoint repeats the last leg's); a speed above 15 m/s is left for :func:`check_limits`."""
    return np.maximum(np.append(speeds, speeds[-1]), DJI_SPEED_RANGE[0])


def dji_kmz(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray, cruise: float, name: str,
            ell: np.ndarray | None = None, home_ell: float | None = None, frame: str = "relative") -> bytes:
    """DJI WPML mission (``.kmz``: ``wpmz/template.kml`` and ``wpmz/waylines.wpml``).

    ``ell`` ``(M,)``: WGS84 ellipsoid heights of ``geo``, ``home_ell`` the takeoff point's: DJI
    reads ``wpml:ellipsoidHeight`` and ``takeOffRefPoint``'s height as ellipsoid heights in every
    mode. ``frame`` ``relative``: heights ``relativeToStartPoint``; ``amsl``: template heights
    ``EGM96`` (AMSL), executed as ``WGS84`` ellipsoid heights. Waypoint speeds below 1 m/s are
    raised to 1 m/s."""
    if frame not in DJI_HEIGHT_MODE:
        check_frame("kmz", frame)
    if ell is None or home_ell is None:
        raise ValueError("dji_kmz needs the WGS84 ellipsoid heights (ell, home_ell)")
    rel = geo[:, 2] - home[2]
    height = rel if frame == "relative" else geo[:, 2]  # wpml:height in the template's heightMode
    execute = rel if frame == "relative" else np.asarray(ell, dtype=float)  # in executeHeightMode
    tpl_mode, exe_mode = DJI_HEIGHT_MODE[frame]
    spd = dji_speeds(speeds)
    auto = float(np.clip(cruise, *DJI_SPEED_RANGE))
    config = _dji_config(home, float(home_ell), auto)
    tpl_marks, wl_marks = [], []
    for k in range(len(geo)):
        point = f"<Point><coordinates>{geo[k, 1]:.8f},{geo[k, 0]:.8f}</coordinates></Point>"
        common = (f"<wpml:index>{k}</wpml:index>"
                  f"<wpml:waypointSpeed>{spd[k]:.2f}</wpml:waypointSpeed>"
                  "<wpml:waypointHeadingParam><wpml:waypointHeadingMode>followWayline"
                  "</wpml:waypointHeadingMode></wpml:waypointHeadingParam>"
                  "<wpml:waypointTurnParam><wpml:waypointTurnMode>toPointAndStopWithDiscontinuityCurvature"
                  "</wpml:waypointTurnMode><wpml:waypointTurnDampingDist>0</wpml:waypointTurnDampingDist>"
                  "</wpml:waypointTurnParam><wpml:useStraightLine>1</wpml:useStraightLine>")
        tpl_marks.append(f"<Placemark>{point}{common}<wpml:height>{height[k]:.3f}</wpml:height>"
                         f"<wpml:ellipsoidHeight>{ell[k]:.3f}</wpml:ellipsoidHeight>"
                         "<wpml:useGlobalHeight>0</wpml:useGlobalHeight>"
                         "<wpml:useGlobalSpeed>0</wpml:useGlobalSpeed></Placemark>")
        wl_marks.append(f"<Placemark>{point}{common}<wpml:executeHeight>{execute[k]:.3f}"
                        "</wpml:executeHeight></Placemark>")
    template = (
        f'<?xml version="1.0" encoding="UTF-8"?>\n<kml {DJI_NS}><Document>'
        f"<wpml:author>staghunt</wpml:author><name>{escape(name)}</name>{config}"
        "<Folder><wpml:templateType>waypoint</wpml:templateType><wpml:templateId>0</wpml:templateId>"
        "<wpml:waylineCoordinateSysParam><wpml:coordinateMode>WGS84</wpml:coordinateMode>"
        f"<wpml:heightMode>{tpl_mode}</wpml:heightMode></wpml:waylineCoordinateSysParam>"
        f"<wpml:autoFlightSpeed>{auto:.2f}</wpml:autoFlightSpeed>"
        "<wpml:globalWaypointTurnMode>toPointAndStopWithDiscontinuityCurvature</wpml:globalWaypointTurnMode>"
        "<wpml:globalUseStraightLine>1</wpml:globalUseStraightLine>"
        "<wpml:gimbalPitchMode>manual</wpml:gimbalPitchMode>"
        f"{''.join(tpl_marks)}</Folder></Document></kml>\n"
    )
    waylines = (
        f'<?xml version="1.0" encoding="UTF-8"?>\n<kml {DJI_NS}><Document>{config}'
        "<Folder><wpml:templateId>0</wpml:templateId>"
        f"<wpml:executeHeightMode>{exe_mode}</wpml:executeHeightMode>"
        f"<wpml:waylineId>0</wpml:waylineId><wpml:autoFlightSpeed>{auto:.2f}</wpml:autoFlightSpeed>"
        f"{''.join(wl_marks)}</Folder></Document></kml>\n"
    )
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("wpmz/template.kml", template)
        z.writestr("wpmz/waylines.wpml", waylines)
    return buf.getvalue()


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
