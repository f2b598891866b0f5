"""Unilateral best responses and the equilibrium certificate: each UAV's Nash gap.

A team plan ``X = (X_1 .. X_N)`` is a Nash equilibrium of the game of docs/model.md section 5 when
no UAV can lower its own cost ``J_n(X_n, X_-n)`` by changing only its own path. For every UAV
``n`` this module fixes the others' paths, re-optimises ``X_n`` alone on ``J_n`` with
single-player SPSO (one swarm, :func:`staghunt.solvers.swarm.run_swarm`), seeded, with a given
budget and warm-started from the current path (particle 0 is the encoded current path), and
reports the **Nash gap** (docs/model.md eq. (16))

    ``gap_n = J_n(X) - J_n(best response found)``  (absolute, >= 0), and ``gap_n / J_n(X)``.

Since the current path is one of the particles and bests only improve, the best found is never
worse than the current path, so ``gap_n >= 0``. A plan whose relative gaps are all
``<= epsilon`` (default :data:`DEFAULT_EPSILON` = 1 %) is reported as an epsilon-equilibrium;
otherwise the UAV with the largest gap is named with what it would gain.

What the certificate is and is not:

- The search is a heuristic, so a gap is a *lower bound* on the true Nash gap: "no deviation
  better than ``epsilon`` was found with this budget", not a proof. More particles and
  iterations make it stronger.
- The deviation is judged with the feasibility-first rule of
  :mod:`staghunt.solvers.dominance` on the deviating UAV's own violation (docs/model.md eq.
  (19)): a deviation that breaks a hard constraint (obstacle, ground, separation along
  segments) never beats a feasible path.
- The search is independent of how the plan was found: a plain swarm, its own seeds
  (``[seed, n]``), so a method cannot certify itself by construction. It is followed by a local
  search (:func:`staghunt.solvers.local.polish`: one coordinate of one waypoint at a time, in
  the site frame) from the current path and from the swarm's best deviation, with
  :data:`LOCAL_SHARE` of the swarm's budget each. The swarm's spherical encoding moves every
  later waypoint with each step and cannot represent every path (below), so without it a plan
  whose UAV gains more than ``epsilon`` by moving one waypoint a little could pass (plans made
  by sliding a team's waypoints along its routes did: swarm gaps of 0 where the local search
  found 1.3-5.8 %). Another search can only lower the best deviation found: the certificate
  never gets weaker for it.
- An infeasible plan gets no certificate: its gaps are reported as infinite
  (``status = "infeasible"``), because a UAV with an infinite cost gains an unbounded amount by
  any feasible deviation, and the others' costs are not comparable while the team violates a
  constraint.
- The warm start is the current path encoded in the spherical search space
  (:func:`staghunt.encoding.encode`). If the path is not representable there (a step longer
  than ``2 |G - S| / K``, steeper than 45 degrees, or more than 45 degrees off the start-goal
  direction), encoding clamps it; ``roundtrip_error`` reports how far the decoded warm start
  lies from the current path (metres), and the gap is still measured against the current path
  itself (and floored at 0).

Randomness: UAV ``n`` is searched with ``numpy.random.default_rng([seed, n])``, so the same plan,
budget and seed give the same certificate.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from staghunt.costs import NUMPY_COSTS, CostEngine, CostModel, evaluate
from staghunt.encoding import ANGLE_RANGE, decode, encode
from staghunt.inputs import check_waypoints
from staghunt.scenario.model import Scenario, SolverSettings, check_settings
from staghunt.solvers.requests import RequestError, check_seed
from staghunt.solvers.local import LocalSearch, polish
from staghunt.solvers.problem import solo_problem
from staghunt.solvers.searches import CertificateWork, Searches
from staghunt.solvers.swarm import Progress, SwarmRunner, run_swarm, shared_pool

DEFAULT_EPSILON = 0.01
"""Default tolerance: a relative Nash gap of at most 1 % of the UAV's own cost."""

LOCAL_SHARE = 0.25
"""Budget of each of a UAV's two local searches, as a share of its swarm search's."""

DEFAULT_PARTICLES = 400
DEFAULT_ITERATIONS = 200
"""Default budget of each UAV's deviation search: 400 x 201 = 80,400 path evaluations, four
times the 200 x 100 of staghunt 0.1, which reported half the gap a 1000 x 500 search finds."""



