"""``staghunt export``: every mission file of a plan, built in memory, then written atomically.

Nothing is written unless every file could be built, and the set is written as one
(:func:`staghunt.io.atomic.write_file_set`): staged in the output directory, then moved into
place; a failure or an interrupt leaves the directory as it was. The paths are checked against
the embedded scenario with ``evaluate``'s check (the stored status is not trusted). An
infeasible plan, trajectories that break a limit in time, or (with ``simulate``) a simulated
flight that does, are refused unless ``force``; then every file that has a place for it says
so, and ``MISSION_UNSAFE.txt`` lists why.

Altitudes are written in one frame per export (``relative`` to home, ``amsl``, or above the
``terrain`` of the scenario's model); a format without that frame, or a file that would break a
published limit of its target (:data:`staghunt.missions.formats.TARGET_LIMITS`), is refused with
:class:`~staghunt.missions.formats.TargetLimitError` before anything is written. WGS84 ellipsoid
heights (DJI) come from the EGM2008 geoid (:mod:`staghunt.geo.geoid`).
"""

from __future__ import annotations

import json
import math
import os
import stat
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from staghunt.costs import CostModel
from staghunt.costs.model import full_paths, to_absolute
from staghunt.errors import FieldError
from staghunt.flight.mission import MissionFlight, fly_mission, read_trajectories_csv
from staghunt.geo import GeoOrigin, check_origin, site_to_geodetic
from staghunt.geo.geoid import GEOID_MODEL, geoid_height, geoid_source
from staghunt.io.atomic import write_file_set
from staghunt.missions import formats as fm
from staghunt.trajectory import SafetyReport, Trajectories, time_and_check


class ExportRefused(FieldError):
    """The plan is infeasible or unsafe in time and ``force`` was not given (exit 3)."""

    def __init__(self, message: str) -> None:
        super().__init__(message, "force")


@dataclass(frozen=True)
class ExportReport:
    """What was written: ``files``; the timing (``duration`` s, ``stretch``, per UAV
    ``max_speed``, ``max_acceleration``, the reference duration ``bound`` s and the number of
    ``merged`` waypoint indices); the in-time ``safety``; the simulated ``flight`` (with
    ``--simulate``); ``seconds`` spent; the ``altitude_frame`` and the geoid height at the
    origin (m, ``geoid_model``)."""

    files: tuple[Path, ...]
    origin: GeoOrigin
    duration: float
    stretch: float
    max_speed: tuple[float, ...]
    max_acceleration: tuple[float, ...]
    safety: SafetyReport
    bound: float = math.nan
    merged: int = 0
    flight: MissionFlight | None = None
    warnings: tuple[str, ...] = field(default=())
    seconds: float = 0.0
    altitude_frame: str = "relative"
    geoid_height: float = 0.0
    geoid_model: str = GEOID_MODEL


def _parse_formats(formats: Any) -> tuple[str, ...]:
    if formats is None:
        return fm.FORMATS
    items = [f.strip() for f in (formats.split(",") if isinstance(formats, str) else formats)]
    unknown = [f for f in items if f not in fm.FORMATS]
    if unknown or not items:
        raise ValueError(f"unknown format {unknown[0] if unknown else ''!r}; choose from {', '.join(fm.FORMATS)}")
    return tuple(dict.fromkeys(items))


def parse_altitude_frame(frame: Any) -> str:
    """``relative`` (default), ``amsl`` or ``terrain``; anything else is a one-line ``ValueError``."""
    text = "relative" if frame is None else str(frame).strip().lower()
    if text not in fm.ALTITUDE_FRAMES:
        raise ValueError(f"unknown altitude frame {str(frame)[:40]!r}; choose from {', '.join(fm.ALTITUDE_FRAMES)}")
    return text


