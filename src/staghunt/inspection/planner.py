"""``plan_inspection``: objectives to an allocated, cooperative, timed and checked inspection.

1. Capture plans from every objective and its camera (:mod:`staghunt.acquisition`).
2. Tasks (one per capture segment) allocated to the UAVs for the makespan within their
   endurance and the windows (:mod:`.allocation`), the greedy baseline beside it.
3. The legs that join the captures (:mod:`.legs`): the team takes off together and plays the game
   to its first captures (formation over the scenario's graph, separation, obstacles); after that
   each UAV is on its own clock: between captures and home when its work is done it flies alone
   (a straight hop, the shortest way round or over an obstacle, or the game with it as the only
   player). Coming home together would keep the early ones hovering at their last capture in the
   others' way, spending endurance for nothing: they come home as they finish. The game's way out
   is longer than the straight lines the allocation assumed: the work is allocated again from
   where and when it leaves each UAV, and that timeline kept when it ends earlier.
4. Every UAV's flight timed (:mod:`.timeline`) and the whole team checked in time: separation at
   the same instant, clearance, ground, ceiling. A conflict between two UAVs at work is resolved
   by making the later one wait.
5. The coverage the planned photos give (:mod:`staghunt.acquisition.coverage`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from staghunt.acquisition.clearance import Keepout
from staghunt.acquisition.coverage import Photos, measure_inspection
from staghunt.acquisition.plan import plan_captures
from staghunt.acquisition.segments import CapturePlan
from staghunt.costs import CostModel, to_absolute
from staghunt.errors import FieldError
from staghunt.inspection.allocation import Allocation, Problem, shortfall
from staghunt.inspection.routing import solve
from staghunt.inspection.legs import leg_scenario, solo_leg, team_leg
from staghunt.inspection.tasks import Fleet, Task, check_capable, make_tasks
from staghunt.inspection.timeline import Piece, Timeline, capture_piece, hover_piece, path_piece, team_pieces
from staghunt.result import PlanResult
from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.solvers.response import CertifyOptions
from staghunt.task.objectives import Inspection
from staghunt.trajectory import SafetyReport, check_positions

__all__ = ["InspectConfig", "InspectionPlan", "InspectionStatus", "plan_inspection", "fleet_of"]

SLACK = 1.25
"""Planned transit time over the straight line's (legs round obstacles, accelerating, braking)."""
SEPARATION_MARGIN = 0.5
"""Two UAVs at work are kept this much farther apart than the separation limit (m): the team is
checked every 0.1 s, and a vehicle strays from its reference."""


class InspectionStatus(str, Enum):
    """``PLANNED``: every required task allocated, every leg feasible, the team safe in time.
    ``INFEASIBLE``: a leg has no feasible path or a window is missed (``message`` says which).
    ``UNSAFE``: the timed team breaks a separation or clearance that waiting could not mend."""

    PLANNED = "planned"
    INFEASIBLE = "infeasible"
    UNSAFE = "unsafe"


@dataclass(frozen=True)
class InspectConfig:
    """How an inspection is planned.

    - ``allocation``: ``"ortools"`` (bisection on the makespan with OR-Tools, from the greedy
      allocation) or ``"greedy"``; ``solutions``, ``rounds``, ``time_cap_s``: OR-Tools' budget
      (:func:`staghunt.inspection.allocation.solve_ortools`).
    - ``leg_settings``: the swarm settings of the team legs (``None``: the scenario's);
      ``solo_settings``: of a UAV's own leg round an obstacle.
    - ``certify``: the team legs' equilibrium certificate (``None``: none).
    - ``engine``: the planning engine (``"auto"``, ``"numba"``, ``"numpy"``).
    """

    allocation: str = "ortools"
    solutions: int = 30
    rounds: int = 6
    time_cap_s: float = 1.0
    leg_settings: SolverSettings | None = None
    solo_settings: SolverSettings = SolverSettings(particles=200, iterations=100, waypoints=5)
    certify: CertifyOptions | None = CertifyOptions()
    engine: str = "auto"


