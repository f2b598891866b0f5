"""``check_compare``, ``run_compare`` and ``staghunt compare``: checks, files, resume, interruption,
dominance, Fig. 8 block."""

from __future__ import annotations

import csv
import json
import types
from pathlib import Path

import numpy as np
import pytest

import staghunt.cli.analysis
import staghunt.study.tasks
import staghunt.api
from staghunt.analysis.compare import (
    CSV_COLUMNS,
    CertifyOptions,
    CompareListener,
    check_compare,
    dominance_table,
    format_report,
    parse_methods,
    parse_seeds,
    run_compare,
)
from staghunt.analysis.paper import PAPER_GAME_LN, PAPER_RIGID_VIRTUAL_LN
from staghunt.scenario import load_scenario
from staghunt.solvers import METHODS

METHODS4 = ("game", "paper", "rigid", "independent", "weighted")
SEEDS = (1, 2)
TINY_CERT = CertifyOptions(particles=6, iterations=2, epsilon=0.01)
ENGINE = ["--engine", "numpy"]  # no compile time in the tests


def strict(path: Path):
    def reject(token):
        raise AssertionError(f"non-standard JSON constant {token!r}")

    return json.loads(path.read_text(encoding="utf-8"), parse_constant=reject)


@pytest.fixture(scope="module")
def scenario():
    return load_scenario("scenario2")


@pytest.fixture(scope="module")
def settings(scenario):
    return scenario.solver.with_(particles=8, iterations=2, waypoints=5)


@pytest.fixture(scope="module")
def done(tmp_path_factory, scenario, settings):
    out = tmp_path_factory.mktemp("cmp")
    report = run_compare(check_compare(scenario, METHODS4, SEEDS, settings, TINY_CERT, engine="numpy"), out)
    return out, report


# ------------------------------------------------------------------------------------------------
# Parsing
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("text, seeds", [("1-3", (1, 2, 3)), ("7", (7,)), ("1,4,7", (1, 4, 7)),
                                         ("1-3,2,8", (1, 2, 3, 8)), (" 0 - 1 ", (0, 1))])
def test_parse_seeds(text, seeds):
    assert parse_seeds(text) == seeds


@pytest.mark.parametrize("text", ["", "3-1", "-1", "a", "1-", "1,,2", "1.5"])
def test_parse_seeds_rejects(text):
    """The library names the field; the command line adds the flag (``--seeds``)."""
    with pytest.raises(ValueError, match="^seeds: ") as info:
        parse_seeds(text)
    assert info.value.field == "seeds"


def test_parse_methods():
    assert parse_methods("game, rigid,game") == ("game", "rigid")
    assert parse_methods("game,nope") == ("game", "nope")  # parsed; checked with its run
    with pytest.raises(ValueError, match="^methods: ") as info:
        parse_methods(" , ")
    assert info.value.field == "methods"


@pytest.mark.parametrize("methods, seeds, field, expect", [
    (("game", "nope"), (1,), "method", "unknown method 'nope'; choose one of "),
    ((), (1,), "methods", "no methods to compare"),
    (("game", "game"), (1,), "methods", "methods must not repeat"),
    (("game",), (), "seeds", "no seeds to run"),
    (("game",), (1, 1), "seeds", "seeds must not repeat"),
    (("game",), (1, -2), "seed", "seed must be an integer >= 0, got -2"),
])
def test_check_compare_refuses_before_any_run(scenario, settings, methods, seeds, field, expect):
    with pytest.raises(ValueError, match=expect) as info:
        check_compare(scenario, methods, seeds, settings, TINY_CERT, engine="numpy")
    assert info.value.field == field


