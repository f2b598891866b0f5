"""The pinhole camera on a stabilised gimbal: its axes, where a point falls in the image, and the
ground sampling distance and incidence of a surface element in a photo.

A photo is taken from position ``c`` (site frame, m) with the gimbal at ``yaw`` (rad, counter-
clockwise from east: the direction of the image's height axis for a nadir photo, the direction
the camera looks for a level one) and ``pitch`` (rad, ``-pi/2`` = nadir, 0 = level); the gimbal
keeps the roll at 0. Camera axes in the site frame:

- forward (optical axis) ``f = (cos p cos y, cos p sin y, sin p)``;
- up (the image's height axis, towards its top row) ``u = (-sin p cos y, -sin p sin y, cos p)``;
- right (the image's width axis) ``r = f x u``.

A point ``X`` at depth ``z = (X - c).f > 0`` falls at ``(x, y) = F ((X - c).r, (X - c).u) / z`` on
the sensor (mm, ``F`` the focal length); it is in the photo when ``|x| <= W/2`` and ``|y| <= H/2``
(``W x H`` the sensor, turned by 90 degrees for a portrait camera).

The GSD of a surface element (unit normal ``n``) is exact for the pinhole model: with ``J`` the
2 x 2 Jacobian of ``(x, y)`` with respect to two orthonormal directions in the surface, one
pixel's footprint is ``p J^-1`` (``p`` the pixel pitch), so its longest side is
``p / sigma_min(J)``: the GSD in the surface's worst direction. For a nadir photo of level ground
it equals QGroundControl's ``distance x sensor width / (image width x focal length)``.
"""

from __future__ import annotations

import numpy as np

from staghunt.camera.model import Camera

__all__ = ["camera_axes", "project", "sensor_extent", "surface_gsd", "tangent_basis"]


def camera_axes(yaw: np.ndarray, pitch: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(forward, right, up)``, each ``(..., 3)`` unit vectors, for gimbal angles ``(...)`` (rad)."""
    yaw = np.asarray(yaw, dtype=float)
    pitch = np.asarray(pitch, dtype=float)
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    f = np.stack([cp * cy, cp * sy, sp], axis=-1)
    u = np.stack([-sp * cy, -sp * sy, cp], axis=-1)
    r = np.cross(f, u)
    return f, r, u


def sensor_extent(camera: Camera) -> tuple[float, float]:
    """``(extent along right, extent along up)`` of the sensor (mm)."""
    if camera.landscape:
        return camera.sensor_width_mm, camera.sensor_height_mm
    return camera.sensor_height_mm, camera.sensor_width_mm


def project(camera: Camera, points: np.ndarray, position: np.ndarray, yaw: np.ndarray, pitch: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where ``points`` ``(..., 3)`` fall in photos taken at ``position`` ``(..., 3)`` with gimbal
    ``yaw``, ``pitch`` ``(...)`` (broadcast against each other): ``(x, y, depth, inside)`` with
    ``x, y`` on the sensor (mm), ``depth`` along the optical axis (m) and ``inside`` the points in
    front of the camera and within the frame."""
    f, r, u = camera_axes(yaw, pitch)
    d = np.asarray(points, dtype=float) - np.asarray(position, dtype=float)
    z = (d * f).sum(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = camera.focal_length_mm * (d * r).sum(-1) / z
        y = camera.focal_length_mm * (d * u).sum(-1) / z
    w, h = sensor_extent(camera)
    inside = (z > 0) & (np.abs(x) <= 0.5 * w) & (np.abs(y) <= 0.5 * h)
    return x, y, z, inside


def tangent_basis(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ``(..., 3)`` orthogonal to each other and to unit ``normals`` ``(..., 3)``."""
    n = np.asarray(normals, dtype=float)
    helper = np.where(np.abs(n[..., 2:3]) < 0.9, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    t1 = np.cross(helper, n)
    t1 /= np.linalg.norm(t1, axis=-1, keepdims=True)
    t2 = np.cross(n, t1)
    return t1, t2


def surface_gsd(camera: Camera, points: np.ndarray, normals: np.ndarray, position: np.ndarray,
                yaw: np.ndarray, pitch: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(gsd_cm, incidence_deg)`` of surface elements at ``points`` with unit ``normals`` (both
    ``(..., 3)``) in photos taken at ``position`` with gimbal ``yaw``, ``pitch`` (broadcast).

    ``gsd_cm``: the longest side of one pixel's footprint on the surface (cm; ``inf`` behind the
    camera or for a surface seen edge-on); ``incidence_deg``: the angle between the surface normal
    and the direction to the camera (90 or more: the back of the surface faces the camera)."""
    f, r, u = camera_axes(yaw, pitch)
    d = np.asarray(points, dtype=float) - np.asarray(position, dtype=float)
    n = np.asarray(normals, dtype=float)
    t1, t2 = tangent_basis(n)
    z = (d * f).sum(-1)
    dr, du = (d * r).sum(-1), (d * u).sum(-1)
    F = camera.focal_length_mm
    with np.errstate(divide="ignore", invalid="ignore"):
        def row(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            tf = (t * f).sum(-1)
            return (F * ((t * r).sum(-1) * z - dr * tf) / z**2, F * ((t * u).sum(-1) * z - du * tf) / z**2)

        a, c = row(t1)  # d(x, y)/d t1
        b, e = row(t2)  # d(x, y)/d t2
        frob = a * a + b * b + c * c + e * e
        det = a * e - b * c
        disc = np.sqrt(np.maximum(frob * frob - 4.0 * det * det, 0.0))
        smin = np.sqrt(np.maximum(0.5 * (frob - disc), 0.0))
        gsd_cm = 100.0 * camera.pixel_pitch_mm / smin
        dist = np.linalg.norm(d, axis=-1)
        cos_inc = -(d * n).sum(-1) / dist
    gsd_cm = np.where((z > 0) & np.isfinite(gsd_cm), gsd_cm, np.inf)
    incidence = np.degrees(np.arccos(np.clip(cos_inc, -1.0, 1.0)))
    return gsd_cm, incidence
