"""Mission files, one function per format: each returns the file's content (text or bytes) and
writes nothing, so an export can build every file before it writes any.

Per UAV ``n`` the inputs are the planned points in WGS84, ``geo`` ``(M, 3)`` = ``(lat, lon, alt
AMSL)``, the common waypoint times ``times`` ``(M,)`` (s), the leg speeds ``speeds`` ``(M - 1,)``
(m/s, the average speed that keeps the common times) and the takeoff point ``home`` = ``(lat,
lon, alt AMSL)`` of the ground under the UAV's start. Altitude datums:

- QGroundControl ``.plan`` and QGC WPL 110: mission items relative to home (MAV_FRAME 3,
  ``AMSL = home altitude + value``); the home position itself AMSL;
- DJI WPML: ``relativeToStartPoint`` (the takeoff point, declared in ``takeOffRefPoint``);
- Litchi CSV: ``altitudemode 0``, relative to the takeoff point;
- KML (``altitudeMode absolute``) and GeoJSON: AMSL.
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

QGC_WAYPOINT = 16
QGC_LAND = 21
QGC_TAKEOFF = 22
QGC_CHANGE_SPEED = 178
FRAME_GLOBAL = 0
FRAME_RELATIVE = 3
DJI_SPEED_RANGE = (1.0, 15.0)
LITCHI_SPEED_RANGE = (0.0, 15.0)

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


def _mission_items(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray) -> list[tuple[int, int, list[float]]]:
    """``(command, frame, 7 params)``: take off to the start, then per leg a speed command and
    the leg's end point (relative altitudes), in flight order."""
    rel = geo[:, 2] - home[2]
    items: list[tuple[int, int, list[float]]] = [
        (QGC_TAKEOFF, FRAME_RELATIVE, [0.0, 0.0, 0.0, math.nan, geo[0, 0], geo[0, 1], rel[0]])]
    for k in range(1, len(geo)):
        items.append((QGC_CHANGE_SPEED, FRAME_RELATIVE, [1.0, float(speeds[k - 1]), -1.0, 0.0, 0.0, 0.0, 0.0]))
        items.append((QGC_WAYPOINT, FRAME_RELATIVE, [0.0, 0.0, 0.0, math.nan, geo[k, 0], geo[k, 1], rel[k]]))
    return items


def qgc_plan(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray, cruise: float,
             note: str = "") -> str:
    """QGroundControl plan (JSON, ``fileType`` Plan, version 1)."""
    items = []
    for seq, (cmd, frame, params) in enumerate(_mission_items(geo, speeds, home), start=1):
        p = [None if isinstance(v, float) and math.isnan(v) else float(v) for v in params]
        item = _qgc_item(seq, cmd, frame, p)
        if cmd in (QGC_WAYPOINT, QGC_TAKEOFF):
            item.update({"AMSLAltAboveTerrain": None, "Altitude": p[6], "AltitudeMode": 1})
        items.append(item)
    plan = {
        "fileType": "Plan",
        "version": 1,
        "groundStation": "staghunt" + (f" ({note})" if note else ""),
        "mission": {
            "version": 2,
            "firmwareType": 12,  # PX4 (MAV_AUTOPILOT_PX4); QGC converts for ArduPilot on load
            "vehicleType": 2,  # MAV_TYPE_QUADROTOR
            "cruiseSpeed": float(cruise),
            "hoverSpeed": float(cruise),
            "plannedHomePosition": [float(home[0]), float(home[1]), float(home[2])],
            "items": items,
        },
        "geoFence": {"version": 2, "circles": [], "polygons": []},
        "rallyPoints": {"version": 2, "points": []},
    }
    return json.dumps(plan, indent=2) + "\n"


def qgc_wpl(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray) -> str:
    """QGC WPL 110 text (ArduPilot / Mission Planner): line 0 home (absolute), then the items."""
    lines = ["QGC WPL 110"]

    def row(seq: int, frame: int, cmd: int, p: list[float], current: int = 0) -> str:
        vals = [0.0 if math.isnan(v) else v for v in p]
        fields = [str(seq), str(current), str(frame), str(cmd)] + [f"{v:.8f}" for v in vals[:4]] + \
                 [f"{vals[4]:.8f}", f"{vals[5]:.8f}", f"{vals[6]:.6f}", "1"]
        return "\t".join(fields)

    lines.append(row(0, FRAME_GLOBAL, QGC_WAYPOINT, [0, 0, 0, 0, home[0], home[1], home[2]], current=1))
    for seq, (cmd, frame, params) in enumerate(_mission_items(geo, speeds, home), start=1):
        lines.append(row(seq, frame, cmd, params))
    return "\n".join(lines) + "\n"


