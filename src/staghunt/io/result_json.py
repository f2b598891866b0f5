"""``result.json``: a :class:`~staghunt.result.PlanResult` as strict JSON, written atomically.

Encoding
--------
- The file is strict JSON (``json.dumps(..., allow_nan=False)``): it never holds the non-standard
  tokens ``NaN``, ``Infinity`` or ``-Infinity``, so any JSON parser reads it.
- An infinite number (an infeasible cost, the separation of a UAV flying alone, the clearance
  without obstacles) is written as the **string** ``"inf"`` (``"-inf"`` for minus infinity). The
  file says so itself in ``notes.infinity``. :func:`read_result` turns these strings back into
  ``float("inf")`` in the numeric fields; :func:`decode_number` does it for one value.
- ``NaN`` is never written: :func:`result_to_dict` raises ``ValueError`` naming the field instead.
- Floats are written with Python's shortest round-trip ``repr`` (full precision, nothing rounded),
  so reading the file gives back the very same ``float64`` values.
- Keys appear in a fixed order (the order of :func:`result_to_dict`), so the same plan always
  gives the same bytes apart from ``wall_time_s``.

Layout (``N`` UAVs, ``K`` free waypoints, ``I`` iterations, ``C`` compared objectives)::

    format, version, notes, method, seed, engine, status, message, wall_time_s (the search),
    compile_time_s (one-time engine compilation before it), certificate_time_s, evaluations,
    search {what the method recorded; game: rounds, accepted_replies, converged, ...},
    certificate (null if not certified) {status, verdict, epsilon, max_relative_gap, ...,
        particles, iterations, seed, uavs [N x {name, J_n, best_response_J_n, gap,
        relative_gap, evaluations (the deviation budget), ...}]},
    equilibria (null unless a multi-start game) [each distinct certified equilibrium found:
        {start, J [N], feasible, evaluations, certificate {status, epsilon, max_relative_gap,
         relative_gaps [N], complete (false: stopped at its first deviation beyond epsilon, the
         gaps of the UAVs not searched to the end are those found so far), particles,
         iterations}, dominated, selected, same [indices into
         search.candidates merged into it]}],
    selection (null unless a multi-start game) {payoff_dominant, rule, found, starts, starts_searched,
        stopped_at_first_certified (stop="certified": the starts after it left unsearched), selected_start},
    settings {particles, iterations, waypoints, c0, damping, c1, c2, velocity_fraction, starts},
    scenario (staghunt.scenario.scenario_to_dict),
    metrics {collision_free_waypoints, collision_free_continuous, obstacle_free,
             min_separation_waypoints, min_separation_segments, min_clearance},
    violations [str, ...],
    objective_history (I + 1) x C,
    uavs [N x {name, path (K + 2) x [x, y, z] absolute, heights (K + 2) above ground,
               cost {total, single, formation, terms {length, threat, altitude, turning, climb},
                     weighted_terms {...}},
               history (I + 1) best J_n per iteration,
               metrics {path_length, min_clearance, min_separation_waypoints,
                        min_separation_segments, separation_limit, formation_error (K),
                        formation_rms, min_height}}],
    leader_path (K + 2) x [x, y, z]      (method "rigid" only)

Writing is atomic: the text goes to a temporary file in the destination's directory, is flushed
and ``fsync``-ed, then moved over the destination with ``os.replace``. On any failure (including
``KeyboardInterrupt``) the temporary file is removed and the destination is left untouched.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np

from staghunt._version import __version__
from staghunt.io.atomic import write_text_atomic
from staghunt.io.certificate import certificate_to_dict

from staghunt.costs import TERM_NAMES

FORMAT = "staghunt-result/1"

INFINITY_NOTE = (
    'Strict JSON: an infinite number is written as the string "inf" ("-inf" for minus infinity); '
    "NaN never appears. Floats are written at full precision."
)
_HISTORY_NOTE = (
    "uavs[n].history[i] is UAV n's cost J_n of the best allocation after initialisation (i = 0) and "
    "after iteration i; objective_history[i] is what the solver compared (one value per UAV for "
    "'game', the team's summed cost for single-objective methods)."
)
_PATH_NOTE = (
    "uavs[n].path holds absolute [x, y, z] from start to goal (K + 2 points, metres); "
    "uavs[n].heights the height above ground of each point."
)


# ------------------------------------------------------------------------------------------------
# Numbers
# ------------------------------------------------------------------------------------------------


def encode_number(value: float, where: str = "value") -> float | str:
    """A finite float as itself, ``inf`` as ``"inf"``, ``-inf`` as ``"-inf"``; ``NaN`` raises ``ValueError``."""
    v = float(value)
    if math.isnan(v):
        raise ValueError(f"{where}: NaN cannot be written to strict JSON")
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return v


def decode_number(value: Any) -> Any:
    """Inverse of :func:`encode_number`: ``"inf"``/``"-inf"`` -> ``float``; anything else unchanged."""
    if value == "inf":
        return math.inf
    if value == "-inf":
        return -math.inf
    return value


def encode_array(a: Any, where: str) -> Any:
    """An array (any shape) of floats as nested lists with :func:`encode_number` applied."""
    arr = np.asarray(a, dtype=float)
    if np.isnan(arr).any():
        idx = tuple(int(i) for i in np.argwhere(np.isnan(arr))[0])
        raise ValueError(f"{where}{list(idx)}: NaN cannot be written to strict JSON")
    if arr.ndim == 0:
        return encode_number(arr, where)
    return _map(arr.tolist())


def _map(obj: Any) -> Any:
    if isinstance(obj, list):
        return [_map(v) for v in obj]
    return encode_number(obj)


def _decode_tree(obj: Any) -> Any:
    if isinstance(obj, list):
        return [_decode_tree(v) for v in obj]
    if isinstance(obj, dict):
        return {k: _decode_tree(v) for k, v in obj.items()}
    return decode_number(obj)


def weighted_terms(weights: np.ndarray, terms: np.ndarray) -> np.ndarray:
    """``weights * terms`` elementwise with ``0 * inf = 0`` (a zero weight drops the term)."""
    w = np.asarray(weights, dtype=float)
    t = np.asarray(terms, dtype=float)
    with np.errstate(invalid="ignore"):
        prod = w * t
    return np.where(w == 0, 0.0, prod)


def terms_dict(values: np.ndarray, where: str) -> dict[str, float | str]:
    """The five J_s terms ``(5,)`` as ``{length, threat, altitude, turning, climb}``."""
    return {name: encode_number(v, f"{where}.{name}") for name, v in zip(TERM_NAMES, values)}


# ------------------------------------------------------------------------------------------------
# PlanResult -> dict
# ------------------------------------------------------------------------------------------------


def result_to_dict(result: Any) -> dict[str, Any]:
    """The plain-data (strict-JSON-able) form of a :class:`~staghunt.result.PlanResult`.

    Raises ``ValueError`` naming the field if any value is ``NaN``.
    """
    # Imported here: staghunt.scenario / checks pull in the whole package.
    from staghunt.checks import violations
    from staghunt.costs import CostModel
    from staghunt.scenario import scenario_to_dict

    scenario = result.scenario
    names = [u.name for u in scenario.team]
    m = result.metrics
    c = result.costs
    n_uavs = len(names)
    history = np.asarray(result.history, dtype=float)
    model = CostModel.from_scenario(scenario)
    broken = violations(model, np.asarray(result.waypoints, dtype=float), names)

    uavs = []
    for n, name in enumerate(names):
        w = f"uavs[{n}]"
        weights = scenario.team[n].weights.as_array()
        terms = np.asarray(c.terms[0, n], dtype=float)
        uavs.append(
            {
                "name": name,
                "path": encode_array(result.paths[n], f"{w}.path"),
                "heights": encode_array(result.heights[n], f"{w}.heights"),
                "cost": {
                    "total": encode_number(c.total[0, n], f"{w}.cost.total"),
                    "single": encode_number(c.single[0, n], f"{w}.cost.single"),
                    "formation": encode_number(c.formation[0, n], f"{w}.cost.formation"),
                    "terms": terms_dict(terms, f"{w}.cost.terms"),
                    "weighted_terms": terms_dict(
                        weighted_terms(weights, terms), f"{w}.cost.weighted_terms"
                    ),
                },
                "history": encode_array(history[:, n], f"{w}.history"),
                "metrics": {
                    key: encode_array(getattr(m, key)[n], f"{w}.metrics.{key}")
                    for key in (
                        "path_length",
                        "min_clearance",
                        "min_separation_waypoints",
                        "min_separation_segments",
                        "separation_limit",
                        "formation_error",
                        "formation_rms",
                        "min_height",
                    )
                },
            }
        )

    def overall(a: np.ndarray, where: str) -> float | str:
        return encode_number(np.min(a) if n_uavs else math.inf, f"metrics.{where}")

    out: dict[str, Any] = {
        "format": FORMAT,
        "version": __version__,
        "notes": {"infinity": INFINITY_NOTE, "paths": _PATH_NOTE, "history": _HISTORY_NOTE},
        "method": result.method,
        "seed": int(result.seed),
        "engine": result.engine,
        "status": result.status.value,
        "message": result.message,
        "wall_time_s": encode_number(result.wall_time_s, "wall_time_s"),
        "compile_time_s": encode_number(result.compile_time_s, "compile_time_s"),
        "certificate_time_s": encode_number(result.certificate_time_s, "certificate_time_s"),
        "evaluations": int(result.evaluations),
        "search": _plain({k: v for k, v in result.details.items() if k not in ("equilibria", "selection")},
                         "search"),
        "certificate": None if result.certificate is None else certificate_to_dict(result.certificate),
        "equilibria": _plain(result.details.get("equilibria"), "equilibria"),
        "selection": _plain(result.details.get("selection"), "selection"),
        "settings": settings_to_dict(result.settings),
        "scenario": scenario_to_dict(scenario),
        "metrics": {
            "collision_free_waypoints": bool(m.collision_free_waypoints),
            "collision_free_continuous": bool(m.collision_free_continuous),
            "obstacle_free": bool(m.obstacle_free),
            "min_separation_waypoints": overall(m.min_separation_waypoints, "min_separation_waypoints"),
            "min_separation_segments": overall(m.min_separation_segments, "min_separation_segments"),
            "min_clearance": overall(m.min_clearance, "min_clearance"),
        },
        "violations": list(broken),
        "objective_history": encode_array(result.objective_history, "objective_history"),
        "uavs": uavs,
    }
    if result.leader_path is not None:
        out["leader_path"] = encode_array(result.leader_path, "leader_path")
    return out


def _plain(value: Any, where: str) -> Any:
    """Method details as strict-JSON-able data (numbers through :func:`encode_number`)."""
    if isinstance(value, dict):
        return {str(k): _plain(v, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, (bool, str)) or value is None:
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    return encode_number(float(value), where)


def settings_to_dict(settings: Any) -> dict[str, Any]:
    """Solver settings (a :class:`~staghunt.scenario.SolverSettings`) as plain data, field order kept."""
    out: dict[str, Any] = {}
    for f in fields(settings):
        v = getattr(settings, f.name)
        if isinstance(v, (int, np.integer)) and not isinstance(v, bool):
            out[f.name] = int(v)
        else:
            out[f.name] = encode_number(v, f"settings.{f.name}")
    return out


# ------------------------------------------------------------------------------------------------
# Files
# ------------------------------------------------------------------------------------------------


def dumps_strict(data: Any) -> str:
    """``json.dumps`` with ``allow_nan=False``, indent 2, keys in insertion order, trailing newline."""
    return json.dumps(data, allow_nan=False, indent=2, ensure_ascii=False) + "\n"


def write_json_atomic(data: Any, path: str | os.PathLike[str]) -> Path:
    """Write ``data`` as strict JSON to ``path`` atomically (temp file, fsync, ``os.replace``).

    The text is produced before any file is touched; if anything fails (or the run is
    interrupted) the temporary file is removed and ``path`` is left as it was.
    """
    return write_text_atomic(dumps_strict(data), path)


def write_result(result: Any, path: str | os.PathLike[str]) -> Path:
    """Write ``result`` (a :class:`~staghunt.result.PlanResult`) to ``path`` as ``result.json``, atomically."""
    return write_json_atomic(result_to_dict(result), path)


def load_json_strict(path: str | os.PathLike[str]) -> Any:
    """Parse a strict-JSON file, read once (a FIFO works); ``NaN``/``Infinity`` tokens raise
    ``ValueError``.

    Every error (missing file, a directory, not UTF-8, bad or too deeply nested JSON) is a
    ``ValueError`` with one line naming the file.
    """
    from staghunt.inputs import parse_json, read_text

    return parse_json(read_text(path, "JSON file"), os.fspath(path))


_NUMERIC_TOP = ("wall_time_s", "compile_time_s", "certificate_time_s", "metrics",
                "objective_history", "leader_path")
_NUMERIC_UAV = ("path", "heights", "cost", "history", "metrics")


def read_result(path: str | os.PathLike[str], *, decode_inf: bool = True) -> dict[str, Any]:
    """Read a ``result.json`` (once). With ``decode_inf`` the ``"inf"`` strings of the numeric
    fields become ``float("inf")`` (the scenario and the text fields are left as written).

    Raises ``ValueError`` with one line if the file is missing, not strict JSON, or not a result.
    """
    return result_from_data(load_json_strict(path), os.fspath(path), decode_inf=decode_inf)


def result_from_data(data: Any, source: str = "RESULT.json", *, decode_inf: bool = True) -> dict[str, Any]:
    """Check parsed ``result.json`` data (:func:`check_result_data`) and decode its ``"inf"``
    strings (with ``decode_inf``)."""
    check_result_data(data, source)
    if not decode_inf:
        return data
    out = dict(data)
    for key in _NUMERIC_TOP:
        if key in out:
            out[key] = _decode_tree(out[key])
    uavs = []
    for u in data["uavs"]:
        u = dict(u)
        for key in _NUMERIC_UAV:
            if key in u:
                u[key] = _decode_tree(u[key])
        uavs.append(u)
    out["uavs"] = uavs
    return out


_INT_SETTINGS = ("particles", "iterations", "waypoints")


def _kind(value: Any) -> str:
    from staghunt.inputs import show

    if value is None:
        return "null"
    names = {bool: "a boolean", str: "a string", list: "a list", dict: "an object"}
    for t, label in names.items():
        if isinstance(value, t):
            return f"{label} {show(value)}" if t in (str, bool) else label
    return f"{type(value).__name__} {show(value)}"


def _is_number(v: Any, allow_inf: bool = False) -> bool:
    if isinstance(v, bool):
        return False
    if isinstance(v, int):
        return True
    if isinstance(v, float):
        return math.isfinite(v) or allow_inf
    return allow_inf and v in ("inf", "-inf")


def check_result_data(data: Any, source: str = "RESULT.json") -> None:
    """Raise ``ValueError`` (one line: ``source: element: problem``) unless ``data`` has the
    shape of a ``result.json``: the format tag, ``uavs`` as objects with numeric ``path``
    ((K + 2) x 3, finite, within :data:`staghunt.inputs.MAX_MAGNITUDE`) and ``heights``,
    ``cost`` an object of numbers, ``settings`` numbers of the right kind, ``seed`` an integer
    >= 0 and ``scenario`` an object. What is checked is what ``certify`` and ``evaluate`` use."""
    from staghunt.inputs import MAX_MAGNITUDE

    def fail(where: str, detail: str) -> None:
        raise ValueError(f"{source}: {where}: {detail}")

    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"{source}: not a staghunt result file (format {FORMAT!r})")
    if not isinstance(data.get("uavs"), list):
        fail("uavs", f"expected a list, got {_kind(data.get('uavs'))}")
    if not isinstance(data.get("scenario"), dict):
        fail("scenario", f"expected an object (the embedded scenario), got {_kind(data.get('scenario'))}")
    seed = data.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        fail("seed", f"expected an integer >= 0, got {_kind(seed)}")
    settings = data.get("settings", {})
    if not isinstance(settings, dict):
        fail("settings", f"expected an object, got {_kind(settings)}")
    for key, v in settings.items():
        if key in _INT_SETTINGS:
            if isinstance(v, bool) or not isinstance(v, int):
                fail(f"settings.{key}", f"expected an integer, got {_kind(v)}")
        elif not _is_number(v):
            fail(f"settings.{key}", f"expected a finite number, got {_kind(v)}")
    lengths = set()
    for n, u in enumerate(data["uavs"]):
        w = f"uavs[{n}]"
        if not isinstance(u, dict):
            fail(w, f"expected an object, got {_kind(u)}")
        path, heights = u.get("path"), u.get("heights")
        if not isinstance(path, list) or len(path) < 3:
            fail(f"{w}.path", f"expected a list of at least 3 [x, y, z] points, got {_kind(path)}")
        for i, p in enumerate(path):
            if not isinstance(p, list) or len(p) != 3:
                fail(f"{w}.path[{i}]", f"expected [x, y, z], got {_kind(p)}")
            for j, v in enumerate(p):
                if not _is_number(v) or abs(v) > MAX_MAGNITUDE:
                    fail(f"{w}.path[{i}][{j}]", f"expected a finite number of magnitude <= "
                         f"{MAX_MAGNITUDE:.0e}, got {_kind(v)}")
        if not isinstance(heights, list) or len(heights) != len(path):
            fail(f"{w}.heights", f"expected a list of {len(path)} numbers (one per path point), got {_kind(heights)}"
                 + (f" of {len(heights)}" if isinstance(heights, list) else ""))
        for i, v in enumerate(heights):
            if not _is_number(v) or abs(v) > MAX_MAGNITUDE:
                fail(f"{w}.heights[{i}]", f"expected a finite number, got {_kind(v)}")
        lengths.add(len(path))
        cost = u.get("cost", {})
        if not isinstance(cost, dict):
            fail(f"{w}.cost", f"expected an object, got {_kind(cost)}")
        for key in ("total", "single", "formation"):
            if key in cost and not _is_number(cost[key], allow_inf=True):
                fail(f"{w}.cost.{key}", f"expected a number or \"inf\", got {_kind(cost[key])}")
        if "name" in u and not isinstance(u["name"], str):
            fail(f"{w}.name", f"expected a string, got {_kind(u['name'])}")
    if len(lengths) > 1:
        fail("uavs", "every UAV's path must have the same number of points")
