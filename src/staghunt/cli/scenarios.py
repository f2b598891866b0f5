"""``staghunt scenarios``, ``show``, ``methods`` and ``schema``: what there is to plan with."""

from __future__ import annotations

import argparse
import json
from typing import Any

from staghunt.cli.common import EXIT_OK, add_scenario_argument, command


def add_commands(sub: Any) -> None:
    """Register ``scenarios``, ``show``, ``methods`` and ``schema`` on ``sub`` (from ``add_subparsers``)."""
    command(sub, "scenarios", cmd_scenarios)
    add_scenario_argument(command(sub, "show", cmd_show))
    command(sub, "methods", cmd_methods)
    p = command(sub, "schema", cmd_schema)
    kind = p.add_mutually_exclusive_group()
    kind.add_argument("--events", action="store_true",
                      help="the schema of an events file ('staghunt fly --events FILE') instead")
    kind.add_argument("--sweep", action="store_true",
                      help="the schema of a sweep spec ('staghunt sweep SPEC.toml') instead")


def cmd_scenarios(args: argparse.Namespace) -> int:
    """list the built-in scenarios"""
    from staghunt.scenario import builtin_names, load_scenario

    names = builtin_names()
    width = max((len(n) for n in names), default=0)
    for name in names:
        s = load_scenario(name)
        what = f"{s.n_uavs} UAVs, {len(s.world.cylinders) + len(s.world.prisms)} obstacles"
        desc = " ".join(s.description.split())
        print(f"{name:<{width}}  {what}" + (f"  {desc}" if desc else ""))
    return EXIT_OK


def cmd_show(args: argparse.Namespace) -> int:
    """print a validated scenario as JSON"""
    from staghunt.scenario import load_scenario, scenario_to_dict

    scenario = load_scenario(args.scenario)
    print(json.dumps(scenario_to_dict(scenario), indent=2, allow_nan=False, ensure_ascii=False))
    return EXIT_OK


def cmd_methods(args: argparse.Namespace) -> int:
    """list the planning methods"""
    from staghunt.solvers import DESCRIPTIONS, METHODS

    width = max((len(n) for n in METHODS), default=0)
    for name in METHODS:
        print(f"{name:<{width}}  {DESCRIPTIONS.get(name, '')}")
    return EXIT_OK




def cmd_schema(args: argparse.Namespace) -> int:
    """print the JSON Schema of the scenario file format

    Print the JSON Schema of the scenario format (TOML files checked as JSON data), for editors:
    'staghunt schema > scenario.schema.json', then point the editor's TOML support at it (see
    docs/scenario-format.md).
    """
    from staghunt.scenario.schema import EventsFile, json_schema

    if args.sweep:
        from staghunt.study.spec import sweep_schema

        schema = sweep_schema()
    else:
        schema = json_schema(EventsFile) if args.events else json_schema()
    print(json.dumps(schema, indent=2, ensure_ascii=False))
    return EXIT_OK
