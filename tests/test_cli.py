"""The command line, run in-process with ``main([...])`` (and once as ``python -m staghunt``)."""

from __future__ import annotations

from dataclasses import replace

import io
import json
import math
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

import staghunt.api
from staghunt.cli import ProgressReporter, main
from staghunt.costs import TERM_NAMES, CostModel, evaluate
from staghunt.scenario import builtin_names, builtin_path, load_scenario
from staghunt.solvers import METHODS

TINY = ["--particles", "20", "--iterations", "5", "--certify-particles", "6", "--certify-iterations", "2"]


def _strict_loads(text: str):
    def reject(token: str):
        raise AssertionError(f"non-standard JSON constant {token!r}")

    return json.loads(text, parse_constant=reject)


def _decode(v):
    return math.inf if v == "inf" else v


def run_plan(tmp_path: Path, *extra: str, name: str = "out") -> tuple[int, Path]:
    out = tmp_path / name
    code = main(["plan", "scenario1", *TINY, "--no-plots", "--quiet", "--out", str(out), *extra])
    return code, out


# --------------------------------------------------------------------------------------------
# Listing commands
# --------------------------------------------------------------------------------------------


def test_scenarios(capsys):
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == len(builtin_names())
    for line, name in zip(out, builtin_names()):
        assert line.startswith(name)
        assert " UAVs, " in line and "obstacles" in line


def test_methods(capsys):
    assert main(["methods"]) == 0
    out = capsys.readouterr().out
    for name in METHODS:
        assert any(line.startswith(name) for line in out.splitlines())


def test_show(capsys):
    assert main(["show", "scenario2"]) == 0
    data = _strict_loads(capsys.readouterr().out)
    assert data["name"] == "scenario2"
    assert len(data["obstacles"]) == 4 and len(data["team"]) == 3


def test_help_and_version(capsys):
    assert main(["--help"]) == 0
    assert "plan" in capsys.readouterr().out
    assert main(["plan", "--help"]) == 0
    assert "--particles" in capsys.readouterr().out
    assert main(["--version"]) == 0
    assert "staghunt" in capsys.readouterr().out


# --------------------------------------------------------------------------------------------
# plan
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("method", sorted(METHODS))
def test_plan_writes_result(tmp_path, capsys, method):
    code, out = run_plan(tmp_path, "--method", method)
    captured = capsys.readouterr()
    data = _strict_loads((out / "result.json").read_text(encoding="utf-8"))
    assert data["status"] in ("feasible", "infeasible")
    assert code == (0 if data["status"] == "feasible" else 3)
    assert data["method"] == method
    assert data["settings"]["particles"] == 20 and data["settings"]["iterations"] == 5
    assert data["settings"]["waypoints"] == 10  # the scenario's K
    assert len(data["uavs"][0]["path"]) == 12
    assert "status:" in captured.out and str(out / "result.json") in captured.out
    assert captured.err == ""  # --quiet: no progress
    assert [p.name for p in out.iterdir()] == ["result.json"]


def test_plan_summary_and_progress_lines(tmp_path, capsys):
    out = tmp_path / "o"
    code = main(["plan", "scenario1", *TINY, "--waypoints", "4", "--no-plots", "--out", str(out)])
    captured = capsys.readouterr()
    assert code in (0, 3)
    for col in ("J_n", "ln J_n", "J_s", "J_f", "length", "clearance", "sep wp", "sep seg"):
        assert col in captured.out
    for name in ("UAV1", "UAV2", "UAV3"):
        assert name in captured.out
    # stderr is not a terminal here: plain progress lines, about every 10 %.
    lines = captured.err.splitlines()
    assert lines and all(line.startswith("staghunt: iteration") for line in lines)
    assert "5/5" in lines[-1]
    data = _strict_loads((out / "result.json").read_text(encoding="utf-8"))
    assert len(data["uavs"][0]["path"]) == 6


def test_plan_same_seed_same_paths(tmp_path):
    a = run_plan(tmp_path, "--seed", "7", name="a")[1]
    b = run_plan(tmp_path, "--seed", "7", name="b")[1]
    c = run_plan(tmp_path, "--seed", "8", name="c")[1]
    pa, pb, pc = (
        [u["path"] for u in json.loads((d / "result.json").read_text())["uavs"]] for d in (a, b, c)
    )
    assert pa == pb
    assert pa != pc


