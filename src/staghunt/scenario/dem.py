"""DEM ground: reading the grid (``.npy`` or GeoTIFF), its checksum, and the check that it covers
the site box. Failures raise :class:`ScenarioError` naming the ``ground`` key at fault."""

from __future__ import annotations

import errno
import functools
import hashlib
import math
import os
from pathlib import Path

import numpy as np

from staghunt.scenario.errors import ScenarioError
from staghunt.scenario.errors import fmt as _fmt
from staghunt.world import Bounds, GeoOrigin, Terrain

DEM_SUFFIXES = (".npy", ".tif", ".tiff")

ELEVATION_RANGE = (-500.0, 10000.0)
"""Elevations (m above mean sea level) a geo-referenced DEM may hold under the site: the range of
an ``[origin]`` altitude. A value beyond it is a unit error or an undeclared nodata value."""

MAX_GRID_NODES = 16_000_000
"""Most nodes of the site grid a GeoTIFF is resampled into (128 MB of float64): a larger one
comes from a ``cell_size`` far finer than any DEM needs."""


def resolve_file(path: Path, key: str, what: str) -> Path:
    """``path`` made absolute with its symbolic links resolved; :class:`ScenarioError` naming
    ``key`` for a symlink loop or a path the system refuses (too long, ...)."""
    try:
        return path.resolve()
    except RuntimeError:  # Python < 3.13: "Symlink loop from ..."
        raise ScenarioError(f"{what} {str(path)!r} is a symbolic link loop", key) from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise ScenarioError(f"{what} {str(path)!r} is a symbolic link loop", key) from None
        raise ScenarioError(f"cannot open {what} {str(path)!r}: {exc.strerror or exc}", key) from None


def file_digest(path: Path, key: str) -> str:
    """SHA-256 of a file's bytes (read in blocks), computed once per process for a file of a
    given size, modification time and inode (a GeoTIFF of a site can take seconds to hash)."""
    try:
        st = os.stat(path)
        return _file_digest(str(path), st.st_size, st.st_mtime_ns, st.st_ino)
    except OSError as exc:
        raise ScenarioError(f"cannot read {str(path)!r}: {exc.strerror or exc}", key) from None


@functools.lru_cache(maxsize=16)
def _file_digest(path: str, size: int, mtime_ns: int, inode: int) -> str:  # noqa: ARG001 (the cache key)
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def geotiff_digest(terrain: Terrain) -> str:
    """SHA-256 of the GeoTIFF file a terrain was read from (:func:`read_geotiff_terrain`), made
    when asked for (a scenario's dump, a ``ground.sha256`` check), not at every load."""
    return file_digest(Path(terrain.source), "ground.file")


def grid_size(b: Bounds, cell_size: float, key: str = "ground.cell_size") -> tuple[int, int]:
    """``(rows, cols)`` of the site grid at ``cell_size``; :class:`ScenarioError` when it would
    exceed :data:`MAX_GRID_NODES` (a too fine ``cell_size``, not a memory budget, is the cause)."""
    span_x, span_y = b.xmax - b.xmin, b.ymax - b.ymin
    nx, ny = span_x / cell_size, span_y / cell_size
    if not (math.isfinite(nx) and math.isfinite(ny)) or (nx + 1) * (ny + 1) > MAX_GRID_NODES:
        finest = math.sqrt(max(span_x, 1e-9) * max(span_y, 1e-9) / MAX_GRID_NODES)
        count = (nx + 1) * (ny + 1)
        nodes = f"about {count:.3g}" if math.isfinite(count) else "more than 1e308"
        raise ScenarioError(
            f"cell_size = {_fmt(cell_size)} m would resample the {_fmt(span_x)} x {_fmt(span_y)} m site into "
            f"a grid of {nodes} nodes (at most {MAX_GRID_NODES:.3g}); use a cell_size "
            f">= {finest:.3g} m (the ground needs no finer grid than its DEM's pixels)", key)
    cols = int(math.ceil(nx - 1e-9)) + 1
    rows = int(math.ceil(ny - 1e-9)) + 1
    return rows, cols


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


