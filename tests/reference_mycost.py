"""An independent scalar transcription of the SPSO reference's ``MyCost`` (docs/model.md eq. (2)).

One path at a time, plain loops and the ``math`` module, 1-based MATLAB indices kept where the
reference uses them. Used by ``test_reference.py`` to check the batched engine.

- path: full arrays ``x_all, y_all, z_rel_all`` (start, K free waypoints, goal), heights above
  ground;
- DEM ``H`` (rows = y, cols = x), sampled ``H(round(y), round(x))`` 1-based with MATLAB's
  ``round`` (halves away from zero); for a ``float32`` DEM the absolute altitude is
  ``single(z) + H`` (single-precision sum) promoted to double;
- threats ``(cx, cy, R)``; drone size 1, danger distance 10;
- thresholds 45 degrees for turning and climb-angle change; weights ``5, 1, 10, 1, 1``.
"""

from __future__ import annotations

import math
from decimal import ROUND_HALF_UP, Decimal

import numpy as np

DRONE_SIZE = 1.0
DANGER_DIST = 10.0 * DRONE_SIZE
TURNING_MAX = 45.0
CLIMB_MAX = 45.0
B1, B2, B3, B4, B5 = 5.0, 1.0, 10.0, 1.0, 1.0


def matlab_round(v: float) -> int:
    """MATLAB ``round``: nearest integer, halves away from zero (exact, via Decimal)."""
    return int(Decimal(v).quantize(Decimal(1), rounding=ROUND_HALF_UP))


def norm(v) -> float:
    return math.sqrt(sum(c * c for c in v))


def dot(a, b) -> float:
    return sum(x * y for x, y in zip(a, b))


def dist_p2s(x, a, b) -> float:
    """``DistP2S(x, a, b)``: distance from point ``x`` to segment ``ab`` (2-D)."""
    d_ab = norm((a[0] - b[0], a[1] - b[1]))
    d_ax = norm((a[0] - x[0], a[1] - x[1]))
    d_bx = norm((b[0] - x[0], b[1] - x[1]))
    if d_ab != 0:
        if dot((a[0] - b[0], a[1] - b[1]), (x[0] - b[0], x[1] - b[1])) * dot(
            (b[0] - a[0], b[1] - a[1]), (x[0] - a[0], x[1] - a[1])
        ) >= 0:
            # det([b - a; x - a])
            A = ((b[0] - a[0], b[1] - a[1]), (x[0] - a[0], x[1] - a[1]))
            det = A[0][0] * A[1][1] - A[0][1] * A[1][0]
            return abs(det) / d_ab
        return min(d_ax, d_bx)
    return d_ax  # a and b identical


def cross3(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def nnz(v) -> int:
    return sum(1 for c in v if c != 0)


def my_cost(x_all, y_all, z_rel_all, H: np.ndarray, threats, zmin: float, zmax: float):
    """Returns ``(cost, J1, J2, J3, J4_turning, J4_climb)`` for one full path."""
    x_all = [float(v) for v in x_all]
    y_all = [float(v) for v in y_all]
    z_all = [float(v) for v in z_rel_all]
    N = len(x_all)
    n = N - 2  # free waypoints
    z = z_all[1:-1]

    # Altitude wrt sea level = z_relative + ground level
    z_abs = [0.0] * N
    for i in range(1, N + 1):  # MATLAB 1-based
        g = H[matlab_round(y_all[i - 1]) - 1, matlab_round(x_all[i - 1]) - 1]
        if H.dtype == np.float32:
            z_abs[i - 1] = float(np.float32(z_all[i - 1]) + g)  # single + single, then double
        else:
            z_abs[i - 1] = z_all[i - 1] + float(g)

    # J1 - path length
    J1 = 0.0
    for i in range(1, N):
        diff = (x_all[i] - x_all[i - 1], y_all[i] - y_all[i - 1], z_abs[i] - z_abs[i - 1])
        J1 += norm(diff)

    # J2 - threats
    J2 = 0.0
    for cx, cy, R in threats:
        for j in range(1, N):
            dist = dist_p2s((cx, cy), (x_all[j - 1], y_all[j - 1]), (x_all[j], y_all[j]))
            if dist > R + DRONE_SIZE + DANGER_DIST:
                c = 0.0
            elif dist < R + DRONE_SIZE:
                c = math.inf
            else:
                c = (R + DRONE_SIZE + DANGER_DIST) - dist
            J2 += c

    # J3 - altitude over the free waypoints
    J3 = 0.0
    for i in range(n):
        if z[i] < 0:
            J3 += math.inf
        else:
            J3 += abs(z[i] - (zmax + zmin) / 2)

    # J4 - smoothness (turning, climb-angle change), 1-based as in MATLAB
    Jt = 0.0
    Jc = 0.0

    def X(k):
        return x_all[k - 1]

    def Y(k):
        return y_all[k - 1]

    def Z(k):
        return z_abs[k - 1]

    for i in range(1, N - 1):  # i = 1 .. N-2
        for j in range(i, 0, -1):  # j = i : -1 : 1
            segment1_proj = (X(j + 1) - X(j), Y(j + 1) - Y(j), 0.0)
            if nnz(segment1_proj) != 0:
                break
        for j in range(i, N - 1):  # j = i : N-2
            segment2_proj = (X(j + 2) - X(j + 1), Y(j + 2) - Y(j + 1), 0.0)
            if nnz(segment2_proj) != 0:
                break
        climb_angle1 = math.degrees(math.atan2(Z(i + 1) - Z(i), norm(segment1_proj)))
        climb_angle2 = math.degrees(math.atan2(Z(i + 2) - Z(i + 1), norm(segment2_proj)))
        turning_angle = math.degrees(
            math.atan2(norm(cross3(segment1_proj, segment2_proj)), dot(segment1_proj, segment2_proj))
        )
        if abs(turning_angle) > TURNING_MAX:
            Jt += abs(turning_angle)
        if abs(climb_angle2 - climb_angle1) > CLIMB_MAX:
            Jc += abs(climb_angle2 - climb_angle1)

    def term(w, t):
        return w * t  # all weights non-zero here

    cost = term(B1, J1) + term(B2, J2) + term(B3, J3) + term(B4, Jt) + term(B5, Jc)
    return cost, J1, J2, J3, Jt, Jc
