"""GDAL's viewshed in "minimum visible height" mode, for benchmarks/bench_exposure.py.

Runs under Debian's /usr/bin/python3 with python3-gdal (not the project venv):

    /usr/bin/python3 benchmarks/gdal_viewshed.py DEM.npy [OUT.npz] < request.json

DEM.npy: float64 heights [rows, cols], row 0 north. request.json:
``{"cell": metres, "curvature_coeff": k, "observers": [[row, col, height_m,
range_m or null], ...], "prefixes": [1, 4, 16], "repeats": 3}``. Each observer
stands on the centre of cell (row, col), ``height_m`` above it. Prints JSON:
GDAL's version and the seconds of each observer's ViewshedGenerate call, best
of ``repeats`` (in memory, timed in-process; no file I/O). With OUT.npz, also
saves for every prefix n the minimum over the first n observers of GDAL's lowest
visible altitude (ground + GVOT_MIN_TARGET_HEIGHT_FROM_GROUND, metres AMSL; inf
where out of range), as float64 arrays "min_<n>".
"""

import json
import sys
import time

import numpy as np
from osgeo import gdal

OUT_OF_RANGE = -9999.0
NODATA = -9998.0


def viewsheds(h, cell, curvature, observers, repeats=1):
    n_rows, n_cols = h.shape
    mem = gdal.GetDriverByName("MEM").Create("", n_cols, n_rows, 1, gdal.GDT_Float64)
    mem.SetGeoTransform((0.0, cell, 0.0, 0.0, 0.0, -cell))
    band = mem.GetRasterBand(1)
    band.WriteArray(h)
    seconds, grids = [], []
    for row, col, height, range_m in observers:
        best = float("inf")
        for _ in range(repeats):
            start = time.perf_counter()
            out = gdal.ViewshedGenerate(
                band, "MEM", "", [], (col + 0.5) * cell, -(row + 0.5) * cell, float(height),
                0.0, 1.0, 0.0, OUT_OF_RANGE, NODATA, float(curvature), gdal.GVM_Edge,
                float(range_m or 0.0), heightMode=gdal.GVOT_MIN_TARGET_HEIGHT_FROM_GROUND)
            best = min(best, time.perf_counter() - start)
        seconds.append(best)
        grids.append(_full_grid(out, h, cell))
        out = None
    return seconds, grids


def _full_grid(out, h, cell):
    """GDAL's output (which covers only the window within range) as altitudes AMSL."""
    above = out.GetRasterBand(1).ReadAsArray()
    gt = out.GetGeoTransform()
    r0 = int(round(-gt[3] / cell))
    c0 = int(round(gt[0] / cell))
    grid = np.full(h.shape, np.inf)
    window = grid[r0:r0 + above.shape[0], c0:c0 + above.shape[1]]
    alt = h[r0:r0 + above.shape[0], c0:c0 + above.shape[1]] + above
    window[:] = np.where(above > NODATA + 0.5, alt, np.inf)
    return grid


def main(argv):
    request = json.load(sys.stdin)
    h = np.load(argv[1]).astype(np.float64)
    seconds, grids = viewsheds(h, float(request["cell"]), float(request["curvature_coeff"]),
                               request["observers"], int(request.get("repeats", 1)))
    if len(argv) > 2:
        mins = {}
        for n in request.get("prefixes", [len(grids)]):
            mins[f"min_{n}"] = np.min(np.stack(grids[:n]), axis=0)
        np.savez(argv[2], **mins)
    json.dump({"gdal_version": gdal.__version__, "seconds": seconds}, sys.stdout)
    print()


if __name__ == "__main__":
    main(sys.argv)
