"""The layout of the compiled engine's arrays: the named columns and indices the kernels and the
Python side share (plain integers: Numba freezes module-level integers as compile-time
constants, so naming them costs nothing), the modes of a pass, and the block size.

Layout: the particle index is innermost, so the loops over a block's lanes vectorise.

- Swarm state: ``X``, ``V``, ``PB``: ``(S, K, 3, P)``; ``gbest``: ``(S, K, 3)``;
  ``cost``, ``pcost``: ``(C, P)``; ``viol``, ``pviol``: ``(P,)``; ``J``: ``(N, P)`` per-UAV ``J_n``.
- Model arrays (:mod:`staghunt.engine.arrays`): ``uav (N, U_COLUMNS)`` = start ``(x, y, h)``,
  goal ``(x, y, h)``, start ``z``, goal ``z``, radius, ``beta``, separation limit ``d_s + 2 r``
  (columns ``U_*`` below);
  ``weights (N, 5)``; ``cyl (T, 3)``; ``prm (Q, 8)`` prisms = base, top, first edge, edge
  count, bounding box; ``pedge (E, 4)`` footprint edges (:func:`staghunt.world.prism_arrays`);
  ``heads``, ``tails (M,)``; ``mu (N, M)``; ``ref_diff (M, 3)``;
  ``grid (R, Cg)``; ``par`` (see ``P_*`` indices below).
- Swarm arrays: ``sw (S, SW_COLUMNS)`` = decoding start ``(x, y, h)``, decoding box low, high,
  search range low, high, velocity limit (each 3, over ``(rho, psi, phi)`` for the last three),
  then a flag (1: ``|psi| <= pi/4`` and ``|phi - c| <= pi/4``), ``c``, ``sin c``, ``cos c``
  (columns ``SW_*`` below);
  ``member (N,)``; ``offsets (N, 3)``; ``fixed (N, K, 3)``; ``players (C,)``.
- Block scratch (:class:`staghunt.engine.scratch.Scratch`): one thread's buffers of ``B`` lanes.
"""

from __future__ import annotations

# Indices into ``par``.
P_MARGIN = 0
P_SAFE = 1  # d_s (informational: the limits d_s + 2 r are in ``uav[:, U_LIMIT]``)
P_THR_TURN = 2
P_THR_CLIMB = 3
P_HREF = 4
P_CONTINUOUS = 5
P_TERRAIN = 6  # 0 flat, 1 nearest (float64 grid), 2 nearest (float32 arithmetic), 3 bilinear
P_OX = 7
P_OY = 8
P_CELL = 9
P_C1 = 10
P_C2 = 11
P_SUM = 12  # 1: the objective is the team sum, else the players' J
P_CLEAR = 13  # hard minimum clearance c: infeasible strictly inside R + r + c
P_CEIL = 14  # altitude ceiling (absolute z; inf = none)
N_PAR = 15
SOLO_STRIDE = 7
"""A problem with fixed paths (a unilateral deviation: :func:`staghunt.solvers.problem.solo_problem`)
appends, per UAV ``n``, its constant unweighted ``J_s`` terms (5) and obstacle and ground
violations (2) to ``par`` at ``N_PAR + SOLO_STRIDE * n``. Then only the swarm-following UAVs'
``J_s`` terms are computed, only pairs with a player are checked, the violation is the players'
own, and ``J`` of the other UAVs is NaN (as :meth:`SwarmProblem.evaluate`)."""

PRUNE_MIN_UAVS = 4  # separation pairs are pruned by boxes over a block's lanes for N above this
PRUNE_GUARD = 1e-6  # m added to a pair's limit before a box gap counts as clear

# Columns of ``uav (N, U_COLUMNS)`` (:func:`staghunt.engine.arrays.model_arrays`). Module-level
# integers: Numba freezes them as compile-time constants, so naming them costs nothing.
U_START = 0  # start (x, y, h): columns 0, 1, 2
U_GOAL = 3  # goal (x, y, h): columns 3, 4, 5
U_START_Z = 6  # start's absolute z
U_GOAL_Z = 7  # goal's absolute z
U_RADIUS = 8  # the UAV's radius r
U_BETA = 9  # its formation weight beta
U_LIMIT = 10  # its separation limit d_s + 2 r
U_COLUMNS = 11

# Columns of ``sw (S, SW_COLUMNS)`` (:func:`staghunt.engine.arrays.swarm_arrays`); the blocks of
# three run over (x, y, h) for the decoding box, over (rho, psi, phi) for the search range.
SW_START = 0  # decoding start (x, y, h)
SW_LOW = 3  # decoding box, low
SW_HIGH = 6  # decoding box, high
SW_RANGE_LOW = 9  # search range, low
SW_RANGE_HIGH = 12  # search range, high
SW_VMAX = 15  # velocity limit
SW_SMALL = 18  # 1.0: |psi| <= pi/4 and |phi - c| <= pi/4 (the decoder's fast path)
SW_CENTRE = 19  # c, the centre of phi's range
SW_SIN = 20  # sin c
SW_COS = 21  # cos c
SW_COLUMNS = 22

MODE_INIT = 0  # draw uniform positions, evaluate, personal bests = positions
MODE_STEP = 1  # PSO step, evaluate, personal bests by dominance
MODE_EVALUATE = 2  # evaluate the waypoints ``wp`` (no swarm state touched)
MODE_DEVIATE = 3  # evaluate ``wp`` as deviations of the ``players`` from fixed paths (see team_pass)


def block_size(n_uavs: int, waypoints: int) -> int:
    """Lanes per block: a multiple of 8 in ``[64, 256]`` keeping a block's paths in cache where
    that leaves 64 lanes or more. Large teams get 64 even so: with fewer lanes the loops over a
    block's lanes (the pair check's above all) measured slower than a larger block's cache
    misses (N = 24, K = 20: 24 lanes before; benchmarks/README.md)."""
    b = (16384 // max(1, n_uavs * (waypoints + 2))) // 8 * 8
    return max(64, min(256, b))
