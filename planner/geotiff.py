"""GeoTIFF output on the working grid, and reading a working-grid terrain back."""

from pathlib import Path

import numpy as np
import rasterio
from rasterio.errors import RasterioIOError

from .errors import InputError
from .fileio import atomic_path
from .terrain import Terrain


def write_grid(path, array, terrain: Terrain, nodata=None) -> None:
    """Write ``array`` (the terrain's shape) as a one-band, deflate-compressed GeoTIFF
    in the terrain's CRS and transform, atomically. The file keeps the array's
    dtype (float32 for heights and exposure, int16 for counts); float grids get
    NaN as nodata unless ``nodata`` says otherwise."""
    array = np.asarray(array)
    if array.shape != terrain.shape:
        raise ValueError(f"array shape {array.shape} is not the terrain's {terrain.shape}")
    if nodata is None and np.issubdtype(array.dtype, np.floating):
        nodata = np.nan
    profile = {
        "driver": "GTiff", "width": array.shape[1], "height": array.shape[0], "count": 1,
        "dtype": array.dtype.name, "crs": terrain.crs, "transform": terrain.transform,
        "nodata": nodata, "compress": "deflate",
        "predictor": 3 if np.issubdtype(array.dtype, np.floating) else 2,
    }
    if array.shape[0] >= 256 and array.shape[1] >= 256:
        profile.update(tiled=True, blockxsize=256, blockysize=256)
    with atomic_path(path) as tmp:
        with rasterio.open(tmp, "w", **profile) as ds:
            ds.write(array, 1)


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
        epsg = ds.crs.to_epsg()
        if epsg is None or not ds.crs.is_projected:
            raise InputError(path, f"not a working-grid terrain: CRS {ds.crs} is not a "
                                   "projected EPSG CRS")
        height = np.ma.filled(ds.read(1, masked=True, out_dtype="float64"), np.nan)
        transform = ds.transform
    if abs(transform.a + transform.e) > 1e-9 * abs(transform.a) or transform.b or transform.d:
        raise InputError(path, "not a working-grid terrain: the grid is not square and north up")
    return Terrain(height, transform, f"EPSG:{epsg}", source=str(path))
