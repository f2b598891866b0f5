"""The compiled engine: :func:`staghunt.solvers.swarm.run_swarm` and
:func:`staghunt.costs.evaluate` with the same semantics, on Numba kernels.

Randomness: one 64-bit key is drawn from the run's ``numpy.random.Generator``; every random
number of the run is a counter-based hash of (key, iteration, swarm, waypoint, component,
particle), so a seed gives the same plan for any thread count or block split. The stream is not
the NumPy engine's, so the two engines give different (statistically equivalent) plans.

Compilation: the kernels are compiled on first use and cached on disk (``cache=True``; Numba's
cache location rules apply, e.g. ``NUMBA_CACHE_DIR``). :func:`prepare` does it explicitly. When
the cache is cold it says so once through ``notify`` (default: a ``logging`` warning on
``staghunt.engine``, which reaches stderr even when logging is not configured) and compiles the
kernel entry points in two processes at once (this one and a helper subprocess writing to the
same cache), which roughly halves the wait on a 2-core machine.
"""

from __future__ import annotations

import functools
import logging
import os
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from dataclasses import replace
from typing import TYPE_CHECKING, Any, Callable, Iterable, Iterator

import numpy as np

from staghunt.costs import CostModel, Costs
from staghunt.engine import kernels as kn
from staghunt.engine.arrays import ModelArrays, SwarmArrays, kernel_args, model_arrays, no_swarm, swarm_arrays
from staghunt.engine.jit import entry_table
from staghunt.engine.loop import (
    MIN_SHARED_PARTICLES,
    chunk_length,
    iterate_chunk,
    kernel_threads,
    parallel_block,
)
from staghunt.engine.scratch import Scratch, borrow, give_back
from staghunt.engine.threads import AdaptiveThreads, usable_cores
from staghunt.scenario.model import SolverSettings
from staghunt.solvers.problem import SwarmProblem
from staghunt.solvers.swarm import Progress, SwarmOutcome

if TYPE_CHECKING:
    from staghunt.engine.deviations import Deviations

logger = logging.getLogger("staghunt.engine")

COLD_COMPILE_ESTIMATE_S = 20
"""Announced one-time compile: 16.7-18.5 s in two processes (``team_search`` follows 0.4-1.7 s
later, beside the run), 30 s in one, on a quiet 2-core VM (``uav_pass`` 10 s, ``team_pass`` 7 s,
``iterate`` 5 s, ``polish`` 5 s, ``team_search`` 3 s; 43 s and 63 s while ``iterate`` and
``polish`` compiled both entries again inside them; ``benchmarks/README.md``)."""

NOTIFY_AFTER_S = 1.0
"""When the cache index cannot be read: loading every kernel from a warm cache takes well under
this; beyond it we are compiling."""

HELPER_PHASES = (("uav_pass",), ("polish",), ("team_search",))
"""What the helper subprocess compiles, in turn, while this process compiles the others: after
each phase it writes a line to its stdout (``iterate``, ``polish`` and ``team_search`` call both
entries, and start once ``uav_pass`` is in the cache). :func:`prepare` does not wait for the
last phase (:data:`LATER`)."""
LATER = ("team_search",)
"""Entries a cold :func:`prepare` leaves to the helper while the run goes on: ``game``'s team
search, whose Python loop makes the same decisions (:func:`team_search_ready`), so the first run
does not wait 3 s more for it."""

HELPER_TIMEOUT_S = 600
"""Longest wait for each of the helper's phases; beyond it the helper is killed and this process
compiles what is left."""

_ready = threading.Event()
_prepare_lock = threading.Lock()
_later: dict[str, Any] = {}
"""The helper still compiling :data:`LATER` (``"helper"``) and ``"done"``, an event set when it
has, or has ended."""


UAV_PASS_PER_CALL = ("mode", "q0", "nb", "it", "key", "inertia")
TEAM_PASS_PER_CALL = ("mode", "q0", "nb")
POLISH_PER_CALL = ("n", "step", "min_step", "max_evaluations", "J0", "lower", "upper", "path")
TEAM_SEARCH_PER_CALL = ("slide", "fractions", "step", "min_step", "max_evaluations", "spent", "costs", "lower",
                        "upper", "ends", "best")
