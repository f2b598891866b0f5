"""The engine's contract (:class:`staghunt.engine.Engine`, its solvers' part
:class:`staghunt.costs.CostEngine`): the NumPy reference's answer to each capability, the
compiled engine's, and the solvers reaching every capability through the engine they are given
(``None`` from a shortcut: the reference loop, with the same decisions)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from staghunt import plan  # noqa: E402
from staghunt.costs import NUMPY_COSTS, CostEngine, CostModel, Costs, NumpyCosts, evaluate  # noqa: E402
from staghunt.engine import Engine, NumpyEngine, get_engine, side_by_side  # noqa: E402
from staghunt.engine.deviations import Deviations  # noqa: E402
from staghunt.engine.numba_engine import NumbaEngine, team_search_ready  # noqa: E402
from staghunt.scenario import load_scenario  # noqa: E402
from staghunt.solvers import base  # noqa: E402
from staghunt.solvers.local import local_pass, polish  # noqa: E402
from staghunt.solvers.swarm import run_swarm  # noqa: E402
from staghunt.solvers.team_search import team_polish, team_slide  # noqa: E402


@pytest.fixture(scope="module")
def scene() -> tuple[CostModel, np.ndarray]:
    """Scenario 1's model and a feasible plan ``(3, 4, 3)`` a little off its equilibrium."""
    scenario = load_scenario("scenario1")
    model = CostModel.from_scenario(scenario)
    wp = plan(scenario, "rigid", 1, scenario.solver.with_(particles=30, iterations=10, waypoints=4),
              engine="numpy").waypoints
    assert evaluate(model, wp[None]).total_violation[0] == 0
    return model, np.array(wp)


class CompiledArithmeticOnly(NumpyEngine):
    """The compiled engine's ``evaluate`` and ``run_swarm`` with the reference's answers to the
    rest of the contract (no compiled shortcut): the solvers run their Python loops on the
    compiled engine's costs."""

    name = "numba"

    def __init__(self) -> None:
        self.inner = NumbaEngine(threads=1)
        self.run_swarm = self.inner.run_swarm  # type: ignore[assignment]

    def evaluate(self, model: CostModel, waypoints: np.ndarray) -> Costs:  # type: ignore[override]
        return self.inner.evaluate(model, waypoints)


def test_the_numpy_reference_answers_every_capability(scene):
    model, wp = scene
    J = evaluate(model, wp[None]).total[0]
    for reference in (NUMPY_COSTS, NumpyCosts(), NumpyEngine(), get_engine("numpy")):
        assert isinstance(reference, CostEngine)
        assert reference.name == "numpy"
        assert reference.evaluate is evaluate  # the reference's costs themselves
        assert reference.prepare() == 0.0  # nothing to compile
        assert reference.team_search(model, wp, J, 10_000, 0, fractions=(0.4,)) is None  # no shortcut
        assert reference.team_search(model, wp, J, 10_000, 0, step=1.0, min_step=0.01) is None
        assert reference.deviations(model, wp, 1) is None
    engine = NumpyEngine()
    assert isinstance(engine, Engine) and engine.run_swarm is run_swarm and engine.threads == 1
    assert side_by_side(engine) == (engine, 1)
    assert not isinstance(NUMPY_COSTS, Engine)  # no run_swarm: not a whole engine
    assert base.MethodRun.__dataclass_fields__["engine"].default is NUMPY_COSTS


def test_the_compiled_engine_answers_every_capability(scene):
    model, wp = scene
    engine = NumbaEngine(threads=1)
    assert isinstance(engine, Engine) and isinstance(engine, CostEngine)
    assert engine.name == "numba" and engine.threads == 1
    assert isinstance(engine.prepare(), float)
    assert engine.prepare() < 1.0  # loaded already: nothing more to do
    costs = engine.evaluate(model, wp[None])
    np.testing.assert_allclose(costs.total, evaluate(model, wp[None]).total, rtol=1e-9)
    assert team_search_ready(wait=True)
    found = engine.team_search(model, wp, costs.total[0], 10_000, 3, fractions=(0.4, 0.2))
    assert found is not None and found[0].shape == wp.shape and 3 <= found[1] <= 10_000
    dev = engine.deviations(model, wp, 1, costs)
    assert isinstance(dev, Deviations)
    assert dev(wp[1][None])[0] == costs.total[0, 1]  # UAV 2 flying its own path: its J_n