def export_result(result_path: str, out_dir: str, origin: GeoOrigin | None = None,
                  formats: Any = None, force: bool = False, plots: bool = True,
                  data: dict[str, Any] | None = None, altitude_frame: str = "relative",
                  simulate: bool = False, progress: Callable[[float, float], None] | None = None
                  ) -> ExportReport:
    """Export the plan of ``result_path`` (a ``result.json``) to ``out_dir``.

    ``origin``: the site frame's geodetic origin (default: the scenario's; one of them is
    needed). ``altitude_frame``: ``relative`` (to the takeoff point), ``amsl`` or ``terrain``
    (above the scenario's terrain under each waypoint) for ``.plan``, ``.waypoints``, ``.kmz``
    and Litchi. ``simulate``: fly ``trajectories.csv`` with the simulated vehicles first
    (:func:`staghunt.flight.mission.fly_mission`; ``progress(t, t_end)`` about once per simulated
    second); a flight that breaks a limit is unsafe like a plan that does. Raises ``ValueError``
    with one line for bad input (a frame a chosen format lacks and a target's limit included:
    :class:`~staghunt.missions.formats.TargetLimitError`), :class:`ExportRefused` for an
    infeasible or unsafe plan without ``force``."""
    from staghunt.analysis.certify import plan_from_result_data
    from staghunt.io.paths_json import evaluate_paths, paths_from_result
    from staghunt.io.result_json import read_result

    t0 = time.perf_counter()
    chosen = _parse_formats(formats)
    frame = parse_altitude_frame(altitude_frame)
    for f in chosen:
        fm.check_frame(f, frame)
    if data is None:
        data = read_result(result_path)
    scenario, _, _ = plan_from_result_data(data, str(result_path))
    origin = origin if origin is not None else scenario.origin
    if origin is None:
        raise FieldError(f"{result_path}: the scenario has no [origin]; give an origin (latitude, longitude, altitude)", "origin")
    check_origin(origin, "origin" if origin is not scenario.origin else "scenario origin")
    out = Path(out_dir)
    if not str(out_dir).strip():
        raise FieldError("the output directory must not be empty", "out")
    if out.exists() and not out.is_dir():
        raise FieldError(f"the output directory {str(out)!r} exists and is not a directory", "out")
    # The stored status is not trusted: the paths are checked against the embedded scenario
    # with evaluate's own check (starts and goals the scenario's, the site box, obstacles,
    # ground, ceiling, separation), and the absolute paths rebuilt from it.
    wp = paths_from_result(data, scenario, str(result_path))  # ValueError: not this scenario's ends
    checked = evaluate_paths(scenario, wp)
    names = [u.name for u in scenario.team]
    model = CostModel.from_scenario(scenario)
    paths = to_absolute(model.terrain, full_paths(model, wp[None]))[0]  # (N, K + 2, 3) absolute
    _check_duration(paths, scenario.vehicle, str(result_path))
    traj, safety = time_and_check(model, paths, scenario.vehicle, names)
    problems = []
    if checked["status"] != "feasible":
        problems += [f"the paths are infeasible in the embedded scenario: {v}" for v in checked["violations"]]
    elif data.get("status") != "feasible":
        problems.append(f"the plan is {data.get('status')!r}: {data.get('message', '')}")
    problems += list(safety.problems)
    if problems and not force:
        raise _refused(result_path, problems)
    note = "UNSAFE: " + problems[0] if problems else ""
    files = _build(scenario, model, traj, origin, chosen, names, note[:200], frame)  # checks the targets' limits
    flight = None
    if simulate:  # after every check that needs no flight, so a refusal comes before minutes of it
        t = traj.grid()
        pos, vel = traj.sample(t)
        flight = fly_mission(scenario, *read_trajectories_csv(fm.trajectories_csv(t, pos, vel)),
                             progress=progress)
        if flight.problems:
            problems += list(flight.problems)
            if not force:
                raise _refused(result_path, problems)
            note = "UNSAFE: " + problems[0]
            files = _build(scenario, model, traj, origin, chosen, names, note[:200], frame)
    if problems:
        files["MISSION_UNSAFE.txt"] = "This mission was exported although it was refused (forced):\n" + \
            "\n".join(f"- {p}" for p in problems) + "\nDo not fly it as it is.\n"
    summary = _summary(data, origin, traj, safety, problems, names, frame)
    if flight is not None:
        summary["flight"] = _flight_summary(flight, names)

    def figures(stage: Path) -> list[Path]:
        from staghunt.plots.mission import save_mission_figures

        return list(save_mission_figures(traj, scenario, stage))

    def manifest(names: list[str]) -> tuple[str, str]:
        summary["files"] = sorted([*names, MANIFEST])  # what a later export into out replaces
        return MANIFEST, json.dumps(summary, indent=1) + "\n"

    try:  # the whole set or nothing, replacing the previous export's set: staged, then moved into place
        written = write_file_set(out, files, figures if plots else None, previous_set(out), manifest)
    except OSError as exc:
        raise ValueError(f"cannot write to {str(out)!r}: {exc.strerror or exc}") from None
    return ExportReport(files=tuple(written), origin=origin, duration=traj.duration, stretch=traj.stretch,
                        max_speed=tuple(float(v) for v in traj.max_speed),
                        max_acceleration=tuple(float(v) for v in traj.max_acceleration),
                        safety=safety, bound=traj.bound, merged=traj.merged, flight=flight,
                        warnings=tuple(problems), seconds=time.perf_counter() - t0,
                        altitude_frame=frame, geoid_height=float(summary["origin"]["geoid_height_m"]))


