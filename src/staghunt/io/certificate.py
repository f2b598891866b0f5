"""The plain-data (strict-JSON) form of an equilibrium certificate, as ``result.json``,
``staghunt certify --out`` and ``compare`` store it."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from staghunt.solvers.response import Certificate


def _num(v: float | None) -> float | str | None:
    if v is None:
        return None
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return float(v)


def certificate_to_dict(cert: Certificate) -> dict[str, Any]:
    """Strict-JSON-able form (infinity as the string ``"inf"``, full precision)."""
    return {
        "status": cert.status,
        "verdict": cert.verdict,
        "epsilon": cert.epsilon,
        "epsilon_kind": "relative (gap / J_n of the plan)",
        "max_relative_gap": _num(cert.max_relative_gap),
        "max_gap": _num(cert.max_gap),
        "worst_uav": cert.uavs[cert.worst].name if cert.uavs else None,
        "particles": cert.particles,
        "iterations": cert.iterations,
        "seed": cert.seed,
        "notes": list(cert.notes),
        "uavs": [
            {
                "name": u.name,
                "J_n": _num(u.current),
                "best_response_J_n": _num(u.best),
                "gap": _num(u.gap),
                "relative_gap": _num(u.relative),
                "roundtrip_error": u.roundtrip_error,
                "evaluations": u.evaluations,
                "best_response_waypoints": None if u.deviation is None else np.asarray(u.deviation).tolist(),
            }
            for u in cert.uavs
        ],
    }
