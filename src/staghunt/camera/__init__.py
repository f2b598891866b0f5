"""Cameras: the model with QGroundControl's CameraCalc formulas (:mod:`.model`), the shipped
table of real cameras (``cameras.json``, each with its source) and the pinhole projection on a
stabilised gimbal (:mod:`.projection`). Knows nothing of UAVs, sites or plans."""

from staghunt.camera.model import CAMERA_FIELDS, Camera, camera_table, get_camera

__all__ = ["CAMERA_FIELDS", "Camera", "camera_table", "get_camera"]