@dataclass(frozen=True)
class CertifyOptions:
    """Budget of each UAV's deviation search (``particles`` x ``iterations``) and the relative
    tolerance ``epsilon`` of the verdict."""

    particles: int = DEFAULT_PARTICLES
    iterations: int = DEFAULT_ITERATIONS
    epsilon: float = DEFAULT_EPSILON

    def check(self) -> None:
        """Raise ``ValueError`` (one line) for an unusable budget or tolerance."""
        ok = (isinstance(self.particles, int) and not isinstance(self.particles, bool) and self.particles >= 1
              and isinstance(self.iterations, int) and not isinstance(self.iterations, bool)
              and self.iterations >= 0)
        if not ok:
            raise ValueError("certificate budget: particles must be an integer >= 1 and iterations >= 0")
        if not (isinstance(self.epsilon, (int, float)) and math.isfinite(self.epsilon) and self.epsilon >= 0):
            raise ValueError(f"epsilon must be a finite number >= 0, got {self.epsilon!r}")


ROUNDTRIP_TOLERANCE = 1e-6
"""Metres; a larger encode/decode difference of the warm start is reported in the notes."""


def check_search(settings: SolverSettings, certify: CertifyOptions | None = None,
                 what: str = "solver settings") -> SolverSettings | None:
    """The one check of solver settings and of a certificate's budget, made once per run by
    :func:`staghunt.api.check_plan` (plan, compare, fly) and :func:`check_certify` (certify).
    Returns the certificate searches' settings (``settings`` with the certificate's particles
    and iterations; ``None`` without ``certify``). Raises :class:`RequestError` (field
    ``settings`` or ``certify``), one line starting with ``what``; settings that disable the
    certificate's search (no attraction) are refused here, before any search."""
    try:
        check_settings(settings, what)
    except ValueError as exc:
        raise RequestError(str(exc), "settings") from None
    if certify is None:
        return None
    try:
        certify.check()
    except ValueError as exc:
        raise RequestError(str(exc), "certify") from None
    if settings.c1 == 0 and settings.c2 == 0 and certify.iterations > 0:
        raise RequestError(f"{what}: c1 and c2 are both 0, so the certificate's search cannot move "
                           "towards any better path; give c1 or c2 > 0, or skip the certificate", "certify")
    return settings.with_(particles=certify.particles, iterations=certify.iterations)


@dataclass(frozen=True, eq=False)
class CertifyRequest:
    """A certificate that :func:`check_certify` has checked: the scenario, the team plan
    (read-only ``(N, K, 3)``), the searches' settings (the budget of ``options``, ``K``
    waypoints), the options and the seed. :func:`certify_plan` runs it without checking again."""

    scenario: Scenario
    waypoints: np.ndarray
    settings: SolverSettings
    options: CertifyOptions
    seed: int

    @classmethod
    def of_checked(cls, scenario: Scenario, waypoints: np.ndarray, search: SolverSettings,
                   options: CertifyOptions, seed: int) -> "CertifyRequest":
        """The request for a plan a checked run made (``search``: what :func:`check_search`
        returned for that run); nothing is checked again."""
        wp = np.array(waypoints, dtype=float)
        wp.setflags(write=False)
        return cls(scenario, wp, search.with_(waypoints=wp.shape[1]), options, int(seed))


def check_certify(scenario: Scenario, waypoints: np.ndarray, options: CertifyOptions | None = None,
                  seed: int = 0, settings: SolverSettings | None = None,
                  what: str = "certificate settings") -> CertifyRequest:
    """Every check a certificate needs, made once: the plan (a finite ``(N, K, 3)`` array of
    moderate magnitude, :func:`staghunt.inputs.check_waypoints`), the seed, the settings
    (default: the scenario's) and the budget (:func:`check_search`). Returns the
    :class:`CertifyRequest`; raises a :class:`~staghunt.errors.FieldError` (``field``:
    ``waypoints``, ``seed``, ``settings`` or ``certify``) with one line."""
    wp = check_waypoints(waypoints, scenario.n_uavs)
    options = options if options is not None else CertifyOptions()
    search = check_search(settings if settings is not None else scenario.solver, options, what)
    assert search is not None
    return CertifyRequest.of_checked(scenario, wp, search, options, check_seed(seed))


