"""``staghunt export``: the mission files of a plan (parse, call :mod:`staghunt.missions`, report).

Exit codes: ``0`` written; ``3`` refused: the plan is infeasible, its timed trajectories break a
limit, or (``--simulate``) so does their simulated flight (``--force`` writes them anyway, marked
unsafe); ``2`` bad input; ``130`` interrupted.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any, Callable, Sequence

from staghunt.cli.common import EXIT_NEGATIVE, EXIT_OK, PROG, add_out_option, add_plots_option, command, error, one_line

OPTIONS_WITH_NEGATIVE_VALUES = ("--origin",)


def join_negative_values(argv: Sequence[str]) -> list[str]:
    """``--origin -33.88,151.2,30`` -> ``--origin=-33.88,151.2,30``: argparse would take a value
    starting with ``-`` that is not a plain number for an option; southern and western users
    type exactly that."""
    out: list[str] = []
    i = 0
    args = list(argv)
    while i < len(args):
        if args[i] in OPTIONS_WITH_NEGATIVE_VALUES and i + 1 < len(args):
            out.append(f"{args[i]}={args[i + 1]}")
            i += 2
        else:
            out.append(args[i])
            i += 1
    return out


def _parsed(parse: Callable[[str], Any], text: str) -> Any:
    """``parse(text)``, its ``ValueError`` turned into argparse's one-line error (exit 2)."""
    try:
        return parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _origin(text: str) -> Any:
    from staghunt.geo import parse_origin

    return _parsed(parse_origin, text)


def _altitude_frame(text: str) -> str:
    from staghunt.missions.export import parse_altitude_frame

    return _parsed(parse_altitude_frame, text)


_origin.__name__ = "origin"
_altitude_frame.__name__ = "altitude frame"


def add_commands(sub: Any) -> None:
    from staghunt.missions import FORMATS

    p = command(sub, "export", cmd_export, {
        EXIT_OK: "written",
        EXIT_NEGATIVE: "refused (infeasible plan, or unsafe in time or in the simulated flight; --force writes it "
        "marked unsafe)"})
    p.add_argument("result", metavar="RESULT.json|INSPECTION.json",
                   help="a result.json or an inspection.json written by 'staghunt plan'")
    add_out_option(p)
    from staghunt.cli.inspect import add_objectives_option

    add_objectives_option(p)
    p.add_argument("--origin", type=_origin, metavar="LAT,LON,ALT",
                   help="geodetic origin of the site frame's (0, 0, 0): degrees, degrees, metres AMSL "
                   "(default: the scenario's [origin]); e.g. --origin -33.8837,151.2006,30")
    p.add_argument("--formats", metavar="LIST", default=",".join(FORMATS),
                   help=f"comma-separated formats (default: all: {','.join(FORMATS)})")
    p.add_argument("--altitude-frame", type=_altitude_frame, default="relative", metavar="FRAME",
                   help="altitudes of .plan, .waypoints, .kmz and Litchi: relative (to the takeoff point, "
                   "default), amsl (above mean sea level; DJI: EGM96 / WGS84 ellipsoid; Litchi has none) or "
                   "terrain (above the scenario's terrain under each waypoint: MAVLink frame 10, Litchi "
                   "above ground; DJI has none)")
    p.add_argument("--force", action="store_true", help="export an infeasible or unsafe plan, marked as such")
    add_plots_option(p, "speed.png and separation.png")
    p.add_argument("--simulate", action="store_true",
                   help="first fly trajectories.csv with simulated multirotors (rotorpy, 100 Hz, no wind) "
                   "and report tracking error, separation and clearance in flight in mission.json; a "
                   "flight that breaks a limit is refused like an unsafe plan (exit 3 unless --force)")


def _inspection_source(args: argparse.Namespace) -> tuple[str | None, Any]:
    """``(the inspection.json to export, or None; the file's data)``: the file itself, or
    (``--objectives``) the inspection planned for the result's scenario with those objectives,
    written to ``DIR/inspection.json`` first. The file is read once (a FIFO works)."""
    from pathlib import Path

    from staghunt.io.result_json import load_json_strict

    data = load_json_strict(args.result)
    if isinstance(data, dict) and data.get("format") == "staghunt-inspection":
        if args.objectives is not None:
            raise ValueError(f"{args.result} is an inspection already; --objectives is for a result.json")
        return args.result, data
    if args.objectives is None:
        return None, data
    from staghunt.inspection.files import write_inspection
    from staghunt.inspection.planner import plan_inspection
    from staghunt.scenario.objectives_file import with_objectives

    if not isinstance(data, dict) or not isinstance(data.get("scenario"), dict):
        raise ValueError(f"{args.result}: not a staghunt result file (no scenario)")
    scenario = with_objectives(data["scenario"], args.objectives, name="inspection", base_dir=None, source=args.result)
    plan = plan_inspection(scenario, scenario.inspection, seed=int(data.get("seed", 0) or 0))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    return str(write_inspection(plan, out / "inspection.json")), data


