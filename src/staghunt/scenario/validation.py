"""Scenario validation with one-line messages: pydantic's first error on the
:class:`~staghunt.scenario.schema.ScenarioFile` model becomes a :class:`ScenarioError` naming
the key path (``team[2].start[1]``, array-of-tables entries indexed from 0), the value and what
was expected."""

from __future__ import annotations

import numbers
import types
import typing
from collections.abc import Mapping
from typing import Any

import numpy as np
from pydantic import BaseModel, ValidationError

from staghunt.scenario.errors import ScenarioError
from staghunt.scenario.errors import fmt as _fmt
from staghunt.scenario.schema import ScenarioFile

__all__ = ["key_path", "plain", "validate"]


# What a fixed-length array holds, by key; units of two-sided ranges; hints for array errors.
_VECTORS = {"start": "[x, y, h]", "goal": "[x, y, h]", "weights": "[w1, w2, w3, w4, w5]", "origin": "[x0, y0]"}
_UNITS = {"turning_threshold_deg": " degrees", "climb_threshold_deg": " degrees", "latitude": " degrees",
          "longitude": " degrees", "altitude": " m above mean sea level", "speed": " m/s",
          "position_noise": " m", "velocity_noise": " m/s"}
_ARRAY_HINTS = {"team": " (write [[team]] for each UAV)", "obstacles": " (write [[obstacles]] for each obstacle)",
                "prisms": " (write [[prisms]] for each prism)", "boxes": " (write [[boxes]] for each box)",
                "nofly": " (write [[nofly]] for each zone)", "geojson": " (write [[geojson]] for each file)"}


# pydantic error type -> message ({got}: "got a string '100'"; {value}: the value itself).
_MESSAGES = {
    "missing": "required key is missing",
    "float_type": "expected a number, {got}",
    "finite_number": "must be a finite number, got {value}",
    "int_type": "expected an integer, {got}",
    "bool_type": "expected true or false, {got}",
    "string_type": "expected a string, {got}",
    "model_type": "expected a table, {got}",
    "dict_type": "expected a table, {got}",
    "model_attributes_type": "expected a table, {got}",
    "list_type": "expected an array, {got}",
    "tuple_type": "expected an array, {got}",
    "literal_error": "must be one of {expected}, got {value!r}",
    "string_pattern_mismatch": "must not be empty, got {value!r}",
}


def plain(value: Any) -> Any:
    """``value`` as plain TOML-like data: NumPy arrays and scalars become lists and Python
    scalars, tuples lists (a key whose value is ``None`` counts as absent: see ``_Table``)."""
    if isinstance(value, Mapping):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


_UNION_TAGS = {"area", "facade", "point"}
"""The objectives' kinds: pydantic puts the tag of a tagged union in the error's location
(``objectives[0].area.gsd_cm``); the key path leaves it out."""


def key_path(loc: tuple[int | str, ...]) -> str:
    """``("team", 2, "start")`` -> ``"team[2].start"``; ``("objectives", 0, "area", "gsd_cm")``
    -> ``"objectives[0].gsd_cm"``."""
    out = ""
    for i, part in enumerate(loc):
        if part in _UNION_TAGS and i > 0 and isinstance(loc[i - 1], int) and i + 1 < len(loc):
            continue
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _kind(value: object) -> str:
    """Short type description for messages (TOML vocabulary)."""
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, numbers.Integral):
        return "an integer"
    if isinstance(value, numbers.Real):
        return "a float"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, Mapping):
        return "a table"
    if isinstance(value, (list, tuple)):
        return "an array"
    return f"a {type(value).__name__}"


