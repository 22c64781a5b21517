"""GeoTIFF output on the working grid, and reading a working-grid terrain back."""

from pathlib import Path

import numpy as np
import rasterio
from rasterio.errors import RasterioIOError

from common.errors import InputError
from common.fileio import atomic_path

from .grid import Terrain


def write_grid(path, array, terrain: Terrain, nodata=None, descriptions=()) -> None:
    """Write ``array`` (the terrain's shape, or bands x shape) as a deflate-compressed
    GeoTIFF in the terrain's CRS and transform, atomically. The file keeps the
    array's dtype (float32 for exposure, int16 for counts); float grids get NaN as
    nodata unless ``nodata`` says otherwise."""
    array = np.asarray(array)
    bands = array.reshape((-1, *array.shape[-2:]))
    if bands.shape[1:] != terrain.shape:
        raise ValueError(f"array shape {array.shape} is not the terrain's {terrain.shape}")
    if nodata is None and np.issubdtype(array.dtype, np.floating):
        nodata = np.nan
    profile = {
        "driver": "GTiff", "width": bands.shape[2], "height": bands.shape[1],
        "count": bands.shape[0], "dtype": array.dtype.name, "crs": terrain.crs,
        "transform": terrain.transform, "nodata": nodata, "compress": "deflate",
        "predictor": 3 if np.issubdtype(array.dtype, np.floating) else 2,
    }
    if bands.shape[1] >= 256 and bands.shape[2] >= 256:
        profile.update(tiled=True, blockxsize=256, blockysize=256)
    with atomic_path(path) as tmp:
        with rasterio.open(tmp, "w", **profile) as ds:
            ds.write(bands)
            for band, text in enumerate(descriptions, start=1):
                ds.set_band_description(band, text)


TERRAIN_BANDS = ("terrain for line of sight (m AMSL; nowhere above the source DEM)",
                 "ground for clearance (m AMSL; nowhere below the source DEM)")


def write_terrain(path, terrain: Terrain) -> None:
    """The working grid as planned on, in float64 so that a plan re-checked from it
    sees exactly the heights it was proven on: band 1 occludes sight lines, band
    2 is the ground for clearance (the same heights on a DEM kept on its own
    lattice)."""
    write_grid(path, np.stack([terrain.height, terrain.upper]).astype(np.float64), terrain,
               descriptions=TERRAIN_BANDS)


def read_grid(path, shape) -> np.ndarray:
    """Band 1 of a grid `write_grid` wrote, in its own dtype; InputError unless it
    has ``shape`` (the working grid's)."""
    try:
        with rasterio.open(path) as ds:
            band = ds.read(1)
    except RasterioIOError:
        raise InputError(path, "not a raster GDAL can read") from None
    if band.shape != tuple(shape):
        raise InputError(path, f"not on the working grid ({band.shape}, not {tuple(shape)})")
    return band


def read_terrain(path) -> Terrain:
    """A working-grid terrain GeoTIFF (as written by `write_grid`) as a `Terrain`."""
    path = Path(path)
    if not path.exists():
        raise InputError(path, "no such file")
    try:
        ds = rasterio.open(path)
    except RasterioIOError:
        raise InputError(path, "not a raster GDAL can read") from None
    with ds:
        if ds.crs is None:
            raise InputError(path, "raster has no CRS")
        if not ds.crs.is_projected:
            raise InputError(path, f"not a working-grid terrain: CRS {ds.crs} is not "
                                   "projected")
        epsg = ds.crs.to_epsg()
        crs = f"EPSG:{epsg}" if epsg else ds.crs.to_wkt()
        bands = [np.ma.filled(ds.read(b, masked=True, out_dtype="float64"), np.nan)
                 for b in range(1, min(ds.count, 2) + 1)]
        transform = ds.transform
    if abs(transform.a + transform.e) > 1e-9 * abs(transform.a) or transform.b or transform.d:
        raise InputError(path, "not a working-grid terrain: the grid is not square and north up")
    upper = bands[1] if len(bands) > 1 and not np.array_equal(bands[0], bands[1],
                                                              equal_nan=True) else None
    return Terrain(bands[0], transform, crs, source=str(path), height_upper=upper)
