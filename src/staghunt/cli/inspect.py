"""``staghunt cameras``, ``staghunt inspect`` and the inspection path of ``staghunt plan``:
parse, call :mod:`staghunt.inspection`, write, report.

Exit codes: ``0`` planned (``inspect``: allocated); ``3`` the inspection was planned but a leg is
infeasible, a window is missed or the team is unsafe in time (``inspection.json`` still written);
``2`` bad input (objectives, cameras, endurance too short for any allocation), nothing written.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from staghunt.cli.common import (
    EXIT_NEGATIVE, EXIT_OK, PROG, add_plots_option, add_quiet_option, add_scenario_argument, add_seed_option,
    check_out_dir, command, os_reason, path_argument, safe_name, say,
)
from staghunt.inputs import clip


def add_objectives_option(p: argparse.ArgumentParser) -> None:
    """``--objectives FILE``: an objectives file whose tables replace the scenario's."""
    p.add_argument("--objectives", metavar="FILE", type=path_argument,
                   help="objectives file (TOML: [camera] or camera = NAME, [payload], [inspection], [[objectives]]): "
                   "the inspection to plan; its tables replace the scenario's")


def add_allocation_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--allocation", choices=["ortools", "greedy"], default="ortools",
                   help="ortools (default): OR-Tools routing, bisection on the makespan; greedy: cheapest insertion")


def add_commands(sub: Any) -> None:
    command(sub, "cameras", cmd_cameras)
    p = command(sub, "inspect", cmd_inspect, {EXIT_OK: "every required objective allocated"})
    add_scenario_argument(p)
    add_objectives_option(p)
    add_allocation_option(p)
    add_seed_option(p)
    p.add_argument("--out", metavar="DIR", type=path_argument, help="also write DIR/allocation.json and, unless "
                   "--no-plots, DIR/inspection.png")
    add_plots_option(p)
    add_quiet_option(p)


def cmd_cameras(args: argparse.Namespace) -> int:
    """list the shipped cameras (QGroundControl CameraMetaData fields, with sources)"""
    from staghunt.camera import camera_table

    rows = [("camera", "sensor mm", "image px", "focal mm", "min interval s", "GSD at 50 m cm/px")]
    for c in camera_table().values():
        rows.append((c.name, f"{c.sensor_width_mm:g} x {c.sensor_height_mm:g}", f"{c.image_width_px} x {c.image_height_px}",
                     f"{c.focal_length_mm:g}", f"{c.min_trigger_interval_s:g}", f"{c.gsd_cm(50.0):.3g}"))
    print(_table(rows))
    for c in camera_table().values():
        print(f"- {c.name}: {c.source}")
    return EXIT_OK


def load_inspection_scenario(source: str, objectives: str | None) -> Any:
    """The scenario with its objectives (an objectives file's replacing them); ``ValueError``
    naming the input when there is none to plan."""
    from staghunt.scenario import load_scenario

    scenario = load_scenario(source, objectives=objectives)
    if scenario.inspection is None or not scenario.inspection.objectives:
        raise ValueError(f"{source}: no objectives to inspect (give --objectives FILE, or [[objectives]] and a camera "
                         "in the scenario)")
    return scenario


