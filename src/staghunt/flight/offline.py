"""The plan a flight takes off with, made sound against the known motions before take-off
(docs/model.md, section 8), and the events checked against it."""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Callable

import numpy as np

from staghunt.api import PlanRequest, plan
from staghunt.costs import to_absolute
from staghunt.flight.config import FlyConfig
from staghunt.flight.known import CURVE_SLACK, Acceptance, KnownWorld, covers, game_margins, swept_obstacles
from staghunt.safety import Margins
from staghunt.safety.measure import moving_clearance, static_clearance
from staghunt.scenario import Scenario
from staghunt.trajectory.quintic import Piece, Reference, timed_path
from staghunt.world import Cylinder, Prism
from staghunt.world.dynamic import Dynamics

MAX_DELAY_S = 60
"""Longest take-off delay (s) tried to let a known motion pass."""


class FlightInputError(ValueError):
    """An events or flight input that cannot be flown (one line, names the entry at fault)."""


def offline_acceptance(scenario: Scenario, dyn: Dynamics, config: FlyConfig) -> tuple[Acceptance, Margins, float]:
    """The take-off plan's acceptance: the planner's polyline keeps the required clearance and
    its timed curve stays within :data:`~staghunt.flight.known.CURVE_SLACK` of it, so the fixed
    obstacles are judged at the required margins less that slack; the known motions at the
    required clearance plus the tracking allowance, as in flight. Returns the acceptance, its
    margins and the motions' extra metres."""
    acc = Acceptance(scenario, KnownWorld(scenario), dyn, config.allowance)
    required = Margins.required(scenario)
    margins = replace(required, clearance=max(0.0, required.clearance - CURVE_SLACK))
    return acc, margins, CURVE_SLACK + config.allowance


def takeoff_scenario(scenario: Scenario, config: FlyConfig) -> Scenario:
    """The scenario a flight solves its own take-off plan on: the clearance and ``d_s`` its
    re-plans' game keeps (:func:`~staghunt.flight.known.game_margins` of the required margins
    grown by the tracking allowance), so that vehicles tracking the plan keep the required
    margins. The paper's plans lie on their constraints: solved at the required
    margins themselves, the timed curve of 87 of the 100 scenario-2 episodes (as first built) of
    ``benchmarks/replan.py`` passed within 5 cm of the required clearance, and tracking errors
    made breaches (benchmarks/JOURNAL.md, "Closed loop: the take-off plan's margins"). Where a
    start or a goal is closer than that to an obstacle or to a team-mate, the margin is relaxed
    to what it has (never below the required one)."""
    required = Margins.required(scenario)
    need, d_s = game_margins(required.grown(config.allowance))
    g = scenario.world.terrain
    ends = np.concatenate([to_absolute(g, scenario.starts()[:, None]), to_absolute(g, scenario.goals()[:, None])],
                          axis=1)  # (N, 2, 3)
    r = np.array([u.radius for u in scenario.team])
    have = float(static_clearance(scenario.world.cylinders, scenario.world.prisms, ends, r).min(initial=np.inf))
    clearance = max(required.clearance, min(need, have))
    d = np.linalg.norm(ends[:, None] - ends[None], axis=-1) - (r[:, None] + r[None, :])[..., None]  # (N, N, 2)
    d[np.arange(len(r)), np.arange(len(r))] = np.inf
    separation = max(required.separation, min(d_s, float(d.min(initial=np.inf)) - 1e-6))
    return replace(scenario, costs=replace(scenario.costs, min_clearance=clearance, safe_distance=separation))


def offline_plan(scenario: Scenario, dyn: Dynamics, waypoints: np.ndarray, config: FlyConfig,
                 solve: Callable[[list[tuple[str, float, float]]], np.ndarray]
                 ) -> tuple[np.ndarray, Piece, list[tuple[str, float, float]], list[str]]:
    """Make a plan ``(N, K, 3)`` sound against the known motions before take-off: time it, check
    it in time (:func:`offline_acceptance`), and while it conflicts with a motion re-plan
    (``solve(windows) -> (N, K, 3)``) with the swept volumes of the conflict windows. If that
    does not remove a conflict (a motion over a goal, or one the routes cannot avoid), the
    take-off is delayed, by whole seconds up to :data:`MAX_DELAY_S`, until the first plan
    without the swept stand-ins (or the last one) passes. Returns the plan, its timed piece
    (starting at the take-off delay), the windows used and the problems left (empty: sound)."""
    acc, margins, extra = offline_acceptance(scenario, dyn, config)
    names = [u.name for u in scenario.team]
    windows: list[tuple[str, float, float]] = []
    problems: list[str] = []
    start = to_absolute(scenario.world.terrain, scenario.starts()[:, None])
    goal = to_absolute(scenario.world.terrain, scenario.goals()[:, None])

    def timed(wp: np.ndarray, delay: float) -> Piece:
        return timed_path(np.concatenate([start, to_absolute(scenario.world.terrain, wp), goal], axis=1), delay,
                          scenario.vehicle)

    def check(piece: Piece) -> Any:
        return acc.check(Reference((piece,)), 0.0, piece.t1, margins, motion_extra=extra)

    tried = [np.asarray(waypoints, dtype=float)]
    for _ in range(config.attempts + 1):
        piece = timed(waypoints, 0.0)
        verdict = check(piece)
        problems = verdict.problems(names)
        if not problems:
            return waypoints, piece, windows, []
        new = [w for w in verdict.windows if not any(covers(o, w) for o in windows)]
        if not new:
            break
        windows.extend((n, max(0.0, a - config.window_pad), b + config.window_pad) for n, a, b in new)
        waypoints = solve(windows)
        tried.append(waypoints)
    for delay in np.arange(1.0, MAX_DELAY_S + 1.0):
        for wp in (tried[0], tried[-1]):
            piece = timed(wp, float(delay))
            if check(piece).safe:
                return wp, piece, windows, []
    return waypoints, timed(waypoints, 0.0), windows, problems