"""The kernel entries' leading parameters given at each call; the rest are bound by name
(:func:`staghunt.engine.arrays.kernel_args`)."""


class _Pass:
    """The arrays of one run of ``P`` particles (or, with ``wp`` ``(Q, N, K, 3)``, one
    evaluation of ``Q`` allocations) and the two kernel calls per block."""

    def __init__(self, ma: ModelArrays, sa: SwarmArrays, N: int, K: int, S: int, C: int, P: int,
                 wp: np.ndarray | None = None, initial: np.ndarray | None = None) -> None:
        self.ma, self.sa = ma, sa
        self.B = kn.block_size(N, K)
        self.X = np.zeros((S, K, 3, P))
        self.V = np.zeros((S, K, 3, P))
        self.PB = np.zeros((S, K, 3, P))
        self.pcost = np.zeros((C, P))
        self.pviol = np.zeros(P)
        self.cost = np.zeros((C, P))
        self.viol = np.zeros(P)
        self.J = np.zeros((N, P))
        self.gbest = np.zeros((S, K, 3))
        self.initial = np.zeros((0, S, K, 3)) if initial is None else initial
        if wp is None:
            self.wp = np.zeros((0, N, K, 3))
            self.terms_out, self.vio_out, self.res_out = np.zeros((0, N, 5)), np.zeros((0, N, 3)), np.zeros((0, 3, N))
        else:
            Q = wp.shape[0]
            self.wp = wp
            self.terms_out, self.vio_out, self.res_out = np.empty((Q, N, 5)), np.empty((Q, N, 3)), np.empty((Q, 3, N))
        self.scratch: list[Scratch] = []
        self.N, self.K, self.S = N, K, S
        self.mode, self.it, self.key, self.inertia = kn.MODE_INIT, 0, np.uint64(0), 0.0
        self._bound: dict[int, tuple[Any, ...]] = {}

    @property
    def uav_entries(self) -> np.ndarray:
        """``uav_pass``'s compiled code, as :func:`kernels.iterate` and :func:`kernels.polish` call it
        (:func:`staghunt.engine.jit.entry_table`)."""
        return entry_table(kn.uav_pass)

    @property
    def team_entries(self) -> np.ndarray:
        """``team_pass``'s compiled code, likewise."""
        return entry_table(kn.team_pass)

    def ensure_scratch(self, threads: int) -> None:
        """Borrow block buffers for ``threads`` threads from the pool (see :meth:`release`)."""
        if len(self.scratch) < threads:
            self.scratch += borrow((self.N, self.K, self.S, self.B), threads - len(self.scratch))

    def release(self) -> None:
        """Give the block buffers back to the pool: the next run of the same shape reuses them
        (every kernel writes a buffer before it reads it, within each block)."""
        give_back((self.N, self.K, self.S, self.B), self.scratch)
        self.scratch = []

    def block(self, q0: int, nb: int, worker: int, entries: Iterable[str] = ("uav_pass", "team_pass")) -> None:
        """Run the kernel entries on particles ``q0 .. q0+nb`` (``nb <= B``) with ``worker``'s scratch."""
        w = self.scratch[worker]
        bound = self._bound.get(worker)
        if bound is None or bound[0] is not w:  # the arrays, bound once by the kernels' parameter names
            bound = self._bound[worker] = (
                w, kernel_args(kn.uav_pass, self, self.ma, self.sa, w, per_call=UAV_PASS_PER_CALL),
                kernel_args(kn.team_pass, self, self.ma, self.sa, w, per_call=TEAM_PASS_PER_CALL))
        for name in entries:
            if name == "uav_pass":
                kn.uav_pass(self.mode, q0, nb, self.it, self.key, self.inertia, *bound[1])
            else:
                kn.team_pass(self.mode, q0, nb, *bound[2])

    def work(self, p0: int, p1: int, worker: int) -> None:
        """All particles ``p0 .. p1`` in blocks of ``B``."""
        for q0 in range(p0, p1, self.B):
            self.block(q0, min(self.B, p1 - q0), worker)


ENTRIES = ("uav_pass", "team_pass", "select_global", "iterate", "polish", "team_search")
"""Compiled entry points; ``iterate`` calls the first three, ``polish`` and ``team_search`` the
first two (through the entries' addresses: :func:`staghunt.engine.jit.entry_call`)."""


