"""``fly``: the paper's closed loop (its Fig. 1) in simulation, wired from small parts.

The parts (docs/model.md, section 8): the vehicles (:mod:`~staghunt.flight.vehicles`, stepped
at ``sim_rate``), their sensor (:mod:`~staghunt.flight.sensor`), what each UAV decides on its
own (:mod:`~staghunt.flight.onboard`: the plan it flies, holds, its reflex), the radio
(:mod:`~staghunt.flight.link`), and the ground station (:mod:`~staghunt.flight.station`, the
planner: ``tick(t, observations)`` at the sensor rate, re-planning with
:mod:`~staghunt.flight.replan`). :func:`simulate` runs one step after the other: messages
arrive, the sensor measures and the UAVs report, the station ticks and sends, the UAVs
decide, the vehicles fly their references. The flight is judged on the simulated vehicles
against the true world at each step (:mod:`~staghunt.flight.result`). A camera or a task
layer is one more part wired here.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Callable

import numpy as np

from staghunt.analysis.certify import plan_from_result_data
from staghunt.api import PlanRequest, check_plan
from staghunt.checks import check_inside_site
from staghunt.costs import CostModel
from staghunt.engine import Engine, side_by_side
from staghunt.flight import aside
from staghunt.flight.config import FlyConfig
from staghunt.flight.link import GROUND, Outage, RadioLink
from staghunt.flight.offline import FlightInputError, check_events_against_plan, plan_around
from staghunt.flight.onboard import Onboard, OnboardTeam
from staghunt.flight.replan import PRELOAD, Replanner
from staghunt.flight.result import FlightResult, baseline_arrival, verdict_of
from staghunt.flight.sensor import Sensor
from staghunt.flight.station import GroundStation
from staghunt.flight.vehicles import DrydenGust, SimulatedTeam
from staghunt.inputs import check_waypoints
from staghunt.io.result_json import read_result
from staghunt.result import PlanResult
from staghunt.scenario import Scenario, load_scenario
from staghunt.scenario.dynamics import load_events
from staghunt.scenario.model import SolverSettings
from staghunt.trajectory.quintic import Reference
from staghunt.trajectory.team import Track, end_time
from staghunt.world.dynamic import Dynamics


@dataclass(frozen=True, eq=False)
class Parts:
    """The parts of one flight, wired by :func:`simulate`."""

    team: SimulatedTeam
    sensor: Sensor
    radio: RadioLink
    onboard: OnboardTeam
    station: GroundStation


def build(scenario: Scenario, dyn: Dynamics, ref0: Reference, config: FlyConfig, engine: Engine,
          rng: np.random.Generator, certify_search: SolverSettings | None = None,
          outages: tuple[Outage, ...] = ()) -> Parts:
    """The parts of a flight of ``ref0``, each with its own generator drawn from ``rng``."""
    replan_rng, noise_rng, wind_rng, link_rng = rng.spawn(4)
    dt = 1.0 / config.sim_rate
    starts = ref0.state(np.array([0.0]))[0][:, 0]
    ground = scenario.world.terrain.height(starts[:, 0], starts[:, 1])
    mean_alt = float(np.mean(starts[:, 2] - ground))
    heading = math.radians(config.wind_heading_deg)
    wind = None
    if config.wind > 0:
        wind = DrydenGust(config.wind * np.array([math.cos(heading), math.sin(heading), 0.0]), mean_alt, dt, wind_rng)
    radio = RadioLink(config.link or dyn.link, link_rng, outages)
    replanner = Replanner(scenario, dyn, config, engine, replan_rng, certify_search)
    station = GroundStation(replanner, dyn, config, ref0, dt, radio.worst_delay)
    radii = np.array([u.radius for u in scenario.team])
    members = [Onboard(n, Track(((ref0.pieces[0].t0, ref0, n),)), scenario.vehicle, config.plan_timeout,
                       config.reflex_latency, scenario.costs.safe_distance, scenario.costs.min_clearance, radii)
               for n in range(scenario.n_uavs)]
    team = SimulatedTeam(starts, dt, wind, scenario.vehicle, [u.radius for u in scenario.team])
    return Parts(team, Sensor(dyn, [u.name for u in scenario.team], noise_rng,
                                radii + scenario.costs.min_clearance), radio,
                 OnboardTeam(members), station)


def _arrived(parts: Parts, goals: np.ndarray) -> float:
    """When every UAV's track ends at its goal (``inf``: one ends elsewhere, holding)."""
    ends = []
    for m in parts.onboard.members:
        end = end_time(m.track)
        if float(np.linalg.norm(m.track.state(np.array([end]))[0][0, 0] - goals[m.n])) > 1.0:
            return math.inf
        ends.append(end)
    return max(ends)


