"""GDAL's ViewshedGenerate over many viewpoints, for benchmarks/bench_visibility.py.

Runs under Debian's /usr/bin/python3 with python3-gdal (not the project venv):

    /usr/bin/python3 benchmarks/gdal_viewsheds_many.py IN.npz OUT.npz

IN.npz: height [rows, cols] float64, cell (m), rows/cols/z of the viewpoints
(z metres AMSL), radius_m, curv_coeff, target_height_m, keep_every.
OUT.npz: seconds (the viewshed loop, timed in-process), visible [n] counts,
and, for every ``keep_every``-th viewpoint, the flat indices of the cells GDAL
marks visible (kept_ids, kept_ptr, kept_flat) so the caller can compare.
"""

import sys
import time

import numpy as np
from osgeo import gdal


def main(src, dst):
    data = np.load(src)
    h = data["height"]
    cell = float(data["cell"])
    rows, cols, z = data["rows"], data["cols"], data["z"]
    radius = float(data["radius_m"])
    keep_every = int(data["keep_every"])
    n_rows, n_cols = h.shape
    mem = gdal.GetDriverByName("MEM").Create("", n_cols, n_rows, 1, gdal.GDT_Float64)
    mem.SetGeoTransform((0.0, cell, 0.0, 0.0, 0.0, -cell))
    band = mem.GetRasterBand(1)
    band.WriteArray(h)
    visible = np.zeros(len(rows), np.int64)
    kept_ids, kept_flat = [], []
    start = time.perf_counter()
    for k, (r, c, zk) in enumerate(zip(rows, cols, z)):
        out = gdal.ViewshedGenerate(
            band, "MEM", "", [], (c + 0.5) * cell, -(r + 0.5) * cell,
            float(zk - h[r, c]), float(data["target_height_m"]), 1.0, 0.0, 0.0, 0.0,
            float(data["curv_coeff"]), gdal.GVM_Edge, radius)
        mask = out.GetRasterBand(1).ReadAsArray()
        visible[k] = int(np.count_nonzero(mask))
        if k % keep_every == 0:  # the output covers only the window within range
            gt = out.GetGeoTransform()
            r_seen, c_seen = np.nonzero(mask)
            r_seen = r_seen + int(round(-gt[3] / cell))
            c_seen = c_seen + int(round(gt[0] / cell))
            kept_ids.append(k)
            kept_flat.append(r_seen.astype(np.int64) * n_cols + c_seen)
        out = None
    seconds = time.perf_counter() - start
    ptr = np.zeros(len(kept_flat) + 1, np.int64)
    ptr[1:] = np.cumsum([len(f) for f in kept_flat])
    np.savez(dst, seconds=seconds, visible=visible, kept_ids=np.array(kept_ids, np.int64),
             kept_ptr=ptr, kept_flat=np.concatenate(kept_flat) if kept_flat else np.zeros(0))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
