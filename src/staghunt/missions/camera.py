"""Camera and gimbal actions of a mission, as each target writes them.

A :class:`CameraAction` says what happens when the UAV reaches a waypoint: the gimbal's pitch,
the UAV's heading (the camera looks along it: the gimbal's yaw stays 0 relative to the body),
distance triggering started or stopped, one photo, a hover. Per format:

- MAVLink (QGroundControl ``.plan``, QGC WPL 110 ``.waypoints``): the heading is the
  ``NAV_WAYPOINT``'s param4 (degrees, 0 = north, clockwise) and the hover its param1 (s); the gimbal
  pitch is ``MAV_CMD_DO_MOUNT_CONTROL`` (205; param1 pitch, param7 ``MAV_MOUNT_MODE_MAVLINK_TARGETING``)
  placed before the waypoint, so that the gimbal turns on the way there; after it,
  ``MAV_CMD_DO_SET_CAM_TRIGG_DIST`` (206; param1 the distance, param3 1 = one photo at once; a
  distance of 0 stops) and ``MAV_CMD_IMAGE_START_CAPTURE`` (2000; param3 1 = one photo).
- DJI WPML: ``waypointHeadingMode`` ``smoothTransition`` with the heading angle (-180..180, 0 =
  north); a ``reachPoint`` action group with ``gimbalRotate`` (absolute pitch), ``hover`` and
  ``takePhoto``; distance triggering is an action group over the capture's waypoints with the
  ``multipleDistance`` trigger and a ``takePhoto`` action.
- Litchi CSV: the ``heading(deg)`` column, ``gimbalmode`` 2 (interpolate) with
  ``gimbalpitchangle``, actions 5 (tilt camera, the angle), 0 (stay for, ms) and 1 (take photo),
  and ``photo_distinterval`` (m) from the waypoint that starts the capture to the one that ends it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["CameraAction", "MAV_CMD_DO_MOUNT_CONTROL", "MAV_CMD_DO_SET_CAM_TRIGG_DIST", "MAV_CMD_IMAGE_START_CAPTURE",
           "compass"]

MAV_CMD_DO_MOUNT_CONTROL = 205
MAV_CMD_DO_SET_CAM_TRIGG_DIST = 206
MAV_CMD_IMAGE_START_CAPTURE = 2000
MAV_MOUNT_MODE_MAVLINK_TARGETING = 2


@dataclass(frozen=True)
class CameraAction:
    """At a waypoint: ``gimbal_pitch_deg`` (-90 = nadir), ``heading_deg`` (compass: 0 = north,
    clockwise), ``start_distance_m`` (a photo now and every that many metres flown), ``stop``
    (end distance triggering), ``photo`` (one photo, after ``hold_s`` of hovering)."""

    gimbal_pitch_deg: float | None = None
    heading_deg: float | None = None
    start_distance_m: float | None = None
    stop: bool = False
    photo: bool = False
    hold_s: float = 0.0

    def merged(self, other: "CameraAction") -> "CameraAction":
        """This action and ``other`` at one waypoint (``other``'s settings win where both set one)."""
        return CameraAction(
            gimbal_pitch_deg=other.gimbal_pitch_deg if other.gimbal_pitch_deg is not None else self.gimbal_pitch_deg,
            heading_deg=other.heading_deg if other.heading_deg is not None else self.heading_deg,
            start_distance_m=other.start_distance_m if other.start_distance_m is not None else self.start_distance_m,
            stop=self.stop or other.stop, photo=self.photo or other.photo, hold_s=self.hold_s + other.hold_s)

    @property
    def empty(self) -> bool:
        return self == CameraAction()


def compass(yaw_rad: float) -> float:
    """A site-frame yaw (rad, counter-clockwise from east) as a compass heading (degrees in
    [0, 360), 0 = north, clockwise)."""
    return (90.0 - math.degrees(yaw_rad)) % 360.0
