"""Method comparison: every method on every seed, scored with the same ``J_n``.

:func:`check_compare` checks every run of a comparison once, before any work; :func:`run_compare`
then plans the scenario with each method and seed (seed-major: all methods of
seed 1, then seed 2, ...), certifies every plan (:mod:`staghunt.analysis.certify`) and keeps
everything on disk as it goes, so a long run can be interrupted and resumed:

- ``DIR/runs/<method>-s<seed>.json``: the plan's ``result.json`` (written atomically as soon as
  the run ends); ``DIR/runs/<method>-s<seed>.certify.json``: its certificate.
- ``DIR/compare.json`` and ``DIR/compare.csv``: the aggregate of every finished run, rewritten
  atomically after each run. A run whose files already exist is not planned again (resume); if
  they were made with other settings the comparison stops with a ``ValueError`` instead of
  mixing budgets.

Fairness: every method gets the same ``SolverSettings`` (particles, iterations, K), hence the
same budget of single-UAV path evaluations, ``particles x (iterations + 1) x N`` (a joint
evaluation of ``N`` paths counts ``N``; ``independent``'s ``N`` one-UAV runs count one each).
Every allocation is re-scored with the scenario's ``J_n`` (the game's cost model), whatever its
method optimised, and compared with :func:`staghunt.solvers.dominance.dominates` (Pareto
dominance with the feasibility-first rule).

``compare.csv`` has one row per method, seed and UAV (see :data:`CSV_COLUMNS`);
``compare.json`` holds the same runs plus the summary per method and UAV, the dominance verdict
of each seed, the Nash gaps and the paper's Fig. 8 block (:mod:`staghunt.analysis.paper`).

Modules: :mod:`.model` (the request, records, report, parsing of seeds and methods),
:mod:`.runner` (checking, running and resuming), :mod:`.stats` (statistics and dominance), :mod:`.formats` (JSON, CSV,
text). Figures: :mod:`staghunt.plots.compare`.
"""

from staghunt.analysis.compare.formats import CSV_COLUMNS, aggregate, csv_text, format_report
from staghunt.analysis.compare.model import (
    COMPARE_FORMAT,
    DEFAULT_METHODS,
    REFERENCE_METHOD,
    CertifyOptions,
    CompareListener,
    CompareReport,
    CompareRequest,
    RunRecord,
    certificate_file,
    parse_methods,
    parse_seeds,
    run_file,
)
from staghunt.analysis.compare.runner import check_compare, record_from_files, run_compare
from staghunt.analysis.compare.stats import best_seed, dominance_table, summarize

__all__ = [
    "COMPARE_FORMAT", "CSV_COLUMNS", "DEFAULT_METHODS", "REFERENCE_METHOD", "CertifyOptions",
    "CompareListener", "CompareReport", "CompareRequest", "RunRecord", "aggregate", "best_seed",
    "certificate_file", "check_compare",
    "csv_text", "dominance_table", "format_report", "parse_methods", "parse_seeds",
    "record_from_files", "run_compare", "run_file", "summarize",
]
