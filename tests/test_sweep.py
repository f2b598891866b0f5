"""``staghunt sweep``: the spec (keys, grid, schema), a real local Dask cluster (processes) on a
tiny sweep, the Parquet store, resuming (a rerun adds nothing; more seeds run only the new
tasks), ``kill -9`` of the client or of a worker mid-sweep, failed tasks, an unreachable
scheduler, and the figures.

The compiled engine is used as in production; its kernels come from Numba's on-disk cache (a
cold cache compiles once, about a minute, on the first test that needs it)."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import jsonschema
import numpy as np
import pyarrow.parquet as pq
import pytest

from staghunt.study.spec import SpecError, expand, load_spec, parse_seeds
from staghunt.study.sweep import RESULTS, run_sweep
from staghunt.study.tasks import TaskOutcome

ROOT = Path(__file__).resolve().parents[1]

TINY = """
scenarios = ["scenario1"]
methods = ["game", "rigid"]
seeds = "{seeds}"
particles = {particles}
iterations = {iterations}
waypoints = 4

[certificate]
particles = 6
iterations = 2

[grid]
beta = [0.5, 2]
"""


def write_spec(directory: Path, name: str = "spec.toml", seeds: str = "1-2", particles: int = 10,
               iterations: int = 5, extra: str = "") -> Path:
    path = directory / name
    path.write_text(TINY.format(seeds=seeds, particles=particles, iterations=iterations) + extra)
    return path


def run_cli(argv: list[str]) -> int:
    from staghunt import cli

    return cli.main(argv)


def env() -> dict[str, str]:
    e = dict(os.environ)
    e["PYTHONPATH"] = str(ROOT / "src") + os.pathsep + e.get("PYTHONPATH", "")
    return e


def rows(out: Path) -> dict[str, list]:
    return pq.read_table(out / RESULTS).to_pydict()


@pytest.fixture(scope="module")
def cluster_run(tmp_path_factory):
    """The tiny sweep (8 tasks) on a LocalCluster of 2 worker processes."""
    d = tmp_path_factory.mktemp("sweep")
    spec = write_spec(d)
    out = d / "out"
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = run_cli(["sweep", str(spec), "--out", str(out), "--workers", "2"])
    return spec, out, code, err.getvalue()


# ------------------------------------------------------------------------------------------------
# The spec
# ------------------------------------------------------------------------------------------------


UAV2_WEIGHTS = "uav.UAV2.weights = [[1, 1, 1, 1, 1], [2, 1, 1, 1, 1]]\n"


def test_expand_grid_and_keys(tmp_path):
    spec, base = load_spec(write_spec(tmp_path, extra=UAV2_WEIGHTS))
    sweep = expand(spec, base)
    assert len(sweep.tasks) == 2 * 2 * 2 * 2  # beta x UAV2 weights x seeds x methods
    assert len({t.key for t in sweep.tasks}) == len(sweep.tasks)
    assert sweep.overrides == (("beta", "float"), ("uav.UAV2.weights", "weights"))
    t = next(t for t in sweep.tasks if t.labels["beta"] == 2.0 and t.labels["uav.UAV2.weights"][0] == 2.0)
    team = t.request.scenario.team
    assert [u.weights.beta for u in team] == [2.0, 2.0, 2.0]
    from staghunt.scenario import load_scenario

    original = load_scenario("scenario1").team
    assert team[1].weights.w1 == 2.0 != original[1].weights.w1
    assert (team[0].weights.w1, team[2].weights.w1) == (original[0].weights.w1, original[2].weights.w1)
    assert t.request.settings.waypoints == 4 and t.request.settings.particles == 10
    assert t.request.certify.particles == 6 and t.request.engine.threads == 1
    # The key is the configuration's: the same spec gives the same keys, another budget others.
    again = expand(*load_spec(write_spec(tmp_path, name="b.toml", extra=UAV2_WEIGHTS)))
    assert [t.key for t in again.tasks] == [t.key for t in sweep.tasks]
    other = expand(*load_spec(write_spec(tmp_path, name="c.toml", particles=11)))
    assert not {t.key for t in other.tasks} & {t.key for t in sweep.tasks}


ALL_AXES = """
[grid]
beta = [0.5, 2]
weights = [[1, 1, 1, 1, 1], [2, 1, 1, 1, 3]]
uav.2.beta = [1, 10]
uav.UAV3.weights = [[1, 2, 1, 1, 1], [1, 1, 1, 2, 1]]
waypoints = [4, 5]
iterations = [3, 5]
"""


def test_tasks_on_demand_are_those_of_every_combination_validated(tmp_path):
    """Every task, made on demand from the checked values, is the task of its combination of
    overrides applied to the scenario's data and validated whole (what expand did for every
    combination before issue 40): the same scenario, run and labels, and the same key, so a
    results.parquet written before keeps its tasks done."""
    from staghunt.api import check_plan
    from staghunt.io.result_json import settings_to_dict
    from staghunt.scenario import builtin_path, load_scenario, scenario_from_dict, scenario_to_dict
    from staghunt.study.grid import task_key

    text = TINY.format(seeds="1,7", particles=10, iterations=5).replace("[grid]\nbeta = [0.5, 2]\n", ALL_AXES)
    sweep = expand(*load_spec(_spec(tmp_path, text)))
    assert len(sweep) == len(sweep.tasks) == 2 ** 6 * 2 * 2
    keys = list(sweep.keys())
    assert len(set(keys)) == len(keys)
    base = scenario_to_dict(load_scenario("scenario1"))
    base["solver"].update(particles=10, iterations=5, waypoints=4)
    for i in range(0, len(sweep), 7):
        task = sweep.tasks[i]
        labels = dict(task.labels)
        data = json.loads(json.dumps(base))
        for u in data["team"]:
            u["beta"], u["weights"] = labels["beta"], labels["weights"]
        data["team"][1]["beta"] = labels["uav.2.beta"]
        data["team"][2]["weights"] = labels["uav.UAV3.weights"]
        data["solver"].update(waypoints=labels["waypoints"], iterations=labels["iterations"])
        whole = scenario_from_dict(data, name="scenario1", base_dir=builtin_path("scenario1").parent)
        assert scenario_to_dict(task.request.scenario) == scenario_to_dict(whole)
        plain = json.loads(json.dumps(scenario_to_dict(whole), default=str))
        assert task.key == keys[i] == task_key(plain, labels["method"], labels["seed"],
                                               settings_to_dict(whole.solver), sweep.certify, "numba")
        checked = check_plan(whole, labels["method"], labels["seed"], whole.solver, "numba", 1, sweep.certify)
        assert (task.request.method, task.request.seed, task.request.settings) == (checked.method, checked.seed,
                                                                                    checked.settings)
        assert task.request.estimate == checked.estimate and task.request.certify == checked.certify


def _spec(directory: Path, text: str, name: str = "s.toml") -> Path:
    path = directory / name
    path.write_text(text)
    return path


def test_a_spec_beyond_the_limit_is_refused_at_once_with_its_count(tmp_path, capsys):
    from staghunt.study.spec import MAX_TASKS

    assert MAX_TASKS == 1_000_000
    # 1 x 6 x 100,000 x 2 = 1,200,000 tasks; the scenario is never read (it does not exist).
    text = TINY.format(seeds="1-100000", particles=10, iterations=5).replace('"scenario1"', '"nosuch.toml"')
    text = text.replace("beta = [0.5, 2]", "beta = [0.5, 1, 2, 3, 4, 5]")
    t0 = time.process_time()
    assert run_cli(["sweep", str(_spec(tmp_path, text)), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err == ("staghunt: error: the spec makes 1,200,000 tasks (1 scenario x 6 grid combinations x 100,000 "
                   "seeds x 2 methods); a sweep runs at most 1,000,000: split it into several specs (e.g. by "
                   "seeds), each with its own --out\n")
    assert time.process_time() - t0 < 5 and not (tmp_path / "o").exists()
    many = ",".join(f"{k * 100_000}-{k * 100_000 + 99_999}" for k in range(11))  # 1,100,000 seeds
    with pytest.raises(SpecError, match=r"^seeds: more than 1,000,000 seeds$"):
        expand(*load_spec(_spec(tmp_path, TINY.format(seeds=many, particles=10, iterations=5))))


@pytest.mark.parametrize("grid, named", [
    ("beta = [0.5, 2, 0.5]", "grid.beta: the value 0.5 is listed twice"),
    ("waypoints = [4, 4]", "grid.waypoints: the value 4 is listed twice"),
    ("beta = [0.5, 2]\nuav.1.beta = [1]\nuav.2.beta = [1]\nuav.3.beta = [1]",
     "grid.beta: changes nothing in scenario 'scenario1'"),
    ("particles = [10, 1000000000]", "scenario 'scenario1' with particles = 1000000000, method 'game': "),
])
def test_grid_values_that_would_make_tasks_twice_or_cannot_run(tmp_path, grid, named):
    text = TINY.format(seeds="1", particles=10, iterations=5).replace("beta = [0.5, 2]", grid)
    with pytest.raises(SpecError) as exc:
        expand(*load_spec(_spec(tmp_path, text)))
    assert str(exc.value).startswith(named), str(exc.value)


def test_pending_and_a_subset(tmp_path):
    """pending() names exactly the tasks whose key is not stored, without making the others."""
    sweep = expand(*load_spec(write_spec(tmp_path, seeds="1-3")))  # 12 tasks

    def fake(task):
        return TaskOutcome(task.key, {"status": "feasible", "J": [1.0, 2.0, 3.0]})

    first = run_sweep(sweep, tmp_path / "o", task_fn=fake, tasks=sweep.tasks[::3])
    assert (first.total, first.done) == (4, 4)
    from staghunt.study.sweep import open_stores, pending

    results, _ = open_stores(tmp_path / "o", sweep)
    todo = pending(sweep, results)
    assert list(todo.indices) == [i for i in range(12) if i % 3]
    assert {t.key for t in todo} == set(list(sweep.keys())) - results.keys()
    second = run_sweep(sweep, tmp_path / "o", task_fn=fake)
    assert (second.skipped, second.done) == (4, 8)


def test_batches_in_flight_stay_bounded():
    """The Dask executor reads (and submits) the tasks batch by batch: never more than two
    batches ahead of what it has handed back, and every task exactly once."""
    import operator
    from collections.abc import Sequence

    from staghunt.study.executor import DaskExecutor

    class Lazy(Sequence):
        def __init__(self, n):
            self.n, self.read = n, 0

        def __len__(self):
            return self.n

        def __getitem__(self, i):
            self.read = max(self.read, i + 1)
            return i

    tasks = Lazy(300)
    got = {}
    with DaskExecutor(workers=2) as ex:
        batch = ex.batch_size()
        assert batch == 8
        for n, (i, outcome) in enumerate(ex.map_unordered(operator.neg, tasks), 1):
            assert tasks.read - n <= 2 * batch, (tasks.read, n)
            got[i] = outcome
    assert got == {i: -i for i in range(300)}


def test_parse_seeds():
    assert parse_seeds("1-3,8,2") == (1, 2, 3, 8)
    with pytest.raises(SpecError):
        parse_seeds("3-1")


@pytest.mark.parametrize("extra, named", [
    ("bogus = 1\n", "bogus: unknown key"),
    ("betta = [1]\n", "grid.betta: unknown key; allowed keys here: beta, weights"),
    ("uav.2.bta = [1]\n", "grid.uav.2.bta: unknown key; allowed keys here: beta, weights"),
    ("uav.9.beta = [1]\n", "grid.uav.9: scenario 'scenario1' has no UAV '9'"),
    ("beta = [-1]\n", "grid.beta[0]: must be >= 0"),
    ("weights = [[1, 1, 1]]\n", "grid.weights[0]: expected [w1, w2, w3, w4, w5] (5 numbers)"),
    ("beta = [1e300]\n", "scenario 'scenario1' with beta = 1e+300: team[0].beta"),
])
def test_bad_spec_exits_2_naming_the_key(tmp_path, capsys, extra, named):
    text = TINY.format(seeds="1", particles=5, iterations=1)
    if extra.startswith("bogus"):
        text = extra + text
    else:
        text = text.replace("[grid]\nbeta = [0.5, 2]\n", "[grid]\n" + extra)
    spec = tmp_path / "bad.toml"
    spec.write_text(text)
    out = tmp_path / "out"
    assert run_cli(["sweep", str(spec), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("staghunt: error: ") and err.count("\n") == 1 and named in err, err
    assert not out.exists()  # refused before anything was created


def test_unknown_method_and_scenario(tmp_path, capsys):
    spec = tmp_path / "m.toml"
    spec.write_text(TINY.format(seeds="1", particles=5, iterations=1).replace('"rigid"', '"nope"'))
    assert run_cli(["sweep", str(spec), "--out", str(tmp_path / "o")]) == 2
    assert "methods[1]: unknown method 'nope'" in capsys.readouterr().err
    spec.write_text(TINY.format(seeds="1", particles=5, iterations=1).replace('"scenario1"', '"nosuch.toml"'))
    assert run_cli(["sweep", str(spec), "--out", str(tmp_path / "o")]) == 2
    assert "scenarios[0]: no such scenario file" in capsys.readouterr().err


def test_schema_validates_the_example_spec(capsys):
    import tomllib

    assert run_cli(["schema", "--sweep"]) == 0
    schema = json.loads(capsys.readouterr().out)
    jsonschema.Draft202012Validator.check_schema(schema)
    validator = jsonschema.Draft202012Validator(schema)
    example = tomllib.loads((ROOT / "examples" / "sweep.toml").read_text())
    validator.validate(example)
    assert len(expand(*load_spec(ROOT / "examples" / "sweep.toml")).tasks) == 96
    for bad in ({**example, "bogus": 1}, {**example, "grid": {"betta": [1]}},
                {**example, "grid": {"uav": {"2": {"beta": [-1]}}}}, {**example, "seeds": [-1]}):
        with pytest.raises(jsonschema.ValidationError):
            validator.validate(bad)


# ------------------------------------------------------------------------------------------------
# A real cluster
# ------------------------------------------------------------------------------------------------


def test_cluster_sweep_rows(cluster_run, tmp_path):
    spec, out, code, err = cluster_run
    assert code == 0, err
    assert "running on a local Dask cluster of 2 worker processes" in err
    # Numba's on-disk cache warmed by the client: the workers load the kernels, never compile.
    loaded = re.search(r"workers loaded the compiled engine in at most ([0-9.]+) s", err)
    assert loaded and float(loaded.group(1)) < 5.0, err
    assert "8 tasks finished, 0 skipped (already done), 0 failed" in err
    data = rows(out)
    sweep = expand(*load_spec(spec))
    assert sorted(data["key"]) == sorted(t.key for t in sweep.tasks)  # every task exactly once
    assert set(data["status"]) <= {"feasible", "infeasible"}
    for i in range(len(data["key"])):
        J, J_s, J_f = (np.array(data[c][i]) for c in ("J", "J_s", "J_f"))
        assert J.shape == (3,)
        # The beta override reached the scenario: J_n = J_s + beta J_f with the row's beta.
        np.testing.assert_allclose(J, J_s + data["beta"][i] * J_f, rtol=1e-9)
        assert len(data["history"][i]) == 5 + 1 and len(data["history"][i][0]) == 3
        np.testing.assert_allclose(data["history"][i][-1], J, rtol=1e-9)
        assert data["evaluations"][i] > 0 and data["wall_time_s"][i] > 0
        assert 0 <= data["max_relative_gap"][i] or data["status"][i] == "infeasible"
        assert data["equilibrium"][i] == (data["status"][i] == "feasible" and data["max_relative_gap"][i] <= 0.01)
        # The multi-start game says whether its selected equilibrium is payoff-dominant; the
        # other methods select nothing.
        if data["method"][i] == "game":
            assert data["payoff_dominant"][i] in (True, False)
        else:
            assert data["payoff_dominant"][i] is None
        # The client warmed Numba's cache: no worker compiled.
        assert data["compile_time_s"][i] < 5.0
        assert data["worker"][i] and data["version"][i]
    assert len({w.split(":")[1] for w in data["worker"]}) >= 1
    # The same tasks in this process give the same plans: the cluster changes nothing but where.
    inline = tmp_path / "inline"
    assert run_cli(["sweep", str(spec), "--out", str(inline), "--workers", "1", "--quiet", "--no-figures"]) == 0
    here = rows(inline)
    by_key = {k: j for k, j in zip(here["key"], here["J"])}
    for k, j in zip(data["key"], data["J"]):
        np.testing.assert_array_equal(j, by_key[k])
    png = (out / "beta_tradeoff.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and (out / "convergence.png").stat().st_size > 10_000


def test_rerun_adds_no_rows_and_more_seeds_run_only_the_new_tasks(cluster_run, tmp_path, capsys):
    import shutil

    spec, out, _, _ = cluster_run
    work = tmp_path / "out"
    shutil.copytree(out, work)
    parts = sorted(p.name for p in (work / RESULTS).glob("part-*"))
    assert run_cli(["sweep", str(spec), "--out", str(work), "--workers", "2", "--no-figures"]) == 0
    err = capsys.readouterr().err
    assert "8 tasks, 8 already in" in err and "0 to run" in err
    assert sorted(p.name for p in (work / RESULTS).glob("part-*")) == parts  # nothing written
    more = write_spec(tmp_path, name="more.toml", seeds="1-3")
    assert run_cli(["sweep", str(more), "--out", str(work), "--workers", "1", "--no-figures"]) == 0
    err = capsys.readouterr().err
    assert "12 tasks, 8 already in" in err and "4 to run" in err and "4 tasks finished" in err
    data = rows(work)
    assert len(data["key"]) == 12 and len(set(data["key"])) == 12
    assert sorted(data["seed"]).count(3) == 4
    for png in work.glob("*.png"):
        png.unlink()
    assert run_cli(["sweep", str(more), "--out", str(work), "--figures-only"]) == 0  # from the table alone
    assert (work / "beta_tradeoff.png").read_bytes()[:4] == b"\x89PNG" and (work / "convergence.png").is_file()
    assert run_cli(["sweep", str(more), "--out", str(tmp_path / "empty"), "--figures-only"]) == 2
    assert "no results (run the sweep first)" in capsys.readouterr().err


def test_failed_tasks_are_recorded_and_run_again(tmp_path):
    sweep = expand(*load_spec(write_spec(tmp_path, seeds="1")))

    def broken(task):
        return TaskOutcome(task.key, {"status": "error", "message": "ZeroDivisionError: boom"}, error="boom")

    first = run_sweep(sweep, tmp_path / "o", task_fn=broken)
    assert (first.done, first.failed) == (0, 4)
    errors = pq.read_table(tmp_path / "o" / "errors.parquet").to_pydict()
    assert errors["status"] == ["error"] * 4 and errors["message"][0] == "ZeroDivisionError: boom"
    assert pq.read_table(tmp_path / "o" / RESULTS).num_rows == 0
    second = run_sweep(sweep, tmp_path / "o")  # failed tasks are not finished: run again
    assert (second.skipped, second.done, second.failed) == (0, 4, 0)
    assert pq.read_table(tmp_path / "o" / RESULTS).num_rows == 4


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_unreachable_scheduler(tmp_path, capsys):
    spec = write_spec(tmp_path, seeds="1")
    t0 = time.perf_counter()
    code = run_cli(["sweep", str(spec), "--out", str(tmp_path / "o"), "--scheduler",
                    f"tcp://127.0.0.1:{_free_port()}", "--connect-timeout", "1"])
    assert code == 2 and time.perf_counter() - t0 < 20
    lines = capsys.readouterr().err.splitlines()
    # The size of the study first (before any work), then the one error line.
    assert len(lines) == 2 and lines[0].endswith("4 tasks, 0 already in " + str(tmp_path / "o" / RESULTS) + ", 4 to run")
    assert lines[1].startswith("staghunt: error: cannot reach the Dask scheduler at tcp://127.0.0.1:")


# ------------------------------------------------------------------------------------------------
# kill -9 mid-sweep
# ------------------------------------------------------------------------------------------------


def _start(spec: Path, out: Path, workers: int) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "staghunt", "sweep", str(spec), "--out", str(out),
                             "--workers", str(workers), "--no-figures", "--quiet", "--flush-every", "0"],
                            env=env(), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)


def _wait_for_rows(out: Path, proc: subprocess.Popen, timeout: float = 60) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end and proc.poll() is None:
        if any((out / RESULTS).glob("part-*.parquet")):
            return
        time.sleep(0.05)
    raise AssertionError(f"no rows written before the sweep ended (rc={proc.poll()})")


def _exactly_once(spec: Path, out: Path) -> None:
    keys = rows(out)["key"]
    assert sorted(keys) == sorted(t.key for t in expand(*load_spec(spec)).tasks)


def test_kill_9_of_the_client_then_rerun(tmp_path):
    spec = write_spec(tmp_path, seeds="1-4", particles=800, iterations=300)  # 16 tasks, ~0.1-0.6 s each
    out = tmp_path / "out"
    proc = _start(spec, out, workers=2)
    try:
        _wait_for_rows(out, proc)
        os.kill(proc.pid, signal.SIGKILL)  # the client alone; its workers are orphaned
        proc.wait(timeout=30)
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)  # the orphans (they cannot write: only the client does)
        except ProcessLookupError:
            pass
    before = pq.read_table(out / RESULTS).num_rows
    assert 0 < before < 16
    rerun = subprocess.run([sys.executable, "-m", "staghunt", "sweep", str(spec), "--out", str(out),
                            "--workers", "1", "--no-figures"], env=env(), capture_output=True, text=True, timeout=120)
    assert rerun.returncode == 0, rerun.stderr
    assert f"{before} already in" in rerun.stderr and f"{16 - before} tasks finished" in rerun.stderr
    _exactly_once(spec, out)


def test_kill_9_of_a_worker_mid_sweep(tmp_path):
    import psutil

    spec = write_spec(tmp_path, seeds="1-4", particles=800, iterations=300)
    out = tmp_path / "out"
    proc = _start(spec, out, workers=2)
    try:
        _wait_for_rows(out, proc)
        workers = [p for p in psutil.Process(proc.pid).children(recursive=True)
                   if "multiprocessing" in " ".join(p.cmdline())]
        assert workers, "no worker process found"
        workers[0].send_signal(signal.SIGKILL)
        _, err = proc.communicate(timeout=120)
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    print(f"sweep with a killed worker: exit {proc.returncode}")
    if proc.returncode == 3:  # the task on the killed worker was recorded as failed: rerun it
        rerun = subprocess.run([sys.executable, "-m", "staghunt", "sweep", str(spec), "--out", str(out),
                                "--workers", "2", "--no-figures"], env=env(), capture_output=True, text=True,
                               timeout=120)
        assert rerun.returncode == 0, rerun.stderr
    else:
        assert proc.returncode == 0, err
    _exactly_once(spec, out)


# ------------------------------------------------------------------------------------------------
# Figures
# ------------------------------------------------------------------------------------------------


def test_pareto_front():
    from staghunt.plots.study import pareto_front

    pts = np.array([[1, 5], [2, 2], [3, 3], [5, 1], [2, 2], [np.inf, 0], [0.5, 9]])
    assert pareto_front(pts).tolist() == [True, True, False, True, True, False, True]


# ------------------------------------------------------------------------------------------------
# The store
# ------------------------------------------------------------------------------------------------


def test_store_drops_temporary_parts_and_compacts_duplicate_keys(tmp_path):
    import pyarrow as pa

    from staghunt.study.store import ResultStore

    schema = pa.schema([("key", pa.string()), ("J", pa.list_(pa.float64()))])
    store = ResultStore(tmp_path / "r.parquet", schema).open()
    store.append([{"key": "a", "J": [1.0, 2.0]}, {"key": "b", "J": [3.0]}])
    store.append([{"key": "a", "J": [9.0]}, {"key": "c", "J": None}])  # "a" twice: a second client
    (store.path / ".part-0-0-0.parquet.tmp").write_bytes(b"PAR1 half a part")  # a killed writer
    assert pq.read_table(store.path).num_rows == 4  # readers skip the hidden temporary part
    store = ResultStore(tmp_path / "r.parquet", schema).open()
    assert not list(store.path.glob(".*.tmp")) and len(store.parts()) == 1
    data = pq.read_table(store.path).to_pydict()
    assert data == {"key": ["a", "b", "c"], "J": [[1.0, 2.0], [3.0], None]}  # the first row of "a" kept
    assert store.keys() == {"a", "b", "c"}


def test_store_keeps_its_parts_few(tmp_path, monkeypatch):
    """A writer merges its own parts every MERGE_EVERY parts, and open() merges the small parts
    of a store that has more than MAX_PARTS: reading which tasks are done stays fast."""
    import pyarrow as pa

    from staghunt.study import store as store_module
    from staghunt.study.store import ResultStore

    monkeypatch.setattr(store_module, "MERGE_EVERY", 3)
    schema = pa.schema([("key", pa.string()), ("J", pa.list_(pa.float64()))])
    store = ResultStore(tmp_path / "r.parquet", schema).open()
    for k in range(7):
        store.append([{"key": f"k{k}", "J": [float(k)]}])
    assert len(store.parts()) == 3  # (k0-k2), (k3-k5), k6
    assert store.keys() == {f"k{k}" for k in range(7)} and "k6" in store
    monkeypatch.setattr(store_module, "MAX_PARTS", 2)
    again = ResultStore(tmp_path / "r.parquet", schema).open()
    assert len(again.parts()) == 1
    data = pq.read_table(again.path).to_pydict()
    assert sorted(zip(data["key"], data["J"])) == [(f"k{k}", [float(k)]) for k in range(7)]
