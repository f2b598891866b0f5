"""The game's loops of a re-plan, with a deadline: best-response rounds that return the best
plan they have when time is up (:func:`anytime_rounds`), and the certify-and-improve loop
(:func:`certify_and_improve`): certify a plan, adopt the better replies its certificate finds,
certify again.

Both know nothing of flight: what a plan must pass to be flown (timed, spliced, checked in
time) is a callback, ``accept(plan) -> flown or None``. Time is a :class:`Deadline`; without
one (``Deadline()``) nothing depends on the wall clock, so a seeded re-plan is reproducible.
Shapes: ``N`` UAVs, ``K`` free waypoints.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Generic, TypeVar

import numpy as np

from staghunt.costs import CostEngine, CostModel, Costs, NumpyCosts
from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.solvers.clear import pushed_clear
from staghunt.solvers.finish import adopt_replies
from staghunt.solvers.game import RoundsOutcome, best_response_rounds
from staghunt.solvers.local import LocalSearch, local_pass
from staghunt.solvers.response import LOCAL_SHARE, Certificate, CertifyOptions, CertifyRequest, certify_plan
from staghunt.solvers.swarm import SwarmRunner

LOCAL_PASSES = 5
"""Most passes of the UAVs' local searches before a certificate."""
ESTIMATE_DECAY = 0.8
"""A certificate's running estimate shrinks by this factor whenever it leaves no time for the
first certificate of a call: an estimate grown by one slow or abandoned certificate would
otherwise stop every later certificate, the only measurements that could bring it down."""

Flown = TypeVar("Flown")


