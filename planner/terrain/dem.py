# Over 600 lines, knowingly: reading, mosaicking, void filling and the warp are one
# pipeline over one private model of a source grid (`_Grid`); apart, each step would
# hand that private type across modules.
"""DEM loading: GeoTIFF (any CRS), SRTM ``.hgt`` tiles and the built-in sample,
mosaicked, cropped, void-filled and reprojected to a `Terrain` in local UTM.

The pipeline, the same for every input:

1. Each file is read (only the window covering ``area`` plus a small margin),
   nodata becomes NaN, the band's scale and offset are applied, heights in feet
   become metres (the unit the band or the CRS's vertical axis gives, or
   ``z_unit``) and ellipsoidal heights are shifted to AMSL.
2. Files on the same source grid (adjacent SRTM tiles, tiles of one GeoTIFF
   set) are placed into one array, so voids and seams across tile edges are
   handled as if the tiles were one file.
3. Small voids are filled (see `fill_small_voids`); large ones stay NaN.
4. Each group is warped onto one square north-up UTM grid and the groups are
   combined, the first file given winning where they overlap. The warp is our
   own: every working-grid centre is transformed exactly (pyproj) into the
   source grid and interpolated bilinearly between source centres. GDAL's
   warper (rasterio.warp.reproject) was measured here to be off by ~0.08 source
   pixels even at zero tolerance: 0.25 m on a 3 m/pixel slope, metres on steep
   ground, too much for a hiding margin of 10 m.
"""

import re
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import rasterio
from affine import Affine
from pyproj import CRS, Proj, Transformer
from rasterio.crs import CRS as RioCRS
from rasterio.errors import NotGeoreferencedWarning, RasterioIOError
from rasterio.warp import transform_bounds
from rasterio.windows import Window, from_bounds
from scipy import ndimage, sparse
from scipy.sparse.linalg import spsolve

from common.errors import InputError
from common.units import Z_UNIT_WORDS, Z_UNITS, z_unit_of, z_unit_of_factor

from . import dem_kernels
from .grid import Terrain, bilinear

MAX_FILLED_VOID_CELLS = 64  # a void component up to this many source cells is interpolated
#: over a filled void the terrain that hides is lowered, and the ground for clearance
#: raised, by this much (m): Laplace interpolation over up to 64 cells of steep
#: ground (where radar DEMs have their voids) misses the relief by metres to tens of
#: metres, and neither a ridge that hides nor a knoll that rises may be taken on trust
VOID_FILL_MARGIN_M = 20.0
AREA_MARGIN_CELLS = 8  # source cells read beyond --area, for interpolation at its edge
MAX_GRID_CELLS = 64_000_000  # refuse working grids larger than this (8000 x 8000)
WARP_CHUNK_CELLS = 1 << 20  # working-grid cells transformed at once (bounds memory)
HGT_VOID = -32768
HGT_SIZES = {1201 * 1201 * 2: 1201, 3601 * 3601 * 2: 3601}
SAMPLE_NAME = "jacksboro_fault_dem.npz"
WGS84 = RioCRS.from_epsg(4326)


@dataclass
class _Grid:
    """Heights on a source grid: float64, NaN = nodata; ``covered`` marks the
    footprint of the files (NaN inside it is a void, outside it is no data)."""

    height: np.ndarray
    transform: Affine
    crs: RioCRS  # horizontal CRS
    source: str
    covered: np.ndarray = None
    z_unit: dict = None  # the heights' unit, when said (`_to_metres`)

    def __post_init__(self):
        if self.covered is None:
            self.covered = np.ones(self.height.shape, bool)


# --- public API --------------------------------------------------------------------------


