"""DEM ground: reading the grid (``.npy`` or GeoTIFF), its checksum, and the check that it covers
the site box. Failures raise :class:`ScenarioError` naming the ``ground`` key at fault."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from staghunt.scenario.errors import ScenarioError
from staghunt.scenario.errors import fmt as _fmt
from staghunt.world import Bounds, Terrain

DEM_SUFFIXES = (".npy", ".tif", ".tiff")


def read_dem_array(path: Path, key: str) -> np.ndarray:
    """Load a DEM grid from ``.npy`` or GeoTIFF; 2-D, finite, read-only, float32 or float64."""
    suffix = path.suffix.lower()
    if suffix not in DEM_SUFFIXES:
        raise ScenarioError(
            f"unsupported DEM file type {path.suffix!r} of {str(path)!r}; "
            f"use one of {', '.join(DEM_SUFFIXES)}",
            key,
        )
    if not path.is_file():
        raise ScenarioError(f"no such DEM file {str(path)!r}", key)
    try:
        if suffix == ".npy":
            raw = np.load(path, allow_pickle=False)
        else:
            try:
                import tifffile  # optional dependency, imported only when needed
            except ImportError:
                raise ScenarioError(
                    "reading a GeoTIFF DEM needs the optional 'tifffile' package: "
                    "pip install staghunt[geotiff]",
                    key,
                ) from None
            raw = tifffile.imread(path)
    except ScenarioError:
        raise
    except Exception as exc:  # corrupt file, pickled object array, unreadable TIFF...
        raise ScenarioError(f"cannot read DEM file {str(path)!r}: {exc}", key) from None
    raw = np.asarray(raw)
    if raw.ndim != 2 or raw.size == 0:
        raise ScenarioError(
            f"DEM in {str(path)!r} must be a non-empty 2-D grid, got shape {raw.shape}", key
        )
    if raw.dtype.kind not in "iuf":
        raise ScenarioError(f"DEM in {str(path)!r} must be numeric, got dtype {raw.dtype}", key)
    dtype = np.float32 if raw.dtype == np.float32 else np.float64
    grid = np.array(raw, dtype=dtype, copy=True, order="C")
    if not np.all(np.isfinite(grid)):
        bad = np.argwhere(~np.isfinite(grid))[0]
        raise ScenarioError(
            f"DEM in {str(path)!r} holds a non-finite value at row {bad[0]}, column {bad[1]}", key
        )
    from staghunt.inputs import MAX_MAGNITUDE

    if float(np.max(np.abs(grid))) > MAX_MAGNITUDE:
        raise ScenarioError(
            f"DEM in {str(path)!r} holds elevations beyond the supported magnitude {MAX_MAGNITUDE:.0e} m", key
        )
    grid.setflags(write=False)
    return grid


def grid_digest(grid: np.ndarray) -> str:
    """SHA-256 of the grid's C-order bytes (dtype as stored)."""
    return hashlib.sha256(np.ascontiguousarray(grid).tobytes()).hexdigest()


def check_dem_covers(terrain: Terrain, b: Bounds) -> None:
    """The DEM must cover the site box: cell centres for bilinear sampling, cells for nearest."""
    extent = terrain.extent()
    assert extent is not None and terrain.elevation is not None
    x0, x1, y0, y1 = extent
    slack = 0.5 * terrain.cell_size if terrain.sampling == "nearest" else 0.0
    rows, cols = terrain.elevation.shape
    eps = 1e-9 * max(1.0, abs(b.xmin), abs(b.xmax), abs(b.ymin), abs(b.ymax))
    if x0 - slack > b.xmin + eps or x1 + slack < b.xmax - eps or (
        y0 - slack > b.ymin + eps or y1 + slack < b.ymax - eps
    ):
        what = "cells" if slack else "cell centres"
        raise ScenarioError(
            f"the DEM ({rows} rows x {cols} columns, {what} spanning "
            f"x [{_fmt(x0 - slack)}, {_fmt(x1 + slack)}], "
            f"y [{_fmt(y0 - slack)}, {_fmt(y1 + slack)}]) "
            f"does not cover the site box x [{_fmt(b.xmin)}, {_fmt(b.xmax)}], "
            f"y [{_fmt(b.ymin)}, {_fmt(b.ymax)}]; check ground.origin and ground.cell_size",
            "ground",
        )
