"""The figures the docs quote agree with benchmarks/results/*.json (benchmarks/figures.py), and the
checker finds a figure that differs, is missing, has no date and machine, or stands unmarked."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "benchmarks"


def _figures():
    sys.path.insert(0, str(BENCH))  # figures.py imports figure_rules beside it
    try:
        spec = importlib.util.spec_from_file_location("staghunt_bench_figures", BENCH / "figures.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module  # dataclasses look their module up
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(BENCH))
    return module


figures = _figures()
MACHINE = {"cpus": 2, "platform": "Linux x86_64", "load": [1.0, 1.5]}


def test_every_quoted_figure_agrees_with_the_results() -> None:
    problems, differ = figures.run(check=True)
    assert not problems, "\n".join(map(str, problems)) + "\n(python benchmarks/figures.py rewrites the figures)"
    assert differ == 0


def test_the_docs_quote_figures_from_the_results() -> None:
    quoted = {}
    for path in figures.documents():
        for spec, _ in figures.MARKER.findall(path.read_text(encoding="utf-8")):
            quoted.setdefault(path.relative_to(ROOT).as_posix(), set()).add(spec.split()[0])
    assert {"bench.json", "first_run.json"} <= quoted["README.md"]
    assert len(quoted["benchmarks/README.md"]) >= 8


@pytest.mark.parametrize("path", sorted((BENCH / "results").glob("*.json")), ids=lambda p: p.name)
def test_every_results_file_says_when_and_where(path: Path) -> None:
    text = figures.provenance(json.loads(path.read_text(encoding="utf-8")), path.name)
    assert text.startswith("20") and "CPU" in text and "load" in text


def _site(tmp: Path, doc: str, data: dict | None = None) -> Path:
    (tmp / "benchmarks" / "results").mkdir(parents=True)
    (tmp / "README.md").write_text(doc, encoding="utf-8")
    if data is not None:
        (tmp / "benchmarks" / "results" / "r.json").write_text(json.dumps(data), encoding="utf-8")
    return tmp


DATA = {"date": "2026-11-26 09:46 UTC", "code": "abc1234", "machine": MACHINE,
        "runs": [{"label": "new", "wall_s": 81.37}, {"label": "old", "wall_s": 135.2}, {"label": "new", "wall_s": 93.8},
                 {"label": "old", "wall_s": 113.4}]}
SOURCE = "<!-- fig r.json @ -->2026-11-26 09:46 UTC, 2-CPU Linux x86_64, load 1.0-1.5, code abc1234<!-- /fig -->"


def test_a_figure_that_agrees_passes(tmp_path: Path) -> None:
    doc = f"Measured {SOURCE}: <!-- fig r.json runs[label=new].wall_s ; range .0f -->81-94<!-- /fig --> s.\n"
    assert figures.run(check=True, root=_site(tmp_path, doc, DATA), allow={}) == ([], 0)


def test_a_figure_that_differs_fails_the_check_and_is_rewritten(tmp_path: Path) -> None:
    doc = f"Measured {SOURCE}: <!-- fig r.json runs[0].wall_s ; .1f -->80.0<!-- /fig --> s.\n"
    root = _site(tmp_path, doc, DATA)
    problems, differ = figures.run(check=True, root=root, allow={})
    assert differ == 1 and len(problems) == 1 and "'80.0'" in problems[0].text and "'81.4'" in problems[0].text
    assert figures.run(check=False, root=root, allow={}) == ([], 1)
    assert "-->81.4<!--" in (root / "README.md").read_text()
    assert figures.run(check=True, root=root, allow={}) == ([], 0)


@pytest.mark.parametrize("spec, message", [
    ("r.json runs[5].wall_s", "no item 5"),
    ("r.json runs[0].cpu_s", "missing: 'cpu_s'"),
    ("r.json runs[label=gone].wall_s", "no item matches"),
    ("other.json runs", "results/other.json does not exist"),
    ("r.json", "names no path"),
])
def test_a_figure_missing_from_the_results_fails(tmp_path: Path, spec: str, message: str) -> None:
    doc = f"{SOURCE} <!-- fig {spec} -->81.37<!-- /fig --> s\n"
    problems, _ = figures.run(check=True, root=_site(tmp_path, doc, DATA), allow={})
    assert len(problems) == 1 and message in problems[0].text


def test_results_without_date_and_machine_fail(tmp_path: Path) -> None:
    data = {"runs": DATA["runs"]}
    doc = "<!-- fig r.json runs[0].wall_s -->81.37<!-- /fig --> s\n"
    problems, _ = figures.run(check=True, root=_site(tmp_path, doc, data), allow={})
    assert any("no top-level 'date' and 'machine'" in p.text for p in problems)


def test_figures_need_their_date_and_machine_before_them_under_the_same_heading(tmp_path: Path) -> None:
    table = "| run | s |\n|---|---|\n| new | <!-- fig r.json runs[0].wall_s -->81.37<!-- /fig --> |\n"
    for i, doc in enumerate([f"Measured {SOURCE}:\n\n{table}", f"# A\n\nMeasured {SOURCE}.\n\nSomething else.\n\n{table}"]):
        assert figures.run(check=True, root=_site(tmp_path / str(i), doc, DATA), allow={}) == ([], 0)
    for i, doc in enumerate([f"Measured {SOURCE}.\n\n## B\n\n{table}", f"{table}\nMeasured {SOURCE}.\n", table]):
        problems, _ = figures.run(check=True, root=_site(tmp_path / f"bad{i}", doc, DATA), allow={})
        assert len(problems) == 1 and "without its date and machine" in problems[0].text


@pytest.mark.parametrize("text, bare", [
    ("The first run took 81.4 s on this machine.", ["81.4 s"]),
    ("Algorithm 1 is 0.81x the time before, 725 ns per path evaluation.", ["0.81x", "725 ns"]),
    ("It gains 14-67 % and peaks at 192 MB.", ["14-67 %", "192 MB"]),
    ("The target: at most 20 s, under 1 s for later runs, within 3 %.", []),
    ("Run `bench.py --quick  # ~1 min` or\n\n    python x.py  # 4 min\n", []),
    ("A marked <!-- fig r.json runs[0].wall_s -->81.37<!-- /fig --> s figure.", []),
    ("An example, `<!-- fig r.json runs[0].wall_s -->2.5<!-- /fig --> s` or `<!-- fig r.json @ -->`.", []),
])
def test_an_unmarked_measured_figure_fails(tmp_path: Path, text: str, bare: list[str]) -> None:
    problems, _ = figures.run(check=True, root=_site(tmp_path, f"{SOURCE}\n{text}\n", DATA), allow={})
    assert sorted(p.text.split("'")[1] for p in problems) == sorted(bare)


def test_the_allow_list_exempts_a_phrase_and_fails_when_it_is_gone(tmp_path: Path) -> None:
    root = _site(tmp_path, "The latency budget (0.3 s, fixed) and the clock.\n", DATA)
    assert figures.run(check=True, root=root, allow={"README.md": ["0.3 s, fixed"]}) == ([], 0)
    problems, _ = figures.run(check=True, root=root, allow={"README.md": ["0.5 s, fixed"]})
    assert {p.text.split(":")[0] for p in problems} == {"'0.3 s' looks measured but is not marked",
                                                         "allow-listed phrase no longer found"}


def test_benchmarks_readme_flags_every_unmarked_decimal(tmp_path: Path) -> None:
    root = _site(tmp_path, "", DATA)
    (root / "benchmarks" / "README.md").write_text("Paired ratio 1.14 (seeds 1-3), Python 3.11.7.\n")
    problems, _ = figures.run(check=True, root=root, allow={})
    assert [p.text.split("'")[1] for p in problems] == ["1.14"]


def test_unmarking_a_real_readme_figure_fails() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    lines = text.split("\n")
    unmarked = figures.MARKER.sub(lambda m: m.group(2), text).split("\n")
    bare = figures.bare_figures("README.md", unmarked, figures.code_lines(unmarked))
    assert len(bare) > len(figures.bare_figures("README.md", lines, figures.code_lines(lines))) + 5


@pytest.mark.parametrize("expr, text", [
    ("runs[*].wall_s ; max .1f", "135.2"),
    ("runs[*].wall_s ; median .0f", "104"),
    ("runs[*].wall_s ; p50 .0f", "104"),
    ("runs[*].wall_s ; p95 .2f", "131.93"),
    ("runs[label=new].wall_s ; count", "2"),
    ("runs[label=new].wall_s ; .1f", "81.4 / 93.8"),
    ("runs[label=new][1].wall_s ; .1f", "93.8"),
    ("runs[*][-1].label", "old"),
    ("runs[?label][?wall_s] ; count", "4"),
    ("runs[label=gone] ; count", "0"),
    ("runs[label=new].wall_s ; interval .0f", "[81, 94]"),
    ("runs[label=new].wall_s / runs[label=old].wall_s ; first .2f", "0.60"),
    ("runs[1].wall_s ; /60 .2f", "2.25"),
    ("runs[0].wall_s + runs[1].wall_s ; .2f", "216.57"),
    ("runs[label=old].wall_s - runs[label=new].wall_s ; .1f", "53.8 / 19.6"),
    ("runs[1].wall_s / runs[0].wall_s ; % .0f", "166"),
    ("runs[label=new].wall_s / runs[*].wall_s ; pooled % .1f", "41.3"),  # (81.37 + 93.8) / 423.77
    ("runs[0].label", "new"),
    ("machine.load[1]", "1.5"),
    ("runs[label=new].wall_s ; max <=90?met:missed_by_far", "missed by far"),
    ("runs[0].wall_s ; <=90?met:missed", "met"),
])
def test_rendering(expr: str, text: str) -> None:
    assert figures.render(DATA, expr) == text


def test_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert figures.main(["--get", "bench.json", "paper_numba.best_s ; .3f"]) == 0
    assert capsys.readouterr().out.strip().replace(".", "").isdigit()
    assert figures.main(["--get", "bench.json", "no.such.path"]) == 2
    assert "missing" in capsys.readouterr().err
    assert figures.main(["--paths", "first_run.json"]) == 0
    assert "runs[0].wall_s = " in capsys.readouterr().out