@dataclass(frozen=True, eq=False)
class InspectionPlan:
    """A planned inspection.

    - ``captures``: every objective's capture segments; ``tasks``: the allocated units.
    - ``allocation``: the chosen allocation, ``baseline``: the greedy one beside it.
    - ``outbound``: the team's game from take-off to the first captures (``None`` when nobody
      flies); ``solo``: ``[(uav, PlanResult), ...]`` the legs the game planned for one UAV alone.
    - ``timeline``: every UAV's flight in time; ``safety``: the team checked in time.
    - ``coverage``: what the planned photos cover, per objective.
    """

    scenario: Scenario
    inspection: Inspection
    config: InspectConfig
    seed: int
    status: InspectionStatus
    message: str
    captures: CapturePlan
    tasks: tuple[Task, ...]
    allocation: Allocation
    baseline: Allocation
    outbound: PlanResult | None
    solo: tuple[tuple[int, PlanResult], ...]
    timeline: Timeline
    safety: SafetyReport
    coverage: tuple[dict, ...]
    times: dict = field(default_factory=dict)

    @property
    def makespan(self) -> float:
        return self.timeline.end

    def photos(self) -> Photos:
        """The planned photos of every UAV (time, position, gimbal angles, speed)."""
        parts = []
        for n, pieces in enumerate(self.timeline.pieces):
            for p in pieces:
                if p.kind != "capture" or p.segment is None:
                    continue
                pos, yaw, pitch = p.segment.photo_poses()
                # when: along the capture in proportion to the distance flown (planned timing)
                if len(pos) > 1:
                    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pos, axis=0), axis=1))])
                    frac = s / max(s[-1], 1e-9)
                else:
                    frac = np.array([0.5])
                t = p.t0 + frac * p.duration
                parts.append(Photos(t, np.full(len(pos), n), pos, yaw, pitch, np.full(len(pos), p.segment.speed if
                                    p.segment.trigger == "distance" else 0.0), np.full(len(pos), p.segment.objective),
                                    np.full(len(pos), int(p.task))))
        return Photos.concat(parts)


def fleet_of(scenario: Scenario, inspection: Inspection) -> Fleet:
    """The fleet at take-off: everyone at its start, its whole endurance ahead."""
    n = scenario.n_uavs
    terrain = scenario.world.terrain
    return Fleet(
        starts=to_absolute(terrain, scenario.starts()), goals=to_absolute(terrain, scenario.goals()),
        ready=np.zeros(n), endurance=np.array([p.endurance_s for p in inspection.payloads], dtype=float),
        speed=np.full(n, scenario.vehicle.cruise_speed), names=tuple(u.name for u in scenario.team),
        active=np.ones(n, dtype=bool))


