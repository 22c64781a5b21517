"""Visibility sets and hidden travel times: speed, size, and agreement.

For the sample terrain and a 1024^2 synthetic terrain: candidates, targets,
seconds for all visibility sets (sweep and, on a subset, the exact method),
nonzeros and memory of the structure, agreement of the sweep with the exact
method, seconds for the travel graph and the viewpoint time matrix (overlay
vs exact on a subset), and GDAL's ViewshedGenerate over the same viewpoints
and radius (Debian's python3-gdal in a subprocess, timed in-process there).

    .venv/bin/python -c "from benchmarks.bench_visibility import main; main()"
"""

import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from common.errors import InputError
from planner.exposure import ExposureParams, Outpost, compute_exposure, sample_outposts
from planner.terrain import sample_terrain, synthetic_terrain
from planner.travel import TravelGraph
from planner.visibility import SensorParams, candidate_viewpoints, compute_visibility, fleet_region

GDAL_PYTHON = "/usr/bin/python3"
GDAL_SCRIPT = Path(__file__).with_name("gdal_viewsheds_many.py")
EXACT_SUBSET = 200  # viewpoints checked against the exact method
GDAL_KEEP_EVERY = 20  # every n-th GDAL viewshed is kept for the agreement figure
EXACT_ROWS = 20  # full Dijkstra sources to check the overlay time matrix against


def main(argv=None):
    sensor = SensorParams()
    _warm_up(sensor)
    cases = [("sample", sample_terrain(), None),
             ("synthetic 1024^2", synthetic_terrain(1024, 1024, cell=30.0, seed=1,
                                                    family="mixed"), 4000)]
    results = []
    for name, terrain, n_wanted in cases:
        results.append(_case(name, terrain, sensor, n_wanted))
    return results


