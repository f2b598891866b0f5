"""Hostile input through the real CLI: every case exits with the documented code, stderr holds at
most one line (never a traceback or a Python warning), and nothing half-written stays behind.

Run in-process through ``staghunt.cli.main`` (plus a few subprocesses for pipes and FIFOs), with
tiny budgets and the NumPy engine so that the whole module stays fast.
"""

from __future__ import annotations

import copy
import json
import os
import re
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from staghunt import budget
from staghunt.cli import main
from staghunt.scenario import builtin_path

TINY = ["--particles", "6", "--iterations", "1", "--waypoints", "3", "--engine", "numpy",
        "--certify-particles", "4", "--certify-iterations", "1", "--no-plots", "--quiet"]
CERT = ["--particles", "4", "--iterations", "1", "--engine", "numpy", "--quiet"]
SCENARIO_TEXT = builtin_path("scenario1").read_text(encoding="utf-8")
SRC = str(Path(__file__).resolve().parents[1] / "src")


# ------------------------------------------------------------------------------------------------
# Helpers
# ------------------------------------------------------------------------------------------------


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def assert_clean(err: str, code: int) -> None:
    """At most one line on stderr (exactly one, an error line, for exit 2), short, no traceback
    or warning."""
    lines = err.splitlines()
    assert "Traceback" not in err and "Warning" not in err and "Exception ignored" not in err, err
    if code == 2:
        assert len(lines) == 1, err
        assert lines[0].startswith("staghunt: error: "), err
    else:
        assert len(lines) <= 1, err
    assert all(len(line) <= 500 for line in lines), [len(line) for line in lines]


def refused(capsys, *argv: str, expect: str | None = None) -> str:
    code, out, err = run(capsys, *argv)
    assert code == 2, (code, out, err)
    assert_clean(err, code)
    if expect is not None:
        assert re.search(expect, err), err
    return err


def no_leftovers(directory: Path) -> None:
    """No temporary (half-written) file in ``directory``."""
    if directory.exists():
        assert not [p.name for p in directory.iterdir() if p.name.endswith(".tmp")]


def toml_with(**values: str) -> str:
    """scenario1's TOML with the first ``key = ...`` line of each key replaced."""
    text = SCENARIO_TEXT
    for key, value in values.items():
        text, n = re.subn(rf"(?m)^{key}\s*=.*$", f"{key} = {value}", text, count=1)
        assert n == 1, key
    return text


def write(tmp_path: Path, name: str, text: str | bytes) -> Path:
    p = tmp_path / name
    if isinstance(text, bytes):
        p.write_bytes(text)
    else:
        p.write_text(text, encoding="utf-8")
    return p


def feed_fifo(path: Path, data: bytes) -> threading.Thread:
    """Create a FIFO at ``path`` and write ``data`` into it from a thread (one reader)."""
    os.mkfifo(path)

    def writer() -> None:
        with open(path, "wb") as fh:
            fh.write(data)

    t = threading.Thread(target=writer, daemon=True)
    t.start()
    return t


@pytest.fixture(scope="module")
def result_file(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("plan")
    assert main(["plan", "scenario1", *TINY, "--seed", "1", "--out", str(out)]) in (0, 3)
    return out / "result.json"


@pytest.fixture(scope="module")
def result_data(result_file) -> dict:
    return json.loads(result_file.read_text())


def paths_of(result: dict) -> dict:
    return {"uavs": [{"waypoints": [[p[0], p[1], h] for p, h in zip(u["path"][1:-1], u["heights"][1:-1])]}
                     for u in result["uavs"]]}


# ------------------------------------------------------------------------------------------------
# Scenario files (show / plan)
# ------------------------------------------------------------------------------------------------


SCENARIO_CASES = {
    "utf16": (SCENARIO_TEXT.encode("utf-16"), r"not UTF-8 text.*UTF-16"),
    "latin1": ("description = 'caf\u00e9'\n".encode("latin-1") + SCENARIO_TEXT.encode(), r"not UTF-8"),
    "empty": (b"", r"site: required key is missing"),
    "binary": (bytes(range(256)), r"not UTF-8|invalid TOML"),
    "nul": (b"name = \"a\x00b\"\n", r"invalid TOML"),
    "deep_array": ("a = " + "[" * 50000 + "]" * 50000, r"nested too deeply|nested more than"),
    "deep_table": ("a = " + "{b = " * 3000 + "1" + "}" * 3000, r"nested too deeply|nested more than"),
    "huge_int": (toml_with(xmax="1" + "0" * 400), r"site\.xmax: an integer of \d+ bits is beyond"),
    "huge_int_4300": (toml_with(xmax="1" * 5000), r"invalid TOML|beyond"),
    "huge_key": (SCENARIO_TEXT + "\n" + "k" * 100_000 + " = 1\n", r"unknown key"),
    "huge_value": (toml_with(description='"' + "d" * 100_000 + '"'), None),
    "desired_height_1e308": (toml_with(desired_height="1e308"), r"costs\.desired_height: 1e\+308 is beyond"),
    "xmax_1e300": (toml_with(xmax="1e300"), r"site\.xmax: 1e\+300 is beyond"),
    "xmin_minus_1e308": (toml_with(xmin="-1.7e308"), r"site\.xmin"),
    "start_near_1e308": (toml_with(start="[1e307, 10, 20]"), r"team\[0\]\.start\[0\]"),
    "weight_huge": (toml_with(weights="[1e300, 1, 1, 1, 1]"), r"team\[0\]\.weights\[0\]"),
    "nan": (toml_with(xmax="nan"), r"site\.xmax: must be a finite number"),
    "inf": (toml_with(hmax="inf"), r"site\.hmax: must be a finite number"),
    "string_number": (toml_with(xmax='"100"'), r"site\.xmax: expected a number"),
    "negative_radius": (toml_with(radius="-1"), r"radius"),
    "waypoints_float": (toml_with(waypoints="1e8"), r"solver\.waypoints: expected an integer"),
    "particles_zero": (toml_with(particles="0"), r"solver\.particles"),
    "velocity_fraction_0": (toml_with(velocity_fraction="0"), r"velocity_fraction"),
    "bool_number": (toml_with(xmax="true"), r"site\.xmax"),
    "array_for_table": ("site = [1, 2]\n" + SCENARIO_TEXT.replace("[site]", "[site_]"), r"site|unknown key"),
}


@pytest.mark.parametrize("case", sorted(SCENARIO_CASES))
def test_scenario_file_refused(tmp_path, capsys, case):
    data, expect = SCENARIO_CASES[case]
    if case == "huge_value":  # valid, only long: shown (not refused), the plan may use it
        p = write(tmp_path, "s.toml", data)
        code, out, err = run(capsys, "show", str(p))
        assert code == 0 and not err
        return
    p = write(tmp_path, "s.toml", data)
    err = refused(capsys, "show", str(p), expect=expect)
    assert str(p) in err  # the file is named


@pytest.mark.parametrize("case", ["utf16", "huge_key", "desired_height_1e308", "deep_array"])
def test_plan_refuses_before_creating_anything(tmp_path, capsys, case):
    p = write(tmp_path, "s.toml", SCENARIO_CASES[case][0])
    out = tmp_path / "out"
    refused(capsys, "plan", str(p), *TINY, "--out", str(out))
    assert not out.exists()


def test_scenario_directory_fifo_missing(tmp_path, capsys):
    refused(capsys, "show", str(tmp_path), expect=r"a directory, not a file")
    refused(capsys, "show", str(tmp_path / "nope.toml"), expect=r"no such scenario file")
    refused(capsys, "show", "", expect=r"no such scenario file")
    fifo = tmp_path / "scenario.fifo"
    t = feed_fifo(fifo, SCENARIO_TEXT.encode())
    code, out, err = run(capsys, "show", str(fifo))
    t.join(5)
    assert code == 0 and json.loads(out)["name"] == "scenario1" and not err


def test_utf8_bom_is_accepted(tmp_path, capsys):
    p = write(tmp_path, "bom.toml", b"\xef\xbb\xbf" + SCENARIO_TEXT.encode())
    code, out, err = run(capsys, "show", str(p))
    assert code == 0 and not err


def test_long_error_lines_are_cut(tmp_path, capsys):
    key = "k" * 100_000
    p = write(tmp_path, "s.toml", SCENARIO_TEXT + f"\n{key} = 1\n")
    err = refused(capsys, "show", str(p))
    assert len(err) < 600 and "..." in err


# ------------------------------------------------------------------------------------------------
# evaluate
# ------------------------------------------------------------------------------------------------


def _evaluate(tmp_path, capsys, data, name="paths.json") -> tuple[int, str, str]:
    p = tmp_path / name
    p.write_text(data if isinstance(data, str) else json.dumps(data))
    code, out, err = run(capsys, "evaluate", "scenario1", str(p))
    assert_clean(err, code)
    return code, out, err


@pytest.mark.parametrize("coord,value,bound", [(2, 60.0, "hmax"), (2, -3.0, "hmin"), (0, 1e6, "xmax"),
                                               (1, -500.0, "ymin")])
def test_evaluate_outside_site_box_is_infeasible(tmp_path, capsys, result_data, coord, value, bound):
    data = paths_of(result_data)
    data["uavs"][0]["waypoints"][1][coord] = value
    code, out, err = _evaluate(tmp_path, capsys, data)
    assert code == 3
    report = json.loads(out)
    assert report["status"] == "infeasible"
    assert any("leaves the site box" in v and f"site.{bound}" in v for v in report["violations"])


@pytest.mark.parametrize("value,expect", [
    (1e200, r"uavs\[0\]\.waypoints\[0\]\[0\]: 1e\+200 is beyond"),
    (int("9" * 400), r"uavs\[0\]\.waypoints\[0\]\[0\]: an integer beyond"),
    (-1.7e308, r"is beyond"),
    ("10", r"expected a number"),
    (None, r"expected a number"),
    (True, r"expected a number"),
    ([1, 2], r"expected a number"),
])
def test_evaluate_bad_numbers(tmp_path, capsys, result_data, value, expect):
    data = paths_of(result_data)
    data["uavs"][0]["waypoints"][0][0] = value
    p = tmp_path / "paths.json"
    p.write_text(json.dumps(data))
    refused(capsys, "evaluate", "scenario1", str(p), expect=expect)


@pytest.mark.parametrize("text,expect", [
    ("[" * 100_000 + "]" * 100_000, r"nested too deeply"),
    ('{"uavs": [[[NaN, 1, 2]]]}', r"non-standard JSON number"),
    ('{"uavs": [Infinity]}', r"non-standard JSON number"),
    ('{"uavs": [' + "1" * 5000 + "]}", r"not valid JSON"),
    ("", r"not valid JSON"),
    ("[]", r"expected a JSON object"),
    ('{"uavs": null}', r"uavs: expected a list"),
    ('{"uavs": [null, null, null]}', r"uavs\[0\]: expected an object"),
    ('{"uavs": []}', r"has 3 UAVs"),
    ('{"' + "x" * 100_000 + '": 1}', r"unknown key"),
    ('{"uavs": [{"waypoints": [], "path": []}, {}, {}]}', r"exactly one"),
    ('{"uavs": [{"waypoints": []}, {}, {}]}', r"at least 1 free waypoint"),
])
def test_evaluate_bad_files(tmp_path, capsys, text, expect):
    p = tmp_path / "paths.json"
    p.write_text(text)
    err = refused(capsys, "evaluate", "scenario1", str(p), expect=expect)
    assert str(p) in err


def test_evaluate_utf16_directory_missing(tmp_path, capsys):
    p = tmp_path / "paths.json"
    p.write_bytes('{"uavs": []}'.encode("utf-16"))
    refused(capsys, "evaluate", "scenario1", str(p), expect=r"not UTF-8 text.*UTF-16")
    refused(capsys, "evaluate", "scenario1", str(tmp_path), expect=r"a directory")
    refused(capsys, "evaluate", "scenario1", str(tmp_path / "none.json"), expect=r"no such file")


def test_evaluate_accepts_a_result_file(capsys, result_file, result_data):
    code, out, err = run(capsys, "evaluate", "scenario1", str(result_file))
    assert_clean(err, code)
    assert code == (0 if result_data["status"] == "feasible" else 3)
    report = json.loads(out)
    for u, stored in zip(report["uavs"], result_data["uavs"]):
        assert u["total"] == stored["cost"]["total"]


def test_evaluate_result_file_in_another_scenario(tmp_path, capsys, result_file, result_data):
    """The paths are evaluated in the scenario given (scenario2 shares scenario1's team); a team
    that does not match is refused."""
    code, out, err = run(capsys, "evaluate", "scenario2", str(result_file))
    assert code in (0, 3) and json.loads(out)["scenario"] == "scenario2"
    assert_clean(err, code)
    d = copy.deepcopy(result_data)
    d["uavs"] = d["uavs"][:2]
    p = tmp_path / "two.json"
    p.write_text(json.dumps(d))
    refused(capsys, "evaluate", "scenario1", str(p), expect=r"has 3 UAVs")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.recursive(st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False, allow_infinity=False)
                    | st.text(max_size=5),
                    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=5), inner, max_size=3),
                    max_leaves=20))
