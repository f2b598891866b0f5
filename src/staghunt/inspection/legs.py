"""The legs that join the captures, planned by the game.

- :func:`team_leg`: the UAVs that leave together (take-off to their first capture, or their last
  capture back to their goals, all at once) play the stag hunt game of the scenario on a leg
  whose starts and goals are those points: formation cost over the scenario's graph (restricted
  to the UAVs that fly the leg; the reference shape is the leg's goals, as in the paper),
  separation and obstacle costs, solved and certified as ``staghunt plan`` does.
- :func:`solo_leg`: a UAV alone between two captures (the others are at work elsewhere, on their
  own clocks): the straight hop when it clears everything (the turn between two survey lines),
  else the shortest way round or over what blocks it (:mod:`.detour`), else the game with that
  UAV as its only player (``J_s``: length, threats, height, turns).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from staghunt.acquisition.clearance import Keepout
from staghunt.acquisition.plan import CAPTURE_MARGIN
from staghunt.api import plan
from staghunt.inspection.detour import detour
from staghunt.result import PlanResult
from staghunt.scenario.model import Scenario, SolverSettings
from staghunt.solvers.response import CertifyOptions
from staghunt.task import Formation

__all__ = ["leg_scenario", "solo_leg", "team_leg"]


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float, copy=True)
    a.setflags(write=False)
    return a


def leg_scenario(scenario: Scenario, uavs: list[int], starts: np.ndarray, goals: np.ndarray, name: str,
                 reference: np.ndarray | None = None) -> Scenario:
    """``scenario`` for the UAVs ``uavs`` only, from absolute ``starts`` to absolute ``goals``
    (``(len(uavs), 3)`` each): the formation graph restricted to the edges between them, its
    reference shape ``reference`` (absolute, ``(len(uavs), 3)``; default: the goals, as in the
    paper)."""
    terrain = scenario.world.terrain
    team = []
    for i, k in enumerate(uavs):
        s, g = np.asarray(starts[i], float), np.asarray(goals[i], float)
        hs = float(s[2] - np.asarray(terrain.height(s[:1], s[1:2]))[0])
        hg = float(g[2] - np.asarray(terrain.height(g[:1], g[1:2]))[0])
        team.append(replace(scenario.team[k], start=(float(s[0]), float(s[1]), hs), goal=(float(g[0]), float(g[1]), hg)))
    inc = np.asarray(scenario.formation.incidence, dtype=float)[uavs]
    mu = np.asarray(scenario.formation.edge_weights, dtype=float)[uavs]
    keep = np.count_nonzero(inc, axis=0) == 2  # edges with both ends in the leg
    ref = goals if reference is None else reference
    formation = Formation(incidence=_frozen(inc[:, keep]), edge_weights=_frozen(mu[:, keep]), reference=_frozen(ref))
    return replace(scenario, name=f"{scenario.name}:{name}", team=tuple(team), formation=formation)


def team_leg(scenario: Scenario, uavs: list[int], starts: np.ndarray, goals: np.ndarray, name: str,
             settings: SolverSettings, seed: int, engine: str = "auto", certify: CertifyOptions | None = None,
             reference: np.ndarray | None = None) -> PlanResult:
    """The game on the leg of ``uavs`` from ``starts`` to ``goals`` (absolute, ``(n, 3)``), the
    formation's reference shape ``reference`` (default: the goals)."""
    leg = leg_scenario(scenario, uavs, starts, goals, name, reference)
    return plan(leg, method="game", seed=seed, settings=settings, engine=engine, certify=certify)


def solo_leg(scenario: Scenario, k: int, a: np.ndarray, b: np.ndarray, settings: SolverSettings, seed: int,
             engine: str = "auto") -> tuple[np.ndarray, PlanResult | None]:
    """UAV ``k``'s leg from ``a`` to ``b`` (absolute): ``(points (M, 3), plan or None)``."""
    keep = Keepout(scenario, scenario.team[k].radius, CAPTURE_MARGIN)  # room for the wind, as captures have
    hop = np.array([a, b], dtype=float)
    if np.linalg.norm(hop[1] - hop[0]) < 1e-9:
        return hop[:1].repeat(2, axis=0), None
    if keep.segment_ok(hop).all():
        return hop, None
    way = detour(keep, hop[0], hop[1])
    if way is not None:
        return way, None
    result = team_leg(scenario, [k], hop[:1], hop[1:], f"{scenario.team[k].name} leg", settings, seed, engine)
    return np.asarray(result.paths[0], dtype=float), result
