"""Equilibrium certificates of result files, and their reports (table, JSON).

The search itself, what a certificate is and is not, lives in :mod:`staghunt.solvers.response`
(docs/model.md section 7); :func:`certify_on_engine` runs it on a chosen engine.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from staghunt.budget import check_memory, estimate_certify
from staghunt.checks import check_inside_site
from staghunt.costs import CostModel
from staghunt.engine import Engine, get_engine
from staghunt.io.certificate import certificate_to_dict
from staghunt.io.result_json import read_result
from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.solvers.response import (
    DEFAULT_EPSILON,
    DEFAULT_ITERATIONS,
    DEFAULT_PARTICLES,
    Certificate,
    CertifyOptions,
    CertifyRequest,
    UAVGap,
    check_certify,
)
from staghunt.solvers.response import (
    certify_plan as _certify_plan,
)

__all__ = [
    "DEFAULT_EPSILON",
    "DEFAULT_ITERATIONS",
    "DEFAULT_PARTICLES",
    "Certificate",
    "UAVGap",
    "certificate_table",
    "certificate_to_dict",
    "certify_on_engine",
    "certify_result_file",
    "check_certify_plan",
    "plan_from_result_data",
    "run_certificate",
]


def certify_on_engine(
    scenario: Scenario,
    waypoints: np.ndarray,
    *,
    particles: int = DEFAULT_PARTICLES,
    iterations: int = DEFAULT_ITERATIONS,
    seed: int = 0,
    epsilon: float = DEFAULT_EPSILON,
    settings: SolverSettings | None = None,
    progress: Callable[[int, int, int, int], None] | None = None,
    engine: "str | Engine" = "auto",
    threads: int | None = None,
) -> Certificate:
    """:func:`staghunt.solvers.response.certify_plan` with the searches run by ``engine`` (see
    :func:`staghunt.engine.get_engine`). Refuses (``ValueError``) waypoints that are not a finite
    ``(N, K, 3)`` array of moderate magnitude or that leave the site box, and a budget that
    cannot fit in memory (:func:`check_certify_plan`)."""
    request, resolved = check_certify_plan(scenario, waypoints, CertifyOptions(particles, iterations, epsilon),
                                           seed, settings, engine, threads)
    return run_certificate(request, resolved, progress)


def check_certify_plan(scenario: Scenario, waypoints: np.ndarray, options: CertifyOptions, seed: int = 0,
                       settings: SolverSettings | None = None, engine: "str | Engine" = "auto",
                       threads: int | None = None, warn: Callable[[str], None] | None = None,
                       source: str | None = None) -> tuple[CertifyRequest, Engine]:
    """Every check a certificate of ``waypoints`` needs, made once: the plan, the seed, the
    budget and settings (:func:`staghunt.solvers.response.check_certify`), the plan inside the
    site box, the engine and the memory. ``source``: the file the plan comes from (named in
    the messages). Returns the checked request and the resolved engine for
    :func:`run_certificate`."""
    request = check_certify(scenario, waypoints, options, seed, settings,
                            what=f"{source}: settings" if source else "certificate settings")
    wp = request.waypoints
    check_inside_site(CostModel.from_scenario(scenario), wp, [u.name for u in scenario.team], source)
    resolved = get_engine(engine, threads)
    check_memory(estimate_certify(scenario.n_uavs, len(scenario.world.cylinders), wp.shape[1],
                                  options.particles, options.iterations, resolved, threads),
                 shrink="a smaller certificate budget (particles or iterations)", warn=warn, field="certify")
    return request, resolved


def run_certificate(request: CertifyRequest, engine: Engine,
                    progress: Callable[[int, int, int, int], None] | None = None) -> Certificate:
    """The certificate of a checked request, its searches run by ``engine``."""
    return _certify_plan(request, progress=progress, runner=engine.run_swarm, engine=engine)


# ------------------------------------------------------------------------------------------------
# result.json in, certificate out
# ------------------------------------------------------------------------------------------------


def plan_from_result_data(data: dict[str, Any], source: str = "RESULT.json") -> tuple[Scenario, np.ndarray, SolverSettings]:
    """The scenario, free waypoints ``(N, K, 3)`` and solver settings embedded in a parsed
    ``result.json`` (as :func:`staghunt.io.result_json.read_result` returns it). The settings
    are read, not judged: a search with them is checked where it is made
    (:func:`check_certify_plan`, :func:`staghunt.api.check_plan`).

    Waypoints are ``uavs[n].path`` x, y and ``uavs[n].heights`` (h above ground) without the
    start and goal. Raises ``ValueError`` with one line naming the offending field.
    """
    from dataclasses import fields

    from staghunt.scenario import ScenarioError, scenario_from_dict

    if not isinstance(data.get("scenario"), dict):
        raise ValueError(f"{source}: no embedded scenario (key 'scenario')")
    raw = data["scenario"]
    try:
        scenario = scenario_from_dict(raw, name=str(raw.get("name") or "scenario"))
    except ScenarioError as exc:
        raise ValueError(f"{source}: embedded scenario: {exc}") from None
    uavs = data.get("uavs")
    if not isinstance(uavs, list) or len(uavs) != scenario.n_uavs:
        raise ValueError(
            f"{source}: uavs: expected {scenario.n_uavs} entries (one per UAV of the scenario)"
        )
    rows = []
    for n, u in enumerate(uavs):
        where = f"{source}: uavs[{n}]"
        try:
            path = np.asarray(u["path"], dtype=float)
            heights = np.asarray(u["heights"], dtype=float)
        except (KeyError, TypeError, ValueError):
            raise ValueError(f"{where}: needs numeric 'path' ((K + 2) x 3) and 'heights' (K + 2)") from None
        if path.ndim != 2 or path.shape[1] != 3 or path.shape[0] < 3 or heights.shape != (path.shape[0],):
            raise ValueError(
                f"{where}: 'path' must be (K + 2) x 3 with K >= 1 and 'heights' K + 2 long, got "
                f"{list(path.shape)} and {list(heights.shape)}"
            )
        if not (np.all(np.isfinite(path)) and np.all(np.isfinite(heights))):
            raise ValueError(f"{where}: path and heights must be finite numbers")
        rows.append(np.column_stack([path[1:-1, :2], heights[1:-1]]))
    if len({r.shape for r in rows}) != 1:
        raise ValueError(f"{source}: every UAV must have the same number of waypoints")
    base = SolverSettings()
    raw_settings = data.get("settings") if isinstance(data.get("settings"), dict) else {}
    known = {f.name for f in fields(SolverSettings)}
    try:
        settings = base.with_(**{k: v for k, v in raw_settings.items() if k in known})
    except TypeError as exc:
        raise ValueError(f"{source}: settings: {exc}") from None
    return scenario, np.stack(rows), settings


def certify_result_file(
    path: str,
    *,
    data: dict[str, Any] | None = None,
    warn: Callable[[str], None] | None = None,
    particles: int = DEFAULT_PARTICLES,
    iterations: int = DEFAULT_ITERATIONS,
    seed: int = 0,
    epsilon: float = DEFAULT_EPSILON,
    progress: Callable[[int, int, int, int], None] | None = None,
    engine: "str | Engine" = "auto",
    threads: int | None = None,
) -> tuple[Certificate, dict[str, Any]]:
    """Certify the plan stored in ``path`` (a ``result.json``); returns the certificate and the
    parsed result. Notes any disagreement between the stored and the recomputed ``J_n``.

    ``data``: the file's content already read with :func:`staghunt.io.result_json.read_result`
    (the file is then not read again: it may be a pipe). Refuses (``ValueError``) a plan whose
    waypoints leave the site box, and a budget that cannot fit in memory."""
    if data is None:
        data = read_result(path)
    scenario, wp, settings = plan_from_result_data(data, str(path))
    request, resolved = check_certify_plan(scenario, wp, CertifyOptions(particles, iterations, epsilon), seed,
                                           settings, engine, threads, warn, source=str(path))
    cert = run_certificate(request, resolved, progress)
    stored = [u.get("cost", {}).get("total") for u in data["uavs"]]
    for u, s in zip(cert.uavs, stored):
        if isinstance(s, (int, float)) and not _close(float(s), u.current):
            cert = _with_note(cert, f"{u.name}: J_n recomputed from the paths ({u.current:.12g}) differs "
                                    f"from the stored cost ({float(s):.12g}); the cost code or "
                                    "scenario changed since the file was written")
    return cert, data


def _close(a: float, b: float) -> bool:
    if math.isinf(a) or math.isinf(b):
        return a == b
    return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))


def _with_note(cert: Certificate, note: str) -> Certificate:
    from dataclasses import replace

    return replace(cert, notes=cert.notes + (note,))


# ------------------------------------------------------------------------------------------------
# Reporting
# ------------------------------------------------------------------------------------------------


def certificate_table(cert: Certificate) -> str:
    """Plain-text table: per UAV its ``J_n``, best response, gap and relative gap."""
    def g(v: float | None) -> str:
        if v is None:
            return "-"
        return "inf" if math.isinf(v) else f"{v:.6g}"

    def pct(v: float) -> str:
        return "inf" if math.isinf(v) else f"{v:.3%}"

    rows = [("UAV", "J_n", "best response", "gap", "relative", "deviates")]
    for u in cert.uavs:
        dev = "-" if not cert.feasible else ("yes" if u.relative > cert.epsilon else "no")
        rows.append((u.name, g(u.current), g(u.best), g(u.gap), pct(u.relative), dev))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join([r[0].ljust(widths[0])] + [c.rjust(w) for c, w in zip(r[1:], widths[1:])])
             for r in rows]
    return "\n".join(lines)
