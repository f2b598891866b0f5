"""Memory a run needs, estimated before anything is allocated, and the machine's memory.

:func:`estimate_plan` and :func:`estimate_certify` add up the arrays a run allocates (the swarm
arrays ``X``, ``V``, personal bests ``(S, K, 3, P)``, costs and violations, the history
``(I + 1) x N``, the compiled engine's per-thread block scratch, or the NumPy engine's population
temporaries ``(P, N, N, K + 2, 3)`` and ``(P, N, K + 1, T)``) plus the interpreter's own baseline
(:data:`BASELINE_BYTES`, Python + NumPy + Numba loaded). :func:`check_memory` refuses a run that
cannot fit in the available memory (``MemAvailable`` of ``/proc/meminfo``) with one line saying
what it needs, what the machine has and how to shrink it, and warns above
:data:`WARN_FRACTION` of it. ``benchmarks/memory.py`` compares the estimate with the measured
peak RSS of real runs.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable

from staghunt.errors import FieldError

if TYPE_CHECKING:  # annotations only
    from staghunt.engine import Engine

F8 = 8
BASELINE_BYTES = 175 * 2**20
"""Resident memory of a ``staghunt plan`` process before its arrays with the compiled engine
(interpreter, NumPy, pydantic, Numba and the loaded kernels; matplotlib not loaded), measured
with a 10-particle run (``benchmarks/memory.py``)."""

BASELINE_NUMPY_BYTES = 50 * 2**20
"""The same with the NumPy engine (Numba is not imported)."""

WARN_FRACTION = 0.25
"""Warn when a run needs more than this share of the available memory."""

REFUSE_FRACTION = 0.9
"""Refuse a run that needs more than this share of the available memory."""

logger = logging.getLogger("staghunt.budget")


class MemoryBudgetError(FieldError):
    """A run that cannot fit in memory (one line: ``need``, what it needs and what the machine
    has; then ``shrink``, how to shrink it, in plain words; ``field``: the argument to shrink)."""

    def __init__(self, need: str, shrink: str, field: str) -> None:
        super().__init__(f"{need}; use {shrink}", field)
        self.need = need
        self.shrink = shrink


def human(n: float) -> str:
    """Bytes as ``1.5 GB`` / ``320 MB`` (powers of 1024)."""
    if n >= 2**40 * 10**6:
        return f"more than {2**40 * 10**6 // 2**40:.0e} TB"  # also ints beyond float's range
    for unit, size in (("TB", 2**40), ("GB", 2**30), ("MB", 2**20), ("kB", 2**10)):
        if abs(n) >= size:
            value = n / size
            return f"{value:.4g} {unit}" if value < 1e6 else f"{value:.3e} {unit}"
    return f"{int(n)} B"


@dataclass(frozen=True)
class MemoryEstimate:
    """Peak bytes of a run: ``total`` = ``baseline`` + the largest phase's arrays (``parts``)."""

    total: int
    baseline: int
    parts: dict[str, int] = field(default_factory=dict)
    what: str = "run"

    @property
    def arrays(self) -> int:
        return self.total - self.baseline

    def describe(self) -> str:
        big = sorted(self.parts.items(), key=lambda kv: -kv[1])[:3]
        detail = ", ".join(f"{k} {human(v)}" for k, v in big if v > 0)
        return f"about {human(self.total)} ({detail}; interpreter {human(self.baseline)})"