def load_dem(paths, area=None, resolution=None, geoid_offset=None, z_unit=None) -> Terrain:
    """Load DEM files and return them as one `Terrain` in the local UTM zone.

    ``paths``: GeoTIFFs (any CRS GDAL reads) and/or SRTM ``.hgt`` tiles.
    ``area``: (south, west, north, east) degrees; files are read only there.
    ``resolution``: working grid spacing in metres (default: the DEM's own
    spacing at its centre, mean of x and y).
    ``geoid_offset``: N = ellipsoid height - geoid height in metres; heights of
    a DEM that is not known to be AMSL are shifted to ``h - N``. Required for a
    DEM whose CRS says its heights are ellipsoidal.
    ``z_unit``: the unit of every file's heights ("m", "ft" or "us-ft",
    `common.units.Z_UNITS`), whatever the files say; by default each file's
    band unit or its CRS's vertical axis says it (metres when neither does).
    Heights in feet are converted to metres with a warning naming the file and
    the unit; a unit that is no length of those is refused.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    paths = [Path(p) for p in paths]
    if not paths:
        raise InputError("--dem", "no DEM file given")
    area = _check_area(area)
    names = ", ".join(str(p) for p in paths)
    if z_unit is not None and z_unit not in Z_UNITS:
        raise InputError("--z-unit", f"must be one of {', '.join(Z_UNITS)}, got {z_unit!r}")
    grids = [g for g in (_read_file(p, area, geoid_offset, z_unit) for p in paths)
             if g is not None]
    if not grids:
        raise InputError(names, f"area {_fmt_area(area)} does not overlap the DEM "
                                "(or holds only nodata there)")
    return _to_terrain(grids, area, resolution, names)


def sample_terrain(resolution=None, area=None) -> Terrain:
    """The USGS DEM that matplotlib ships (Jacksboro fault, Tennessee), in UTM 16N.

    The npz holds ``elevation`` (344 x 403, metres) on a 3 arc-second
    geographic grid with cell *edges* ``xmin``/``xmax`` and, despite their
    names, ``ymin`` = 36.733 (north edge) and ``ymax`` = 36.446 (south edge).
    Row 0 is the north edge: matplotlib's own 3-D example maps row 0 to
    ``ymin``, and only this way round does the Pine Mountain ridge, which
    leaves the Jacksboro fault line, strike NE-SW like every Appalachian fold
    (flipped it would strike NW-SE); tests/test_dem.py checks that strike.
    """
    from matplotlib import cbook

    with cbook.get_sample_data(SAMPLE_NAME) as dem:
        height = dem["elevation"].astype(np.float64)
        west, north = float(dem["xmin"]), float(max(dem["ymin"], dem["ymax"]))
        dx, dy = float(dem["dx"]), float(dem["dy"])
    transform = Affine(dx, 0.0, west, 0.0, -dy, north)
    source = f"matplotlib sample {SAMPLE_NAME}"
    area = _check_area(area)
    window = _area_window(WGS84, transform, height.shape, area)
    if window is None:
        raise InputError(source, f"area {_fmt_area(area)} does not overlap the sample terrain")
    rows, cols = window.toslices()
    grid = _Grid(height[rows, cols], _window_transform(transform, window), WGS84, source)
    return _to_terrain([grid], area, resolution, source)


def utm_crs(lon: float, lat: float) -> str:
    """The WGS 84 / UTM zone of (lon, lat) as "EPSG:326zz" (north) or "EPSG:327zz"."""
    zone = int(np.floor((lon + 180.0) / 6.0)) % 60 + 1
    return f"EPSG:{(32600 if lat >= 0 else 32700) + zone}"


def fill_small_voids(height: np.ndarray, covered=None, max_cells=MAX_FILLED_VOID_CELLS):
    """Fill small voids in place by harmonic (Laplace) interpolation from their rim.

    A void is a connected (8-neighbour) component of NaN cells inside ``covered``.
    It is filled when it has at most ``max_cells`` cells and does not touch the
    array border or uncovered cells (its true extent is unknown there). All
    filled voids are solved together as one sparse linear system: each filled
    cell is the mean of its 4 neighbours, known cells being fixed.
    Returns (number of filled voids, filled cells, number of voids left, bool mask
    of the filled cells).
    """
    covered = np.ones(height.shape, bool) if covered is None else covered
    void = np.isnan(height) & covered
    labels, n = ndimage.label(void, structure=np.ones((3, 3), int))
    if n == 0:
        return 0, 0, 0, np.zeros(height.shape, bool)
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    open_edge = ~covered
    open_edge[[0, -1], :] = True
    open_edge[:, [0, -1]] = True
    touching = np.unique(labels[ndimage.binary_dilation(open_edge, np.ones((3, 3), bool)) & void])
    fillable = sizes <= max_cells
    fillable[0] = False
    fillable[touching] = False
    fill = fillable[labels]
    if fill.any():
        height[fill] = _laplace_solve(height, fill)
    n_filled = int(fillable.sum())
    return n_filled, int(fill.sum()), n - n_filled, fill


# --- reading files -------------------------------------------------------------------------


def _read_file(path: Path, area, geoid_offset, z_unit=None):
    if not path.exists():
        raise InputError(path, "no such file")
    if path.is_dir():
        raise InputError(path, "is a folder, not a DEM file")
    if path.suffix.lower() == ".hgt":
        grid = _read_hgt(path, area)
        vertical, said = "orthometric", []  # SRTM heights are EGM96 geoid metres
    else:
        grid, vertical, said = _read_raster(path, area)
    if grid is None:
        return None
    _to_metres(grid, path, said, z_unit)
    if vertical == "ellipsoidal" and geoid_offset is None:
        raise InputError(path, "heights are ellipsoidal (its CRS says so); give --geoid-offset N "
                               "(ellipsoid minus geoid height, m) to convert them to AMSL")
    if geoid_offset is not None:
        if vertical == "orthometric":
            warnings.warn(f"{path}: heights are already AMSL; --geoid-offset ignored for it",
                          stacklevel=3)
        else:
            grid.height -= float(geoid_offset)
    return grid


def _read_hgt(path: Path, area):
    """An SRTM tile: n x n big-endian int16, pixel-is-point, samples on whole degrees."""
    size = path.stat().st_size
    if size not in HGT_SIZES:
        raise InputError(path, f"unknown .hgt size ({size} bytes): expected 1201 x 1201 "
                               "(3\") or 3601 x 3601 (1\") 16-bit samples")
    match = re.match(r"([NS])(\d{2})([EW])(\d{3})", path.name.upper())
    if not match:
        raise InputError(path, "cannot tell the tile's south-west corner from its name "
                               "(expected e.g. N36W085.hgt)")
    lat = int(match[2]) * (1 if match[1] == "N" else -1)
    lon = int(match[4]) * (1 if match[3] == "E" else -1)
    n = HGT_SIZES[size]
    d = 1.0 / (n - 1)
    # The first row/col centres lie on lat + 1 / lon: the area grid starts half a cell out.
    transform = Affine(d, 0.0, lon - d / 2, 0.0, -d, lat + 1 + d / 2)
    window = _area_window(WGS84, transform, (n, n), area)
    if window is None:
        return None
    samples = np.memmap(path, dtype=">i2", mode="r", shape=(n, n))
    rows, cols = window.toslices()
    block = np.asarray(samples[rows, cols])
    height = np.where(block == HGT_VOID, np.nan, block.astype(np.float64))
    grid = _Grid(height, _window_transform(transform, window), WGS84, str(path))
    return _check_not_empty(grid, area)


def _read_raster(path: Path, area):
    """Any raster GDAL reads; returns (grid or None, vertical datum kind, what the
    file says of its heights' unit: [(who says it, the unit's name, metres per unit
    or None)]). The band's scale and offset are applied, as GDAL defines them."""
    try:
        with warnings.catch_warnings():  # a missing CRS is reported below, as an error
            warnings.simplefilter("ignore", NotGeoreferencedWarning)
            ds = rasterio.open(path)
    except RasterioIOError:
        raise InputError(path, "not a raster GDAL can read") from None
    with ds:
        if ds.crs is None:
            raise InputError(path, "raster has no CRS (georeference it, e.g. gdal_edit.py "
                                   "-a_srs EPSG:4326)")
        if ds.count < 1:
            raise InputError(path, "raster has no bands")
        crs, vertical, said = _horizontal_crs(ds.crs, path)
        if ds.units and ds.units[0]:
            said.insert(0, (f"band unit {ds.units[0]!r}", ds.units[0], None))
        if ds.transform.b or ds.transform.d:  # rotated grid: read it all, the warp crops
            window = Window(0, 0, ds.width, ds.height)
        else:
            window = _area_window(crs, ds.transform, ds.shape, area)
            if window is None:
                return None, vertical, said
        data = ds.read(1, window=window, masked=True, out_dtype="float64")
        height = np.ma.filled(data, np.nan)
        scale, offset = ds.scales[0], ds.offsets[0]
        if (scale, offset) != (1.0, 0.0):  # GDAL's value = raw * scale + offset
            height = height * scale + offset
        height[~np.isfinite(height)] = np.nan
        transform = _window_transform(ds.transform, window)
    return _check_not_empty(_Grid(height, transform, crs, str(path)), area), vertical, said


