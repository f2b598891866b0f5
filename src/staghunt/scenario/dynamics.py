"""The changing site's tables (``[[moving]]``, ``[[jibs]]``, ``[[events]]``, ``[sensing]``,
``[link]``), in a
scenario file or an events file (``staghunt fly --events FILE``): checked tables in,
:class:`~staghunt.world.dynamic.Dynamics` out, with the checks that need the site."""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from staghunt.scenario.errors import ScenarioError, fmt
from staghunt.scenario.shapes import check_polygon, make_prism, nofly_zone
from staghunt.world import Cylinder, World
from staghunt.world.dynamic import Dynamics, Event, Link, MovingCylinder, Sensing, SlewingJib, Trigger

if TYPE_CHECKING:
    from staghunt.scenario.model import Scenario
    from staghunt.task import UAV
    from staghunt.scenario.schema import EventsFile, JibTable, ScenarioFile


def _inside(world: World, x: float, y: float) -> bool:
    return world.bounds.contains_xy(x, y)


def _jib(t: "JibTable", i: int, world: World) -> SlewingJib:
    key = f"jibs[{i}]"
    px, py = t.pivot
    if not _inside(world, px, py):
        raise ScenarioError(f"pivot {tuple(t.pivot)} lies outside the site", f"{key}.pivot")
    g = float(world.terrain.height(np.array([px]), np.array([py]))[0])
    jib = SlewingJib(t.name, (px, py), t.length, t.width, g + t.base, g + t.height, t.angle_from,
                     t.angle_to, t.rate, t.counter, t.start_time, t.repeat, (t.base, t.height))
    sweep = abs(t.angle_to - t.angle_from)
    angles = np.linspace(0.0, sweep, max(2, math.ceil(sweep / 2.0) + 1)) / max(t.rate, 1e-9) + t.start_time
    corners = jib.polygons(angles).reshape(-1, 2)
    b = world.bounds
    out = (corners[:, 0] < b.xmin) | (corners[:, 0] > b.xmax) | (corners[:, 1] < b.ymin) | (corners[:, 1] > b.ymax)
    if out.any():
        x, y = corners[np.argmax(out)]
        raise ScenarioError(f"the jib leaves the site while it slews (a corner reaches ({fmt(float(x))}, "
                            f"{fmt(float(y))}))", key)
    return jib


def dynamics_from_tables(f: "ScenarioFile | EventsFile", world: World, uavs: Sequence[str], prefix: str = "",
                         first_popup: int = 1) -> tuple[Dynamics, bool, bool]:
    """The :class:`Dynamics` of the checked tables of ``f`` in ``world`` with the team's UAVs
    called ``uavs`` (a trigger names one), and whether ``f`` gave a ``[sensing]`` and a
    ``[link]`` table. ``prefix`` goes before key paths in errors; appeared obstacles without a
    name are called ``pop-up <i>`` from ``first_popup`` on."""
    moving = []
    for i, m in enumerate(f.moving):
        for k, (x, y) in enumerate(m.path):
            if not _inside(world, x, y):
                raise ScenarioError(f"({fmt(x)}, {fmt(y)}) lies outside the site: a moving obstacle "
                                    "must stay in the site", f"{prefix}moving[{i}].path[{k}]")
        moving.append(MovingCylinder(m.name, m.radius, tuple((float(x), float(y)) for x, y in m.path),
                                     m.speed, m.start_time, m.repeat))
    jibs = [_jib(t, i, world) for i, t in enumerate(f.jibs)]
    events = []
    popup = first_popup
    for i, e in enumerate(f.events):
        key = f"{prefix}events[{i}]"
        if e.kind == "disappear":
            assert e.name is not None
            events.append(Event(e.time, "disappear", e.name))
            continue
        if e.kind == "uav_lost":
            assert e.uav is not None
            events.append(Event(e.time, "uav_lost", e.uav))
            continue
        if e.kind == "objective":
            assert e.objective is not None
            events.append(Event(e.time, "objective", e.objective.name, objective=e.objective.model_dump()))
            continue
        name = e.name
        if name is None:
            name, popup = f"pop-up {popup}", popup + 1
        shape: Any
        if e.polygon is None:
            assert e.x is not None and e.y is not None and e.radius is not None
            if not _inside(world, e.x, e.y):
                raise ScenarioError(f"({fmt(e.x)}, {fmt(e.y)}) lies outside the site", f"{key}.x")
            shape = Cylinder(e.x, e.y, e.radius, name)
        else:
            poly = check_polygon(e.polygon, f"{key}.polygon")
            shape = (nofly_zone(poly, name) if e.height is None
                     else make_prism(poly, e.base or 0.0, e.height, world.terrain, name))
        trigger = None
        if e.trigger is not None:
            if e.trigger.uav is not None and e.trigger.uav not in uavs:
                raise ScenarioError(f"no UAV named {e.trigger.uav!r}; the team: {', '.join(uavs)}",
                                    f"{key}.trigger.uav")
            trigger = Trigger(e.trigger.uav, e.trigger.within or 0.0, e.trigger.lead or 0.0)
        events.append(Event(e.time, "appear", name, shape, trigger=trigger))
    sensing = Sensing(**f.sensing.model_dump()) if f.sensing is not None else Sensing()
    link = Link(**f.link.model_dump()) if f.link is not None else Link()
    dyn = Dynamics(tuple(moving), tuple(jibs), tuple(sorted(events, key=lambda e: e.time)), sensing, link)
    return dyn, f.sensing is not None, f.link is not None


