"""Formation graph and formation error (docs/model.md eq. (5)), in both of its forms.

Shapes: ``N`` UAVs, ``M`` edges, ``K`` waypoints. Positions are absolute ``(x, y, z)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class Formation:
    """Edge-weighted formation graph and reference shape.

    - ``incidence``: ``(N, M)``; ``D[n, e] = +1`` if UAV ``n`` is the head of edge ``e``,
      ``-1`` if its tail, else 0.
    - ``edge_weights``: ``(N, M)``; ``mu[n, e] >= 0``, UAV ``n``'s weight of edge ``e``.
    - ``reference``: ``(N, 3)`` absolute reference positions ``P_r`` (only differences matter).
    """

    incidence: np.ndarray
    edge_weights: np.ndarray
    reference: np.ndarray

    @property
    def n_edges(self) -> int:
        return int(self.incidence.shape[1])

    def heads_tails(self) -> tuple[np.ndarray, np.ndarray]:
        """``(M,)`` head and tail UAV index of every edge."""
        return np.argmax(self.incidence > 0, axis=0), np.argmax(self.incidence < 0, axis=0)

    def quadratic_forms(self) -> np.ndarray:
        """``(N, N, N)``: ``Q[n] = D W_n D^T``, so ``E_n = sum_ab (p_a - r_a).(p_b - r_b) Q[n, a, b]``."""
        D = self.incidence.astype(float)
        return np.einsum("ae,ne,be->nab", D, self.edge_weights, D)


def formation_error_edges(positions: np.ndarray, formation: Formation) -> np.ndarray:
    """Edge-sum form of eq. (5a).

    ``positions``: ``(..., N, 3)`` absolute positions of the team at one instant (any leading
    batch axes). Returns ``(..., N)``: ``E_n = sum_e mu[n, e] ||(P_h - P_t) - (P_h,r - P_t,r)||^2``.
    """
    heads, tails = formation.heads_tails()
    ref = formation.reference
    dev = (positions[..., heads, :] - positions[..., tails, :]) - (ref[heads] - ref[tails])
    sq = np.einsum("...ec,...ec->...e", dev, dev)  # (..., M)
    return np.einsum("...e,ne->...n", sq, formation.edge_weights)


def formation_error_quadratic(positions: np.ndarray, formation: Formation) -> np.ndarray:
    """Quadratic form of eq. (5b): ``E_n = (P - P_r)^T (D W_n D^T (x) I_3) (P - P_r)``.

    Same shapes as :func:`formation_error_edges`; the two agree to rounding.
    """
    delta = positions - formation.reference  # (..., N, 3)
    Q = formation.quadratic_forms()  # (N, N, N)
    return np.einsum("...ac,nab,...bc->...n", delta, Q, delta)


def is_connected(incidence: np.ndarray) -> bool:
    """Whether the undirected graph with this ``(N, M)`` incidence matrix is connected."""
    n = incidence.shape[0]
    if n <= 1:
        return True
    adj = {i: set() for i in range(n)}
    for e in range(incidence.shape[1]):
        (h,) = np.nonzero(incidence[:, e] > 0)
        (t,) = np.nonzero(incidence[:, e] < 0)
        adj[int(h[0])].add(int(t[0]))
        adj[int(t[0])].add(int(h[0]))
    seen = {0}
    stack = [0]
    while stack:
        for nb in adj[stack.pop()]:
            if nb not in seen:
                seen.add(nb)
                stack.append(nb)
    return len(seen) == n
