"""Cameras: the shipped table of real cameras and QGroundControl's CameraCalc formulas.

A :class:`Camera` holds the fields of QGroundControl's ``CameraMetaData.json`` (sensor width and
height in mm, image width and height in px, focal length in mm, landscape, fixed orientation,
minimum trigger interval in s). The formulas are QGroundControl's ``CameraCalc`` ones
(``src/MissionManager/CameraCalc.cc``), for a nadir camera over flat ground:

- GSD (cm/px) = distance (m) x sensor width (mm) x 100 / (image width (px) x focal length (mm));
- distance (m) = image width x GSD x focal length / (sensor width x 100);
- footprint across the track ("side") = image width x GSD / 100 (landscape: the long side
  across the track), along it ("front") = image height x GSD / 100 (portrait: swapped);
- line spacing = side footprint x (1 - side overlap); trigger distance = front footprint x
  (1 - front overlap).

The table (``cameras.json`` beside this module) cites each camera's source.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

__all__ = ["CAMERA_FIELDS", "Camera", "camera_table", "get_camera"]

CAMERA_FIELDS = ("sensor_width_mm", "sensor_height_mm", "image_width_px", "image_height_px", "focal_length_mm")
"""The five numbers that define a camera's geometry (an inline ``[camera]`` table gives them)."""


@dataclass(frozen=True)
class Camera:
    """A frame camera on a gimbal (pinhole model, square pixels of ``sensor_width_mm /
    image_width_px``).

    ``landscape``: the image's long side (its width) lies across the direction of travel in a
    survey (QGroundControl's convention); ``False`` turns the camera by 90 degrees.
    ``min_trigger_interval_s``: the fastest the camera takes photos (0 = no limit).
    ``exposure_s``: the shutter time used for the motion blur (1/1000 s by default)."""

    name: str
    sensor_width_mm: float
    sensor_height_mm: float
    image_width_px: int
    image_height_px: int
    focal_length_mm: float
    landscape: bool = True
    min_trigger_interval_s: float = 0.0
    fixed_orientation: bool = False
    exposure_s: float = 1e-3
    brand: str = ""
    source: str = ""

    # --- QGroundControl CameraCalc ------------------------------------------------------------

    def gsd_cm(self, distance_m: float) -> float:
        """Ground sampling distance (cm/px) at ``distance_m`` from a surface facing the camera."""
        return distance_m * self.sensor_width_mm * 100.0 / (self.image_width_px * self.focal_length_mm)

    def distance_m(self, gsd_cm: float) -> float:
        """Distance (m) to a surface facing the camera at which the GSD is ``gsd_cm``."""
        return self.image_width_px * gsd_cm * self.focal_length_mm / (self.sensor_width_mm * 100.0)

    def footprint_m(self, gsd_cm: float) -> tuple[float, float]:
        """``(side, front)`` footprint (m) at ``gsd_cm``: across and along the direction of travel."""
        w = self.image_width_px * gsd_cm / 100.0
        h = self.image_height_px * gsd_cm / 100.0
        return (w, h) if self.landscape else (h, w)

    def line_spacing_m(self, gsd_cm: float, side_overlap: float) -> float:
        """Distance (m) between survey lines for ``side_overlap`` (a fraction in ``[0, 1)``)."""
        return self.footprint_m(gsd_cm)[0] * (1.0 - side_overlap)

    def trigger_distance_m(self, gsd_cm: float, front_overlap: float) -> float:
        """Distance (m) between photos along a line for ``front_overlap`` (a fraction in ``[0, 1)``)."""
        return self.footprint_m(gsd_cm)[1] * (1.0 - front_overlap)

    # --- beyond CameraCalc --------------------------------------------------------------------

    @property
    def pixel_pitch_mm(self) -> float:
        """Side of one pixel on the sensor (mm)."""
        return self.sensor_width_mm / self.image_width_px

    @property
    def half_fov_rad(self) -> tuple[float, float]:
        """Half the angles of view ``(across, along)`` the camera's width and height axes (rad)."""
        return (math.atan(self.sensor_width_mm / (2.0 * self.focal_length_mm)),
                math.atan(self.sensor_height_mm / (2.0 * self.focal_length_mm)))

    def blur_px(self, speed_ms: float, gsd_cm: float) -> float:
        """Motion blur (px) of a photo taken at ``speed_ms`` parallel to the surface, at ``gsd_cm``,
        during ``exposure_s``: the distance travelled during the exposure over one pixel's footprint."""
        return speed_ms * self.exposure_s / (gsd_cm / 100.0)

    def speed_for_blur(self, gsd_cm: float, max_blur_px: float) -> float:
        """The highest speed (m/s) whose motion blur at ``gsd_cm`` is at most ``max_blur_px``."""
        return max_blur_px * (gsd_cm / 100.0) / self.exposure_s


def _from_entry(e: dict) -> Camera:
    return Camera(
        name=e["canonicalName"], sensor_width_mm=float(e["sensorWidth"]), sensor_height_mm=float(e["sensorHeight"]),
        image_width_px=int(e["imageWidth"]), image_height_px=int(e["imageHeight"]),
        focal_length_mm=float(e["focalLength"]), landscape=bool(e["landscape"]),
        min_trigger_interval_s=float(e["minTriggerInterval"]), fixed_orientation=bool(e["fixedOrientation"]),
        brand=e.get("brand", ""), source=e.get("source", ""))


@lru_cache(maxsize=1)
def camera_table() -> dict[str, Camera]:
    """The shipped cameras by canonical name (QGroundControl's ``canonicalName``)."""
    text = resources.files("staghunt.camera").joinpath("cameras.json").read_text(encoding="utf-8")
    return {c.name: c for c in map(_from_entry, json.loads(text))}


def get_camera(name: str) -> Camera:
    """The shipped camera ``name``; ``KeyError`` with the known names when there is none."""
    table = camera_table()
    if name not in table:
        raise KeyError(f"unknown camera {name!r}; known: {', '.join(sorted(table))}")
    return table[name]
