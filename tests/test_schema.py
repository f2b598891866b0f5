"""``staghunt schema``: the JSON Schema of the scenario format validates the built-in scenarios
with a standard validator (the TOML parsed to JSON data first), and rejects what the loader
rejects for type, key and range reasons."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from typing import Any

import jsonschema
import pytest

from staghunt.scenario import builtin_names, builtin_path


@pytest.fixture(scope="module")
def schema() -> dict[str, Any]:
    proc = subprocess.run([sys.executable, "-m", "staghunt", "schema"], capture_output=True,
                          text=True, timeout=120, check=True)
    out = json.loads(proc.stdout)
    jsonschema.Draft202012Validator.check_schema(out)
    return out


def toml_as_json(name: str) -> Any:
    with builtin_path(name).open("rb") as fh:
        return json.loads(json.dumps(tomllib.load(fh)))


@pytest.mark.parametrize("name", ["scenario1", "scenario2"])
def test_builtin_scenarios_validate(schema: dict[str, Any], name: str) -> None:
    assert name in builtin_names()
    jsonschema.Draft202012Validator(schema).validate(toml_as_json(name))


@pytest.mark.parametrize(
    "path, value",
    [
        (("colour",), "red"),
        (("site", "xmax"), "100"),
        (("site", "xmax"), True),
        (("team", 0, "start"), [1.0, 2.0]),
        (("team", 0, "weights"), [1.0, -1.0, 1.0, 1.0, 1.0]),
        (("solver", "particles"), 10.5),
        (("solver", "velocity_fraction"), 0.0),
        (("costs", "continuous_separation"), 1),
        (("ground", "kind"), "hilly"),
        (("origin", "latitude"), 91.0),
        (("vehicle", "max_speed"), 0.0),
        (("vehicle", "airframe"), "x500"),
    ],
)
def test_schema_rejects(schema: dict[str, Any], path: tuple[Any, ...], value: Any) -> None:
    data = toml_as_json("scenario2")
    target = data
    for p in path[:-1]:
        target = target[p]
    target[path[-1]] = value
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.Draft202012Validator(schema).validate(data)


def test_none_is_absent_but_unknown_keys_are_not() -> None:
    from staghunt.scenario import ScenarioError, load_scenario, scenario_from_dict, scenario_to_dict

    data = scenario_to_dict(load_scenario("scenario1"))
    data["costs"]["desired_height"] = None  # absent: the middle of the height band
    data["origin"] = None
    assert scenario_from_dict(data, name="x").origin is None
    data["colour"] = None
    with pytest.raises(ScenarioError, match="colour: unknown key"):
        scenario_from_dict(data, name="x")
