"""An inspection flown in simulation: the vehicles fly every UAV's timeline, each camera
triggers along the *flown* trajectory, the task layer tracks the work and re-allocates it when
a UAV is lost, an objective is added or an obstacle appears; the photos are measured for
coverage.

- Vehicles: :class:`~staghunt.flight.vehicles.SimulatedTeam` (rotorpy multirotors and their SE(3)
  controllers) tracking the timeline's position, velocity, acceleration and jerk at ``sim_rate``,
  optionally in Dryden wind.
- Cameras (:class:`CameraTrigger`, one per UAV): while the UAV's reference is in a capture, a
  photo at its start, then one whenever the vehicle has flown the segment's trigger distance since
  the last, never sooner than the camera's minimum interval after it (a photo due earlier waits);
  at a viewpoint, one photo three quarters into the hover. A photo is taken where the vehicle
  truly is, with the gimbal at the planned angles (a stabilised gimbal), at the vehicle's speed.
- Decisions (:mod:`staghunt.inspection.decision`): events are read at the planner's ticks (10 Hz);
  the re-allocation's measured time (at least one tick) is the latency, the old timeline flies
  meanwhile. A lost UAV lands straight down at 1 m/s where it is.
- The flight is judged on the vehicles by the one safety judge (:mod:`staghunt.safety`):
  separation at the same instant, clearance to the site's obstacles (those that appeared, from
  then on), ground and ceiling; contact and margin breaches are reported apart.
"""

from __future__ import annotations

import io
import math
import time
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from staghunt.acquisition.coverage import Photos, measure_inspection
from staghunt.inspection.decision import Decision, WorkLog, reallocate
from staghunt.inspection.planner import InspectConfig
from staghunt.inspection.tasks import make_tasks
from staghunt.inspection.timeline import Piece, Timeline
from staghunt.scenario.model import Scenario
from staghunt.world.dynamic import Event

__all__ = ["CameraTrigger", "InspectionFlight", "captures_csv", "fly_inspection"]

SIM_RATE = 100.0
TICK_S = 0.1


class CameraTrigger:
    """One UAV's camera: distance (or hover) triggering along its flown trajectory."""

    def __init__(self, uav: int, min_interval: float) -> None:
        self.uav = uav
        self.min_interval = min_interval
        self.piece: Piece | None = None
        self.last_t = -math.inf
        self.last_pos: np.ndarray | None = None
        self.flown = 0.0
        self.due = False
        self.photos: list[tuple] = []

    def update(self, t: float, piece: Piece | None, pos: np.ndarray, vel: np.ndarray) -> None:
        """One simulation step at ``t``: ``piece`` the reference's piece now (``None``: none)."""
        seg = piece.segment if piece is not None and piece.kind == "capture" else None
        if piece is not self.piece:  # a new piece: a capture starts with a photo
            self.piece = piece
            self.flown = 0.0
            self.due = seg is not None and seg.trigger == "distance"
            self.hovered = False
            self.last_pos = pos.copy()
        if seg is None:
            self.last_pos = pos.copy()
            return
        if seg.trigger == "points":
            if not self.hovered and t >= piece.t0 + 0.75 * (piece.t1 - piece.t0):
                self.due, self.hovered = True, True
        else:
            self.flown += float(np.linalg.norm(pos - self.last_pos))
            if self.flown >= seg.trigger_distance:
                self.due = True
        self.last_pos = pos.copy()
        if self.due and t - self.last_t >= self.min_interval - 1e-9:
            k = int(np.argmin(np.linalg.norm(seg.points - pos, axis=1)))
            self.photos.append((t, self.uav, pos.copy(), float(seg.yaw[k]), float(seg.pitch[k]),
                                float(np.linalg.norm(vel)), seg.objective, int(piece.task)))
            self.last_t, self.due, self.flown = t, False, 0.0


