"""``fly``: the paper's closed loop (its Fig. 1) in simulation.

Task execution (simulated multirotors and their controllers, :mod:`~staghunt.flight.vehicles`)
runs at ``sim_rate``; at every planner tick (``sensing.rate``) the planner receives every
UAV's measured position and velocity (with the configured noise), senses appeared obstacles
within range, predicts conflicts with the known motions within the horizon, and re-solves the
game when either happens (:mod:`~staghunt.flight.replan`). The flight is judged on the
simulated vehicles against the true world at each instant.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import Any, Callable

import numpy as np

from staghunt.analysis.certify import plan_from_result_data
from staghunt.api import PlanRequest, check_plan, plan
from staghunt.checks import check_inside_site
from staghunt.costs import CostModel
from staghunt.engine import Engine, side_by_side
from staghunt.flight.aside import start as start_worker
from staghunt.trajectory.quintic import Reference
from staghunt.flight.known import check_piece, swept_obstacles
from staghunt.flight.replan import FlyConfig, ReplanRecord, Replanner, offline_plan
from staghunt.safety.measure import moving_clearance, separations, static_clearance
from staghunt.flight.vehicles import DrydenGust, SimulatedTeam
from staghunt.inputs import check_waypoints
from staghunt.io.result_json import read_result
from staghunt.result import PlanResult
from staghunt.scenario import Scenario, load_scenario
from staghunt.scenario.dynamics import load_events
from staghunt.scenario.model import SolverSettings
from staghunt.world import Cylinder, Prism
from staghunt.world.dynamic import Dynamics

ARRIVAL_TOLERANCE = 1.0
"""A UAV has arrived once it stays within this distance (m) of its goal."""


class FlightStatus(str, Enum):
    """How an episode ended: ``ARRIVED`` every UAV at its goal with no collision and no
    separation breach; ``STOPPED`` the team stopped safely because no plan reached the goals
    (exit code 3); ``UNSAFE`` a collision or separation breach happened in the simulated
    flight (exit code 3)."""

    ARRIVED = "arrived"
    STOPPED = "stopped"
    UNSAFE = "unsafe"


@dataclass(frozen=True, eq=False)
class FlightResult:
    """A simulated closed-loop flight of ``N`` UAVs, sampled at ``T`` simulation steps.

    - ``times``: ``(T,)`` s after take-off; ``actual``, ``reference``: ``(N, T, 3)`` absolute
      site positions of the vehicles and of the references they track; ``velocity``: ``(N, T, 3)``.
    - ``replans``: one :class:`ReplanRecord` per re-plan.
    - ``min_separation``: ``(N,)`` least distance to a team-mate at the same instant;
      ``separation_limit``: ``(N,)`` ``d_s + 2 r``.
    - ``min_clearance``: ``(N,)`` least clearance to any obstacle where it truly was at that
      instant (static, appeared, moving); ``required_clearance``: the scenario's hard clearance.
    - ``tracking_rms``, ``tracking_max``: ``(N,)`` |actual - reference| (m).
    - ``arrival``: ``(N,)`` time each UAV arrived for good (``nan``: never);
      ``baseline_arrival``: when the plan without events arrives; ``extra_time``: the last
      arrival minus that.
    - ``stops``: synchronised stops to hover; ``plan_*``: the offline plan before take-off.
    """

    scenario: Scenario
    dynamics: Dynamics
    config: FlyConfig
    seed: int
    status: FlightStatus
    message: str
    times: np.ndarray
    actual: np.ndarray
    velocity: np.ndarray
    reference: np.ndarray
    replans: tuple[ReplanRecord, ...]
    min_separation: np.ndarray
    separation_limit: np.ndarray
    min_clearance: np.ndarray
    required_clearance: float
    tracking_rms: np.ndarray
    tracking_max: np.ndarray
    arrival: np.ndarray
    baseline_arrival: float
    stops: int
    plan_waypoints: np.ndarray
    plan_windows: tuple[tuple[str, float, float], ...]
    wall_time_s: float
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def extra_time(self) -> float:
        return float(np.max(self.arrival) - self.baseline_arrival) if np.all(np.isfinite(self.arrival)) else math.inf

    @property
    def safe(self) -> bool:
        return self.status is not FlightStatus.UNSAFE

    @property
    def uav_names(self) -> list[str]:
        return [u.name for u in self.scenario.team]


class FlightInputError(ValueError):
    """An events or flight input that cannot be flown (one line, names the entry at fault)."""


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
        mc, which = moving_clearance(dyn, start, np.array([0.0]), r)
        if np.any(mc < 0):
            n = int(np.argmin(mc[:, 0]))
            raise FlightInputError(f"a moving obstacle covers {names[n]}'s start at take-off")


def _true_shapes(scenario: Scenario, dyn: Dynamics, t: float) -> tuple[tuple[Cylinder, ...], tuple[Prism, ...]]:
    gone = dyn.removed(t)
    cyl = [c for c in scenario.world.cylinders if c.name not in gone]
    prm = [p for p in scenario.world.prisms if p.name not in gone]
    for e in dyn.events:
        if e.kind == "appear" and e.time <= t and e.name not in gone:
            (cyl if isinstance(e.shape, Cylinder) else prm).append(e.shape)  # type: ignore[arg-type]
    return tuple(cyl), tuple(prm)


def _horizontal_distance(shape: Cylinder | Prism, xy: np.ndarray) -> np.ndarray:
    """``(N,)`` horizontal distance from points ``(N, 2)`` to the shape's outline (0 inside)."""
    pos = np.column_stack([xy, np.zeros(len(xy))])[:, None]
    if isinstance(shape, Cylinder):
        return np.maximum(static_clearance((shape,), (), pos, np.zeros(len(xy)))[:, 0], 0.0)
    flat = replace(shape, base=-np.inf, top=np.inf)
    return static_clearance((), (flat,), pos, np.zeros(len(xy)))[:, 0]


