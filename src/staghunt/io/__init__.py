"""Input/output: the ``result.json`` format of a plan and the ``PATHS.json`` input of ``staghunt evaluate``.

Both are strict JSON (no ``NaN``/``Infinity`` tokens); an infinite number is written as the string
``"inf"`` (or ``"-inf"``). See :mod:`staghunt.io.result_json`.
"""

from staghunt.io.paths_json import evaluate_paths, read_paths
from staghunt.io.result_json import (
    FORMAT,
    decode_number,
    encode_number,
    read_result,
    result_to_dict,
    write_json_atomic,
    write_result,
)

__all__ = [
    "FORMAT",
    "decode_number",
    "encode_number",
    "evaluate_paths",
    "read_paths",
    "read_result",
    "result_to_dict",
    "write_json_atomic",
    "write_result",
]