def _tiny(entries: Iterable[str]) -> None:
    """Compile (or load) the given kernel entries by running them once on a tiny two-UAV problem
    built directly (no scenario parsing), with exactly the argument types of real runs."""
    N, K, P = 2, 2, 8
    par = np.zeros(kn.N_PAR)
    par[kn.P_MARGIN], par[kn.P_SAFE], par[kn.P_HREF], par[kn.P_CONTINUOUS] = 10.0, 2.0, 20.0, 1.0
    par[kn.P_CELL], par[kn.P_C1], par[kn.P_C2] = 1.0, 1.5, 1.5
    uav = np.zeros((N, kn.U_COLUMNS))
    uav[:, kn.U_START:kn.U_START + 3] = [[10.0, 10.0, 20.0], [20.0, 10.0, 20.0]]
    uav[:, kn.U_GOAL:kn.U_GOAL + 3] = [[80.0, 80.0, 20.0], [90.0, 80.0, 20.0]]
    uav[:, kn.U_START_Z], uav[:, kn.U_GOAL_Z] = 20.0, 20.0
    uav[:, kn.U_RADIUS], uav[:, kn.U_BETA], uav[:, kn.U_LIMIT] = 1.0, 1.0, 4.0
    par[kn.P_CEIL] = np.inf
    ma = ModelArrays(uav=uav, weights=np.ones((N, 5)), cyl=np.array([[50.0, 50.0, 4.0]]),
                     prm=np.array([[-np.inf, 30.0, 0.0, 4.0, 60.0, 70.0, 20.0, 30.0]]),
                     pedge=np.array([[60.0, 20.0, 70.0, 20.0], [70.0, 20.0, 70.0, 30.0],
                                     [70.0, 30.0, 60.0, 30.0], [60.0, 30.0, 60.0, 20.0]]),
                     heads=np.zeros(1, dtype=np.int64), tails=np.ones(1, dtype=np.int64),
                     mu=np.ones((N, 1)), ref_diff=np.array([[-10.0, 0.0, 0.0]]), grid=np.zeros((1, 1)),
                     par=par)
    q = np.pi / 4
    sw = np.zeros((N, kn.SW_COLUMNS))
    sw[:, kn.SW_START:kn.SW_START + 3] = [10.0, 10.0, 20.0]
    sw[:, kn.SW_LOW:kn.SW_LOW + 3] = [0.0, 0.0, 5.0]
    sw[:, kn.SW_HIGH:kn.SW_HIGH + 3] = [100.0, 100.0, 35.0]
    sw[:, kn.SW_RANGE_LOW:kn.SW_RANGE_LOW + 3] = [0.0, -q, 0.0]
    sw[:, kn.SW_RANGE_HIGH:kn.SW_RANGE_HIGH + 3] = [50.0, q, 2 * q]
    sw[:, kn.SW_VMAX:kn.SW_VMAX + 3] = [25.0, q, q]
    sw[:, kn.SW_SMALL], sw[:, kn.SW_CENTRE], sw[:, kn.SW_SIN], sw[:, kn.SW_COS] = 1.0, q, np.sin(q), np.cos(q)
    sa = SwarmArrays(sw=sw, member=np.arange(N, dtype=np.int64), offsets=np.zeros((N, 3)),
                     fixed=np.zeros((N, K, 3)), players=np.arange(N, dtype=np.int64))
    run = _Pass(ma, sa, N, K, N, N, P)
    run.ensure_scratch(1)
    names = list(entries)
    callers = bool({"iterate", "polish", "team_search"} & set(names))  # they call both entries: load them first
    kernel_names = [e for e in ("uav_pass", "team_pass") if e in names or callers]
    if kernel_names:
        run.block(0, P, 0, kernel_names)
    if "select_global" in names:
        kn.select_global(run.cost, run.viol, np.zeros((N, 1)), 0.0, True)
    if "polish" in names:  # UAV 0's deviations from the fixed path of UAV 1 (MODE_DEVIATE)
        solo = replace(ma, par=np.concatenate([par, np.zeros(N * kn.SOLO_STRIDE)]))
        players = no_swarm(N, K, players=np.zeros(1, dtype=np.int64), member=np.array([0, -1], dtype=np.int64))
        dev = _Pass(solo, players, N, K, 0, 1, 0, wp=np.zeros((6 * K + 1, N, K, 3)))
        dev.ensure_scratch(1)
        path = np.zeros((K, 3))
        kn.polish(0, 1.0, 0.5, 0, 1.0, np.zeros(3), np.ones(3), path,
                  *kernel_args(kn.polish, dev, solo, players, dev.scratch[0], per_call=POLISH_PER_CALL))
        dev.release()
    if "team_search" in names:  # a slide, then a polish, of the team (MODE_EVALUATE)
        team = _Pass(ma, no_swarm(N, K), N, K, 0, 1, 0, wp=np.zeros((6 * K, N, K, 3)))
        team.mode = kn.MODE_EVALUATE
        team.ensure_scratch(1)
        for fractions in (np.array([0.5]), np.zeros(0)):
            kn.team_search(fractions.size > 0, fractions, 1.0, 0.5, 0, 0, np.ones(N), np.zeros(3), np.ones(3),
                           np.zeros((N, 2, 3)), np.zeros((N, K, 3)),
                           *kernel_args(kn.team_search, team, ma, sa, team.scratch[0], per_call=TEAM_SEARCH_PER_CALL))
        team.release()
    if "iterate" in names:
        hist = np.zeros((3, N))
        for threads in sorted({1, min(2, kernel_threads())}):  # the serial loop, then the parallel one
            stack = Scratch(N, K, N, run.B, 2)
            iterate_chunk(0, 3, run.B, threads, np.uint64(1), np.array([0.7, 0.0, 0.9]), run, np.zeros((N, 1)),
                     hist, np.zeros((3, N)), np.zeros(3), stack)