def test_check_compare_checks_every_run_once(scenario, settings, monkeypatch):
    """One :func:`staghunt.api.check_plan` per method; every (method, seed) run is a checked
    request that ``run_compare`` uses as it is."""
    from staghunt.analysis.compare import runner

    calls = []
    real = runner.check_plan
    monkeypatch.setattr(runner, "check_plan", lambda *a, **k: calls.append(a[1]) or real(*a, **k))
    request = check_compare(scenario, ("game", "rigid"), (3, 1), settings, None, engine="numpy")
    assert calls == ["game", "rigid"]
    assert request.seeds == (3, 1) and sorted(request.runs) == [("game", 1), ("game", 3), ("rigid", 1), ("rigid", 3)]
    assert all(r.method == m and r.seed == s and r.settings is settings for (m, s), r in request.runs.items())


# ------------------------------------------------------------------------------------------------
# A finished comparison
# ------------------------------------------------------------------------------------------------


def test_files(done, scenario):
    out, report = done
    assert report.complete and len(report.records) == len(METHODS4) * len(SEEDS)
    for m in METHODS4:
        for s in SEEDS:
            assert (out / "runs" / f"{m}-s{s}.json").is_file()
            assert (out / "runs" / f"{m}-s{s}.certify.json").is_file()
    data = strict(out / "compare.json")
    assert data["complete"] and data["missing"] == []
    assert [(r["method"], r["seed"]) for r in data["runs"]] == [(m, s) for s in SEEDS for m in METHODS4]
    rows = list(csv.DictReader((out / "compare.csv").open()))
    assert tuple(rows[0].keys()) == CSV_COLUMNS
    assert len(rows) == len(METHODS4) * len(SEEDS) * scenario.n_uavs
    assert not list(out.glob(".*")) and not list((out / "runs").glob(".*"))  # no temporary files left


def test_every_allocation_is_scored_with_the_same_J(done, settings, scenario):
    _, report = done
    for r in report.records:
        stored = json.loads((Path(done[0]) / "runs" / f"{r.method}-s{r.seed}.json").read_text())
        assert [u["cost"]["total"] if u["cost"]["total"] != "inf" else np.inf for u in stored["uavs"]] == list(r.J)
        budget = settings.particles * (settings.iterations + 1) * scenario.n_uavs
        assert (r.evaluations <= budget) if r.method == "game" else (r.evaluations == budget)


def test_summary(done, scenario):
    _, report = done
    summary = report.data["summary"]
    assert list(summary) == list(METHODS4)
    for e in summary.values():
        assert e["runs"] == len(SEEDS) and len(e["uavs"]) == scenario.n_uavs
        for u in e["uavs"]:
            for key in ("J_mean", "J_std", "lnJ_mean", "path_length_mean", "formation_rms_mean",
                        "min_separation_segments", "min_clearance", "collision_free_rate",
                        "nash_gap_relative_mean", "nash_gap_relative_max"):
                assert key in u
    rigid = summary["rigid"]["uavs"]
    assert all(u["formation_rms_mean"] < 1e-6 for u in rigid)  # members keep the shape exactly
    text = format_report(report)
    for word in ("J_n mean", "min sep", "coll-free", "Nash gap", "Pareto-dominate", "Paper Fig. 8"):
        assert word in text


def test_dominance_matches_dominates(done):
    _, report = done
    dom = report.data["dominance"]
    assert set(dom) == {"paper", "rigid", "independent", "weighted"}
    from staghunt.solvers.dominance import dominates

    game = {r.seed: r for r in report.records if r.method == "game"}
    for r in report.records:
        if r.method == "game":
            continue
        g = game[r.seed]
        want = ("game_dominates" if dominates(g.J, g.violation, r.J, r.violation)
                else "dominates_game" if dominates(r.J, r.violation, g.J, g.violation) else "neither")
        assert dom[r.method]["seeds"][str(r.seed)] == want
    for e in dom.values():
        assert e["game_dominates"] + e["dominates_game"] + e["neither"] == e["compared"] == len(SEEDS)


def _rec(method, seed, J, violation=0.0):
    return types.SimpleNamespace(method=method, seed=seed, J=np.array(J, float), violation=violation)


