"""Which numbers in the docs are figures: the rules that ``figures.py --check`` applies."""

from __future__ import annotations

BOUND = r"(?:<=|>=|≤|≥|<|>|at most|at least|up to|under|within|below|above|beyond|than|every|target)"
STRICT = {"benchmarks/README.md"}
ALLOW: dict[str, list[str]] = {}