def read_geotiff_terrain(path: Path, origin: GeoOrigin, b: Bounds, cell_size: float, sampling: str,
                         nodata_fill: float | None, key: str) -> Terrain:
    """A geo-referenced GeoTIFF DEM (any CRS rasterio and pyproj know; elevations in metres above
    mean sea level) resampled into the site frame: a ``(rows, cols)`` float64 grid of site
    heights ``z = elevation - origin.altitude`` whose first node is ``(xmin, ymin)`` and whose
    spacing is ``cell_size``, covering the site box. Each node is transformed into the DEM's
    CRS (pyproj) and interpolated bilinearly between the four surrounding pixel centres. The
    grid is then sampled at flight time as any DEM (``sampling``).

    Raises :class:`ScenarioError` (key ``key``) for a file that is not a raster, has no CRS,
    does not cover the site box, or has no data under it (unless ``nodata_fill``, an elevation
    in metres above mean sea level, is given)."""
    import rasterio  # heavy import, only for this kind of ground
    import rasterio.windows
    from rasterio.enums import Resampling
    from rasterio.errors import RasterioIOError

    from staghunt.world.georef import site_to_crs

    if not path.is_file():
        raise ScenarioError(f"no such DEM file {str(path)!r}", key)
    lo, hi = ELEVATION_RANGE
    if nodata_fill is not None and not lo <= nodata_fill <= hi:
        raise ScenarioError(f"must be an elevation in [{_fmt(lo)}, {_fmt(hi)}] m above mean sea level, "
                            f"got {_fmt(nodata_fill)}", "ground.nodata_fill")
    rows, cols = grid_size(b, cell_size)
    xs = b.xmin + cell_size * np.arange(cols)
    ys = b.ymin + cell_size * np.arange(rows)
    gx, gy = np.meshgrid(xs, ys)  # (rows, cols)
    try:
        # A small block cache: a decimated read passes every tile of the window through it.
        with rasterio.Env(GDAL_CACHEMAX=64), rasterio.open(path) as src:
            if src.crs is None:
                raise ScenarioError(
                    f"the DEM {str(path)!r} has no CRS (coordinate reference system); "
                    "use ground.kind = 'dem' for a grid already in site coordinates", key)
            crs = src.crs.to_wkt()
            inverse = ~src.transform
            height, width = src.height, src.width
            X, Y = site_to_crs(origin, crs, gx, gy)
            X, Y = np.asarray(X), np.asarray(Y)
            u = inverse.a * X + inverse.b * Y + inverse.c - 0.5  # fractional pixel-centre indices
            v = inverse.d * X + inverse.e * Y + inverse.f - 0.5
            outside = ~((u >= -1e-9) & (u <= width - 1 + 1e-9) & (v >= -1e-9) & (v <= height - 1 + 1e-9))
            if outside.any():
                i, j = np.argwhere(outside)[0]
                raise ScenarioError(
                    f"the DEM {str(path)!r} ({width} x {height} pixels) does not cover the site box "
                    f"x [{_fmt(b.xmin)}, {_fmt(b.xmax)}], y [{_fmt(b.ymin)}, {_fmt(b.ymax)}] around the "
                    f"origin ({_fmt(origin.latitude)}, {_fmt(origin.longitude)}): site point "
                    f"x={_fmt(gx[i, j])}, y={_fmt(gy[i, j])} lies outside it", key)
            # Read only the window of pixels the site needs (a DEM may be far larger than the site),
            # and no finer than about two pixels per grid cell: GDAL averages (or uses an overview)
            # rather than handing over every pixel of a fine DEM.
            pixels_per_metre = max(math.hypot(inverse.a, inverse.d), math.hypot(inverse.b, inverse.e)) * _crs_units_per_metre(
                X, Y, gx, gy)
            factor = pixels_per_metre * cell_size / 2.0  # > 1: more than two pixels per grid cell
            pad = 1 + (int(math.ceil(factor)) if factor > 1.5 else 0)  # a (decimated) pixel beyond the nodes
            c0 = max(int(math.floor(u.min())) - pad, 0)
            r0 = max(int(math.floor(v.min())) - pad, 0)
            c1 = min(int(math.ceil(u.max())) + pad + 1, width)
            r1 = min(int(math.ceil(v.max())) + pad + 1, height)
            win_w, win_h = c1 - c0, r1 - r0
            window = rasterio.windows.Window(c0, r0, win_w, win_h)
            u = u - c0
            v = v - r0
            if factor > 1.5:
                out_w, out_h = max(2, int(math.ceil(win_w / factor))), max(2, int(math.ceil(win_h / factor)))
                values = src.read(1, window=window, masked=True, out_shape=(out_h, out_w),
                                  resampling=Resampling.average)
                u = (u + 0.5) * out_w / win_w - 0.5
                v = (v + 0.5) * out_h / win_h - 0.5
            else:
                values = src.read(1, window=window, masked=True)
    except ScenarioError:
        raise
    except RasterioIOError as exc:
        raise ScenarioError(f"cannot read {str(path)!r} as a raster: {exc}", key) from None
    except Exception as exc:  # noqa: BLE001 - any other reader failure is bad input too
        raise ScenarioError(f"cannot read {str(path)!r} as a raster: {exc}", key) from None
    grid_values = np.asarray(np.ma.getdata(values), dtype=np.float64)
    missing = np.ma.getmaskarray(values) | ~np.isfinite(grid_values)
    height, width = grid_values.shape
    u = np.clip(u, 0.0, width - 1.0)
    v = np.clip(v, 0.0, height - 1.0)
    j0 = np.minimum(np.floor(u).astype(np.intp), max(width - 2, 0))
    i0 = np.minimum(np.floor(v).astype(np.intp), max(height - 2, 0))
    j1 = np.minimum(j0 + 1, width - 1)
    i1 = np.minimum(i0 + 1, height - 1)
    fu = u - j0
    fv = v - i0
    hole = missing[i0, j0] | missing[i0, j1] | missing[i1, j0] | missing[i1, j1]
    if hole.any():
        if nodata_fill is None:
            i, j = np.argwhere(hole)[0]
            raise ScenarioError(
                f"the DEM {str(path)!r} has no data under the site at x={_fmt(gx[i, j])}, "
                f"y={_fmt(gy[i, j])}, where paths may fly ({int(hole.sum())} grid nodes); "
                "give ground.nodata_fill or a DEM without holes there", key)
        grid_values = np.where(missing, float(nodata_fill), grid_values)
    g = grid_values
    used = np.stack([g[i0, j0], g[i0, j1], g[i1, j0], g[i1, j1]])
    bad = ~((used >= lo) & (used <= hi)).all(axis=0)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        worst = used[:, i, j][np.argmax(np.abs(used[:, i, j] - 0.5 * (lo + hi)))]
        raise ScenarioError(
            f"the DEM {str(path)!r} holds an elevation of {float(worst):.6g} m near site x={_fmt(gx[i, j])}, "
            f"y={_fmt(gy[i, j])}; elevations must lie in [{_fmt(lo)}, {_fmt(hi)}] m above mean sea level "
            "(wrong units, or a nodata value the file does not declare?)", key)
    top = g[i0, j0] * (1 - fu) + g[i0, j1] * fu
    bottom = g[i1, j0] * (1 - fu) + g[i1, j1] * fu
    z = top * (1 - fv) + bottom * fv - origin.altitude
    z = np.ascontiguousarray(z, dtype=np.float64)
    z.setflags(write=False)
    return Terrain(elevation=z, origin=(float(b.xmin), float(b.ymin)), cell_size=float(cell_size),
                   sampling=sampling,  # type: ignore[arg-type]
                   source=str(path), georef={"kind": "geotiff", "nodata_fill": nodata_fill})


def _crs_units_per_metre(X: np.ndarray, Y: np.ndarray, gx: np.ndarray, gy: np.ndarray) -> float:
    """CRS units per site metre, from the grid's extent in both (about 1 for a projected CRS in
    metres, about 1 / 111,000 for one in degrees)."""
    site = math.hypot(float(gx.max() - gx.min()), float(gy.max() - gy.min()))
    crs = math.hypot(float(np.ptp(X)), float(np.ptp(Y)))
    return crs / site if site > 0 and crs > 0 else 1.0