def test_dominance_rules():
    records = [
        _rec("game", 1, [1, 1, 1]), _rec("x", 1, [2, 1, 1]),           # game dominates
        _rec("game", 2, [1, 3, 1]), _rec("x", 2, [1, 2, 1]),           # x dominates game
        _rec("game", 3, [1, 3, 1]), _rec("x", 3, [3, 1, 1]),           # incomparable
        _rec("game", 4, [9, 9, 9]), _rec("x", 4, [np.inf, 1, 1], 2.0),  # infeasible loses
    ]
    d = dominance_table(records, ("game", "x"))["x"]
    assert d["seeds"] == {"1": "game_dominates", "2": "dominates_game", "3": "neither", "4": "game_dominates"}
    assert (d["game_dominates"], d["dominates_game"], d["neither"]) == (2, 1, 1)
    assert dominance_table(records, ("x",)) == {}


def test_fig8_block(done):
    _, report = done
    block = report.data["paper_fig8"]
    rows = block["rows"]
    assert [r["paper"] for r in rows if r["method"] == "game"] == list(PAPER_GAME_LN)
    virtual = rows[-1]
    assert virtual["who"].startswith("virtual") and virtual["paper"] == PAPER_RIGID_VIRTUAL_LN
    rigid = [r for r in report.records if r.method == "rigid"]
    want = np.mean([np.log(r.J.sum()) for r in rigid])  # the team sum the rigid swarm minimises
    assert virtual["ours_ln_mean"] == pytest.approx(want, rel=1e-12)
    assert not block["at_paper_settings"]
    assert "d_s" in block["note"] and "virtual" in block["note"]


# ------------------------------------------------------------------------------------------------
# Resume and interruption
# ------------------------------------------------------------------------------------------------


def test_resume_plans_nothing_again(done, scenario, settings, monkeypatch):
    out, _ = done
    before = (out / "compare.json").read_bytes()

    def no_plan(*a, **k):
        raise AssertionError("a finished run was planned again")

    monkeypatch.setattr(staghunt.api, "plan", no_plan)
    monkeypatch.setattr(staghunt.study.tasks, "run_plan_task", no_plan)
    report = run_compare(check_compare(scenario, METHODS4, SEEDS, settings, TINY_CERT, engine="numpy"), out)
    assert report.complete
    assert (out / "compare.json").read_bytes() == before


def test_resume_certifies_a_run_planned_but_not_certified(done, scenario, settings, monkeypatch, tmp_path):
    """A run on disk without its certificate is certified, not planned again: the same
    certificate as the one the comparison made."""
    out, _ = done
    import shutil

    copy = tmp_path / "cmp"
    shutil.copytree(out, copy)
    lost = copy / "runs" / "game-s1.certify.json"
    lost.unlink()

    def no_plan(*a, **k):
        raise AssertionError("a finished run was planned again")

    monkeypatch.setattr(staghunt.api, "plan", no_plan)
    report = run_compare(check_compare(scenario, METHODS4, SEEDS, settings, TINY_CERT, engine="numpy"), copy)
    assert report.complete
    assert strict(lost) == strict(out / "runs" / "game-s1.certify.json")


def test_interrupt_keeps_finished_runs_and_resumes(tmp_path, scenario, settings, monkeypatch):
    class Stop(CompareListener):
        def run_finished(self, index, total, record, resumed):
            if index == 3:
                raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_compare(check_compare(scenario, ("game", "rigid"), (1, 2), settings, None, engine="numpy"), tmp_path,
                    listener=Stop())
    data = strict(tmp_path / "compare.json")
    assert [(r["method"], r["seed"]) for r in data["runs"]] == [("game", 1), ("rigid", 1), ("game", 2)]
    assert not data["complete"] and data["missing"] == ["rigid-s2"]
    calls = []
    real = staghunt.api.plan
    monkeypatch.setattr(staghunt.api, "plan", lambda request, **k: calls.append((request.method, request.seed))
                        or real(request, **k))
    report = run_compare(check_compare(scenario, ("game", "rigid"), (1, 2), settings, None, engine="numpy"), tmp_path)
    assert calls == [("rigid", 2)] and report.complete


def _profiling() -> bool:
    import dask

    return bool(dask.config.get("distributed.worker.profile.enabled"))