def _to_metres(grid: _Grid, path, said, z_unit) -> None:
    """Convert ``grid``'s heights to metres, in place: in ``z_unit`` if given, else in
    the unit the file says (``said``: `_read_raster`'s), metres if it says none.
    Warns naming the file and the unit whenever heights are not taken as metres or
    ``z_unit`` overrides what the file says; InputError for a unit that is none of
    `Z_UNITS` or for a band and a CRS that disagree."""
    units = []
    for who, name, factor in said:
        unit = z_unit_of(name) if factor is None else z_unit_of_factor(factor)
        if unit is None and z_unit is None:
            raise InputError(path, f"heights in an unknown unit: {who} is not metres, feet or "
                                   "US survey feet (give --z-unit m, ft or us-ft if they are "
                                   "one of these)")
        units.append((who, unit))
    known = {u for _, u in units if u is not None}
    if z_unit is None and len(known) > 1:
        raise InputError(path, f"{' but '.join(who for who, _ in units)}: which unit are the "
                               "heights in? Give --z-unit m, ft or us-ft")
    unit = z_unit or (known.pop() if known else "m")
    says = "; ".join(f"{who}" for who, u in units if u != unit)
    if unit == "m" and not says:
        return
    by = "--z-unit " + z_unit if z_unit else units[-1][0]  # the CRS's, where both agree
    text = f"heights taken as {Z_UNIT_WORDS[unit]} ({by})"
    if unit != "m":
        grid.height *= Z_UNITS[unit]
        text += f" and converted to metres (x {Z_UNITS[unit]:.10g})"
    if says:
        text += f", although the file says otherwise ({says})"
    grid.z_unit = {"file": str(path), "unit": unit, "metres_per_unit": Z_UNITS[unit],
                   "said_by": by}
    warnings.warn(f"{path}: {text}", stacklevel=4)