def plan_inspection(scenario: Scenario, inspection: Inspection, config: InspectConfig = InspectConfig(),
                    seed: int = 0) -> InspectionPlan:
    """Plan the inspection of ``scenario`` (see the module's docstring). Raises
    :class:`~staghunt.errors.FieldError` for objectives the team cannot fly at all (no camera for
    them, endurance too short for any allocation)."""
    times: dict[str, float] = {}
    t = time.perf_counter()
    captures = plan_captures(scenario, inspection)
    tasks = make_tasks(inspection, captures)
    check_capable(tasks)
    times["captures_s"] = time.perf_counter() - t
    fleet = fleet_of(scenario, inspection)
    problem = Problem(tuple(tasks), fleet, slack=SLACK)
    t = time.perf_counter()
    baseline = solve(problem, "greedy")
    alloc = baseline if config.allocation == "greedy" else solve(problem, config.allocation, config.solutions,
                                                                 config.rounds, config.time_cap_s)
    times["allocation_s"] = time.perf_counter() - t
    if not alloc.ok:
        raise FieldError(shortfall(problem, alloc), "endurance")
    t = time.perf_counter()
    fly = Flight(scenario, inspection, config, seed, tasks)
    timeline, outbound, solo, problems = fly.build(alloc)
    if outbound is not None and outbound.feasible and not problems:
        again = from_way_out(fly, problem, alloc, timeline)
        if again is not None and not again[2].problems and again[1].end < timeline.end - 1e-6:
            again[2].notes = fly.notes + [f"work allocated again from the end of the outbound leg: makespan "
                                          f"{timeline.end:.0f} s -> {again[1].end:.0f} s"]
            alloc, timeline, fly = again
            solo, problems = fly.solo, fly.problems
    times["legs_s"] = time.perf_counter() - t
    t = time.perf_counter()
    safety = check_timeline(scenario, timeline)
    times["check_s"] = time.perf_counter() - t
    plan = InspectionPlan(scenario, inspection, config, seed, InspectionStatus.PLANNED, "", captures, tuple(tasks), alloc,
                          baseline, outbound, tuple(solo), timeline, safety, (), times)
    t = time.perf_counter()
    cameras = {o.name: inspection.camera_for(o) for o in inspection.objectives}
    coverage = tuple(measure_inspection(inspection, scenario, plan.photos(), cameras))
    times["coverage_s"] = time.perf_counter() - t
    status, message = InspectionStatus.PLANNED, f"planned: makespan {timeline.end:.0f} s"
    if fly.notes:
        message += "; " + "; ".join(fly.notes)
    if problems:
        status, message = InspectionStatus.INFEASIBLE, "infeasible: " + "; ".join(problems[:3])
    elif not safety.safe:
        status, message = InspectionStatus.UNSAFE, "unsafe: " + "; ".join(safety.problems[:3])
    return replace(plan, status=status, message=message, coverage=coverage, times=times)


def from_way_out(fly: Flight, problem: Problem, alloc: Allocation, timeline: Timeline
                 ) -> tuple[Allocation, Timeline, Flight] | None:
    """The work allocated again from where and when the team's outbound leg (in ``timeline``)
    leaves each UAV: the first allocation times each UAV's way out alone and straight, while the
    game brings the team to its first captures together, later (its longest path sets the pace).
    The new allocation (with ``alloc``'s lower bound), its timeline and its builder (whose
    ``problems`` say what failed); ``None`` when no allocation fits from there."""
    fleet, config = problem.fleet, fly.config
    head = [[p for p in pieces if p.label == "outbound"] for pieces in timeline.pieces]
    t_out = max((h[-1].t1 for h in head if h), default=0.0)
    starts = np.array([h[-1].state(np.array([h[-1].t1]))[0, 0] if h else fleet.starts[k] for k, h in enumerate(head)])
    ready = np.full(fleet.n, t_out)
    after = replace(fleet, starts=starts, ready=ready, endurance=fleet.endurance - ready)
    again = solve(Problem(problem.tasks, after, stop_s=problem.stop_s, slack=problem.slack), config.allocation,
                  config.solutions, config.rounds, config.time_cap_s)
    if not again.ok:
        return None
    fly2 = Flight(fly.scenario, fly.inspection, config, fly.seed, fly.tasks)
    built, _, _, _ = fly2.build(again, fleet=after, head=head, after=t_out)
    return replace(again, lower_bound=alloc.lower_bound), built, fly2


def _certified(result: PlanResult, config: InspectConfig) -> bool:
    """The team leg is certified an equilibrium (or nothing is certified at all)."""
    return config.certify is None or (result.certificate is not None and result.certificate.is_equilibrium)


def check_timeline(scenario: Scenario, timeline: Timeline, step: float = 0.1) -> SafetyReport:
    """The team's flight checked every ``step`` s (separation at the same instant, clearance,
    ground, ceiling): :func:`staghunt.trajectory.check_positions`."""
    ts = np.arange(0.0, timeline.end + step, step)
    pos = timeline.positions(ts)
    return check_positions(CostModel.from_scenario(scenario), pos, list(timeline.names), step)


