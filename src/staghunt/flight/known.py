"""What the planner knows of the changing site, the problem a re-plan solves, and the planner's
acceptance of a plan by the one safety judge.

The planner's view (:class:`KnownWorld`: the static obstacles, the sensed ones, those known to be
gone), the re-plan's problem built from it (:func:`sub_scenario`, :func:`swept_obstacles`, the
warm start :func:`warm_plan`), and :class:`Acceptance`, the check every plan passes before it is
sent (docs/model.md, section 8). Shapes: ``N`` UAVs, ``K`` free waypoints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from staghunt.costs import to_absolute
from staghunt.flight.link import HoldReason
from staghunt.flight.onboard import hold_piece
from staghunt.safety import Margins, Scene, Verdict, judge
from staghunt.safety.measure import moving_clearance, static_clearance
from staghunt.scenario import Scenario
from staghunt.trajectory.quintic import Piece, Reference
from staghunt.trajectory.schedule import SCHEDULE_SHARE
from staghunt.trajectory.team import RowTeam, TeamTrajectory, Track, end_time, row_of
from staghunt.world import Cylinder, Prism
from staghunt.world.dynamic import Dynamics, max_motion_speed

CHECK_STEP_S = 0.05
"""Time step of the acceptance's samples (s)."""
STRAGGLER_STEP_S = 0.1
"""Time step of the commit rule's check (:meth:`Acceptance.stragglers`; UAVs apart by metres)."""
LEAD_IN_MIN_SPEED = 0.5
"""m/s: below this the switch state counts as at rest for the lead-in (:func:`lead_in`)."""
CURVE_SLACK = 0.2
"""Metres a re-plan's game keeps beyond the clearance its acceptance asks: the timed curve
leaves the planned polyline by up to about 0.15 m between waypoints (3 m sub-legs), and a best
reply lies on its constraints."""
TIMING_SLACK = 0.1
"""Metres the game's separation limit exceeds the acceptance's: the timed curve leaves the
polyline between waypoints by centimetres, so a best reply at exactly the game's limit (an
equilibrium lies on its constraints) would otherwise fail the check by a few centimetres
(measured: 4.44-4.49 m against 4.5 m) and could not be flown."""


def game_margins(accepted: Margins) -> tuple[float, float]:
    """``(clearance, d_s)`` the game keeps for a plan accepted at ``accepted`` (the required
    margins grown by the tracking allowance): :data:`CURVE_SLACK` and :data:`TIMING_SLACK` more.
    The re-plans' game (:meth:`staghunt.flight.replan.Replanner._problem`) and the take-off plan
    ``fly`` solves (:func:`staghunt.flight.offline.takeoff_scenario`) both keep them."""
    return accepted.clearance + CURVE_SLACK, accepted.separation + TIMING_SLACK


@dataclass
class KnownWorld:
    """What the planner knows of the site: the scenario's static obstacles, the appeared ones
    it has sensed (by name), and the names it knows to be gone."""

    scenario: Scenario
    sensed: dict[str, Cylinder | Prism] = field(default_factory=dict)
    removed: set[str] = field(default_factory=set)

    def shapes(self) -> tuple[tuple[Cylinder, ...], tuple[Prism, ...]]:
        w = self.scenario.world
        cyl = [c for c in w.cylinders if c.name not in self.removed]
        prm = [p for p in w.prisms if p.name not in self.removed]
        for name, s in self.sensed.items():
            if name not in self.removed:
                (cyl if isinstance(s, Cylinder) else prm).append(s)
        return tuple(cyl), tuple(prm)


def to_xyh(scenario: Scenario, absolute: np.ndarray) -> np.ndarray:
    """``(..., 3)`` absolute ``(x, y, z)`` -> ``(x, y, h)`` above the ground."""
    out = np.array(absolute, dtype=float, copy=True)
    out[..., 2] -= scenario.world.terrain.height(out[..., 0], out[..., 1])
    return out


def sub_scenario(scenario: Scenario, starts_xyh: np.ndarray, cylinders: tuple[Cylinder, ...],
                 prisms: tuple[Prism, ...], goals_xyh: np.ndarray | None = None) -> Scenario:
    """``scenario`` with new starts ``(N, 3)`` ``(x, y, h)`` (and goals, if given) and the given
    obstacles (formation, weights and settings unchanged)."""
    goals = [u.goal for u in scenario.team] if goals_xyh is None else [tuple(float(v) for v in g) for g in goals_xyh]
    team = tuple(replace(u, start=tuple(float(v) for v in s), goal=g)
                 for u, s, g in zip(scenario.team, starts_xyh, goals))
    world = replace(scenario.world, cylinders=cylinders, prisms=prisms)
    return replace(scenario, team=team, world=world)


