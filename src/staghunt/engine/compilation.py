"""Compiling the kernels, or loading them from Numba's on-disk cache, before they run.

Every compiled entry (:data:`ENTRIES`) is compiled for exactly the argument types of real runs,
taken from a tiny two-UAV problem built directly (no scenario parsing, nothing run):
:func:`signature`. The cache is stamped by every kernel module (:func:`staghunt.engine.jit.kernel_stamp`).

What a run needs first (:data:`RUN`) is ready when :func:`prepare` returns; what it can do
without for a while (:data:`LATER`: the parallel swarm loop, whose serial twin runs meanwhile,
and ``game``'s compiled team search, whose Python loop makes the same decisions) is ready when
:func:`ready` says so. On a cold cache, with two cores or more, a helper subprocess compiles
:data:`HELPER_PART` (into the same cache) while this process compiles the rest, then
:data:`LATER` while the run goes on; this process loads the helper's work when it needs it. A
helper that fails or hangs costs time, never a result: what it did not compile is compiled here.
An evaluation alone (:data:`EVALUATION`) compiles only the two entries of the pass.
"""

from __future__ import annotations

import fcntl
import logging
import os
import subprocess
import sys
import threading
import time
from functools import lru_cache
from typing import Any, Callable, Iterable

import numpy as np

from staghunt.engine import kernels as kn
from staghunt.engine.arrays import ModelArrays, SwarmArrays, kernel_args
from staghunt.engine.loop import ITERATE_PER_CALL, RunState
from staghunt.engine.passes import POLISH_PER_CALL, TEAM_PASS_PER_CALL, TEAM_SEARCH_PER_CALL, UAV_PASS_PER_CALL, Pass
from staghunt.engine.scratch import Scratch
from staghunt.engine.threads import usable_cores

logger = logging.getLogger("staghunt.engine")

ENTRIES = ("uav_pass", "team_pass", "select_global", "iterate_serial", "polish", "team_search", "iterate")
"""The compiled entry points. ``iterate`` and ``iterate_serial`` call the first two through
their addresses, ``polish`` and ``team_search`` too (:func:`staghunt.engine.jit.entry_call`):
no entry compiles another, so they compile in any order, in any process."""
EVALUATION = ("uav_pass", "team_pass")
"""What an evaluation of given plans needs (:func:`staghunt.engine.numba_engine.evaluate`)."""
RUN = ("uav_pass", "team_pass", "select_global", "iterate_serial", "polish")
"""What a run needs before it starts: a swarm on one thread, the polish of ``game`` and of the
certificate."""
LATER = ("team_search", "iterate")
"""What a run can start without (:func:`ready`): ``team_search`` (``game``'s Python loop makes
the same decisions meanwhile) and the parallel ``iterate`` (its serial twin runs meanwhile, on
one thread); together about as long to compile as everything in :data:`RUN` (measured:
``benchmarks/README.md``, "First run")."""
HELPER_PART = ("uav_pass", "polish")
"""What the helper compiles on a cold cache while this process compiles the rest of what is
asked (``team_pass``, ``select_global``, ``iterate_serial``): about even halves."""

COLD_COMPILE_MEASURED = "10-15 s on a quiet 2-core machine, longer on a busy one"
"""The one-time compilation announced on a cold cache: :data:`RUN` in two processes, as measured
on this project's 2-core machines (``benchmarks/README.md``, "First run": 10.0-10.8 s at load
1.2-1.7 on 2026-11-27; busy machines have taken several times as long)."""
NOTIFY_AFTER_S = 1.0
"""When the cache index cannot be read: loading every kernel from a warm cache takes well under
this; beyond it we are compiling."""
HELPER_TIMEOUT_S = 600
"""Longest wait for each of the helper's phases; beyond it the helper is killed and this process
compiles what is left."""

_lock = threading.RLock()
_loaded: set[str] = set()
"""Entries compiled or loaded in this process."""
_later: dict[str, Any] = {}
"""The helper compiling :data:`LATER` (``"helper"``) and ``"done"``, an event set when it has,
or has ended."""


# --------------------------------------------------------------------------------------------
# The argument types of real runs
# --------------------------------------------------------------------------------------------