def _horizontal_crs(crs: RioCRS, path=None):
    """(2-D CRS for warping, "ellipsoidal" | "orthometric" | "unknown" heights, what
    its vertical axis says of the heights' unit: [] or [(who, unit name, metres per
    unit)]). InputError for a vertical axis pointing down (depths)."""
    full = CRS.from_wkt(crs.to_wkt())
    said = []
    for axis in full.axis_info:
        if axis.direction in ("up", "down"):
            vertical_crs = full.sub_crs_list[-1] if full.is_compound else full
            if axis.direction == "down":
                raise InputError(path, f"its CRS's vertical axis ({vertical_crs.name}) is "
                                       "a depth, positive down: heights are needed")
            said = [(f"vertical CRS {vertical_crs.name!r} in {axis.unit_name}",
                     axis.unit_name, axis.unit_conversion_factor)]
            break
    axes = [a.name.lower() for c in [full, *full.sub_crs_list] for a in c.axis_info]
    if "ellipsoidal height" in axes:
        vertical = "ellipsoidal"
    elif "gravity-related height" in axes:
        vertical = "orthometric"
    else:
        vertical = "unknown"
    if len(full.axis_info) > 2 or full.is_compound:
        return RioCRS.from_wkt(full.to_2d().to_wkt()), vertical, said
    return crs, vertical, said


def _check_not_empty(grid: _Grid, area):
    if np.isfinite(grid.height).any():
        return grid
    if area is None:
        raise InputError(grid.source, "every cell is nodata")
    return None  # no data inside the area: another tile may have some


def _transform_bounds(src, dst, bounds):
    """(left, bottom, right, top) in ``dst``, or None where ``dst`` cannot hold them."""
    try:
        out = transform_bounds(src, dst, *bounds, densify_pts=21)
    except Exception:  # noqa: BLE001 - PROJ refuses points far outside a projection
        return None
    return out if np.all(np.isfinite(out)) else None


def _window_transform(transform: Affine, window: Window) -> Affine:
    return transform @ Affine.translation(window.col_off, window.row_off)


def _area_window(crs, transform, shape, area):
    """Pixel window of ``area`` (+ margin) in a raster, or None if they do not overlap.
    Without an area: the whole raster."""
    full = Window(0, 0, shape[1], shape[0])
    if area is None:
        return full
    south, west, north, east = area
    bounds = _transform_bounds(WGS84, crs, (west, south, east, north))
    if bounds is None:
        return None
    win = from_bounds(*bounds, transform=transform)
    m = AREA_MARGIN_CELLS
    col0, row0 = np.floor(win.col_off) - m, np.floor(win.row_off) - m
    col1 = np.ceil(win.col_off + win.width) + m
    row1 = np.ceil(win.row_off + win.height) + m
    col0, row0 = max(col0, 0), max(row0, 0)
    col1, row1 = min(col1, shape[1]), min(row1, shape[0])
    if col1 <= col0 or row1 <= row0:
        return None
    return Window(int(col0), int(row0), int(col1 - col0), int(row1 - row0))


# --- mosaic, voids, reprojection -------------------------------------------------------------


def _to_terrain(grids, area, resolution, source: str) -> Terrain:
    groups = [_merge(g) for g in _group_by_grid(grids)]
    filled = [fill_small_voids(g.height, g.covered) for g in groups]
    meta = {"filled_voids": sum(f[0] for f in filled),
            "filled_cells": sum(f[1] for f in filled),
            "unfilled_voids": sum(f[2] for f in filled),
            "sources": [g.source for g in grids],
            "z_units": [g.z_unit for g in grids if g.z_unit]}
    terrain = _working_terrain(groups, area, resolution, source, meta)
    if meta["filled_voids"]:
        terrain = _mark_filled(terrain, groups, [f[3] for f in filled])
        warnings.warn(f"{source}: {filled_voids_text(terrain)}", stacklevel=3)
    return terrain