def check_names(dyn: Dynamics, world: World, key: str = "events") -> None:
    """The names that tie the changing world together, checked once it is whole (a scenario's
    own, or merged with an events file's): every changing obstacle has a name of its own,
    none of a static obstacle of the site (a ``disappear`` could not tell them apart), and every
    ``disappear`` names an obstacle that is there by then (of the site, or one that appeared
    before). ``dyn.events`` are in time order."""
    static = {c.name for c in world.cylinders} | {p.name for p in world.prisms}
    changing = [m.name for m in dyn.moving] + [j.name for j in dyn.jibs]
    changing += [e.name for e in dyn.events if e.kind == "appear"]
    seen: set[str] = set()
    for n in changing:
        if n in seen:
            raise ScenarioError(f"the name {n!r} is given to two changing obstacles", key)
        if n in static:
            raise ScenarioError(f"the name {n!r} is given to a changing obstacle and to an obstacle of the "
                                "site; give them different names", key)
        seen.add(n)
    there = static | {m.name for m in dyn.moving} | {j.name for j in dyn.jibs}
    appears = {e.name: e.time for e in dyn.events if e.kind == "appear"}
    for i, e in enumerate(dyn.events):
        if e.kind == "appear":
            there.add(e.name)
        elif e.kind != "disappear":
            continue
        elif e.name in appears and e.name not in there:
            raise ScenarioError(f"{e.name!r} disappears at t = {fmt(e.time)} s, before it appears at "
                                f"t = {fmt(appears[e.name])} s", f"{key}[{i}].time")
        elif e.name not in there:
            raise ScenarioError(f"no obstacle called {e.name!r} to disappear", f"{key}[{i}].name")


def check_take_off(dyn: Dynamics, team: "tuple[UAV, ...]", world: World, prefix: str = "") -> None:
    """No known motion of ``dyn`` may cover a UAV's start at take-off (``t = 0``: a moving
    cylinder waits at its first vertex, a jib at ``angle_from``): the UAV could not take off.
    Raises :class:`ScenarioError` naming the entry (``moving[i]``, ``jibs[i]``)."""
    starts = np.array([u.start for u in team], dtype=float)
    r = np.array([u.radius for u in team], dtype=float)
    for i, m in enumerate(dyn.moving):
        x, y = m.path[0]
        d = np.hypot(starts[:, 0] - x, starts[:, 1] - y) - m.radius - r
        if np.any(d < 0):
            n = int(np.argmin(d))
            raise ScenarioError(f"covers {team[n].name}'s start ({fmt(starts[n, 0])}, {fmt(starts[n, 1])}) at "
                                f"take-off: it waits at path[0] = ({fmt(x)}, {fmt(y)}) with radius {fmt(m.radius)} m "
                                f"until start_time", f"{prefix}moving[{i}]")
    z = starts[:, 2] + world.terrain.height(starts[:, 0], starts[:, 1])
    for i, j in enumerate(dyn.jibs):
        a = math.radians(j.angle_from)
        dx, dy = starts[:, 0] - j.pivot[0], starts[:, 1] - j.pivot[1]
        along, across = dx * math.cos(a) + dy * math.sin(a), -dx * math.sin(a) + dy * math.cos(a)
        gap = np.hypot(np.maximum.reduce([-j.counter - along, np.zeros_like(along), along - j.length]),
                       np.maximum(np.abs(across) - 0.5 * j.width, 0.0))
        hit = (gap < r) & (z > j.base - r) & (z < j.top + r)
        if np.any(hit):
            n = int(np.argmax(hit))
            raise ScenarioError(f"covers {team[n].name}'s start at take-off (the jib lies at angle_from = "
                                f"{fmt(j.angle_from)} degrees until start_time)", f"{prefix}jibs[{i}]")


