"""The episodes of the closed-loop benchmark (benchmarks/replan.py), built once and saved as plain
JSON, so that the same episodes can be flown by other code (the benchmark's "before" column) or
again.

- **scenario 2** (3 UAVs), planned once at the paper's setting (2000 x 1500, K = 10, seed 1)
  with the flight's margins (:func:`staghunt.flight.offline.takeoff_scenario`, as ``fly`` plans):
  a site vehicle (a cylinder of radius 2.5 m, 2-4 m/s, a known motion) crosses the team's route
  on a straight line across the site, timed to reach the route within +-2 s of the team; the
  plan is made sound against it before take-off; then a cylinder of radius 2-6 m appears on a
  random UAV's route 2-5 s ahead of it (the UAV would touch it 2-5 s after it appears; at a
  random time in the first 60 % of the flight), or sooner, as soon as that UAV comes as close to
  it as it was then on the plan (the event's trigger: the flight, re-timed by the receding
  horizon and the link, meets it as far ahead as the plan would have);
- **site_wedge** (8 UAVs), planned once at its own setting (400 x 300, seed 1), the same way: the tower
  crane's jib with its load (a box 3 m wide from 10 to 35 m above ground, 55-70 m long) slews
  into the route (3-8 deg/s, timed to sweep the route when the team is near), plus a pop-up
  load (radius 3-6 m) 2-5 s ahead of a random UAV.

Every draw is seeded by the episode's number: the same command builds the same episodes. A known
motion that no plan can avoid (``fly`` refuses to take off: a truck that parks on the route) is
drawn again, and the plans' figures list the episodes drawn again and why.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import provenance


MAX_DRAWS = 5
"""Draws of an episode's known motion until the flight can take off (:func:`build`)."""


def _reference(scenario: Any, waypoints: np.ndarray) -> Any:
    from staghunt.costs import to_absolute
    from staghunt.trajectory.quintic import Reference, timed_path

    g = scenario.world.terrain
    pts = np.concatenate([to_absolute(g, scenario.starts()[:, None]), to_absolute(g, waypoints),
                          to_absolute(g, scenario.goals()[:, None])], axis=1)
    return Reference((timed_path(pts, 0.0, scenario.vehicle),))


def _popup(scenario: Any, ref: Any, rng: np.random.Generator, radius: tuple[float, float],
           name: str) -> Any:
    """A cylinder on a random UAV's route that the UAV would touch 2-5 s after it appears (its
    reference enters the cylinder grown by the body radius that long after the appearance),
    appearing at a random time in the first 60 % of the flight, clear of every UAV at that
    time (by 2 m) and of every goal (by 5 m); or sooner, once that UAV comes as close to it as
    it is then (:func:`_trigger`)."""
    from staghunt.world import Cylinder
    from staghunt.world.dynamic import Event

    T = ref.arrival
    r = np.array([u.radius for u in scenario.team])
    goals = np.array([u.goal[:2] for u in scenario.team])
    grid = np.arange(0.0, T, 0.05)
    path = ref.state(grid)[0]  # (N, G, 3)
    for _ in range(1000):
        n = int(rng.integers(scenario.n_uavs))
        t = float(rng.uniform(3.0, 0.6 * T))
        lead = float(rng.uniform(2.0, 5.0))
        R = float(rng.uniform(*radius))
        # the centre: the first point on UAV n's route, after time t, whose disc of radius R + r
        # the UAV enters `lead` seconds after t
        later = np.flatnonzero(grid >= t)
        for k in later:
            p = path[n, k, :2]
            inside = np.hypot(path[n, later, 0] - p[0], path[n, later, 1] - p[1]) < R + r[n]
            first = grid[later[np.argmax(inside)]]
            if first - t >= lead:
                break
        else:
            continue
        now = ref.state(np.array([t]))[0][:, 0]
        gap = np.hypot(now[:, 0] - p[0], now[:, 1] - p[1]) - R - r
        to_goal = np.hypot(goals[:, 0] - p[0], goals[:, 1] - p[1]) - R - r
        if gap.min() > 2.0 and to_goal.min() > 5.0:
            shape = Cylinder(float(p[0]), float(p[1]), R, name)
            lead = float(first - t)
            return Event(t, "appear", name, shape, trigger=_trigger(scenario, ref, n, shape, lead)), n, lead
    raise RuntimeError("no pop-up position found")