def test_plan_default_out_dir(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = main(["plan", "scenario1", *TINY, "--method", "rigid", "--seed", "3", "--no-plots", "--quiet"])
    assert code in (0, 3)
    assert (tmp_path / "runs" / "scenario1-rigid-s3" / "result.json").is_file()


def test_plan_infeasible_exit_3_still_writes(tmp_path, capsys, monkeypatch):
    scenario = load_scenario("scenario1")
    real_plan = staghunt.api.plan

    def straight_plan(request, progress=None, **kw):  # the CLI runs the request it checked
        settings = request.settings
        real = real_plan(replace(request, settings=settings.with_(iterations=0)), progress=progress)
        s, g = scenario.starts(), scenario.goals()
        t = np.arange(1, settings.waypoints + 1) / (settings.waypoints + 1)
        wp = s[:, None, :] + t[None, :, None] * (g - s)[:, None, :]
        return staghunt.api.assemble(request.scenario, request.method, request.seed, settings, wp, real.history,
                                     real.objective_history, real.evaluations, real.wall_time_s)

    monkeypatch.setattr(staghunt.api, "plan", straight_plan)
    code, out = run_plan(tmp_path)
    data = _strict_loads((out / "result.json").read_text(encoding="utf-8"))
    assert code == 3
    assert data["status"] == "infeasible" and data["message"].startswith("infeasible")
    assert "status: infeasible" in capsys.readouterr().out


def test_plan_keyboard_interrupt(tmp_path, capsys, monkeypatch):
    def interrupted(request, progress=None, **kw):
        progress(1, 5, np.array([1.0, 2.0, 3.0]))
        raise KeyboardInterrupt

    monkeypatch.setattr(staghunt.api, "plan", interrupted)
    out = tmp_path / "o"
    code = main(["plan", "scenario1", *TINY, "--no-plots", "--out", str(out)])
    err = capsys.readouterr().err.splitlines()
    assert code == 130
    assert err[-1] == "staghunt: interrupted"
    assert not (out / "result.json").exists()


def test_plots_failure_is_a_warning(tmp_path, capsys, monkeypatch):
    fake = types.ModuleType("staghunt.plots")

    def save_figures(result, out_dir):
        raise RuntimeError("no display")

    fake.save_figures = save_figures
    monkeypatch.setitem(sys.modules, "staghunt.plots", fake)
    out = tmp_path / "o"
    code = main(["plan", "scenario1", *TINY, "--quiet", "--out", str(out)])
    err = capsys.readouterr().err
    assert code in (0, 3)
    assert err.strip() == "staghunt: warning: figures not written: no display"
    assert (out / "result.json").is_file()


def test_plots_are_written_when_wanted(tmp_path, capsys, monkeypatch):
    fake = types.ModuleType("staghunt.plots")
    calls = []

    def save_figures(result, out_dir):
        calls.append(out_dir)
        p = Path(out_dir) / "paths.png"
        p.write_bytes(b"png")
        return [p]

    fake.save_figures = save_figures
    monkeypatch.setitem(sys.modules, "staghunt.plots", fake)
    out = tmp_path / "o"
    assert main(["plan", "scenario1", *TINY, "--quiet", "--out", str(out)]) in (0, 3)
    assert calls == [out]
    assert "paths.png" in capsys.readouterr().out


def test_progress_bar_on_a_terminal():
    class Tty(io.StringIO):
        def isatty(self):
            return True

    stream = Tty()
    rep = ProgressReporter(stream)
    for i in range(1, 4):
        rep(i, 3, np.array([1.5, math.inf]))
    rep.close()
    text = stream.getvalue()
    assert text.startswith("\r[") and text.endswith("\n")
    assert "3/3" in text and "100%" in text and "ETA" in text and "inf" in text
    quiet = Tty()
    rep = ProgressReporter(quiet, quiet=True)
    rep(1, 3, np.array([1.0]))
    rep.close()
    assert quiet.getvalue() == ""


# --------------------------------------------------------------------------------------------
# evaluate
# --------------------------------------------------------------------------------------------


def hand_waypoints(scenario, k: int = 3) -> np.ndarray:
    """Waypoints that swing around the obstacles (feasibility is not required)."""
    s, g = scenario.starts(), scenario.goals()
    t = np.arange(1, k + 1) / (k + 1)
    wp = s[:, None, :] + t[None, :, None] * (g - s)[:, None, :]
    wp[:, :, 0] += 18.0 * np.sin(np.pi * t)[None, :]
    wp[:, :, 1] -= 18.0 * np.sin(np.pi * t)[None, :]
    wp[:, :, 2] += np.array([1.0, -2.0, 0.5])[None, :]
    return wp


@pytest.mark.parametrize("form", ["waypoints", "path"])
def test_evaluate_matches_costs(tmp_path, capsys, form):
    scenario = load_scenario("scenario1")
    wp = hand_waypoints(scenario)
    uavs = []
    for n, u in enumerate(scenario.team):
        if form == "waypoints":
            uavs.append({"name": u.name, "waypoints": wp[n].tolist()})
        else:
            full = np.vstack([scenario.starts()[n], wp[n], scenario.goals()[n]])
            uavs.append({"path": full.tolist()})
    paths = tmp_path / "PATHS.json"
    paths.write_text(json.dumps({"uavs": uavs}), encoding="utf-8")
    code = main(["evaluate", "scenario1", str(paths)])
    data = _strict_loads(capsys.readouterr().out)
    costs = evaluate(CostModel.from_scenario(scenario), wp[None])
    assert code == (0 if data["status"] == "feasible" else 3)
    assert data["status"] == ("infeasible" if data["violations"] else "feasible")
    for n, u in enumerate(data["uavs"]):
        assert u["name"] == scenario.team[n].name
        assert _decode(u["total"]) == costs.total[0, n]
        assert _decode(u["single"]) == costs.single[0, n]
        assert _decode(u["formation"]) == costs.formation[0, n]
        w = scenario.team[n].weights.as_array()
        for i, term in enumerate(TERM_NAMES):
            assert _decode(u["terms"][term]) == costs.terms[0, n, i]
            assert _decode(u["weighted_terms"][term]) == w[i] * costs.terms[0, n, i]


def test_evaluate_infeasible_uses_inf_strings(tmp_path, capsys):
    scenario = load_scenario("scenario1")
    s, g = scenario.starts(), scenario.goals()
    t = np.array([0.25, 0.5, 0.75])
    wp = s[:, None, :] + t[None, :, None] * (g - s)[:, None, :]  # straight through the cylinders
    paths = tmp_path / "PATHS.json"
    paths.write_text(json.dumps({"uavs": [{"waypoints": w.tolist()} for w in wp]}), encoding="utf-8")
    code = main(["evaluate", "scenario1", str(paths)])
    text = capsys.readouterr().out
    data = _strict_loads(text)
    assert code == 3
    assert data["status"] == "infeasible" and data["violations"]
    assert "inf" in [u["total"] for u in data["uavs"]]


# --------------------------------------------------------------------------------------------
# Bad input: one line on stderr, exit code 2, no traceback, nothing written
# --------------------------------------------------------------------------------------------


def _scenario_text() -> str:
    return builtin_path("scenario1").read_text(encoding="utf-8")


def _write(tmp_path: Path, name: str, text: str) -> str:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return str(p)


def _good_paths(scenario) -> dict:
    return {"uavs": [{"waypoints": w.tolist()} for w in hand_waypoints(scenario)]}


def bad_cases(tmp_path: Path) -> dict[str, list[str]]:
    scenario = load_scenario("scenario1")
    out = ["--out", str(tmp_path / "out")]
    unknown_key = _write(tmp_path, "unknown.toml", "bogus = 1\n" + _scenario_text())
    inside = _write(
        tmp_path,
        "inside.toml",
        _scenario_text().replace("start = [10.0, 10.0, 20.0]", "start = [40.0, 40.0, 20.0]"),
    )
    nan_weight = _write(
        tmp_path,
        "nan.toml",
        _scenario_text().replace("weights = [1.0, 100.0", "weights = [nan, 100.0", 1),
    )
    two = _good_paths(scenario)
    two["uavs"] = two["uavs"][:2]
    wrong_n = _write(tmp_path, "wrong_n.json", json.dumps(two))
    malformed = _write(tmp_path, "malformed.json", '{"uavs": [ {"waypoints": [[1, 2, 3]] }')
    nan_paths = _write(
        tmp_path, "nan_paths.json", '{"uavs": [{"waypoints": [[NaN, 1, 2]]}, {"waypoints": [[1, 1, 2]]}, '
        '{"waypoints": [[1, 1, 2]]}]}'
    )
    bad_end = _good_paths(scenario)
    bad_end["uavs"][0] = {"path": [[0.0, 0.0, 20.0], [50.0, 50.0, 20.0], [85.0, 88.66, 20.0]]}
    bad_end_file = _write(tmp_path, "bad_end.json", json.dumps(bad_end))
    uneven = _good_paths(scenario)
    uneven["uavs"][1]["waypoints"] = uneven["uavs"][1]["waypoints"][:2]
    uneven_file = _write(tmp_path, "uneven.json", json.dumps(uneven))
    wrong_name = _good_paths(scenario)
    wrong_name["uavs"][0]["name"] = "UAV3"
    wrong_name_file = _write(tmp_path, "wrong_name.json", json.dumps(wrong_name))
    a_file = _write(tmp_path, "a_file", "x")
    return {
        "unknown scenario": ["plan", "no-such-scenario", *TINY, *out],
        "unknown key": ["plan", unknown_key, *TINY, *out],
        "start inside obstacle": ["plan", inside, *TINY, *out],
        "nan weight": ["plan", nan_weight, *TINY, *out],
        "zero particles": ["plan", "scenario1", "--particles", "0", "--iterations", "5", *out],
        "negative iterations": ["plan", "scenario1", "--particles", "5", "--iterations", "-1", *out],
        "not an integer": ["plan", "scenario1", "--particles", "many", *out],
        "unknown method": ["plan", "scenario1", "--method", "telepathy", *TINY, *out],
        "negative seed": ["plan", "scenario1", "--seed", "-3", *TINY, *out],
        "out is a file": ["plan", "scenario1", *TINY, "--out", a_file],
        "out under a file": ["plan", "scenario1", *TINY, "--out", a_file + "/sub"],
        "unknown command": ["teleport", "scenario1"],
        "no command": [],
        "show unknown": ["show", "nowhere.toml"],
        "evaluate wrong N": ["evaluate", "scenario1", wrong_n],
        "evaluate malformed": ["evaluate", "scenario1", malformed],
        "evaluate NaN token": ["evaluate", "scenario1", nan_paths],
        "evaluate missing file": ["evaluate", "scenario1", str(tmp_path / "missing.json")],
        "evaluate bad endpoint": ["evaluate", "scenario1", bad_end_file],
        "evaluate uneven K": ["evaluate", "scenario1", uneven_file],
        "evaluate wrong name": ["evaluate", "scenario1", wrong_name_file],
        "evaluate bad scenario": ["evaluate", unknown_key, wrong_n],
    }


CASE_IDS = [
    "unknown scenario", "unknown key", "start inside obstacle", "nan weight", "zero particles",
    "negative iterations", "not an integer", "unknown method", "negative seed", "out is a file",
    "out under a file", "unknown command", "no command", "show unknown", "evaluate wrong N",
    "evaluate malformed", "evaluate NaN token", "evaluate missing file", "evaluate bad endpoint",
    "evaluate uneven K", "evaluate wrong name", "evaluate bad scenario",
]


@pytest.mark.parametrize("case", CASE_IDS)
def test_bad_input_one_line_exit_2(tmp_path, capsys, case):
    argv = bad_cases(tmp_path)[case]
    code = main(argv)
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert code == 2, captured.err
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("staghunt: error: ")
    assert "Traceback" not in captured.err + captured.out
    assert not (tmp_path / "out").exists()


def test_bad_input_messages_are_specific(tmp_path, capsys):
    cases = bad_cases(tmp_path)
    expect = {
        "unknown command": "argument COMMAND: invalid choice: 'teleport'",
        "unknown key": "bogus",
        "start inside obstacle": "inside obstacle",
        "nan weight": "finite",
        "zero particles": "--particles",
        "evaluate wrong N": "3 UAVs",
        "evaluate malformed": "not valid JSON",
        "evaluate bad endpoint": "start",
        "evaluate wrong name": "UAV1",
    }
    for case, word in expect.items():
        assert main(cases[case]) == 2
        err = capsys.readouterr().err
        assert word in err, (case, err)


# --------------------------------------------------------------------------------------------
# python -m staghunt
# --------------------------------------------------------------------------------------------


def test_python_m_staghunt(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "staghunt", "plan", "scenario1", "--particles", "10",
         "--iterations", "2", "--no-plots", "--quiet", "--out", str(out)],
        capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode in (0, 3), proc.stderr
    assert "Traceback" not in proc.stderr
    data = _strict_loads((out / "result.json").read_text(encoding="utf-8"))
    assert data["status"] == ("feasible" if proc.returncode == 0 else "infeasible")


def test_the_command_line_adds_the_flags_of_a_refused_field():
    from staghunt.budget import MemoryBudgetError
    from staghunt.cli.common import worded
    from staghunt.errors import FieldError

    assert worded(FieldError("the scenario has no [origin]", "origin"), "export").endswith("(--origin LAT,LON,ALT)")
    assert worded(FieldError("seeds: the range '3-1' runs backwards", "seeds"), "compare").endswith("(--seeds)")
    assert worded(ValueError("plain")) == "plain"
    refused = MemoryBudgetError("the certificate would need 9 TB", "a smaller certificate budget", "certify")
    assert worded(refused, "certify") == "the certificate would need 9 TB; use a smaller --particles or --iterations"
    assert worded(refused, "plan") == str(refused)


def test_the_epilog_lists_every_exit_code():
    from staghunt.cli import build_parser

    epilog = build_parser().epilog
    for code in ("0", "1", "2", "3", "130", "141"):
        assert f" {code} " in f" {epilog} ", code