def _going(traj: TeamTrajectory, t: float, row: int) -> tuple[TeamTrajectory, int, float]:
    """Where UAV ``row`` of ``traj`` was going at ``t``: the trajectory under any stop it is
    making there, the row in it and the time along it (a stop's warped time)."""
    if isinstance(traj, Track):
        _, inner, r = traj.segment_at(t)
        return _going(inner, t, r)
    if isinstance(traj, RowTeam):
        return _going(traj.parts[row], t, traj.rows[row])
    if isinstance(traj, Reference):
        return _going(traj.piece_at(t), t, row)
    if isinstance(traj, Piece) and traj.kind in ("stop", "slow") and traj.base is not None:
        return _going(traj.base, float(traj.warp(np.array([t]))[0][0]), row)
    return traj, row, t


TAIL_GAP_M = 1.0
"""A planned point closer than this (m, every UAV) to where the team is at a receding horizon's
end is not kept in the tail beyond it (:func:`route_beyond`): the curve there leaves the
polyline by centimetres, and a leg that short would be a jog of the path."""


def route_beyond(base: TeamTrajectory, t: float) -> np.ndarray | None:
    """``(N, M, 3)`` absolute: the planned points the team's timed path passes after ``t`` (its
    knots, the polyline that was planned and checked), ``None`` unless every UAV of ``base``
    flies a row of one timed path then. A receding-horizon re-plan keeps these beyond its
    horizon: samples of the curve in time carried its wobbles and, where it crawled, points
    centimetres apart at right angles into the next plan's path, which slowed its timing in
    turn (benchmarks/JOURNAL.md, "Closed loop: where the extra time goes")."""
    found = [_going(base, t, n) for n in range(base.n_uavs)]
    piece, _, tau = found[0]
    if not isinstance(piece, Piece) or piece.kind != "path" or any(f[0] is not piece for f in found):
        return None
    rows = [f[1] for f in found]
    points = piece.points[rows][:, piece.knots > tau + 1e-9]
    here = piece.state(np.array([tau]))[0][rows, 0]  # (N, 3)
    near = np.linalg.norm(points - here[:, None], axis=-1).max(axis=0) < TAIL_GAP_M  # (M,)
    return None if near.all() else points[:, int(np.argmin(near)):]  # from the first point not near


def warm_plan(scenario: Scenario, base: TeamTrajectory, t_s: float, K: int,
              until: float | None = None) -> np.ndarray:
    """``(N, K, 3)`` ``(x, y, h)``: the rest of the path each UAV of ``base`` is flying (or was,
    before a stop) after ``t_s``, sampled at ``K`` evenly spaced times up to its end (or
    ``until``): the warm start of a re-plan."""
    out = np.empty((base.n_uavs, K, 3))
    for n in range(base.n_uavs):
        traj, row, tau = _going(base, t_s, n)
        end = end_time(traj) if until is None else min(end_time(traj), until - t_s + tau)
        tau = min(max(tau, float(traj.span[0][row])), max(end, tau))
        times = tau + (max(end, tau) - tau) * np.arange(1, K + 1) / (K + 1)
        out[n] = traj.state(times)[0][row]
    return np.clip(to_xyh(scenario, out), scenario.world.bounds.lower, scenario.world.bounds.upper)


@dataclass(frozen=True, eq=False)
class Start:
    """Where a re-plan starts: at ``t_s``, after ``base`` (what each UAV flies until then), in
    the state ``pos``, ``vel``, ``acc`` ``(N, 3)`` (absolute site, m, m/s, m/s^2)."""

    t_s: float
    base: TeamTrajectory
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray

    @classmethod
    def measured(cls, base: TeamTrajectory, t_s: float, t_m: np.ndarray, pos: np.ndarray,
                 vel: np.ndarray) -> tuple["Start", float]:
        """The start from each UAV's measured position and velocity ``(N, 3)`` at times ``t_m``
        ``(N,)``: ``base`` at ``t_s`` plus the measured departure from it at ``t_m`` (tracking
        error, noise), acceleration ``base``'s. Returns it and the largest departure (m)."""
        s = base.state(np.array([t_s]))[:, :, 0]  # (4, N, 3)
        times, at = np.unique(t_m, return_inverse=True)
        then = base.state(times)[:, np.arange(len(t_m)), at.ravel()]  # (4, N, 3): UAV n at its t_m
        off_p, off_v = pos - then[0], vel - then[1]
        return cls(t_s, base, s[0] + off_p, s[1] + off_v, s[2]), float(np.linalg.norm(off_p, axis=-1).max())