@lru_cache(maxsize=1)
def _tiny() -> dict[str, tuple[Any, ...]]:
    """``{entry: arguments}``: a call of every entry on a tiny two-UAV problem, with exactly the
    argument types of real runs (never run: only their types are used)."""
    N, K, P = 2, 2, 8
    par = np.zeros(kn.N_PAR)
    par[kn.P_MARGIN], par[kn.P_SAFE], par[kn.P_HREF], par[kn.P_CONTINUOUS] = 10.0, 2.0, 20.0, 1.0
    par[kn.P_CELL], par[kn.P_C1], par[kn.P_C2], par[kn.P_CEIL] = 1.0, 1.5, 1.5, np.inf
    uav = np.zeros((N, kn.U_COLUMNS))
    ma = ModelArrays(uav=uav, weights=np.ones((N, 5)), cyl=np.array([[50.0, 50.0, 4.0]]),
                     prm=np.zeros((1, 8)), pedge=np.zeros((4, 4)), heads=np.zeros(1, dtype=np.int64),
                     tails=np.ones(1, dtype=np.int64), mu=np.ones((N, 1)), ref_diff=np.zeros((1, 3)),
                     grid=np.zeros((1, 1)), par=par)
    sa = SwarmArrays(sw=np.zeros((N, kn.SW_COLUMNS)), member=np.arange(N, dtype=np.int64), offsets=np.zeros((N, 3)),
                     fixed=np.zeros((N, K, 3)), players=np.arange(N, dtype=np.int64))
    run = Pass(ma, sa, N, K, N, N, P)
    w = Scratch(N, K, N, run.B)
    calls: dict[str, tuple[Any, ...]] = {
        "uav_pass": (kn.MODE_INIT, 0, P, 0, np.uint64(0), 0.0,
                     *kernel_args(kn.uav_pass, run, ma, sa, w, per_call=UAV_PASS_PER_CALL)),
        "team_pass": (kn.MODE_INIT, 0, P, *kernel_args(kn.team_pass, run, ma, sa, w, per_call=TEAM_PASS_PER_CALL)),
        "select_global": (run.cost, run.viol, np.zeros((N, 1)), 0.0, True),
    }
    stack = Scratch(N, K, N, run.B, 2)
    extra = RunState(np.uint64(1), np.zeros(3), np.zeros((N, 1)), np.zeros((3, N)), np.zeros((3, N)), np.zeros(3))
    loop = (0, 1, run.B, *kernel_args(kn.iterate, extra, run, ma, sa, stack, per_call=ITERATE_PER_CALL))
    calls["iterate"] = calls["iterate_serial"] = loop
    dev = Pass(ma, sa, N, K, 0, 1, 0, wp=np.zeros((6 * K + 1, N, K, 3)))
    calls["polish"] = (0, 1.0, 0.5, 0, 1.0, np.zeros(3), np.ones(3), np.zeros((K, 3)),
                       *kernel_args(kn.polish, dev, ma, sa, w, per_call=POLISH_PER_CALL))
    calls["team_search"] = (True, np.zeros(1), 1.0, 0.5, 0, 0, np.ones(N), np.zeros(3), np.ones(3),
                            np.zeros((N, 2, 3)), np.zeros((N, K, 3)),
                            *kernel_args(kn.team_search, dev, ma, sa, w, per_call=TEAM_SEARCH_PER_CALL))
    return calls


def signature(entry: str) -> tuple[Any, ...]:
    """The Numba argument types ``entry`` is compiled for (those of every real run)."""
    from numba import typeof

    return tuple(typeof(a) for a in _tiny()[entry])


def _compile(entries: Iterable[str]) -> None:
    """Compile (or load from the cache) ``entries`` in this process."""
    for name in entries:
        if name not in _loaded:
            getattr(kn, name).compile(signature(name))
            _loaded.add(name)


def cache_is_warm(entries: Iterable[str]) -> bool | None:
    """Whether Numba's on-disk cache holds ``entries`` for the current kernel sources (``None``:
    cannot tell; this peeks at Numba's cache index, an internal API)."""
    try:
        return all(bool(getattr(kn, name)._cache._cache_file._load_index()) for name in entries)
    except Exception:  # noqa: BLE001 (any internal change: fall back to timing)
        return None


# --------------------------------------------------------------------------------------------
# The helper subprocess
# --------------------------------------------------------------------------------------------


LATER_LOCK = "staghunt-later.lock"
"""A file in the cache directory that the helper compiling :data:`LATER` holds locked (``flock``)
while it does: a process that finds it locked does not start another helper for them (the
workers of a sweep all starting at once), and waits for the cache instead."""


def _later_lock() -> int | None:
    """A descriptor of :data:`LATER_LOCK` (``None`` if there is no cache directory to hold it)."""
    try:
        path = os.path.join(kn.iterate._cache.cache_path, LATER_LOCK)
        return os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except (AttributeError, OSError, TypeError):
        return None


def _later_busy() -> bool:
    """Whether another process's helper is compiling :data:`LATER` now (it holds the lock)."""
    fd = _later_lock()
    if fd is None:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        fcntl.flock(fd, fcntl.LOCK_UN)
        return False
    except OSError:
        return True
    finally:
        os.close(fd)


def compile_phases(phases: str) -> None:
    """Entry point of the helper subprocess: compile the entries of each phase (``uav_pass,polish;
    team_search,iterate``: phases separated by ``;``, entries by ``,``), writing the phase to
    stdout once its entries are in the cache. The phase of :data:`LATER` holds
    :data:`LATER_LOCK` (another helper holding it: that phase is left to it)."""
    for phase in phases.split(";"):
        entries = [e for e in phase.split(",") if e]
        if set(entries) <= set(LATER):
            fd = _later_lock()
            try:
                if fd is not None:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                print(phase, flush=True)
                continue
        _compile(entries)
        print(phase, flush=True)


