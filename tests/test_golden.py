"""Reproducibility: byte-identical ``result.json`` for the same inputs and seed, for every
method; and golden results that a refactor cannot change unnoticed.

Golden files: ``tests/golden/<method>.json`` hold, for scenario2 with 12 particles, 4 iterations
and seed 7 (NumPy reference engine), the final waypoints and each UAV's ``J_n`` at full
precision (see :mod:`staghunt.analysis.golden`). The test re-plans and compares within 1e-12.

If a change of results is *intended* (a deliberate fix of the model or the solver), regenerate
the files on purpose and commit them with the change, saying why:

    python tests/test_golden.py --update            # all registered methods
    python tests/test_golden.py --update game rigid # some of them
    STAGHUNT_UPDATE_GOLDEN=1 python -m pytest tests/test_golden.py   # same, through pytest

A new method gets its golden file the same way; until then its golden test fails.
"""

from __future__ import annotations

import json
import os
import re
import sys
from pathlib import Path

import pytest

from staghunt import plan
from staghunt.analysis.golden import FORMAT, golden_differences, golden_record
from staghunt.io.result_json import write_result
from staghunt.scenario import load_scenario
from staghunt.solvers import METHODS

GOLDEN_DIR = Path(__file__).parent / "golden"
UPDATE_ENV = "STAGHUNT_UPDATE_GOLDEN"


def golden_path(method: str) -> Path:
    return GOLDEN_DIR / f"{method}.json"


def write_golden(method: str) -> Path:
    path = golden_path(method)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(golden_record(method), indent=1, allow_nan=False)
    text = re.sub(r"\[[^\[\]{}]*\]", lambda m: " ".join(m.group(0).split()), text)  # [x, y, h] on one line
    path.write_text(text + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize("method", sorted(METHODS))
def test_same_seed_gives_byte_identical_result_json(method, tmp_path):
    # The NumPy reference engine (when plan() offers engines): the compiled engine's own
    # determinism is tested with the engine.
    scenario = load_scenario("scenario2")
    settings = scenario.solver.with_(particles=8, iterations=3, waypoints=5)
    texts = []
    for i in range(2):
        path = tmp_path / f"result{i}.json"
        write_result(plan(scenario, method, 11, settings, engine="numpy"), path)
        data = json.loads(path.read_text(encoding="utf-8"))
        assert isinstance(data.pop("wall_time_s"), (int, float))
        texts.append(json.dumps(data, indent=2, allow_nan=False))
    assert texts[0] == texts[1]
    # Byte level too: only the wall_time_s line may differ.
    a, b = ((tmp_path / f"result{i}.json").read_bytes().splitlines() for i in range(2))
    differing = [x for x, y in zip(a, b) if x != y]
    assert len(a) == len(b) and all(x.strip().startswith(b'"wall_time_s"') for x in differing)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_golden_result(method):
    if os.environ.get(UPDATE_ENV):
        write_golden(method)
        pytest.skip(f"{UPDATE_ENV} set: wrote {golden_path(method)}")
    path = golden_path(method)
    if not path.exists():
        pytest.fail(f"no golden file {path}; create it deliberately: python tests/test_golden.py --update {method}")
    stored = json.loads(path.read_text(encoding="utf-8"))
    assert stored["format"] == FORMAT
    diffs = golden_differences(golden_record(method), stored)
    assert not diffs, (
        f"{method} no longer reproduces {path}:\n  " + "\n  ".join(diffs)
        + "\nIf the change is intended, regenerate with: python tests/test_golden.py --update " + method
    )


def test_golden_comparison_notices_a_tiny_change():
    stored = json.loads(golden_path("paper").read_text(encoding="utf-8"))
    changed = json.loads(json.dumps(stored))
    changed["waypoints"][1][2][0] *= 1 + 1e-9
    changed["J_n"][2] = "inf"
    diffs = golden_differences(changed, stored)
    assert len(diffs) == 2 and diffs[0].startswith("waypoints[1, 2, 0]") and diffs[1].startswith("J_n[2]")
    assert golden_differences(stored, stored) == []


def main(argv: list[str]) -> int:
    if not argv or argv[0] != "--update":
        print(__doc__)
        print("usage: python tests/test_golden.py --update [METHOD ...]")
        return 2
    methods = argv[1:] or sorted(METHODS)
    for m in methods:
        if m not in METHODS:
            print(f"unknown method {m!r}; choose from {', '.join(sorted(METHODS))}", file=sys.stderr)
            return 2
        print(f"wrote {write_golden(m)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