def test_get_engine_refuses_an_object_without_the_whole_contract():
    class NoShortcuts:  # run_swarm and evaluate only: the contract before it was written down
        name, threads = "numpy", 1
        run_swarm = staticmethod(run_swarm)
        evaluate = staticmethod(evaluate)

    with pytest.raises(ValueError, match="not an engine"):
        get_engine(NoShortcuts())  # type: ignore[arg-type]


def test_the_solvers_reach_the_capabilities_through_the_engine(scene):
    """``polish`` asks its engine for ``deviations``, the team searches ask for ``team_search``
    (not with ``compiled=False``); each uses the answer."""
    model, wp = scene
    asked: list[str] = []

    class Recording(NumpyCosts):
        def team_search(self, *args, **kwargs):
            asked.append("team_search")
            return None

        def deviations(self, *args, **kwargs):
            asked.append("deviations")
            return None

    engine = Recording()
    assert polish(model, wp, 0, 500, engine)[1] == polish(model, wp, 0, 500)[1]
    team_slide(model, wp, 5000, engine)
    team_polish(model, wp, 5000, engine)
    team_slide(model, wp, 5000, engine, compiled=False)
    assert asked == ["deviations", "team_search", "team_search"]

    class Answering(NumpyCosts):
        def team_search(self, model, plan, costs, max_evaluations, spent, fractions=(), step=0.0, min_step=0.0):
            return plan + 1.0, spent + 7

    moved, spent = team_slide(model, wp, 5000, Answering())
    assert np.array_equal(moved, wp + 1.0) and spent == 3 + 7  # 3: the plan's own costs


def test_the_reference_loops_and_the_compiled_shortcuts_make_the_same_decisions(scene):
    """Given the compiled engine, the solvers take its shortcuts; given its arithmetic with the
    reference's answers (no shortcuts), they run their loops: the same plans, evaluations and
    searches (``tests/test_engine.py`` compares each search on many plans)."""
    model, wp = scene
    compiled, loops = NumbaEngine(threads=1), CompiledArithmeticOnly()
    assert team_search_ready(wait=True)
    off = wp.copy()
    off[2, 1:3, 2] += 4.0  # UAV 3 out of the formation: its search and the team's gain
    for engine_search in (lambda e: polish(model, off, 2, 600, e), lambda e: team_slide(model, off, 3000, e),
                          lambda e: team_polish(model, off, 3000, e)):
        a, b = engine_search(compiled), engine_search(loops)
        assert np.array_equal(a[0], b[0]) and a[1] == b[1]
        assert not np.array_equal(a[0], off)
    J = compiled.evaluate(model, off[None]).total[0]
    a, b = local_pass(model, off, J, 600, 0.01, compiled), local_pass(model, off, J, 600, 0.01, loops)
    assert np.array_equal(a.plan, b.plan) and np.array_equal(a.gains, b.gains) and a.evaluations == b.evaluations
    assert [(m.n, m.arithmetic, m.evaluations) for m in a.searches] == [(m.n, m.arithmetic, m.evaluations)
                                                                       for m in b.searches]
    assert a.gains[2] > 0.01


def test_a_method_run_carries_the_engine_it_was_given(monkeypatch):
    """``plan`` hands the method the resolved engine itself (``MethodRun.engine``); the game on
    the compiled engine with and without its shortcuts reaches the same plan."""
    scenario = load_scenario("scenario1")
    settings = scenario.solver.with_(particles=20, iterations=8, waypoints=4, starts=2)
    seen: list[object] = []
    game = base.METHODS["game"]

    def watched(run: base.MethodRun) -> base.SolverOutput:
        seen.append(run.engine)
        return game(run)

    monkeypatch.setitem(base.METHODS, "game", watched)
    compiled, loops = NumbaEngine(threads=1), CompiledArithmeticOnly()
    a = plan(scenario, "game", 2, settings, engine=compiled)
    b = plan(scenario, "game", 2, settings, engine=loops)
    assert seen == [compiled, loops]
    assert np.array_equal(a.waypoints, b.waypoints) and a.evaluations == b.evaluations
    assert a.engine == b.engine == "numba"