def _trigger(scenario: Any, ref: Any, n: int, shape: Any, lead: float) -> Any:
    """The trigger of a pop-up that UAV ``n`` of the plan ``ref`` would touch ``lead`` s after it
    appears: the UAV within the horizontal distance from the pop-up's outline that it has, on
    ``ref``, ``lead`` s before it first enters it (its body touching it; at take-off at the
    latest)."""
    from staghunt.world.dynamic import Trigger

    grid, d, entry = _entry(ref, n, shape, scenario.team[n].radius)
    k = int(np.searchsorted(grid, max(0.0, entry - lead) - 1e-9)) if entry is not None else 0
    return Trigger(scenario.team[n].name, float(d[k] - shape.radius))


def _entry(ref: Any, n: int, shape: Any, body: float, since: float = 0.0) -> tuple[np.ndarray, np.ndarray, float | None]:
    """UAV ``n`` of the plan ``ref`` every 0.05 s from ``since`` (the times ``(G,)``): its
    horizontal distance from the pop-up's centre ``(G,)``, and the first time its body (radius
    ``body``) is inside the pop-up (``None``: never)."""
    grid = np.arange(since, ref.arrival, 0.05)
    xy = ref.state(grid)[0][n, :, :2]
    d = np.hypot(xy[:, 0] - shape.x, xy[:, 1] - shape.y)
    inside = d < shape.radius + body
    return grid, d, (float(grid[np.argmax(inside)]) if inside.any() else None)


def add_triggers(episodes: list[dict[str, Any]]) -> list[int]:
    """Give the pop-ups of episodes saved before triggers (code before 2026-11-27 17:00 UTC) the
    trigger :func:`build` gives them now (:func:`_trigger` with the saved lead), on the plan the
    flight takes off with (the episode's, made sound again by
    :func:`staghunt.flight.offline.plan_around`, as ``fly`` does). Returns the numbers of the
    episodes whose take-off plan is not the one their pop-up was placed on (its UAV enters the
    pop-up more than a sample away from the saved lead after the pop-up's time: ``fly``'s
    take-off has changed since the build); their triggers are on the take-off plan too."""
    from dataclasses import replace

    import staghunt
    from staghunt.api import check_plan
    from staghunt.flight import FlyConfig
    from staghunt.flight.offline import plan_around
    from staghunt.world.dynamic import Dynamics

    moved: list[int] = []
    scenarios: dict[str, Any] = {}
    for e in episodes:
        if not e["events"] or "trigger" in e["events"][0]:
            continue
        sc = scenarios.setdefault(e["kind"], staghunt.load_scenario(e["kind"]))
        wp, dyn = from_plain(e)
        known = Dynamics(dyn.moving, dyn.jibs)  # the plan is made sound against the known motion alone
        request = check_plan(replace(sc, dynamics=known), "game", 1, sc.solver, "auto")
        _, ref, _, _ = plan_around(request, known, wp, FlyConfig())
        v, n, shape = e["events"][0], e["popup_uav"], dyn.events[0].shape
        entry = _entry(ref, n, shape, sc.team[n].radius, since=v["time"])[2]
        if entry is None or abs(entry - v["time"] - e["popup_lead_s"]) > 0.051:
            moved.append(e["episode"])
        trig = _trigger(sc, ref, n, shape, e["popup_lead_s"])
        v["trigger"] = {"uav": trig.uav, "within": trig.within}
    return moved


def _truck(scenario: Any, ref: Any, rng: np.random.Generator) -> Any:
    """A site vehicle crossing the route on a straight line across the site."""
    from staghunt.world.dynamic import MovingCylinder

    b = scenario.world.bounds
    T = ref.arrival
    for _ in range(1000):
        t_c = float(rng.uniform(0.3, 0.8) * T)
        m = int(rng.integers(scenario.n_uavs))
        s = ref.state(np.array([t_c]))
        p, v = s[0][m, 0, :2], s[1][m, 0, :2]
        if np.linalg.norm(v) < 0.5:
            continue
        d = np.array([-v[1], v[0]]) / np.linalg.norm(v)  # across the route
        speed = float(rng.uniform(2.0, 4.0))
        # the segment of the line p + s d inside the site (margin 3 m)
        lo, hi = -1e9, 1e9
        for k, (a, z) in enumerate(((b.xmin + 3, b.xmax - 3), (b.ymin + 3, b.ymax - 3))):
            if abs(d[k]) > 1e-9:
                s1, s2 = (a - p[k]) / d[k], (z - p[k]) / d[k]
                lo, hi = max(lo, min(s1, s2)), min(hi, max(s1, s2))
        if rng.random() < 0.5:
            d, lo, hi = -d, -hi, -lo
        a, z = p + lo * d, p + hi * d
        arrive = t_c + float(rng.uniform(-2.0, 2.0))
        start = arrive - (-lo) / speed  # it passes p at `arrive`
        if start < 0:
            continue
        return MovingCylinder("truck", 2.5, ((float(a[0]), float(a[1])), (float(z[0]), float(z[1]))),
                              speed, start)
    raise RuntimeError("no crossing found")