def litchi_csv(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray) -> str:
    """Litchi mission CSV: every planned point, altitude relative to the takeoff point
    (``altitudemode 0``), heading along the next leg, speed of the leg that starts there."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(LITCHI_HEADER)
    M = len(geo)
    for k in range(M):
        a, b = (k, k + 1) if k + 1 < M else (k - 1, k)
        dlat = math.radians(geo[b, 0] - geo[a, 0])
        dlon = math.radians(geo[b, 1] - geo[a, 1]) * math.cos(math.radians(geo[a, 0]))
        heading = (math.degrees(math.atan2(dlon, dlat)) + 360.0) % 360.0
        speed = float(np.clip(speeds[min(k, M - 2)], *LITCHI_SPEED_RANGE))
        row = [f"{geo[k, 0]:.8f}", f"{geo[k, 1]:.8f}", f"{max(0.0, geo[k, 2] - home[2]):.2f}",
               f"{heading:.1f}", "0", "0", "0", "0"] + ["-1", "0"] * 15
        row += ["0", f"{speed:.2f}", "0", "0", "0", "0", "-1", "-1"]
        w.writerow(row)
    return out.getvalue()


def _dji_config(home: np.ndarray, speed: float) -> str:
    return (
        "<wpml:missionConfig>"
        "<wpml:flyToWaylineMode>safely</wpml:flyToWaylineMode>"
        "<wpml:finishAction>noAction</wpml:finishAction>"
        "<wpml:exitOnRCLost>executeLostAction</wpml:exitOnRCLost>"
        "<wpml:executeRCLostAction>hover</wpml:executeRCLostAction>"
        "<wpml:takeOffSecurityHeight>20</wpml:takeOffSecurityHeight>"
        f"<wpml:takeOffRefPoint>{home[0]:.8f},{home[1]:.8f},{home[2]:.3f}</wpml:takeOffRefPoint>"
        f"<wpml:globalTransitionalSpeed>{speed:.2f}</wpml:globalTransitionalSpeed>"
        "<wpml:droneInfo><wpml:droneEnumValue>68</wpml:droneEnumValue>"
        "<wpml:droneSubEnumValue>0</wpml:droneSubEnumValue></wpml:droneInfo>"
        "</wpml:missionConfig>"
    )


DJI_NS = ('xmlns="http://www.opengis.net/kml/2.2" '
          'xmlns:wpml="http://www.dji.com/wpmz/1.0.2"')


def dji_kmz(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray, cruise: float, name: str) -> bytes:
    """DJI WPML mission (``.kmz``: ``wpmz/template.kml`` and ``wpmz/waylines.wpml``), heights
    ``relativeToStartPoint``, waypoint speeds clamped to the format's 1-15 m/s."""
    rel = geo[:, 2] - home[2]
    spd = np.clip(np.append(speeds, speeds[-1]), *DJI_SPEED_RANGE)
    auto = float(np.clip(cruise, *DJI_SPEED_RANGE))
    config = _dji_config(home, auto)
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
        tpl_marks.append(f"<Placemark>{point}{common}<wpml:height>{rel[k]:.3f}</wpml:height>"
                         f"<wpml:ellipsoidHeight>{rel[k]:.3f}</wpml:ellipsoidHeight>"
                         "<wpml:useGlobalHeight>0</wpml:useGlobalHeight>"
                         "<wpml:useGlobalSpeed>0</wpml:useGlobalSpeed></Placemark>")
        wl_marks.append(f"<Placemark>{point}{common}<wpml:executeHeight>{rel[k]:.3f}"
                        "</wpml:executeHeight></Placemark>")
    template = (
        f'<?xml version="1.0" encoding="UTF-8"?>\n<kml {DJI_NS}><Document>'
        f"<wpml:author>staghunt</wpml:author><name>{escape(name)}</name>{config}"
        "<Folder><wpml:templateType>waypoint</wpml:templateType><wpml:templateId>0</wpml:templateId>"
        "<wpml:waylineCoordinateSysParam><wpml:coordinateMode>WGS84</wpml:coordinateMode>"
        "<wpml:heightMode>relativeToStartPoint</wpml:heightMode></wpml:waylineCoordinateSysParam>"
        f"<wpml:autoFlightSpeed>{auto:.2f}</wpml:autoFlightSpeed>"
        "<wpml:globalWaypointTurnMode>toPointAndStopWithDiscontinuityCurvature</wpml:globalWaypointTurnMode>"
        "<wpml:globalUseStraightLine>1</wpml:globalUseStraightLine>"
        "<wpml:gimbalPitchMode>manual</wpml:gimbalPitchMode>"
        f"{''.join(tpl_marks)}</Folder></Document></kml>\n"
    )
    waylines = (
        f'<?xml version="1.0" encoding="UTF-8"?>\n<kml {DJI_NS}><Document>{config}'
        "<Folder><wpml:templateId>0</wpml:templateId>"
        "<wpml:executeHeightMode>relativeToStartPoint</wpml:executeHeightMode>"
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