def _show(value: object) -> str:
    """``repr`` of a value for messages, cut to a readable length."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _table_at(loc: tuple[int | str, ...], root: type[BaseModel] = ScenarioFile) -> type[BaseModel] | None:
    """The table model (under ``root``) that holds the key at ``loc`` (``None`` if there is none)."""
    model: Any = root
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        if part not in model.model_fields:  # a key of a dict of tables
            continue
        model = _model_in(model.model_fields[part].annotation)
        if model is None:
            return None
    return model


def _model_in(annotation: Any) -> type[BaseModel] | None:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = _model_in(arg)
        if found is not None:
            return found
    return None


def _field_bounds(loc: tuple[int | str, ...], root: type[BaseModel] = ScenarioFile) -> dict[str, float]:
    """The ``ge``/``gt``/``le``/``lt`` bounds declared on the field at ``loc``."""
    table = _table_at(tuple(p for p in loc if isinstance(p, str)), root)
    name = next((p for p in reversed(loc) if isinstance(p, str)), None)
    if table is None or name not in table.model_fields:
        return {}
    bounds: dict[str, float] = {}

    def collect(meta: Any) -> None:
        for kind in ("ge", "gt", "le", "lt"):
            if getattr(meta, kind, None) is not None:
                bounds[kind] = getattr(meta, kind)

    info = table.model_fields[name]
    for meta in info.metadata:
        collect(meta)
    if not bounds:  # bounds on the items of a list: list[Annotated[float, Field(ge=0)]]
        for arg in _walk(info.annotation):
            for meta in getattr(arg, "__metadata__", ()):
                collect(meta)
                for inner in getattr(meta, "metadata", ()):
                    collect(inner)
    return bounds


def _walk(annotation: Any) -> list[Any]:
    out = [annotation]
    for arg in typing.get_args(annotation):
        if not isinstance(arg, (types.NoneType, str)):
            out += _walk(arg)
    return out


def _range(value: Any, loc: tuple[int | str, ...], root: type[BaseModel] = ScenarioFile) -> str:
    b = _field_bounds(loc, root)
    lo = ("(", b["gt"]) if "gt" in b else ("[", b["ge"]) if "ge" in b else None
    hi = (")", b["lt"]) if "lt" in b else ("]", b["le"]) if "le" in b else None
    got = f"got {_fmt(value)}"
    if lo and hi:
        name = next((p for p in reversed(loc) if isinstance(p, str)), "")
        return f"must lie in {lo[0]}{_fmt(lo[1])}, {_fmt(hi[1])}{hi[0]}{_UNITS.get(name, '')}, {got}"
    if lo:
        return f"must be {'>' if lo[0] == '(' else '>='} {_fmt(lo[1])}, {got}"
    assert hi is not None
    return f"must be {'<' if hi[0] == ')' else '<='} {_fmt(hi[1])}, {got}"


def _message(err: Any, root: type[BaseModel] = ScenarioFile) -> tuple[str, str]:
    """(key path, detail) of one pydantic error against the model ``root``."""
    loc: tuple[int | str, ...] = tuple(err["loc"])
    kind, value, ctx = err["type"], err.get("input"), err.get("ctx") or {}
    name = next((p for p in reversed(loc) if isinstance(p, str)), "")
    got = f"got {_kind(value)} {_show(value)}"
    if kind == "staghunt":
        return key_path((*loc, ctx["key"])), str(ctx["detail"])
    if kind == "extra_forbidden":
        table = _table_at(loc, root)
        allowed = ", ".join(table.model_fields) if table is not None else ""
        return key_path(loc), f"unknown key; allowed keys here: {allowed}"
    if kind in _MESSAGES:
        hint = _ARRAY_HINTS.get(str(loc[-1]), "") if kind == "list_type" else ""
        return key_path(loc), _MESSAGES[kind].format(got=got, value=value, expected=ctx.get("expected")) + hint
    if kind in ("too_short", "too_long"):
        if loc == ("team",):
            return "team", "the team needs at least one UAV ([[team]] entry)"
        n = ctx.get("min_length") if kind == "too_short" else ctx.get("max_length")
        what = _VECTORS.get(name)
        expect = f"{what} ({n} numbers)" if what else f"{'at least' if kind == 'too_short' else 'at most'} {n} entries"
        return key_path(loc), f"expected {expect}, got {len(value) if hasattr(value, '__len__') else value} values"
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        return key_path(loc), _range(value, loc, root)
    return key_path(loc), f"{err['msg']}, {got}"  # not expected: pydantic's own words


def validate(data: Any, model: type[BaseModel] = ScenarioFile) -> Any:
    """Check plain data (:func:`plain` of a parsed TOML document) against the format (``model``:
    :class:`ScenarioFile`, or ``EventsFile``, whose tables are the scenario's own); raise
    :class:`ScenarioError` naming the first problem found."""
    if not isinstance(data, Mapping):
        raise ScenarioError(f"expected a table, got {_kind(data)}")
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
        # An unknown key first: a misspelt key also shows as a missing one.
        first = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
        key, detail = _message(first, model)
        raise ScenarioError(detail, key or None) from None