MANIFEST = "mission.json"
"""The export's summary, written last; its ``files`` list the set (itself included)."""


def previous_set(out: Path) -> list[str]:
    """The files a previous export wrote into ``out``, as its :data:`MANIFEST` lists them (none
    if there is none or it cannot be read: only what an export listed is ever replaced)."""
    try:
        if not stat.S_ISREG(os.stat(out / MANIFEST).st_mode):  # never open a FIFO or a device
            return []
        with open(out / MANIFEST, encoding="utf-8") as fh:
            data = json.loads(fh.read(MAX_MANIFEST_BYTES))
    except (OSError, ValueError, RecursionError):
        return []
    if not isinstance(data, dict) or data.get("format") != "staghunt-mission/1":
        return []
    names = data.get("files")
    if names is None:  # an older export's manifest, without its list: the files such an export writes
        return _older_set(data)
    if not isinstance(names, list):
        return []
    return [n for n in names if isinstance(n, str)]


def _older_set(data: dict[str, Any]) -> list[str]:
    """The names an export of staghunt before ``mission.json`` listed its files could write, for
    the UAVs its manifest names (``max_speed_m_s``): per UAV ``uav<n>.plan``, ``.waypoints``,
    ``.kmz``, ``.litchi.csv``; for the team ``mission.kml``, ``mission.geojson``,
    ``trajectories.csv``, the figures, ``MISSION_UNSAFE.txt`` and ``mission.json``."""
    speeds = data.get("max_speed_m_s")
    count = len(speeds) if isinstance(speeds, dict) else 0
    team = ["mission.json", "MISSION_UNSAFE.txt", "mission.kml", "mission.geojson", "trajectories.csv",
            "speed.png", "separation.png"]
    return team + [f"uav{n}{ext}" for n in range(1, count + 1) for ext in (".plan", ".waypoints", ".kmz", ".litchi.csv")]


MAX_MANIFEST_BYTES = 16 * 2**20


MAX_MISSION_SECONDS = 3600.0
"""Longest mission the timing is asked for (its reference bound, s): beyond any multirotor's
battery, and a timed sampling of it (milliseconds) would not fit in memory."""


def _check_duration(paths: np.ndarray, vehicle: Any, source: str) -> None:
    """Refuse (``ValueError``, one line naming the ``[vehicle]`` key) a mission whose reference
    duration (longest path / cruise speed + cruise / max acceleration) exceeds
    :data:`MAX_MISSION_SECONDS`: a speed of micrometres per second, not the budget, is the cause."""
    longest = float(np.linalg.norm(np.diff(paths, axis=1), axis=-1).sum(axis=-1).max())
    bound = longest / vehicle.cruise_speed + vehicle.cruise_speed / vehicle.max_acceleration
    if not bound <= MAX_MISSION_SECONDS:
        raise ValueError(
            f"{source}: the mission would last at least {bound:.3g} s (the longest path, {longest:.6g} m, at "
            f"vehicle.cruise_speed = {vehicle.cruise_speed:g} m/s with vehicle.max_speed = {vehicle.max_speed:g} m/s "
            f"and max_acceleration = {vehicle.max_acceleration:g} m/s^2), more than {MAX_MISSION_SECONDS:g} s; "
            "check the scenario's [vehicle] table")