def simulate(scenario: Scenario, dyn: Dynamics, ref0: Reference, config: FlyConfig, engine: Any,
             rng: np.random.Generator, progress: Callable[[float, float], None] | None = None,
             certify_search: SolverSettings | None = None
             ) -> tuple[dict[str, Any], list[ReplanRecord], int, str, str]:
    """Fly ``ref0`` in closed loop. Returns the sampled flight, the re-plans, the number of
    stops, the ending (``"arrived"`` / ``"stopped"``) and a message. ``certify_search``: the
    re-plans' certificate settings, checked (:class:`~staghunt.flight.replan.Replanner`)."""
    replan_rng, noise_rng, wind_rng = rng.spawn(3)
    dt = 1.0 / config.sim_rate
    per_tick = max(1, round(config.sim_rate / dyn.sensing.rate))
    starts = ref0.state(np.array([0.0]))[0][:, 0]
    mean_alt = float(np.mean(starts[:, 2] - scenario.world.terrain.height(starts[:, 0], starts[:, 1])))
    heading = math.radians(config.wind_heading_deg)
    wind = None
    if config.wind > 0:
        wind = DrydenGust(config.wind * np.array([math.cos(heading), math.sin(heading), 0.0]),
                          mean_alt, dt, wind_rng)
    team = SimulatedTeam(starts, dt, wind, scenario.vehicle, [u.radius for u in scenario.team])
    planner = Replanner(scenario, dyn, config, engine, replan_rng, certify_search)
    ref = ref0
    pending = [e for e in dyn.events if e.kind == "appear"]
    stops, stopped_at, retries = 0, -1.0, 0
    ending, message = "arrived", ""
    t_end = ref.arrival + config.hold
    t_cap = ref0.arrival * 4 + 120.0
    rows_t: list[float] = []
    rows_x: list[np.ndarray] = []
    rows_v: list[np.ndarray] = []
    rows_r: list[np.ndarray] = []
    k = 0
    while True:
        t = k * dt
        if k % per_tick == 0:
            # The planner's tick: measured states, sensing, predicted conflicts.
            meas = team.positions()
            meas_v = team.velocities()
            if dyn.sensing.position_noise > 0:
                meas = meas + noise_rng.normal(0.0, dyn.sensing.position_noise, meas.shape)
            if dyn.sensing.velocity_noise > 0:
                meas_v = meas_v + noise_rng.normal(0.0, dyn.sensing.velocity_noise, meas_v.shape)
            trigger = ""
            for e in list(pending):
                if e.time <= t and e.shape is not None:
                    d = _horizontal_distance(e.shape, meas[:, :2])
                    if np.min(d) <= dyn.sensing.range:
                        planner.known.sensed[e.name] = e.shape
                        pending.remove(e)
                        trigger = trigger or f"sensed {e.name} at {np.min(d):.1f} m"
            for e in dyn.events:
                if e.kind == "disappear" and e.time <= t and e.name not in planner.known.removed:
                    planner.known.removed.add(e.name)
            windows: list[tuple[str, float, float]] = []
            if not trigger and dyn.known_motion:
                _, found, _ = check_piece(scenario, planner.known, dyn, ref, t, t + config.horizon)
                if found:
                    windows = [(n, max(t, a - config.window_pad), b + config.window_pad) for n, a, b in found]
                    trigger = "predicted conflict with " + ", ".join(sorted({w[0] for w in found}))
            if (not trigger and stopped_at >= 0 and ending == "arrived"
                    and t >= stopped_at + config.retry_interval * (retries + 1)):
                trigger = "retry after stop"
            if trigger:
                scale = config.stop_budget_factor if stopped_at >= 0 else 1
                if trigger == "retry after stop":
                    retries += 1
                ref, rec = planner.solve(ref, t, trigger, scale, windows, (meas, meas_v))
                if rec.stopped and rec.solved:
                    stops += 1
                if rec.status == "sidestep":
                    pass  # still holding, elsewhere: the retries go on
                elif not rec.solved:
                    if stopped_at < 0:
                        stops += 1
                        stopped_at = t
                    elif retries >= config.retries_after_stop:
                        ending = "stopped"
                        message = (f"goal unreachable: after {retries} re-plans from the hover no plan "
                                   f"passes ({'; '.join(rec.problems[:2]) or 'no feasible plan'})")
                        t_end = t + config.hold
                else:
                    stopped_at, retries = -1.0, 0
                if ending == "arrived":
                    t_end = ref.arrival + config.hold
                    if stopped_at >= 0:  # hover long enough for every retry
                        t_end = max(t_end, stopped_at + config.retry_interval * (config.retries_after_stop + 1)
                                    + config.hold)
        if t > t_end or t > t_cap:
            break
        s = ref.state(np.array([t]))[:, :, 0]  # (4, N, 3)
        rows_t.append(t)
        rows_x.append(team.positions())
        rows_v.append(team.velocities())
        rows_r.append(s[0])
        team.step(t, s)
        k += 1
        if progress is not None and k % int(config.sim_rate) == 0:
            progress(t, t_end)
    if ending == "arrived" and stopped_at >= 0:
        ending, message = "stopped", "the team stopped to hover and never resumed"
    flight = {"times": np.array(rows_t), "actual": np.stack(rows_x, axis=1),
              "velocity": np.stack(rows_v, axis=1), "reference": np.stack(rows_r, axis=1)}
    return flight, planner.records, stops, ending, message