def _jib(scenario: Any, ref: Any, rng: np.random.Generator) -> Any:
    """The tower crane's jib with its load slewing from south to north into the route."""
    from staghunt.world.dynamic import SlewingJib

    pivot = (398.0, 153.0)
    length = float(rng.uniform(55.0, 70.0))
    rate = float(rng.uniform(3.0, 8.0))
    # when does the team pass the crane's x?
    t = np.linspace(0.0, ref.arrival, 400)
    x = ref.state(t)[0][..., 0].mean(axis=0)
    t_pass = float(t[np.argmin(np.abs(x - pivot[0]))])
    # sweep the route (about 60 degrees before north) at the team's passing time +- 4 s
    start = max(0.0, t_pass + float(rng.uniform(-4.0, 4.0)) - 120.0 / rate)
    g = float(scenario.world.terrain.height(np.array([pivot[0]]), np.array([pivot[1]]))[0])
    return SlewingJib("crane jib (load)", pivot, length, 3.0, g + 10.0, g + 35.0, -90.0, 90.0, rate,
                      0.0, start, "stop", (10.0, 35.0))


def _with_popup(kind: str, episode: int, scenario: Any, waypoints: np.ndarray, known: Any
                ) -> tuple[np.ndarray, Any, int, float, int]:
    """The plan made sound against the episode's known motion (:func:`staghunt.flight.offline.plan_around`),
    and the episode's changing world with a pop-up 2-5 s ahead of a random UAV on *that* plan."""
    from dataclasses import replace

    from staghunt.api import check_plan
    from staghunt.flight import FlyConfig
    from staghunt.flight.offline import plan_around
    from staghunt.world.dynamic import Dynamics

    request = check_plan(replace(scenario, dynamics=known), "game", 1, scenario.solver, "auto")
    wp2, ref, windows, _ = plan_around(request, known, waypoints, FlyConfig())
    rng = np.random.default_rng([2 if kind == "scenario2" else 3, episode])
    radius, name = ((2.0, 6.0), "pop-up") if kind == "scenario2" else ((3.0, 6.0), "pop-up load")
    popup, n, lead = _popup(scenario, ref, rng, radius, name)
    return wp2, Dynamics(known.moving, known.jibs, (popup,), known.sensing), n, lead, len(windows)


def to_plain(kind: str, episode: int, waypoints: np.ndarray, dyn: Any, uav: int, lead: float, windows: int) -> dict[str, Any]:
    """An episode as plain JSON: the plan flown and the changing world (absolute site heights)."""
    from staghunt.world import Cylinder

    return {
        "kind": kind, "episode": episode, "waypoints": np.asarray(waypoints).tolist(),
        "moving": [{"name": m.name, "radius": m.radius, "path": [list(v) for v in m.path], "speed": m.speed,
                    "start_time": m.start_time, "repeat": m.repeat} for m in dyn.moving],
        "jibs": [{"name": j.name, "pivot": list(j.pivot), "length": j.length, "width": j.width, "base": j.base,
                  "top": j.top, "angle_from": j.angle_from, "angle_to": j.angle_to, "rate": j.rate,
                  "counter": j.counter, "start_time": j.start_time, "repeat": j.repeat,
                  "agl": list(j.agl) if j.agl else None} for j in dyn.jibs],
        "events": [{"time": e.time, "kind": e.kind, "name": e.name, "x": e.shape.x, "y": e.shape.y,
                    "radius": e.shape.radius,
                    **({"trigger": {"uav": e.trigger.uav, "within": e.trigger.within}} if e.trigger else {})}
                   for e in dyn.events if isinstance(e.shape, Cylinder)],
        "popup_uav": uav, "popup_lead_s": lead, "plan_windows": windows,
    }


POPUPS = ("lead", "placed", "timed")
"""How a pop-up appears (:func:`from_plain`): ``lead``, at its time or sooner once any UAV's
reference would breach the required clearance to it within its drawn lead (``popup_lead_s``;
the runs since 2026-11-27 21:00 UTC); ``placed``, at its time or sooner once the UAV it was
placed for is as close as the plan had it then (the saved trigger; the runs from 17:00 to 21:00
UTC); ``timed``, at its time only (the runs before)."""