def plan_around(request: PlanRequest, dyn: Dynamics, waypoints: np.ndarray | None, config: FlyConfig
                ) -> tuple[np.ndarray, Reference, tuple[tuple[str, float, float], ...], str]:
    """The offline plan made sound against the known motions: plan the request's scenario with
    the flight's margins (:func:`takeoff_scenario`; the method, seed, settings and engine of
    :func:`staghunt.api.check_plan`, checked once) unless ``waypoints`` ``(N, K, 3)`` are given
    (flown as given), time it, and re-plan with the swept stand-ins of its conflict windows
    until it passes (:func:`offline_plan`). If no plan at the flight's margins passes (a truck
    that parks where the route round its swept volume goes), the same again at the required
    margins. Returns the waypoints, the timed reference, the windows and which margins the plan
    was solved with (:data:`PLAN_MARGINS`); raises :class:`FlightInputError` if a conflict
    remains."""
    scenario = request.scenario

    def solver(margins: Scenario) -> Callable[[list[tuple[str, float, float]]], np.ndarray]:
        def solve(windows: list[tuple[str, float, float]]) -> np.ndarray:
            c2, p2 = swept_obstacles(scenario, dyn, windows)
            world = replace(scenario.world, cylinders=scenario.world.cylinders + c2,
                            prisms=scenario.world.prisms + p2)
            return np.array(plan(request.with_scenario(replace(margins, world=world))).waypoints)
        return solve

    grown = takeoff_scenario(scenario, config)
    tries = [("flight", grown)] + ([("required", scenario)] if grown.costs != scenario.costs else [])
    for label, margins in tries:
        solve = solver(margins)
        wp = solve([]) if waypoints is None else np.asarray(waypoints, dtype=float)
        wp, piece, windows, problems = offline_plan(scenario, dyn, wp, config, solve)
        if not problems:
            return wp, Reference((piece,)), tuple(windows), "given" if waypoints is not None and not windows else label
    raise FlightInputError("the plan cannot be flown safely: " + "; ".join(problems[:2]))


PLAN_MARGINS = ("flight", "required", "given")
"""Which margins the plan a flight takes off with was solved with: ``flight`` (the required ones
grown by the tracking allowance and the curve's slack, :func:`takeoff_scenario`), ``required``
(no plan kept those round the known motions), ``given`` (the plan given to the flight, flown as
given)."""


def check_events_against_plan(scenario: Scenario, dyn: Dynamics, ref: Reference) -> None:
    """Refuse, before any simulation, an appearing obstacle that swallows a UAV at the moment it
    appears (at its planned position), or a moving obstacle on a UAV's start at take-off."""
    r = np.array([u.radius for u in scenario.team])
    names = [u.name for u in scenario.team]
    for i, e in enumerate(dyn.events):
        if e.kind != "appear" or e.shape is None:
            continue
        pos = ref.state(np.array([e.time]))[0]  # (N, 1, 3)
        cyl = (e.shape,) if isinstance(e.shape, Cylinder) else ()
        prm = (e.shape,) if isinstance(e.shape, Prism) else ()
        c = static_clearance(cyl, prm, pos, r)[:, 0]
        if np.any(c < 0):
            n = int(np.argmin(c))
            raise FlightInputError(
                f"events[{i}] ({e.name}): appears at t = {e.time:g} s on top of {names[n]} "
                f"(its planned position is {-c[n]:.2f} m inside the obstacle); an obstacle cannot "
                "appear where a UAV is")
    if dyn.known_motion:
        start = ref.state(np.array([0.0]))[0]
        mc, _ = moving_clearance(dyn, start, np.array([0.0]), r)
        if np.any(mc < 0):
            n = int(np.argmin(mc[:, 0]))
            raise FlightInputError(f"a moving obstacle covers {names[n]}'s start at take-off")
