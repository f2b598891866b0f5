"""DJI WPML missions (``.kmz``: ``wpmz/template.kml`` and ``wpmz/waylines.wpml``), one of the
formats of :mod:`staghunt.missions.formats`: heights relative to the takeoff point or AMSL, WGS84
ellipsoid heights where DJI reads them, waypoint speeds within DJI's range."""

from __future__ import annotations

import io
import zipfile
from xml.sax.saxutils import escape

import numpy as np

from staghunt.missions.camera import CameraAction
from staghunt.missions.targets import DJI_HEIGHT_MODE, DJI_SPEED_RANGE, check_frame

__all__ = ["DJI_NS", "dji_kmz", "dji_speeds"]


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


def _heading(a: CameraAction | None) -> str:
    if a is None or a.heading_deg is None:
        return ("<wpml:waypointHeadingParam><wpml:waypointHeadingMode>followWayline"
                "</wpml:waypointHeadingMode></wpml:waypointHeadingParam>")
    angle = (float(a.heading_deg) + 180.0) % 360.0 - 180.0  # DJI: -180..180, 0 = north, clockwise
    return ("<wpml:waypointHeadingParam><wpml:waypointHeadingMode>smoothTransition</wpml:waypointHeadingMode>"
            f"<wpml:waypointHeadingAngle>{angle:.1f}</wpml:waypointHeadingAngle>"
            "<wpml:waypointPoiPoint>0.000000,0.000000,0.000000</wpml:waypointPoiPoint>"
            "<wpml:waypointHeadingPathMode>followBadArc</wpml:waypointHeadingPathMode></wpml:waypointHeadingParam>")


def _action(i: int, func: str, params: str) -> str:
    return (f"<wpml:action><wpml:actionId>{i}</wpml:actionId><wpml:actionActuatorFunc>{func}</wpml:actionActuatorFunc>"
            f"<wpml:actionActuatorFuncParam>{params}</wpml:actionActuatorFuncParam></wpml:action>")


def _groups(k: int, a: CameraAction | None, capture_end: dict[int, int], next_id: list[int]) -> str:
    """The action groups that start at waypoint ``k``: on reaching it (gimbal, hover, photo), and
    a capture's distance-triggered photos from it to ``capture_end[k]``."""
    if a is None:
        return ""
    out, acts = [], []
    if a.gimbal_pitch_deg is not None:
        acts.append(("gimbalRotate", "<wpml:gimbalHeadingYawBase>aircraft</wpml:gimbalHeadingYawBase>"
                     "<wpml:gimbalRotateMode>absoluteAngle</wpml:gimbalRotateMode>"
                     "<wpml:gimbalPitchRotateEnable>1</wpml:gimbalPitchRotateEnable>"
                     f"<wpml:gimbalPitchRotateAngle>{a.gimbal_pitch_deg:.1f}</wpml:gimbalPitchRotateAngle>"
                     "<wpml:gimbalRollRotateEnable>0</wpml:gimbalRollRotateEnable>"
                     "<wpml:gimbalRollRotateAngle>0</wpml:gimbalRollRotateAngle>"
                     "<wpml:gimbalYawRotateEnable>0</wpml:gimbalYawRotateEnable>"
                     "<wpml:gimbalYawRotateAngle>0</wpml:gimbalYawRotateAngle>"
                     "<wpml:gimbalRotateTimeEnable>0</wpml:gimbalRotateTimeEnable>"
                     "<wpml:gimbalRotateTime>0</wpml:gimbalRotateTime>"
                     "<wpml:payloadPositionIndex>0</wpml:payloadPositionIndex>"))
    if a.hold_s > 0:
        acts.append(("hover", f"<wpml:hoverTime>{a.hold_s:.1f}</wpml:hoverTime>"))
    if a.photo:
        acts.append(("takePhoto", "<wpml:payloadPositionIndex>0</wpml:payloadPositionIndex>"
                     "<wpml:useGlobalPayloadLensIndex>1</wpml:useGlobalPayloadLensIndex>"))

    def group(trigger: str, end: int, actions: list[tuple[str, str]]) -> str:
        gid = next_id[0]
        next_id[0] += 1
        body = "".join(_action(i, f, p) for i, (f, p) in enumerate(actions))
        return (f"<wpml:actionGroup><wpml:actionGroupId>{gid}</wpml:actionGroupId>"
                f"<wpml:actionGroupStartIndex>{k}</wpml:actionGroupStartIndex>"
                f"<wpml:actionGroupEndIndex>{end}</wpml:actionGroupEndIndex>"
                f"<wpml:actionGroupMode>sequence</wpml:actionGroupMode><wpml:actionTrigger>{trigger}"
                f"</wpml:actionTrigger>{body}</wpml:actionGroup>")

    if acts:
        out.append(group("<wpml:actionTriggerType>reachPoint</wpml:actionTriggerType>", k, acts))
    if a.start_distance_m is not None:
        out.append(group("<wpml:actionTriggerType>multipleDistance</wpml:actionTriggerType>"
                         f"<wpml:actionTriggerParam>{a.start_distance_m:.2f}</wpml:actionTriggerParam>",
                         capture_end.get(k, k), [("takePhoto", "<wpml:payloadPositionIndex>0</wpml:payloadPositionIndex>"
                                                  "<wpml:useGlobalPayloadLensIndex>1</wpml:useGlobalPayloadLensIndex>")]))
    return "".join(out)


