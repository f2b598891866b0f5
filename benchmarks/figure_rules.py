"""Which numbers in README.md, docs/*.md and benchmarks/README.md are measured figures, which
``figures.py --check`` requires to be marked (the rules in words: benchmarks/README.md, "Figures in
the docs").

Outside code (fenced or indented blocks, inline code), headings, link targets and markers:

- a number with a unit of time, size or ratio (``UNIT``): ``s ms us ns min h MB MiB GB GiB kB %
  times``, or a ratio written ``0.81x``; a range (``1.1-1.3 s``, ``180 to 770 times``) is one figure;
- in the files of ``STRICT`` (benchmarks/README.md), also any decimal number (``DECIMAL``);
- except a number right after a bound word (``BOUND``: a target, a limit or a period), and the
  phrases of ``ALLOW`` (per file; ``"*"`` for every file): definitions, not measurements. An
  allow-listed phrase that no longer appears in its file is itself a problem.
"""

from __future__ import annotations

import re

BOUND = r"(?:<=|>=|≤|≥|<|>|at most|at least|up to|under|within|below|above|beyond|than|every|target)"
STRICT = {"benchmarks/README.md"}
# Definitions that read like figures: each phrase must contain the figure and appear in its file.
ALLOW: dict[str, list[str]] = {
    "*": [
        "1 %-equilibri",            # epsilon of the certificate, part of the name of what it certifies
    ],
    "README.md": [
        "within 1 cm over 10 s",    # the tolerance of tests/test_vehicles.py
        "0.215 s for 3 UAVs, 1 s for 8",  # the re-planner's default deadlines (settings)
        "the next 20 s of the route",   # the receding horizon's default length (a setting)
    ],
    "docs/model.md": [
        "(10 % of",                 # the rigid seed's share of the budget
        "share, 10 % of",
        "1 % of the budget",        # the first reply's share
        "(default 1 %)",            # the certificate's epsilon
        "within 1 cm over 10 s",    # the tolerance of tests/test_vehicles.py
        "horizon (10 s)",           # the re-planner's horizon
        "latency 0.215 s for up to three UAVs plus 0.16 s per further UAV",  # the default deadline
        "target (a p95 of 0.2 s)",  # issue 38's latency target for 3 UAVs
        "at 0.215 s (",             # the default deadline (a setting)
        "default 0.1 s, 0.03 s, 1 %",   # the link's default delay, jitter and loss (settings)
        "(1 s), braking at three",  # a UAV's hold timeout (a setting)
        "reflex latency (0.05 s)",  # the onboard reflex's latency (a setting)
        "needs plus 0.3 s",         # the reflex's look-ahead margin (a setting)
        "20 s of the route ahead",  # the receding horizon (a setting)
        "1-4 times the motion's size",  # the sidestep's search
        "exposure 1/1000 s",        # a camera's default exposure
        "falls 10 % of",            # survey lines' extension rule
        "at 97 % of",               # the overlaps' planning margin
        "and 95 % of the speed",    # captures' speed margin under the blur limit
        "down to 40 % of",          # how far a facade position may be pulled in
        "plus 2 s per task",        # the allocation's transit model
        "one 0.1 s tick",           # the planner's tick
    ],
    "docs/inspection.md": [
        "flown at 95 % of",         # captures' speed margin under the blur limit
        "at 97 % of",               # the overlaps' planning margin
    ],
    "docs/compare.md": [
        "(10 % of the budget)",     # the rigid seed's share
        "epsilon: 1 % relative",    # the certificate's default
        "epsilon = 1 %",
        "about 65 %",               # the known answer of a test case (tests/test_certify.py)
    ],
    "docs/missions.md": [
        "an 86 MB wheel",           # the size of a dependency's wheel
        "grid file (150 MB)",       # the size of its data file
        "on a 2 ms grid",           # the grid the timing is checked on
    ],
    "docs/scenario-format.md": [
        "motor time constant 0.05 s",  # the m300 airframe's parameter
        "64 MB block cache",        # GDAL's cache setting
    ],
    "docs/sweep.md": [
        "(the last 2 s)",           # the store's flush period
    ],
    "benchmarks/README.md": [
        "(0.215 s for 3 UAVs, 0.2 s before code",  # the re-planner's default deadlines (settings)
        "1 s for 8)",               # the same, for 8 UAVs
        "effect 0.3 s after its trigger",  # the old loop's fixed latency budget (a setting)
        "link 100 ms delay, 30 ms jitter, 1 % loss",  # the benchmark's link (its settings)
        "300 ms delay, 30 ms jitter, 5 % loss",       # the worse link's settings
        "1 s for 8*",               # issue 38's latency target for 8 UAVs
        "0.2 s for 3 UAVs, too short",  # the default deadline (a setting)
        "with the deadline at 0.2 s*",  # the default deadline before (a setting)
        "before the deadline of 0.215 s,",  # the default deadline (a setting)
        "three UAVs is now 0.215 s",   # the default deadline (a setting)
        "by a p95 of 200 ms",          # issue 38's latency target for 3 UAVs
        "no re-plan over 200 ms",      # that target's bound (the slowest re-plans are in the table)
        "fixed latency of 0.15 s (",  # the fixed-latency runs' setting
        "radius 2.5 m",             # replan.py's episode generator
        "2-5 s later",
        "2-5 s ahead",
        "on a 2 ms grid",           # the grid TOPP-RA's peaks are read on
        "within 1 cm over 10 s",    # the tolerance of tests/test_vehicles.py
        "max \\|dx\\| over 10 s",     # the same, as a column
        "beta in {0.5, 2}",         # sweep.py's grid
        "at 1.5 cm/px",             # the built-in inspections' targets
        "at 0.5 cm/px",
        "(10 s apart)",             # inspection.py's losses
        "at 25, 40, 55 and 70 %",
        "OR-Tools run 30 s",        # its reference runs
        "(the camera's: 0.7 s)",    # the camera's minimum interval
        "1/1000 s",                 # the exposure
        "(legs x 1.25, 2 s per task)",  # the allocation's model
    ],
}

