"""The safety fallbacks of a re-plan: synchronised stops (to hover, before a plan from rest, or in
an emergency) and a hovering team's sidestep out of a known motion's way.

Every fallback is a plan like any other: a :class:`~staghunt.trajectory.quintic.Reference`
whose first piece starts when the UAVs switch to it, judged by the planner's
:class:`~staghunt.flight.known.Acceptance` before it is sent. A stop slows the team's current
trajectory (each UAV's row of it) down with one common time warp, so every UAV stays on the
path already checked (:func:`~staghunt.trajectory.quintic.stop_piece`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from staghunt.flight.known import Acceptance
from staghunt.flight.records import ReplanStatus
from staghunt.safety.measure import static_clearance
from staghunt.solvers.improve import Deadline
from staghunt.trajectory.quintic import Piece, Reference, slow_piece, stop_piece, timed_path
from staghunt.trajectory.team import RowTeam, TeamTrajectory, Track, end_time

YIELD_DELAYS = (1.0, 2.0, 3.0, 5.0, 8.0, 12.0)
"""Seconds a yield (:meth:`Fallback.yield_to`) may delay the team's arrival, tried in this order."""
YIELD_FACTORS = (0.25, 0.1)
"""Shares of its planned pace a yield slows the team to, tried in this order for each delay
(never a hover: that is a stop)."""
EMERGENCY_FACTORS = (2.0, 3.0)
"""Multiples of ``max_acceleration`` an emergency stop may brake at, tried in this order: the
mission limit (3 m/s^2 by default) is well below a multirotor's capability (the simulated
Hummingbird's thrust-to-weight ratio is about 10: 9 m/s^2 of braking tilts it by 43 degrees at
1.4 g of thrust), and a stop that the lower factor cannot make clear of what is known uses the
higher one."""


def stopping(base: TeamTrajectory, t: float) -> bool:
    """Whether every UAV of ``base`` is at rest or coming to rest (flying a stop) at ``t``."""
    speed = np.linalg.norm(base.state(np.array([t]))[1][:, 0], axis=-1)
    return all(speed[n] < 1e-3 or _is_stop_under(base, t, n) for n in range(base.n_uavs))


def rest_time(base: TeamTrajectory, t: float, within: float = 60.0) -> float:
    """The first time from ``t`` on when every UAV of ``base`` is at rest (every 0.1 s;
    ``t + within`` at the latest)."""
    grid = t + np.arange(0.0, within + 0.1, 0.1)
    speed = np.linalg.norm(base.state(grid)[1], axis=-1).max(axis=0)
    still = np.flatnonzero(speed < 1e-3)
    return float(grid[still[0]]) if still.size else t + within


def _piece_end(base: TeamTrajectory, t: float) -> float:
    """When the piece of ``base`` flown at ``t`` ends (s): what a yield from ``t`` slows."""
    return end_time(base.piece_at(t) if isinstance(base, Reference) else base)


def _is_stop_under(base: TeamTrajectory, t: float, n: int) -> bool:
    """Whether UAV ``n`` of ``base`` flies a stop piece at ``t``."""
    traj, row = base, n
    while True:
        if isinstance(traj, Track):
            _, traj, row = traj.segment_at(t)
        elif isinstance(traj, RowTeam):
            traj, row = traj.parts[row], traj.rows[row]
        elif isinstance(traj, Reference):
            traj = traj.piece_at(t)
        else:
            return isinstance(traj, Piece) and traj.kind == "stop"