def lead_in(acceptance: "Acceptance", start: Start) -> np.ndarray | None:
    """``(N, 3)`` absolute lead-in points of a re-plan from a moving ``start``, where the new plan
    starts: each UAV goes on along its velocity for its stopping distance at the timing's braking
    rate (``|v|^2 / 2 a``, ``a`` = ``max_acceleration`` x
    :data:`~staghunt.trajectory.schedule.SCHEDULE_SHARE`), so that the timing can take a sharp
    first turn from the switch speed. A UAV whose lead-in would come closer than the game's
    clearance (:func:`game_margins`) to a known obstacle, or leave the site, goes on for its
    stopping distance at ``max_acceleration`` only. ``None`` when the team is nearly at rest
    (:data:`LEAD_IN_MIN_SPEED`), or such a short lead-in leaves the site or comes closer than
    the accepted clearance to a known obstacle: the plan then starts at the switch state.

    At ``max_acceleration`` for every UAV (before), the schedule's backward pass slowed the start
    below the switch speed for a sharp first turn, the spline overshot the lead-in's end and
    came back, and stretching the schedule made it worse: in 39 of 100 scenario-2 episodes (fixed
    latency) a UAV flew 2 m or more backwards (benchmarks/JOURNAL.md, "Closed loop: the lead-in at the timing's braking
    rate")."""
    speed = np.linalg.norm(start.vel, axis=-1)
    if speed.max() < LEAD_IN_MIN_SPEED:
        return None
    ahead = start.vel / np.maximum(speed, 1e-9)[:, None]
    a_max = acceptance.scenario.vehicle.max_acceleration
    short = start.pos + ahead * (speed**2 / (2.0 * a_max))[:, None]
    inside, clear = _lead_room(acceptance, start.pos, short)
    if not inside.all() or np.any(clear < acceptance.margins.clearance):
        return None
    long = start.pos + ahead * (speed**2 / (2.0 * SCHEDULE_SHARE * a_max))[:, None]
    inside, clear = _lead_room(acceptance, start.pos, long)
    roomy = inside & (clear >= game_margins(acceptance.margins)[0])
    return np.where(roomy[:, None], long, short)


