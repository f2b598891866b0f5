"""Engines: what runs the swarm loop and evaluates costs.

- ``"numpy"``: the readable batched NumPy reference (:func:`staghunt.solvers.swarm.run_swarm`,
  :func:`staghunt.costs.evaluate`).
- ``"numba"``: compiled kernels (:mod:`staghunt.engine.numba_engine`), one fused pass per
  iteration, on 1 or more threads. Same semantics; agreement is tested (``tests/test_engine.py``).
- ``"auto"``: ``"numba"`` when Numba imports, else ``"numpy"``.

Every method is a :class:`~staghunt.solvers.problem.SwarmProblem` run by an engine's
``run_swarm``, so every engine runs every method. The contract (:class:`Engine`) is written
down in two parts: what the solvers may ask of an engine (:class:`staghunt.costs.CostEngine`:
``name``, ``prepare``, ``evaluate``, ``team_search``, ``deviations``, below the solvers, which
receive the engine through it) and, here, ``run_swarm`` and ``threads``. The NumPy reference
answers each (:class:`NumpyEngine`); nothing is reached by probing an engine for attributes.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from staghunt.costs import CostEngine, NumpyCosts
from staghunt.solvers.swarm import SwarmRunner, run_swarm

ENGINE_NAMES = ("auto", "numpy", "numba")


@runtime_checkable
class Engine(CostEngine, Protocol):
    """An engine: the solvers' part of the contract (:class:`staghunt.costs.CostEngine`), plus
    ``run_swarm`` (contract of :func:`staghunt.solvers.swarm.run_swarm`) and ``threads`` (the
    thread count it runs on: ``None`` = adaptive, else fixed)."""

    run_swarm: SwarmRunner
    threads: int | None


class NumpyEngine(NumpyCosts):
    """The NumPy reference engine: :func:`staghunt.solvers.swarm.run_swarm` and
    :func:`staghunt.costs.evaluate` themselves, on one thread (``threads`` 1), with the
    reference's answers to the rest of the contract (:class:`staghunt.costs.NumpyCosts`:
    nothing to prepare, no compiled shortcuts)."""

    run_swarm = staticmethod(run_swarm)
    threads: int | None = 1

    def __repr__(self) -> str:
        return "NumpyEngine()"


def numba_available() -> bool:
    """Whether the compiled engine can be used (Numba imports)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def get_engine(engine: "str | Engine" = "auto", threads: int | None = None) -> Engine:
    """Resolve an engine name (``"auto"``, ``"numpy"``, ``"numba"``) or pass an engine through.

    ``threads``: for ``"numba"`` (and ``"auto"`` resolving to it), ``None`` = adaptive, else a
    fixed positive count. Raises ``ValueError`` for an unknown name or a bad ``threads``.
    """
    if not isinstance(engine, str):
        if not isinstance(engine, Engine):
            raise ValueError(f"not an engine: {engine!r}")
        return engine
    if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int) or threads < 1):
        raise ValueError(f"threads must be a positive integer or None, not {threads!r}")
    name = engine.lower()
    if name == "auto":
        name = "numba" if numba_available() else "numpy"
    if name == "numpy":
        return NumpyEngine()
    if name == "numba":
        if not numba_available():
            raise ValueError("engine 'numba' needs the numba package (pip install numba)")
        from staghunt.engine.numba_engine import NumbaEngine

        return NumbaEngine(threads=threads)
    raise ValueError(f"unknown engine {engine!r}; choose one of {', '.join(ENGINE_NAMES)}")


def side_by_side(engine: Engine) -> tuple[Engine, int]:
    """``(engine, workers)`` for many small independent searches (a certificate's per-UAV
    searches): with the compiled engine on several cores, ``workers`` searches at once, one
    thread each (a compiled engine pinned to one thread: no per-iteration barrier, which small
    swarms pay dearly); otherwise ``engine`` itself, one search at a time."""
    threads = engine.threads
    if engine.name == "numba" and (threads is None or threads > 1):
        from staghunt.engine.threads import usable_cores

        workers = usable_cores() if threads is None else threads
        if workers > 1:
            return get_engine("numba", threads=1), workers
    return engine, 1


__all__ = ["ENGINE_NAMES", "Engine", "NumpyEngine", "get_engine", "numba_available", "side_by_side"]