def cmd_inspect(args: argparse.Namespace) -> int:
    """show the objectives, capture plans and allocation of an inspection, before anything flies

    Plan every objective's captures with its camera (survey lines, facade layers, viewpoints; what
    had to move to be safe, what cannot be reached), split them into tasks and allocate them to the
    UAVs for the makespan within their endurance and the time windows (OR-Tools, with the greedy
    baseline beside it and a lower bound). No leg is planned and nothing flies: 'staghunt plan' with
    the same objectives plans the legs with the game, times and checks the team.
    """
    from staghunt.acquisition.plan import plan_captures
    from staghunt.inspection.allocation import Problem
    from staghunt.inspection.routing import solve
    from staghunt.inspection.planner import SLACK, fleet_of
    from staghunt.inspection.tasks import make_tasks

    scenario = load_inspection_scenario(args.scenario, args.objectives)
    if args.out is not None:
        check_out_dir(Path(args.out), "allocation.json")
    insp = scenario.inspection
    captures = plan_captures(scenario, insp)
    tasks = make_tasks(insp, captures)
    problem = Problem(tuple(tasks), fleet_of(scenario, insp), slack=SLACK)
    greedy = solve(problem, "greedy")
    alloc = greedy if args.allocation == "greedy" else solve(problem, args.allocation)
    print(objectives_table(captures))
    for o in captures.objectives:
        for note in o.moved:
            print(f"  moved: {o.name}: {note}")
        for note in o.unreached:
            print(f"  UNREACHED: {o.name}: {note}")
    print(allocation_table(alloc, greedy, tasks, problem.fleet.names))
    if args.out is not None:
        out = Path(args.out)
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ValueError(f"cannot create output directory {str(out)!r}: {os_reason(exc)}") from None
        from staghunt.inspection.files import allocation_dict
        from staghunt.io.result_json import write_json_atomic

        path = write_json_atomic(allocation_dict(scenario, captures, tasks, alloc, greedy), out / "allocation.json")
        print(f"wrote {path}")
        if not args.no_plots:
            figure = _figure(lambda: __import__("staghunt.plots.inspection", fromlist=["x"]).allocation_figure(
                scenario, captures, tasks, alloc, out / "inspection.png"))
            if figure:
                print(f"wrote {figure}")
    if not alloc.ok:
        raise ValueError(alloc.message)
    return EXIT_OK


def _figure(draw: Any) -> Path | None:
    try:
        return draw()
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # a plotting bug is not the user's input
        say(f"{PROG}: warning: figure not written: {clip(str(exc))}")
        return None


def run_inspection_plan(scenario: Any, args: argparse.Namespace, certify: Any) -> int:
    """``staghunt plan`` of a scenario with objectives: plan the inspection, write
    ``DIR/inspection.json`` and its figures, report."""
    from staghunt.inspection.files import write_inspection
    from staghunt.inspection.planner import InspectConfig, plan_inspection

    out = Path(args.out) if args.out is not None else Path("runs") / f"{safe_name(scenario.name)}-inspection-s{args.seed}"
    check_out_dir(out, "inspection.json")
    settings = scenario.solver.with_(particles=args.particles, iterations=args.iterations, waypoints=args.waypoints,
                                     starts=args.starts)
    config = InspectConfig(allocation=getattr(args, "allocation", "ortools"), leg_settings=settings, certify=certify,
                           engine=args.engine or "auto")
    plan = plan_inspection(scenario, scenario.inspection, config, seed=args.seed)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"cannot create output directory {str(out)!r}: {os_reason(exc)}") from None
    path = write_inspection(plan, out / "inspection.json")
    figures = [] if args.no_plots else [f for f in (
        _figure(lambda: __import__("staghunt.plots.inspection", fromlist=["x"]).plan_figure(plan, out / "inspection.png")),
        _figure(lambda: __import__("staghunt.plots.inspection", fromlist=["x"]).coverage_figure(
            plan.scenario, plan.inspection, plan.photos(), out / "coverage.png", "planned"))) if f]
    if not args.quiet:
        print(objectives_table(plan.captures))
        print(allocation_table(plan.allocation, plan.baseline, list(plan.tasks), plan.timeline.names))
        if plan.outbound is not None and plan.outbound.certificate is not None:
            print(f"outbound leg (the team's game to the first captures): {plan.outbound.certificate.verdict}")
        print(coverage_table(plan.coverage))
        t = plan.times
        print("time: " + ", ".join(f"{k[:-2]} {v:.1f} s" for k, v in t.items()))
    print(f"status: {plan.message}")
    print(f"wrote {path}")
    for f in figures:
        print(f"wrote {f}")
    return EXIT_OK if plan.status.value == "planned" else EXIT_NEGATIVE


# ------------------------------------------------------------------------------------------------
# Tables
# ------------------------------------------------------------------------------------------------


