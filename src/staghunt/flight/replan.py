"""Real-time trajectory modification: the game re-solved in flight (receding horizon).

A re-plan at planner tick ``t_now`` switches at ``t_s = t_now + latency_budget`` (a fixed
budget, so an episode is reproducible from its seed; the real solve time is measured and
reported beside it). From the team's reference state at ``t_s`` (position, velocity,
acceleration: the splice is continuous in all three) it

1. builds the problem the team knows at ``t_s``: the scenario's goals, the UAVs' switch
   positions as starts (moving: their lead-in points, each UAV's stopping distance ahead along
   its velocity, :meth:`Replanner._lead_in`), the static obstacles, the sensed ones
   (:class:`KnownWorld`), and the swept volumes of the known motions over the time windows
   where a conflict was predicted;
2. warm-starts the game from the current plan (the rest of the reference resampled to ``K``
   free waypoints) and runs the best-response rounds
   (:func:`staghunt.solvers.game.best_response_rounds`, ``repair``: a warm plan cut by the new
   obstacle is first repaired reply by reply);
3. times the new paths from the switch state (:func:`~staghunt.trajectory.quintic.timed_path`)
   and checks them *in time*: clearance to the obstacles known, separation, and the known
   motions at their true positions; a new conflict with a motion adds its window (step 1) and
   the team solves again, up to ``attempts`` times;
4. certifies the accepted plan (each UAV's Nash gap, :func:`staghunt.solvers.response.certify_plan`).

From a moving state the same is solved from rest after a synchronised stop, side by side on
two cores (or only if the moving one fails, on one), and flown if the moving one fails; a
moving solve that ends infeasible is tried again only if the plan from rest does not pass. If
neither gives a plan that passes, the team stops: a synchronised stop to hover
(:func:`~staghunt.trajectory.quintic.stop_piece`), after which it re-plans with
``stop_budget_factor`` times the budget.
"""

from __future__ import annotations

import math
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, replace
from typing import Any, Callable

import numpy as np

from staghunt.costs import CostModel, to_absolute
from staghunt.encoding import ANGLE_RANGE
from staghunt.engine import Engine, get_engine, side_by_side
from staghunt.flight.aside import rest_worker, worker_broke
from staghunt.flight.aside import start as start_worker
from staghunt.flight.known import (
    KnownWorld,
    check_piece,
    covers,
    remaining_plan,
    sub_scenario,
    swept_obstacles,
    to_xyh,
)
from staghunt.trajectory.quintic import Piece, Reference, stop_piece, timed_path
from staghunt.safety.measure import static_clearance
from staghunt.scenario import Scenario, SolverSettings
from staghunt.solvers.game import best_response_rounds
from staghunt.solvers.local import LocalSearch, local_pass
from staghunt.solvers.response import LOCAL_SHARE, CertifyOptions, CertifyRequest, certify_plan, check_search
from staghunt.world import Cylinder, Prism
from staghunt.world.dynamic import Dynamics

WIDE_AZIMUTH = math.pi / 2
"""Half-width of the heading range of a plan from rest (a stop, or the hover): the paper's
``pi/4`` keeps every leg within 45 degrees of the goal direction, and a UAV at rest just in
front of an obstacle cannot leave it that way."""
SEPARATION_MARGIN = 0.5
"""Metres added to ``d_s`` in a re-plan's problem (and so in its in-time check): the vehicles
track their references within centimetres without wind, tenths of a metre in it, and a plan
solved to an equilibrium may keep two UAVs exactly at the limit."""
TIMING_SLACK = 0.1
"""Metres the game's separation limit exceeds the in-time check's (``d_s`` grown by
:data:`SEPARATION_MARGIN` plus this in the re-plan's problem, by the margin alone in the check):
the timed curve leaves the polyline between waypoints by centimetres, so a best reply at
exactly the game's limit (an equilibrium lies on its constraints) would otherwise fail the
check by a few centimetres (measured: 4.44-4.49 m against 4.5 m) and could not be flown."""
MAX_DELAY_S = 60
"""Longest take-off delay (s) tried to let a known motion pass."""
MAX_STRETCH = 2.0
"""A plan from a moving switch state that must be slowed more than this to meet the limits
(a sharp turn at speed) is flown from rest instead: stop in sync, then the new plan."""
LEAD_IN_MIN_SPEED = 0.5
"""m/s: below this the switch state counts as at rest for the lead-in (:meth:`Replanner._lead_in`)."""
RELAX_KEEP = 0.8
"""A UAV that rests closer than the hard clearance to an obstacle (an emergency stop short of a
pop-up) re-plans with the clearance relaxed to this share of what it has: its paths may leave
sideways, not come closer (the solver's plans lie on their constraints, and a plan allowed to
come half the hard clearance closer grazed a pop-up within the vehicles' tracking error)."""
LOCAL_PASSES = 5
"""Most passes of the UAVs' local searches before a re-plan's first certificate."""
EMERGENCY_FACTORS = (2.0, 3.0)
"""Multiples of ``max_acceleration`` an emergency stop may brake at, tried in this order: the
mission limit (3 m/s^2 by default) is well below a multirotor's capability (the simulated
Hummingbird's thrust-to-weight ratio is about 10: 9 m/s^2 of braking tilts it by 43 degrees at
1.4 g of thrust), and a stop that the lower factor cannot make clear of what is known uses the
higher one."""