def test_evaluate_random_json_never_crashes(tmp_path, capsys, value):
    data = {"uavs": [{"waypoints": value}, {"waypoints": value}, {"waypoints": value}]}
    p = tmp_path / "random.json"
    p.write_text(json.dumps(data))
    code, out, err = run(capsys, "evaluate", "scenario1", str(p))
    assert code in (0, 2, 3)
    assert_clean(err, code)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.sampled_from(["xmin", "xmax", "ymax", "hmin", "hmax", "radius", "beta", "danger_margin",
                        "safe_distance", "desired_height", "min_clearance", "c0", "c1", "damping"]),
       st.one_of(st.floats(), st.integers(min_value=-10**30, max_value=10**30),
                 st.text(alphabet="abc\"'[]{}", max_size=4)))
def test_scenario_random_values_never_crash(tmp_path, capsys, key, value):
    if isinstance(value, str):
        literal = json.dumps(value)
    elif isinstance(value, float) and value != value:
        literal = "nan"
    elif isinstance(value, float) and abs(value) == float("inf"):
        literal = "inf" if value > 0 else "-inf"
    else:
        literal = repr(value)
    p = tmp_path / "random.toml"
    p.write_text(toml_with(**{key: literal}))
    code, out, err = run(capsys, "show", str(p))
    assert code in (0, 2)
    assert_clean(err, code)


# ------------------------------------------------------------------------------------------------
# certify
# ------------------------------------------------------------------------------------------------


def _tampered(result_data: dict, edit) -> dict:
    d = copy.deepcopy(result_data)
    edit(d)
    return d


CERTIFY_CASES = {
    "cost_list": (lambda d: d["uavs"][0].__setitem__("cost", [1, 2]), r"uavs\[0\]\.cost: expected an object"),
    "cost_total_string": (lambda d: d["uavs"][0]["cost"].__setitem__("total", "big"), r"uavs\[0\]\.cost\.total"),
    "uav_null": (lambda d: d["uavs"].__setitem__(1, None), r"uavs\[1\]: expected an object, got null"),
    "setting_string": (lambda d: d["settings"].__setitem__("c1", "1.5"), r"settings\.c1: expected a finite number"),
    "particles_string": (lambda d: d["settings"].__setitem__("particles", "10"), r"settings\.particles"),
    "velocity_fraction_0": (lambda d: d["settings"].__setitem__("velocity_fraction", 0),
                            r"settings: velocity_fraction must be a number in \(0, 1\]"),
    "c1_c2_zero": (lambda d: d["settings"].update(c1=0, c2=0), r"c1 and c2 are both 0"),
    "settings_list": (lambda d: d.__setitem__("settings", [1]), r"settings: expected an object"),
    "seed_negative": (lambda d: d.__setitem__("seed", -1), r"seed: expected an integer >= 0"),
    "seed_string": (lambda d: d.__setitem__("seed", "0"), r"seed"),
    "no_format": (lambda d: d.pop("format"), r"not a staghunt result file"),
    "uavs_missing": (lambda d: d.pop("uavs"), r"uavs: expected a list"),
    "scenario_null": (lambda d: d.__setitem__("scenario", None), r"scenario: expected an object"),
    "path_short": (lambda d: d["uavs"][0].__setitem__("path", [[0, 0, 0]]), r"uavs\[0\]\.path"),
    "path_huge": (lambda d: d["uavs"][0]["path"][1].__setitem__(0, 1e200), r"uavs\[0\]\.path\[1\]\[0\]"),
    "path_int_400": (lambda d: d["uavs"][0]["path"][1].__setitem__(0, int("9" * 400)), r"uavs\[0\]\.path\[1\]\[0\]"),
    "heights_short": (lambda d: d["uavs"][0].__setitem__("heights", [1.0]), r"uavs\[0\]\.heights"),
    "outside_site": (lambda d: d["uavs"][0]["heights"].__setitem__(1, 500.0), r"leaves the site box"),
    "scenario_bad": (lambda d: d["scenario"]["site"].__setitem__("xmax", "x"), r"embedded scenario.*site\.xmax"),
    "scenario_huge": (lambda d: d["scenario"]["costs"].__setitem__("desired_height", 1e308), r"desired_height"),
}