def filled_voids_text(terrain) -> str:
    """What was filled and where, in one line (`Terrain.meta`'s ``filled_at``)."""
    m = terrain.meta
    at = m.get("filled_at", [])
    where = ", ".join(f"{v['lat']:.5f},{v['lon']:.5f} ({v['cells']} cells)" for v in at[:5])
    more = f" and {len(at) - 5} more" if len(at) > 5 else ""
    return (f"filled {m['filled_voids']} small void(s) ({m['filled_cells']} source cells) by "
            f"interpolation at {where}{more}: there the terrain that hides is lowered and the "
            f"ground for clearance raised by {VOID_FILL_MARGIN_M:g} m; "
            f"{m['unfilled_voids']} larger void(s) left as no data (not flyable, not targets)")


def _mark_filled(terrain, groups, fills) -> Terrain:
    """``terrain`` with the working cells whose surface depends on a filled source
    cell (the patches around it) in ``meta["filled_mask"]``, with the voids'
    places (``filled_at``), and `VOID_FILL_MARGIN_M` taken off the terrain that
    hides and added to the ground for clearance there: the interpolation guesses
    at ground nobody measured."""
    mask = np.zeros(terrain.shape, bool)
    places = []
    for g, fill in zip(groups, fills):
        if not fill.any():
            continue
        to_work = Transformer.from_crs(CRS.from_wkt(g.crs.to_wkt()), terrain.crs, always_xy=True)
        rows, cols = np.nonzero(fill)
        x, y = to_work.transform(*(g.transform * (cols + 0.5, rows + 0.5)))
        wr, wc = terrain.rowcol(np.asarray(x), np.asarray(y))
        # a source cell reaches as far as its own size into the working surface
        x1, y1 = to_work.transform(*(g.transform * (cols[:1] + 1.5, rows[:1] + 1.5)))
        reach = int(np.ceil(np.hypot(x1[0] - x[0], y1[0] - y[0]) / terrain.cell_size)) + 1
        r, c = np.rint(wr).astype(int), np.rint(wc).astype(int)
        ok = (r >= 0) & (c >= 0) & (r < terrain.shape[0]) & (c < terrain.shape[1])
        here = np.zeros(terrain.shape, bool)
        here[r[ok], c[ok]] = True
        mask |= ndimage.binary_dilation(here, np.ones((3, 3), bool), iterations=reach)
        labels, n = ndimage.label(fill, structure=np.ones((3, 3), int))
        for k, where in enumerate(ndimage.find_objects(labels), start=1):
            rr, cc = np.nonzero(labels[where] == k)
            cx, cy = g.transform * (cc.mean() + where[1].start + 0.5,
                                    rr.mean() + where[0].start + 0.5)
            lon, lat = Transformer.from_crs(CRS.from_wkt(g.crs.to_wkt()), WGS84,
                                            always_xy=True).transform(cx, cy)
            places.append({"lat": float(lat), "lon": float(lon), "cells": int(len(rr))})
    lower, upper = terrain.height.copy(), terrain.upper.copy()
    lower[mask] -= VOID_FILL_MARGIN_M
    upper[mask] += VOID_FILL_MARGIN_M
    return replace(terrain, height=lower, height_upper=upper,
                   meta={**terrain.meta, "filled_mask": mask, "filled_at": places})


def _working_terrain(groups, area, resolution, source, meta) -> Terrain:
    own = _own_lattice(groups, area, resolution)
    if own is not None:
        height, transform, crs = own
        height, transform = _trim(height, transform)
        if height is None:
            raise InputError(source, "no DEM data inside the area")
        return Terrain(height, transform, crs, source=source,
                       meta={**meta, "resampled": False})
    crs, transform, shape = _target_grid(groups, area, resolution, source)
    lower = np.full(shape, np.nan)
    upper = np.full(shape, np.nan)
    for g in groups:  # the first file wins where files overlap
        g_lower, g_upper = _warp(g, crs, transform, shape)
        empty = np.isnan(lower) & np.isnan(upper)
        np.copyto(lower, g_lower, where=empty)
        np.copyto(upper, g_upper, where=empty)
    (lower, upper), transform = _trim_all((lower, upper), transform)
    if lower is None:
        raise InputError(source, "no DEM data inside the area")
    both = np.isfinite(lower) & np.isfinite(upper)
    band = upper[both] - lower[both]
    meta.update(resampled=True,
                envelope_mean_m=float(band.mean()) if band.size else 0.0,
                envelope_max_m=float(band.max()) if band.size else 0.0)
    return Terrain(lower, transform, crs, source=source, meta=meta, height_upper=upper,
                   source_surface=SourceSurface(tuple(groups), crs))