@dataclass(frozen=True, eq=False)
class UAVGap:
    """One UAV's unilateral best-response search.

    - ``current``: its ``J_n`` in the plan (``inf`` if infeasible).
    - ``best``: the least ``J_n`` it reached by changing its own path alone (``None`` if not
      searched, i.e. the plan is infeasible).
    - ``gap``: ``current - best`` floored at 0 (``inf`` for an infeasible plan); ``relative``:
      ``gap / current`` (0 if both are 0).
    - ``deviation``: ``(K, 3)`` free waypoints ``(x, y, h)`` of the best response found, or ``None``.
    - ``roundtrip_error``: metres between the decoded warm start and the current path.
    - ``evaluations``: single-UAV path evaluations spent (``particles * (iterations + 1)`` in
      the swarm, plus the local searches'); ``taken``: how many of them a local search made
      before the certificate spent (``certify_plan``'s ``searched``), counted by its maker too.
    - ``complete``: ``False`` for a UAV searched only from the plan, in a certificate stopped at
      its first refutation (``certify_plan``'s ``refute``): its gap is the one found so far.
    """

    name: str
    current: float
    best: float | None
    gap: float
    relative: float
    deviation: np.ndarray | None
    roundtrip_error: float
    evaluations: int
    taken: int = 0
    complete: bool = True


@dataclass(frozen=True, eq=False)
class Certificate:
    """The Nash gaps of a plan and the verdict.

    ``status``: ``"equilibrium"`` (every relative gap ``<= epsilon``), ``"deviation"`` (some
    UAV found a better path: see :attr:`worst`) or ``"infeasible"`` (no certificate).
    :attr:`complete`: ``False`` for a certificate stopped at its first refutation
    (:func:`certify_plan`'s ``refute``): a deviation beyond ``epsilon`` was found, and the UAVs
    not searched to the end have the gap found so far (0 and ``best`` ``None`` if none).
    """

    uavs: tuple[UAVGap, ...]
    epsilon: float
    feasible: bool
    particles: int
    iterations: int
    seed: int
    notes: tuple[str, ...] = ()

    @property
    def complete(self) -> bool:
        """Whether every UAV was searched to the end (:attr:`UAVGap.complete`)."""
        return all(u.complete for u in self.uavs)

    @property
    def max_relative_gap(self) -> float:
        return max((u.relative for u in self.uavs), default=0.0)

    @property
    def max_gap(self) -> float:
        return max((u.gap for u in self.uavs), default=0.0)

    @property
    def worst(self) -> int:
        """Index of the UAV with the largest relative gap (the first one on ties)."""
        rel = [u.relative for u in self.uavs]
        return int(np.argmax(rel)) if rel else -1

    @property
    def is_equilibrium(self) -> bool:
        return self.feasible and self.complete and self.max_relative_gap <= self.epsilon

    @property
    def status(self) -> str:
        if not self.feasible:
            return "infeasible"
        return "equilibrium" if self.is_equilibrium else "deviation"

    @property
    def verdict(self) -> str:
        """One plain-language sentence."""
        budget = f"{self.particles} particles x {self.iterations} iterations per UAV, seed {self.seed}"
        if not self.feasible:
            bad = [u.name for u in self.uavs if not math.isfinite(u.current)]
            who = f" ({', '.join(bad)} with infinite cost)" if bad else ""
            return (
                "infeasible plan: no equilibrium certificate; the plan violates a hard constraint"
                f"{who}, so the Nash gaps are infinite"
            )
        if self.is_equilibrium:
            return (
                f"epsilon-equilibrium with epsilon = {self.epsilon:.3g} relative ({self.epsilon:.2%} "
                f"of each UAV's own cost): no UAV found a unilateral improvement larger than that "
                f"with {budget} (largest relative gap {self.max_relative_gap:.3%}, largest absolute "
                f"gap {self.max_gap:.6g}); the search is heuristic, a larger budget may still find one"
            )
        w = self.uavs[self.worst]
        return (
            f"not an epsilon-equilibrium for epsilon = {self.epsilon:.3g}: {w.name} would deviate, "
            f"lowering its J_n from {w.current:.6g} to {w.best:.6g} (gap {w.gap:.6g}, "
            f"{w.relative:.2%}) with the others' paths fixed ({budget})"
        )