@dataclass(frozen=True, eq=False)
class InspectionFlight:
    """A simulated inspection: ``times (T,)``, ``actual``/``reference``/``velocity (N, T, 3)``;
    ``photos`` taken; ``coverage`` measured on them (per objective); ``decisions`` in flight;
    ``lost`` ``{name: time}``; per UAV least separation and clearance in the flight; ``problems``
    (contact or a breach of a required margin; empty: safe); ``timeline`` as finally flown."""

    scenario: Scenario
    timeline: Timeline
    times: np.ndarray
    actual: np.ndarray
    reference: np.ndarray
    velocity: np.ndarray
    photos: Photos
    coverage: tuple[dict, ...]
    decisions: tuple[Decision, ...]
    lost: dict[str, float]
    min_separation: np.ndarray
    separation_limit: np.ndarray
    min_clearance: np.ndarray
    required_clearance: float
    problems: tuple[str, ...]
    wall_time_s: float
    wind: float
    details: dict = field(default_factory=dict)

    @property
    def safe(self) -> bool:
        return not any(p.startswith("contact") for p in self.problems)

    def summary(self) -> dict[str, Any]:
        names = list(self.timeline.names)
        err = np.linalg.norm(self.actual - self.reference, axis=-1)
        return {
            "simulator": "rotorpy's Multirotor and SE3Control (batched, the scenario's airframe)",
            "rate_hz": SIM_RATE, "wind_m_s": self.wind,
            "duration_s": float(self.times[-1]) if len(self.times) else 0.0, "wall_time_s": self.wall_time_s,
            "photos": len(self.photos), "tracking_rms_m": dict(zip(names, np.sqrt((err ** 2).mean(axis=1)).tolist())),
            "min_separation_m": dict(zip(names, self.min_separation.tolist())),
            "separation_limit_m": dict(zip(names, self.separation_limit.tolist())),
            "min_clearance_m": dict(zip(names, self.min_clearance.tolist())),
            "required_clearance_m": self.required_clearance, "lost": self.lost,
            "decisions": [{"time_s": d.time, "trigger": d.trigger, "latency_s": d.latency_s, "cpu_s": d.cpu_s,
                           "switch_s": d.switch,
                           "tasks_reallocated": d.tasks_left, "makespan_s": d.allocation.makespan,
                           "notes": list(d.notes)} for d in self.decisions],
            "safe": self.safe, "problems": list(self.problems)}

    def coverage_json(self) -> dict[str, Any]:
        from staghunt.inspection.files import clean

        return clean({"format": "staghunt-coverage", "version": 1, "measured_on": "the flown trajectory (simulated)",
                      "wind_m_s": self.wind, "photos": len(self.photos), "objectives": list(self.coverage),
                      "lost": self.lost, "decisions": self.summary()["decisions"]})


def captures_csv(flight: InspectionFlight) -> str:
    """``t,uav,x,y,z,heading_deg,gimbal_pitch_deg,speed,objective,task``: every photo, the camera's
    position in the site frame (``z`` as in ``flight.csv``), ``heading_deg`` the direction of the
    image's height axis counter-clockwise from east, ``gimbal_pitch_deg`` -90 = nadir."""
    p = flight.photos
    out = io.StringIO()
    out.write("t,uav,x,y,z,heading_deg,gimbal_pitch_deg,speed,objective,task\n")
    for i in range(len(p)):
        x, y, z = p.position[i]
        name = flight.timeline.names[int(p.uav[i])]
        out.write(f"{p.t[i]:.3f},{name},{x:.3f},{y:.3f},{z:.3f},{math.degrees(p.yaw[i]) % 360.0:.2f},"
                  f"{math.degrees(p.pitch[i]):.2f},{p.speed[i]:.3f},{p.objective[i]},{int(p.segment[i])}\n")
    return out.getvalue()


def _piece_at(timeline: Timeline, k: int, t: float) -> Piece | None:
    pieces = timeline.pieces[k]
    for p in pieces:
        if p.t0 <= t < p.t1 or (p.t0 == p.t1 == t):
            return p
    return None