def _spawn_helper(phases: list[list[str]]) -> subprocess.Popen[bytes] | None:
    """Start a subprocess compiling ``phases`` into the shared cache (``None`` if it cannot start)."""
    env = dict(os.environ)
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # src/
    env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    spec = ";".join(",".join(phase) for phase in phases)
    code = f"from staghunt.engine.compilation import compile_phases; compile_phases({spec!r})"
    try:
        return subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL)
    except OSError:
        return None


def _follow(helper: subprocess.Popen[bytes], count: int) -> list[threading.Event]:
    """One event per phase of ``helper``, set when it reports that phase done or ends."""
    events = [threading.Event() for _ in range(count)]
    stdout = helper.stdout

    def read() -> None:
        if stdout is not None:
            for i, _ in enumerate(iter(stdout.readline, b"")):
                if i < len(events):
                    events[i].set()
        helper.wait()
        for e in events:
            e.set()

    threading.Thread(target=read, name="staghunt-engine-helper", daemon=True).start()
    return events


# --------------------------------------------------------------------------------------------
# prepare and ready
# --------------------------------------------------------------------------------------------


def prepare(notify: Callable[[str], None] | None = None, parallel: bool = True,
            entries: tuple[str, ...] = RUN) -> float:
    """Load (or, the first time, compile) ``entries`` (default :data:`RUN`; with it, also start
    :data:`LATER` on a cold cache); returns the seconds it took.

    On a cold cache (Numba's cache index lacks an entry asked for, or, if the index cannot be
    read, loading takes longer than :data:`NOTIFY_AFTER_S`), ``notify`` (default: a warning on
    the ``staghunt.engine`` logger, which reaches stderr even when logging is not configured)
    is called once with what happens and, with ``parallel`` and two usable cores or more, a
    helper subprocess compiles :data:`HELPER_PART` meanwhile, then :data:`LATER` while the run
    goes on (:func:`ready`)."""
    if all(e in _loaded for e in entries):
        return 0.0
    with _lock:
        t0 = time.perf_counter()
        say = notify if notify is not None else logger.warning
        later = [e for e in LATER if entries == RUN and e not in _loaded and not _later]
        cold_now = [e for e in entries if e not in _loaded]
        warm = cache_is_warm(cold_now)
        if warm is None:  # cannot tell: announce if loading takes long
            timer = threading.Timer(NOTIFY_AFTER_S, lambda: say(_message()))
            timer.start()
            try:
                _compile(cold_now)
            finally:
                timer.cancel()
            return time.perf_counter() - t0
        cold_later = [e for e in later if not cache_is_warm([e])]
        helper_now = [e for e in cold_now if e in HELPER_PART] if not warm else []
        if cold_later and not helper_now and _later_busy():  # another process's helper compiles them
            _later.update(poll=True)
            cold_later = []
        phases = [p for p in (helper_now, cold_later) if p]
        helper = _spawn_helper(phases) if phases and parallel and usable_cores() > 1 else None
        if not warm:
            say(_message())
        try:
            _compile(e for e in cold_now if helper is None or e not in helper_now)
        except BaseException:
            if helper is not None:
                helper.kill()
            raise
        if helper is not None:
            events = _follow(helper, len(phases))
            if helper_now:
                if not events[0].wait(HELPER_TIMEOUT_S):
                    helper.kill()  # hung: what is left is compiled here
            if cold_later:
                _later.update(done=events[-1], helper=helper)
        _compile(cold_now)  # the helper's work, from the cache (or compiled here if it failed)
        return time.perf_counter() - t0


def _message() -> str:
    return (f"staghunt: compiling the fast engine (one time: {COLD_COMPILE_MEASURED}; "
            "later runs load it from the cache)...")


def ready(entry: str, wait: bool = False) -> bool:
    """Whether ``entry`` (one of :data:`LATER`) can run in this process now: yes once it is
    loaded, or, while the helper still compiles it beside the first run, no (``wait``: wait for
    the helper instead). When the helper is done (or has failed), the entry is loaded here
    (compiled here if the helper did not)."""
    if entry in _loaded:
        return True
    done = _later.get("done")
    if done is not None and not done.is_set():
        if not wait:
            return False
        if not done.wait(HELPER_TIMEOUT_S):
            _later["helper"].kill()  # hung: compiled here
    elif _later.get("poll") and not wait and not _in_cache(entry):
        return False  # another process's helper is compiling it: taken from the cache once there
    with _lock:
        _compile([entry])
    return True


_POLL_EVERY_S = 1.0
_polled: dict[str, float] = {}


def _in_cache(entry: str) -> bool:
    """Whether ``entry`` is in the cache now (its index read at most once a second)."""
    now = time.monotonic()
    if now - _polled.get(entry, -_POLL_EVERY_S) < _POLL_EVERY_S:
        return False
    _polled[entry] = now
    return bool(cache_is_warm([entry]))


def team_search_ready(wait: bool = False) -> bool:
    """:func:`ready` for ``game``'s compiled team search."""
    return ready("team_search", wait)


def parallel_ready(wait: bool = False) -> bool:
    """:func:`ready` for the parallel swarm loop (``kernels.iterate``)."""
    return ready("iterate", wait)