def simulate(scenario: Scenario, dyn: Dynamics, ref0: Reference, config: FlyConfig, engine: Engine,
             rng: np.random.Generator, progress: Callable[[float, float], None] | None = None,
             certify_search: SolverSettings | None = None, outages: tuple[Outage, ...] = ()
             ) -> tuple[dict[str, Any], Parts]:
    """Fly ``ref0`` in closed loop (module docstring). Returns the sampled flight (``times``
    ``(T,)``; ``actual``, ``velocity``, ``reference`` ``(N, T, 3)``) and the parts as they
    ended (the station holds the re-plans, the stops, the ending)."""
    parts = build(scenario, dyn, ref0, config, engine, rng, certify_search, outages)
    team, sensor, radio, onboard, station = parts.team, parts.sensor, parts.radio, parts.onboard, parts.station
    members = onboard.members
    dt = 1.0 / config.sim_rate
    per_tick = max(1, round(config.sim_rate / dyn.sensing.rate))
    goals = scenario.goals()
    goals[:, 2] = scenario.world.terrain.absolute(goals[:, 0], goals[:, 1], goals[:, 2])
    t_cap = ref0.arrival * 4 + 120.0
    inbox: list[Any] = []
    rows_t: list[float] = []
    rows_x: list[np.ndarray] = []
    rows_v: list[np.ndarray] = []
    rows_r: list[np.ndarray] = []
    t_end = ref0.arrival + config.hold
    k = 0
    while True:
        t = k * dt
        pos, vel = team.positions(), team.velocities()
        acks: list[Any] = []
        for dst, message in radio.deliver(t):
            if dst == GROUND:
                inbox.append(message)
            else:
                members[dst].receive(t, message, pos[dst], acks)
        for a in acks:
            radio.send(t, a.uav, GROUND, a)
        if k % per_tick == 0:
            seen = sensor.detect(t, pos, onboard.course)
            meas_p, meas_v = sensor.measure(pos, vel)
            for m in members:
                m.seen = seen[m.n]
                radio.send(t, m.n, GROUND, m.telemetry(t, meas_p[m.n], meas_v[m.n]))
                for j in range(len(members)):
                    if j != m.n:
                        radio.send(t, m.n, j, m.beacon(t, meas_p[m.n]))
            for dst, message in station.tick(t, inbox):
                radio.send(t, GROUND, dst, message)
            inbox = []
            done = _arrived(parts, goals)
            t_end = max(done + config.hold, station.waiting(t)) if station.gave_up is None else station.waiting(t)
        for dst, message in station.release(t):
            radio.send(t, GROUND, dst, message)
        for m in members:
            m.step(t, dt)
            m.reflex(t)
        if t > t_end or t > t_cap:
            break
        ref = onboard.reference(t)
        rows_t.append(t)
        rows_x.append(pos)
        rows_v.append(vel)
        rows_r.append(ref[0])
        team.step(t, ref)
        k += 1
        if progress is not None and k % int(config.sim_rate) == 0:
            progress(t, t_end)
    flight = {"times": np.array(rows_t), "actual": np.stack(rows_x, axis=1),
              "velocity": np.stack(rows_v, axis=1), "reference": np.stack(rows_r, axis=1)}
    return flight, parts


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
    names = [u.name for u in scenario.team]
    for e in dyn.events:
        g = e.trigger
        if g is not None and ((g.uav is not None and g.uav not in names)
                              or not (0 <= g.within < math.inf and 0 <= g.lead < math.inf and g.within + g.lead > 0)):
            raise FlightInputError(f"events: {e.name}'s trigger needs no UAV or one of the team ({', '.join(names)}), "
                                   f"and a distance (m) or a lead (s) > 0, both finite; got {g.uav!r} within "
                                   f"{g.within!r}, lead {g.lead!r}")
    if config.link is not None:
        dyn = replace(dyn, link=config.link)
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
    (:func:`~staghunt.flight.offline.offline_plan`), then flown; ``progress(t, t_end)`` follows
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
    compile_s = float(resolved.prepare())
    if side_by_side(resolved)[1] > 1:
        aside.start(PRELOAD)  # the re-plans' second process loads its kernels during the offline plan
    wall0 = time.perf_counter()
    rng = np.random.default_rng(seed)

    planned_here = waypoints is None
    wp, ref0, windows, plan_margins = plan_around(request.plan, dyn, waypoints, config)
    check_events_against_plan(scenario, dyn, ref0)
    flight, parts = simulate(scenario, dyn, ref0, config, resolved, rng.spawn(1)[0], progress,
                             request.certify_search, config.outages)
    station = parts.station
    dyn = parts.sensor.flown()  # the events as they happened: a triggered appear at its time
    verdict, arrival, status, message = verdict_of(scenario, dyn, flight, station.message)
    err = np.linalg.norm(flight["actual"] - flight["reference"], axis=-1)
    for a in (*flight.values(), arrival, err):
        a.setflags(write=False)
    r = np.array([u.radius for u in scenario.team])
    return FlightResult(
        scenario=scenario, dynamics=dyn, config=config, seed=seed, status=status, message=message,
        times=flight["times"], actual=flight["actual"], velocity=flight["velocity"],
        reference=flight["reference"], replans=tuple(station.records), verdict=verdict,
        separation_limit=scenario.costs.safe_distance + 2 * r, required_clearance=float(scenario.costs.min_clearance),
        tracking_rms=np.sqrt(np.mean(err**2, axis=1)), tracking_max=err.max(axis=1), arrival=arrival,
        baseline_arrival=baseline_arrival(ref0), stops=station.stops, holds=parts.onboard.holds, plan_waypoints=wp,
        plan_windows=tuple(windows), plan_margins=plan_margins, wall_time_s=time.perf_counter() - wall0,
        link={"delay_s": parts.radio.link.delay, "jitter_s": parts.radio.link.jitter, "loss": parts.radio.link.loss,
              "sent": parts.radio.sent, "lost": parts.radio.lost},
        details={"compile_time_s": compile_s, "engine": resolved.name, "planned_offline": planned_here},
    )