def _baseline(ref: Reference) -> float:
    """When the plan flown without events arrives (by :func:`arrival_times` on its reference)."""
    t = np.arange(0.0, ref.arrival + 0.01, 0.01)
    pos = ref.state(t)[0]
    return float(np.nanmax(arrival_times(t, pos, pos[:, -1])))


def judge(scenario: Scenario, dyn: Dynamics, flight: dict[str, Any]) -> dict[str, np.ndarray]:
    """Separation, clearance (the true world at each instant), tracking and arrival of a flight."""
    t, x, ref = flight["times"], flight["actual"], flight["reference"]
    r = np.array([u.radius for u in scenario.team])
    clear = np.full(x.shape[:2], np.inf)
    # Static and appeared obstacles: constant between events.
    cuts = sorted({0.0, *[e.time for e in dyn.events]})
    for i, t0 in enumerate(cuts):
        t1 = cuts[i + 1] if i + 1 < len(cuts) else np.inf
        sel = (t >= t0) & (t < t1)
        if sel.any():
            cyl, prm = _true_shapes(scenario, dyn, t0)
            clear[:, sel] = static_clearance(cyl, prm, x[:, sel], r)
    if dyn.known_motion:
        clear = np.minimum(clear, moving_clearance(dyn, x, t, r)[0])
    err = np.linalg.norm(x - ref, axis=-1)
    goals = scenario.goals()
    goals[:, 2] = scenario.world.terrain.absolute(goals[:, 0], goals[:, 1], goals[:, 2])
    arrival = arrival_times(t, x, goals)
    return {
        "min_separation": separations(x).min(axis=1),
        "min_clearance": clear.min(axis=1),
        "clearance": clear,
        "tracking_rms": np.sqrt(np.mean(err**2, axis=1)),
        "tracking_max": err.max(axis=1),
        "arrival": arrival,
    }