def cmd_export(args: argparse.Namespace) -> int:
    """mission files of a plan for ground stations (QGC, ArduPilot, DJI, Litchi)

    Geo-reference the plan in RESULT.json, time it (common waypoint times, within the scenario's
    [vehicle] limits), check separation and clearance in time, and write the mission files to DIR:
    uav{n}.plan (QGroundControl), uav{n}.waypoints (QGC WPL 110), uav{n}.kmz (DJI WPML),
    uav{n}.litchi.csv (Litchi), mission.kml, mission.geojson, trajectories.csv, mission.json
    (timing, datums, minima), speed.png and separation.png. docs/missions.md says how to load each.
    An inspection (INSPECTION.json, or RESULT.json with --objectives FILE) exports every UAV's own
    mission with its camera actions: gimbal pitch, heading, distance triggering, photos at
    viewpoints; with --simulate also captures.csv and coverage.json of the simulated flight.
    """
    from staghunt.missions import export_result
    from staghunt.missions.export import ExportRefused

    source, data = _inspection_source(args)
    if source is not None:
        from staghunt.missions.inspection import export_inspection

        try:
            summary = export_inspection(source, args.out, origin=args.origin, formats=args.formats, force=args.force,
                                        plots=not args.no_plots, altitude_frame=args.altitude_frame,
                                        simulate=args.simulate, data=data if source == args.result else None)
        except ExportRefused as exc:
            error(one_line(exc, "export"))
            return EXIT_NEGATIVE
        if "flight" in summary:
            from staghunt.cli.inspect import flight_report

            print(flight_report(summary["flight"]))
        print(f"inspection mission: makespan {summary['makespan_s']:.0f} s; camera actions in every UAV's mission; "
              f"altitudes {args.altitude_frame}; wrote {len(summary['files'])} files to {args.out}")
        return EXIT_OK

    def progress(t: float, t_end: float) -> None:
        if sys.stderr.isatty():
            sys.stderr.write(f"\r{PROG}: flying the mission in simulation, t = {t:5.1f} of {t_end:.1f} s ")
            sys.stderr.flush()

    try:
        from staghunt.io.result_json import result_from_data

        report = export_result(args.result, args.out, origin=args.origin, formats=args.formats,
                               data=result_from_data(data, args.result),
                               force=args.force, plots=not args.no_plots, simulate=args.simulate,
                               progress=progress, altitude_frame=args.altitude_frame)
    except ExportRefused as exc:
        error(one_line(exc, "export"))
        return EXIT_NEGATIVE
    s = report.safety
    print(f"mission: {report.duration:.1f} s ({report.duration / report.bound:.2f} x the bound "
          f"max L / cruise + cruise / max acceleration = {report.bound:.1f} s), waypoint times shared "
          f"by the team; max speed {max(report.max_speed):.2f} m/s, max acceleration "
          f"{max(report.max_acceleration):.2f} m/s^2"
          + (f"; {report.merged} near-duplicate waypoint(s) merged" if report.merged else ""))
    print(f"in time ({s.times} samples, step {s.step:.3f} s): min separation {min(s.min_separation):.2f} m "
          f"(limit {max(s.separation_limit):g}), min clearance {min(s.min_clearance):.2f} m "
          f"(required {s.required_clearance:g}), min height {min(s.min_height):.2f} m")
    for note in s.notes[:3]:
        print(f"note: {note}")
    f = report.flight
    if f is not None:
        if sys.stderr.isatty():
            sys.stderr.write("\n")
        print(f"in flight (simulated, {f.sim_rate:g} Hz, {f.seconds:.0f} s): tracking RMS "
              f"{f.tracking_rms.max():.3f} m (max {f.tracking_max.max():.3f} m), min separation "
              f"{f.min_separation.min():.2f} m (limit {f.separation_limit.max():g}), min clearance "
              f"{f.min_clearance.min():.2f} m (required {f.required_clearance:g})")
    if report.warnings:
        print(f"{PROG}: warning: exported with --force although: {report.warnings[0]}", file=sys.stderr)
    print(f"origin {report.origin.latitude:.6f}, {report.origin.longitude:.6f}, {report.origin.altitude:g} m AMSL "
          f"(geoid {report.geoid_height:+.2f} m, {report.geoid_model}); altitudes {args.altitude_frame}; "
          f"wrote {len(report.files)} files to {args.out} in {report.seconds:.2f} s")
    return EXIT_OK