def _table(rows: list[tuple[str, ...]]) -> str:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join([r[0].ljust(widths[0])] + [v.rjust(w) for v, w in zip(r[1:], widths[1:])]).rstrip()
                     for r in rows)


def objectives_table(captures: Any) -> str:
    """Per objective: kind, planned GSD and distance, segments, photos (and QGroundControl's for an
    area), capture time, moved and unreached counts."""
    rows = [("objective", "kind", "GSD cm/px", "distance m", "segments", "photos", "QGC photos", "work s", "moved",
             "unreached")]
    for o in captures.objectives:
        rows.append((o.name, o.kind, f"{o.gsd_cm:.3g}", f"{o.distance_m:.1f}", str(len(o.segments)), str(o.photos),
                     "-" if o.qgc_photos is None else str(o.qgc_photos), f"{o.work_s:.0f}", str(len(o.moved)),
                     str(len(o.unreached))))
    return _table(rows)


def allocation_table(alloc: Any, greedy: Any, tasks: list[Any], names: tuple[str, ...]) -> str:
    """Per UAV: its tasks (by objective), work, transit, waiting and end; the makespan against the
    lower bound and the greedy baseline."""
    rows = [("UAV", "tasks", "objectives", "work s", "transit s", "wait s", "end s")]
    for r in alloc.routes:
        objs = sorted({tasks[v.task].objective for v in r.visits})
        rows.append((names[r.uav], str(len(r.visits)), ", ".join(objs) or "-", f"{r.work:.0f}", f"{r.transit:.0f}",
                     f"{r.wait:.0f}", f"{r.end:.0f}"))
    ratio = alloc.makespan / alloc.lower_bound if alloc.lower_bound > 0 else float("nan")
    text = _table(rows)
    text += (f"\nallocation ({alloc.method}): makespan {alloc.makespan:.0f} s, lower bound {alloc.lower_bound:.0f} s "
             f"(ratio {ratio:.3f}); greedy baseline {greedy.makespan:.0f} s; {alloc.solve_time_s:.2f} s")
    if alloc.dropped:
        text += f"\nleft out (optional): {', '.join(sorted({tasks[i].objective for i in alloc.dropped}))}"
    return text


def coverage_table(coverage: Any) -> str:
    """Per objective: the share of cells or patches at the target GSD, with five images or more,
    images per element, overlaps reached and blur."""
    rows = [("objective", "kind", "at target GSD", ">= 5 images", "images (median)", "front overlap", "side overlap",
             "blur px (max)")]
    for c in coverage:
        if c["kind"] == "point":
            rows.append((c["objective"], "point", f"{c['visits_done']}/{c['visits']} visits", "-", "-", "-", "-", "-"))
            continue

        def share(d: dict) -> str:
            return "-" if d["reached_share"] is None else f"{d['reached_share']:.1%}"

        rows.append((c["objective"], c["kind"], f"{c['target_share']:.1%}",
                     f"{c['min_images_share']:.1%}" if c["kind"] == "area" else "-",
                     f"{c['images_per_element']['median']:.0f}" if c["images_per_element"]["median"] is not None else "-",
                     share(c["front_overlap"]), share(c["side_overlap"]),
                     "-" if c["blur_px"]["max"] is None else f"{c['blur_px']['max']:.2f}"))
    return _table(rows)


def flight_report(summary: dict) -> str:
    """The simulated inspection flight in a few lines."""
    lines = [f"in flight (simulated, {summary['rate_hz']:g} Hz, wind {summary['wind_m_s']:g} m/s, "
             f"{summary['duration_s']:.0f} s in {summary['wall_time_s']:.0f} s): {summary['photos']} photos; "
             f"least separation {min(summary['min_separation_m'].values()):.2f} m, least clearance "
             f"{min(summary['min_clearance_m'].values()):.2f} m (required {summary['required_clearance_m']:g})"]
    for d in summary["decisions"]:
        lines.append(f"  t = {d['time_s']:6.1f} s  {d['trigger']}: {d['tasks_reallocated']} tasks re-allocated in "
                     f"{d['latency_s'] * 1000:.0f} ms, new makespan {d['makespan_s']:.0f} s")
    for p in summary["problems"]:
        lines.append(f"  problem: {p}")
    return "\n".join(lines)