def plan_around(request: PlanRequest, dyn: Dynamics, waypoints: np.ndarray | None, config: FlyConfig
                ) -> tuple[np.ndarray, Reference, tuple[tuple[str, float, float], ...]]:
    """The offline plan made sound against the known motions (docs/model.md, section 8): plan
    the request's scenario (:func:`staghunt.api.check_plan`: the method, seed, settings and
    engine, checked once) unless ``waypoints`` ``(N, K, 3)`` are given, time it, and re-plan
    with the swept stand-ins of its conflict windows until it passes the in-time check. Returns
    the waypoints, the timed reference and the windows; raises :class:`FlightInputError` if a
    conflict remains."""
    scenario = request.scenario

    def solve(windows: list[tuple[str, float, float]]) -> np.ndarray:
        c2, p2 = swept_obstacles(scenario, dyn, windows)
        world = replace(scenario.world, cylinders=scenario.world.cylinders + c2,
                        prisms=scenario.world.prisms + p2)
        return np.array(plan(request.with_scenario(replace(scenario, world=world))).waypoints)

    wp = solve([]) if waypoints is None else np.asarray(waypoints, dtype=float)
    wp, piece, windows, problems = offline_plan(scenario, dyn, wp, config, solve)
    if problems:
        raise FlightInputError("the plan cannot be flown safely: " + "; ".join(problems[:2]))
    return wp, Reference((piece,)), tuple(windows)


def arrival_times(times: np.ndarray, pos: np.ndarray, goals: np.ndarray) -> np.ndarray:
    """``(N,)`` the time from which each of ``pos`` ``(N, T, 3)`` stays within
    :data:`ARRIVAL_TOLERANCE` of its goal ``(N, 3)`` (``nan``: it never does)."""
    away = np.linalg.norm(pos - goals[:, None], axis=-1) > ARRIVAL_TOLERANCE  # (N, T)
    last = np.where(away.any(axis=1), (away.shape[1] - 1) - np.argmax(away[:, ::-1], axis=1), -1)
    return np.array([times[i + 1] if i + 1 < len(times) else np.nan for i in last])