def load_events(path: str | os.PathLike[str], scenario: "Scenario") -> Dynamics:
    """The scenario's changing world plus an events file's (read once, checked whole before
    anything runs); raises :class:`ScenarioError` naming the file and the entry at fault."""
    from staghunt.inputs import check_magnitudes, parse_toml, read_text
    from staghunt.scenario.schema import EventsFile
    from staghunt.scenario.validation import plain, validate

    source = os.fspath(path)
    try:
        data = plain(parse_toml(read_text(source, "events file (TOML)"), source))
        check_magnitudes(data)
        f = validate(data, EventsFile)
        own = scenario.dynamics
        first = 1 + sum(1 for e in own.events if e.kind == "appear")
        extra, sensing_given, link_given = dynamics_from_tables(f, scenario.world, [u.name for u in scenario.team],
                                                                first_popup=first)
        check_take_off(extra, scenario.team, scenario.world)
        dyn = own.merged(extra, sensing_given, link_given)
        check_names(dyn, scenario.world)
    except ScenarioError as exc:
        raise ScenarioError(exc.detail, exc.key, source) from None
    except ValueError as exc:
        raise ScenarioError(str(exc), None, source) from None
    return dyn


def dynamics_to_dict(dyn: Dynamics) -> dict[str, Any]:
    """The changing world in the scenario file's layout (only the tables it has)."""
    out: dict[str, Any] = {}
    if dyn.moving:
        out["moving"] = [{"name": m.name, "radius": m.radius, "path": [list(v) for v in m.path],
                          "speed": m.speed, "start_time": m.start_time, "repeat": m.repeat}
                         for m in dyn.moving]
    if dyn.jibs:
        out["jibs"] = [{"name": j.name, "pivot": list(j.pivot), "length": j.length, "counter": j.counter,
                        "width": j.width, "base": (j.agl or (0.0, 0.0))[0], "height": (j.agl or (0.0, 0.0))[1],
                        "angle_from": j.angle_from, "angle_to": j.angle_to, "rate": j.rate,
                        "start_time": j.start_time, "repeat": j.repeat} for j in dyn.jibs]
    if dyn.events:
        rows = []
        for e in dyn.events:
            row: dict[str, Any] = {"time": e.time, "kind": e.kind, "name": e.name}
            if e.kind == "uav_lost":
                row = {"time": e.time, "kind": e.kind, "uav": e.name}
            elif e.kind == "objective":
                row = {"time": e.time, "kind": e.kind, "objective": e.objective}
            elif isinstance(e.shape, Cylinder):
                row.update(x=e.shape.x, y=e.shape.y, radius=e.shape.radius)
            elif e.shape is not None:
                row["polygon"] = [list(v) for v in e.shape.polygon]
                if e.shape.agl is not None:
                    row.update(base=e.shape.agl[0], height=e.shape.agl[1])
            if e.trigger is not None:
                row["trigger"] = e.trigger.as_table()
            rows.append(row)
        out["events"] = rows
    s = dyn.sensing
    out["sensing"] = {"range": s.range, "rate": s.rate, "position_noise": s.position_noise,
                      "velocity_noise": s.velocity_noise}
    out["link"] = {"delay": dyn.link.delay, "jitter": dyn.link.jitter, "loss": dyn.link.loss}
    return out
