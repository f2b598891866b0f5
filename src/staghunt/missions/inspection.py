"""``staghunt export`` of an inspection: every UAV's own mission with the camera's actions.

From ``inspection.json`` (:mod:`staghunt.inspection.files`) each UAV's flight becomes waypoints
(:func:`uav_mission`): the legs' points at the cruise speed, each capture's points at its speed
(a straight run's inner points dropped), hovers as holds. At a capture's first waypoint the
gimbal is set, the UAV turns to the camera's heading and distance triggering starts (a photo at
once, then every trigger distance); at its last the triggering stops; at a viewpoint the UAV
hovers its dwell and takes one photo. The files are those of a plan's export
(:mod:`staghunt.missions.formats`), each with its camera actions (:mod:`staghunt.missions.camera`),
written as one set with ``mission.json``; with ``simulate`` the simulated team flies the
inspection first, triggers the cameras along the flown trajectories and writes ``captures.csv``
and ``coverage.json`` (:func:`staghunt.flight.inspection.fly_inspection`).
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from staghunt.errors import FieldError
from staghunt.geo import GeoOrigin, check_origin, site_to_geodetic
from staghunt.geo.geoid import geoid_height
from staghunt.inspection.files import read_inspection, read_timeline
from staghunt.io.atomic import write_file_set
from staghunt.missions import formats as fm
from staghunt.missions.camera import CameraAction, compass
from staghunt.missions.export import MANIFEST, ExportRefused, parse_altitude_frame, previous_set

__all__ = ["export_inspection", "uav_mission"]

MERGE_M = 0.6
"""Waypoints closer than this (DJI's least distance between waypoints) become one."""


def _straight(points: np.ndarray, tol: float = 0.25) -> np.ndarray:
    """The indices of ``points`` ``(M, 3)`` to keep: the ends and every point more than ``tol``
    metres off the line from the last kept point to the next one (a straight run keeps its ends)."""
    keep = [0]
    for i in range(1, len(points) - 1):
        a, b, p = points[keep[-1]], points[i + 1], points[i]
        d = b - a
        n = float(np.dot(d, d))
        off = p - a - (np.dot(p - a, d) / n) * d if n > 0 else p - a
        if float(np.linalg.norm(off)) > tol:
            keep.append(i)
    keep.append(len(points) - 1)
    return np.array(sorted(set(keep)))


def uav_mission(pieces: tuple[Any, ...], cruise: float) -> tuple[np.ndarray, np.ndarray, list[CameraAction], np.ndarray]:
    """One UAV's waypoints ``(M, 3)`` (absolute site frame), leg speeds ``(M - 1,)`` (m/s), camera
    actions ``(M,)`` and leg durations ``(M - 1,)`` (s) from its timeline's pieces."""
    pts: list[np.ndarray] = []
    speeds: list[float] = []
    acts: list[CameraAction] = []
    durs: list[float] = []

    def add(p: np.ndarray, speed: float, action: CameraAction, duration: float) -> None:
        if pts and float(np.linalg.norm(p - pts[-1])) < MERGE_M:
            acts[-1] = acts[-1].merged(action)
            if durs:
                durs[-1] += duration
            return
        if pts:
            speeds.append(speed)
            durs.append(duration)
        pts.append(np.asarray(p, dtype=float))
        acts.append(action)

    for p in pieces:
        if p.kind == "hover":
            if pts:
                acts[-1] = acts[-1].merged(CameraAction(hold_s=p.duration))
            else:
                add(p.points[0], cruise, CameraAction(hold_s=p.duration), 0.0)
            continue
        seg = p.segment
        if seg is not None and seg.trigger == "points":  # a viewpoint: hover, then one photo
            add(seg.points[0], cruise, CameraAction(gimbal_pitch_deg=math.degrees(float(seg.pitch[0])),
                                                    heading_deg=compass(float(seg.yaw[0]))), 0.0)
            acts[-1] = acts[-1].merged(CameraAction(hold_s=seg.dwell_s, photo=True))
            continue
        q = np.asarray(p.points, dtype=float)
        keep = _straight(q)
        length = float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())
        speed = length / p.duration if p.duration > 0 else cruise
        for j, i in enumerate(keep):
            action = CameraAction()
            if seg is not None:
                heading = compass(float(seg.yaw[i]))
                if j == 0:
                    action = CameraAction(gimbal_pitch_deg=math.degrees(float(seg.pitch[i])), heading_deg=heading,
                                          start_distance_m=float(seg.trigger_distance))
                elif j == len(keep) - 1:
                    action = CameraAction(heading_deg=heading, stop=True)
                else:
                    action = CameraAction(heading_deg=heading)
            leg = float(np.linalg.norm(q[i] - q[keep[j - 1]])) if j else 0.0
            add(q[i], speed, action, leg / speed if speed > 0 else 0.0)
    return np.array(pts), np.array(speeds), acts, np.array(durs)