def _source(source: Any) -> tuple[Scenario, np.ndarray | None, SolverSettings | None]:
    """A scenario (object, built-in name or TOML path), a :class:`~staghunt.PlanResult`, or a
    ``result.json`` path -> the scenario, the plan's waypoints (``None``: plan first) and its
    settings."""
    if isinstance(source, Scenario):
        return source, None, None
    if isinstance(source, PlanResult):
        return source.scenario, np.array(source.waypoints), source.settings
    text = os.fspath(source)
    if text.lower().endswith(".json"):
        return plan_from_result_data(read_result(text), text)
    return load_scenario(text), None, None


@dataclass(frozen=True, eq=False)
class FlightRequest:
    """A flight that :func:`check_flight` has checked: the offline plan's run (``plan``, a
    :class:`~staghunt.api.PlanRequest` whose scenario carries the flight's changing world), the
    plan to fly (``waypoints`` ``(N, K, 3)``; ``None``: planned first), the flight settings
    and the settings of the re-plans' certificate searches. :func:`fly` flies it without
    checking anything again."""

    plan: PlanRequest
    waypoints: np.ndarray | None
    config: FlyConfig
    certify_search: SolverSettings

    @property
    def scenario(self) -> Scenario:
        return self.plan.scenario


def check_flight(
    source: Any,
    *,
    waypoints: np.ndarray | None = None,
    events: Any = None,
    seed: int = 0,
    config: FlyConfig | None = None,
    settings: SolverSettings | None = None,
    budget: Mapping[str, int | None] | None = None,
    engine: "str | Engine" = "auto",
    threads: int | None = None,
    warn: Callable[[str], None] | None = None,
) -> FlightRequest:
    """Every check a flight needs, made once, before any plan or simulation: the source (loaded
    once), the plan to fly, the events, the flight settings (:meth:`FlyConfig.check`), the
    offline plan's run (:func:`staghunt.api.check_plan`: seed, settings, engine, memory) and the
    re-plans' certificate (:meth:`FlyConfig.certify_search`).

    ``source``: a :class:`Scenario`, a built-in name or TOML path (planned first with the
    default method at ``settings``, default the scenario's), a :class:`~staghunt.PlanResult` or
    a ``result.json`` path (its plan is flown). ``waypoints``: ``(N, K, 3)`` ``(x, y, h)`` to fly
    instead of the source's plan. ``events``: a path to an events file (added to the scenario's
    changing world) or a :class:`~staghunt.world.dynamic.Dynamics` (replacing it); default the
    scenario's own. ``seed``: one generator seeds the offline plan, the re-plans, the sensor
    noise and the wind, so the same inputs and seed give the same flight. ``budget``:
    ``particles``, ``iterations``, ``waypoints``, ``starts`` replacing those of the plan's
    settings (``None`` values: kept). ``engine``, ``threads``: those of :func:`staghunt.plan`.
    ``warn`` receives the memory warning.

    Returns the :class:`FlightRequest`; raises ``ValueError`` (a
    :class:`~staghunt.scenario.ScenarioError`, a :class:`~staghunt.errors.FieldError` naming the
    argument at fault, or a :class:`FlightInputError`), one line."""
    config = config or FlyConfig()
    config.check()
    scenario, source_waypoints, plan_settings = _source(source)
    if waypoints is not None:
        waypoints = check_waypoints(waypoints, scenario.n_uavs)
    elif source_waypoints is not None:
        waypoints = source_waypoints
    if waypoints is not None:
        check_inside_site(CostModel.from_scenario(scenario), waypoints, [u.name for u in scenario.team],
                          os.fspath(source) if isinstance(source, (str, os.PathLike)) else None)
    if events is None:
        dyn = scenario.dynamics
    elif isinstance(events, Dynamics):
        dyn = events
    else:
        dyn = load_events(events, scenario)
    task_events = [e for e in dyn.events if e.kind in ("uav_lost", "objective")]
    if task_events:  # the task layer's events: only an inspection's flight has work to re-allocate
        raise FlightInputError(f"events: a {task_events[0].kind} event needs an inspection to re-allocate "
                               "(give objectives: --objectives FILE)")
    scenario = replace(scenario, dynamics=dyn)
    settings = (settings or plan_settings or scenario.solver).with_(**(budget or {}))
    request = check_plan(scenario, "game", seed, settings, engine, threads, warn=warn)
    return FlightRequest(request, waypoints, config, config.certify_search(scenario))