def capture_ends(actions: list[CameraAction] | None) -> dict[int, int]:
    """``{waypoint that starts a distance-triggered capture: the waypoint that stops it}``."""
    if actions is None:
        return {}
    out, start = {}, None
    for k, a in enumerate(actions):
        if a.stop and start is not None:
            out[start] = k
            start = None
        if a.start_distance_m is not None:
            start = k
    if start is not None:
        out[start] = len(actions) - 1
    return out


def dji_kmz(geo: np.ndarray, speeds: np.ndarray, home: np.ndarray, cruise: float, name: str,
            ell: np.ndarray | None = None, home_ell: float | None = None, frame: str = "relative",
            actions: list[CameraAction] | None = None) -> bytes:
    """DJI WPML mission (``.kmz``: ``wpmz/template.kml`` and ``wpmz/waylines.wpml``).

    ``ell`` ``(M,)``: WGS84 ellipsoid heights of ``geo``, ``home_ell`` the takeoff point's: DJI
    reads ``wpml:ellipsoidHeight`` and ``takeOffRefPoint``'s height as ellipsoid heights in every
    mode. ``frame`` ``relative``: heights ``relativeToStartPoint``; ``amsl``: template heights
    ``EGM96`` (AMSL), executed as ``WGS84`` ellipsoid heights. Waypoint speeds below 1 m/s are
    raised to 1 m/s. ``actions`` ``(M,)``: the waypoints' camera and gimbal
    (:mod:`staghunt.missions.camera`), as action groups and headings in both files."""
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
    ends, next_id = capture_ends(actions), [0]
    for k in range(len(geo)):
        a = actions[k] if actions is not None else None
        point = f"<Point><coordinates>{geo[k, 1]:.8f},{geo[k, 0]:.8f}</coordinates></Point>"
        common = (f"<wpml:index>{k}</wpml:index>"
                  f"<wpml:waypointSpeed>{spd[k]:.2f}</wpml:waypointSpeed>"
                  f"{_heading(a)}"
                  "<wpml:waypointTurnParam><wpml:waypointTurnMode>toPointAndStopWithDiscontinuityCurvature"
                  "</wpml:waypointTurnMode><wpml:waypointTurnDampingDist>0</wpml:waypointTurnDampingDist>"
                  "</wpml:waypointTurnParam><wpml:useStraightLine>1</wpml:useStraightLine>"
                  + _groups(k, a, ends, next_id))
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