def available_memory() -> tuple[int | None, str]:
    """(bytes available to a new allocation, where the figure comes from); ``None`` if unknown.

    Linux: ``MemAvailable`` of ``/proc/meminfo``; elsewhere ``sysconf`` free pages."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024, "MemAvailable"
    except (OSError, ValueError, IndexError):
        pass
    try:
        pages = os.sysconf("SC_AVPHYS_PAGES")
        size = os.sysconf("SC_PAGE_SIZE")
        if pages > 0 and size > 0:
            return int(pages) * int(size), "free physical memory"
    except (ValueError, OSError, AttributeError):
        pass
    return None, "unknown"


def _swarm_shape(method: str, n_uavs: int) -> tuple[int, int, int]:
    """(swarms S, objectives C, UAVs N of the model) of a method's largest swarm run."""
    if method in ("game", "rigid"):
        return 1, 1, n_uavs
    if method == "independent":
        return 1, 1, 1
    if method == "weighted":
        return n_uavs, 1, n_uavs
    return n_uavs, n_uavs, n_uavs  # paper and any other joint method


def _block(N: int, K: int) -> int:
    b = (16384 // max(1, N * (K + 2))) // 8 * 8  # engine.kernels.block_size
    return max(64, min(256, b))


def _scratch(N: int, K: int, S: int) -> int:
    """Bytes of one thread's block scratch of the compiled engine (``numba_engine.Scratch``)."""
    B = _block(N, K)
    S1 = K + 1
    cells = (max(S, 1) * 3 * K + 3 * N * (K + 2) + N * K + 5 * S1 + 6 * S1 + 2 * S1
             + 3 * N * S1 + 2 * S1 + 3 * (K + 2) + 11 * N + max(S1, 3 * N, 8) + 12)
    return cells * B * F8


def _swarm_parts(engine: str, P: int, I: int, K: int, S: int, C: int, N: int, T: int,
                 threads: int) -> dict[str, int]:
    """Bytes of one swarm run's arrays."""
    cube = S * K * 3 * P * F8  # one (S, K, 3, P) array
    parts: dict[str, int] = {}
    if engine == "numba":
        parts["swarm X, V, best (S x K x 3 x P)"] = 3 * cube
        parts["costs (P)"] = (2 * C + N + 2) * P * F8
        parts["engine scratch"] = threads * _scratch(N, K, S)
    else:
        # X, V, pbest, r1, r2 and the velocity update's temporaries (those alive at the peak).
        parts["swarm X, V, best (S x K x 3 x P)"] = 6 * cube
        parts["costs (P)"] = (2 * C + 2 * N + 2) * P * F8
        # The evaluation's largest temporaries alive at once: pairwise separations
        # (P, N, N, K + 2, 3), obstacle distances (P, N, K + 1, T), decoded paths (P, N, K + 2, 3);
        # the factors are calibrated on measured peaks (benchmarks/memory.py).
        pair = P * N * N * (K + 2) * 3 * F8 if N > 1 else 0
        parts["evaluation temporaries"] = (3 * pair + 3 * P * N * (K + 1) * max(T, 1) * F8
                                           + 15 * P * N * (K + 2) * 3 * F8 // 2)
    parts["history (I + 1)"] = (I + 1) * (C + N + 1) * F8
    return parts


def _resolve(engine: "str | Engine") -> str:
    if not isinstance(engine, str):
        return engine.name
    name = engine.lower()
    if name == "auto":
        from staghunt.engine import numba_available

        return "numba" if numba_available() else "numpy"
    return name


def _baseline(engine: str) -> int:
    return BASELINE_BYTES if engine == "numba" else BASELINE_NUMPY_BYTES


def _threads(engine: str, threads: int | None) -> int:
    if engine != "numba":
        return 1
    if threads is not None:
        return int(threads)
    from staghunt.engine.threads import usable_cores

    return usable_cores()


def estimate_plan(scenario: Any, settings: Any, method: str = "game", engine: "str | Engine" = "auto",
                  threads: int | None = None, certify: Any = None) -> MemoryEstimate:
    """Peak memory of :func:`staghunt.plan` for ``scenario`` with ``settings`` (and, with
    ``certify`` a :class:`~staghunt.solvers.response.CertifyOptions`, its certificate)."""
    name = _resolve(engine)
    nthreads = _threads(name, threads)
    N, T = scenario.n_uavs, len(scenario.world.cylinders)
    P, I, K = int(settings.particles), int(settings.iterations), int(settings.waypoints)
    S, C, Nm = _swarm_shape(method, N)
    parts = _swarm_parts(name, P, I, K, S, C, Nm, T, nthreads)
    # The plan's own record: the method's history and the result's copies of it.
    parts["history (I + 1)"] += 4 * (I + 1) * (N + C) * F8
    if certify is not None:
        cert = _swarm_parts(name, int(certify.particles), int(certify.iterations), K, 1, 1, N, T, nthreads)
        if sum(cert.values()) > sum(parts.values()):
            parts = {f"certificate {k}": v for k, v in cert.items()}
    base = _baseline(name)
    return MemoryEstimate(total=base + sum(parts.values()), baseline=base, parts=parts, what="plan")


def estimate_certify(n_uavs: int, n_obstacles: int, waypoints: int, particles: int, iterations: int,
                     engine: "str | Engine" = "auto", threads: int | None = None) -> MemoryEstimate:
    """Peak memory of one certificate (each UAV's deviation search, one after the other)."""
    name = _resolve(engine)
    parts = _swarm_parts(name, int(particles), int(iterations), int(waypoints), 1, 1, n_uavs,
                         n_obstacles, _threads(name, threads))
    base = _baseline(name)
    return MemoryEstimate(total=base + sum(parts.values()), baseline=base, parts=parts, what="certificate")


_warned: set[tuple[str, int]] = set()


def _first_time(estimate: MemoryEstimate) -> bool:
    """Warn once per estimate (the CLI checks before creating files, the library again)."""
    key = (estimate.what, estimate.total)
    if key in _warned:
        return False
    _warned.add(key)
    return True


def estimate_evaluate(n_uavs: int, n_obstacles: int, waypoints: int, population: int = 1) -> MemoryEstimate:
    """Peak memory of evaluating ``population`` team plans with the NumPy reference
    (``staghunt evaluate``, the checks of a result)."""
    parts = _swarm_parts("numpy", int(population), 0, int(waypoints), 0, 1, int(n_uavs), int(n_obstacles), 1)
    parts = {k: v for k, v in parts.items() if k == "evaluation temporaries"}
    base = BASELINE_NUMPY_BYTES
    return MemoryEstimate(total=base + sum(parts.values()), baseline=base, parts=parts, what="evaluation")


def check_memory(estimate: MemoryEstimate, shrink: str = "fewer particles, iterations or waypoints",
                 available: int | None = None, warn: Callable[[str], None] | None = None,
                 field: str = "settings") -> MemoryEstimate:
    """Raise :class:`MemoryBudgetError` (``shrink`` and ``field``: what to shrink, unless the
    largest part is the threads' scratch or the history) if ``estimate`` cannot fit in the available memory;
    above :data:`WARN_FRACTION` of it, warn once through ``warn`` (default: a warning on the
    ``staghunt.budget`` logger)."""
    source = "given"
    if available is None:
        available, source = available_memory()
    if available is None:
        return estimate
    if estimate.total > REFUSE_FRACTION * available:
        biggest = max(estimate.parts.items(), key=lambda kv: kv[1], default=("", 0))[0]
        if "scratch" in biggest:
            shrink, field = "fewer threads or waypoints", "threads"
        elif "history" in biggest:
            shrink, field = "fewer iterations", "iterations"
        raise MemoryBudgetError(
            f"the {estimate.what} would need {estimate.describe()}, but this machine has "
            f"{human(available)} available ({source})", shrink, field)
    if estimate.total > WARN_FRACTION * available and _first_time(estimate):
        (warn or logger.warning)(
            f"staghunt: warning: the {estimate.what} needs {human(estimate.total)}, "
            f"{100.0 * estimate.total / available:.0f}% of the {human(available)} available ({source})"
        )
    return estimate
