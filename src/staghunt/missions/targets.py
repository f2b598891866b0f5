"""What each mission target accepts: the altitude frames of each per-UAV format
(:data:`FRAME_SUPPORT`, refused with the reason when missing: :func:`check_frame`), the
published limits of each target (:data:`TARGET_LIMITS`, checked by :func:`check_limits`), and
the altitudes of the planned points in a frame (:func:`frame_altitudes`). The formats
themselves: :mod:`staghunt.missions.formats`."""

from __future__ import annotations

from typing import Any

import numpy as np

from staghunt.errors import FieldError


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