def fly_inspection(scenario: Scenario, timeline: Timeline, events: tuple[Event, ...] = (), wind: float = 0.0,
                   seed: int = 0, config: InspectConfig | None = None, tail_s: float = 3.0,
                   progress: Callable[[float, float], None] | None = None) -> InspectionFlight:
    """Fly ``timeline`` (see the module's docstring) with ``events`` (``uav_lost``, ``objective``,
    ``appear``, ``disappear``); one ``numpy.random.Generator`` from ``seed`` drives the wind."""
    from staghunt.flight.vehicles import DrydenGust, SimulatedTeam

    if any(e.trigger is not None for e in events):
        raise ValueError("an inspection's obstacles appear at their time: a trigger is flown by `staghunt fly` only")
    started = time.perf_counter()
    config = config if config is not None else InspectConfig()
    insp = scenario.inspection
    assert insp is not None
    rng = np.random.default_rng(seed)
    dt = 1.0 / SIM_RATE
    n = timeline.n
    start_pos = timeline.positions(np.array([0.0]))[:, 0]
    gust = None
    if wind > 0:
        gust = DrydenGust(np.array([wind, 0.0, 0.0]), float(np.mean(start_pos[:, 2])), dt, rng)
    team = SimulatedTeam(start_pos, dt, gust, scenario.vehicle, [u.radius for u in scenario.team])
    cams = [CameraTrigger(k, insp.payloads[k].camera.min_trigger_interval_s) for k in range(n)]
    from staghunt.acquisition.plan import plan_captures

    log = WorkLog(make_tasks(insp, plan_captures(scenario, insp)))
    _check_tasks(log, timeline)
    warm_up(log, scenario)  # the ground station has its solvers loaded before take-off, not at the first event
    alive = np.ones(n, dtype=bool)
    lost: dict[int, tuple[float, np.ndarray]] = {}
    decisions: list[Decision] = []
    pending = sorted(events, key=lambda e: e.time)
    world_now = scenario
    queued: list[tuple[float, Timeline, Decision]] = []
    times, actual, refs, vels = [], [], [], []
    t, step, end = 0.0, 0, timeline.end + tail_s
    names = [u.name for u in scenario.team]
    per_tick = int(round(TICK_S * SIM_RATE))
    ground: dict[int, float] = {}
    while t <= end + 1e-9:
        if step % per_tick == 0:
            while queued and queued[0][0] <= t + 1e-9:  # a decision takes effect
                _, timeline, _ = queued.pop(0)
                end = max(end, timeline.end + tail_s)
            fired = [e for e in pending if e.time <= t + 1e-9]
            pending = [e for e in pending if e.time > t + 1e-9]
            if fired:
                added, changed, why = [], False, []
                for e in fired:
                    if e.kind == "uav_lost":
                        k = names.index(e.name)
                        if alive[k]:
                            alive[k] = False
                            lost[k] = (t, team.positions()[k].copy())
                            why.append(f"{e.name} lost")
                    elif e.kind == "objective":
                        added.append(e.objective)
                        why.append(f"objective {e.objective.name} added")
                    elif e.kind in ("appear", "disappear"):
                        world_now = _changed_world(world_now, e)
                        changed = True
                        why.append(f"{e.name} {e.kind}s")
                if added:
                    insp = replace(insp, objectives=insp.objectives + tuple(added))
                    world_now = replace(world_now, inspection=insp)
                new, decision = reallocate(world_now, insp, log, timeline, t, alive, lost, config, seed + step,
                                           "; ".join(why), tuple(added), changed, latency_floor=TICK_S)
                switch = math.ceil((t + decision.latency_s) / TICK_S - 1e-9) * TICK_S
                decision = replace(decision, switch=switch)
                decisions.append(decision)
                queued.append((switch, new, decision))
                queued.sort(key=lambda q: q[0])
                end = max(end, new.end + tail_s)
                if progress is not None:
                    progress(t, end)
            # the reference until the next tick (a decision only takes effect at a tick)
            block = timeline.state((step + np.arange(per_tick)) * dt)  # (4, N, per_tick, 3)
        state = block[:, :, step % per_tick].copy()  # (4, N, 3)
        for k, (t_lost, at) in lost.items():  # a lost UAV: straight down where it was
            if k not in ground:
                ground[k] = float(np.asarray(scenario.world.terrain.height(at[:1], at[1:2]))[0]) + 0.3
            g = ground[k]
            z = max(g, at[2] - 1.0 * (t - t_lost))
            state[:, k] = 0.0
            state[0, k] = [at[0], at[1], z]
            state[1, k, 2] = -1.0 if z > g else 0.0
        team.step(t, state)
        pos, vel = team.positions(), team.velocities()
        for k in range(n):
            if alive[k]:
                cams[k].update(t, _piece_at(timeline, k, t), pos[k], vel[k])
        times.append(t)
        actual.append(pos)
        refs.append(state[0].copy())
        vels.append(vel)
        step += 1
        t = step * dt
    photos = _photos(cams)
    cameras = {o.name: insp.camera_for(o) for o in insp.objectives}
    coverage = tuple(measure_inspection(insp, world_now, photos, cameras))
    A = np.stack(actual, axis=1)
    R = np.stack(refs, axis=1)
    V = np.stack(vels, axis=1)
    T = np.array(times)
    sep, limit, clear, problems = _judge(scenario, world_now, A, T, lost, [e for e in events if e.kind == "appear"])
    return InspectionFlight(scenario, timeline, T, A, R, V, photos, coverage, tuple(decisions),
                            {names[k]: v[0] for k, v in lost.items()}, sep, limit, clear,
                            float(scenario.costs.min_clearance), tuple(problems), time.perf_counter() - started, wind)