@pytest.mark.parametrize("case", sorted(CERTIFY_CASES))
def test_certify_hand_edited_result(tmp_path, capsys, result_data, case):
    edit, expect = CERTIFY_CASES[case]
    p = tmp_path / "result.json"
    p.write_text(json.dumps(_tampered(result_data, edit)))
    err = refused(capsys, "certify", str(p), *CERT, expect=expect)
    assert str(p) in err


def test_certify_reads_a_fifo_once(tmp_path, capsys, result_file):
    fifo = tmp_path / "result.fifo"
    t = feed_fifo(fifo, result_file.read_bytes())
    code, out, err = run(capsys, "certify", str(fifo), *CERT)
    t.join(5)
    assert code in (0, 3), err
    assert_clean(err, code)
    assert "verdict:" in out


@pytest.mark.parametrize("argv,expect", [
    (["--particles", "1e12"], r"would need about .* available .*smaller --particles"),
    (["--particles", "1000000000000"], r"would need about"),
    (["--iterations", "100000000000"], r"would need about"),
    (["--particles", "0"], r"--particles"),
    (["--particles", "abc"], r"--particles"),
    (["--epsilon", "nan"], r"--epsilon"),
    (["--epsilon", "1e999"], r"--epsilon"),
    (["--seed", "-1"], r"--seed"),
    (["--threads", "0"], r"--threads"),
    (["--out", ""], r"--out: must not be empty"),
    (["--out", "/nonexistent-dir/cert.json"], r"no such directory"),
    (["--out", "x" * 300], r"this file system allows"),
])
def test_certify_bad_options(tmp_path, capsys, result_file, argv, expect):
    refused(capsys, "certify", str(result_file), "--engine", "numpy", "--quiet", *argv, expect=expect)


def test_certify_out_is_a_directory(tmp_path, capsys, result_file):
    refused(capsys, "certify", str(result_file), *CERT, "--out", str(tmp_path), expect=r"is a directory")


# ------------------------------------------------------------------------------------------------
# plan: output directory, budgets, dry run
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("argv,expect", [
    (["--out", ""], r"--out: must not be empty"),
    (["--out", " "], r"--out: must not be empty"),
    (["--particles", "-1"], r"--particles"),
    (["--iterations", "1.5"], r"--iterations"),
    (["--waypoints", "0"], r"--waypoints"),
    (["--method", "nope"], r"--method"),
    (["--engine", "fast"], r"--engine"),
    (["--seed", "x"], r"--seed"),
    (["--epsilon", "-1%"], r"--epsilon"),
    (["--certify-particles", "0"], r"--certify-particles"),
])
def test_plan_bad_options(tmp_path, capsys, monkeypatch, argv, expect):
    monkeypatch.chdir(tmp_path)
    refused(capsys, "plan", "scenario1", *TINY, *argv, expect=expect)
    assert not (tmp_path / "runs").exists()


def test_plan_out_name_too_long(tmp_path, capsys):
    out = tmp_path / ("a" * 300)
    refused(capsys, "plan", "scenario1", *TINY, "--out", str(out), expect=r"allows 255")
    deep = tmp_path.joinpath(*(["d" * 200] * 25))
    refused(capsys, "plan", "scenario1", *TINY, "--out", str(deep), expect=r"longer than 4096")


