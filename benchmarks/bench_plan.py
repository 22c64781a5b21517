"""The whole planner on real terrain: `gcs plan --sample` timing and the methods compared.

    .venv/bin/python benchmarks/bench_plan.py [--quick]

1. `plan_mission` on the built-in sample terrain with 4 UAVs and k = 1, cold
   (numba kernels compiled or loaded from cache) and warm, per stage: the goal
   is under 20 s warm on 2 cores.
2. Every method on the sample terrain problems (the full DEM without launch
   points, and the demo area with one base), k = 0 and 1: coverage time, ratio
   to RT and to the makespan lower bound, snapshots, planning seconds.
3. What conservative resampling costs (planner.terrain.dem): a DEM that must be
   resampled (a geographic one) is planned on two surfaces that bracket it, so
   its exposure surface is safe against the DEM itself. Rows: the uncropped
   sample against the same grid resampled naively (the bracket's midpoint,
   which is what planning used before: not safe), and a synthetic terrain
   written as a 1" geographic GeoTIFF against the same heights in a UTM
   GeoTIFF kept on its own lattice (no resampling). Flyable area, targets,
   plan time.
"""

import argparse
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner.coverage import METHODS  # noqa: E402
from planner.pipeline import allocate, launch_starts, plan_mission, prepare  # noqa: E402
from planner.scenario import Scenario, make_scenario, read_scenario  # noqa: E402

DEMO = Path(__file__).resolve().parents[1] / "gcs" / "data" / "demo.toml"


def time_gcs_plan():
    scenario = Scenario(sample=True, uavs=4, k=1).validate()
    for label in ("cold", "warm"):
        t0 = time.perf_counter()
        ctx, outcome = plan_mission(scenario)
        total = time.perf_counter() - t0
        stages = ", ".join(f"{k} {v:.1f}" for k, v in outcome.plan.timing_s.items()
                           if k != "total")
        print(f"plan --sample --uavs 4 --k 1 ({label}): {total:5.1f} s  [{stages}]  "
              f"{'goal < 20 s warm: ' + ('met' if total < 20 else 'NOT met') if label == 'warm' else ''}")
    m = outcome.plan.metrics
    print(f"  {ctx.terrain.shape[0]}x{ctx.terrain.shape[1]} cells, {len(ctx.viewpoints)} "
          f"viewpoints, {m['targets']} targets; RT coverage {m['coverage_time_s'] / 60:.0f} min, "
          f"lower bound {m['lower_bound_s'] / 60:.0f} min")


def compare_methods(quick):
    cases = [("sample, no launch", Scenario(sample=True, uavs=4).validate())]
    demo = make_scenario(read_scenario(DEMO), {})
    cases.append(("demo area, one base", demo))
    ks = (0,) if quick else (0, 1)
    head = (f"{'case':<22} {'k':>2} {'method':>6} | {'coverage min':>12} {'/RT':>6} {'/LB':>6} "
            f"| {'snapshots':>9} {'plan s':>7}")
    print(head)
    print("-" * len(head))
    for name, scenario in cases:
        ctx = prepare(scenario)
        for k in ks:
            ctx.scenario = Scenario(**{**scenario.__dict__, "k": k}).validate()
            starts = launch_starts(ctx)
            rt = None
            for method in METHODS:
                t0 = time.perf_counter()
                out = allocate(ctx, scenario.uavs, starts, method=method)
                seconds = time.perf_counter() - t0
                m = out.plan.metrics
                rt = rt or m["coverage_time_s"]
                print(f"{name:<22} {k:>2} {method:>6} | {m['coverage_time_s'] / 60:12.1f} "
                      f"{m['coverage_time_s'] / rt:6.3f} {m['ratio_to_lower_bound']:6.2f} | "
                      f"{m['snapshots']:9d} {seconds:7.1f}", flush=True)


def _plan_row(name, scenario, terrain=None, outposts=None):
    t0 = time.perf_counter()
    ctx, outcome = plan_mission(scenario, terrain=terrain, outposts=outposts)
    seconds = time.perf_counter() - t0
    cell_km2 = (ctx.terrain.cell_size / 1000) ** 2
    m = outcome.plan.metrics
    print(f"{name:<44} | {ctx.surface.flyable.sum() * cell_km2:9.1f} {m['targets']:8d} "
          f"{m['coverage_time_s'] / 60:9.1f} {seconds:7.1f}", flush=True)
    return ctx


def resampling_cost():
    import json
    import tempfile

    import numpy as np
    from affine import Affine
    from pyproj import Transformer

    from planner.terrain import Terrain, synthetic_terrain

    head = f"{'DEM (4 UAVs, k = 1, rt)':<44} | {'flyable km2':>11} {'targets':>8} {'cover min':>9} {'plan s':>7}"
    print(head)
    print("-" * len(head))
    sample = Scenario(sample=True, uavs=4, k=1).validate()
    ctx = _plan_row("sample, conservative (lower/upper surfaces)", sample)
    t = ctx.terrain
    naive = Terrain((t.height + t.upper) / 2, t.transform, t.crs)
    _plan_row("sample, naive midpoint (not safe)", sample, naive, ctx.outposts)
    synthetic = synthetic_terrain(400, 400, cell=30.0, seed=7, family="mixed")
    with tempfile.TemporaryDirectory() as tmp:
        utm = Path(tmp) / "utm.tif"
        geo = Path(tmp) / "geo.tif"
        _write(utm, synthetic.height, synthetic.transform, synthetic.crs)
        # the same surface sampled on a 1" geographic grid over the same ground
        to_ll = Transformer.from_crs(synthetic.crs, "EPSG:4326", always_xy=True)
        (w, n), (e, s) = (to_ll.transform(*synthetic.xy(r, c)) for r, c in ((20, 20), (380, 380)))
        d = 1 / 3600
        lon, lat = np.meshgrid(np.arange(w, e, d) + d / 2, np.arange(n, s, -d) - d / 2)
        height = synthetic.ground(*synthetic.from_lonlat(lon, lat)).reshape(lon.shape)
        _write(geo, height, Affine(d, 0, w, 0, -d, n), "EPSG:4326")
        area = (s + 0.01, w + 0.01, n - 0.01, e - 0.01)
        posts = Path(tmp) / "posts.geojson"
        posts.write_text(json.dumps({"type": "FeatureCollection", "features": [
            {"type": "Feature", "properties": {"height_m": 10.0},
             "geometry": {"type": "Point", "coordinates": [w + fx * (e - w), s + fy * (n - s)]}}
            for fx, fy in ((0.3, 0.3), (0.7, 0.35), (0.5, 0.7), (0.2, 0.8))]}))
        for name, dem in (("synthetic, 1\" geographic (conservative)", geo),
                          ("synthetic, UTM on its own lattice (exact)", utm)):
            _plan_row(name, Scenario(dem=[str(dem)], area=area, uavs=4, k=1,
                                     outposts=str(posts)).validate())


def _write(path, height, transform, crs):
    import rasterio

    with rasterio.open(path, "w", driver="GTiff", width=height.shape[1], height=height.shape[0],
                       count=1, dtype="float64", crs=crs, transform=transform,
                       nodata=float("nan")) as ds:
        ds.write(height, 1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="k = 0 only")
    args, _ = ap.parse_known_args(argv)  # options of other benchmarks run with it
    warnings.simplefilter("ignore", UserWarning)
    time_gcs_plan()
    print()
    compare_methods(args.quick)
    print()
    resampling_cost()


if __name__ == "__main__":
    main()