def certify_plan(
    request: CertifyRequest,
    *,
    progress: Callable[[int, int, int, int], None] | None = None,
    runner: SwarmRunner = run_swarm,
    azimuth: float = ANGLE_RANGE,
    workers: int = 1,
    carried: Mapping[int, UAVGap] | None = None,
    engine: CostEngine = NUMPY_COSTS,
    searched: Sequence[LocalSearch] = (),
    refute: bool = False,
    work: CertificateWork | None = None,
) -> Certificate:
    """Nash gaps of the team plan of ``request`` (:func:`check_certify`, run as checked): each
    UAV's search with the request's budget, seed and swarm parameters (``c0``, ``damping``,
    ``c1``, ``c2``, ``velocity_fraction`` of its settings), the verdict with its ``epsilon``.

    ``progress(uav, n_uavs, iteration, iterations)`` is called during the searches.
    ``runner``: what runs the searches (an engine's ``run_swarm``) and ``engine`` the local
    searches (the same engine: :class:`staghunt.costs.CostEngine`); the plan's costs, and the local searches' results, are
    always evaluated with the NumPy reference. ``azimuth``: half-width of the deviations' heading
    range (the strategy space the plan was solved in). ``workers``: searches run at once
    (threads; each UAV's swarm and its local searches are separate tasks, :func:`_side_by_side`;
    each swarm has its own generator, so the certificate is the same for any count; ``runner``
    must then be thread-safe, e.g. a compiled engine pinned to one thread).
    ``carried``: searches made for an earlier plan that stand for this one, by UAV: UAV ``n``'s
    problem (the others' paths) is the one that search fixed, and the UAV now flies a path of
    its own. Its search is not run again: its best deviation is compared with the plan's cost
    (the UAV flies that search's best reply after a certificate round: gap 0), and a note says
    so. ``searched``: local searches already made (:func:`staghunt.solvers.local.local_pass`
    before a certificate); one that is exactly a search the certificate would make (the same
    plan, UAV, budget and arithmetic: :meth:`~staghunt.solvers.local.LocalSearch.stands_for`)
    is taken instead of being made again. The certificate is the same, its evaluations
    included.

    ``refute``: stop at the first UAV whose searches so far find a deviation beyond
    ``epsilon`` (every UAV's local search from the plan first, then each UAV's swarm and local
    search in turn): the verdict "not an equilibrium" is then the full certificate's (a gap only
    grows with more searching), at a share of its cost, and the certificate is marked not
    ``complete``. For a search that only needs the verdict of a plan that is often refuted
    (the rounds of ``game``). ``work``: a :class:`CertificateWork` of an earlier call with
    the same request, whose searches are taken rather than made again (a refuted certificate
    completed later costs only what it did not search); it is filled with this call's.

    On an engine of choice, with the plan's site and memory checked too:
    :func:`staghunt.analysis.certify.certify_on_engine`.
    """
    scenario, wp, run_settings = request.scenario, request.waypoints, request.settings
    seed, epsilon = request.seed, request.options.epsilon
    particles, iterations = request.options.particles, request.options.iterations
    model = CostModel.from_scenario(scenario)
    names = [u.name for u in scenario.team]
    current = evaluate(model, wp[None])
    J = current.total[0]
    feasible = bool(current.total_violation[0] == 0 and np.all(np.isfinite(J)))
    lock = threading.Lock()

    def swarm(n: int) -> tuple[float, np.ndarray, int, float, str | None]:
        """UAV ``n``'s swarm search: its best cost and path, evaluations, round trip, note."""
        name, problem = names[n], problems[n]
        initial = encode(wp[n][None, None], problem.starts, problem.space)[0]  # (1, K, 3)
        warm = decode(initial[None], problem.starts, problem.lower, problem.upper)[0, 0]
        roundtrip = float(np.max(np.abs(warm - wp[n])))
        note = None
        if roundtrip > ROUNDTRIP_TOLERANCE:
            note = (
                f"{name}: the current path is not exactly representable in the search space "
                f"(encode/decode moves it by up to {roundtrip:.3g} m); the gap is still measured "
                "against the current path"
            )
        report: Progress | None = None
        if progress is not None:
            def report(it: int, total: int, best: np.ndarray, _n: int = n) -> None:
                with lock:
                    progress(_n, len(names), it, total)
        rng = np.random.default_rng([int(seed), n])
        out = runner(problem, run_settings, rng, report, initial)
        best = float(out.best_cost[0])
        deviation = np.array(out.best_waypoints[n])
        if out.best_violation > 0 or not math.isfinite(best):
            best, deviation = float(J[n]), wp[n].copy()  # only when the warm start itself broke
        return best, deviation, out.path_evaluations, roundtrip, note

    def local(n: int, origin: np.ndarray) -> tuple[float | None, np.ndarray, int, int]:
        """UAV ``n``'s local search from ``origin`` (module docstring), or the one made just
        before from this plan (``searched``): the ``J_n`` it reached (``None``: it did not
        move, or not to a feasible plan), its path, its evaluations and those taken."""
        team = wp.copy()
        team[n] = origin
        made = next((m for m in searched if m.stands_for(team, n, budgets[n], engine)), None)
        if made is not None:  # made just before, from this plan: the same search
            moved, used, taken = made.moved(team), made.evaluations, made.evaluations
        else:
            moved, used, taken = *polish(model, team, n, budgets[n], engine), 0
        if moved is team:
            return None, origin, used, taken
        c = evaluate(model, moved[None])
        reached = float(c.total[0, n]) if c.total_violation[0] == 0 else None
        return reached, np.array(moved[n]), used, taken

    def gap_of(n: int, counted: bool = True) -> tuple[UAVGap, str | None]:
        """UAV ``n``'s gap from the searches ``work`` holds for it: its local search from the
        plan, and (``counted``) its swarm's and the local search's from the swarm's best."""
        made = work.swarms.get(n) if counted else None
        best, deviation, spent, roundtrip, note = made if made is not None else (float(J[n]), wp[n].copy(), 0, 0.0, None)
        taken = 0
        for part in (work.from_plan.get(n), work.from_best.get(n) if counted else None):
            if part is None:
                continue
            reached, path, used, took = part
            spent, taken = spent + used, taken + took
            if reached is not None and reached < best:
                best, deviation = reached, path
        gap = max(0.0, float(J[n]) - best)
        if gap == 0.0:
            deviation = wp[n].copy()
        relative = gap / float(J[n]) if J[n] != 0 else (0.0 if gap == 0 else math.inf)
        deviation.setflags(write=False)
        if made is None and gap == 0.0:
            return UAVGap(names[n], float(J[n]), None, 0.0, 0.0, None, 0.0, spent, taken, counted), None
        return UAVGap(names[n], float(J[n]), best, gap, relative, deviation, roundtrip, spent, taken, counted), note

    found: list[tuple[UAVGap, str | None] | None] = [None] * len(names)
    todo = []
    for n in range(len(names)):
        if not feasible:
            found[n] = UAVGap(names[n], float(J[n]), None, math.inf, math.inf, None, 0.0, 0), None
        elif carried is not None and n in carried:
            found[n] = _carried(carried[n], float(J[n]), wp[n])
        else:
            todo.append(n)
    problems = {n: solo_problem(model, wp, n, run_settings.velocity_fraction, azimuth) for n in todo}
    # Each local search has LOCAL_SHARE of its UAV's swarm budget (known before the swarm runs).
    budgets = {n: int(LOCAL_SHARE * problems[n].path_evaluations(run_settings)) for n in todo}
    work = work if work is not None else CertificateWork()
    searches = Searches(todo, swarm, local, wp, work, shared_pool(workers, "certify") if workers > 1 and len(todo) > 1
                         else None)
    counted = set(todo)
    if not refute:
        searches.in_turn(todo, None, plan_too=True)
    else:  # the local searches from the plan, then each UAV's others in turn, up to the first refuted
        searches.from_plan()
        so_far = {n: gap_of(n, False)[0].relative for n in todo}
        if max(so_far.values(), default=0.0) > epsilon:
            counted = set()
        else:  # the closest to a refutation first
            order = sorted(todo, key=lambda n: -so_far[n])
            counted = set(searches.in_turn(order, lambda n: gap_of(n)[0].relative > epsilon))
    for n in todo:
        found[n] = gap_of(n, n in counted)
    unsearched = [names[n] for n in todo if n not in counted]
    gaps = [g for g, _ in found]  # type: ignore[misc]
    notes = [note for _, note in found if note is not None]  # type: ignore[misc]
    if unsearched:
        notes.append(f"stopped at the first deviation beyond epsilon: {', '.join(unsearched)} searched only "
                     "from the plan (their gaps are those found so far)")
    return Certificate(
        uavs=tuple(gaps),
        epsilon=float(epsilon),
        feasible=feasible,
        particles=particles,
        iterations=iterations,
        seed=int(seed),
        notes=tuple(notes),
    )


def _carried(earlier: UAVGap, current: float, path: np.ndarray) -> tuple[UAVGap, str]:
    """UAV ``earlier.name``'s gap in a plan where it flies ``path`` ``(K, 3)`` at cost
    ``current``, from an earlier search of the same problem (:func:`certify_plan`'s ``carried``)."""
    assert earlier.best is not None
    best = min(float(earlier.best), current)
    gap = current - best
    relative = gap / current if current != 0 else (0.0 if gap == 0 else math.inf)
    deviation = np.array(path if gap == 0.0 else earlier.deviation)
    deviation.setflags(write=False)
    note = (f"{earlier.name}: the others' paths are those of the previous search of its deviations "
            f"({earlier.evaluations} path evaluations), which stands: not searched again")
    return UAVGap(earlier.name, current, best, gap, relative, deviation, earlier.roundtrip_error, 0), note