def from_plain(e: dict[str, Any], popups: str = "lead") -> tuple[np.ndarray, Any]:
    """The plan ``(N, K, 3)`` and the :class:`~staghunt.world.dynamic.Dynamics` of a plain episode
    (built with constructors that the code of 2026-11 has too), its pop-up appearing as
    ``popups`` says (:data:`POPUPS`)."""
    from staghunt.world import Cylinder
    from staghunt.world.dynamic import Dynamics, Event, MovingCylinder, SlewingJib

    moving = tuple(MovingCylinder(m["name"], m["radius"], tuple(tuple(v) for v in m["path"]), m["speed"],
                                  m["start_time"], m["repeat"]) for m in e["moving"])
    jibs = tuple(SlewingJib(j["name"], tuple(j["pivot"]), j["length"], j["width"], j["base"], j["top"], j["angle_from"],
                            j["angle_to"], j["rate"], j["counter"], j["start_time"], j["repeat"],
                            tuple(j["agl"]) if j["agl"] else None) for j in e["jibs"])
    if popups not in POPUPS:
        raise ValueError(f"popups: one of {', '.join(POPUPS)}; got {popups!r}")
    events = tuple(Event(v["time"], v["kind"], v["name"], Cylinder(v["x"], v["y"], v["radius"], v["name"]),
                         trigger=_plain_trigger(v, e, popups))
                   for v in e["events"])
    return np.array(e["waypoints"], dtype=float), Dynamics(moving, jibs, events)


def _plain_trigger(v: dict[str, Any], e: dict[str, Any], popups: str) -> Any:
    from staghunt.world.dynamic import Trigger

    if popups == "timed" or "trigger" not in v:
        return None
    if popups == "placed":
        return Trigger(v["trigger"]["uav"], v["trigger"]["within"])
    return Trigger(None, lead=e["popup_lead_s"])


def build(counts: dict[str, int]) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """``counts`` episodes of each kind (``scenario2``, ``site_wedge``) as plain dicts, and the
    offline plans' figures. Plans at each scenario's own setting, seed 1."""
    import time

    import staghunt
    from staghunt.flight import FlyConfig
    from staghunt.flight.offline import FlightInputError, takeoff_scenario
    from staghunt.world.dynamic import Dynamics

    episodes: list[dict[str, Any]] = []
    plans: dict[str, Any] = {}
    for kind, count in counts.items():
        if count == 0:
            continue
        sc = staghunt.load_scenario(kind)
        t0 = time.perf_counter()
        res = staghunt.plan(takeoff_scenario(sc, FlyConfig()), seed=1)  # with the flight's margins, as `fly` plans
        plans[kind] = {"status": res.status.value, "plan_s": time.perf_counter() - t0,
                       "particles": sc.solver.particles, "iterations": sc.solver.iterations}
        wp = np.array(res.waypoints)
        ref = _reference(sc, wp)
        redrawn: list[str] = []
        for e in range(count):
            for draw in range(MAX_DRAWS):
                # draw 0 is the episode's seed of old; a known motion that no plan avoids (`fly`
                # refuses the flight before take-off) is drawn again, and said so
                rng = np.random.default_rng([0 if kind == "scenario2" else 1, e, *([draw] if draw else [])])
                known = (Dynamics(moving=(_truck(sc, ref, rng),)) if kind == "scenario2"
                         else Dynamics(jibs=(_jib(sc, ref, rng),)))
                try:
                    wp2, dyn, n, lead, windows = _with_popup(kind, e, sc, wp, known)
                    break
                except FlightInputError as err:
                    redrawn.append(f"episode {e}, draw {draw}: {err}")
            else:
                raise RuntimeError(f"{kind} episode {e}: no draw of its known motion can be flown")
            episodes.append(to_plain(kind, e, wp2, dyn, n, lead, windows))
        plans[kind]["redrawn"] = redrawn
    return episodes, plans


def save(path: Path, episodes: list[dict[str, Any]], plans: dict[str, Any], started: provenance.Started) -> None:
    """Write the episodes and the plans they fly, stamped with when, where and by which code they
    were built (``started``)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    data = provenance.stamped(started, {"plans": plans, "episodes": episodes})
    path.write_text(json.dumps(data) + "\n")


def load(path: Path) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    data = json.loads(path.read_text())
    return data["episodes"], data["plans"]


def add_triggers_to_file(path: Path, started: provenance.Started) -> int:
    """:func:`add_triggers` on the saved episodes of ``path``, written back with the build's own
    stamp kept and the addition's (``started``) under ``triggers_added``, with the episodes
    whose take-off plan moved. Returns how many pop-ups were given a trigger (0: the file is
    left as it is)."""
    data = json.loads(path.read_text())
    todo = sum(bool(e["events"]) and "trigger" not in e["events"][0] for e in data["episodes"])
    if todo:
        moved = add_triggers(data["episodes"])
        data["triggers_added"] = provenance.stamped(started, {"pop-ups": todo, "take-off plan moved": moved})
        path.write_text(json.dumps(data) + "\n")
    return todo
