"""The one exception of scenario loading, and the number format of its messages (kept free of
heavy imports)."""

from __future__ import annotations

from typing import Any


class ScenarioError(ValueError):
    """An invalid scenario: one human-readable line naming the offending key path.

    ``detail`` is the explanation, ``key`` the TOML key path (``None`` for file-level problems)
    and ``source`` the file the scenario came from, if any. ``str(error)`` joins them as
    ``"source: key: detail"``.
    """

    def __init__(self, detail: str, key: str | None = None, source: str | None = None) -> None:
        from staghunt.inputs import clip

        # Echoed input (a 100,000-character key) is cut so the line stays readable.
        self.detail = clip(detail)
        self.key = None if key is None else clip(key)
        self.source = source
        parts = [p for p in (source, key) if p]
        super().__init__(": ".join([*parts, self.detail]))

    def __reduce__(self) -> tuple[Any, ...]:
        return (self.__class__, (self.detail, self.key, self.source))


def fmt(v: float) -> str:
    """Compact number for messages: ``40`` rather than ``40.0``, full precision otherwise."""
    return f"{v:.12g}"
