"""When, where and on what code a benchmark ran: the ``date``, ``code`` and ``machine`` that every
``benchmarks/results/*.json`` carries at its top level, and that ``figures.py`` renders beside
every figure quoted from it.

    started = provenance.start()          # before the measurements: the time, the load average
    ...
    data = provenance.stamped(started, data)   # {"date", "code", "machine", **data}

``machine`` is ``{"cpus", "platform", "cpu", "python", "load": [1-min load before, after]}``.
"""

from __future__ import annotations

import os
import platform
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Started:
    """The moment a benchmark started: UTC time, the 1-minute load average, the checkout's commit."""

    date: str
    load: float | None
    code: str | None


def load_now() -> float | None:
    """The 1-minute load average, rounded to 0.01 (None where the OS has none)."""
    try:
        return round(os.getloadavg()[0], 2)
    except OSError:
        return None


def start() -> Started:
    """Record the start of a benchmark."""
    return Started(time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), load_now(), code_version())


def cpu_model() -> str:
    """The processor's model name as the OS reports it ('' when unknown)."""
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def code_version(root: Path = ROOT) -> str | None:
    """The checkout's commit (short hash, '+' when the tree has changes), None outside git."""
    try:
        rev = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no", "--", "src"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return rev + ("+" if dirty else "")


def machine(load_before: float | None) -> dict[str, Any]:
    """This machine, with the load average before the run and now."""
    loads = [x for x in (load_before, load_now()) if x is not None]
    return {"cpus": os.cpu_count(), "platform": f"{platform.system()} {platform.machine()}", "cpu": cpu_model(),
            "python": platform.python_version(), "load": [min(loads), max(loads)] if loads else None}


def stamped(started: Started, data: dict[str, Any], code: str | None = "checkout") -> dict[str, Any]:
    """``data`` with ``date``, ``code`` and ``machine`` first. ``code`` is this checkout's commit when
    the benchmark started unless given (None: not recorded). Keys of an existing
    ``data["machine"]`` are kept."""
    rest = {k: v for k, v in data.items() if k not in ("date", "code", "machine")}
    old = data.get("machine") if isinstance(data.get("machine"), dict) else {}
    return {"date": started.date, "code": started.code if code == "checkout" else code,
            "machine": {**old, **machine(started.load)}, **rest}
