"""The figures of a flight (``staghunt fly``): the five PNGs, ``flight.gif`` and ``replay.html``.
The flight's data files: :mod:`staghunt.io.flight_files`."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from staghunt.io.flight_files import flight_dict
from staghunt.plots.animation import flight_animation
from staghunt.plots.flight import flight_figures
from staghunt.plots.replay import write_replay_html


def write_flight_figures(result: Any, out_dir: str | os.PathLike[str]) -> list[Path]:
    """Write the five figures, ``flight.gif`` and ``replay.html`` of ``result`` (a
    :class:`~staghunt.flight.FlightResult`) into ``out_dir``; returns the paths written."""
    out = Path(out_dir)
    data = flight_dict(result)
    files = flight_figures(data, out)
    files.append(flight_animation(data, out / "flight.gif"))
    write_replay_html(out / "replay.html", data)
    return files + [out / "replay.html"]