def test_plan_out_is_a_file(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    refused(capsys, "plan", "scenario1", *TINY, "--out", str(f), expect=r"not a directory")
    refused(capsys, "plan", "scenario1", *TINY, "--out", str(f / "sub"), expect=r"not a directory")


def test_plan_400_character_scenario_name_plans(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    p = write(tmp_path, "long.toml", toml_with(name='"' + "n" * 400 + '"'))
    code, out, err = run(capsys, "plan", str(p), *TINY)
    assert code in (0, 3)
    assert_clean(err, code)
    (made,) = (tmp_path / "runs").iterdir()
    assert len(made.name) < 100 and (made / "result.json").is_file()


@pytest.mark.parametrize("argv", [
    ["--particles", "1e8"],
    ["--particles", "100000000"],
    ["--iterations", "1e12"],
    ["--waypoints", "100000000"],
    ["--certify-particles", "1e10"],
])
def test_plan_budget_that_cannot_fit(tmp_path, capsys, monkeypatch, argv):
    monkeypatch.setattr(budget, "available_memory", lambda: (8 * 2**30, "MemAvailable"))
    out = tmp_path / "out"
    err = refused(capsys, "plan", "scenario1", *TINY, *argv, "--out", str(out),
                  expect=r"would need about .* GB|TB.*8 GB available")
    assert "8 GB available" in err and "use fewer" in err
    assert not out.exists()


def test_scenario_waypoints_that_cannot_fit(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(budget, "available_memory", lambda: (8 * 2**30, "MemAvailable"))
    p = write(tmp_path, "k.toml", toml_with(waypoints="100000000"))
    refused(capsys, "plan", str(p), "--particles", "6", "--iterations", "1", "--no-plots",
            "--out", str(tmp_path / "o"), expect=r"would need about")
    assert not (tmp_path / "o").exists()


def test_plan_big_budget_warns_once(tmp_path, capsys, monkeypatch):
    est = budget.estimate_plan(__import__("staghunt").load_scenario("scenario1"),
                               __import__("staghunt").load_scenario("scenario1").solver.with_(
                                   particles=6, iterations=1, waypoints=3), "game", "numpy")
    monkeypatch.setattr(budget, "available_memory", lambda: (int(est.total * 2.5), "MemAvailable"))
    budget._warned.clear()
    out = tmp_path / "out"
    code, stdout, err = run(capsys, "plan", "scenario1", *TINY, "--no-certify", "--out", str(out))
    assert code in (0, 3)
    assert_clean(err, code)
    assert err.startswith("staghunt: warning: the plan needs")
    assert (out / "result.json").is_file()


def test_library_plan_refuses_before_allocating(monkeypatch):
    import staghunt

    monkeypatch.setattr(budget, "available_memory", lambda: (2**30, "MemAvailable"))
    s = staghunt.load_scenario("scenario1")
    with pytest.raises(budget.MemoryBudgetError, match="would need"):
        staghunt.plan(s, settings=s.solver.with_(particles=10**8, iterations=1), engine="numpy")


def test_dry_run_prints_estimate_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "out"
    code, stdout, err = run(capsys, "plan", "scenario1", "--particles", "3e6", "--dry-run", "--out", str(out))
    assert code == 0 and not err
    assert re.search(r"memory: about [\d.]+ GB", stdout)
    assert "3000000 particles" in stdout
    assert not out.exists()


def test_estimate_grows_with_the_budget():
    import staghunt

    s = staghunt.load_scenario("scenario1")
    small = budget.estimate_plan(s, s.solver.with_(particles=1000), "paper", "numba", 1)
    big = budget.estimate_plan(s, s.solver.with_(particles=100_000), "paper", "numba", 1)
    assert big.arrays > 50 * small.arrays
    assert budget.estimate_plan(s, s.solver, "game", "numpy").arrays > budget.estimate_plan(
        s, s.solver, "game", "numba", 1).arrays


def test_available_memory_is_read():
    avail, source = budget.available_memory()
    assert avail is None or avail > 0


# ------------------------------------------------------------------------------------------------
# compare
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("argv,expect", [
    (["--out", ""], r"--out: must not be empty"),
    (["--seeds", "x-y"], r"seed"),
    (["--methods", "nope"], r"nope"),
    (["--particles", "1e12"], r"would need about"),
])
def test_compare_bad_input(tmp_path, capsys, argv, expect):
    out = tmp_path / "cmp"
    args = ["compare", "scenario1", "--particles", "6", "--iterations", "1", "--waypoints", "3",
            "--seeds", "1", "--engine", "numpy", "--no-certify", "--no-figure", "--quiet", "--out", str(out)]
    refused(capsys, *args, *argv, expect=expect)
    assert not out.exists()


# ------------------------------------------------------------------------------------------------
# Pipes and processes: nothing lost, no "Exception ignored"
# ------------------------------------------------------------------------------------------------


def _sub(args: list[str], shell_tail: str, tmp_path: Path, unbuffered: bool = False) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    py = f"{sys.executable} {'-u ' if unbuffered else ''}-m staghunt"
    cmd = f"{py} {' '.join(args)} {shell_tail}; echo \"rc=${{PIPESTATUS[0]}}\" >&2"
    return subprocess.run(["bash", "-c", cmd], capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)


@pytest.mark.parametrize("unbuffered", [False, True])
def test_plan_into_a_closed_pipe_keeps_the_result(tmp_path, unbuffered):
    args = ["plan", "scenario1", *TINY[:-1], "--out", "out"]  # not quiet: the report is long
    proc = _sub(args, "| head -c 1 >/dev/null", tmp_path, unbuffered)
    assert "Traceback" not in proc.stderr and "Exception ignored" not in proc.stderr, proc.stderr
    assert "rc=141" in proc.stderr or "rc=0" in proc.stderr or "rc=3" in proc.stderr, proc.stderr
    result = json.loads((tmp_path / "out" / "result.json").read_text())
    assert result["format"] == "staghunt-result/1"
    no_leftovers(tmp_path / "out")


def test_plan_with_stderr_into_a_closed_pipe(tmp_path):
    args = ["plan", "scenario1", "--particles", "6", "--iterations", "40", "--waypoints", "3", "--engine",
            "numpy", "--no-certify", "--no-plots", "--out", "out"]
    proc = _sub(args, "2>&1 | head -c 1 >/dev/null", tmp_path, unbuffered=True)
    assert "Traceback" not in proc.stderr and "Exception ignored" not in proc.stderr, proc.stderr
    assert (tmp_path / "out" / "result.json").is_file()


def test_certify_process_substitution(tmp_path, result_file):
    proc = _sub(["certify", f"<(cat {result_file})", *CERT], "", tmp_path)
    assert "not valid JSON" not in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
    assert "verdict:" in proc.stdout


# ------------------------------------------------------------------------------------------------
# DEM files, threads, random edits of a result file
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", ["huge", "nan", "object", "3d", "garbage", "directory"])
def test_dem_files(tmp_path, capsys, case):
    import numpy as np

    dem = tmp_path / "dem.npy"
    if case == "huge":
        np.save(dem, np.full((20, 20), 1e300))
    elif case == "nan":
        np.save(dem, np.full((20, 20), np.nan))
    elif case == "object":
        np.save(dem, np.array([[{"a": 1}]], dtype=object), allow_pickle=True)
    elif case == "3d":
        np.save(dem, np.zeros((2, 2, 2)))
    elif case == "garbage":
        dem.write_bytes(b"\x93NUMPY garbage")
    else:
        dem.mkdir()
    text = SCENARIO_TEXT.replace('kind = "flat"', f'kind = "dem"\nfile = "{dem}"\ncell_size = 10.0')
    if text == SCENARIO_TEXT:
        pytest.skip("scenario1 has no ground.kind line to edit")
    p = write(tmp_path, "s.toml", text)
    refused(capsys, "show", str(p), expect=r"ground|DEM")


def test_threads_are_bounded(tmp_path, capsys):
    refused(capsys, "plan", "scenario1", *TINY, "--threads", "1000000", "--out", str(tmp_path / "o"),
            expect=r"--threads: must be an integer <= ")


def _leaves(value, where=()):
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _leaves(v, (*where, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _leaves(v, (*where, i))
    else:
        yield where


JSON_VALUES = st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False, allow_infinity=False) \
    | st.text(max_size=4) | st.lists(st.integers(), max_size=2) | st.just({})


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_certify_random_edits_never_crash(tmp_path_factory, capsys, result_data, data):
    """Replace one leaf (outside the long notes and histories) of a real result.json by a random
    JSON value: certify refuses it (2) or certifies (0 / 3), never a traceback."""
    leaves = [w for w in _leaves(result_data)
              if w and w[0] not in ("notes", "objective_history", "search", "certificate", "message")
              and "history" not in w]
    where = data.draw(st.sampled_from(leaves))
    value = data.draw(JSON_VALUES)
    d = copy.deepcopy(result_data)
    target = d
    for k in where[:-1]:
        target = target[k]
    target[where[-1]] = value
    p = tmp_path_factory.mktemp("edit") / "result.json"
    p.write_text(json.dumps(d))
    code, out, err = run(capsys, "certify", str(p), *CERT)
    assert code in (0, 2, 3), (where, value, err)
    assert_clean(err, code)


# ------------------------------------------------------------------------------------------------
# The library's entry points
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kwargs,expect", [
    ({"seed": -1}, r"seed must be an integer >= 0"),
    ({"seed": "x"}, r"seed must be an integer >= 0"),
    ({"seed": True}, r"seed must be an integer >= 0"),
    ({"method": "nope"}, r"unknown method"),
    ({"threads": 0}, r"threads"),
    ({"engine": "fast"}, r"unknown engine"),
])
def test_library_plan_refuses(kwargs, expect):
    import staghunt

    s = staghunt.load_scenario("scenario1")
    args = {"engine": "numpy", "settings": s.solver.with_(particles=4, iterations=1, waypoints=3), **kwargs}
    with pytest.raises(ValueError, match=expect):
        staghunt.plan(s, **args)


@pytest.mark.parametrize("edit,expect", [
    (lambda wp: wp.__setitem__((0, 0, 0), 1e200), r"beyond the supported magnitude"),
    (lambda wp: wp.__setitem__((0, 0, 2), float("nan")), r"finite"),
    (lambda wp: wp.__setitem__((1, 1, 2), 60.0), r"leaves the site box.*hmax"),
])
def test_library_certify_and_evaluate_refuse(result_data, edit, expect):
    import numpy as np

    import staghunt
    from staghunt.analysis.certify import certify_on_engine
    from staghunt.io.paths_json import evaluate_paths

    s = staghunt.load_scenario("scenario1")
    wp = np.array([u["waypoints"] for u in paths_of(result_data)["uavs"]], dtype=float)
    edit(wp)
    with pytest.raises(ValueError, match=expect):
        certify_on_engine(s, wp, particles=4, iterations=1, engine="numpy")
    if "site box" in expect:
        assert evaluate_paths(s, wp)["status"] == "infeasible"
    else:
        with pytest.raises(ValueError, match=expect):
            evaluate_paths(s, wp)


def test_certify_out_never_replaces_a_special_file(tmp_path, capsys, result_file):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    refused(capsys, "certify", str(result_file), *CERT, "--out", str(fifo), expect=r"not a regular file")
    assert fifo.exists() and not fifo.is_file()


def test_atomic_write_refuses_special_files(tmp_path):
    from staghunt.io.atomic import write_text_atomic

    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="not a regular file"):
        write_text_atomic("x", fifo)
    with pytest.raises(ValueError, match="a directory"):
        write_text_atomic("x", tmp_path)
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_plan_refuses_a_fifo_named_result_json_before_the_search(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    os.mkfifo(out / "result.json")
    refused(capsys, "plan", "scenario1", *TINY, "--out", str(out), expect=r"not a regular file")


def test_ctrl_c_during_the_search(tmp_path):
    import signal
    import time

    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-u", "-m", "staghunt", "plan", "scenario1", "--particles", "20",
                             "--iterations", "1000000", "--waypoints", "3", "--engine", "numpy", "--no-certify",
                             "--no-plots", "--out", "out"], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            # A suite started in the background (nohup, `&`) ignores SIGINT, and a
                            # child inherits that: Python then installs no handler and Ctrl-C is lost.
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and not (tmp_path / "out").exists():
        time.sleep(0.05)
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and err.splitlines()[-1] == "staghunt: interrupted"
    assert not (tmp_path / "out").exists()  # the directory it made for the run is removed again


def test_evaluate_waypoints_that_cannot_fit(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(budget, "available_memory", lambda: (64 * 2**20, "MemAvailable"))
    scenario = __import__("staghunt").load_scenario("scenario1")
    entries = []
    for u in scenario.team:
        xs = [u.start[0] + (u.goal[0] - u.start[0]) * (i + 1) / 20001 for i in range(20000)]
        ys = [u.start[1] + (u.goal[1] - u.start[1]) * (i + 1) / 20001 for i in range(20000)]
        entries.append({"waypoints": [[x, y, 20.0] for x, y in zip(xs, ys)]})
    p = tmp_path / "many.json"
    p.write_text(json.dumps({"uavs": entries}))
    refused(capsys, "evaluate", "scenario1", str(p), expect=r"evaluation would need about .*fewer waypoints")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.one_of(st.integers(min_value=-5, max_value=10**13).map(str),
                          st.floats(allow_nan=True).map(repr), st.text(max_size=6)),
                min_size=3, max_size=3))