@dataclass
class Deadline:
    """A wall-clock deadline (``time.perf_counter()`` seconds; ``None``: none) and the running
    estimates of how long a certificate takes (s) and the loop's other unwatched steps
    (``steps``: ``"accept"``, flying a plan; ``"local pass"``, one pass of the UAVs' local
    searches), to start one only if it can end in time. ``steps`` may be shared between deadlines
    (a flight's re-plans keep one)."""

    end: float | None = None
    certificate_s: float = 0.0
    steps: dict[str, float] = field(default_factory=dict)

    @classmethod
    def after(cls, seconds: float, certificate_s: float = 0.0) -> "Deadline":
        return cls(time.perf_counter() + seconds, certificate_s)

    def left(self) -> float:
        return math.inf if self.end is None else self.end - time.perf_counter()

    @property
    def passed(self) -> bool:
        return self.left() <= 0.0

    def fits(self, seconds: float) -> bool:
        return self.left() >= seconds

    def fits_steps(self, *names: str, after: float = 0.0) -> bool:
        """Whether ``after`` seconds, then the steps ``names`` (by their running estimates), can
        end before the deadline."""
        return self.fits(after + sum(self.steps.get(n, 0.0) for n in names))

    def fits_certificate(self, *then: str) -> bool:
        """Whether a certificate, then the steps ``then``, can end before the deadline."""
        return self.fits_steps(*then, after=self.certificate_s)

    def timed(self, name: str, step: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """``step(*args, **kwargs)``, its wall time entering the running estimate of ``name`` (at once if longer,
        else averaged with it)."""
        t0 = time.perf_counter()
        try:
            return step(*args, **kwargs)
        finally:
            took, before = time.perf_counter() - t0, self.steps.get(name)
            self.steps[name] = took if before is None else max(took, 0.5 * (before + took))


class Cancelled(Exception):
    """Raised inside a solve that is no longer needed."""


class _CertificateLate(Exception):
    """Raised from a certificate's progress once the deadline has passed: the certificate is
    abandoned (a certificate is all or nothing), ``share`` of its searches done."""

    def __init__(self, share: float) -> None:
        self.share = share


class _TimeUp(Exception):
    def __init__(self, plan: np.ndarray, spent: int) -> None:
        self.plan, self.spent = plan, spent


class _Watched(NumpyCosts):
    """``engine``'s evaluations, each of a single plan noted by ``seen(plan, costs)``: an engine
    whose other answers are the reference's (:class:`~staghunt.costs.NumpyCosts`: no compiled
    shortcut, so every candidate of a reply's polish is scored through :meth:`evaluate`)."""

    def __init__(self, engine: CostEngine, seen: Callable[[np.ndarray, Costs], None]) -> None:
        self.engine, self.seen, self.name = engine, seen, engine.name

    def prepare(self) -> float:
        return self.engine.prepare()

    def evaluate(self, model: CostModel, waypoints: np.ndarray) -> Costs:
        out = self.engine.evaluate(model, waypoints)
        if waypoints.shape[0] == 1:
            self.seen(waypoints[0], out)
        return out


def anytime_rounds(model: CostModel, warm: np.ndarray, settings: SolverSettings, rng: np.random.Generator,
                   runner: SwarmRunner, engine: CostEngine, budget: int, deadline: Deadline,
                   cancelled: Callable[[], bool] | None = None, **options: Any) -> RoundsOutcome:
    """:func:`~staghunt.solvers.game.best_response_rounds` from ``warm`` ``(N, K, 3)`` that,
    once ``deadline`` has passed, stops after the reply in progress and returns the plan it
    had then (``converged`` false). ``cancelled()`` true after a reply raises
    :class:`Cancelled`. ``options``: the rounds' keyword arguments (``repair``,
    ``reply_start``, ``azimuth``); with ``repair``, a ``warm`` plan that an obstacle cuts is
    first pushed clear of it (:func:`~staghunt.solvers.clear.pushed_clear`), and so is the
    plan the rounds end with, kept if that makes it feasible: in flight about one event
    re-plan in eight ended with one UAV cutting the pop-up by centimetres to metres, and
    solving again from there took 25-45 ms of a 200 ms deadline (benchmarks/JOURNAL.md,
    "Closed loop: why event plans end uncertified")."""
    warm = np.array(warm, dtype=float)
    first = engine.evaluate(model, warm[None])
    if options.get("repair") and first.total_violation[0] > 0:
        warm = pushed_clear(model, warm)
        first = engine.evaluate(model, warm[None])
    box: dict[str, Any] = {"plan": warm.copy(), "J": first.total[0].copy(), "last": None}

    def seen(plan: np.ndarray, out: Costs) -> None:  # the rounds judge each reply as a whole plan last, before on_reply
        box["last"] = (plan.copy(), out.total[0].copy())

    def on_reply(spent: int, J: np.ndarray) -> None:
        last = box["last"]
        if last is not None and box["J"] is not None and not np.array_equal(J, box["J"]) and np.array_equal(J, last[1]):
            box["plan"] = last[0]  # the reply just judged was accepted
        box["J"] = J.copy()
        if cancelled is not None and cancelled():
            raise Cancelled
        if deadline.passed:
            raise _TimeUp(box["plan"], spent)

    try:
        out = best_response_rounds(model, warm, settings, rng, runner, _Watched(engine, seen), budget, 0, on_reply,
                                   **options)
    except _TimeUp as up:
        J = engine.evaluate(model, up.plan[None]).total[0]
        out = RoundsOutcome(up.plan, J, up.spent + 1, [], 0, False)
    if options.get("repair") and not np.all(np.isfinite(out.costs)):  # ended cutting an obstacle: pushed clear
        pushed = pushed_clear(model, out.plan)
        again = engine.evaluate(model, pushed[None])
        if again.total_violation[0] == 0:
            out = replace(out, plan=pushed, costs=again.total[0], evaluations=out.evaluations + 1)
    return out


def _watch(deadline: Deadline) -> Callable[[int, int, int, int], None] | None:
    """A certificate's progress callback that abandons it once ``deadline`` has passed
    (``None`` without a deadline: nothing depends on the wall clock)."""
    if deadline.end is None:
        return None
    done: dict[int, float] = {}

    def progress(uav: int, n_uavs: int, iteration: int, iterations: int) -> None:
        done[uav] = iteration / max(iterations, 1)
        if deadline.passed:
            raise _CertificateLate(sum(done.values()) / max(n_uavs, 1))

    return progress


@dataclass
class Improved(Generic[Flown]):
    """What :func:`certify_and_improve` ends with: the ``flown`` object of the ``plan``
    ``(N, K, 3)`` kept, its ``certificate`` (``None``: no certificate could end before the
    deadline), the path evaluations ``spent`` and the certificates made."""

    flown: Flown
    plan: np.ndarray
    certificate: Certificate | None
    spent: int = 0
    certificates: int = 0
    notes: list[str] = field(default_factory=list)


def certify_and_improve(sub: Scenario, plan: np.ndarray, flown: Flown, accept: Callable[[np.ndarray], Flown | None],
                        search: SolverSettings, options: CertifyOptions, rounds: int, rng: np.random.Generator,
                        runner: SwarmRunner, engine: CostEngine, judge: CostEngine, azimuth: float,
                        workers: int = 1, deadline: Deadline | None = None) -> Improved[Flown]:
    """Certify ``plan`` of the game ``sub`` (flown as ``flown``, solved with headings within
    ``azimuth``) and improve it while the certificate finds better replies.

    With ``rounds`` > 0, every UAV first makes the certificate's own local search, in passes
    until none gains more than epsilon (or the deadline passes). Then, while a certificate finds
    better replies and ``rounds`` allow: every reply in turn (largest gap first) that still
    gains more than epsilon with those already kept and keeps the plan feasible
    (:func:`~staghunt.solvers.finish.adopt_replies`); if that keeps
    fewer than two, the reply of the UAV with the largest gap that keeps the plan feasible, and
    the next certificate keeps that UAV's search (the others fly what it fixed, if it was
    searched to the end); then the local passes again, and the next certificate.

    Only the plan kept is flown (``accept``), once the certificates are done: the certified
    one, else the one whose certificate found the least largest relative gap (one UAV's better
    reply can widen the others' gaps); if ``accept`` cannot fly it, the next in that order, and
    ``plan`` itself (``flown``) needs no flying. Flying a plan is costly (its timing and the
    checks in time), so flying only the one kept leaves the deadline's time to certificates.

    On one worker each certificate stops at its first refutation (``certify_plan``'s
    ``refute``: only the verdict and the replies found matter here), so a failed one leaves
    time for the next round; a refuted certificate's largest gap is the largest found until it
    stopped. With ``workers`` side by side a certificate runs to the end: its UAVs' searches run
    at once, so one stopped at its first refutation took about as long as a full one (21 against
    23 ms median, 3 UAVs on two cores), and the full one has every UAV's better reply for the
    next round to adopt (scenario 2's first re-plans on two cores: 71.0 of 95 certified against
    67.6, seven alternated runs; on one core the other way, 51 against 59: benchmarks/JOURNAL.md,
    "Closed loop: full certificates on two cores"). Flying a plan
    and a pass of the local searches are not watched by the deadline: each starts only if its
    running estimate (``deadline.steps``) says it ends in time; a pass, a certificate of a plan
    other than ``plan`` and the adoption of replies start only if flying a plan still fits
    after them.

    ``search``, ``options``: the certificates' settings; each draws its seed from ``rng``,
    searches with ``runner``/``engine`` (``workers`` side by side); ``judge`` evaluates
    single plans and makes the local searches before a certificate. ``deadline``: a certificate
    starts only if its running estimate fits before the deadline (the estimate is updated with
    every complete certificate made), and one still searching when the deadline passes is abandoned."""
    deadline = deadline or Deadline()
    model = CostModel.from_scenario(sub)
    local = int(LOCAL_SHARE * search.particles * (search.iterations + 1))
    eps = options.epsilon
    given, made = plan, []
    out = Improved(flown, plan, None)

    def settle(plan: np.ndarray) -> tuple[np.ndarray, tuple[LocalSearch, ...]]:
        """The certificate's own local searches before it, in passes while one gains more than
        epsilon: the plan they reach and the last pass's searches."""
        team, J = plan.copy(), judge.evaluate(model, plan[None]).total[0]
        last: tuple[LocalSearch, ...] = ()
        for _ in range(LOCAL_PASSES):
            if not deadline.fits_steps("local pass", "accept"):  # its gains count only if the plan is flown
                break
            done = deadline.timed("local pass", local_pass, model, team, J, local, eps, judge, workers=workers)
            team, J, last = done.plan, done.costs, done.searches
            out.spent += done.evaluations
            if not done.gains.any():
                break
        return (plan if np.array_equal(team, plan) else team), last

    searched: tuple[LocalSearch, ...] = ()
    if rounds > 0:
        plan, searched = settle(plan)
    carried: dict[int, Any] = {}
    for round_ in range(rounds + 1):
        if not (deadline.fits_certificate() if plan is given else deadline.fits_certificate("accept")):
            out.notes.append("deadline: no time left for a certificate")
            if out.certificates == 0:  # (never without a deadline: everything fits then)
                deadline.certificate_s *= ESTIMATE_DECAY
            break
        t0 = time.perf_counter()
        request = CertifyRequest.of_checked(sub, plan, search, options, int(rng.integers(2**31)))
        try:
            cert = certify_plan(request, runner=runner, azimuth=azimuth, workers=workers, carried=carried,
                                engine=engine, searched=searched, progress=_watch(deadline), refute=workers < 2)
        except _CertificateLate as late:  # its estimate from the share of its searches done
            took = time.perf_counter() - t0
            deadline.certificate_s = max(deadline.certificate_s, took / max(late.share, 0.1))
            out.notes.append(f"deadline: the certificate was abandoned after {took:.2f} s, "
                             f"{100 * late.share:.0f} % done")
            break
        took = time.perf_counter() - t0
        if cert.complete:  # a refuted certificate's time says little of a full one's
            deadline.certificate_s = took if out.certificates == 0 and deadline.certificate_s == 0 else \
                max(took, 0.5 * (deadline.certificate_s + took))
        out.certificates += 1
        out.spent += sum(u.evaluations - u.taken for u in cert.uavs)  # settle() counted what it took
        made.append((plan, cert))
        if cert.is_equilibrium or round_ == rounds:
            break
        if not deadline.fits_certificate("accept"):  # an improvement that cannot be certified and flown in time
            out.notes.append("deadline: no time left to certify the better replies")
            break
        order = [n for n in sorted(range(len(cert.uavs)), key=lambda m: -cert.uavs[m].relative)
                 if cert.uavs[n].relative > eps and cert.uavs[n].deviation is not None]
        adopted = None
        if len(order) > 1:  # every reply in turn, kept if it still gains more than epsilon
            team, taken, spent = adopt_replies(model, plan, cert, judge)
            out.spent += spent
            adopted = team if taken > 1 else None
        carried = {}
        if adopted is None:  # one reply: the largest gap that keeps the plan feasible
            for n in order:
                candidate = plan.copy()
                candidate[n] = cert.uavs[n].deviation
                out.spent += 1
                if judge.evaluate(model, candidate[None]).total_violation[0] == 0:
                    adopted = candidate
                    # the others fly what UAV n's search fixed (if it was searched to the end)
                    carried = {n: cert.uavs[n]} if cert.uavs[n].complete else {}
                    break
        if adopted is None:
            break
        plan, searched = settle(adopted)
        if plan is not adopted:  # a carried search fixed the others' paths as they were
            carried = {}
    # the plan flown: the certified one, else the one whose certificate found the least largest gap
    for plan, cert in sorted(made, key=lambda m: (not m[1].is_equilibrium, m[1].max_relative_gap)):
        if plan is given:
            out.plan, out.certificate = plan, cert
            return out
        if not deadline.fits_steps("accept"):
            out.notes.append("deadline: no time left to fly a plan certified")
            break
        again = deadline.timed("accept", accept, plan)
        if again is not None:
            out.flown, out.plan, out.certificate = again, plan, cert
            return out
        found = "an equilibrium" if cert.is_equilibrium else f"with a largest gap of {100 * cert.max_relative_gap:.1f} %"
        out.notes.append(f"a plan certified {found} could not be flown")
    return out
