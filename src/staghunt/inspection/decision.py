"""The decision maker in flight: what is done, what is left, and who does it now.

The task layer tracks the work (:class:`WorkLog`): a task is done when the UAV flying it finishes
its capture, in progress while it flies it. On an event it re-allocates what is left among the
UAVs still flying (:func:`reallocate`):

- ``uav_lost``: the UAV lands where it is; its tasks not started, and what is left of the capture
  it was flying (the segment from where it stopped), go to the others;
- an objective added in flight: its captures are planned (the site as it is now) and join what is
  left;
- an obstacle that appears: every capture not yet flown is checked against the new site; a
  stretch that is no longer safe is cut out and reported, the rest stays to do.

Every UAV still flying finishes the piece it is in (a capture, a leg, a hover), then flies the new
allocation from there (:meth:`staghunt.inspection.planner.Flight.build`): its own legs to its
tasks and home, the team deconflicted in time from the switch on. What the photos of a lost UAV
show counts: it lands and keeps its memory card.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from staghunt.acquisition.plan import keepout, plan_objective
from staghunt.acquisition.segments import CapturePlan, CaptureSegment, arc_length
from staghunt.acquisition.survey import _runs
from staghunt.inspection.allocation import Allocation, Problem
from staghunt.inspection.routing import solve
from staghunt.inspection.planner import SLACK, Flight, InspectConfig, fleet_of
from staghunt.inspection.tasks import Task, Way, make_tasks
from staghunt.inspection.timeline import Piece, Timeline, hover_piece
from staghunt.scenario.model import Scenario
from staghunt.task.objectives import Inspection, Objective

__all__ = ["Decision", "WorkLog", "reallocate", "split_blocked"]


@dataclass
class WorkLog:
    """The tasks (growing: objectives added, what is left of a task re-issued as a new one) and
    which are done (captured by a UAV to its end) or superseded (re-issued), by index."""

    tasks: list[Task]
    done: set[int] = field(default_factory=set)
    superseded: set[int] = field(default_factory=set)

    def update(self, timeline: Timeline, t: float, lost: dict[int, tuple[float, np.ndarray]]) -> None:
        """Mark done every capture a UAV finished by ``t`` (a lost one: before it was lost)."""
        for k, pieces in enumerate(timeline.pieces):
            until = min(t, lost[k][0]) if k in lost else t
            for p in pieces:
                if p.kind == "capture" and p.task is not None and p.t1 <= until + 1e-9:
                    self.done.add(p.task)


@dataclass(frozen=True)
class Decision:
    """One decision in flight: at ``time`` (s) on ``trigger``, taking ``latency_s`` (measured
    wall time of the re-allocation and the legs; ``cpu_s`` the CPU time it took, which a loaded
    machine does not inflate), effective from ``switch`` (s); ``tasks_left`` counts the tasks
    re-allocated; the new ``allocation``, and notes (what became unreachable)."""

    time: float
    trigger: str
    latency_s: float
    switch: float
    tasks_left: int
    allocation: Allocation
    notes: tuple[str, ...] = ()
    cpu_s: float = 0.0


def _remainder(seg: CaptureSegment, at: np.ndarray) -> CaptureSegment | None:
    """What is left of ``seg`` flown from the planned point before the one nearest ``at`` to its end
    (``None``: nothing)."""
    if seg.trigger == "points":
        return seg
    k = int(np.argmin(np.linalg.norm(seg.points - at, axis=1)))
    if k >= len(seg.points) - 1:
        return None
    k = max(k - 1, 0)  # from the planned point before: the new photos overlap the last ones taken
    return replace(seg, points=seg.points[k:].copy(), yaw=seg.yaw[k:].copy(), pitch=seg.pitch[k:].copy())


def split_blocked(scenario: Scenario, task: Task) -> tuple[list[CaptureSegment], float]:
    """The safe runs of ``task``'s segment in ``scenario`` (its site as it is now) and the length
    (m) cut out."""
    seg = task.segment
    keep = keepout(scenario)
    if seg.trigger == "points" or len(seg.points) < 2:
        ok = keep.point_ok(seg.points)
        return ([seg] if ok.all() else []), (0.0 if ok.all() else float("nan"))
    ok = keep.point_ok(seg.points)
    seg_ok = keep.segment_ok(seg.points) & ok[:-1] & ok[1:]
    if seg_ok.all():
        return [seg], 0.0
    lost = float(np.sum(np.diff(arc_length(seg.points))[~seg_ok]))
    out = []
    for r0, r1 in _runs(seg_ok):
        sl = slice(r0, r1 + 2)
        out.append(replace(seg, points=seg.points[sl].copy(), yaw=seg.yaw[sl].copy(), pitch=seg.pitch[sl].copy()))
    return out, lost


def reallocate(scenario: Scenario, inspection: Inspection, log: WorkLog, timeline: Timeline, t: float,
               alive: np.ndarray, lost: dict[int, tuple[float, np.ndarray]], config: InspectConfig, seed: int,
               trigger: str, added: tuple[Objective, ...] = (), check_site: bool = False,
               latency_floor: float = 0.1) -> tuple[Timeline, Decision]:
    """Re-allocate what is left at ``t`` (see the module's docstring) and build the new timeline.

    ``alive``: ``(N,)`` UAVs still flying; ``lost``: ``{uav: (when, where it was lost)}`` (its
    unfinished capture is cut there, its timeline ends with its landing); ``added``: objectives
    added now (``inspection`` already holds them); ``check_site``: the site changed (cut what is no
    longer safe)."""
    started, cpu = time.perf_counter(), time.process_time()
    log.update(timeline, t, lost)
    notes: list[str] = []
    tasks = log.tasks
    for obj in added:
        plan = plan_objective(scenario, inspection, obj)
        notes += [f"{obj.name}: {u}" for u in plan.unreached]
        base = len(tasks)
        tasks.extend(replace(x, index=base + i) for i, x in enumerate(make_tasks(inspection, CapturePlan((plan,)))))
    # what each alive UAV keeps: its pieces up to the end of the one it is in at t
    head: list[list[Piece]] = []
    ready = np.zeros(timeline.n)
    where = np.zeros((timeline.n, 3))
    kept: set[int] = set()
    terrain = scenario.world.terrain
    for k, pieces in enumerate(timeline.pieces):
        if not alive[k]:
            t_lost, at = lost[k]
            before = [p for p in pieces if p.t0 < t_lost - 1e-9] or [pieces[0]]
            if before[-1].label != "lost: landing" and before[-1].label != "landed":
                g = float(np.asarray(terrain.height(at[:1], at[1:2]))[0])
                before = before + [landing(at, g, t_lost)]
            head.append(before)
            ready[k] = t
            where[k] = before[-1].points[-1]
            continue
        upto = [p for p in pieces if p.t0 <= t + 1e-9]
        if not upto:
            upto = [pieces[0]]
        mine = list(upto)
        end = mine[-1]
        kept |= {p.task for p in mine if p.task is not None}
        ready[k] = max(end.t1, t)
        where[k] = end.state(np.array([end.t1]))[0, 0] if end.spline is not None else end.hold
        head.append(mine)
    left: list[Task] = []
    for task in list(tasks):
        if task.index in log.done or task.index in log.superseded or task.index in kept:
            continue
        # a lost UAV's capture in progress: what is left of it
        flying = next(((k, p) for k, (t_lost, _) in lost.items() for p in timeline.pieces[k]
                       if p.task == task.index and p.kind == "capture" and p.t0 <= t_lost < p.t1), None)
        seg = task.segment
        if flying is not None:  # as that UAV was flying it
            rest = _remainder(flying[1].segment, lost[flying[0]][1])
            if rest is None:
                log.done.add(task.index)
                continue
            seg = rest
        if check_site:
            runs, cut = split_blocked(scenario, replace(task, ways=(Way(seg),)))
            if cut != 0.0:
                notes.append(f"task {task.index} ({task.objective}): {'all' if not runs else f'{cut:.1f} m'} no longer "
                             "safe after the site changed: not captured")
        else:
            runs = [seg]
        for r in runs:
            ways = (Way(r), Way(r.reversed())) if r.reversible and len(r.points) > 1 else (Way(r),)
            left.append(replace(task, ways=ways, duration=r.duration))
    # the tasks to allocate get fresh indices into a fresh list (kept ones keep theirs for the log)
    base = len(tasks)
    fresh = [replace(x, index=base + i) for i, x in enumerate(left)]
    tasks.extend(fresh)
    log.superseded |= {x.index for x in left}
    full = fleet_of(scenario, inspection)
    fleet = replace(full, starts=where, ready=ready, endurance=full.endurance - ready, active=alive.copy())
    local = Problem(tuple(replace(x, index=i) for i, x in enumerate(fresh)), fleet, slack=SLACK)
    alloc = solve(local, config.allocation, solutions=min(config.solutions, 10), rounds=min(config.rounds, 2),
                  time_cap_s=min(config.time_cap_s, 0.25))
    # back to the log's indices
    remap = {i: x.index for i, x in enumerate(fresh)}
    alloc = replace(alloc, routes=tuple(replace(r, visits=tuple(replace(v, task=remap[v.task]) for v in r.visits))
                                        for r in alloc.routes))
    fly = Flight(scenario, inspection, config, seed, tasks)
    new, _, _, problems = fly.build(alloc, fleet=fleet, head=head, after=t)
    latency = max(time.perf_counter() - started, latency_floor)
    decision = Decision(t, trigger, latency, t + latency, len(fresh), alloc, tuple(notes + problems),
                        time.process_time() - cpu)
    return new, decision


def landing(piece_at: np.ndarray, ground: float, t: float, rate: float = 1.0) -> Piece:
    """A lost UAV's way down: from ``piece_at`` straight down to the ground at ``rate`` m/s."""
    from staghunt.inspection.timeline import path_piece
    from staghunt.task import VehicleLimits

    bottom = np.array([piece_at[0], piece_at[1], ground + 0.3])
    if piece_at[2] - bottom[2] < 0.1:
        return hover_piece(t, t, bottom, label="landed")
    return path_piece("leg", t, np.array([piece_at, bottom]), VehicleLimits(max_speed=rate, max_acceleration=1.0,
                                                                            cruise_speed=rate), label="lost: landing")