def warm_up(log: WorkLog | None = None, scenario: Scenario | None = None) -> None:
    """Load and run OR-Tools' routing once on a two-task problem (its first use costs seconds of
    imports and set-up that a decision in flight would otherwise pay) and, given the mission's
    work ``log``, time every way of every capture (a re-allocation then times only its new legs
    and the rest of a capture a lost UAV left unfinished)."""
    from staghunt.inspection.allocation import Problem
    from staghunt.inspection.routing import solve
    from staghunt.inspection.tasks import Fleet, Task, Way
    from staghunt.acquisition.segments import CaptureSegment

    seg = CaptureSegment("warm-up", "line", 0, np.array([[0.0, 0, 10], [10.0, 0, 10]]), np.zeros(2), np.zeros(2),
                         "distance", 5.0, 5.0, 1.0, "none")
    tasks = tuple(Task(i, "warm-up", (Way(seg),), seg.duration, None, (0,)) for i in range(2))
    fleet = Fleet(np.zeros((1, 3)), np.zeros((1, 3)), np.zeros(1), np.full(1, 1e4), np.ones(1), ("w",), np.ones(1, bool))
    solve(Problem(tasks, fleet), "ortools", solutions=2, rounds=1, time_cap_s=0.2)
    if log is not None and scenario is not None:
        from staghunt.inspection.timeline import capture_piece

        for task in log.tasks:
            for way in task.ways:
                capture_piece(0.0, way.segment, scenario.vehicle, task.index)


def _check_tasks(log: WorkLog, timeline: Timeline) -> None:
    """The timeline's captures must be the tasks of this inspection (same indices)."""
    for pieces in timeline.pieces:
        for p in pieces:
            if p.task is not None and (p.task >= len(log.tasks) or log.tasks[p.task].objective != p.segment.objective):
                raise ValueError("the timeline's captures do not match the scenario's objectives (was the inspection "
                                 "planned for another scenario or other objectives?)")


def _photos(cams: list[CameraTrigger]) -> Photos:
    rows = sorted((p for c in cams for p in c.photos), key=lambda r: (r[0], r[1]))
    if not rows:
        return Photos.empty()
    return Photos(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]), np.array([r[2] for r in rows]),
                  np.array([r[3] for r in rows]), np.array([r[4] for r in rows]), np.array([r[5] for r in rows]),
                  np.array([r[6] for r in rows]), np.array([r[7] for r in rows]))


def _changed_world(scenario: Scenario, e: Event) -> Scenario:
    from staghunt.world import Cylinder, Prism

    w = scenario.world
    if e.kind == "appear":
        if isinstance(e.shape, Cylinder):
            w = replace(w, cylinders=w.cylinders + (e.shape,))
        elif isinstance(e.shape, Prism):
            w = replace(w, prisms=w.prisms + (e.shape,))
    else:
        w = replace(w, cylinders=tuple(c for c in w.cylinders if c.name != e.name),
                    prisms=tuple(p for p in w.prisms if p.name != e.name))
    return replace(scenario, world=w)


