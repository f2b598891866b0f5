"""An objectives file (``--objectives FILE``): read and checked against its schema, and merged
into a scenario's plain data (:func:`staghunt.scenario.inspection.merge_objectives`)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from staghunt.scenario.errors import ScenarioError
from staghunt.scenario.loader import scenario_from_dict
from staghunt.scenario.model import Scenario

__all__ = ["read_objectives", "with_objectives"]


def read_objectives(path: str | os.PathLike[str]) -> dict[str, Any]:
    """An objectives file read once and checked against its schema (:class:`ScenarioError`
    naming the file and the key)."""
    from staghunt.inputs import check_magnitudes, parse_toml, read_text
    from staghunt.scenario.schema_inspection import ObjectivesFile
    from staghunt.scenario.validation import validate

    text = os.fspath(path)
    try:
        data = parse_toml(read_text(Path(text), "objectives file (TOML)"), text)
        check_magnitudes(data)
    except ValueError as exc:
        raise ScenarioError(str(exc)) from None
    try:
        validate(data, ObjectivesFile)
    except ScenarioError as exc:
        raise ScenarioError(exc.detail, exc.key, text) from None
    return data


def with_objectives(scenario: Mapping[str, Any], objectives: str | os.PathLike[str], *, name: str,
                    base_dir: Path | None, source: str | None = None) -> Scenario:
    """The scenario of plain data ``scenario`` with the objectives file ``objectives`` merged in;
    an error in the objectives is reported against the objectives file."""
    from staghunt.scenario.inspection import INSPECTION_KEYS, merge_objectives

    extra = read_objectives(objectives)
    where = Path(os.fspath(objectives)).parent
    for obj in extra.get("objectives", []):  # its GeoJSON files are relative to the objectives file
        if isinstance(obj, dict) and isinstance(obj.get("geojson"), str) and base_dir is not None:
            obj["geojson"] = str((where / obj["geojson"]).resolve())
    try:
        return scenario_from_dict(merge_objectives(scenario, extra), name=name, base_dir=base_dir)
    except ScenarioError as exc:
        mine = exc.key is not None and exc.key.split(".")[0].split("[")[0] in INSPECTION_KEYS
        raise ScenarioError(exc.detail, exc.key, os.fspath(objectives) if mine else source) from None