def _lead_room(acceptance: "Acceptance", pos: np.ndarray, lead: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(N,)`` each: whether ``lead`` ``(N, 3)`` lies in the site, and the least clearance to
    the known obstacles along the straight lead-ins from ``pos`` ``(N, 3)``."""
    sc = acceptance.scenario
    xyh = to_xyh(sc, lead)
    inside = np.all((xyh >= np.asarray(sc.world.bounds.lower)) & (xyh <= np.asarray(sc.world.bounds.upper)), axis=-1)
    along = pos[:, None] + (lead - pos)[:, None] * np.linspace(0.0, 1.0, 9)[None, :, None]
    r = np.array([u.radius for u in sc.team])
    return inside, static_clearance(*acceptance.known.shapes(), along, r).min(axis=1)


@dataclass(frozen=True)
class Acceptance:
    """The planner's acceptance of a plan: the one safety judge (:func:`staghunt.safety.judge`)
    on the plan's reference sampled every :data:`CHECK_STEP_S`, against what the planner knows
    (static and sensed obstacles, the known motions at their true positions), with the
    scenario's required margins grown by ``allowance`` (the tracking error it leaves to the
    vehicles); a known motion's clearance also gets the distance the UAV and the motion can
    close between two samples."""

    scenario: Scenario
    known: KnownWorld
    dyn: Dynamics
    allowance: float

    @property
    def margins(self) -> Margins:
        return Margins.required(self.scenario).grown(self.allowance)

    def check(self, traj: TeamTrajectory, t0: float, t1: float, margins: Margins | None = None,
              known: KnownWorld | None = None, motion_extra: float = 0.0, motions: bool = True) -> Verdict:
        """Judge ``traj`` over ``[t0, t1]`` (``margins``: other margins than :attr:`margins`;
        ``known``: another view of the site; ``motion_extra``: metres more from the known
        motions; ``motions=False``: the fixed and sensed obstacles, team-mates, ground and
        ceiling only)."""
        sc = self.scenario
        t = _samples(t0, t1)
        pos = traj.state(t)[0]
        scene = Scene.fixed(sc.world, *(known or self.known).shapes(), motions=self.dyn if motions else None)
        return judge(scene, np.array([u.radius for u in sc.team]), t, pos, margins or self.margins,
                     [u.name for u in sc.team], motion_margin=self.closing + motion_extra)

    @property
    def closing(self) -> float:
        """Metres a UAV and a known motion can close between two samples (added to the
        motions' required clearance)."""
        return (self.scenario.vehicle.max_speed + max_motion_speed(self.dyn)) * CHECK_STEP_S / 2

    def clear_of_motions(self, traj: TeamTrajectory, t0: float, t1: float) -> bool:
        """Whether ``traj`` keeps the known motions' clearance over ``[t0, t1]``, as :meth:`check`
        asks it (the same samples and margin): a screen for re-timings of paths already
        judged against everything else (:meth:`Fallback.yield_to`), whose one candidate that
        passes it is then judged in full."""
        t = _samples(t0, t1)
        r = np.array([u.radius for u in self.scenario.team])
        clear, _ = moving_clearance(self.dyn, traj.state(t)[0], t, r)
        return bool(np.all(clear >= self.margins.clearance + self.closing))

    def stragglers(self, new: TeamTrajectory, base: TeamTrajectory, t_s: float, learn: float) -> list[str]:
        """The commit rule's check (RMADER's, for one planner): a UAV that misses the plan
        ``new`` (starting at ``t_s``) flies its row of ``base`` for ``learn`` seconds more (until
        a heartbeat tells it), then holds, braking (:func:`~staghunt.flight.onboard.hold_piece`),
        while its team-mates fly ``new``. Returns the problems: a team-mate's new path within the
        required separation of a straggler's, for each UAV as the straggler."""
        sc = self.scenario
        r = np.array([u.radius for u in sc.team])
        names = [u.name for u in sc.team]
        t_h = t_s + learn
        problems: list[str] = []
        for j in range(sc.n_uavs):
            track = Track(((t_s, *row_of(base, j)),))
            hold = hold_piece(track, t_h, sc.vehicle, HoldReason.MISSED)
            late = track.then(t_h, hold, 0)
            t = np.arange(t_s, hold.arrival + STRAGGLER_STEP_S, STRAGGLER_STEP_S)
            mine = late.state(t)[0][0]  # (T, 3)
            theirs = new.state(t)[0]  # (N, T, 3)
            d = np.linalg.norm(theirs - mine[None], axis=-1)  # (N, T)
            d[j] = np.inf
            need = sc.costs.safe_distance + r + r[j]
            bad = d <= need[:, None]
            if bad.any():
                i, k = np.unravel_index(np.argmax(bad), bad.shape)
                problems.append(f"if {names[j]} missed the plan, {names[i]} would come {d[i, k]:.2f} m from it at "
                                f"t = {t[k]:.1f} s (required more than {need[i]:.2f} m)")
        return problems

    def later_only(self, new: Reference, verdict: Verdict, after: float, margins: Margins) -> bool:
        """Whether ``new``, refused by ``verdict`` (its check with ``margins``), breaks nothing
        but the clearance of known motions, and that only from ``after`` on (a re-plan's start
        plus the conflict horizon, ``FlyConfig.later_conflicts``): the station's
        predicted-conflict re-plan meets those conflicts when they come within the horizon, as
        it meets any plan's, and the plan is flown meanwhile (a moving team's re-plan has no
        time left for another solve around a window tens of seconds away: refused, the plan
        stopped the team)."""
        if not verdict.windows or min(a for _, a, _ in verdict.windows) <= after:
            return False
        return self.check(new, new.pieces[0].t0, new.arrival, margins, motions=False).safe

    def problem_margins(self, clearance: float, off_polyline: bool = False) -> Margins:
        """The acceptance's margins for a re-plan whose game keeps ``clearance`` to obstacles:
        :data:`CURVE_SLACK` less (at least 0) for the dense curve, which keeps within about
        0.15 m of the game's polyline; for a curve ``off_polyline`` (the smooth one,
        :data:`~staghunt.trajectory.quintic.SMOOTH_SPACING`, which rounds the polyline's corners
        by more, or one without the game's waypoints that turn a UAV back), at least the
        acceptance's own, whatever the game granted a UAV within them."""
        c = max(0.0, clearance - CURVE_SLACK)
        return replace(self.margins, clearance=max(c, self.margins.clearance) if off_polyline else c)

    def away_from(self, traj: TeamTrajectory, t0: float, t1: float, at: np.ndarray) -> list[str]:
        """The problems of ``traj`` over ``[t0, t1]`` at the acceptance's own margins with the
        known fixed obstacles other than those within the game's clearance of the points ``at``
        ``(N, P, 3)`` where the plan starts. A game whose UAV starts within its clearance of an
        obstacle relaxes the clearance to what the UAV has (:func:`game_problem`), for the whole
        plan: this keeps the relaxation to the obstacles it was granted for (a receding plan
        from 1.04 m of a pop-up passed a fixed obstacle 22 m on at 1.00 m, accepted at
        0.84 m: scenario 2 episode 84 of benchmarks/replan.py at a fixed latency)."""
        need = game_margins(self.margins)[0]
        r = np.array([u.radius for u in self.scenario.team])
        cyl, prm = self.known.shapes()
        near = {o.name for o in cyl if float(static_clearance((o,), (), at, r).min()) < need}
        near |= {o.name for o in prm if float(static_clearance((), (o,), at, r).min()) < need}
        view = KnownWorld(self.scenario, dict(self.known.sensed), set(self.known.removed) | near)
        verdict = self.check(traj, t0, t1, self.margins, known=view, motions=False)
        return verdict.problems([u.name for u in self.scenario.team])


def swept_obstacles(scenario: Scenario, dyn: Dynamics, windows: list[tuple[str, float, float]]
                    ) -> tuple[tuple[Cylinder, ...], tuple[Prism, ...]]:
    """The swept stand-ins (:meth:`Dynamics.swept`) of the conflict ``windows`` ``(name, from,
    to)``, less any that holds a UAV's start or goal in ``scenario`` within the hard clearance:
    the UAV is there at another time than the motion (the acceptance judges it), and a
    stand-in around an end would leave no plan at all."""
    cyl: list[Cylinder] = []
    prm: list[Prism] = []
    for name, a, b in windows:
        c2, p2 = dyn.swept(a, b, {name})
        cyl += c2
        prm += p2
    g = scenario.world.terrain
    ends = np.concatenate([to_absolute(g, scenario.starts()), to_absolute(g, scenario.goals())])
    r = np.tile(np.array([u.radius for u in scenario.team]), 2)
    need = scenario.costs.min_clearance
    keep_c = tuple(c for c in cyl if np.all(static_clearance((c,), (), ends[:, None], r) >= need))
    keep_p = tuple(p for p in prm if np.all(static_clearance((), (p,), ends[:, None], r) >= need))
    return keep_c, keep_p


def _samples(t0: float, t1: float) -> np.ndarray:
    """The acceptance's instants over ``[t0, t1]``, every :data:`CHECK_STEP_S` at most."""
    return np.linspace(t0, max(t1, t0), max(2, math.ceil((t1 - t0) / CHECK_STEP_S) + 1))


def game_problem(scenario: Scenario, dyn: Dynamics, accepted: Margins, starts: np.ndarray,
                 cyl: tuple[Cylinder, ...], prm: tuple[Prism, ...], windows: list[tuple[str, float, float]],
                 goals: np.ndarray | None = None) -> Scenario:
    """The scenario a re-plan's team solves: the known obstacles ``cyl``, ``prm`` plus the
    swept stand-ins of the ``windows``, the ``starts`` ``(N, 3)`` and ``goals`` (default the
    scenario's) as ``x, y, h``, the clearance and ``d_s`` grown as the acceptance's margins
    ``accepted`` ask plus the curve's and timing's slack (:func:`game_margins`). A UAV whose
    start is already closer than that to an obstacle (a stop short of a pop-up) relaxes the
    clearance to what it has, so that a path away from it exists: its paths may leave
    sideways, not come closer (the solver's plans lie on their constraints: relaxed to a share
    of it, they came closer than the UAV's own reflex lets a reference come, it held, and
    re-planned from there closer still: scenario2 episode 67 of benchmarks/replan.py)."""
    sub = sub_scenario(scenario, starts, cyl, prm, goals)
    more_c, more_p = swept_obstacles(sub, dyn, windows)
    sub = sub_scenario(scenario, starts, cyl + more_c, prm + more_p, goals)
    need, d_s = game_margins(accepted)
    sub = replace(sub, costs=replace(sub.costs, safe_distance=d_s, min_clearance=need))
    at = to_absolute(sub.world.terrain, starts[:, None])
    r = np.array([u.radius for u in sub.team])
    have = float(static_clearance(sub.world.cylinders, sub.world.prisms, at, r).min(initial=math.inf))
    if have < need:
        sub = replace(sub, costs=replace(sub.costs, min_clearance=max(0.0, have)))
    return sub


def covers(a: tuple[str, float, float], b: tuple[str, float, float]) -> bool:
    return a[0] == b[0] and a[1] <= b[1] and b[2] <= a[2]
