"""The figures that README.md, docs/*.md and benchmarks/README.md quote, regenerated from
``benchmarks/results/*.json`` (the rules: benchmarks/README.md, "Figures in the docs").

    python benchmarks/figures.py                  # rewrite every marked figure from the results
    python benchmarks/figures.py --check          # report what differs, is missing or is unmarked; exit 1
    python benchmarks/figures.py --get bench.json 'paper_numba.times_s ; min .2f'   # render one figure
    python benchmarks/figures.py --paths bench.json                                 # every value a file holds

A figure in the Markdown sits between two HTML comments (invisible on GitHub):

    <!-- fig bench.json paper_numba.times_s ; min .2f -->2.22<!-- /fig --> s
    <!-- fig bench.json @ -->2026-11-26 09:46 UTC, 2-CPU Linux x86_64, load 1.3-1.6<!-- /fig -->

The first names a results file, a path into it and how to render the value; the second (``@``)
renders the file's ``date``, ``machine`` and ``code``. Exit status: 0 all figures agree (or were
rewritten), 1 a figure is missing, differs (with ``--check``) or a measured-looking number stands
outside a marker, 2 bad usage.
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from figure_rules import ALLOW, CODE_SPAN, MARKER, allowed, bare_figures, code_lines

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"
DOCS = ("README.md", "docs/*.md", "benchmarks/README.md")

STRAY = re.compile(r"<!--\s*/?fig\b")
STEP = re.compile(r"\[([^\]]*)\]|\.?([^.\[\]]+)")
REDUCERS = {"min": min, "max": max, "sum": sum, "count": len, "first": lambda v: v[0], "last": lambda v: v[-1],
            "median": statistics.median, "mean": statistics.fmean}
PERCENTILE = re.compile(r"p\d{1,2}(?:\.\d+)?")
BINARY = re.compile(r" ([/+-]) ")
VERDICT = re.compile(r"(<=|>=|<|>)(-?\d+(?:\.\d+)?)\?([^:]*):(.*)")
class FigureError(ValueError):
    """A figure that cannot be rendered: the file, the path or the format is wrong."""


@dataclass(frozen=True)
class Problem:
    """One finding: where, and what."""

    doc: str
    line: int
    text: str

    def __str__(self) -> str:
        return f"{self.doc}:{self.line}: {self.text}"


# ------------------------------------------------------------------------------------------------
# Results files and paths into them


_cache: dict[Path, Any] = {}


def load(name: str, results: Path = RESULTS) -> Any:
    """A results file, parsed once. Only plain names inside ``results`` are allowed."""
    if "/" in name or "\\" in name or not name.endswith(".json"):
        raise FigureError(f"{name!r}: a results file is a plain name ending in .json")
    path = results / name
    if path not in _cache:
        try:
            _cache[path] = json.loads(path.read_text(encoding="utf-8"))
        except OSError:
            raise FigureError(f"results/{name} does not exist") from None
        except ValueError as exc:
            raise FigureError(f"results/{name} is not JSON: {exc}") from None
    return _cache[path]


def steps(path: str) -> list[str]:
    """``a.b[0][k=v][*][key with spaces]`` -> ['a', 'b', '[0]', '[k=v]', '[*]', '[key with spaces]']."""
    out, pos = [], 0
    path = path.strip()
    while pos < len(path):
        m = STEP.match(path, pos)
        if not m or m.end() == pos:
            raise FigureError(f"bad path {path!r} at {path[pos:]!r}")
        out.append(f"[{m.group(1)}]" if m.group(1) is not None else m.group(2).strip())
        pos = m.end()
    if not out:
        raise FigureError("empty path")
    return out


def _literal(text: str) -> Any:
    try:
        return json.loads(text)
    except ValueError:
        return text


def _matches(item: Any, key: str, want: str | None) -> bool:
    """``[key=want]`` (``[?key]`` when ``want`` is None: the item has ``key``)."""
    if not isinstance(item, dict) or key not in item:
        return False
    return want is None or item[key] == _literal(want) or str(item[key]) == want


def resolve(data: Any, path: str) -> Any:
    """The value at ``path``: a key or index per step; ``[*]`` fans out over a list's items (or a
    dict's values), ``[key=value]`` keeps the items whose ``key`` equals ``value`` (``[?key]``: the
    items that have ``key``); after a fan-out
    the result is the list of what each item gave (a second ``[key=value]`` narrows that list, and an
    index right after them picks one item: ``runs[label=new][0]``)."""
    items, fanned, just_fanned = [data], False, False
    for step in steps(path):
        inner = step[1:-1] if step.startswith("[") else None
        test = (inner.split("=", 1) if "=" in inner else ([inner[1:], None] if inner.startswith("?") else None)) \
            if inner is not None else None
        if test and fanned:  # a second filter narrows the items already fanned out
            items = [x for x in items if _matches(x, *test)]
            continue
        if just_fanned and inner is not None and re.fullmatch(r"-?\d+", inner):
            try:  # an index right after [*] or a filter picks one of the items it gave
                items, fanned, just_fanned = [items[int(inner)]], False, False
            except IndexError:
                raise FigureError(f"no item {inner} among the {len(items)} of {path!r}") from None
            continue
        just_fanned = inner == "*" or bool(test)
        nxt: list[Any] = []
        for item in items:
            if inner == "*" or test:
                pool = list(item.values()) if isinstance(item, dict) else item
                if not isinstance(pool, list):
                    raise FigureError(f"{step} applied to a {type(item).__name__} in {path!r}")
                nxt.extend([x for x in pool if _matches(x, *test)] if test else pool)
                fanned = True
                continue
            key: Any = step if inner is None else inner
            if isinstance(item, list):
                try:
                    nxt.append(item[int(key)])
                except (ValueError, IndexError):
                    raise FigureError(f"no item {key} in {path!r}") from None
            elif isinstance(item, dict) and key in item:
                nxt.append(item[key])
            else:
                raise FigureError(f"missing: {key!r} in {path!r}")
        items = nxt
    return items if fanned else items[0]


# ------------------------------------------------------------------------------------------------
# Rendering


def _number(v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise FigureError(f"not a number: {v!r}")
    return v


def _fmt(v: Any, spec: str) -> str:
    if v is None:
        raise FigureError("the results hold null here")
    if isinstance(v, str):
        return v
    if isinstance(v, bool):
        return "yes" if v else "no"
    try:
        return format(v, spec) if spec else (str(v) if isinstance(v, int) else format(v, "g"))
    except (ValueError, TypeError):
        raise FigureError(f"format {spec!r} does not apply to {v!r}") from None


def percentile(values: list[float], q: float) -> float:
    """The q-th percentile, linear between the order statistics (NumPy's default)."""
    v = sorted(values)
    k = (len(v) - 1) * q / 100
    lo = int(k)
    return v[lo] + (v[min(lo + 1, len(v) - 1)] - v[lo]) * (k - lo)


def combine(op: str, a: Any, b: Any) -> Any:
    """``a op b`` for op in ``/ + -``, item by item when either is a list."""
    if isinstance(a, list) or isinstance(b, list):
        la = a if isinstance(a, list) else [a] * len(b)
        lb = b if isinstance(b, list) else [b] * len(a)
        if len(la) != len(lb):
            raise FigureError(f"cannot combine {len(la)} values with {len(lb)}")
        return [combine(op, x, y) for x, y in zip(la, lb)]
    x, y = _number(a), _number(b)
    if op == "/" and y == 0:
        raise FigureError("division by zero")
    return x / y if op == "/" else (x + y if op == "+" else x - y)


def render(data: Any, expr: str) -> str:
    """The text of one figure of ``data``: ``PATH [/ PATH] [; OPS]`` (or ``+``, ``-`` between two paths;
    the op ``pooled`` sums each side's values before they are combined)."""
    path, _, ops = expr.partition(" ; ")
    parts = BINARY.split(path)
    if len(parts) > 3:
        raise FigureError(f"at most one of ' / ', ' + ', ' - ' in {path!r}")
    if len(parts) == 1:
        value = resolve(data, parts[0])
    else:
        a, b = resolve(data, parts[0]), resolve(data, parts[2])
        if "pooled" in ops.split():  # each side summed first: sum(a) / sum(b), not item by item
            a, b = (sum(map(_number, v)) if isinstance(v, list) else v for v in (a, b))
        value = combine(parts[1], a, b)
    spec, join, shape = "", " / ", None
    for op in ops.split():
        if op == "pooled":
            continue
        if PERCENTILE.fullmatch(op):
            if not isinstance(value, list) or not value:
                raise FigureError(f"{op} needs several values; {path!r} gives {'none' if value == [] else 'one'}")
            value = percentile([_number(v) for v in value], float(op[1:]))
        elif op in REDUCERS or op in ("range", "interval", "sorted"):
            if not isinstance(value, list):
                raise FigureError(f"{op} needs several values; the path gives one")
            if op == "count":
                value = len(value)
            elif not value:
                raise FigureError(f"no item matches in {path!r} (only 'count' quotes nothing as 0)")
            elif op == "sorted":
                value = sorted(value)
            elif op in ("range", "interval"):
                shape, value = op, [min(map(_number, value)), max(map(_number, value))]
            else:
                value = REDUCERS[op]([_number(v) for v in value])
        elif op[0] in "*/" and len(op) > 1:
            f = float(op[1:]) if op[0] == "*" else 1 / float(op[1:])
            value = [_number(v) * f for v in value] if isinstance(value, list) else _number(value) * f
        elif op == "%":
            value = [_number(v) * 100 for v in value] if isinstance(value, list) else _number(value) * 100
        elif op == "commas":
            join = ", "
        elif m := VERDICT.fullmatch(op):
            if isinstance(value, list):
                raise FigureError(f"{op} needs one value; reduce the list first")
            limit, yes, no = float(m.group(2)), m.group(3), m.group(4)
            ok = {"<=": _number(value) <= limit, "<": value < limit, ">=": value >= limit, ">": value > limit}[m.group(1)]
            return (yes if ok else no).replace("_", " ")
        else:
            _fmt(1.5, op)
            spec = op
    if not isinstance(value, list):
        return _fmt(value, spec)
    if not value:
        raise FigureError(f"no item matches in {path!r} (only 'count' quotes nothing as 0)")
    texts = [_fmt(v, spec) for v in value]
    if shape is None:
        return join.join(texts)
    lo, hi = texts
    if shape == "interval":
        return f"[{lo}, {hi}]"
    return lo if lo == hi else (f"{lo} to {hi}" if lo.startswith("-") else f"{lo}-{hi}")


def provenance(data: Any, name: str) -> str:
    """``2026-11-26 09:46 UTC, 2-CPU Linux x86_64 (AMD EPYC), load 1.3-1.6, code f3ecfe3``."""
    if not isinstance(data, dict) or not isinstance(data.get("date"), str) or not isinstance(data.get("machine"), dict):
        raise FigureError(f"results/{name} has no top-level 'date' and 'machine'")
    m = data["machine"]
    if not all(k in m for k in ("cpus", "platform", "load")):
        raise FigureError(f"results/{name}: 'machine' needs 'cpus', 'platform' and 'load'")
    where = f"{m['cpus']}-CPU {m['platform']}" + (f" ({m['cpu']})" if m.get("cpu") else "")
    load_ = m["load"]
    if load_ is None:
        load_text = "load not recorded"
    else:
        lo, hi = (f"{x:.1f}" for x in (min(load_), max(load_)))
        load_text = f"load {lo}" if lo == hi else f"load {lo}-{hi}"
    text = f"{data['date']}, {where}, {load_text}"
    return text + (f", code {data['code']}" if data.get("code") else "")


def figure(spec: str, results: Path = RESULTS) -> tuple[str, str]:
    """``(file, rendered text)`` of a marker's spec: ``FILE @`` or ``FILE PATH [; OPS]``."""
    name, _, expr = spec.strip().partition(" ")
    if not expr.strip():
        raise FigureError(f"marker '{spec}' names no path (or '@')")
    data = load(name, results)
    if expr.strip() == "@":
        return name, provenance(data, name)
    provenance(data, name)  # a quoted file must say when and where
    return name, render(data, expr.strip())


# ------------------------------------------------------------------------------------------------
# Documents


def blocks(lines: list[str], code: set[int]) -> list[tuple[int, int]]:
    """(section, block) of each line: a section starts at a heading, a block at a blank line."""
    out, section, block, prev_blank = [], 0, 0, False
    for i, line in enumerate(lines):
        blank = not line.strip()
        if i not in code and line.startswith("#"):
            section += 1
        if blank and not prev_blank:
            block += 1
        out.append((section, block))
        prev_blank = blank
    return out


def process(doc: str, text: str, check: bool, results: Path = RESULTS) -> tuple[str, list[Problem], int]:
    """Check (or rewrite) one document: its new text, the problems found, figures changed."""
    lines = text.split("\n")
    code = code_lines(lines)
    block_of = blocks(lines, code)
    problems: list[Problem] = []
    quoted: dict[tuple[int, int], set[str]] = {}
    sourced: dict[tuple[int, int], set[str]] = {}
    changed = 0
    new_lines = []
    for i, line in enumerate(lines):
        def sub(m: re.Match[str], i: int = i) -> str:
            nonlocal changed
            spec, shown = m.group(1), m.group(2)
            try:
                name, want = figure(spec, results)
            except FigureError as exc:
                problems.append(Problem(doc, i + 1, f"{exc} [{spec}]"))
                return m.group(0)
            (sourced if spec.strip().endswith(" @") else quoted).setdefault(block_of[i], set()).add(name)
            if want == shown:
                return m.group(0)
            changed += 1
            if check:
                problems.append(Problem(doc, i + 1, f"differs: the text says {shown!r}, results/{name} gives {want!r} [{spec}]"))
                return m.group(0)
            return m.group(0)[: m.start(2) - m.start()] + want + m.group(0)[m.end(2) - m.start():]
        if i in code:  # code is shown as it is: a marker there is an example, not a figure
            new_lines.append(line)
            continue
        pieces = CODE_SPAN.split(line)
        spans = CODE_SPAN.findall(line)
        for k, piece in enumerate(pieces):
            pieces[k] = MARKER.sub(sub, piece)
            if STRAY.search(MARKER.sub("", piece)):
                problems.append(Problem(doc, i + 1, "an unmatched <!-- fig --> or <!-- /fig --> "
                                                    "(a marker opens and closes on one line)"))
        new_lines.append("".join(p + (spans[k] if k < len(spans) else "") for k, p in enumerate(pieces)))
    for (section, block), names in quoted.items():
        known = {n for (s, b), got in sourced.items() if s == section and b <= block for n in got}
        for name in sorted(names - known):
            line = block_of.index((section, block)) + 1
            problems.append(Problem(doc, line, f"figures from results/{name} without its date and machine: "
                                               f"<!-- fig {name} @ --> in this block or before it under the same heading"))
    return "\n".join(new_lines), problems, changed


def documents(root: Path = ROOT) -> list[Path]:
    """README.md, docs/*.md and benchmarks/README.md."""
    return [p for pattern in DOCS for p in sorted(root.glob(pattern))]


def run(check: bool, root: Path = ROOT, allow: dict[str, list[str]] | None = None) -> tuple[list[Problem], int]:
    """Check or rewrite every document under ``root`` against ``root/benchmarks/results``; the
    problems and how many figures changed (or differ)."""
    _cache.clear()
    allow = ALLOW if allow is None else allow
    results = root / "benchmarks" / "results"
    problems: list[Problem] = []
    used: set[tuple[str, str]] = set()
    total = 0
    for path in documents(root):
        doc = path.relative_to(root).as_posix()
        text = path.read_text(encoding="utf-8")
        new, found, changed = process(doc, text, check, results)
        problems += found
        total += changed
        lines = text.split("\n")
        for line, fig, seen in bare_figures(doc, lines, code_lines(lines)):
            if not allowed(doc, fig, seen, allow, used):
                problems.append(Problem(doc, line, f"{fig!r} looks measured but is not marked: mark it "
                                                   "(<!-- fig FILE PATH -->), reword it, or allow-list it (figure_rules.py)"))
        if not check and new != text:
            path.write_text(new, encoding="utf-8")
    for key, phrases in allow.items():
        for phrase in phrases:
            if (key, phrase) not in used:
                problems.append(Problem(key, 0, f"allow-listed phrase no longer found: {phrase!r}"))
    return problems, total


def leaves(data: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """Every scalar in ``data`` with its path (``--paths``)."""
    if isinstance(data, dict):
        out = []
        for k, v in data.items():
            plain = re.fullmatch(r"[^.\[\] =]+", str(k))
            step = (f".{k}" if prefix else str(k)) if plain else f"[{k}]"
            out += leaves(v, prefix + step)
        return out
    if isinstance(data, list):
        return [x for i, v in enumerate(data) for x in leaves(v, f"{prefix}[{i}]")]
    return [(prefix, data)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="change nothing; report differences (exit 1)")
    parser.add_argument("--get", nargs=2, metavar=("FILE", "EXPR"), help="render one figure, e.g. bench.json 'a.b ; .1f'")
    parser.add_argument("--paths", metavar="FILE", help="list every value of a results file with its path")
    args = parser.parse_args(argv)
    try:
        if args.get:
            print(figure(f"{args.get[0]} {args.get[1]}")[1])
            return 0
        if args.paths:
            for path, value in leaves(load(args.paths)):
                print(f"{path} = {json.dumps(value)}")
            return 0
    except FigureError as exc:
        print(f"figures.py: {exc}", file=sys.stderr)
        return 2
    problems, changed = run(args.check)
    for p in problems:
        print(p)
    verb = "differ" if args.check else "rewritten"
    print(f"{changed} figure(s) {verb}; {len(problems)} problem(s)", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