@dataclass(frozen=True)
class FlyConfig:
    """Settings of a closed-loop flight.

    - ``sim_rate``: simulation steps per second (Hz, >= 100).
    - ``latency_budget``: seconds between the tick that triggers a re-plan and its switch time.
    - ``horizon``: seconds ahead in which a predicted conflict with a known motion triggers a
      re-plan.
    - ``replan_particles``, ``replan_iterations``: the game's budget per re-plan
      (``particles x (iterations + 1) x N`` path evaluations, as for ``plan``).
    - ``certify_particles``, ``certify_iterations``, ``epsilon``: each re-plan's certificate.
    - ``certify_rounds``: a certificate that finds a UAV's better reply hands it back: the
      reply is adopted if the plan stays feasible and passes the in-time check, and the plan is
      certified again, up to this many times (0: report the first certificate as it is).
    - ``attempts``: solves per re-plan (each new predicted conflict with a motion adds its
      swept window and solves again).
    - ``window_pad``: seconds added on both sides of a conflict's time window.
    - ``stop_budget_factor``: after a stop to hover, the next re-plan gets this many times the
      budget and the latency budget.
    - ``retries_after_stop``, ``retry_interval``: re-plans tried while hovering (then the goal
      is reported unreachable).
    - ``wind``: mean wind speed (m/s, Dryden turbulence on top), blowing towards
      ``wind_heading_deg`` (counter-clockwise from east).
    - ``log_rate``: rows per second and UAV in ``flight.csv``.
    - ``hold``: seconds simulated after arrival or after giving up, hovering.
    """

    sim_rate: float = 100.0
    latency_budget: float = 0.3
    horizon: float = 10.0
    replan_particles: int = 100
    replan_iterations: int = 100
    certify_particles: int = 200
    certify_iterations: int = 100
    epsilon: float = 0.01
    certify_rounds: int = 4
    reply_start: float = 0.1
    attempts: int = 3
    window_pad: float = 3.0
    stop_budget_factor: int = 4
    retries_after_stop: int = 3
    retry_interval: float = 2.0
    wind: float = 0.0
    wind_heading_deg: float = 0.0
    log_rate: float = 20.0
    hold: float = 2.0

    def check(self) -> None:
        """Raise ``ValueError`` (one line naming the setting) for unusable settings."""
        def real(v: object) -> bool:
            return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

        def integer(v: object) -> bool:
            return isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 1_000_000

        rules = [
            ("sim_rate", real(self.sim_rate) and 100 <= self.sim_rate <= 2000, "a number in [100, 2000] Hz"),
            ("latency_budget", real(self.latency_budget) and 0 < self.latency_budget <= 10, "a number in (0, 10] s"),
            ("horizon", real(self.horizon) and 0 < self.horizon <= 600, "a number in (0, 600] s"),
            ("replan_particles", integer(self.replan_particles), "an integer in [1, 1e6]"),
            ("replan_iterations", integer(self.replan_iterations), "an integer in [1, 1e6]"),
            ("certify_particles", integer(self.certify_particles), "an integer in [1, 1e6]"),
            ("certify_iterations", integer(self.certify_iterations), "an integer in [1, 1e6]"),
            ("epsilon", real(self.epsilon) and self.epsilon >= 0, "a finite number >= 0"),
            ("certify_rounds", isinstance(self.certify_rounds, int) and not isinstance(self.certify_rounds, bool)
             and 0 <= self.certify_rounds <= 20, "an integer in [0, 20]"),
            ("reply_start", real(self.reply_start) and 0 < self.reply_start <= 1, "a number in (0, 1]"),
            ("attempts", integer(self.attempts) and self.attempts <= 20, "an integer in [1, 20]"),
            ("window_pad", real(self.window_pad) and 0 <= self.window_pad <= 60, "a number in [0, 60] s"),
            ("stop_budget_factor", integer(self.stop_budget_factor) and self.stop_budget_factor <= 100, "an integer in [1, 100]"),
            ("retries_after_stop", integer(self.retries_after_stop) and self.retries_after_stop <= 100, "an integer in [1, 100]"),
            ("retry_interval", real(self.retry_interval) and 0 < self.retry_interval <= 60, "a number in (0, 60] s"),
            ("wind", real(self.wind) and 0 <= self.wind <= 30, "a number in [0, 30] m/s"),
            ("wind_heading_deg", real(self.wind_heading_deg), "a finite number of degrees"),
            ("log_rate", real(self.log_rate) and 1 <= self.log_rate <= self.sim_rate, "a number in [1, sim_rate] Hz"),
            ("hold", real(self.hold) and 0 <= self.hold <= 600, "a number in [0, 600] s"),
        ]
        for name, ok, what in rules:
            if not ok:
                raise ValueError(f"flight setting {name} must be {what}, got {getattr(self, name)!r}")

    def certify_options(self) -> CertifyOptions:
        """The re-plans' certificate: its budget and tolerance."""
        return CertifyOptions(self.certify_particles, self.certify_iterations, self.epsilon)

    def certify_search(self, scenario: Scenario) -> SolverSettings:
        """The settings of the re-plans' certificate searches in ``scenario`` (its solver's, with
        the certificate's budget), checked (:func:`~staghunt.solvers.response.check_search`): once
        per flight, before it starts. Raises a :class:`~staghunt.errors.FieldError`."""
        search = check_search(scenario.solver, self.certify_options(), "re-plan settings")
        assert search is not None
        return search


