"""What the planner knows of the changing site, and the checks of a reference in time.

The planner's view (:class:`KnownWorld`: the static obstacles, the sensed ones, those known to be
gone), the re-plan's problem built from it (:func:`sub_scenario`, :func:`swept_obstacles`, the
warm start :func:`remaining_plan`), and :func:`check_piece`, the in-time check every new piece
passes before it is flown (docs/model.md, section 8). Shapes: ``N`` UAVs, ``K`` free waypoints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from staghunt.costs import to_absolute
from staghunt.trajectory.quintic import Reference
from staghunt.safety.measure import moving_clearance, separations, static_clearance
from staghunt.scenario import Scenario
from staghunt.world import Cylinder, Prism
from staghunt.world.dynamic import Dynamics, max_motion_speed, motion_names

CHECK_STEP_S = 0.05
"""Time step of the in-time checks of a new piece and of the horizon (s)."""

@dataclass
class KnownWorld:
    """What the planner knows of the site: the scenario's static obstacles, the appeared ones
    it has sensed (by name), and the names it knows to be gone."""

    scenario: Scenario
    sensed: dict[str, Cylinder | Prism] = field(default_factory=dict)
    removed: set[str] = field(default_factory=set)

    def shapes(self) -> tuple[tuple[Cylinder, ...], tuple[Prism, ...]]:
        w = self.scenario.world
        cyl = [c for c in w.cylinders if c.name not in self.removed]
        prm = [p for p in w.prisms if p.name not in self.removed]
        for name, s in self.sensed.items():
            if name not in self.removed:
                (cyl if isinstance(s, Cylinder) else prm).append(s)
        return tuple(cyl), tuple(prm)


def to_xyh(scenario: Scenario, absolute: np.ndarray) -> np.ndarray:
    """``(..., 3)`` absolute ``(x, y, z)`` -> ``(x, y, h)`` above the ground."""
    out = np.array(absolute, dtype=float, copy=True)
    out[..., 2] -= scenario.world.terrain.height(out[..., 0], out[..., 1])
    return out


def sub_scenario(scenario: Scenario, starts_xyh: np.ndarray, cylinders: tuple[Cylinder, ...],
                 prisms: tuple[Prism, ...]) -> Scenario:
    """``scenario`` with new starts ``(N, 3)`` ``(x, y, h)`` and the given obstacles (goals,
    formation, weights and settings unchanged)."""
    team = tuple(replace(u, start=tuple(float(v) for v in s)) for u, s in zip(scenario.team, starts_xyh))
    world = replace(scenario.world, cylinders=cylinders, prisms=prisms)
    return replace(scenario, team=team, world=world)


def remaining_plan(scenario: Scenario, ref: Reference, t_s: float, K: int) -> np.ndarray:
    """``(N, K, 3)`` ``(x, y, h)``: the rest of the current plan after ``t_s``, resampled at
    ``K`` evenly spaced times of the path being flown (the warm start of a re-plan)."""
    piece = ref.piece_at(t_s)
    base = piece.base if piece.kind == "stop" and piece.base is not None else piece
    tau = piece.warp(np.array([t_s]))[0][0] if piece.kind == "stop" else t_s
    tau = min(max(tau, base.t0), base.t1)
    times = tau + (base.t1 - tau) * np.arange(1, K + 1) / (K + 1)
    pos = base.state(times)[0]  # (N, K, 3)
    return np.clip(to_xyh(scenario, pos), scenario.world.bounds.lower, scenario.world.bounds.upper)


def check_piece(scenario: Scenario, known: KnownWorld, dyn: Dynamics, piece_ref: Reference,
                t0: float, t1: float) -> tuple[list[str], list[tuple[str, float, float]], float]:
    """Check the reference over ``[t0, t1]`` every :data:`CHECK_STEP_S`: clearance to the
    known obstacles (at least half the hard clearance: the rest is left for tracking error),
    separation above ``d_s + 2 r``, height above ground, and clearance to the known motions at
    their true positions (the hard clearance plus the distance the UAV and the obstacle can
    close between two samples). Returns the problems, the motions' conflict windows
    ``(name, first, last)`` and the least clearance to anything known (m)."""
    if t1 <= t0:
        return [], [], math.inf
    t = np.linspace(t0, t1, max(2, math.ceil((t1 - t0) / CHECK_STEP_S) + 1))
    pos = piece_ref.state(t)[0]  # (N, T, 3)
    r = np.array([u.radius for u in scenario.team])
    names = [u.name for u in scenario.team]
    c = scenario.costs
    problems: list[str] = []
    cyl, prm = known.shapes()
    clear = static_clearance(cyl, prm, pos, r)
    if np.any(clear < 0.5 * c.min_clearance):
        n, k = np.unravel_index(np.argmin(clear), clear.shape)
        problems.append(f"{names[n]} passes {clear[n, k]:.2f} m from an obstacle at t = {t[k]:.1f} s")
    sep = separations(pos)
    limit = c.safe_distance + 2 * r
    if np.any(sep <= limit[:, None]):
        n, k = np.unravel_index(np.argmin(sep - limit[:, None]), sep.shape)
        problems.append(f"{names[n]} comes {sep[n, k]:.2f} m from a team-mate at t = {t[k]:.1f} s")
    h = pos[..., 2] - scenario.world.terrain.height(pos[..., 0], pos[..., 1])
    if np.any(h < 0):
        problems.append(f"below ground at t = {t[np.argmin(h.min(axis=0))]:.1f} s")
    windows: list[tuple[str, float, float]] = []
    least = float(clear.min(initial=math.inf))
    if dyn.known_motion:
        margin = (scenario.vehicle.max_speed + max_motion_speed(dyn)) * CHECK_STEP_S / 2
        mc, which = moving_clearance(dyn, pos, t, r)
        least = min(least, float(mc.min(initial=math.inf)))
        bad = mc < c.min_clearance + margin
        labels = motion_names(dyn)
        for i in np.unique(which[bad]):
            ks = np.flatnonzero((bad & (which == i)).any(axis=0))
            windows.append((labels[i], float(t[ks[0]]), float(t[ks[-1]])))
            problems.append(f"conflict with {labels[i]} from t = {t[ks[0]]:.1f} s to {t[ks[-1]]:.1f} s")
    return problems, windows, least


def swept_obstacles(scenario: Scenario, dyn: Dynamics, windows: list[tuple[str, float, float]]
                    ) -> tuple[tuple[Cylinder, ...], tuple[Prism, ...]]:
    """The swept stand-ins (:meth:`Dynamics.swept`) of the conflict ``windows`` ``(name, from,
    to)``, less any that holds a UAV's start or goal in ``scenario`` within the hard clearance:
    the UAV is there at another time than the motion (the in-time check judges it), and a
    stand-in around an end would leave no plan at all."""
    cyl: list[Cylinder] = []
    prm: list[Prism] = []
    for name, a, b in windows:
        c2, p2 = dyn.swept(a, b, {name})
        cyl += c2
        prm += p2
    g = scenario.world.terrain
    ends = np.concatenate([to_absolute(g, scenario.starts()), to_absolute(g, scenario.goals())])
    r = np.tile(np.array([u.radius for u in scenario.team]), 2)
    need = scenario.costs.min_clearance
    keep_c = tuple(c for c in cyl if np.all(static_clearance((c,), (), ends[:, None], r) >= need))
    keep_p = tuple(p for p in prm if np.all(static_clearance((), (p,), ends[:, None], r) >= need))
    return keep_c, keep_p


def covers(a: tuple[str, float, float], b: tuple[str, float, float]) -> bool:
    return a[0] == b[0] and a[1] <= b[1] and b[2] <= a[2]