def export_inspection(path: str, out_dir: str, origin: GeoOrigin | None = None, formats: Any = None,
                      force: bool = False, plots: bool = True, altitude_frame: str = "relative",
                      simulate: bool = False, wind: float = 0.0, seed: int = 0,
                      data: dict[str, Any] | None = None) -> dict[str, Any]:
    """Export the inspection of ``path`` (an ``inspection.json``) to ``out_dir``; returns the
    summary written to ``mission.json`` (``files``: what was written). Refuses (``ExportRefused``)
    an inspection planned unsafe or infeasible, or (``simulate``) whose simulated flight breaks a
    limit, unless ``force``."""
    t0 = time.perf_counter()
    from staghunt.missions.export import _parse_formats

    chosen = _parse_formats(formats)
    frame = parse_altitude_frame(altitude_frame)
    for f in chosen:
        fm.check_frame(f, frame)
    data = data if data is not None else read_inspection(path)
    scenario, timeline = read_timeline(data, str(path))
    origin = origin if origin is not None else scenario.origin
    if origin is None:
        raise FieldError(f"{path}: the scenario has no [origin]; give an origin (latitude, longitude, altitude)", "origin")
    check_origin(origin, "origin" if origin is not scenario.origin else "scenario origin")
    problems = [] if data.get("status") == "planned" else [f"the inspection is {data.get('status')!r}: {data.get('message')}"]
    flight = None
    if simulate:
        from staghunt.flight.inspection import fly_inspection

        flight = fly_inspection(scenario, timeline, wind=wind, seed=seed)
        problems += list(flight.problems)
    if problems and not force:
        raise ExportRefused(f"{path}: not exported: {problems[0]}" + (f" (and {len(problems) - 1} more)" if len(problems) > 1
                                                                      else "") + "; a forced export writes it anyway")
    note = ("UNSAFE: " + problems[0])[:200] if problems else ""
    files = _build(scenario, timeline, origin, chosen, note, frame)
    if flight is not None:
        from staghunt.flight.inspection import captures_csv

        files["captures.csv"] = captures_csv(flight)
        files["coverage.json"] = json.dumps(flight.coverage_json(), indent=1) + "\n"
    if problems:
        files["MISSION_UNSAFE.txt"] = "This mission was exported although it was refused (forced):\n" + \
            "\n".join(f"- {p}" for p in problems) + "\nDo not fly it as it is.\n"
    summary = {"format": "staghunt-mission/1", "kind": "inspection", "seed": data.get("seed"),
               "plan_status": data.get("status"), "altitude_frame": frame, "makespan_s": timeline.end,
               "origin": {"latitude": origin.latitude, "longitude": origin.longitude, "altitude_amsl_m": origin.altitude},
               "camera_actions": {"plan, waypoints": "NAV_WAYPOINT param4 heading, param1 hover; MAV_CMD_DO_MOUNT_CONTROL "
                                                     "before a capture; MAV_CMD_DO_SET_CAM_TRIGG_DIST at its start and end; "
                                                     "MAV_CMD_IMAGE_START_CAPTURE at a viewpoint",
                                  "kmz": "gimbalRotate, hover, takePhoto (reachPoint); takePhoto (multipleDistance)",
                                  "litchi": "tilt camera (5), stay for (0), take photo (1), photo_distinterval"},
               "safe": not problems, "problems": problems}
    if flight is not None:
        summary["flight"] = flight.summary()

    def figures(stage: Path) -> list[Path]:
        if flight is None:
            return []
        from staghunt.plots.inspection import coverage_figure

        return [coverage_figure(scenario, scenario.inspection, flight.photos, stage / "coverage.png", "flown")]

    def manifest(names: list[str]) -> tuple[str, str]:
        summary["files"] = sorted([*names, MANIFEST])
        summary["seconds"] = time.perf_counter() - t0
        return MANIFEST, json.dumps(summary, indent=1) + "\n"

    out = Path(out_dir)
    try:
        write_file_set(out, files, figures if plots else None, previous_set(out), manifest)
    except OSError as exc:
        raise ValueError(f"cannot write to {str(out)!r}: {exc.strerror or exc}") from None
    return summary