@dataclass(frozen=True, eq=False)
class SourceSurface:
    """The source DEM's own bilinear surface at working-grid points (the first file
    wins where files overlap): exact ground for points that need it, such as the
    outposts' eyes (a working grid's surface only brackets it)."""

    groups: tuple  # of _Grid
    crs: str  # the working grid's CRS

    def ground(self, x, y) -> np.ndarray:
        x, y = np.asarray(x, float), np.asarray(y, float)
        out = np.full(x.shape, np.nan)
        for g in self.groups:
            to_source = Transformer.from_crs(self.crs, CRS.from_wkt(g.crs.to_wkt()),
                                             always_xy=True)
            u, v = ~g.transform @ to_source.transform(x, y)
            np.copyto(out, bilinear(g.height, v - 0.5, u - 0.5), where=np.isnan(out))
        return out


def _own_lattice(groups, area, resolution):
    """(heights, transform, CRS) of the source grid itself, cropped to the area,
    when it can be the working grid: one lattice, north up with square cells in
    metres of a projected CRS whose scale is that of the ground (UTM and the
    like, not Web Mercator), at the working resolution. None otherwise."""
    if len(groups) != 1:
        return None
    g = groups[0]
    t = g.transform
    if t.b or t.d or not (t.a > 0 > t.e) or abs(t.a + t.e) > 1e-9 * t.a:
        return None
    if resolution is not None and abs(float(resolution) - t.a) > 1e-6 * t.a:
        return None
    crs = CRS.from_wkt(g.crs.to_wkt())
    if not crs.is_projected or crs.axis_info[0].unit_name not in ("metre", "meter"):
        return None
    if not _true_scale(crs, g):
        return None
    height = g.height
    if area is not None:
        bounds = _transform_bounds(WGS84, g.crs, (area[1], area[0], area[3], area[2]))
        if bounds is None:
            return None
        # cells whose centres lie within the area grown by a cell
        c0, r0 = ~t @ (bounds[0] - t.a, bounds[3] + t.a)
        c1, r1 = ~t @ (bounds[2] + t.a, bounds[1] - t.a)
        r0, c0 = max(int(np.ceil(r0 - 0.5)), 0), max(int(np.ceil(c0 - 0.5)), 0)
        r1 = min(int(np.floor(r1 - 0.5)) + 1, height.shape[0])
        c1 = min(int(np.floor(c1 - 0.5)) + 1, height.shape[1])
        if r1 <= r0 or c1 <= c0:
            return None
        height = height[r0:r1, c0:c1]
        t = t @ Affine.translation(c0, r0)
    epsg = crs.to_epsg()
    return np.array(height, np.float64), t, f"EPSG:{epsg}" if epsg else crs.to_wkt()


def _true_scale(crs, g: _Grid) -> bool:
    """Whether the projection's scale at the grid's centre is within 0.15 % of 1
    (the most UTM departs from it), so that its metres are metres on the ground."""
    n_rows, n_cols = g.height.shape
    x, y = g.transform @ (n_cols / 2, n_rows / 2)
    lon, lat = Transformer.from_crs(crs, "EPSG:4326", always_xy=True).transform(x, y)
    try:
        factors = Proj(crs).get_factors(lon, lat)
    except Exception:  # noqa: BLE001 - PROJ cannot tell: do not trust the metres
        return False
    scales = (factors.meridional_scale, factors.parallel_scale)
    return all(np.isfinite(k) and abs(k - 1.0) <= 1.5e-3 for k in scales)


