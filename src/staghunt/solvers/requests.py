"""A run refused before it starts: the error that names the argument at fault, and the check of a
seed. Below every solver module (:mod:`staghunt.solvers.base`, :mod:`staghunt.solvers.response`
and the API import it), so that none of them imports another for it."""

from __future__ import annotations

from typing import Any

import numpy as np

from staghunt.errors import FieldError


class RequestError(FieldError):
    """A run refused before it starts (:func:`staghunt.api.check_plan`,
    :func:`staghunt.solvers.response.check_certify`); ``field`` names the argument at fault
    (``method``, ``seed``, ``settings``, ``certify``, ``stop``, ``waypoints``) so that a caller
    (the command line) can word it its own way."""


def check_seed(seed: Any) -> int:
    """``seed`` as an ``int``; :class:`RequestError` unless it is an integer >= 0."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise RequestError(f"seed must be an integer >= 0, got {seed!r}", "seed")
    return int(seed)