def _build(scenario: Any, timeline: Any, origin: GeoOrigin, chosen: tuple[str, ...], note: str, frame: str
           ) -> dict[str, str | bytes]:
    """Every chosen file, each UAV's with its camera actions."""
    cruise = scenario.vehicle.cruise_speed
    terrain = scenario.world.terrain
    files: dict[str, str | bytes] = {}
    geos = []
    for n, pieces in enumerate(timeline.pieces):
        stem = f"uav{n + 1}"
        pts, speeds, acts, durs = uav_mission(pieces, cruise)
        if len(pts) < 2:  # a UAV with no task stays on the ground: no mission
            continue
        speeds = np.clip(speeds, 0.1, scenario.vehicle.max_speed)
        geo = site_to_geodetic(pts[None], origin)[0]
        under = np.column_stack([pts[:, 0], pts[:, 1], terrain.height(pts[:, 0], pts[:, 1])])
        ground = site_to_geodetic(under[None], origin)[0][:, 2]
        home = site_to_geodetic(under[:1][None], origin)[0][0]
        geos.append((timeline.names[n], geo))
        M = len(pts)
        extra = sum((a.gimbal_pitch_deg is not None) + a.stop + (a.start_distance_m is not None) + a.photo for a in acts)
        items = 1 + 2 * (M - 1) + extra
        if "plan" in chosen:
            fm.check_limits("plan", f"{stem}.plan", waypoints=M, items=items)
            files[f"{stem}.plan"] = fm.qgc_plan(geo, speeds, home, cruise, note, ground, frame, acts)
        if "waypoints" in chosen:
            fm.check_limits("waypoints", f"{stem}.waypoints", waypoints=M, items=items + 1)
            files[f"{stem}.waypoints"] = fm.qgc_wpl(geo, speeds, home, ground, frame, acts)
        if "kmz" in chosen:
            ell = geo[:, 2] + geoid_height(geo[:, 0], geo[:, 1])
            home_ell = float(home[2] + geoid_height(home[0], home[1]))
            fm.check_limits("kmz", f"{stem}.kmz", waypoints=M, speeds=fm.dji_speeds(speeds))
            files[f"{stem}.kmz"] = fm.dji_kmz(geo, speeds, home, cruise, timeline.names[n] + (f" {note}" if note else ""),
                                              ell, home_ell, frame, acts)
        if "litchi" in chosen:
            idx, alt, spd, hold = fm.litchi_rows(geo, speeds, home, ground, frame, durs, actions=acts)
            name = f"{stem}.litchi.csv"
            fm.check_limits("litchi", name, waypoints=len(idx), speeds=spd, altitudes=alt,
                            legs=fm.litchi_legs(geo, idx), holds_ms=hold)
            files[name] = fm.litchi_csv(geo, speeds, home, ground, frame, durs, acts)
    names = [g[0] for g in geos]
    if "kml" in chosen:
        files["mission.kml"] = fm.team_kml([g[1] for g in geos], names, note)
    if "geojson" in chosen:
        files["mission.geojson"] = fm.team_geojson([g[1] for g in geos], names, np.zeros(0), note)
    if "trajectories" in chosen:
        t = np.arange(0.0, timeline.end + 0.05, 0.1)
        state = timeline.state(t)
        files["trajectories.csv"] = fm.trajectories_csv(t, state[0], state[1])
    return files