def _warp(g: _Grid, crs: str, transform: Affine, shape):
    """(lower, upper): ``g``'s bilinear surface sampled at the working-grid cell
    centres (exact coordinates, pyproj), lowered and raised by what the working
    grid's own bilinear surface departs from it over the patches around each
    centre (`dem_kernels.resampling_error`), so that the working surfaces of
    ``lower`` and ``upper`` bracket the source surface everywhere. NaN where a
    patch around the centre leaves the source footprint or touches a void."""
    to_source = Transformer.from_crs(crs, CRS.from_wkt(g.crs.to_wkt()), always_xy=True)
    to_pixel = ~g.transform
    n_rows, n_cols = shape
    src_rows, src_cols = g.height.shape
    row = np.empty(shape)
    col = np.empty(shape)
    step = max(WARP_CHUNK_CELLS // n_cols, 1)
    cols = np.arange(n_cols) + 0.5
    for r0 in range(0, n_rows, step):  # chunks of rows bound the memory pyproj uses
        rows = np.arange(r0, min(r0 + step, n_rows))[:, None] + 0.5
        x, y = transform @ (cols[None, :], rows)
        u, v = to_pixel @ to_source.transform(x, y)  # pixel edges: centres at k + 0.5
        row[r0:r0 + len(rows)], col[r0:r0 + len(rows)] = v - 0.5, u - 0.5
    inside = (row >= 0) & (row <= src_rows - 1) & (col >= 0) & (col <= src_cols - 1)
    value = np.where(inside, bilinear(g.height, row, col), np.nan)
    # contiguous, as every grid the kernel sees: one compiled variant, not one per layout
    above, below = dem_kernels.resampling_error(np.ascontiguousarray(g.height), row, col, value)
    return value - _around_vertices(above), value + _around_vertices(below)


def _around_vertices(patch):
    """Per cell centre: the largest value over the (up to four) patches around it;
    NaN if any of them is NaN or it has none."""
    n_rows, n_cols = patch.shape[0] + 1, patch.shape[1] + 1
    out = np.full((n_rows, n_cols), -np.inf)  # stays -inf where no patch is around
    void = np.zeros((n_rows, n_cols), bool)
    nan = np.isnan(patch)
    for dr in (0, 1):
        for dc in (0, 1):
            window = (slice(dr, dr + patch.shape[0]), slice(dc, dc + patch.shape[1]))
            np.fmax(out[window], patch, out=out[window])
            void[window] |= nan
    out[void | np.isinf(out)] = np.nan
    return out


def _group_by_grid(grids):
    """Group grids sharing a CRS, pixel size and pixel alignment (e.g. adjacent tiles)."""
    groups = []
    for g in grids:
        for group in groups:
            if _same_lattice(group[0], g):
                group.append(g)
                break
        else:
            groups.append([g])
    return groups


def _same_lattice(a: _Grid, b: _Grid) -> bool:
    ta, tb = a.transform, b.transform
    if ta.b or ta.d or tb.b or tb.d or a.crs != b.crs:
        return False
    if not (np.isclose(ta.a, tb.a, rtol=1e-9) and np.isclose(ta.e, tb.e, rtol=1e-9)):
        return False
    off = np.array([(tb.c - ta.c) / ta.a, (tb.f - ta.f) / ta.e])
    return bool(np.all(np.abs(off - np.round(off)) < 1e-6))


def _merge(group) -> _Grid:
    """Place grids of one lattice in one array; the first grid wins where they overlap."""
    if len(group) == 1:
        return group[0]
    ref = group[0].transform
    offsets = [(round((g.transform.f - ref.f) / ref.e), round((g.transform.c - ref.c) / ref.a))
               for g in group]
    r0 = min(r for r, _ in offsets)
    c0 = min(c for _, c in offsets)
    r1 = max(r + g.height.shape[0] for (r, _), g in zip(offsets, group))
    c1 = max(c + g.height.shape[1] for (_, c), g in zip(offsets, group))
    height = np.full((r1 - r0, c1 - c0), np.nan)
    covered = np.zeros(height.shape, bool)
    for (r, c), g in zip(offsets, group):
        rows = slice(r - r0, r - r0 + g.height.shape[0])
        cols = slice(c - c0, c - c0 + g.height.shape[1])
        np.copyto(height[rows, cols], g.height, where=np.isnan(height[rows, cols]))
        covered[rows, cols] |= g.covered
    transform = ref @ Affine.translation(c0, r0)
    return _Grid(height, transform, group[0].crs, ", ".join(g.source for g in group), covered)


def _laplace_solve(height, fill):
    """Values for the ``fill`` cells that make each the mean of its 4 neighbours."""
    n_rows, n_cols = height.shape
    idx = np.full(height.shape, -1)
    idx[fill] = np.arange(fill.sum())
    rows, cols = np.nonzero(fill)
    diag = np.zeros(len(rows))
    rhs = np.zeros(len(rows))
    i_list, j_list = [], []
    for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        r, c = rows + dr, cols + dc
        inside = (r >= 0) & (r < n_rows) & (c >= 0) & (c < n_cols)
        r, c = np.clip(r, 0, n_rows - 1), np.clip(c, 0, n_cols - 1)
        neighbour = np.where(inside, idx[r, c], -1)
        known = inside & (neighbour < 0) & np.isfinite(height[r, c])
        unknown = inside & (neighbour >= 0)
        diag += known | unknown
        rhs += np.where(known, height[r, c], 0.0)
        i_list.append(np.nonzero(unknown)[0])
        j_list.append(neighbour[unknown])
    i = np.concatenate(i_list)
    j = np.concatenate(j_list)
    n = len(rows)
    a = sparse.csr_matrix((np.r_[diag, -np.ones(len(i))], (np.r_[np.arange(n), i],
                                                          np.r_[np.arange(n), j])), shape=(n, n))
    return spsolve(a.tocsc(), rhs)


def _target_grid(groups, area, resolution, source):
    """(UTM CRS, transform, shape) of the square north-up working grid."""
    if area is not None:
        lon, lat = (area[1] + area[3]) / 2, (area[0] + area[2]) / 2
    else:
        geo = np.array([transform_bounds(g.crs, WGS84, *_bounds(g), densify_pts=21)
                        for g in groups])
        lon = (geo[:, 0].min() + geo[:, 2].max()) / 2
        lat = (geo[:, 1].min() + geo[:, 3].max()) / 2
    crs = utm_crs(lon, lat)
    if resolution is None:
        resolution = min(_spacing_m(g, crs) for g in groups)
    resolution = float(resolution)
    if not (np.isfinite(resolution) and resolution > 0):
        raise InputError("--resolution", f"must be a positive number of metres, got {resolution}")
    utm = [_transform_bounds(g.crs, crs, _bounds(g)) for g in groups]
    if any(b is None for b in utm):
        raise InputError(source, f"the DEM does not fit one UTM zone grid ({crs}): "
                                 "crop it with --area")
    utm = np.array(utm)
    left, bottom = utm[:, 0].min(), utm[:, 1].min()
    right, top = utm[:, 2].max(), utm[:, 3].max()
    if area is not None:
        a = _transform_bounds(WGS84, crs, (area[1], area[0], area[3], area[2]))
        if a is not None:
            left, bottom = max(left, a[0]), max(bottom, a[1])
            right, top = min(right, a[2]), min(top, a[3])
        if a is None or right <= left or top <= bottom:
            raise InputError(source, f"area {_fmt_area(area)} does not overlap the DEM")
    # Cell centres, not just cell edges, must cover the area: grow by half a cell.
    half = resolution / 2
    left, bottom, right, top = left - half, bottom - half, right + half, top + half
    left = np.floor(left / resolution) * resolution
    top = np.ceil(top / resolution) * resolution
    n_cols = max(int(np.ceil((right - left) / resolution - 1e-9)), 1)
    n_rows = max(int(np.ceil((top - bottom) / resolution - 1e-9)), 1)
    if n_rows * n_cols > MAX_GRID_CELLS:
        raise InputError(source, f"the working grid would be {n_rows} x {n_cols} cells at "
                                 f"{resolution:g} m: crop with --area or raise --resolution")
    return crs, Affine(resolution, 0.0, left, 0.0, -resolution, top), (n_rows, n_cols)


def _bounds(g: _Grid):
    n_rows, n_cols = g.height.shape
    xs, ys = g.transform @ (np.array([0, n_cols, 0, n_cols]), np.array([0, 0, n_rows, n_rows]))
    return xs.min(), ys.min(), xs.max(), ys.max()


def _spacing_m(g: _Grid, utm: str) -> float:
    """Mean of the x and y pixel spacing in metres at the grid's centre."""
    n_rows, n_cols = g.height.shape
    to_utm = Transformer.from_crs(CRS.from_wkt(g.crs.to_wkt()), utm, always_xy=True)
    cols = np.array([n_cols / 2, n_cols / 2 + 1, n_cols / 2])
    rows = np.array([n_rows / 2, n_rows / 2, n_rows / 2 + 1])
    x, y = to_utm.transform(*(g.transform @ (cols, rows)))
    return float((np.hypot(x[1] - x[0], y[1] - y[0]) + np.hypot(x[2] - x[0], y[2] - y[0])) / 2)


def _trim(height, transform):
    """Drop all-NaN border rows and columns; None if nothing is left."""
    (height,), transform = _trim_all((height,), transform)
    return height, transform


def _trim_all(grids, transform):
    """`_trim` of grids of one shape, by where any of them has data."""
    finite = np.logical_or.reduce([np.isfinite(g) for g in grids])
    rows = np.nonzero(finite.any(axis=1))[0]
    cols = np.nonzero(finite.any(axis=0))[0]
    if len(rows) == 0:
        return (None,) * len(grids), transform
    window = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    return (tuple(np.ascontiguousarray(g[window]) for g in grids),
            transform @ Affine.translation(cols[0], rows[0]))


def _check_area(area):
    if area is None:
        return None
    try:
        south, west, north, east = (float(v) for v in area)
    except (TypeError, ValueError):
        raise InputError("--area", f"expected (south, west, north, east) degrees, got {area!r}") \
            from None
    if not (-90 <= south < north <= 90 and -180 <= west < east <= 180):
        raise InputError("--area", f"{_fmt_area((south, west, north, east))}: need "
                                   "-90 <= south < north <= 90 and -180 <= west < east <= 180")
    return south, west, north, east


def _fmt_area(area) -> str:
    return ",".join(f"{v:g}" for v in area)