def test_compare_on_a_dask_cluster_gives_the_same_runs(done, scenario, settings, tmp_path):
    """Compare's runs are tasks of the sweep's task function: on a local Dask cluster (2
    processes) they give the same plans and certificates as in-process, in the same order."""
    from staghunt.study.executor import DaskExecutor

    out, _ = done
    with DaskExecutor(workers=2) as ex:
        report = run_compare(check_compare(scenario, METHODS4, SEEDS, settings, TINY_CERT, engine="numpy", threads=1),
                             tmp_path, executor=ex)
        # No dashboard, so the workers' statistical profiler (100 samples a second) is off.
        assert list(ex.client.run(_profiling).values()) == [False, False]
    assert report.complete
    here, there = strict(out / "compare.json"), strict(tmp_path / "compare.json")
    assert [(r["method"], r["seed"]) for r in there["runs"]] == [(r["method"], r["seed"]) for r in here["runs"]]
    for m in METHODS4:
        for s in SEEDS:
            a, b = strict(out / "runs" / f"{m}-s{s}.json"), strict(tmp_path / "runs" / f"{m}-s{s}.json")
            assert [u["path"] for u in a["uavs"]] == [u["path"] for u in b["uavs"]]
            ca = strict(out / "runs" / f"{m}-s{s}.certify.json")
            cb = strict(tmp_path / "runs" / f"{m}-s{s}.certify.json")
            assert [u["gap"] for u in ca["uavs"]] == [u["gap"] for u in cb["uavs"]]


def test_other_settings_in_the_directory_are_refused(done, scenario, settings):
    out, _ = done
    with pytest.raises(ValueError, match="different solver settings"):
        run_compare(check_compare(scenario, ("game",), (1,), settings.with_(particles=9), TINY_CERT), out)
    with pytest.raises(ValueError, match="different certificate budget"):
        run_compare(check_compare(scenario, ("game",), (1,), settings, CertifyOptions(particles=7, iterations=2)), out)


# ------------------------------------------------------------------------------------------------
# The command line and the figure
# ------------------------------------------------------------------------------------------------


def run_cli(argv: list[str]) -> int:
    """``staghunt`` in-process."""
    from staghunt import cli

    return cli.main(argv)


def test_cli_compare_with_figure(tmp_path, capsys):
    out = tmp_path / "c"
    code = run_cli(["compare", "scenario2", "--methods", "game,rigid", "--seeds", "1-2",
                    "--particles", "6", "--iterations", "2", "--certify-particles", "5",
                    "--certify-iterations", "1", "--out", str(out), *ENGINE])
    captured = capsys.readouterr()
    assert code == 0
    assert "game" in captured.out and "Paper Fig. 8" in captured.out and "wrote" in captured.out
    assert "[4/4] rigid seed 2" in captured.err  # progress on stderr
    png = (out / "compare.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000


def test_cli_compare_interrupted(tmp_path, capsys, monkeypatch):
    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(staghunt.cli.analysis, "run_compare", interrupted)
    code = run_cli(["compare", "scenario2", "--seeds", "1", "--out", str(tmp_path / "i"), "--quiet"])
    assert code == 130
    assert "interrupted: 0 of 5 runs finished and kept" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv",
    [
        ["compare", "nosuch"],
        ["compare", "scenario2", "--methods", "game,nope"],
        ["compare", "scenario2", "--seeds", "5-1"],
        ["compare", "scenario2", "--particles", "0"],
        ["compare", "scenario2", "--epsilon", "-0.1"],
        ["compare", "scenario2", "--out", "FILE"],
    ],
)
def test_cli_compare_bad_input(argv, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    argv = [str(blocker / "sub") if a == "FILE" else a for a in argv]
    assert run_cli(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("staghunt: error: ") and err.count("\n") == 1 and "Traceback" not in err


def test_every_registered_method_can_be_compared():
    assert set(METHODS4) <= set(METHODS)
    assert parse_methods(",".join(METHODS)) == tuple(METHODS)