def run_inspection_fly(args: argparse.Namespace) -> int:
    """``staghunt fly`` of an inspection: plan it (or read inspection.json), fly it with its events,
    write the flight's files."""
    from staghunt.flight.inspection import fly_inspection
    from staghunt.inspection.files import read_inspection, read_timeline, write_inspection
    from staghunt.inspection.planner import InspectConfig, plan_inspection
    from staghunt.scenario.dynamics import load_events
    from staghunt.scenario.inspection import check_inspection_events

    out = Path(args.out)
    check_out_dir(out, "flight.json")
    plan = None
    if str(args.source).endswith(".json"):
        data = read_inspection(args.source)
        scenario, timeline = read_timeline(data, args.source)
    else:
        scenario = load_inspection_scenario(args.source, args.objectives)
        settings = scenario.solver.with_(particles=args.particles, iterations=args.iterations, waypoints=args.waypoints,
                                         starts=args.starts)
        plan = plan_inspection(scenario, scenario.inspection, InspectConfig(leg_settings=settings,
                                                                            engine=args.engine or "auto"), seed=args.seed)
        timeline = plan.timeline
    events: list = []
    if args.events is not None:
        dyn = load_events(args.events, scenario)
        if dyn.moving or dyn.jibs:
            raise ValueError(f"{args.events}: an inspection's flight does not model moving obstacles or slewing jibs "
                             "yet (only obstacles that appear or disappear, lost UAVs and added objectives)")
        try:
            events = check_inspection_events(scenario, dyn.events)
        except ValueError as exc:
            raise ValueError(f"{args.events}: {exc}") from None
    if scenario.dynamics.moving or scenario.dynamics.jibs:
        raise ValueError(f"{scenario.name}: an inspection's flight does not model moving obstacles or slewing jibs yet")

    def progress(t: float, t_end: float) -> None:
        if not args.quiet:
            say(f"{PROG}: re-allocated at t = {t:.1f} s")

    flight = fly_inspection(scenario, timeline, tuple(events), wind=args.wind, seed=args.seed, progress=progress)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"cannot create output directory {str(out)!r}: {os_reason(exc)}") from None
    files = []
    if plan is not None:
        files.append(write_inspection(plan, out / "inspection.json"))
    files += write_inspection_flight(flight, out, plots=not args.no_plots)
    print(flight_report(flight.summary()))
    print(coverage_table(flight.coverage))
    print(f"wrote {len(files)} files to {out}")
    return EXIT_OK if not flight.problems else EXIT_NEGATIVE


def write_inspection_flight(flight: Any, out_dir: Path, plots: bool = True) -> list[Path]:
    """``flight.csv``, ``captures.csv``, ``coverage.json``, ``flight.json`` and, with ``plots``,
    ``coverage.png`` and ``replay.html`` (the photos' footprints drawn), each written atomically."""
    import json

    from staghunt.flight.inspection import captures_csv, flight_csv, flight_dict
    from staghunt.inspection.files import clean
    from staghunt.io.atomic import write_text_atomic

    files = [write_text_atomic(flight_csv(flight), out_dir / "flight.csv"),
             write_text_atomic(captures_csv(flight), out_dir / "captures.csv"),
             write_text_atomic(json.dumps(flight.coverage_json(), indent=1) + "\n", out_dir / "coverage.json"),
             write_text_atomic(json.dumps(clean(flight.summary()), indent=1) + "\n", out_dir / "flight.json")]
    if plots:
        from staghunt.plots.inspection import coverage_figure
        from staghunt.plots.replay import write_replay_html

        figure = _figure(lambda: coverage_figure(flight.scenario, flight.scenario.inspection, flight.photos,
                                                 out_dir / "coverage.png", "flown"))
        if figure:
            files.append(figure)
        write_replay_html(out_dir / "replay.html", flight_dict(flight))
        files.append(out_dir / "replay.html")
    return files