def test_dry_run_random_budgets(capsys, monkeypatch, values):
    monkeypatch.setattr(budget, "available_memory", lambda: (8 * 2**30, "MemAvailable"))
    argv = ["plan", "scenario1", "--dry-run", "--engine", "numpy", "--particles=" + values[0],
            "--iterations=" + values[1], "--waypoints=" + values[2]]
    code, out, err = run(capsys, *argv)
    assert code in (0, 2)
    assert_clean(err, code)
    if code == 0:
        assert "memory: about" in out


def test_absurd_budgets_in_the_library(monkeypatch):
    import staghunt

    s = staghunt.load_scenario("scenario1")
    for changes in ({"particles": 10**400}, {"iterations": 10**30}, {"waypoints": 10**12}):
        with pytest.raises(budget.MemoryBudgetError, match="would need"):
            staghunt.plan(s, settings=s.solver.with_(**changes), engine="numpy")


def test_scenario_budget_beyond_magnitude(tmp_path, capsys):
    p = write(tmp_path, "s.toml", toml_with(particles="1" + "0" * 30))
    refused(capsys, "show", str(p), expect=r"solver\.particles: .*no budget this large")


def test_settings_that_cannot_certify_are_refused_before_the_search(tmp_path, capsys):
    p = write(tmp_path, "c0.toml", toml_with(c1="0", c2="0"))
    out = tmp_path / "out"
    refused(capsys, "plan", str(p), *TINY, "--out", str(out), expect=r"c1 and c2 are both 0.*--no-certify")
    assert not out.exists()
    code, stdout, err = run(capsys, "plan", str(p), *TINY, "--no-certify", "--out", str(out))
    assert code in (0, 3) and (out / "result.json").is_file()


# ------------------------------------------------------------------------------------------------
# export: the paths checked against the embedded scenario, the set written as one (issue 19)
# ------------------------------------------------------------------------------------------------


def _free(d: dict, fn) -> None:
    """Apply ``fn(point, height_list, k)`` to every free waypoint of every UAV."""
    for u in d["uavs"]:
        for k in range(1, len(u["path"]) - 1):
            fn(u["path"][k], u["heights"], k)


EXPORT_CASES = {
    # waypoints 1 km outside the site: evaluate says infeasible (3), so does export now
    "outside_1km": (lambda d: _free(d, lambda p, h, k: p.__setitem__(0, p[0] + 1000.0)), 3,
                    r"not exported: the paths are infeasible in the embedded scenario: .*leaves the site box: x = 1\d{3}"),
    # h = 300 m in a 5 - 35 m band (flat ground: z = h)
    "height_300": (lambda d: (d["uavs"][0]["heights"].__setitem__(1, 300.0), d["uavs"][0]["path"][1].__setitem__(2, 300.0)),
                   3, r"not exported: .*UAV1 waypoint 1 leaves the site box: h = 300 is above site\.hmax = 35"),
    # every start moved 8 m: the takeoff points are no longer the scenario's starts
    "starts_moved": (lambda d: [u["path"][0].__setitem__(0, u["path"][0][0] + 8.0) for u in d["uavs"]], 2,
                     r"uavs\[0\]\.path: first point .* is not UAV1's start"),
}


@pytest.mark.parametrize("case", sorted(EXPORT_CASES))
def test_export_checks_the_paths_not_the_stored_status(tmp_path, capsys, result_data, case):
    edit, code_expected, expect = EXPORT_CASES[case]
    assert result_data["status"] == "feasible"
    p = tmp_path / "result.json"
    p.write_text(json.dumps(_tampered(result_data, edit)))
    out = tmp_path / "mission"
    code, stdout, err = run(capsys, "export", str(p), "--out", str(out), "--no-plots")
    assert code == code_expected, (code, err)
    assert_clean(err, code)
    assert re.search(expect, err), err
    assert not out.exists()


def test_export_max_speed_of_micrometres_names_the_vehicle(tmp_path, capsys, result_data):
    def edit(d: dict) -> None:
        d["scenario"]["vehicle"].update(max_speed=1e-6, cruise_speed=1e-6)

    p = tmp_path / "result.json"
    p.write_text(json.dumps(_tampered(result_data, edit)))
    err = refused(capsys, "export", str(p), "--out", str(tmp_path / "m"), "--no-plots",
                  expect=r"the mission would last at least \d\.?\d*e\+0\d s .*vehicle\.cruise_speed = 1e-06 m/s.*\[vehicle\]")
    assert "memory" not in err and "budget" not in err


def _snapshot(directory: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir())}


@pytest.fixture()
def plan_a_exported(tmp_path, capsys, result_file) -> Path:
    """A directory holding plan A's mission (relative altitudes) and a file of the user's."""
    out = tmp_path / "mission"
    code, _, err = run(capsys, "export", str(result_file), "--out", str(out), "--no-plots")
    assert code == 0, err
    (out / "notes.txt").write_text("mine\n")
    return out


@pytest.mark.parametrize("failure", ["disk_full", "ctrl_c"])
@pytest.mark.parametrize("phase", ["staging", "moving"])
def test_export_over_a_mission_fails_without_mixing_the_sets(capsys, monkeypatch, result_file, plan_a_exported,
                                                            failure, phase):
    """Plan B (another origin: every file differs) over plan A's directory, failing after the
    first file: A's set stays whole, the user's file stays, nothing staged is left."""
    import errno

    from staghunt.io import atomic

    out = plan_a_exported
    before = _snapshot(out)
    exc = OSError(errno.ENOSPC, "No space left on device") if failure == "disk_full" else KeyboardInterrupt()
    calls = {"n": 0}
    if phase == "staging":
        real = atomic._write_new

        def flaky(*args, **kwargs):
            calls["n"] += 1
            if calls["n"] == 2:
                raise exc
            return real(*args, **kwargs)

        monkeypatch.setattr(atomic, "_write_new", flaky)
    else:
        real_replace = os.replace

        def flaky_replace(a, b):
            calls["n"] += 1
            if calls["n"] == 3:  # A's uav1.plan set aside, B's moved in, then the next one fails
                raise exc
            return real_replace(a, b)

        monkeypatch.setattr(atomic.os, "replace", flaky_replace)
    code, _, err = run(capsys, "export", str(result_file), "--out", str(out), "--no-plots", "--origin", "47.4,8.55,500")
    monkeypatch.undo()
    if failure == "disk_full":
        assert code == 2 and re.search(r"cannot write to .*No space left on device", err), err
    else:
        assert code == 130 and err.strip() == "staghunt: interrupted", err
    assert_clean(err, code)
    assert calls["n"] >= 2
    assert _snapshot(out) == before  # names and bytes: A's set, the user's notes.txt, nothing else