@dataclass(frozen=True)
class Fallback:
    """The fallbacks of one flight: its acceptance (scenario, what is known, margins) and the
    horizon (s) a hovering team must stay clear of the known motions."""

    acceptance: Acceptance
    horizon: float

    def when_none_passes(self, base: TeamTrajectory, t_s: float, t_soon: Callable[[], float], at_rest: bool,
                         deadline: Deadline | None = None) -> tuple[Reference | None, ReplanStatus]:
        """What the team flies when a re-plan switching at ``t_s`` finds no plan: the current plan
        (``None``, kept) if it stays clear over the horizon from ``t_soon()`` (the earliest a
        stop decided now reaches the UAVs): a stop would only cut a sidestep under way short,
        perhaps where a known motion will pass; else a hovering (``at_rest``) team's
        :meth:`sidestep` (sought until ``deadline``); else a :meth:`stop` (from ``t_soon()``
        asked again: the sidestep's search took time)."""
        soon = t_soon()
        if self.acceptance.check(base, soon, max(t_s, soon) + self.horizon).safe:
            return None, ReplanStatus.KEPT  # a hover that stays clear needs no sidestep either: one check
        moved = self.sidestep(base, t_s, deadline) if at_rest else None
        if moved is not None:
            return moved, ReplanStatus.SIDESTEP
        soon = t_soon()
        return self.stop(base, soon, max(t_s, soon))

    @staticmethod
    def soonest_yield(base: TeamTrajectory, t_s: float) -> float:
        """The soonest any :meth:`yield_to` plan from ``t_s`` can arrive (s): a yield's slowed
        piece ends one of :data:`YIELD_DELAYS` after the piece flown at ``t_s``
        (:func:`~staghunt.trajectory.quintic.slow_piece`)."""
        return _piece_end(base, t_s) + min(YIELD_DELAYS)

    def yield_to(self, base: TeamTrajectory, t_s: float, deadline: Deadline | None = None,
                 learn: float | None = None, by: float = math.inf) -> Reference | None:
        """The team's current paths flown from ``t_s`` on, slowed in sync to one of
        :data:`YIELD_FACTORS` of their pace and sped up again
        (:func:`~staghunt.trajectory.quintic.slow_piece`) so as to arrive the first of
        :data:`YIELD_DELAYS` later that passes the acceptance to the end (sought until
        ``deadline``), and the commit rule's check if ``learn`` is given (a UAV that misses the
        yield flies on at its pace for ``learn`` seconds: :meth:`Acceptance.stragglers`);
        ``None`` if none does. Only delays arriving by ``by`` (s) are tried: a re-plan with a
        moving plan arriving then wants no later yield, and each candidate's check runs to its
        end (a predicted conflict's yield search took 35 ms of a 200 ms deadline where a moving
        plan won, 17 ms with the bound: benchmarks/JOURNAL.md, "Closed loop: yields bounded by
        the moving plan"). Path-velocity decomposition (Kant and Zucker 1986): the paths keep
        every margin to what does not move and to each other, and only the timing changes, so
        that a known motion crossing them passes first; the paths, and so the game's costs, are
        the plan's."""
        acc = self.acceptance
        if not acc.dyn.known_motion or not acc.check(base, t_s, end_time(base), motions=False).safe:
            return None  # blocked by what does not move: no timing helps
        last = _piece_end(base, t_s)
        for delay in (d for d in YIELD_DELAYS if last + d <= by):
            for factor in YIELD_FACTORS:
                if deadline is not None and deadline.passed:
                    return None
                piece = slow_piece(base, t_s, acc.scenario.vehicle, delay, factor)
                if piece is None:
                    continue
                plan = Reference((piece,))
                if (acc.clear_of_motions(plan, t_s, piece.t1) and acc.check(plan, t_s, piece.t1).safe
                        and (learn is None or not acc.stragglers(plan, base, t_s, learn))):
                    return plan
        return None

    def stop(self, base: TeamTrajectory, t_soon: float, t_s: float) -> tuple[Reference, ReplanStatus]:
        """A synchronised stop at ``t_s`` within ``max_acceleration``; if that stop would come
        closer than the acceptance's margins to something known, an emergency stop from
        ``t_soon`` (the earliest the UAVs can get it) with the braking warp at the first of
        :data:`EMERGENCY_FACTORS` times the acceleration that passes, or else the stop with no
        contact (with an obstacle or a team-mate) that keeps the most clearance."""
        limits = self.acceptance.scenario.vehicle
        options = []
        tries = [(ReplanStatus.STOP, t_s, limits)] + [
            (ReplanStatus.EMERGENCY_STOP, t_soon, replace(limits, max_acceleration=f * limits.max_acceleration))
            for f in EMERGENCY_FACTORS]
        for status, t0, lim in tries:
            piece = stop_piece(base, t0, lim, brake=status is ReplanStatus.EMERGENCY_STOP)
            plan = Reference((piece,))
            verdict = self.acceptance.check(plan, t0, piece.t1 + 1.0)
            if verdict.safe:
                return plan, status
            options.append(((not verdict.contact, verdict.least_clearance), plan, status))
        _, plan, status = max(options, key=lambda o: o[0])  # no contact first, then the most clearance
        return plan, status

    def stop_later(self, base: TeamTrajectory, t_soon: float, t_stop: float) -> bool:
        """Whether the team may fly ``base`` on from ``t_soon`` and still stop in sync at
        ``t_stop`` within ``max_acceleration``, both passing the acceptance: a stop that can
        wait for the next re-plan."""
        acc = self.acceptance
        stop = stop_piece(base, t_stop, acc.scenario.vehicle)
        return (acc.check(base, t_soon, max(t_soon, t_stop)).safe
                and acc.check(Reference((stop,)), t_stop, stop.t1 + 1.0).safe)

    def stop_short(self, base: TeamTrajectory, t_soon: float, t_s: float) -> tuple[Piece, bool]:
        """The stop before a plan from rest: at ``t_s`` within ``max_acceleration``, or, if that
        leaves a UAV within twice the hard clearance of something known (the encoding then has
        little room to leave), from ``t_soon`` with twice the acceleration when that rests
        farther. Returns the stop piece and whether it breaks the acceptance."""
        sc = self.acceptance.scenario
        limits = sc.vehicle
        cyl, prm = self.acceptance.known.shapes()
        r = np.array([u.radius for u in sc.team])
        best = None
        for t0, lim in ((t_s, limits), (t_soon, replace(limits, max_acceleration=2 * limits.max_acceleration))):
            stop = stop_piece(base, t0, lim)
            bad = not self.acceptance.check(Reference((stop,)), t0, stop.t1 + 1.0).safe
            rest = stop.state(np.array([stop.t1]))[0]
            room = float(static_clearance(cyl, prm, rest, r).min(initial=math.inf))
            if best is None or (not bad and (best[1] or room > best[2])):
                best = (stop, bad, room)
            if not bad and room >= 2 * sc.costs.min_clearance:
                break
        assert best is not None
        return best[0], best[1]

    def sidestep(self, base: TeamTrajectory, t_s: float, deadline: Deadline | None = None) -> Reference | None:
        """A team hovering where a known motion will pass: move the whole formation (one rigid
        offset, so separations hold) to a spot that stays clear for the horizon, trying 16
        headings and offsets of 1 to 4 times the largest moving radius plus body and
        clearance, until ``deadline`` (wall clock; ``None``: every spot): first the spots where
        the team rests clear of everywhere the threatening motions go meanwhile (their swept
        stand-ins, :meth:`Dynamics.swept`), nearest first, the farthest from it first among
        equals, then the others, by that clearance. In heading order, a re-plan's deadline
        allowed about a dozen spots, the same ones every re-plan, and a team hovering on a
        truck's road never got past the nearest ring (scenario2 episode 2 of
        benchmarks/replan.py: 38 stops in 9 s, then contact). ``None`` when no known motion
        threatens the hover (it is safe, or only something fixed or sensed breaks its
        margins: a rigid offset sized for a moving obstacle is not the way out of that) or no
        spot is clear."""
        acc, sc = self.acceptance, self.acceptance.scenario
        dyn = acc.dyn
        if not dyn.known_motion:
            return None
        hover = acc.check(base, t_s, t_s + self.horizon)
        if hover.safe or not hover.windows:
            return None
        t0 = rest_time(base, t_s)
        here = base.state(np.array([t0]))[0][:, 0]  # (N, 3) where the team rests
        size = max([m.radius for m in dyn.moving] + [j.width for j in dyn.jibs], default=1.0)
        step = size + max(u.radius for u in sc.team) + sc.costs.min_clearance
        b = sc.world.bounds
        a = np.radians(np.arange(0.0, 360.0, 22.5))
        dist = np.repeat([1.0, 2.0, 3.0, 4.0], a.size)
        offsets = dist[:, None] * step * np.column_stack([np.cos(np.tile(a, 4)), np.sin(np.tile(a, 4)), np.zeros_like(dist)])
        spots = here[None] + offsets[:, None]  # (S, N, 3)
        inside = ((spots[..., 0].min(1) >= b.xmin) & (spots[..., 0].max(1) <= b.xmax)
                  & (spots[..., 1].min(1) >= b.ymin) & (spots[..., 1].max(1) <= b.ymax))
        names = {w[0] for w in hover.windows}
        swept = dyn.swept(t_s, t_s + self.horizon, names)
        r = np.array([u.radius for u in sc.team])
        clear = static_clearance(*swept, np.swapaxes(spots, 0, 1), r).min(axis=0, initial=math.inf)  # (S,)
        out = clear < acc.margins.clearance
        for k in sorted(np.flatnonzero(inside), key=lambda k: (out[k], dist[k] if not out[k] else 0, -clear[k])):
            if deadline is not None and deadline.passed:
                return None
            plan = Reference((timed_path(np.stack([here, spots[k]], axis=1), t0, sc.vehicle),))
            if acc.check(plan, t0, plan.arrival + self.horizon).safe:
                return plan
        return None
