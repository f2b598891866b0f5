"""The building blocks of the scenario format's tables (:mod:`staghunt.scenario.schema`): the
value types, the strict table every section derives from (unknown keys, wrong types, NaN and
infinities refused; a known key set to ``None`` counts as absent), a solid's "top above base"
rule, and the cross-field error that names its key."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, model_validator
from pydantic_core import PydanticCustomError

from staghunt.scenario.errors import fmt as _fmt

__all__ = ["BaseHeight", "Matrix", "NonNegative", "Number", "Polygon", "Solid", "Table", "TopHeight", "XYH", "fail"]


Number = float
NonNegative = Annotated[float, Field(ge=0)]
XYH = Annotated[list[Number], Field(min_length=3, max_length=3, description="[x, y, h], h above ground (m)")]
Matrix = list[list[Number]]


def fail(key: str, detail: str) -> PydanticCustomError:
    """A cross-field error of a table, reported at its key ``key``."""
    return PydanticCustomError("staghunt", "{detail}", {"detail": detail, "key": key})


class Table(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _none_is_absent(cls, data: Any) -> Any:
        """A known key whose value is ``None`` counts as absent (plain-data form); an unknown
        key is still reported, whatever its value."""
        if isinstance(data, Mapping):
            return {k: v for k, v in data.items() if v is not None or k not in cls.model_fields}
        return data

Polygon = Annotated[
    list[Annotated[list[Number], Field(min_length=2, max_length=2)]],
    Field(min_length=3, description="[[x, y], ...] footprint vertices in the site frame (m), not closed"),
]


BaseHeight = Annotated[float, Field(ge=0, description="m above ground; 0 = from the ground")]
TopHeight = Annotated[float, Field(gt=0, description="top, m above ground")]


class Solid(Table):
    """A table of a solid from ``base`` up to ``height`` (fields of its subclass, in their own
    order): the top must lie above the base."""

    @model_validator(mode="after")
    def _top_above_base(self) -> "Solid":
        base, height = self.base, self.height  # type: ignore[attr-defined]  # the subclass's fields
        if height <= base:
            raise fail("height", f"must be above base = {_fmt(base)}, got {_fmt(height)}")
        return self