def test_export_interrupted_into_a_new_directory_leaves_nothing(tmp_path, capsys, monkeypatch, result_file):
    from staghunt.io import atomic

    real = atomic._write_new
    calls = {"n": 0}

    def flaky(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(atomic, "_write_new", flaky)
    out = tmp_path / "new" / "mission"
    code, _, err = run(capsys, "export", str(result_file), "--out", str(out), "--no-plots")
    assert code == 130, err
    assert not (tmp_path / "new").exists()


def test_export_replaces_the_set_and_keeps_the_users_files(capsys, result_file, plan_a_exported):
    out = plan_a_exported
    before = _snapshot(out)
    code, _, err = run(capsys, "export", str(result_file), "--out", str(out), "--no-plots", "--origin", "47.4,8.55,500")
    assert code == 0, err
    after = _snapshot(out)
    assert sorted(after) == sorted(before) and after["notes.txt"] == b"mine\n"
    assert after["uav1.plan"] != before["uav1.plan"] and b'"altitude_amsl_m": 500' in after["mission.json"]


def test_export_removes_the_previous_sets_files_it_does_not_write(capsys, result_file, plan_a_exported):
    """Plan B with fewer formats over plan A (as if A had been forced: a MISSION_UNSAFE.txt in its
    list): A's files that B does not write go, with the move; what A's mission.json does not
    list (the user's notes), a listed name that is now a directory, and names that leave the
    directory stay untouched."""
    out = plan_a_exported
    manifest = json.loads((out / "mission.json").read_text())
    assert "uav1.plan" in manifest["files"] and "mission.json" in manifest["files"]
    (out / "MISSION_UNSAFE.txt").write_text("A was forced\n")
    (out / "kept_dir").mkdir()
    (out.parent / "outside.txt").write_text("not the set's\n")
    manifest["files"] += ["MISSION_UNSAFE.txt", "kept_dir", "../outside.txt", ".hidden"]
    (out / "mission.json").write_text(json.dumps(manifest))
    (out / ".hidden").write_text("x")
    code, _, err = run(capsys, "export", str(result_file), "--out", str(out), "--no-plots", "--formats", "plan")
    assert code == 0, err
    names = sorted(p.name for p in out.iterdir())
    n = len(json.loads((out / "mission.json").read_text())["max_speed_m_s"])
    assert names == sorted([".hidden", "kept_dir", "mission.json", "notes.txt"] + [f"uav{i}.plan" for i in range(1, n + 1)])
    assert (out.parent / "outside.txt").exists() and (out / "notes.txt").read_text() == "mine\n"
    assert sorted(json.loads((out / "mission.json").read_text())["files"]) == sorted(
        ["mission.json"] + [f"uav{i}.plan" for i in range(1, n + 1)])


# ------------------------------------------------------------------------------------------------
# GeoTIFF and GeoJSON ground and obstacles: checked like TOML values (issue 19)
# ------------------------------------------------------------------------------------------------


def _geo_scenario(tmp_path: Path, ground: str = "", geojson: object = None) -> Path:
    """scenario1 (origin, 100 x 100 m site) with a [ground] table and/or a [[geojson]] file."""
    text = SCENARIO_TEXT
    if ground:
        text = text.replace('[ground]\nkind = "flat"  # paper: flat ground', ground)
        assert text != SCENARIO_TEXT
    if geojson is not None:
        gj = tmp_path / "b.geojson"
        if isinstance(geojson, (str, bytes)):
            write(tmp_path, "b.geojson", geojson)
        else:
            gj.write_text(json.dumps(geojson))
        text += f'\n[[geojson]]\nfile = "{gj}"\n'
    return write(tmp_path, "s.toml", text)


def _tif(path: Path, value: float = 500.0, pixel: float = 5.0) -> Path:
    """A UTM 32N GeoTIFF of constant ``value`` covering scenario1's site around its origin."""
    import numpy as np
    import rasterio
    from affine import Affine

    from staghunt.world import GeoOrigin
    from staghunt.world.georef import site_to_crs

    X0, Y0 = (float(v) for v in site_to_crs(GeoOrigin(47.397742, 8.545594, 488.0), "EPSG:32632", 0.0, 0.0))
    n = int(round(240 / pixel))
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="float64", crs="EPSG:32632",
                       transform=Affine(pixel, 0.0, X0 - 70.0, 0.0, -pixel, Y0 + 170.0)) as dst:
        dst.write(np.full((n, n), value), 1)
    return path


def _ground(tif: Path, cell: str = "5.0") -> str:
    return f'[ground]\nkind = "geotiff"\nfile = "{tif}"\ncell_size = {cell}'


def _square(lon: float, lat: float, d: float = 0.0001) -> list:
    return [[[lon, lat], [lon + d, lat], [lon + d, lat + d], [lon, lat + d], [lon, lat]]]


def _fc(*features: object) -> dict:
    return {"type": "FeatureCollection", "features": list(features)}


def _poly(coords: list, **props: object) -> dict:
    return {"type": "Feature", "properties": props, "geometry": {"type": "Polygon", "coordinates": coords}}


ON_SITE = (8.5462, 47.3982)  # about (45, 50) m in scenario1's site frame

GEO_CASES = {
    "tif_1e12": (lambda t: _geo_scenario(t, _ground(_tif(t / "g.tif", 1e12))),
                 r"ground\.file: the DEM .*g\.tif' holds an elevation of 1e\+12 m .*\[-500, 10000\] m above mean sea level"),
    "tif_symlink_loop": (lambda t: (os.symlink(t / "g.tif", t / "g.tif"), _geo_scenario(t, _ground(t / "g.tif")))[1],
                         r"ground\.file: the DEM file .*g\.tif' is a symbolic link loop"),
    "tif_cell_0.005": (lambda t: _geo_scenario(t, _ground(_tif(t / "g.tif"), "0.005")),
                       r"ground\.cell_size: cell_size = 0\.005 m would resample the 100 x 100 m site into a grid "
                       r"of about 4e\+08 nodes"),
    "tif_cell_1e-300": (lambda t: _geo_scenario(t, _ground(_tif(t / "g.tif"), "1e-300")),
                        r"ground\.cell_size: cell_size = 1e-300 m would resample .*use a cell_size >= "),
    "geojson_symlink_loop": (lambda t: (os.symlink(t / "b.geojson", t / "b.geojson"),
                                        write(t, "s.toml", SCENARIO_TEXT + f'\n[[geojson]]\nfile = "{t / "b.geojson"}"\n'))[1],
                             r"geojson\[0\]\.file: the GeoJSON file .*b\.geojson' is a symbolic link loop"),
    "point_lat_95": (lambda t: _geo_scenario(t, geojson=_fc({"type": "Feature", "properties": {"name": "mast", "radius": 2},
                                                            "geometry": {"type": "Point", "coordinates": [8.5, 95.0]}})),
                     r"b\.geojson' features\[0\] \('mast'\): coordinates: position 0 has latitude 95, outside \[-90, 90\]"),
    "point_nan": (lambda t: _geo_scenario(t, geojson='{"type": "FeatureCollection", "features": [{"type": "Feature", '
                                                     '"properties": {"radius": 2}, "geometry": {"type": "Point", '
                                                     '"coordinates": [NaN, 47.4]}}]}'),
                  r"b\.geojson' features\[0\] \('feature 0'\): coordinates: position 0 is not finite"),
    "height_1e300": (lambda t: _geo_scenario(t, geojson=_fc(_poly(_square(*ON_SITE), name="tower", height=1e300))),
                     r"features\[0\] \('tower'\): property 'height' = 1e\+300 is beyond the supported magnitude"),
    "features_int": (lambda t: _geo_scenario(t, geojson={"type": "FeatureCollection", "features": [1]}),
                     r"b\.geojson' features\[0\]: expected a Feature object, got a number"),
    "properties_list": (lambda t: _geo_scenario(t, geojson=_fc({"type": "Feature", "properties": [1, 2],
                                                                "geometry": {"type": "Point", "coordinates": [8.5, 47.4]}})),
                        r"b\.geojson' features\[0\]: 'properties' must be an object, got an array"),
    "geometry_string": (lambda t: _geo_scenario(t, geojson=_fc({"type": "Feature", "geometry": "x"})),
                        r"features\[0\] \('feature 0'\): 'geometry' must be an object, got a string"),
    "ring_of_strings": (lambda t: _geo_scenario(t, geojson=_fc(_poly([["a", "b", "c"]], height=5))),
                        r"features\[0\] \('feature 0'\): polygon 0 outer ring: position 0 must be \[longitude, latitude\]"),
    "far_away_1000km": (lambda t: _geo_scenario(t, geojson=_fc(_poly(_square(47.3982, 8.5462), name="block", height=10))),
                        r"geojson\[0\]\.file: none of the 1 features .* lies \d{4}\.?\d* km from it\); "
                        r"are longitude and latitude swapped"),
}


@pytest.mark.parametrize("case", sorted(GEO_CASES))
def test_geotiff_and_geojson_refused_before_any_work(tmp_path, capsys, case):
    pytest.importorskip("rasterio")
    make, expect = GEO_CASES[case]
    scenario = make(tmp_path)
    out = tmp_path / "out"
    err = refused(capsys, "plan", str(scenario), *TINY, "--out", str(out), expect=expect)
    assert "memory" not in err and "internal error" not in err
    assert not out.exists()


def test_export_refuses_a_geotiff_changed_after_planning(tmp_path, capsys):
    pytest.importorskip("rasterio")
    tif = _tif(tmp_path / "g.tif", 500.0)
    scenario = _geo_scenario(tmp_path, _ground(tif))
    plan_dir = tmp_path / "plan"
    code, _, err = run(capsys, "plan", str(scenario), *TINY, "--no-certify", "--out", str(plan_dir))
    assert code in (0, 3), err
    _tif(tif, 504.0)  # the ground 4 m higher
    out = tmp_path / "mission"
    refused(capsys, "export", str(plan_dir / "result.json"), "--out", str(out), "--no-plots",
            expect=r"embedded scenario: .*ground\.sha256: the GeoTIFF .*g\.tif' does not match this checksum \(file changed\?\)")
    assert not out.exists()