def _refused(result_path: str, problems: list[str]) -> ExportRefused:
    return ExportRefused(f"{result_path}: not exported: {problems[0]}"
                         + (f" (and {len(problems) - 1} more)" if len(problems) > 1 else "")
                         + "; a forced export writes the files anyway, marked unsafe")


def _build(scenario: Any, model: CostModel, traj: Trajectories, origin: GeoOrigin,
           chosen: tuple[str, ...], names: list[str], note: str,
           frame: str = "relative") -> dict[str, str | bytes]:
    """Every chosen file's content; raises :class:`~staghunt.missions.formats.TargetLimitError`
    if one would break its target's limits (nothing is written then)."""
    pts = traj.points  # (N, M, 3) site frame
    geo = site_to_geodetic(pts, origin)  # (N, M, 3)
    under = np.stack([pts[..., 0], pts[..., 1], model.terrain.height(pts[..., 0], pts[..., 1])], axis=-1)
    ground = site_to_geodetic(under, origin)[..., 2]  # (N, M) ground AMSL under each point
    homes = site_to_geodetic(under[:, 0], origin)  # (N, 3) takeoff points: the ground under the start
    need_ell = "kmz" in chosen
    ell = geo[..., 2] + geoid_height(geo[..., 0], geo[..., 1]) if need_ell else None  # (N, M)
    home_ell = homes[:, 2] + geoid_height(homes[:, 0], homes[:, 1]) if need_ell else None  # (N,)
    speeds = np.clip(traj.leg_speeds(), 0.1, scenario.vehicle.max_speed)  # (N, M - 1)
    dts = np.diff(traj.times)  # (M - 1,) common leg durations (s)
    cruise = scenario.vehicle.cruise_speed
    M = pts.shape[1]
    items = 1 + 2 * (M - 1)  # takeoff, then (speed, waypoint) per leg
    files: dict[str, str | bytes] = {}
    for n in range(len(names)):
        stem = f"uav{n + 1}"
        if "plan" in chosen:
            fm.check_limits("plan", f"{stem}.plan", waypoints=M, items=items)
            files[f"{stem}.plan"] = fm.qgc_plan(geo[n], speeds[n], homes[n], cruise, note, ground[n], frame)
        if "waypoints" in chosen:
            fm.check_limits("waypoints", f"{stem}.waypoints", waypoints=M, items=items + 1)
            files[f"{stem}.waypoints"] = fm.qgc_wpl(geo[n], speeds[n], homes[n], ground[n], frame)
        if "kmz" in chosen:
            assert ell is not None and home_ell is not None
            fm.check_limits("kmz", f"{stem}.kmz", waypoints=M, speeds=fm.dji_speeds(speeds[n]))
            files[f"{stem}.kmz"] = fm.dji_kmz(geo[n], speeds[n], homes[n], cruise,
                                              f"{names[n]}" + (f" {note}" if note else ""),
                                              ell[n], float(home_ell[n]), frame)
        if "litchi" in chosen:
            idx, alt, spd, hold = fm.litchi_rows(geo[n], speeds[n], homes[n], ground[n], frame, dts)
            name = f"{stem}.litchi.csv"
            fm.check_limits("litchi", name, waypoints=len(idx), speeds=spd, altitudes=alt,
                            legs=fm.litchi_legs(geo[n], idx), holds_ms=hold)
            files[name] = fm.litchi_csv(geo[n], speeds[n], homes[n], ground[n], frame, dts)
    if "kml" in chosen:
        files["mission.kml"] = fm.team_kml(list(geo), names, note)
    if "geojson" in chosen:
        files["mission.geojson"] = fm.team_geojson(list(geo), names, traj.times, note)
    if "trajectories" in chosen:
        t = traj.grid()
        pos, vel = traj.sample(t)
        files["trajectories.csv"] = fm.trajectories_csv(t, pos, vel)
    return files