NUM = r"(?:\d{1,3}(?:,\d{3})+|\d+)(?:\.\d+)?"  # 12, 1,500, 0.81
SPAN = rf"{NUM}(?:\s*(?:-|–|to)\s*{NUM})?"
UNIT = re.compile(rf"(?<![\w.,]){SPAN}(?:\s?(?:ms|us|µs|ns|s|seconds?|min|minutes?|h|hours?|MB|MiB|GB|GiB|kB|KB|KiB|%|"
                  rf"times)|x)(?![\w])")
DECIMAL = re.compile(r"(?<![\w.])\d+\.\d+(?!\.?\d)")
CODE_SPAN = re.compile(r"`[^`\n]*`")
COMMENT = re.compile(r"<!--.*?-->")
LINK_TARGET = re.compile(r"\]\([^)]*\)")
MARKER = re.compile(r"<!--\s*fig\s+([^\n]*?)\s*-->([^\n]*?)<!--\s*/fig\s*-->")


def code_lines(lines: list[str]) -> set[int]:
    """Indices of lines in fenced or indented code blocks."""
    out, fence, prev_blank, in_indent = set(), None, True, False
    for i, line in enumerate(lines):
        s = line.strip()
        if fence is not None:
            out.add(i)
            if s.startswith(fence):
                fence = None
        elif s.startswith(("```", "~~~")):
            fence = s[:3]
            out.add(i)
        elif line.startswith(("    ", "\t")) and s and (prev_blank or in_indent):
            out.add(i)
            in_indent = True
        elif s:
            in_indent = False
        prev_blank = not s
    return out


def bare_figures(doc: str, lines: list[str], code: set[int]) -> list[tuple[int, str, str]]:
    """(line, figure, context) of every measured-looking number outside a marker; the context is the
    line's text after the end of the line before (a phrase may break across lines)."""
    out = []
    strict = doc in STRICT
    before = ""  # the end of the line before, in the same block: a bound may end it
    for i, line in enumerate(lines):
        if i in code or line.lstrip().startswith("#") or not line.strip():
            before = ""
            continue
        text = LINK_TARGET.sub("]()", COMMENT.sub(" ", MARKER.sub(" ", CODE_SPAN.sub(" ", line))))
        hits = list(UNIT.finditer(text))
        if strict:
            hits += [m for m in DECIMAL.finditer(text) if not any(h.start() <= m.start() < h.end() for h in hits)]
        for m in hits:
            if re.search(BOUND + r"\s*(?:\(|\+-|±|~)?\s*$", before + " " + text[:m.start()], re.I):
                continue
            out.append((i + 1, m.group(0), " ".join((before + " " + text).split())))
        before = text[-40:]
    return out


def allowed(doc: str, figure_text: str, line: str, allow: dict[str, list[str]], used: set[tuple[str, str]]) -> bool:
    """Whether an allow-listed phrase of ``doc`` (or of every doc, '*') holds this figure."""
    for key in (doc, "*"):
        for phrase in allow.get(key, ()):
            if figure_text in phrase and phrase in line:
                used.add((key, phrase))
                return True
    return False