@dataclass
class Flight:
    """Builds every UAV's timeline from an allocation (step 3 and 4 of the module's docstring)."""

    scenario: Scenario
    inspection: Inspection
    config: InspectConfig
    seed: int
    tasks: list[Task]

    def build(self, alloc: Allocation, fleet: Fleet | None = None, head: list[list[Piece]] | None = None,
              after: float | None = None) -> tuple[Timeline, PlanResult | None, list[tuple[int, PlanResult]], list[str]]:
        """Every UAV's timeline for ``alloc``. At take-off (``head`` ``None``): the team's game to the
        first captures, then each UAV's work and its way home. In flight (a re-allocation):
        ``head[k]`` is what UAV ``k`` keeps of its old timeline (up to ``fleet.ready[k]``, at
        ``fleet.starts[k]``); every active UAV then flies alone to its tasks and home; the team is
        deconflicted from ``after`` on."""
        scenario, tasks = self.scenario, self.tasks
        limits = scenario.vehicle
        settings = self.config.leg_settings or scenario.solver
        fleet = fleet if fleet is not None else fleet_of(scenario, self.inspection)
        plans = [alloc.tasks_of(k) for k in range(scenario.n_uavs)]
        if head is None:
            flying = [k for k in range(scenario.n_uavs) if plans[k]]
        else:
            flying = [k for k in range(scenario.n_uavs) if fleet.active[k]]
        self.problems: list[str] = []
        self.notes: list[str] = []
        self.solo: list[tuple[int, PlanResult]] = []
        pieces: list[list[Piece]] = [list(head[k]) for k in range(scenario.n_uavs)] if head is not None else \
            [[] for _ in range(scenario.n_uavs)]
        outbound = None
        if head is None and flying:
            firsts = np.array([tasks[plans[k][0][0]].ways[plans[k][0][1]].entry for k in flying])
            firsts = self._staging(flying, firsts)
            # the team leaves together in its take-off formation (the reference shape: the starts), and
            # spreads out to its first captures at the end of the leg
            outbound = team_leg(scenario, flying, fleet.starts[flying], firsts, "outbound", settings, self.seed,
                                self.config.engine, self.config.certify, reference=fleet.starts[flying])
            if not outbound.feasible or not _certified(outbound, self.config):  # once more, twice the budget
                bigger = settings.with_(particles=2 * settings.particles, iterations=2 * settings.iterations)
                again = team_leg(scenario, flying, fleet.starts[flying], firsts, "outbound", bigger, self.seed + 1,
                                 self.config.engine, self.config.certify, reference=fleet.starts[flying])
                if again.feasible and (not outbound.feasible or _certified(again, self.config)):
                    outbound = again
            if outbound.feasible and not _certified(outbound, self.config):
                gap = outbound.certificate.max_relative_gap if outbound.certificate is not None else math.nan
                self.notes.append(f"outbound: not certified an equilibrium (largest relative gap {gap:.1%}, twice "
                                  "the budget tried)")
            if outbound.feasible:
                model = CostModel.from_scenario(leg_scenario(scenario, flying, fleet.starts[flying], firsts, "outbound",
                                                             fleet.starts[flying]))
                for i, p in zip(flying, team_pieces(0.0, np.asarray(outbound.paths), limits, "outbound", model)):
                    pieces[i].append(p)
            else:  # no feasible joint plan found: each leaves alone, the later ones waiting (deconfliction)
                self.notes.append(f"outbound: the game found no feasible plan ({outbound.message}); the UAVs fly "
                                  "their own legs to their first captures, waiting for one another")
                for k, goal in zip(flying, firsts):
                    self._leg(pieces[k], k, fleet.starts[k], goal, 0.0, "to the first capture", 0)
                    if not pieces[k]:
                        pieces[k].append(hover_piece(0.0, 0.0, fleet.starts[k], label="to the first capture"))
        for k in flying:
            here = pieces[k][-1].points[-1] if head is None else fleet.starts[k]
            t0 = pieces[k][-1].t1 if head is None else float(fleet.ready[k])
            for j, (ti, wi) in enumerate(plans[k]):
                task, way = tasks[ti], tasks[ti].ways[wi]
                if j > 0 or head is not None or float(np.linalg.norm(here - way.entry)) > 1e-6:
                    t0 = self._leg(pieces[k], k, here, way.entry, t0, f"to task {ti}", j)
                if task.window is not None and t0 < task.window[0]:
                    pieces[k].append(hover_piece(t0, task.window[0], way.entry, label=f"waits for the window of task {ti}"))
                    t0 = task.window[0]
                pieces[k].append(capture_piece(t0, way.segment, limits, ti))
                here, t0 = way.exit, pieces[k][-1].t1
            # home as soon as its work is done, round the others' goals (where they wait once home)
            self._leg(pieces[k], k, here, fleet.goals[k], t0, "home", 999, avoid=np.delete(fleet.goals, k, axis=0))
        start_work = after if after is not None else (pieces[flying[0]][0].t1 if flying and outbound is not None and
                                                      outbound.feasible else 0.0)
        self._deconflict(pieces, start_work)
        for k in flying:
            for p in pieces[k]:
                task = tasks[p.task] if p.task is not None and p.task < len(tasks) else None
                if task is not None and task.window is not None and p.t1 > task.window[1] + 1e-6 and p.t0 >= start_work:
                    self.problems.append(f"{fleet.names[k]} flies task {p.task} ({task.objective}) until {p.t1:.0f} s, "
                                         f"past its window's end {task.window[1]:.0f} s")
        for k in range(scenario.n_uavs):
            if not pieces[k]:  # no work: stays at its start
                pieces[k].append(hover_piece(0.0, 0.0, fleet.starts[k], label="no task"))
        for k in flying:
            used = pieces[k][-1].t1 - float(fleet.ready[k])
            if used > fleet.endurance[k] + 1e-6:
                self.problems.append(f"{fleet.names[k]} flies {used:.0f} s, it has {fleet.endurance[k]:.0f} s of endurance")
        timeline = Timeline(tuple(tuple(p) for p in pieces), fleet.names)
        return timeline, outbound, self.solo, self.problems

    def _staging(self, flying: list[int], firsts: np.ndarray) -> np.ndarray:
        """The outbound leg's goals: each UAV's first capture entry, unless it lies within the
        separation limit (plus 2 m) of another's (two walls sharing a corner): then a safe point
        6, 12 or 18 m above it, or as far beside it, from which it joins its capture alone."""
        scenario = self.scenario
        keep = Keepout(scenario, max(u.radius for u in scenario.team))
        limit = scenario.costs.safe_distance + 2 * max(u.radius for u in scenario.team) + 2.0
        goals = np.array(firsts, dtype=float)
        offsets = [np.array([0.0, 0.0, dz]) for dz in (6.0, 12.0, 18.0)] + [
            d * np.array([np.cos(a), np.sin(a), 0.0]) for d in (6.0, 12.0) for a in np.linspace(0, 2 * np.pi, 8,
                                                                                             endpoint=False)]
        for i in range(1, len(goals)):
            if np.linalg.norm(goals[:i] - goals[i], axis=1).min() > limit:
                continue
            for off in offsets:
                cand = firsts[i] + off
                if (np.linalg.norm(goals[:i] - cand, axis=1).min() > limit and keep.point_ok(cand[None])[0]
                        and keep.segment_ok(np.array([cand, firsts[i]])).all()):
                    goals[i] = cand
                    break
        return goals

    def _leg(self, pieces: list[Piece], k: int, a: np.ndarray, b: np.ndarray, t0: float, label: str, j: int,
             avoid: np.ndarray | None = None) -> float:
        """UAV ``k``'s own leg from ``a`` to ``b`` from ``t0`` appended to ``pieces``; its end time.
        ``avoid`` ``(M, 3)``: points it must pass at the separation limit (team-mates' goals)."""
        scenario = self.scenario
        if avoid is not None and len(avoid):
            from staghunt.world import Cylinder

            r = scenario.costs.safe_distance + scenario.team[k].radius - scenario.costs.min_clearance + 0.5
            ghosts = tuple(Cylinder(float(p[0]), float(p[1]), max(r, 0.1), "team-mate at its goal") for p in avoid)
            scenario = replace(scenario, world=replace(scenario.world, cylinders=scenario.world.cylinders + ghosts))
        pts, leg = solo_leg(scenario, k, a, b, self.config.solo_settings, self.seed + 1000 * (k + 1) + j,
                            self.config.engine)
        if leg is not None:
            self.solo.append((k, leg))
            if not leg.feasible:
                self.problems.append(f"{self.scenario.team[k].name} leg {label}: {leg.message}")
        if len(pts) > 1 and float(np.linalg.norm(pts[-1] - pts[0])) > 1e-6:
            pieces.append(path_piece("leg", t0, pts, self.scenario.vehicle, label=label))
            return pieces[-1].t1
        return t0

    def _deconflict(self, pieces: list[list[Piece]], after: float, step: float = 0.1, rounds: int = 40) -> None:
        """Make one of two UAVs that would come too close while at work (after ``after``, the end
        of the team's outbound leg) wait before the piece that brings it there, as long as the
        conflict would last and 1 s more: the one that moves when the other waits where it is, else
        the one whose piece started later; up to ``rounds`` times. What is left is for the check in
        time to report."""
        scenario = self.scenario
        limit = np.array([scenario.costs.safe_distance + 2 * u.radius for u in scenario.team])
        idx = [i for i, p in enumerate(pieces) if p]
        if len(idx) < 2:
            return

        def track(i: int) -> np.ndarray:  # (T, 3) UAV idx[i] at ts (holding where it ends)
            return Timeline((tuple(pieces[idx[i]]),), ("",)).positions(ts)[0]

        ts = np.zeros(0)
        moved: int | None = None
        for _ in range(rounds):
            end = max(pieces[k][-1].t1 for k in idx)
            if moved is None or end > ts[-1]:  # (re)sample everyone; else only the one delayed
                ts = np.arange(after + step, end + step + 30.0, step)
                pos = np.stack([track(i) for i in range(len(idx))])  # (n, T, 3)
            else:
                pos[moved] = track(moved)
            d = np.linalg.norm(pos[:, None] - pos[None, :], axis=-1)  # (n, n, T)
            d[np.arange(len(idx)), np.arange(len(idx))] = math.inf
            bad = d <= limit[idx][:, None, None] + SEPARATION_MARGIN
            if not bad.any():
                return
            ti = int(np.argmax(bad.any(axis=(0, 1))))  # the earliest conflict first
            a, b = (int(v[0]) for v in np.nonzero(bad[:, :, ti]))
            t_hit = ts[ti]
            near = bad[a, b, ti:]
            last = ti + (int(np.argmin(near)) if not near.all() else len(near))
            by = max(2.0, ts[min(last, len(ts) - 1)] - t_hit + 1.0)  # until the conflict is over, and 1 s more
            pa = next((p for p in pieces[idx[a]] if p.t0 <= t_hit <= p.t1), None)
            pb = next((p for p in pieces[idx[b]] if p.t0 <= t_hit <= p.t1), None)
            if pa is None and pb is None:
                return
            # the one to wait: not one that already waits where it is (it is in the other's way), else
            # the one whose current piece started later
            still_a = pa is None or pa.kind == "hover"
            still_b = pb is None or pb.kind == "hover"
            if still_a and still_b:
                return
            if still_a != still_b:
                k, p = (idx[b], pb) if still_a else (idx[a], pa)
            else:
                k, p = (idx[a], pa) if pa.t0 >= pb.t0 else (idx[b], pb)
            if p.label == "outbound" or sum(q.duration for q in pieces[k] if q.label.startswith("waits for a team")) > 120:
                return  # waiting does not help (or no longer): the check in time reports it
            self._delay(pieces[k], pieces[k].index(p), by)
            moved = idx.index(k)

    @staticmethod
    def _delay(pieces: list[Piece], i: int, by: float) -> None:
        """Insert a hover of ``by`` seconds before piece ``i`` and shift the rest."""
        at = pieces[i].points[0] if pieces[i].hold is None else pieces[i].hold
        shifted = [replace(p, t0=p.t0 + by, t1=p.t1 + by) for p in pieces[i:]]
        pieces[i:] = [hover_piece(pieces[i].t0, pieces[i].t0 + by, at, label="waits for a team-mate to pass")] + shifted
