"""``staghunt fly``: a closed-loop flight in simulation with re-planning (parse, call
:func:`staghunt.flight.fly`, write, report).

Exit codes: ``0`` the team arrived with every margin kept; ``3`` the goal became unreachable
and the team stopped safely; ``4`` a required margin was broken (clearance, separation, ground,
ceiling) without contact; ``5`` a contact (the flight log is still written for 3, 4 and 5);
``2`` bad input, before any simulation; ``130`` interrupted (nothing written).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

from staghunt.cli.common import (
    EXIT_INTERRUPTED, EXIT_NEGATIVE, EXIT_OK, EXIT_USAGE, PROG, add_plots_option, add_run_options, add_seed_option,
    check_out_dir, command, engine_kwargs, int_at_least, number_between, one_line, os_reason, path_argument, say,
)
from staghunt.inputs import clip
from staghunt.io.flight_files import latency_summary, write_flight


EXIT_BREACH = 4
EXIT_CONTACT = 5


def _latency(text: str) -> float | str:
    """``--latency``: ``measured`` or a number of seconds in (0, 10]."""
    if text.strip().lower() == "measured":
        return "measured"
    try:
        return number_between(0, 10, "s", above_low=True)(text)
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"'measured' or {exc}") from None


def add_commands(sub: Any) -> None:
    p = command(sub, "fly", cmd_fly, {
        EXIT_OK: "arrived with every margin kept", EXIT_NEGATIVE: "stopped safely, goal unreachable (the log is still written)",
        EXIT_BREACH: "a required margin broken without contact: clearance, separation, ground or ceiling (the log is "
                     "still written)",
        EXIT_CONTACT: "a contact (the log is still written)",
        EXIT_USAGE: "bad input (before any simulation)", EXIT_INTERRUPTED: "interrupted (nothing written)"})
    p.add_argument("source", metavar="SCENARIO|RESULT.json|INSPECTION.json",
                   help="built-in scenario, scenario .toml file, or a result.json or inspection.json written by "
                   "'staghunt plan'")
    from staghunt.cli.inspect import add_objectives_option

    add_objectives_option(p)
    p.add_argument("--events", metavar="FILE", type=path_argument,
                   help="events file (TOML: [[events]], [[moving]], [[jibs]], [sensing]) added to the scenario's")
    p.add_argument("--wind", type=number_between(0, 30, "m/s"), default=0.0, metavar="M/S",
                   help="mean wind speed with Dryden turbulence (default 0)")
    p.add_argument("--wind-heading", type=number_between(-360, 360, "degrees"), default=0.0, metavar="DEG",
                   help="direction the wind blows towards, degrees counter-clockwise from east (default 0)")
    add_seed_option(p, "seed of the whole episode (default 0)")
    p.add_argument("--latency", type=_latency, default="measured", metavar="measured|S",
                   help="how long a re-plan takes to take effect: 'measured' (default: its real wall time, while the "
                   "simulated world goes on) or a fixed number of seconds (reproducible runs); flight.json says which")
    p.add_argument("--deadline", type=number_between(0.01, 10, "s"), default=None, metavar="S",
                   help="a re-plan's time budget (default: the fixed latency, or 0.215 s for 3 UAVs plus 0.16 s per more "
                   "UAV, at most 1 s)")
    p.add_argument("--replan-rate", type=number_between(0, 10, "Hz"), default=None, metavar="HZ",
                   help="receding horizon: re-plans per second with nothing sensed (default 1; 0: only on events)")
    p.add_argument("--replan-horizon", type=number_between(0, 3600, "s"), default=None, metavar="S",
                   help="seconds of the route a receding-horizon re-plan re-solves (default 20; 0: to the goals)")
    p.add_argument("--link-delay", type=number_between(0, 10, "s"), default=None, metavar="S",
                   help="radio delay, one way (default: the scenario's or events file's [link], else 0.1)")
    p.add_argument("--link-jitter", type=number_between(0, 10, "s"), default=None, metavar="S",
                   help="radio jitter, standard deviation (default: [link], else 0.03)")
    p.add_argument("--link-loss", type=number_between(0, 0.99, "share"), default=None, metavar="P",
                   help="share of radio messages lost (default: [link], else 0.01)")
    p.add_argument("--replan-particles", type=int_at_least(1), metavar="N", help="particles of each re-plan's game")
    p.add_argument("--replan-iterations", type=int_at_least(1), metavar="N", help="iterations of each re-plan's game")
    add_plots_option(p, "figures, the animation or the replay page")
    add_run_options(p, None)


def cmd_fly(args: argparse.Namespace) -> int:
    """fly a plan in closed loop: simulated multirotors, sensing, re-planning in flight

    Plan SCENARIO (or take the plan of RESULT.json), make it sound against the site's known motions,
    and fly it with simulated multirotors (the scenario's airframe, rotorpy's SE(3) controller) at 100 Hz; the ground
    station receives the UAVs' states at 10 Hz over a radio link (delay, jitter, loss), learns of
    obstacles they sense, predicts conflicts with moving ones, and re-solves the game in flight
    (warm-started, certified, within a deadline, and every second over a receding horizon) while
    the simulated world goes on; each UAV holds on its own when it hears nothing, and its reflex
    brakes before a sensed obstacle. Writes DIR/flight.csv, replans.json, flight.json (the
    verdict: every breach of a margin, which UAV, where and when), figures, flight.gif and
    replay.html (an offline 3-D replay). Events: docs/scenario-format.md. An inspection (objectives
    in the scenario or --objectives FILE, or an inspection.json) is planned and flown with its
    cameras: the task layer re-allocates the work when a UAV is lost, an objective is added or an
    obstacle appears; it writes flight.csv, captures.csv, coverage.json, flight.json,
    coverage.png and replay.html (with the photos' footprints).
    """
    from staghunt.flight import FlyConfig, check_flight, fly  # the simulator: only for this command

    if _is_inspection(args):
        from staghunt.cli.inspect import run_inspection_fly

        return run_inspection_fly(args)
    out_dir = Path(args.out)
    check_out_dir(out_dir, "flight.json")
    changes = {"latency": args.latency, "deadline": args.deadline, "replan_particles": args.replan_particles,
               "replan_iterations": args.replan_iterations, "replan_rate": args.replan_rate,
               "replan_horizon": args.replan_horizon}
    config = replace(FlyConfig(wind=args.wind, wind_heading_deg=args.wind_heading),
                     **{k: v for k, v in changes.items() if v is not None})
    link = {"delay": args.link_delay, "jitter": args.link_jitter, "loss": args.link_loss}
    if any(v is not None for v in link.values()):
        config = replace(config, link=_link(args, link))
    budget = {"particles": args.particles, "iterations": args.iterations, "waypoints": args.waypoints,
              "starts": args.starts}
    request = check_flight(args.source, events=args.events, seed=args.seed, config=config, budget=budget,
                           warn=say, **engine_kwargs(args))

    def progress(t: float, t_end: float) -> None:
        if not args.quiet and sys.stderr.isatty():
            sys.stderr.write(f"\r{PROG}: flying, t = {t:5.1f} s ")
            sys.stderr.flush()

    result = fly(request, progress=progress)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"cannot create output directory {str(out_dir)!r}: {os_reason(exc)}") from None
    files = write_flight(result, out_dir)
    if not args.no_plots:
        try:
            from staghunt.plots.flight_files import write_flight_figures  # matplotlib only when drawing

            files += write_flight_figures(result, out_dir)
        except KeyboardInterrupt:
            raise
        except Exception as exc:  # figures are a by-product: the flight log stands
            say(f"{PROG}: warning: figures not written: {clip(one_line(exc))}")
    _report(result)
    print(f"wrote {len(files)} files to {out_dir}")
    return result.status.exit_code


def _link(args: argparse.Namespace, given: dict[str, float | None]) -> Any:
    """The link of the command line: the options given over the scenario's or events file's."""
    from staghunt.scenario import load_scenario
    from staghunt.scenario.dynamics import load_events

    try:
        base = load_events(args.events, load_scenario(args.source)).link if args.events else None
    except (ValueError, OSError):
        base = None  # check_flight reports what is wrong with the source or the events
    if base is None:
        try:
            base = load_scenario(args.source).dynamics.link
        except (ValueError, OSError):
            from staghunt.world.dynamic import Link

            base = Link()
    return replace(base, **{k: v for k, v in given.items() if v is not None})


def _is_inspection(args: argparse.Namespace) -> bool:
    """An inspection to fly: an inspection.json, objectives given, or a scenario with objectives."""
    src = str(args.source)
    if args.objectives is not None:
        return True
    if src.endswith(".json"):
        from staghunt.io.result_json import load_json_strict

        data = load_json_strict(src)
        return isinstance(data, dict) and data.get("format") == "staghunt-inspection"
    from staghunt.scenario import load_scenario

    scenario = load_scenario(src)
    return scenario.inspection is not None and bool(scenario.inspection.objectives)


def _report(result: Any) -> None:
    sc = result.scenario
    print(f"{sc.name} / seed {result.seed}: {len(result.times) / result.config.sim_rate:.1f} s of flight "
          f"simulated at {result.config.sim_rate:g} Hz in {result.wall_time_s:.1f} s")
    mode = "measured" if result.config.measured else f"fixed {float(result.config.latency) * 1000:.0f} ms"
    for r in result.replans:
        if r.status.value == "kept" and r.cause.value == "receding":
            continue  # a receding-horizon re-plan that changed nothing
        gaps = ", ".join(f"{g:.2%}" for g in r.nash_gaps) or "-"
        print(f"  t = {r.time:6.2f} s  {r.trigger}: {r.status.value}{' (late)' if r.late else ''}, "
              f"{r.latency_s * 1000:.0f} ms (deadline {r.deadline_s * 1000:.0f} ms), Nash gaps [{gaps}]"
              + (" certified" if r.certified else ""))
    lat = latency_summary(result.replans)
    if lat["replans"]:
        print(f"re-plans: {lat['replans']} (latency {mode}), p50 {lat['latency_p50_s'] * 1000:.0f} ms, p95 "
              f"{lat['latency_p95_s'] * 1000:.0f} ms, max {lat['latency_max_s'] * 1000:.0f} ms, "
              f"{lat['over_deadline']} over the deadline; {lat['certified']}/{lat['solved']} plans certified; "
              f"{result.stops} stop(s) to hover, {result.holds} hold(s) on board")
    print(f"tracking RMS {result.tracking_rms.max():.3f} m (max {result.tracking_max.max():.3f} m); "
          f"least separation {result.min_separation.min():.2f} m (limit {result.separation_limit.max():g}); "
          f"least clearance {result.min_clearance.min():.2f} m (required {result.required_clearance:g}); "
          f"link: {result.link.get('lost', 0)} of {result.link.get('sent', 0)} messages lost")
    names = result.uav_names
    for b in result.verdict.breaches[:5]:
        print(f"  {b.describe(names)}")
    print(f"status: {result.message}")