@dataclass(frozen=True)
class ReplanRecord:
    """One re-plan: when (``time`` = the triggering tick, ``switch_time``), why (``trigger``),
    what it cost (``latency_s`` measured wall time of the whole re-plan, certificate included,
    against ``latency_budget_s``; ``evaluations`` path evaluations), what came out
    (``status``: ``"replanned"``; ``"stop, replanned"``: a synchronised stop, then a new plan
    from rest; ``"stop"``: a synchronised stop to hover, no plan yet; ``"emergency stop"``: the
    same at once, braking at two or three times the acceleration; ``"sidestep"``: a hovering
    team moved as a whole out of a known motion's way), ``attempts`` solves, and the
    certificate (``nash_gaps`` relative per UAV, ``verdict``, ``certified``: an
    epsilon-equilibrium). ``state_error_m``: the largest distance between a
    UAV's state predicted from the fed-back one (position + velocity x latency) and the
    reference state the new plan starts from."""

    time: float
    switch_time: float
    trigger: str
    status: str
    latency_s: float
    latency_budget_s: float
    evaluations: int
    attempts: int
    nash_gaps: tuple[float, ...] = ()
    certified: bool = False
    verdict: str = ""
    problems: tuple[str, ...] = ()
    windows: tuple[tuple[str, float, float], ...] = ()
    state_error_m: float = 0.0

    @property
    def solved(self) -> bool:
        """A new plan was spliced in (possibly after a stop)."""
        return self.status.endswith("replanned")

    @property
    def stopped(self) -> bool:
        """The team came to rest (a stop to hover, before a new plan or instead of one)."""
        return "stop" in self.status

    def to_dict(self) -> dict[str, Any]:
        return {
            "time": round(self.time, 4), "switch_time": round(self.switch_time, 4),
            "trigger": self.trigger, "status": self.status, "latency_s": self.latency_s,
            "latency_budget_s": self.latency_budget_s,
            "overran": self.latency_s > self.latency_budget_s, "evaluations": self.evaluations,
            "attempts": self.attempts, "nash_gaps": list(self.nash_gaps),
            "certified": self.certified, "verdict": self.verdict, "problems": list(self.problems),
            "windows": [{"obstacle": w[0], "from": round(w[1], 3), "to": round(w[2], 3)} for w in self.windows],
            "state_error_m": self.state_error_m,
        }


class _Cancelled(Exception):
    """Raised inside a solve that is no longer needed (:meth:`Replanner._attempts`)."""


@dataclass(frozen=True)
class _Attempt:
    """What :meth:`Replanner._attempts` found: the new plan spliced into its base (``ref``,
    ``None`` if no plan passed), the last rounds' outcome (``out``), its scenario (``sub``), the
    problems, the solves made (``tries``), the path evaluations spent, the heading half-width
    solved in, and the conflict windows known at the end."""

    ref: Reference | None
    out: Any
    sub: Any
    problems: list[str]
    tries: int
    spent: int
    azimuth: float
    windows: list[tuple[str, float, float]]


def _passed(rest: tuple[_Attempt | None, Reference, Piece]) -> bool:
    """Whether a plan from rest (``from_rest``'s outcome in :meth:`Replanner.solve`) passed."""
    return rest[0] is not None and rest[0].ref is not None


