"""Numbers as text for tables, CSV and progress lines: one place that decides how ``nan`` and
the infinities read."""

from __future__ import annotations

import math


def number_text(v: float, spec: str = "", nan: str = "nan", neg_inf: str = "-inf") -> str:
    """``format(v, spec)`` for a finite ``v`` (``spec=""``: the shortest repr), ``"inf"`` for
    plus infinity, ``neg_inf`` for minus infinity and ``nan`` for NaN."""
    v = float(v)
    if math.isnan(v):
        return nan
    if math.isinf(v):
        return "inf" if v > 0 else neg_inf
    return format(v, spec)