def test_100000_buildings_outside_the_site_load_quickly(tmp_path, capsys):
    """An OpenStreetMap-like extract: 100,000 small buildings, none near the site, one on it.
    What cannot touch the site box is pruned before it becomes an obstacle, so the scenario
    loads (and plans) as if only the one building were there (34 s and minutes before)."""
    import time

    from staghunt.scenario import load_scenario
    from staghunt.world.georef import site_to_lonlat

    import numpy as np

    k = np.arange(100_000)
    x, y = 2000.0 + 20.0 * (k % 400), -3000.0 + 20.0 * (k // 400)  # 8 x 5 km, 2 km from the site
    lon, lat = site_to_lonlat(_origin(), x, y)
    feats = [_poly(_square(float(a), float(b), 0.00005), height=10.0) for a, b in zip(lon, lat)]
    feats.append(_poly(_square(*ON_SITE), name="on site", height=10.0))
    scenario = _geo_scenario(tmp_path, geojson=_fc(*feats))
    t0 = time.perf_counter()
    s = load_scenario(str(scenario))
    assert [p.name for p in s.world.prisms] == ["on site"]
    code, out, err = run(capsys, "plan", str(scenario), *TINY, "--dry-run")
    assert code == 0, err
    assert time.perf_counter() - t0 < 60.0  # two loads; generous for a shared machine


def _origin():
    from staghunt.world import GeoOrigin

    return GeoOrigin(47.397742, 8.545594, 488.0)


def test_sparse_geotiff_of_1cm_pixels_is_read_decimated(tmp_path):
    """A sparse 100,000 x 100,000 GeoTIFF of 1 cm pixels under the 100 m site: read decimated
    (no full-resolution window in float64: that peaked at 1.75 GB), planned with no word of
    memory or budget."""
    pytest.importorskip("rasterio")
    import rasterio
    from affine import Affine

    from staghunt.world.georef import site_to_crs

    tif = tmp_path / "sparse.tif"
    X0, Y0 = (float(v) for v in site_to_crs(_origin(), "EPSG:32632", 0.0, 0.0))
    with rasterio.open(tif, "w", driver="GTiff", width=100_000, height=100_000, count=1, dtype="float32",
                       crs="EPSG:32632", transform=Affine(0.01, 0.0, X0 - 450.0, 0.0, -0.01, Y0 + 550.0),
                       tiled=True, blockxsize=256, blockysize=256, sparse_ok=True, bigtiff="YES"):
        pass  # nothing written: every block reads as 0 m above mean sea level
    assert tif.stat().st_size < 10 * 2**20
    scenario = _geo_scenario(tmp_path, _ground(tif))
    out = tmp_path / "plan"
    code = (f"import resource, sys; import rasterio; from staghunt.cli import main; "
            "before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024; "
            f"rc = main({['plan', str(scenario), *TINY, '--no-certify', '--out', str(out)]!r}); "
            "print(rc, before, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024); sys.exit(0)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
                          env={**os.environ, "PYTHONPATH": SRC})
    assert proc.returncode == 0, proc.stderr
    rc, before_mb, peak_mb = (int(v) for v in proc.stdout.split()[-3:])
    assert rc in (0, 3), proc.stderr
    assert "memory" not in proc.stderr and "budget" not in proc.stderr, proc.stderr
    # A full-resolution read of the 10,000 x 10,000 pixel window: about +1.5 GB (1.75 GB in all);
    # decimated: +15-50 MB here, once +650 MB (GDAL's own buffers)
    assert peak_mb - before_mb < 1000, (before_mb, peak_mb)
    assert (out / "result.json").is_file()


@pytest.mark.parametrize("failure", ["disk_full", "ctrl_c"])
def test_export_failing_into_a_new_directory_leaves_nothing(tmp_path, capsys, monkeypatch, result_file, failure):
    """A full disk (or Ctrl-C) after the first file of a new mission set: no half set, not even
    the directory."""
    import errno

    from staghunt.io import atomic

    real = atomic._write_new
    calls = {"n": 0}

    def flaky(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 2:
            raise OSError(errno.ENOSPC, "No space left on device") if failure == "disk_full" else KeyboardInterrupt()
        return real(*args, **kwargs)

    monkeypatch.setattr(atomic, "_write_new", flaky)
    out = tmp_path / "new" / "mission"
    code, _, err = run(capsys, "export", str(result_file), "--out", str(out), "--no-plots")
    assert code == (2 if failure == "disk_full" else 130), err
    assert_clean(err, code)
    assert not (tmp_path / "new").exists()


def test_export_out_empty_is_refused(tmp_path, capsys, result_file, monkeypatch):
    """``--out ''`` would mean the current directory: refused, like every command's ``--out``."""
    monkeypatch.chdir(tmp_path)
    refused(capsys, "export", str(result_file), "--out", "", "--no-plots", expect=r"--out: must not be empty")
    assert not list(tmp_path.iterdir())


# ------------------------------------------------------------------------------------------------
# fly: events files and sources refused before any simulation (issue 19)
# ------------------------------------------------------------------------------------------------

FLY_SMALL = str(Path(__file__).parent / "data" / "flight_small.toml")
FLY_TINY = ["--particles", "8", "--iterations", "2", "--engine", "numpy", "--no-plots", "--quiet"]
APPEAR = "[[events]]\ntime = 1.0\nkind = 'appear'\nx = 20.0\ny = 20.0\nradius = 2.0\n"
MOVING = "[[moving]]\nname = 't'\nradius = {radius}\npath = [[10, 30], [50, 30]]\nspeed = {speed}\n"
JIB = ("[[jibs]]\nname = 'crane'\npivot = {pivot}\nlength = {length}\nwidth = 1.0\nbase = {base}\nheight = 22.0\n"
       "angle_from = 0.0\nangle_to = 90.0\nrate = {rate}\n")

FLY_CASES = {
    "unknown_key": (APPEAR + "colour = 'red'\n", r"events\[0\]\.colour: unknown key"),
    "negative_time": (APPEAR.replace("time = 1.0", "time = -1.0"), r"events\[0\]\.time"),
    "nan_time": (APPEAR.replace("time = 1.0", "time = nan"), r"events\[0\]\.time"),
    "on_a_uav": (APPEAR.replace("time = 1.0", "time = 0.0").replace("x = 20.0\ny = 20.0", "x = 5.0\ny = 15.0"),
                 r"appears at t = 0 s on top of UAV1"),
    "moving_leaves_site": ("[[moving]]\nname = 't'\nradius = 2.0\npath = [[10, 10], [120, 10]]\nspeed = 2.0\n",
                           r"outside the site"),
    # of the same kinds
    "time_1e300": (APPEAR.replace("time = 1.0", "time = 1e300"), r"events\[0\]\.time"),
    "x_1e12": (APPEAR.replace("x = 20.0", "x = 1e12"), r"events\[0\]\.x"),
    "named_like_the_site_mast": (APPEAR + "name = 'mast'\n",
                                 r"the name 'mast' is given to a changing obstacle and to an obstacle of the site"),
    "disappears_before_it_appears": ("[[events]]\ntime = 1.0\nkind = 'disappear'\nname = 'p'\n"
                                     + APPEAR.replace("time = 1.0", "time = 2.0") + "name = 'p'\n",
                                     r"'p' disappears at t = 1 s, before it appears at t = 2 s"),
    "utf16": (("\ufeff" + APPEAR).encode("utf-16"), r"not UTF-8"),
    # Limits named where the value is read (issue 40), one or more per kind of table: a speed of
    # 1e9 m/s was refused as "out of memory; use a smaller budget".
    "moving_speed_1e9": (MOVING.format(speed="1e9", radius="2.0"),
                         r"ev\.toml: moving\[0\]\.speed: must lie in \(0, 50\] m/s, got 1000000000$"),
    "moving_speed_1e9_reverse": (MOVING.format(speed="1e9", radius="2.0") + "repeat = 'reverse'\n",
                                 r"moving\[0\]\.speed: must lie in \(0, 50\] m/s"),
    "moving_over_a_start": (MOVING.format(speed="2.0", radius="1e5"),
                            r"moving\[0\]: covers UAV2's start \(5, 23\) at take-off: it waits at path\[0\] = "
                            r"\(10, 30\) with radius 100000 m"),
    "jib_tip_faster_than_50": (JIB.format(pivot="[5.0, 0.0]", length="40.0", rate="89.0", base="20.0"),
                               r"jibs\[0\]\.rate: the jib's far corner \(40\.0 m from the pivot\) would move at "
                               r"62\.1 m/s, above 50 m/s: rate must be <= 71\.6 deg/s here, got 89"),
    "jib_rate_above_90": (JIB.format(pivot="[30.0, 5.0]", length="8.0", rate="120.0", base="20.0"),
                          r"jibs\[0\]\.rate: must lie in \(0, 90\], got 120"),
    "jib_over_a_start": (JIB.format(pivot="[4.0, 15.0]", length="8.0", rate="5.0", base="5.0"),
                         r"jibs\[0\]: covers UAV1's start at take-off"),
    "event_radius_zero": (APPEAR.replace("radius = 2.0", "radius = 0.0"), r"events\[0\]\.radius: must be > 0, got 0"),
    "sensing_rate_1000": ("[sensing]\nrate = 1000.0\n", r"sensing\.rate: must lie in \[10, 100\], got 1000"),
    "sensing_noise_100": ("[sensing]\nposition_noise = 100.0\n",
                          r"sensing\.position_noise: must lie in \[0, 10\] m, got 100"),
}


@pytest.mark.parametrize("case", sorted(FLY_CASES))
def test_fly_events_refused_before_any_simulation(tmp_path, capsys, case):
    pytest.importorskip("rotorpy")
    text, expect = FLY_CASES[case]
    ev = write(tmp_path, "ev.toml", text)
    out = tmp_path / "flight"
    err = refused(capsys, "fly", FLY_SMALL, "--events", str(ev), "--out", str(out), *FLY_TINY, expect=expect)
    assert "memory" not in err and "budget" not in err
    assert not out.exists()


def test_scenario_motion_limits_named_where_read(tmp_path, capsys):
    """The same tables in a scenario file: refused when the scenario is read (``show``, ``plan``)."""
    scenario = Path(FLY_SMALL).read_text()
    p = write(tmp_path, "s.toml", scenario + MOVING.format(speed="1e9", radius="2.0"))
    refused(capsys, "show", str(p), expect=r"s\.toml: moving\[0\]\.speed: must lie in \(0, 50\] m/s")
    p = write(tmp_path, "s.toml", scenario + MOVING.format(speed="2.0", radius="1e5"))
    refused(capsys, "plan", str(p), *TINY, "--out", str(tmp_path / "out"), expect=r"moving\[0\]: covers UAV2's start")
    assert not (tmp_path / "out").exists()


def test_out_of_memory_does_not_blame_the_budget(capsys, monkeypatch):
    """A MemoryError that no check foresaw says what it was, not that the budget is too large."""
    import staghunt.scenario

    def boom(*args, **kwargs):
        raise MemoryError("Unable to allocate 87.3 GiB for an array with shape (11714449757,)")

    monkeypatch.setattr(staghunt.scenario, "scenario_to_dict", boom)
    code, _, err = run(capsys, "show", "scenario1")
    assert code == 2 and "budget" not in err
    assert err.startswith("staghunt: error: out of memory (Unable to allocate 87.3 GiB for an array"), err


def test_fly_events_file_that_is_a_directory(tmp_path, capsys):
    pytest.importorskip("rotorpy")
    out = tmp_path / "flight"
    refused(capsys, "fly", FLY_SMALL, "--events", str(tmp_path), "--out", str(out), *FLY_TINY, expect=r"directory")
    assert not out.exists()


def test_fly_settings_that_cannot_certify_a_replan_are_refused_before_any_work(tmp_path, capsys, monkeypatch):
    """``[solver] c1 = c2 = 0``: the offline plan needs no certificate, but every re-plan's does,
    and its search could not move: refused before the offline plan, not in the first re-plan."""
    pytest.importorskip("rotorpy")
    import staghunt.flight.offline as offline

    text = Path(FLY_SMALL).read_text().replace("[solver]\n", "[solver]\nc1 = 0.0\nc2 = 0.0\n")
    scenario = write(tmp_path, "s.toml", text)
    monkeypatch.setattr(offline, "plan", lambda *a, **k: pytest.fail("planned before the check"))
    out = tmp_path / "flight"
    refused(capsys, "fly", str(scenario), "--out", str(out), *FLY_TINY,
            expect=r"re-plan settings: c1 and c2 are both 0")
    assert not out.exists()


@pytest.mark.parametrize("case", ["outside_1km", "height_300"])
def test_fly_result_with_paths_outside_the_site(tmp_path, capsys, result_data, case):
    """A result.json whose waypoints were moved 1 km out of the site (or 300 m up in a 5-35 m
    band): refused before anything is planned or flown (it flew, exit 0, for 6 minutes)."""
    pytest.importorskip("rotorpy")
    p = tmp_path / "result.json"
    p.write_text(json.dumps(_tampered(result_data, EXPORT_CASES[case][0])))
    out = tmp_path / "flight"
    refused(capsys, "fly", str(p), "--out", str(out), *FLY_TINY, expect=r"result\.json: uavs: UAV1 waypoint 1 leaves "
            r"the site box: (x = 1\d{3}.* is above site\.xmax|h = 300 is above site\.hmax)")
    assert not out.exists()


# ------------------------------------------------------------------------------------------------
# sweep: bad specs refused before any cluster or file (issue 19)
# ------------------------------------------------------------------------------------------------

SWEEP_SPEC = """scenarios = ["scenario1"]
methods = ["game", "rigid"]
seeds = "1-2"
particles = 6
iterations = 1
waypoints = 3
engine = "numpy"

[certificate]
particles = 4
iterations = 1
"""

SWEEP_CASES = {
    "unknown_method": (SWEEP_SPEC.replace('"rigid"', '"nope"'), r"methods\[1\]: unknown method 'nope'; choose one of"),
    "method_twice": (SWEEP_SPEC.replace('"rigid"', '"game"'), r"methods: a method is listed twice"),
    "seeds_backwards": (SWEEP_SPEC.replace('"1-2"', '"5-1"'), r"seeds: the range '5-1' runs backwards"),
    "seed_negative": (SWEEP_SPEC.replace('"1-2"', "[1, -2]"), r"seeds"),
    "scenario_twice": (SWEEP_SPEC.replace('["scenario1"]', '["scenario1", "scenario1"]'), r"scenarios\[1\]: .* listed twice"),
    "certificate_zero": (SWEEP_SPEC.replace("[certificate]\nparticles = 4", "[certificate]\nparticles = 0"),
                         r"certificate\.particles"),
    "cannot_certify": (None, None),  # below: a scenario with c1 = c2 = 0
    "engine_cuda": (SWEEP_SPEC.replace('"numpy"', '"cuda"'), r"engine"),
    "budget_too_large": (SWEEP_SPEC.replace("particles = 6", "particles = 100000000"), r"would need about"),
    "not_toml": ("scenarios = [\n", r"invalid TOML"),
    "utf16": (SWEEP_SPEC.encode("utf-16"), r"not UTF-8"),
}


@pytest.mark.parametrize("case", sorted(SWEEP_CASES))
def test_sweep_bad_spec_refused_before_any_work(tmp_path, capsys, case):
    text, expect = SWEEP_CASES[case]
    if case == "cannot_certify":
        scenario = write(tmp_path, "s.toml", toml_with(c1="0.0", c2="0.0"))
        text = SWEEP_SPEC.replace('["scenario1"]', f'["{scenario}"]')
        expect = r"certificate: .*c1 and c2 are both 0"
    spec = write(tmp_path, "spec.toml", text)
    out = tmp_path / "sweep"
    refused(capsys, "sweep", str(spec), "--out", str(out), "--workers", "1", "--quiet", expect=expect)
    assert not out.exists()


def test_sweep_spec_that_is_a_directory(tmp_path, capsys):
    out = tmp_path / "sweep"
    refused(capsys, "sweep", str(tmp_path), "--out", str(out), expect=r"directory")
    assert not out.exists()


def test_export_over_an_older_mission_removes_its_files(capsys, result_file, plan_a_exported):
    """A mission exported before ``mission.json`` listed its files (no ``files`` key), forced (a
    ``MISSION_UNSAFE.txt``): a re-export with fewer formats removes that mission's files it does
    not write, the stale warning above all, and keeps the user's."""
    out = plan_a_exported
    manifest = json.loads((out / "mission.json").read_text())
    del manifest["files"]
    (out / "mission.json").write_text(json.dumps(manifest))
    (out / "MISSION_UNSAFE.txt").write_text("the older mission was forced\n")
    code, _, err = run(capsys, "export", str(result_file), "--out", str(out), "--no-plots", "--formats", "plan")
    assert code == 0, err
    n = len(manifest["max_speed_m_s"])
    assert sorted(p.name for p in out.iterdir()) == sorted(["mission.json", "notes.txt"]
                                                         + [f"uav{i}.plan" for i in range(1, n + 1)])