def _cache_is_warm() -> bool | None:
    """Whether Numba's on-disk cache holds every kernel entry for this source (``None``: cannot
    tell; this peeks at Numba's cache index, an internal API)."""
    try:
        return all(bool(getattr(kn, name)._cache._cache_file._load_index()) for name in ENTRIES)
    except Exception:  # noqa: BLE001 (any internal change: fall back to timing)
        return None


def _compile_part(phases: str) -> None:
    """Entry point of the helper subprocess: compile the kernel entries of each phase
    (``uav_pass;polish``: phases separated by ``;``, entries by ``,``), writing the phase's
    entries to stdout once they are in the cache."""
    for phase in phases.split(";"):
        _tiny(phase.split(","))
        print(phase, flush=True)


def _spawn_helper(phases: Iterable[Iterable[str]]) -> subprocess.Popen[bytes] | None:
    """Start a subprocess compiling ``phases`` into the shared cache (``None`` if it cannot start)."""
    env = dict(os.environ)
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # src/
    env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    spec = ";".join(",".join(phase) for phase in phases)
    code = f"from staghunt.engine.numba_engine import _compile_part; _compile_part({spec!r})"
    try:
        return subprocess.Popen([sys.executable, "-c", code], env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    except OSError:
        return None


def prepare(notify: Callable[[str], None] | None = None, parallel: bool = True) -> float:
    """Load (or, the first time, compile) the kernels; returns the seconds it took.

    On a cold cache (Numba's cache index lacks an entry, or, if the index cannot be read,
    loading takes longer than :data:`NOTIFY_AFTER_S`), ``notify`` (default: a warning on the
    ``staghunt.engine`` logger) is called once with a message saying what happens, and, with
    ``parallel``, a helper subprocess compiles :data:`HELPER_PHASES` into the shared cache
    meanwhile: ``uav_pass`` while this process compiles ``team_pass``, then ``polish`` while
    this process compiles ``iterate``, then :data:`LATER` while the run goes on. If the helper
    fails, this process compiles what is left.
    """
    if _ready.is_set():
        return 0.0
    with _prepare_lock:
        if _ready.is_set():
            return 0.0
        say = notify if notify is not None else logger.warning
        t0 = time.perf_counter()
        errors: list[BaseException] = []
        # what needs neither the helper's work nor uav_pass (iterate, polish and team_search call it)
        main_entries = [e for e in ENTRIES if e != "iterate" and not any(e in phase for phase in HELPER_PHASES)]

        def target() -> None:
            try:
                _tiny(main_entries)
            except BaseException as exc:  # re-raised in the caller's thread
                errors.append(exc)

        warm = _cache_is_warm()
        worker = threading.Thread(target=target, name="staghunt-engine-compile", daemon=True)
        worker.start()
        if warm is None:  # cannot tell: a warm cache loads well within NOTIFY_AFTER_S
            worker.join(NOTIFY_AFTER_S)
        helper = None
        if warm is False or (warm is None and worker.is_alive()):
            say(
                "staghunt: compiling the fast engine (one time, about "
                f"{COLD_COMPILE_ESTIMATE_S} s; later runs load it from the cache)..."
            )
            if parallel and usable_cores() > 1:
                helper = _spawn_helper(HELPER_PHASES)
        worker.join()
        if errors:
            if helper is not None:
                helper.kill()
                helper.communicate()
            raise errors[0]
        phases = _follow(helper)  # an event per phase: in the cache, or the helper ended
        if helper is not None and not phases[0].wait(HELPER_TIMEOUT_S):
            helper.kill()  # hung: what is left is compiled here
        _tiny([e for e in ENTRIES if helper is None or not any(e in phase for phase in HELPER_PHASES[1:])])
        if helper is not None:
            if not phases[1].wait(HELPER_TIMEOUT_S):
                helper.kill()
            _tiny(HELPER_PHASES[1])  # loads the helper's work (or compiles it here if it failed)
            _later.update(done=phases[2], helper=helper)
        _ready.set()
        return time.perf_counter() - t0


def _follow(helper: subprocess.Popen[bytes] | None) -> list[threading.Event]:
    """One event per :data:`HELPER_PHASES` entry, set when ``helper`` reports that phase done or
    ends (all set at once without a helper)."""
    events = [threading.Event() for _ in HELPER_PHASES]
    if helper is None or helper.stdout is None:
        for e in events:
            e.set()
        return events
    stdout = helper.stdout

    def read() -> None:
        for i, _ in enumerate(iter(stdout.readline, b"")):
            if i < len(events):
                events[i].set()
        helper.wait()
        for e in events:
            e.set()

    threading.Thread(target=read, name="staghunt-engine-helper", daemon=True).start()
    return events


def team_search_ready(wait: bool = False) -> bool:
    """Whether ``kernels.team_search`` can run in this process now: after a warm or a one-process
    :func:`prepare`, yes; after a cold one, once the helper has compiled it (:data:`LATER`; it is
    then loaded here). ``wait``: wait for the helper (or compile it here) instead of answering no."""
    prepare()
    done = _later.get("done")
    if done is None:
        return True
    if not done.is_set() and not wait:
        return False
    if not done.wait(HELPER_TIMEOUT_S):
        _later["helper"].kill()  # hung: compiled here
    with _prepare_lock:
        if _later.get("done") is done:
            _tiny(LATER)  # loads the helper's work (or compiles it here if it failed)
            _later.clear()
    return True


EVALUATION_PASSES = 8
"""Evaluation passes kept per thread (:func:`evaluate`): the last shapes and models evaluated."""
EVALUATION_ROWS = 256
"""Batches of at most this many allocations use a kept pass; larger ones (rare, and already
dominated by the kernels) build their own, so that no thread keeps large buffers."""
_evaluation_passes = threading.local()


def _evaluation_pass(ma: ModelArrays, N: int, K: int, Q: int) -> _Pass:
    """The pass that evaluates ``Q`` allocations of ``N`` UAVs x ``K`` waypoints of the model of
    ``ma``, with its own block buffers and its kernel arguments bound once: made on this
    thread's first such evaluation, then reused (a search such as ``game``'s team polish
    evaluates small batches of the same shape thousands of times, and building the pass cost
    more than the kernels). One cache per thread, so that threads never share buffers."""
    runs = getattr(_evaluation_passes, "runs", None)
    if runs is None:
        runs = _evaluation_passes.runs = {}
    key = (id(ma), N, K, Q)
    entry = runs.pop(key, None)
    if entry is not None and entry[0] is not ma:  # another model at a freed model's address
        entry[1].release()
        entry = None
    if entry is None:
        run = _Pass(ma, no_swarm(N, K), N, K, 0, 1, 0, wp=np.empty((Q, N, K, 3)))
        run.mode = kn.MODE_EVALUATE
        run.ensure_scratch(1)  # from the pool, given back when the pass is dropped
        entry = (ma, run)
    runs[key] = entry  # the most recent last
    while len(runs) > EVALUATION_PASSES:
        runs.pop(next(iter(runs)))[1].release()
    return entry[1]


def evaluate(model: CostModel, waypoints: np.ndarray) -> Costs:
    """Compiled twin of :func:`staghunt.costs.evaluate`: ``(P, N, K, 3)`` ``(x, y, h)`` -> :class:`Costs`."""
    prepare()
    wp = np.asarray(waypoints, dtype=np.float64)
    P, N, K = wp.shape[0], wp.shape[1], wp.shape[2]
    if P <= EVALUATION_ROWS:
        run = _evaluation_pass(_model_arrays_cached(model), N, K, P)
        run.wp[...] = wp
        run.work(0, P, 0)
    else:
        run = _Pass(_model_arrays_cached(model), no_swarm(N, K), N, K, 0, 1, 0, wp=np.array(wp, order="C"))
        run.mode = kn.MODE_EVALUATE
        run.ensure_scratch(1)
        with _releasing(run):
            run.work(0, P, 0)
    res = run.res_out
    return Costs(terms=run.terms_out.copy(), single=res[:, 1].copy(), formation=res[:, 0].copy(),
                 total=res[:, 2].copy(), violation=run.vio_out.copy())


def _run(
    problem: SwarmProblem,
    settings: SolverSettings,
    rng: np.random.Generator,
    progress: Progress | None,
    initial: np.ndarray | None,
    control: AdaptiveThreads,
) -> SwarmOutcome:
    P, K, iterations = settings.particles, settings.waypoints, settings.iterations
    S = problem.space.n_swarms
    N = problem.model.n_uavs
    C = problem.n_objectives
    key = np.uint64(int(rng.integers(2**63)))
    ma = model_arrays(problem.model, float(settings.c1), float(settings.c2), problem.objective == "sum")
    if problem.fixed is not None and problem.objective == "players":
        ma = replace(ma, par=np.concatenate([ma.par, _fixed_constants(problem)]))
    sa = swarm_arrays(problem, K)
    start = None if initial is None else np.array(initial, dtype=float).reshape(-1, S, K, 3)[:P].copy()
    run = _Pass(ma, sa, N, K, S, C, P, initial=start)
    state = np.array([float(settings.c0), 0.0, float(settings.damping)])  # inertia, best's violation, damping
    gcost = np.zeros((C, 1))
    history = np.empty((iterations + 1, C))
    rhistory = np.empty((iterations + 1, N))
    hviol = np.empty(iterations + 1)
    lanes = min(control.max_threads, kernel_threads())
    shape = (N, K, S, run.B, lanes)
    stack = borrow(shape, 1)[0]
    try:
        def chunk(it0: int, it1: int, threads: int) -> None:
            threads = max(1, min(threads, lanes))
            iterate_chunk(it0, it1, parallel_block(P, run.B, threads), threads, key, state, run, gcost,
                     history, rhistory, hviol, stack)

        t0 = time.perf_counter()
        chunk(0, 1, control.max_threads)
        longest = chunk_length(time.perf_counter() - t0, 1)
        it = 1
        while it <= iterations:
            threads, length = control.chunk(iterations - it + 1, longest)
            t0 = time.perf_counter()
            chunk(it, it + length, threads)
            seconds = time.perf_counter() - t0
            control.record_chunk(seconds, length)
            longest = chunk_length(seconds, length)
            if progress is not None:
                for i in range(it, it + length):
                    progress(i, iterations, history[i].copy())
            it += length
    finally:
        give_back(shape, [stack])
    gviol = float(state[1])
    return SwarmOutcome(
        best=run.gbest.copy(),
        best_waypoints=_decode_one(ma, sa, N, K, S, C, run.gbest),
        best_cost=gcost[:, 0].copy(),
        best_violation=gviol,
        history=history,
        record_history=rhistory,
        history_violation=hviol,
        path_evaluations=problem.path_evaluations(settings),
    )


@functools.lru_cache(maxsize=16)
def _model_arrays_cached(model: CostModel) -> ModelArrays:
    """:func:`model_arrays` of a model evaluated again and again (a frozen :class:`CostModel`
    hashes by identity; its arrays are read-only)."""
    return model_arrays(model)


@contextmanager
def _releasing(run: _Pass) -> Iterator[_Pass]:
    """Give ``run``'s block buffers back to the pool when the run ends, however it ends."""
    try:
        yield run
    finally:
        run.release()


def _fixed_constants(problem: SwarmProblem) -> np.ndarray:
    """``(N * SOLO_STRIDE,)`` per UAV: the unweighted ``J_s`` terms and obstacle and ground
    violations of its ``fixed`` path, computed by the kernels themselves (so a fixed UAV's
    values are bit-identical to a full evaluation's); see :data:`kernels.SOLO_STRIDE`."""
    c = evaluate(problem.model, np.asarray(problem.fixed)[None])
    return np.concatenate([c.terms[0], c.violation[0][:, :2]], axis=1).ravel()


def _decode_one(ma: ModelArrays, sa: SwarmArrays, N: int, K: int, S: int, C: int,
                particle: np.ndarray) -> np.ndarray:
    """Team waypoints ``(N, K, 3)`` of one spherical particle ``(S, K, 3)``, decoded by the kernel
    itself (its trigonometry rounds differently from NumPy's)."""
    one = _Pass(ma, sa, N, K, S, C, 1, initial=np.ascontiguousarray(particle[None]))
    one.ensure_scratch(1)
    try:
        one.block(0, 1, 0, ("uav_pass",))
        w = one.scratch[0]
        return np.stack([w.px[:, 1:K + 1, 0], w.py[:, 1:K + 1, 0], w.ph[:, :, 0]], axis=-1).copy()
    finally:
        one.release()


class NumbaEngine:
    """The compiled engine. ``threads``: ``None`` = adaptive (1 or all usable cores, whichever
    is faster, re-measured every :data:`~staghunt.engine.threads.PROBE_EVERY` iterations);
    an integer pins the count. ``notify`` receives the one-time compile message."""

    name = "numba"

    def __init__(self, threads: int | None = None, notify: Callable[[str], None] | None = None) -> None:
        if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int) or threads < 1):
            raise ValueError(f"threads must be a positive integer or None, not {threads!r}")
        self.threads = threads
        self.notify = notify
        self.last_threads: dict[int, int] = {}

    def prepare(self) -> float:
        """Compile or load the kernels now (see :func:`prepare`)."""
        return prepare(self.notify)

    def run_swarm(
        self,
        problem: SwarmProblem,
        settings: SolverSettings,
        rng: np.random.Generator,
        progress: Progress | None = None,
        initial: np.ndarray | None = None,
    ) -> SwarmOutcome:
        """Same contract as :func:`staghunt.solvers.swarm.run_swarm`."""
        self.prepare()
        shared = settings.particles >= MIN_SHARED_PARTICLES
        control = AdaptiveThreads(usable_cores() if shared else 1, self.threads if shared or self.threads is None else 1)
        out = _run(problem, settings, rng, progress, initial, control)
        self.last_threads = control.summary()
        return out

    def evaluate(self, model: CostModel, waypoints: np.ndarray) -> Costs:
        """Same contract as :func:`staghunt.costs.evaluate`."""
        self.prepare()
        return evaluate(model, waypoints)

    def team_search(self, model: CostModel, plan: np.ndarray, costs: np.ndarray, max_evaluations: int, spent: int,
                    **search: Any) -> tuple[np.ndarray, int] | None:
        """The team slide or polish of ``plan`` in one compiled call (see
        :func:`staghunt.engine.deviations.team_search`); ``None`` while the kernel is still being
        compiled beside the first run (:func:`team_search_ready`): the caller's Python loop then
        makes the same decisions."""
        from staghunt.engine.deviations import team_search

        return team_search(model, plan, costs, max_evaluations, spent, **search) if team_search_ready() else None

    def deviations(self, model: CostModel, plan: np.ndarray, n: int, costs: Costs | None = None) -> Deviations:
        """UAV ``n``'s deviation costs from the feasible ``plan`` (see
        :class:`staghunt.engine.deviations.Deviations`); ``costs``: this engine's
        :meth:`evaluate` of ``plan[None]``, if the caller has it."""
        from staghunt.engine.deviations import Deviations

        self.prepare()
        return Deviations(model, plan, n, costs)

    def __repr__(self) -> str:
        return f"NumbaEngine(threads={self.threads!r})"