def _case(name, terrain, sensor, n_wanted):
    print(f"\n== {name}: {terrain.shape[0]} x {terrain.shape[1]} cells of "
          f"{terrain.cell_size:.1f} m ==")
    t = time.perf_counter()
    outposts = outposts_for(terrain)
    surface = compute_exposure(terrain, outposts, ExposureParams())
    label = f"exposure surface, {len(outposts)} outposts"
    print(f"{label:<31}{time.perf_counter() - t:8.2f} s ({surface.flyable.mean():.0%} flyable)")
    regions = fleet_region(surface)
    spacing = None
    if n_wanted:
        area = np.isin(surface.regions, regions).sum() * terrain.cell_size**2
        spacing = math.sqrt(area / n_wanted)
    vp = candidate_viewpoints(surface, spacing, regions, sensor.sensor_range_m)
    t, cpu = time.perf_counter(), time.process_time()
    vis = compute_visibility(surface, vp, sensor)
    t_vis, cpu_vis = time.perf_counter() - t, time.process_time() - cpu
    print(f"candidates                     {len(vp):8d}")
    print(f"targets (S_c)                  {vis.n_targets:8d}")
    print(f"visibility sets, sweep         {t_vis:8.2f} s  "
          f"({cpu_vis:.2f} s CPU, {1e6 * t_vis / len(vp):.0f} us per viewpoint)")
    print(f"nonzeros                       {vis.nnz:8d}  ({vis.nnz / len(vp):.0f} per viewpoint)")
    print(f"memory (CSR + CSC + targets)   {vis.nbytes / 2**20:8.1f} MiB")
    agree, t_exact, sub, extra, missing = _sweep_vs_exact(surface, vp, vis, sensor)
    print(f"exact method, {len(sub)} viewpoints    {t_exact:8.2f} s  "
          f"(x{t_exact / len(sub) * len(vp) / t_vis:.1f} the sweep per viewpoint)")
    print(f"sweep agreement with exact     {agree:8.4%} of cells in range "
          f"({extra} falsely seen, {missing} falsely hidden)")
    gdal = _gdal(surface, vp, vis, sensor)
    if gdal:
        print(f"GDAL ViewshedGenerate, all     {gdal['seconds']:8.2f} s  "
              f"(ours / GDAL = {t_vis / gdal['seconds']:.2f})")
        print(f"agreement with GDAL            {gdal['agreement']:8.4%} of cells in range "
              f"(GDAL with exact: {gdal['gdal_vs_exact']:.4%})")
    t = time.perf_counter()
    graph = TravelGraph(surface)
    t_graph = time.perf_counter() - t
    print(f"travel graph                   {t_graph:8.2f} s  "
          f"({graph.n_nodes} nodes, {graph.n_edges} directed edges)")
    t = time.perf_counter()
    times = graph.time_matrix(vp.xyz, method="overlay")
    t_overlay = time.perf_counter() - t
    print(f"time matrix, overlay           {t_overlay:8.2f} s  "
          f"({len(vp)}^2, {np.isfinite(times).mean():.0%} finite)")
    sub = np.arange(0, len(vp), max(1, len(vp) // EXACT_ROWS))
    t = time.perf_counter()
    exact_rows = graph.times_between(vp.xyz[sub], vp.xyz)
    t_rows = time.perf_counter() - t
    f = np.isfinite(exact_rows) & (exact_rows > 0)
    ratio = times[sub][f] / exact_rows[f]
    print(f"exact rows, {len(sub)} sources         {t_rows:8.2f} s  "
          f"(all {len(vp)}: ~{t_rows / len(sub) * len(vp):.0f} s)")
    print(f"overlay / exact                mean {ratio.mean():.4f}, "
          f"99th pct {np.percentile(ratio, 99):.4f}, max {ratio.max():.4f}")
    return {"name": name, "candidates": len(vp), "targets": vis.n_targets,
            "visibility_s": t_vis, "nnz": vis.nnz, "bytes": vis.nbytes, "agreement": agree,
            "gdal": gdal, "graph_s": t_graph, "overlay_s": t_overlay,
            "overlay_ratio_max": float(ratio.max())}


def outposts_for(terrain):
    """The built-in outposts on the sample terrain; elsewhere, one on the highest
    ground of each quadrant, 5 m eye height, 6 km range."""
    try:
        return sample_outposts(terrain)
    except InputError:
        pass
    n_rows, n_cols = terrain.shape
    out = []
    for r0, c0 in ((0, 0), (0, n_cols // 2), (n_rows // 2, 0), (n_rows // 2, n_cols // 2)):
        quad = terrain.height[r0:r0 + n_rows // 2, c0:c0 + n_cols // 2]
        r, c = np.unravel_index(np.nanargmax(quad), quad.shape)
        x, y = terrain.xy(r0 + r, c0 + c)
        out.append(Outpost(x=float(x), y=float(y), height_m=5.0, range_m=6000.0))
    return out


def _warm_up(sensor):
    """Compile every kernel once on a small case, so timings are warm."""
    t = synthetic_terrain(48, 48, seed=0)
    surface = compute_exposure(t, outposts_for(t), ExposureParams())
    vp = candidate_viewpoints(surface, 150.0, sensor_range_m=sensor.sensor_range_m)
    for method in ("sweep", "exact"):
        compute_visibility(surface, vp, sensor, method=method)
    graph = TravelGraph(surface)
    graph.time_matrix(vp.xyz, method="overlay")


def _sweep_vs_exact(surface, vp, vis, sensor):
    """Agreement of the sweep with the exact method on a subset of viewpoints."""
    sub = np.arange(0, len(vp), max(1, len(vp) // EXACT_SUBSET))
    t = time.perf_counter()
    exact = compute_visibility(surface, _subset(vp, sub), sensor, method="exact")
    t_exact = time.perf_counter() - t
    extra = missing = 0
    for i, k in enumerate(sub):
        a, b = _cells(vis, k), _cells(exact, i)
        extra += len(np.setdiff1d(a, b))
        missing += len(np.setdiff1d(b, a))
    agree = 1.0 - (extra + missing) / _cells_in_range(surface, vp, sub, sensor)
    return agree, t_exact, sub, extra, missing


def _gdal(surface, vp, vis, sensor):
    """Time GDAL over the same viewpoints; None when python3-gdal is missing."""
    if subprocess.run([GDAL_PYTHON, "-c", "import osgeo.gdal"], capture_output=True).returncode:
        print("GDAL ViewshedGenerate          (python3-gdal not available: skipped)")
        return None
    h = surface.terrain.height
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(src, height=h, cell=surface.terrain.cell_size, rows=vp.indices[:, 0],
                 cols=vp.indices[:, 1], z=vp.xyz[:, 2], radius_m=sensor.sensor_range_m,
                 curv_coeff=surface.params.curvature_coeff,
                 target_height_m=sensor.target_height_m, keep_every=GDAL_KEEP_EVERY)
        subprocess.run([GDAL_PYTHON, str(GDAL_SCRIPT), str(src), str(dst)], check=True)
        out = dict(np.load(dst))
    kept = out["kept_ids"]
    in_range = _cells_in_range(surface, vp, kept, sensor)
    exact = compute_visibility(surface, _subset(vp, kept), sensor, method="exact")
    wrong = gdal_wrong = 0
    for i, k in enumerate(kept):
        theirs = out["kept_flat"][out["kept_ptr"][i]:out["kept_ptr"][i + 1]].astype(np.int64)
        wrong += len(np.setxor1d(_cells(vis, k), theirs))
        gdal_wrong += len(np.setxor1d(_cells(exact, i), theirs))
    return {"seconds": float(out["seconds"]), "agreement": 1.0 - wrong / in_range,
            "gdal_vs_exact": 1.0 - gdal_wrong / in_range, "visible": int(out["visible"].sum())}


def _subset(vp, idx):
    from planner.visibility import Viewpoints
    return Viewpoints(vp.indices[idx], vp.xyz[idx], vp.region[idx])


def _cells(vis, k):
    return vis.target_cells[vis.seen_by(k)]


def _cells_in_range(surface, vp, idx, sensor):
    """Valid cells within sensor range of the viewpoints idx (the agreement's base)."""
    n_rows, n_cols = surface.terrain.shape
    m = int(sensor.sensor_range_m // surface.terrain.cell_size)
    dr, dc = np.mgrid[-m:m + 1, -m:m + 1]
    disk = (dr * dr + dc * dc) * surface.terrain.cell_size**2 <= sensor.sensor_range_m**2
    total = 0
    valid = np.isfinite(surface.terrain.height)
    for r, c in vp.indices[idx]:
        rr, cc = r + dr[disk], c + dc[disk]
        ok = (rr >= 0) & (rr < n_rows) & (cc >= 0) & (cc < n_cols)
        total += int(valid[rr[ok], cc[ok]].sum())
    return total


if __name__ == "__main__":
    sys.exit(main() and 0)