class Replanner:
    """Re-solves the game in flight for one episode; holds what it needs between re-plans.

    With the compiled engine on several cores, a re-plan from a moving state solves from that
    state and from rest after a stop *at the same time*, one thread each (each solve has its own
    generator, drawn before either starts, so the flight is the same on any number of cores;
    only the measured latency and the evaluations spent differ)."""

    def __init__(self, scenario: Scenario, dyn: Dynamics, config: FlyConfig, engine: Engine,
                 rng: np.random.Generator, search: SolverSettings | None = None) -> None:
        """``search``: the certificate searches' settings as :meth:`FlyConfig.certify_search`
        checked them before the flight (``None``: checked here)."""
        self.scenario, self.dyn, self.config, self.engine, self.rng = scenario, dyn, config, engine, rng
        self.search = search if search is not None else config.certify_search(scenario)
        self.known = KnownWorld(scenario)
        self.records: list[ReplanRecord] = []
        self._certifier, self._workers = side_by_side(engine)
        # the engine each of two side-by-side solves uses (pinned to one thread), or the engine
        self._solo = get_engine("numba", threads=1) if self._workers > 1 else engine
        if self._workers > 1:
            start_worker()  # the process of the plans from rest, ready before they are needed

    def solve(self, ref: Reference, t_now: float, trigger: str, scale: int = 1,
              windows: list[tuple[str, float, float]] | None = None,
              measured: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[Reference, ReplanRecord]:
        """Re-plan at tick ``t_now``; returns the new reference and its record. ``scale``: budget
        factor (after a stop). ``measured``: the fed-back positions and velocities ``(N, 3)``.

        The new plan starts from the *reference* state at the switch time, so that the splice is
        continuous for the controller; the state predicted from the fed-back one is compared
        with it and the difference reported (``state_error_m``: the tracking error plus the
        sensor noise, a few centimetres without wind).

        From the switch state (moving) and, unless the team is already at rest, from rest: the
        team stops in sync along its current paths (if that stop is clear of everything known)
        and the new plan starts where it rests. The two are solved side by side when the engine
        has two cores, else one after the other (from rest only if the moving one fails); the
        moving plan is flown when it passes (``"replanned"``), else the one from rest
        (``"stop, replanned"``). If neither passes: the stop alone (``"stop"``, or
        ``"emergency stop"``, :meth:`_stop`)."""
        cfg, scenario = self.config, self.scenario
        wall0 = time.perf_counter()
        budget_s = cfg.latency_budget * scale
        t_s = t_now + budget_s
        K = scenario.solver.waypoints
        settings = scenario.solver.with_(particles=cfg.replan_particles * scale,
                                         iterations=cfg.replan_iterations, waypoints=K)
        windows = list(windows or [])
        moving_rng, rest_rng = self.rng.spawn(2)
        warm = remaining_plan(scenario, ref, t_s, K)
        error = 0.0
        if measured is not None:
            predicted = measured[0] + measured[1] * budget_s
            error = float(np.linalg.norm(predicted - ref.state(np.array([t_s]))[0][:, 0], axis=-1).max())
        at_rest = ref.piece_at(t_s).kind == "stop"

        lead = None if at_rest else self._lead_in(ref, t_s)

        def moving(engine: Engine, rest_passes: Callable[[], bool] | None = None) -> _Attempt:
            return self._attempts(ref, t_s, list(windows), warm, settings, cfg.attempts, MAX_STRETCH,
                                  WIDE_AZIMUTH if at_rest else ANGLE_RANGE, moving_rng, engine, lead,
                                  stop_retrying=rest_passes)

        rest_args = (ref, t_now, t_s, windows, settings, rest_rng)
        # An infeasible moving solve is tried again only if the plan from rest does not pass
        # (asked once the moving one has failed: the same flight on one core and on two).
        if at_rest:
            first, second = moving(self.engine), None
        elif self._workers > 1:
            first, second = self._side_by_side(moving, rest_args)
        else:
            rest_box: list[tuple[_Attempt | None, Reference, Piece]] = []

            def rest_passes() -> bool:
                rest_box.append(self.from_rest(*rest_args, engine=self.engine))
                return _passed(rest_box[0])

            first = moving(self.engine, rest_passes)
            if rest_box:
                second = rest_box[0]
            else:
                second = self.from_rest(*rest_args, engine=self.engine) if first.ref is None else None
        rest = second[0] if second is not None else None
        spent = first.spent + (rest.spent if rest is not None else 0)
        tries = first.tries + (rest.tries if rest is not None else 0)
        chosen, status, splice = first, "replanned", (ref, t_s, MAX_STRETCH, lead)
        if first.ref is None and rest is not None:
            if rest.ref is not None:
                chosen, status, splice = rest, "stop, replanned", (second[1], second[2].t1, math.inf, None)
            else:
                chosen = replace(rest, problems=rest.problems or first.problems)
        used = sorted(set(chosen.windows))
        if chosen.ref is None:
            moved, status = self._sidestep(ref, t_s) if at_rest else (None, "")
            new_ref, status = (moved, status) if moved is not None else self._stop(ref, t_now, t_s)
            record = ReplanRecord(t_now, t_s, trigger, status, time.perf_counter() - wall0, budget_s,
                                  spent, tries, problems=tuple(chosen.problems[:5]), windows=tuple(used),
                                  state_error_m=error)
            return new_ref, self._keep(record)
        new_ref, cert, more = self._certified(chosen.ref, chosen.out.plan, chosen.sub, splice,
                                              chosen.azimuth)
        record = ReplanRecord(
            t_now, t_s, trigger, status, time.perf_counter() - wall0, budget_s, spent + more, tries,
            tuple(float(u.relative) for u in cert.uavs), cert.is_equilibrium, cert.verdict, (),
            tuple(used), error)
        return new_ref, self._keep(record)

    def from_rest(self, ref: Reference, t_now: float, t_s: float, windows: list[tuple[str, float, float]],
                  settings: Any, rng: np.random.Generator, *, engine: Engine, cancel: Any = None
                  ) -> tuple[_Attempt | None, Reference, Piece]:
        """The plan from rest of a re-plan at ``t_now`` switching at ``t_s``: the team stops in
        sync (:meth:`_stop_short`) and the game is solved from where it rests (``None``: that
        stop breaks a check), drawing from ``rng`` and searching with ``engine``; ``cancel``
        (an event) stops it after the reply in progress. Returns the attempt, the stopped
        reference and its stop piece."""
        stopped, stop, bad = self._stop_short(ref, t_now, t_s)
        if bad:
            return None, stopped, stop
        rest = remaining_plan(self.scenario, stopped, stop.t1, settings.waypoints)
        return (self._attempts(stopped, stop.t1, list(windows), rest, settings, 2, math.inf,
                               WIDE_AZIMUTH, rng, engine, cancel=cancel), stopped, stop)

    def _side_by_side(self, moving: Callable[..., _Attempt], rest_args: tuple[Any, ...]
                      ) -> tuple[_Attempt, tuple[_Attempt | None, Reference, Piece]]:
        """The moving solve here and the plan from rest beside it, in the worker process
        (:mod:`staghunt.flight.aside`: no interpreter lock shared) or, while it is not ready or
        where none can run, in a thread; the plan from rest is cancelled once the moving one
        passes. The same outcome either way (each solve has its own generator)."""
        worker = rest_worker()
        if worker is not None:
            later = worker.submit(self.state(), rest_args)
            box: list[tuple[_Attempt | None, Reference, Piece]] = []

            def rest() -> tuple[_Attempt | None, Reference, Piece]:
                if not box:
                    try:
                        box.append(later.result())
                    except BrokenProcessPool:  # the worker died: solve here (the same result)
                        worker_broke()
                        box.append(self.from_rest(*rest_args, engine=self._solo))
                return box[0]

            first = moving(self._solo, lambda: _passed(rest()))
            if first.ref is not None:  # the plan from rest is not needed: stop it
                worker.cancel()
            return first, rest()
        cancel = threading.Event()
        with ThreadPoolExecutor(1) as pool:
            thread = pool.submit(self.from_rest, *rest_args, engine=self._solo, cancel=cancel)
            first = moving(self._solo, lambda: _passed(thread.result()))
            if first.ref is not None:
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

    def _certified(self, new_ref: Reference, plan: np.ndarray, sub: Scenario,
                   splice: tuple[Reference, float, float, np.ndarray | None], azimuth: float
                   ) -> tuple[Reference, Any, int]:
        """Certify ``plan`` (spliced as ``new_ref``, solved with headings within ``azimuth``);
        with ``certify_rounds``, every UAV first makes the certificate's local search and a gain
        beyond epsilon is adopted (the plan re-timed and checked as below; again after every
        adopted reply); then, while a
        certificate finds better replies and ``certify_rounds`` allow, adopt them and
        certify again: every reply in turn (largest gap first) that still gains more than
        epsilon with the replies already kept and keeps the plan feasible, if that keeps more
        than one and the plan's timing from ``splice`` = ``(base, t0, max_stretch, lead)``
        meets the limits and passes the in-time check; else the reply of the UAV with the
        largest gap with which the plan does (or the next largest beyond epsilon). One
        UAV's better reply can widen the others' gaps (best-response dynamics need not settle in a
        few steps), so the plan returned is the certified one with the least largest relative
        gap: never worse than the first. After a single reply is adopted, the next certificate
        keeps that UAV's search (the others fly what it fixed; ``certify_plan``'s ``carried``)
        and searches the others only. Returns that plan's reference, its certificate and the
        path evaluations spent."""
        cfg = self.config
        model = CostModel.from_scenario(sub)
        judge = self._solo.evaluate  # the compiled twin of the reference (the same verdicts)
        base, t0, max_stretch, lead = splice
        options = cfg.certify_options()
        best: tuple[Reference, Any] | None = None
        spent = 0
        local = int(LOCAL_SHARE * self.search.particles * (self.search.iterations + 1))

        def settle(plan: np.ndarray, new_ref: Reference
                   ) -> tuple[np.ndarray, Reference, int, bool, tuple[LocalSearch, ...]]:
            """Before a certificate: the certificate's own local search, by every UAV in turn
            (a compiled pattern search, milliseconds; side by side on two cores), in passes until
            none gains more than epsilon; the gains are kept if the plan stays feasible and its
            timing passes, so that no certificate is spent on a reply a local move finds. Returns
            the plan, its reference, the evaluations spent, whether the plan changed and the last
            pass's searches (the certificate's own searches of the plan when it took nothing)."""
            team, J = plan.copy(), judge(model, plan[None]).total[0]
            used_all = 0
            last: tuple[LocalSearch, ...] = ()
            for _ in range(LOCAL_PASSES):
                done = local_pass(model, team, J, local, cfg.epsilon, judge, workers=self._workers)
                team, J, used_all, last = done.plan, done.costs, used_all + done.evaluations, done.searches
                if not done.gains.any():
                    break
            if not np.array_equal(team, plan):
                spliced, _, _ = self._splice(base, t0, sub, team, max_stretch, lead)
                if spliced is not None:
                    return team, spliced, used_all, True, last
            return plan, new_ref, used_all, False, last

        searched: tuple[LocalSearch, ...] = ()
        if cfg.certify_rounds > 0:
            plan, new_ref, used, _, searched = settle(plan, new_ref)
            spent += used
        carried: dict[int, Any] = {}
        for round_ in range(cfg.certify_rounds + 1):
            request = CertifyRequest.of_checked(sub, plan, self.search, options, int(self.rng.integers(2**31)))
            cert = certify_plan(request, runner=self._certifier.run_swarm, azimuth=azimuth, workers=self._workers,
                                carried=carried, evaluator=self._certifier.evaluate, searched=searched)
            spent += sum(u.evaluations - u.taken for u in cert.uavs)  # settle() counted what it took
            if best is None or cert.max_relative_gap < best[1].max_relative_gap:
                best = (new_ref, cert)
            if cert.is_equilibrium or round_ == cfg.certify_rounds:
                break
            order = [n for n in sorted(range(len(cert.uavs)), key=lambda m: -cert.uavs[m].relative)
                     if cert.uavs[n].relative > cfg.epsilon and cert.uavs[n].deviation is not None]
            adopted = None
            if len(order) > 1:
                # every reply in turn, kept if it still gains more than epsilon after those kept
                team, J = plan.copy(), judge(model, plan[None]).total[0]
                taken = 0
                for n in order:
                    candidate = team.copy()
                    candidate[n] = cert.uavs[n].deviation
                    c = judge(model, candidate[None])
                    spent += 1
                    if c.total_violation[0] == 0 and c.total[0][n] < (1 - cfg.epsilon) * J[n]:
                        team, J, taken = candidate, c.total[0], taken + 1
                if taken > 1:
                    spliced, _, _ = self._splice(base, t0, sub, team, max_stretch, lead)
                    adopted = (team, spliced) if spliced is not None else None
            carried = {}
            if adopted is None:  # one reply: the largest gap that can be flown
                for n in order:
                    candidate = plan.copy()
                    candidate[n] = cert.uavs[n].deviation
                    spent += 1
                    if judge(model, candidate[None]).total_violation[0] > 0:
                        continue
                    spliced, _, _ = self._splice(base, t0, sub, candidate, max_stretch, lead)
                    if spliced is not None:  # else the next-worst UAV's reply
                        adopted = (candidate, spliced)
                        # The others fly what UAV n's search fixed: that search stands for it.
                        carried = {n: cert.uavs[n]}
                        break
            if adopted is None:
                break
            plan, new_ref = adopted
            plan, new_ref, used, moved, searched = settle(plan, new_ref)
            spent += used
            if moved:  # a carried search fixed the others' paths as they were
                carried = {}
        return best[0], best[1], spent

    def _splice(self, base: Reference, t0: float, sub: Scenario, plan: np.ndarray, max_stretch: float,
                lead: np.ndarray | None = None
                ) -> tuple[Reference | None, list[str], list[tuple[str, float, float]] | None]:
        """``plan`` ``(N, K, 3)`` of ``sub`` timed from ``base``'s state at ``t0`` and spliced
        into ``base``. Returns the new reference if its timing meets the limits within
        ``max_stretch`` and it passes the in-time check, else ``None``, with the problems and
        the conflicts with known motions found (``None``: the timing failed)."""
        scenario = self.scenario
        state = base.state(np.array([t0]))[:, :, 0]  # (4, N, 3)
        goals = to_absolute(scenario.world.terrain, scenario.goals()[:, None])
        head = state[0][:, None] if lead is None else np.stack([state[0], lead], axis=1)
        absolute = np.concatenate([head, to_absolute(sub.world.terrain, plan), goals], axis=1)
        try:
            piece = timed_path(absolute, t0, scenario.vehicle, state[1], state[2], max_stretch=max_stretch)
        except ValueError as exc:
            return None, [str(exc)], None
        new_ref = base.spliced(piece)
        problems, found, _ = check_piece(self._checked(sub), self.known, self.dyn, new_ref, t0, piece.t1)
        return (None, problems, found) if problems else (new_ref, [], found)

    @staticmethod
    def _checked(sub: Scenario) -> Scenario:
        """The re-plan's problem ``sub`` as the in-time check judges it: ``d_s`` grown by
        :data:`SEPARATION_MARGIN` only."""
        return replace(sub, costs=replace(sub.costs, safe_distance=sub.costs.safe_distance - TIMING_SLACK))

    def _lead_in(self, ref: Reference, t_s: float) -> np.ndarray | None:
        """``(N, 3)`` absolute lead-in points of a re-plan from a moving state: each UAV goes on
        along its velocity at the switch for the distance it needs to stop at
        ``max_acceleration`` (``|v|^2 / 2 a``), where the new plan starts. A UAV at speed cannot
        turn at once; along the lead-in it slows to the speed of the new path's first turn.
        ``None`` when the team is nearly at rest, or a lead-in leaves the site or comes closer
        than the hard clearance to an obstacle known (the plan then starts at the switch state)."""
        state = ref.state(np.array([t_s]))[:, :, 0]  # (4, N, 3)
        v = state[1]
        speed = np.linalg.norm(v, axis=-1)
        if speed.max() < LEAD_IN_MIN_SPEED:
            return None
        d = speed**2 / (2.0 * self.scenario.vehicle.max_acceleration)
        lead = state[0] + v / np.maximum(speed, 1e-9)[:, None] * d[:, None]
        b = self.scenario.world.bounds
        xyh = to_xyh(self.scenario, lead)
        if np.any(xyh < np.asarray(b.lower)) or np.any(xyh > np.asarray(b.upper)):
            return None
        along = state[0][:, None] + (lead - state[0])[:, None] * np.linspace(0.0, 1.0, 9)[None, :, None]
        r = np.array([u.radius for u in self.scenario.team])
        clear = static_clearance(*self.known.shapes(), along, r)  # (N, 9)
        return None if np.any(clear < self.scenario.costs.min_clearance) else lead

    def _stop_short(self, ref: Reference, t_now: float, t_s: float) -> tuple[Reference, Piece, bool]:
        """The stop before a plan from rest: at the switch time within ``max_acceleration``, or,
        if that leaves a UAV within twice the hard clearance of something known (the encoding
        then has little room to leave), at once with twice the acceleration when that rests
        farther. Returns the stopped reference, its stop piece and whether it breaks a check."""
        limits = self.scenario.vehicle
        cyl, prm = self.known.shapes()
        r = np.array([u.radius for u in self.scenario.team])
        best = None
        for t0, lim in ((t_s, limits), (t_now, replace(limits, max_acceleration=2 * limits.max_acceleration))):
            stop = stop_piece(ref, t0, lim)
            stopped = ref.spliced(stop)
            bad, _, _ = check_piece(self.scenario, self.known, self.dyn, stopped, t0, stop.t1 + 1.0)
            rest = stopped.state(np.array([stop.t1]))[0]
            room = float(static_clearance(cyl, prm, rest, r).min(initial=math.inf))
            if best is None or (not bad and (best[2] or room > best[3])):
                best = (stopped, stop, bool(bad), room)
            if not bad and room >= 2 * self.scenario.costs.min_clearance:
                break
        return best[0], best[1], best[2]

    def _attempts(self, base: Reference, t0: float, windows: list[tuple[str, float, float]],
                  warm: np.ndarray, settings: Any, tries: int, max_stretch: float, azimuth: float,
                  rng: np.random.Generator, engine: Engine, lead: np.ndarray | None = None,
                  cancel: threading.Event | None = None,
                  stop_retrying: Callable[[], bool] | None = None) -> _Attempt:
        """Solve from ``base``'s state at ``t0`` up to ``tries`` times (each new conflict with a
        known motion adds its window to ``windows``, which this call owns), with headings within
        ``azimuth`` of the goal direction, drawing from ``rng`` and searching with ``engine``.
        ``lead``: ``(N, 3)`` lead-in points (:meth:`_lead_in`): the game is solved from them and
        the paths flown from the switch state through them. ``cancel``: once set, the solve
        stops after the reply in progress and returns no plan (its evaluations counted up to
        its last complete solve). ``stop_retrying()``: asked when a solve ends infeasible; if it
        says so (another plan passes), the solve is not tried again."""
        scenario, cfg = self.scenario, self.config
        state = base.state(np.array([t0]))[:, :, 0]  # (4, N, 3)
        starts = to_xyh(scenario, state[0] if lead is None else lead)
        N = scenario.n_uavs
        budget = settings.particles * (settings.iterations + 1) * N
        cyl, prm = self.known.shapes()
        problems: list[str] = []
        out = sub = None
        spent = 0

        def stop_if_cancelled(_spent: int, _J: np.ndarray) -> None:
            if cancel is not None and cancel.is_set():
                raise _Cancelled

        for attempt in range(1, tries + 1):
            sub = self._problem(starts, cyl, prm, windows)
            model = CostModel.from_scenario(sub)
            try:
                out = best_response_rounds(model, warm, settings, rng, engine.run_swarm, engine.evaluate,
                                           budget, 0, stop_if_cancelled, repair=True,
                                           reply_start=cfg.reply_start, azimuth=azimuth)
            except _Cancelled:
                return _Attempt(None, out, sub, ["cancelled"], attempt, spent, azimuth, windows)
            spent += out.evaluations
            warm = out.plan
            if engine.evaluate(model, out.plan[None]).total_violation[0] > 0:
                problems = ["no feasible plan from the switch state"]
                if stop_retrying is not None and stop_retrying():
                    return _Attempt(None, out, sub, problems, attempt, spent, azimuth, windows)
                continue
            new_ref, problems, found = self._splice(base, t0, sub, out.plan, max_stretch, lead)
            done = new_ref is not None or found is None  # passed, or the timing itself failed
            new = [] if done else [w for w in found if not any(covers(o, w) for o in windows)]
            if done or not new:  # no new motion's window: no retry helps
                return _Attempt(new_ref, out, sub, problems, attempt, spent, azimuth, windows)
            windows.extend((n, max(t0, a - cfg.window_pad), b + cfg.window_pad) for n, a, b in new)
        return _Attempt(None, out, sub, problems, tries, spent, azimuth, windows)

    def _sidestep(self, ref: Reference, t_s: float) -> tuple[Reference | None, str]:
        """A team hovering where a known motion will pass: move the whole formation (one rigid
        offset, so separations hold) to the nearest spot that stays clear for the horizon,
        trying 16 headings and offsets of 1 to 4 times the largest moving radius plus body and
        clearance. Returns ``(None, "")`` when the hover is not threatened or no spot is clear."""
        cfg, sc = self.config, self.scenario
        bad, _, _ = check_piece(sc, self.known, self.dyn, ref, t_s, t_s + cfg.horizon)
        if not bad or not self.dyn.known_motion:
            return None, ""
        t0 = max(t_s, ref.piece_at(t_s).t1)  # from rest: after the stop in progress, if any
        here = ref.state(np.array([t0]))[0][:, 0]  # (N, 3)
        size = max([m.radius for m in self.dyn.moving] + [j.width for j in self.dyn.jibs], default=1.0)
        step = size + max(u.radius for u in sc.team) + sc.costs.min_clearance
        b = sc.world.bounds
        for dist in (1.0, 2.0, 3.0, 4.0):
            for a in np.radians(np.arange(0.0, 360.0, 22.5)):
                there = here + dist * step * np.array([math.cos(a), math.sin(a), 0.0])
                if (there[:, 0].min() < b.xmin or there[:, 0].max() > b.xmax
                        or there[:, 1].min() < b.ymin or there[:, 1].max() > b.ymax):
                    continue
                piece = timed_path(np.stack([here, there], axis=1), t0, sc.vehicle)
                cand = ref.spliced(piece)
                bad, _, _ = check_piece(sc, self.known, self.dyn, cand, t_s, piece.t1 + cfg.horizon)
                if not bad:
                    return cand, "sidestep"
        return None, ""

    def _stop(self, ref: Reference, t_now: float, t_s: float) -> tuple[Reference, str]:
        """The fallback: a synchronised stop at the switch time within ``max_acceleration``; if
        that stop (along the current paths) would come closer than the hard clearance to
        something known, an emergency stop at once (``t_now``) with the braking warp
        (:func:`~staghunt.trajectory.quintic.brake_warp`) at the first of
        :data:`EMERGENCY_FACTORS` times the acceleration that passes the in-time check, or else
        the stop that keeps the most clearance. Returns the reference and ``"stop"`` /
        ``"emergency stop"``."""
        limits = self.scenario.vehicle
        if ref.piece_at(t_s).kind == "stop":
            return ref, "stop"
        options = []
        tries = [("stop", t_s, limits)] + [
            ("emergency stop", t_now, replace(limits, max_acceleration=f * limits.max_acceleration))
            for f in EMERGENCY_FACTORS]
        for status, t0, lim in tries:
            piece = stop_piece(ref, t0, lim, brake=status == "emergency stop")
            cand = ref.spliced(piece)
            problems, _, least = check_piece(self.scenario, self.known, self.dyn, cand, t0, piece.t1 + 1.0)
            if not problems:
                return cand, status
            options.append((least, cand, status))
        _, cand, status = max(options, key=lambda o: o[0])
        return cand, status

    def _problem(self, starts: np.ndarray, cyl: tuple[Cylinder, ...], prm: tuple[Prism, ...],
                 windows: list[tuple[str, float, float]]) -> Scenario:
        """The scenario the team solves: known obstacles plus the swept stand-ins of the windows,
        ``d_s`` grown by :data:`SEPARATION_MARGIN` and :data:`TIMING_SLACK` (:meth:`_checked`
        takes the slack back for the in-time check).
        If a UAV's switch position is already closer than the hard clearance to an obstacle (a
        stop short of a pop-up), the clearance of this problem is relaxed to :data:`RELAX_KEEP`
        of what it has, so that a path away from it exists: every leg of the encoding heads
        within 45 degrees of the direction to the goal, so a first leg leaving an obstacle just
        ahead must graze it."""
        sub = sub_scenario(self.scenario, starts, cyl, prm)
        more_c, more_p = swept_obstacles(sub, self.dyn, windows)
        sub = sub_scenario(self.scenario, starts, cyl + more_c, prm + more_p)
        sub = replace(sub, costs=replace(sub.costs, safe_distance=sub.costs.safe_distance + SEPARATION_MARGIN
                                         + TIMING_SLACK))
        at = to_absolute(sub.world.terrain, starts[:, None])
        r = np.array([u.radius for u in sub.team])
        have = float(static_clearance(sub.world.cylinders, sub.world.prisms, at, r).min(initial=math.inf))
        if have < sub.costs.min_clearance:
            relaxed = RELAX_KEEP * max(0.0, have)
            sub = replace(sub, costs=replace(sub.costs, min_clearance=relaxed))
        return sub

    def _keep(self, record: ReplanRecord) -> ReplanRecord:
        self.records.append(record)
        return record


def offline_plan(scenario: Scenario, dyn: Dynamics, waypoints: np.ndarray, config: FlyConfig,
                 solve: Any) -> tuple[np.ndarray, Piece, list[tuple[str, float, float]], list[str]]:
    """Make a plan ``(N, K, 3)`` sound against the known motions before take-off: time it, check
    it in time against the motions, and while it conflicts re-plan (``solve(windows) -> (N, K,
    3)``) with the swept volumes of the conflict windows. If that does not remove a conflict
    (a motion over a goal, or one the routes cannot avoid), the take-off is delayed, by whole
    seconds up to :data:`MAX_DELAY_S`, until the first plan without the swept stand-ins (or the
    last one) passes the in-time check. Returns the plan, its timed piece (starting at the
    take-off delay), the windows used and the problems left (empty: sound)."""
    known = KnownWorld(scenario)
    windows: list[tuple[str, float, float]] = []
    problems: list[str] = []
    start = to_absolute(scenario.world.terrain, scenario.starts()[:, None])
    goal = to_absolute(scenario.world.terrain, scenario.goals()[:, None])

    def timed(wp: np.ndarray, delay: float) -> Piece:
        return timed_path(np.concatenate([start, to_absolute(scenario.world.terrain, wp), goal], axis=1), delay,
                          scenario.vehicle)

    tried = [np.asarray(waypoints, dtype=float)]
    for _ in range(config.attempts + 1):
        piece = timed(waypoints, 0.0)
        problems, found, _ = check_piece(scenario, known, dyn, Reference((piece,)), 0.0, piece.t1)
        if not problems:
            return waypoints, piece, windows, []
        new = [w for w in found if not any(covers(o, w) for o in windows)]
        if not new:
            break
        windows.extend((n, max(0.0, a - config.window_pad), b + config.window_pad) for n, a, b in new)
        waypoints = solve(windows)
        tried.append(waypoints)
    for delay in np.arange(1.0, MAX_DELAY_S + 1.0):
        for wp in (tried[0], tried[-1]):
            piece = timed(wp, float(delay))
            bad, _, _ = check_piece(scenario, known, dyn, Reference((piece,)), 0.0, piece.t1)
            if not bad:
                return wp, piece, windows, []
    return waypoints, timed(waypoints, 0.0), windows, problems