def _judge(scenario: Scenario, final: Scenario, A: np.ndarray, T: np.ndarray, lost: dict, appeared: list[Event]
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """Least separation and clearance per UAV in the simulated flight, and the problems, by the
    one safety judge (:func:`staghunt.safety.judge`): the site as it truly was at each step (an
    obstacle that appeared counts from its time on), the scenario's required margins; contact
    (a body touched an obstacle, a team-mate or the ground) or a breach of a required margin
    (clearance, separation, ground, ceiling). A lost UAV counts until it lands: once it comes down
    within its body and the required ground margin of the terrain (a landing is meant to reach the
    ground), it has left the team."""
    from staghunt.safety import Margins, Scene, judge
    from staghunt.world.dynamic import Dynamics

    names = [u.name for u in scenario.team]
    radius = np.array([u.radius for u in scenario.team])
    margins = Margins.required(scenario)
    on = np.ones(A.shape[:2], dtype=bool)
    for k, (t_lost, at) in lost.items():
        g = float(np.asarray(scenario.world.terrain.height(at[:1], at[1:2]))[0])
        on[k] = ~((T > t_lost) & (A[k, :, 2] - g < radius[k] + margins.ground + 0.5))
    verdict = judge(Scene.true(scenario.world, Dynamics(events=tuple(appeared))), radius, T, A,
                    margins, names, active=on)
    return (verdict.min_separation, scenario.costs.safe_distance + 2 * radius, verdict.min_clearance,
            verdict.problems(names))


def flight_dict(flight: InspectionFlight, max_samples: int = 1500) -> dict[str, Any]:
    """The replay page's data (:func:`staghunt.plots.replay.replay_html`): tracks, the site, the
    decisions as its re-plans and every photo's footprint."""
    from staghunt.acquisition.footprint import footprints

    sc = flight.scenario
    b = sc.world.bounds
    stride = max(1, int(round(0.1 * SIM_RATE)))
    idx = np.arange(0, len(flight.times), stride)
    if len(idx) > max_samples:
        idx = idx[np.linspace(0, len(idx) - 1, max_samples).round().astype(int)]
    insp = sc.inspection
    fps = []
    for obj in insp.objectives:
        mine = flight.photos.take(flight.photos.objective == obj.name)
        corners = footprints(mine, insp.camera_for(obj), sc)
        fps += [{"t": float(mine.t[i]), "uav": int(mine.uav[i]), "corners": corners[i].tolist()}
                for i in range(len(mine)) if np.isfinite(corners[i]).all()]
    terrain = None
    if not sc.world.terrain.is_flat:
        xs, ys = np.linspace(b.xmin, b.xmax, 25), np.linspace(b.ymin, b.ymax, 25)
        X, Y = np.meshgrid(xs, ys)
        terrain = {"x": xs.round(2).tolist(), "y": ys.round(2).tolist(),
                   "z": np.round(sc.world.terrain.height(X, Y), 2).tolist()}
    A = flight.actual
    return {
        "title": f"{sc.name} · inspection · {len(flight.photos)} photos",
        "site": {"xmin": b.xmin, "xmax": b.xmax, "ymin": b.ymin, "ymax": b.ymax,
                 "zmin": float(min(0.0, A[..., 2].min() - 1.0)), "zmax": float(A[..., 2].max() + 5.0)},
        "times": np.round(flight.times[idx], 3).tolist(),
        "uavs": [{"name": u.name, "radius": u.radius, "actual": np.round(A[n, idx], 2).tolist(),
                  "reference": np.round(flight.reference[n, idx], 2).tolist()} for n, u in enumerate(sc.team)],
        "cylinders": [[c.x, c.y, c.radius] for c in sc.world.cylinders],
        "prisms": [{"polygon": [list(v) for v in p.polygon], "base": max(p.base, -1e9), "top": min(p.top, 1e9),
                    "nofly": p.is_nofly} for p in sc.world.prisms],
        "moving": [],
        "replans": [{"time": d.time, "trigger": d.trigger, "verdict": f"{d.tasks_left} tasks re-allocated, "
                     f"{d.latency_s * 1000:.0f} ms"} for d in flight.decisions],
        "footprints": fps,
        "terrain": terrain,
    }


def flight_csv(flight: InspectionFlight, rate: float = 10.0) -> str:
    """``t,uav,x,y,z,vx,vy,vz,x_ref,y_ref,z_ref`` at ``rate`` Hz (site frame, m, m/s)."""
    stride = max(1, int(round(SIM_RATE / rate)))
    out = io.StringIO()
    out.write("t,uav,x,y,z,vx,vy,vz,x_ref,y_ref,z_ref\n")
    names = flight.timeline.names
    for i in range(0, len(flight.times), stride):
        for n in range(flight.actual.shape[0]):
            p, v, r = flight.actual[n, i], flight.velocity[n, i], flight.reference[n, i]
            out.write(f"{flight.times[i]:.2f},{names[n]},{p[0]:.3f},{p[1]:.3f},{p[2]:.3f},{v[0]:.3f},{v[1]:.3f},"
                      f"{v[2]:.3f},{r[0]:.3f},{r[1]:.3f},{r[2]:.3f}\n")
    return out.getvalue()
