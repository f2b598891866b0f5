"""Real-time trajectory modification: the game re-solved in flight from the team's measured state.

A re-plan (:meth:`Replanner.solve`) starts from a :class:`Start`: the time ``t_s`` the new plan
starts (the trigger plus the deadline plus the link's worst delay, so that it reaches the
UAVs in time), what each UAV flies until then (``base``) and the state each UAV is *measured*
in, carried to ``t_s`` (:meth:`Start.measured`). It

1. builds the problem the team knows: the goals (or, for a receding-horizon re-plan, where the
   current plan is ``horizon`` seconds on), the switch positions as starts (moving: their
   lead-in points, each UAV's stopping distance at the timing's braking rate ahead along its
   velocity), the static and sensed obstacles and the swept volumes of the known motions over
   the predicted conflicts' windows, margins grown for the tracking allowance
   (:func:`~staghunt.flight.known.game_problem`);
2. warm-starts the game from the current plan, pushed clear of a new obstacle that cuts it, and runs
   the rounds until they converge or the deadline's game share is spent (:func:`staghunt.solvers.improve.anytime_rounds`);
3. times the new paths from the measured state and accepts them with the one safety judge
   (:class:`~staghunt.flight.known.Acceptance`); a new conflict with a motion adds its window
   and the team solves again, up to ``attempts`` times;
4. certifies and improves the accepted plan while the deadline allows
   (:func:`staghunt.solvers.improve.certify_and_improve`).

From a moving state the same is solved from rest after a synchronised stop, side by side on
two cores (:mod:`~staghunt.flight.aside`) or after the moving solve fails on one, and flown if
the moving one fails. If neither passes, the fallback (:mod:`~staghunt.flight.fallback`):
hovering, a sidestep out of a known motion's way; else what the team flies if it stays clear
over the conflict horizon (a stop would cut a sidestep short), or a stop to hover.
"""

from __future__ import annotations

import itertools
import math
import threading
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, replace
from typing import Any, Callable

import numpy as np

from staghunt.costs import CostModel, to_absolute
from staghunt.encoding import ANGLE_RANGE
from staghunt.engine import Engine, get_engine, side_by_side
from staghunt.flight import aside
from staghunt.flight.config import FlyConfig
from staghunt.flight.fallback import Fallback, stopping
from staghunt.flight.known import (Acceptance, KnownWorld, Start, covers, game_problem, lead_in, route_beyond,
                                   to_xyh, warm_plan)
from staghunt.flight.records import Laps, ReplanStatus, Solved
from staghunt.scenario import Scenario, SolverSettings
from staghunt.solvers.improve import Cancelled, Deadline, anytime_rounds, certify_and_improve
from staghunt.trajectory.quintic import DENSE_SPACING, SMOOTH_SPACING, Reference, soonest_timings
from staghunt.trajectory.team import TeamTrajectory, end_time
from staghunt.trajectory.timing import turn_backs
from staghunt.world.dynamic import Dynamics

WIDE_AZIMUTH = math.pi / 2
"""Half-width of the heading range of a plan from rest (a stop, or the hover): the paper's
``pi/4`` keeps every leg within 45 degrees of the goal direction, and a UAV at rest just in
front of an obstacle cannot leave it that way."""
TURN_BACK_POINTS = 3
"""Game waypoints after the lead-in's end dropped at most, for a timing in which no UAV turns
back there (:func:`~staghunt.trajectory.timing.turn_backs`)."""
MAX_STRETCH = 2.0
"""A plan from a moving switch state that must be slowed more than this to meet the limits
(a sharp turn at speed) is flown from rest instead: stop in sync, then the new plan."""
GAME_SHARE = 0.4
"""Share of the deadline the game's rounds may take; the rest is for timing, acceptance and
the certificate."""
RESERVE_SHARE = 0.10
"""Share of the deadline kept free at its end: no certificate, local pass or timing of a plan
starts that its running estimate says would end in it (the estimates' errors end there); a
timing still running when it begins stops (one more timing or check at most: a few ms), and the
game's own plan flies."""
CERTIFICATE_PRIOR = 0.25
"""A flight's first estimate of a certificate's wall time, as a share of the deadline."""
REST_SHARE = 0.85
"""Share of the deadline the plan from rest may take when it is solved after the moving one, at
most: it also leaves the fallback's running estimate free (:attr:`Replanner.fallback_s`, up to
:data:`FALLBACK_SHARE` of the deadline)."""
FALLBACK_SHARE = 0.5
"""Share of the deadline the fallback's running estimate may keep from the plan from rest."""
FALLBACK_DECAY = 0.8
"""A fallback's wall time enters its running estimate at once if longer; the estimate decays
by this factor with every fallback that is shorter."""
TAIL_STEP_S = 0.5
"""Seconds between the points a receding-horizon re-plan keeps of the current plan beyond its
horizon."""