def _summary(data: dict[str, Any], origin: GeoOrigin, traj: Trajectories, safety: SafetyReport,
             problems: list[str], names: list[str], frame: str = "relative") -> dict[str, Any]:
    n0 = float(geoid_height(origin.latitude, origin.longitude))
    return {
        "format": "staghunt-mission/1",
        "method": data.get("method"), "seed": data.get("seed"), "plan_status": data.get("status"),
        "origin": {"latitude": origin.latitude, "longitude": origin.longitude,
                   "altitude_amsl_m": origin.altitude,
                   "geoid_height_m": round(n0, 3),
                   "altitude_ellipsoid_m": round(origin.altitude + n0, 3)},
        "geoid": {"model": GEOID_MODEL, "source": geoid_source(),
                  "relation": "ellipsoid height (WGS84) = altitude AMSL + geoid height"},
        "altitude_frame": frame,
        "altitude_datums": _datums(frame),
        "duration_s": traj.duration, "stretch": traj.stretch,
        "timing": {"method": "time-optimal (TOPP-RA), one path parameter for the team",
                   "duration_bound_s": traj.bound, "duration_over_bound": traj.duration / traj.bound,
                   "sub_leg_m": None if math.isinf(traj.spacing) else traj.spacing,
                   "merged_waypoints": traj.merged,
                   "plan_index": [int(k) for k in traj.kept]},
        "waypoint_times_s": [float(t) for t in traj.times],
        "max_speed_m_s": dict(zip(names, (float(v) for v in traj.max_speed))),
        "max_acceleration_m_s2": dict(zip(names, (float(v) for v in traj.max_acceleration))),
        "in_time": {"samples": safety.times, "step_s": safety.step,
                    "min_separation_m": dict(zip(names, safety.min_separation)),
                    "separation_limit_m": dict(zip(names, safety.separation_limit)),
                    "min_clearance_m": dict(zip(names, safety.min_clearance)),
                    "required_clearance_m": safety.required_clearance,
                    "min_height_m": dict(zip(names, safety.min_height)),
                    "notes": list(safety.notes)},
        "safe": not problems, "problems": problems,
    }


def _datums(frame: str) -> dict[str, str]:
    """What each file's altitudes mean for ``frame`` (mission.json ``altitude_datums``)."""
    mav = {"relative": "MAV_FRAME 3: metres above home (the ground under the UAV's start)",
           "amsl": "MAV_FRAME 0: metres above mean sea level",
           "terrain": "MAV_FRAME 10: metres above the terrain under each waypoint (the scenario's "
                      "terrain model); takeoff item MAV_FRAME 3"}[frame]
    dji = {"relative": "heightMode/executeHeightMode relativeToStartPoint (metres above the takeoff "
                       "point); wpml:ellipsoidHeight and takeOffRefPoint: WGS84 ellipsoid heights",
           "amsl": "heightMode EGM96 (wpml:height AMSL), executeHeightMode WGS84 (executeHeight = "
                   "ellipsoid height); wpml:ellipsoidHeight and takeOffRefPoint: WGS84 ellipsoid heights",
           }.get(frame, "not written: no terrain frame")
    litchi = {"relative": "altitudemode 0: metres above the takeoff point",
              "terrain": "altitudemode 1: metres above the ground under each waypoint"}.get(frame, "not written: no AMSL mode")
    return {
        "plan, waypoints": mav + "; home position AMSL",
        "kmz": dji,
        "litchi": litchi,
        "kml, geojson": "metres above mean sea level",
        "trajectories": "site frame z (absolute; AMSL = origin altitude + z)",
    }


def _flight_summary(flight: MissionFlight, names: list[str]) -> dict[str, Any]:
    """``mission.json``'s ``flight`` block: the simulated flight of ``trajectories.csv``."""
    per = lambda a: dict(zip(names, (float(v) for v in a)))  # noqa: E731
    return {
        "simulator": "rotorpy Multirotor (Hummingbird parameters) with rotorpy's SE3Control, no wind",
        "rate_hz": flight.sim_rate, "flown": "trajectories.csv (cubic Hermite through its samples)",
        "tracking_rms_m": per(flight.tracking_rms), "tracking_max_m": per(flight.tracking_max),
        "min_separation_m": per(flight.min_separation), "separation_limit_m": per(flight.separation_limit),
        "min_clearance_m": per(flight.min_clearance), "required_clearance_m": flight.required_clearance,
        "min_height_m": per(flight.min_height), "max_altitude_m": per(flight.max_altitude),
        "safe": flight.safe, "problems": list(flight.problems), "seconds": flight.seconds,
    }
