"""A :class:`~staghunt.scenario.model.Scenario` back to plain data in the TOML layout (the
inverse of :func:`staghunt.scenario.loader.scenario_from_dict`)."""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any

import numpy as np

from staghunt.camera import Camera, camera_table
from staghunt.scenario.dem import geotiff_digest, grid_digest
from staghunt.scenario.model import Scenario
from staghunt.task import VehicleLimits

SITE_KEYS = ("xmin", "xmax", "ymin", "ymax", "hmin", "hmax")


def _floats(a: np.ndarray) -> list[Any]:
    return np.asarray(a, dtype=float).tolist()


def scenario_to_dict(scenario: Scenario) -> dict[str, Any]:
    """The scenario as plain JSON-able data in the TOML layout (all defaults filled in).

    A DEM appears as a reference to its file (absolute path) with its shape, dtype, SHA-256,
    origin, cell size and sampling, not as the grid. ``scenario_from_dict`` of the result
    rebuilds an equal scenario (its DEM read again from the file and checked against the
    shape, dtype and checksum).
    """
    w = scenario.world
    b = w.bounds
    terrain = w.terrain
    ground: dict[str, Any]
    if terrain.elevation is None:
        ground = {"kind": "flat"}
    elif terrain.georef is not None:
        ground = {
            "kind": "geotiff",
            "file": terrain.source,
            "cell_size": float(terrain.cell_size),
            "sampling": terrain.sampling,
            "nodata_fill": terrain.georef.get("nodata_fill"),
            "sha256": geotiff_digest(terrain),
        }
    else:
        ground = {
            "kind": "dem",
            "file": terrain.source,
            "origin": [float(terrain.origin[0]), float(terrain.origin[1])],
            "cell_size": float(terrain.cell_size),
            "sampling": terrain.sampling,
            "shape": [int(s) for s in terrain.elevation.shape],
            "dtype": terrain.elevation.dtype.name,
            "sha256": grid_digest(terrain.elevation),
        }
    c = scenario.costs
    s = scenario.solver
    f = scenario.formation
    o = scenario.origin
    from staghunt.scenario.dynamics import dynamics_to_dict
    from staghunt.world.dynamic import Link, Sensing

    out = {
        "name": scenario.name,
        "description": scenario.description,
        "site": {k: float(getattr(b, k)) for k in SITE_KEYS},
        "ground": ground,
        "obstacles": [
            {"x": float(o.x), "y": float(o.y), "radius": float(o.radius), "name": o.name}
            for o in w.cylinders
        ],
        "prisms": [
            {"name": p.name, "polygon": [list(v) for v in p.polygon], "base": p.agl[0], "height": p.agl[1]}
            for p in w.prisms if not p.is_nofly and p.agl is not None
        ],
        "nofly": [{"name": p.name, "polygon": [list(v) for v in p.polygon]} for p in w.prisms if p.is_nofly],
        "airspace": {"ceiling": None if not math.isfinite(w.ceiling) else float(w.ceiling)},
        "team": scenario_to_dict_team(scenario),
        "formation": {
            "incidence": np.asarray(f.incidence).astype(int).tolist(),
            "edge_weights": _floats(f.edge_weights),
            "reference": _floats(f.reference),
        },
        "costs": {
            "danger_margin": float(c.danger_margin),
            "safe_distance": float(c.safe_distance),
            "turning_threshold_deg": float(c.turning_threshold_deg),
            "climb_threshold_deg": float(c.climb_threshold_deg),
            "desired_height": None if c.desired_height is None else float(c.desired_height),
            "continuous_separation": bool(c.continuous_separation),
            "min_clearance": float(c.min_clearance),
        },
        "solver": {
            "particles": int(s.particles),
            "iterations": int(s.iterations),
            "waypoints": int(s.waypoints),
            "c0": float(s.c0),
            "damping": float(s.damping),
            "c1": float(s.c1),
            "c2": float(s.c2),
            "velocity_fraction": float(s.velocity_fraction),
            "starts": int(s.starts),
        },
        "origin": None if o is None else {
            "latitude": float(o.latitude), "longitude": float(o.longitude), "altitude": float(o.altitude)
        },
        "vehicle": {k.name: (getattr(scenario.vehicle, k.name) if k.name == "airframe"
                             else float(getattr(scenario.vehicle, k.name))) for k in fields(VehicleLimits)},
    }
    dyn = scenario.dynamics
    if not dyn.empty or dyn.sensing != Sensing() or dyn.link != Link():
        out.update(dynamics_to_dict(dyn))
    if scenario.inspection is not None:
        out.update(inspection_to_dict(scenario))
    return out


def _camera_value(cam: Camera) -> Any:
    """A shipped camera by its name, another as the table of its geometry."""
    if camera_table().get(cam.name) == cam:
        return cam.name
    return {"name": cam.name, "sensor_width_mm": cam.sensor_width_mm, "sensor_height_mm": cam.sensor_height_mm,
            "image_width_px": cam.image_width_px, "image_height_px": cam.image_height_px,
            "focal_length_mm": cam.focal_length_mm, "min_trigger_interval_s": cam.min_trigger_interval_s,
            "landscape": cam.landscape, "exposure_s": cam.exposure_s}


def inspection_to_dict(scenario: Scenario) -> dict[str, Any]:
    """The inspection's tables: every UAV's payload in its team entry (so the team entries of
    :func:`scenario_to_dict` must be set first), the capture settings and the objectives in the
    site frame (GeoJSON ones placed)."""
    insp = scenario.inspection
    assert insp is not None
    team = []
    for u, p in zip(scenario_to_dict_team(scenario), insp.payloads):
        team.append({**u, "camera": _camera_value(p.camera),
                     "gimbal_pitch_deg": [p.gimbal_pitch_min_deg, p.gimbal_pitch_max_deg], "endurance_s": p.endurance_s})
    objectives = []
    for o in insp.objectives:
        d = {f.name: getattr(o, f.name) for f in fields(o)}
        if "polygon" in d:
            d["polygon"] = [list(v) for v in d["polygon"]]
        if d.get("time_window") is not None:
            d["time_window"] = list(d["time_window"])
        objectives.append(d)
    return {"team": team, "inspection": {"max_blur_px": insp.max_blur_px, "cell_m": insp.cell_m},
            "objectives": objectives}


def scenario_to_dict_team(scenario: Scenario) -> list[dict[str, Any]]:
    """The team entries of :func:`scenario_to_dict`."""
    return [
        {
            "name": u.name,
            "start": [float(v) for v in u.start],
            "goal": [float(v) for v in u.goal],
            "radius": float(u.radius),
            "beta": float(u.weights.beta),
            "weights": _floats(u.weights.as_array()),
        }
        for u in scenario.team
    ]