@dataclass(frozen=True)
class _Attempt:
    """What :meth:`Replanner._attempts` found: the new plan (``None`` if none passed), the
    game's last outcome, its scenario, the problems, the solves made, the path evaluations
    spent, the heading half-width, the windows known at the end and how the plan is timed
    (``timing``: ``(start, max_stretch, lead, tail)`` for :meth:`Replanner._timed`)."""

    plan: Reference | None
    out: Any
    sub: Any
    problems: list[str]
    tries: int
    spent: int
    azimuth: float
    windows: list[tuple[str, float, float]]
    timing: tuple[Any, ...] = ()
    later: tuple[tuple[str, float, float], ...] = ()  # conflicts left to the horizon (Acceptance.later_only)


def _passed(rest: tuple[_Attempt | None, Any] | None) -> bool:
    return rest is not None and rest[0] is not None and rest[0].plan is not None


class Replanner:
    """Re-solves the game in flight for one episode; holds what it knows between re-plans.

    With the compiled engine on several cores, a re-plan from a moving state solves from that
    state and from rest after a stop *at the same time* (each solve has its own generator,
    drawn before either starts, so the flight is the same on any number of cores when the
    latency is fixed)."""

    def __init__(self, scenario: Scenario, dyn: Dynamics, config: FlyConfig, engine: Engine,
                 rng: np.random.Generator, search: SolverSettings | None = None) -> None:
        self.scenario, self.dyn, self.config, self.engine, self.rng = scenario, dyn, config, engine, rng
        self.search = search if search is not None else config.certify_search(scenario)
        self.known = KnownWorld(scenario)
        self.acceptance = Acceptance(scenario, self.known, dyn, config.allowance)
        self.fallback = Fallback(self.acceptance, config.conflict_horizon)
        self.certificate_s = 0.0  # running estimate of a certificate's wall time
        self.steps: dict[str, float] = {}  # and of the certify-and-improve loop's other steps (Deadline.steps)
        self.fallback_s = 0.0  # running estimate of the fallback's wall time (its stops' and sidestep's checks)
        # how long a UAV that missed a plan flies on before a heartbeat tells it (a tick and the
        # link's worst delay; the station sets it)
        self.learn_s = 1.0 / dyn.sensing.rate + (config.link or dyn.link).worst_delay
        self._certifier, self._workers = side_by_side(engine)
        self._solo = get_engine("numba", threads=1) if self._workers > 1 else engine
        self.hint: np.ndarray | None = None  # (N, K, 3) the best try of a deferred re-plan
        self.laps = Laps()  # where the last solve's wall time went
        self.later: dict[int, tuple[tuple[str, float, float], ...]] = {}  # plans passed by Acceptance.later_only
        self.answers_event = True  # the solve answers an event (not a receding-horizon re-plan)
        if self._workers > 1:
            aside.start(PRELOAD)

    def solve(self, start: Start, t_soon: Callable[[], float], scale: int = 1,
              windows: list[tuple[str, float, float]] | None = None, deadline: Deadline | None = None,
              horizon: float = 0.0, fallback: bool = True, defer: float = 0.0) -> Solved:
        """Re-plan from ``start``; ``t_soon()``: the earliest a stop decided now can reach the UAVs.
        ``scale``: budget factor (after a stop); ``windows``: predicted conflicts to solve
        around; ``deadline``: wall-clock budget (``None``: none); ``horizon``: re-solve only
        that many seconds of the route ahead and keep the rest (0: to the goals);
        ``fallback``: if no plan passes, sidestep, keep the current plan when it stays clear
        over the conflict horizon, or stop; else (``False``) keep the current plan
        (:attr:`ReplanStatus.KEPT`); ``defer`` (s, 0: never): if no plan passes from the moving
        state and a stop that much later still passes (:meth:`Fallback.stop_later`), keep the
        current plan (:attr:`ReplanStatus.DEFERRED`): the next solve starts from this one's
        best try (:attr:`hint`); no plan from rest is solved then."""
        cfg, sc = self.config, self.scenario
        laps = self.laps = Laps()
        self.later.clear()
        self.answers_event = fallback
        deadline = deadline or Deadline()
        full = max(0.0, deadline.left()) if deadline.end is not None else 0.0
        game = Deadline(None if deadline.end is None else deadline.end - (1 - GAME_SHARE) * full)
        K = sc.solver.waypoints
        settings = sc.solver.with_(particles=cfg.replan_particles * scale, iterations=cfg.replan_iterations, waypoints=K)
        windows = list(windows or [])
        moving_rng, rest_rng = self.rng.spawn(2)
        t_s, base = start.t_s, start.base
        until = t_s + horizon if horizon > 0 and t_s + horizon < end_time(base) - 1.0 else None
        warm = warm_plan(sc, base, t_s, K, until)
        if self.hint is not None and until is None and self.hint.shape == warm.shape:
            warm = self.hint
        self.hint = None
        at_rest = stopping(base, t_s)
        lead = None if at_rest else lead_in(self.acceptance, start)

        def moving(engine: Engine, rest_passes: Callable[[], bool] | None = None) -> _Attempt:
            return self._attempts(start, windows, warm, settings, cfg.attempts, MAX_STRETCH,
                                  WIDE_AZIMUTH if at_rest else ANGLE_RANGE, moving_rng, engine, game, lead,
                                  stop_retrying=rest_passes, until=until)

        keep_free = max((1 - REST_SHARE) * full, min(self.fallback_s, FALLBACK_SHARE * full))
        rest_args = (base, t_soon(), t_s, windows, settings, rest_rng,
                     None if deadline.end is None else deadline.end - keep_free)
        second: tuple[_Attempt | None, Any] | None = None
        # a stop that can wait for the next re-plan: no plan from rest now, the moving solve has
        # every core and every attempt the deadline allows
        can_defer = (defer > 0 and fallback and not at_rest
                     and self.fallback.stop_later(base, t_soon(), t_s + defer))
        if at_rest or not fallback or can_defer:
            first = moving(self.engine)
        elif self._workers > 1:
            first, second = self._side_by_side(moving, rest_args)
        else:
            box: list[tuple[_Attempt | None, Any]] = []

            def rest_passes() -> bool:  # solved once, when the moving solve first ends infeasible
                if not box:
                    laps.lap("game")
                    box.append(self.from_rest(*rest_args, engine=self.engine))
                    laps.lap("rest")
                return _passed(box[0])

            first = moving(self.engine, rest_passes)
            if first.plan is None:
                rest_passes()
            second = box[0] if box else None
        laps.lap("game")
        rest = second[0] if second is not None else None
        spent = first.spent + (rest.spent if rest is not None else 0)
        tries = first.tries + (rest.tries if rest is not None else 0)
        # known motions in the way: a yield, sought only if one could arrive no later than the moving plan
        yielded = None  # (Fallback.soonest_yield), until the plan from rest would end
        if first.windows and fallback and not at_rest and (
                first.plan is None or first.plan.arrival >= self.fallback.soonest_yield(base, t_s)):
            learn = self.learn_s if cfg.straggler_check else None
            yielded = self.fallback.yield_to(base, t_s, Deadline(rest_args[-1]), learn,
                                             by=math.inf if first.plan is None else first.plan.arrival)
            laps.lap("yield")
        if yielded is not None or (first.plan is None and can_defer):
            if yielded is None and first.out is not None:  # a deferral: the next solve goes on from here
                self.hint = first.out.plan
            return Solved(yielded, ReplanStatus.DEFERRED if yielded is None else ReplanStatus.YIELD, spent, tries,
                          problems=tuple(first.problems[:5]), windows=tuple(sorted(set(first.windows))))
        chosen, status, why = first, ReplanStatus.REPLANNED, ()
        if first.plan is None and rest is not None:
            if rest.plan is not None:  # why the swerve failed stays on the record
                chosen, status, why = rest, ReplanStatus.STOP_REPLANNED, tuple(first.problems[:5])
            else:
                chosen = replace(rest, problems=rest.problems or first.problems)
        used = tuple(sorted(set(chosen.windows)))
        if chosen.plan is None:
            problems = tuple(chosen.problems[:5])
            if at_rest and first.out is not None:  # the next re-plan from the hover goes on from here
                self.hint = first.out.plan
            if not fallback:
                return Solved(None, ReplanStatus.KEPT, spent, tries, problems=problems, windows=used)
            plan, status = self.fallback.when_none_passes(base, t_s, t_soon, at_rest, deadline)
            laps.lap("fallback")
            self.fallback_s = max(laps.parts["fallback"], FALLBACK_DECAY * self.fallback_s)
            return Solved(plan, status, spent, tries, problems=problems, windows=used)
        deadline.certificate_s = self.certificate_s or CERTIFICATE_PRIOR * full
        if deadline.end is not None:
            deadline = Deadline(deadline.end - RESERVE_SHARE * full, deadline.certificate_s, self.steps)
        done = certify_and_improve(  # a plan other than the game's, still timed when the reserve begins, is not flown
            chosen.sub, chosen.out.plan, chosen.plan,
            lambda p: self._timed(chosen.sub, p, *chosen.timing, stop=lambda: deadline.passed)[0],
            self.search, cfg.certify_options(), cfg.certify_rounds, self.rng, self._certifier.run_swarm,
            self._certifier, self._solo, chosen.azimuth, self._workers, deadline)
        self.certificate_s = deadline.certificate_s
        laps.lap("certificate")
        cert = done.certificate
        later = chosen.later if done.flown is chosen.plan else self.later.get(id(done.flown), ())
        if cert is None:
            return Solved(done.flown, status, spent + done.spent, tries, verdict="not certified: " + "; ".join(done.notes),
                          problems=why, windows=used, game=(chosen.sub, done.plan, chosen.azimuth), later=later)
        return Solved(done.flown, status, spent + done.spent, tries, tuple(float(u.relative) for u in cert.uavs),
                      cert.is_equilibrium, cert.verdict, why, used, later=later)

    def certify(self, game: tuple[Scenario, np.ndarray, float]) -> tuple[tuple[float, ...], bool, str, int]:
        """The certificate of a plan sent uncertified (``Solved.game``), made later, with no
        improvement (the plan is flying): its Nash gaps, whether it is an epsilon-equilibrium,
        the verdict and the path evaluations spent."""
        sub, plan, azimuth = game
        done = certify_and_improve(sub, plan, None, lambda p: None, self.search, self.config.certify_options(), 0,
                                   self.rng, self._certifier.run_swarm, self._certifier, self._solo,
                                   azimuth, self._workers)
        cert = done.certificate
        assert cert is not None
        return tuple(float(u.relative) for u in cert.uavs), cert.is_equilibrium, cert.verdict, done.spent

    def from_rest(self, base: TeamTrajectory, t_soon: float, t_s: float, windows: list[tuple[str, float, float]],
                  settings: Any, rng: np.random.Generator, end: float | None = None, *, engine: Engine,
                  cancel: Any = None) -> tuple[_Attempt | None, Any]:
        """The plan from rest: the team stops in sync (:meth:`Fallback.stop_short`) and the game
        is solved from where it rests (``None``: that stop breaks the acceptance), drawing from
        ``rng``, searching with ``engine`` until ``end`` (wall clock); ``cancel`` (an event)
        stops it after the reply in progress. Returns the attempt and the stop piece."""
        stop, bad = self.fallback.stop_short(base, t_soon, t_s)
        if bad:
            return None, stop
        stopped = Reference((stop,))
        rest = stop.state(np.array([stop.t1]))[:, :, 0]
        start = Start(stop.t1, stopped, rest[0], np.zeros_like(rest[0]), np.zeros_like(rest[0]))
        warm = warm_plan(self.scenario, stopped, stop.t1, settings.waypoints)
        attempt = self._attempts(start, list(windows), warm, settings, 2, math.inf, WIDE_AZIMUTH, rng, engine,
                                 Deadline(end), cancel=cancel, head=stop)
        return attempt, stop

    def _side_by_side(self, moving: Callable[..., _Attempt], rest_args: tuple[Any, ...]
                      ) -> tuple[_Attempt, tuple[_Attempt | None, Any]]:
        """The moving solve here and the plan from rest beside it, in the worker process
        (:mod:`staghunt.flight.aside`) or, while it is not ready or where none can run, in a
        thread; the plan from rest is cancelled once the moving one passes."""
        worker = aside.rest_worker()
        if worker is not None:
            later = worker.submit(_from_rest, self.state(), rest_args)
            box: list[tuple[_Attempt | None, Any]] = []

            def rest() -> tuple[_Attempt | None, Any]:
                if not box:
                    try:
                        box.append(later.result())
                    except BrokenProcessPool:  # the worker died: solve here (the same result)
                        aside.worker_broke()
                        box.append(self.from_rest(*rest_args, engine=self._solo))
                return box[0]

            first = moving(self._solo, lambda: _passed(rest()))
            if first.plan is not None:  # the plan from rest is not needed: stop it
                worker.cancel()
            return first, rest()
        cancel = threading.Event()
        with ThreadPoolExecutor(1) as pool:
            thread = pool.submit(self.from_rest, *rest_args, engine=self._solo, cancel=cancel)
            first = moving(self._solo, lambda: _passed(thread.result()))
            if first.plan is not None:
                cancel.set()
            return first, thread.result()

    def state(self) -> dict[str, Any]:
        """What :meth:`rebuilt` needs to make this re-planner again in another process."""
        return {"scenario": self.scenario, "dyn": self.dyn, "config": self.config, "search": self.search,
                "sensed": dict(self.known.sensed), "removed": set(self.known.removed)}

    @classmethod
    def rebuilt(cls, state: dict[str, Any], engine: Engine) -> "Replanner":
        """A re-planner from :meth:`state`, searching with ``engine`` (for its plan from rest)."""
        planner = cls(state["scenario"], state["dyn"], state["config"], engine, np.random.default_rng(0),
                      state["search"])
        planner.known.sensed.update(state["sensed"])
        planner.known.removed.update(state["removed"])
        return planner

    def _timed(self, sub: Scenario, plan: np.ndarray, start: Start, max_stretch: float, lead: np.ndarray | None,
               tail: np.ndarray | None, head: Any = None, stop: Callable[[], bool] | None = None
               ) -> tuple[Reference | None, list[str], list[tuple[str, float, float]] | None]:
        """``plan`` ``(N, K, 3)`` of ``sub`` timed from ``start`` (through the ``lead`` points,
        then ``tail`` ``(N, M, 3)`` absolute, the current plan beyond a receding horizon;
        ``head``: a stop piece flown before, from whose rest the plan starts), on the team's
        common schedule and with each UAV at its own pace, the dense curve and the smooth one,
        and again without the game's waypoints that turn a UAV back at the lead-in's end
        (:func:`~staghunt.trajectory.quintic.soonest_timings`: a timing is made only when every
        sooner one has failed the acceptance). Returns the new plan (the soonest timing that
        meets the limits within ``max_stretch`` and passes the acceptance, at
        :meth:`~staghunt.flight.known.Acceptance.problem_margins`, and at its own margins away
        from the obstacles the plan starts near), else ``None``, with the sooner one's problems
        and the conflicts with known motions found (``None``: the timing failed). ``stop()`` true
        before a timing or a check: ``None``, stopped."""
        sc = self.scenario
        goals = to_absolute(sub.world.terrain, sub.goals()[:, None])
        front = start.pos[:, None] if lead is None else np.stack([start.pos, lead], axis=1)
        parts = [front, to_absolute(sub.world.terrain, plan), goals] + ([tail] if tail is not None else [])
        points = np.concatenate(parts, axis=1)
        # also timed without the game's points that turn a UAV back at the lead-in's end
        drop = turn_backs(points, 1, TURN_BACK_POINTS) if lead is not None else 0
        tries = [points] + ([np.delete(points, np.s_[2:2 + drop], axis=1)] if drop else [])
        order = soonest_timings(tries, start.t_s, sc.vehicle, start.vel, start.acc, max_stretch=max_stretch,
                                spacings=(DENSE_SPACING, SMOOTH_SPACING), stop=stop)
        try:
            pieces = itertools.chain([next(order)], order)
        except ValueError as exc:
            return None, [str(exc)], None
        first: tuple[list[str], list[tuple[str, float, float]]] | None = None
        for i, piece in pieces:  # the sooner timing first; the next if its curve breaks a margin (none once stopped)
            loose = i > 0 or piece.spacing > DENSE_SPACING  # off the game's polyline
            margins = self.acceptance.problem_margins(sub.costs.min_clearance, loose)
            new = Reference((head, piece) if head is not None else (piece,))
            verdict = self.acceptance.check(new, new.pieces[0].t0, piece.t1, margins)
            problems = verdict.problems([u.name for u in sc.team])
            later = (self.config.later_conflicts and self.answers_event
                     and self.acceptance.later_only(new, verdict, start.t_s + self.config.conflict_horizon, margins))
            if later:
                problems = []
            if not problems and margins.clearance < self.acceptance.margins.clearance:
                problems = self.acceptance.away_from(new, new.pieces[0].t0, piece.t1, front)
            if not problems and head is None and self.config.straggler_check:
                problems = self.acceptance.stragglers(new, start.base, start.t_s, self.learn_s)
            if not problems:
                if later:
                    self.later[id(new)] = tuple(verdict.windows)
                return new, [], list(verdict.windows)
            first = first or (problems, list(verdict.windows))
        assert first is not None  # the first piece is always checked
        return None, *first

    def _attempts(self, start: Start, windows: list[tuple[str, float, float]], warm: np.ndarray, settings: Any,
                  tries: int, max_stretch: float, azimuth: float, rng: np.random.Generator, engine: Engine,
                  deadline: Deadline, lead: np.ndarray | None = None, cancel: Any = None,
                  stop_retrying: Callable[[], bool] | None = None, until: float | None = None,
                  head: Any = None) -> _Attempt:
        """Solve from ``start`` up to ``tries`` times (each new conflict with a known motion adds
        its window to ``windows``, which this call owns), headings within ``azimuth`` of the
        goal direction, drawing from ``rng``, searching with ``engine`` until ``deadline``;
        ``lead``: lead-in points (:func:`~staghunt.flight.known.lead_in`); ``until``: a receding horizon's end (the
        problem's goals are where ``start.base`` is then, and the rest of it is kept);
        ``cancel``: an event that stops the solve; ``stop_retrying()``: asked when a solve
        ends infeasible; if true (another plan passes), it is not tried again."""
        sc, cfg = self.scenario, self.config
        starts = to_xyh(sc, start.pos if lead is None else lead)
        goals, tail = None, None
        if until is not None:
            goals = to_xyh(sc, start.base.state(np.array([until]))[0][:, 0])
            tail = route_beyond(start.base, until)
            if tail is None:  # the UAVs fly different curves then: the current plan's curve, sampled
                grid = np.arange(until + TAIL_STEP_S, end_time(start.base) + TAIL_STEP_S, TAIL_STEP_S)
                tail = start.base.state(grid)[0]
        N = sc.n_uavs
        budget = settings.particles * (settings.iterations + 1) * N
        cyl, prm = self.known.shapes()
        problems: list[str] = []
        out = sub = None
        spent = 0
        timing = (start, max_stretch, lead, tail, head)
        for attempt in range(1, tries + 1):
            sub = game_problem(self.scenario, self.dyn, self.acceptance.margins, starts, cyl, prm, windows, goals)
            model = CostModel.from_scenario(sub)
            try:
                out = anytime_rounds(model, warm, settings, rng, engine.run_swarm, engine, budget, deadline,
                                     (lambda: cancel.is_set()) if cancel is not None else None, repair=True,
                                     reply_start=cfg.reply_start, azimuth=azimuth)
            except Cancelled:
                return _Attempt(None, out, sub, ["cancelled"], attempt, spent, azimuth, windows, timing)
            spent += out.evaluations
            warm = out.plan
            if engine.evaluate(model, out.plan[None]).total_violation[0] > 0:
                problems = ["no feasible plan from the switch state"]
                if (stop_retrying is not None and stop_retrying()) or deadline.passed:
                    return _Attempt(None, out, sub, problems, attempt, spent, azimuth, windows, timing)
                continue
            new, problems, found = self._timed(sub, out.plan, *timing)
            done = new is not None or found is None  # passed, or the timing itself failed
            fresh = [] if done else [w for w in found if not any(covers(o, w) for o in windows)]
            if done or not fresh or deadline.passed:
                later = self.later.get(id(new), ()) if new is not None else ()
                return _Attempt(new, out, sub, problems, attempt, spent, azimuth, windows, timing, later)
            windows.extend((n, max(start.t_s, a - cfg.window_pad), b + cfg.window_pad) for n, a, b in fresh)
        return _Attempt(None, out, sub, problems, tries, spent, azimuth, windows, timing)


PRELOAD = __name__
"""What the plans-from-rest worker imports before its first solve (this module)."""


def _from_rest(state: dict[str, Any], args: tuple[Any, ...], cancel: Any) -> tuple[_Attempt | None, Any]:
    """:meth:`Replanner.from_rest` of a re-planner rebuilt from ``state``, on the compiled engine
    pinned to one thread (run in the worker process of :mod:`staghunt.flight.aside`)."""
    engine = get_engine("numba", threads=1)
    return Replanner.rebuilt(state, engine).from_rest(*args, engine=engine, cancel=cancel)