def fly(source: Any, *, progress: Callable[[float, float], None] | None = None, **options: Any) -> FlightResult:
    """Fly a team in closed loop with re-planning; returns a frozen :class:`FlightResult`.

    ``source`` and ``options``: the arguments of :func:`check_flight` (``waypoints``,
    ``events``, ``seed``, ``config``, ``settings``, ``budget``, ``engine``, ``threads``), which
    checks them first; or a :class:`FlightRequest` it returned, flown as checked (no
    ``options``). The plan is first made sound against the known motions
    (:func:`~staghunt.flight.replan.offline_plan`), then flown; ``progress(t, t_end)`` follows
    the simulated time. Raises ``ValueError`` (see :func:`check_flight`; one line naming what
    is at fault) for inputs that cannot be flown, before any simulation."""
    if isinstance(source, FlightRequest):
        if options:
            raise TypeError(f"a checked FlightRequest is flown as it is; got options {sorted(options)}")
        request = source
    else:
        request = check_flight(source, **options)
    scenario, config, seed = request.scenario, request.config, request.plan.seed
    dyn = scenario.dynamics
    waypoints = request.waypoints
    resolved = request.plan.engine
    prepare = getattr(resolved, "prepare", None)
    compile_s = float(prepare()) if callable(prepare) else 0.0
    if side_by_side(resolved)[1] > 1:
        start_worker()  # the re-plans' second process loads its kernels during the offline plan
    wall0 = time.perf_counter()
    rng = np.random.default_rng(seed)

    planned_here = waypoints is None
    wp, ref0, windows = plan_around(request.plan, dyn, waypoints, config)
    check_events_against_plan(scenario, dyn, ref0)
    flight, replans, stops, ending, message = simulate(scenario, dyn, ref0, config, resolved,
                                                       rng.spawn(1)[0], progress, request.certify_search)
    m = judge(scenario, dyn, flight)
    r = np.array([u.radius for u in scenario.team])
    limit = scenario.costs.safe_distance + 2 * r
    breach = bool(np.any(m["min_separation"] <= limit)) or bool(np.any(m["min_clearance"] < 0))
    if breach:
        status = FlightStatus.UNSAFE
        message = (f"unsafe flight: least separation {m['min_separation'].min():.2f} m (limit "
                   f"{limit.max():g}), least clearance {m['min_clearance'].min():.2f} m")
    elif ending == "stopped":
        status = FlightStatus.STOPPED
    else:
        status = FlightStatus.ARRIVED
        message = (f"arrived: least separation {m['min_separation'].min():.2f} m, least clearance "
                   f"{m['min_clearance'].min():.2f} m, {len(replans)} re-plans, {stops} stops")
    frozen = {k: v for k, v in flight.items()}
    for a in (*frozen.values(), *m.values()):
        a.setflags(write=False)
    return FlightResult(
        scenario=scenario, dynamics=dyn, config=config, seed=seed, status=status, message=message,
        times=frozen["times"], actual=frozen["actual"], velocity=frozen["velocity"],
        reference=frozen["reference"], replans=tuple(replans),
        min_separation=m["min_separation"], separation_limit=limit,
        min_clearance=m["min_clearance"], required_clearance=float(scenario.costs.min_clearance),
        tracking_rms=m["tracking_rms"], tracking_max=m["tracking_max"], arrival=m["arrival"],
        baseline_arrival=_baseline(ref0), stops=stops, plan_waypoints=wp,
        plan_windows=tuple(windows), wall_time_s=time.perf_counter() - wall0,
        details={"compile_time_s": compile_s, "engine": resolved.name,
                 "planned_offline": planned_here, "clearance": m["clearance"]},
    )
