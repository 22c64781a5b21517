"""How the planner's cost grows with the area: wall time, CPU time and peak memory
per stage for synthetic UTM DEMs of 256², 512², 1024² (and 2048² without
--quick) cells at 30 m, 5 outposts, one launch point, k = 1, the default
method; the fitted exponent per stage (time ~ cells^p); and the chunked stages
(travel graph, travel times) on a dask LocalCluster of 1 and 2 workers.
``--huge[=N]``: instead, N² (default 4096², 123 km square; 16 UAVs, planned in
parts: ``--parts=P`` to choose how many) on a LocalCluster of 2 and then 1
worker, every stage, and the ratio.
``--terrains[=N]`` (the = is needed): instead, N² (default 1024²) on the benchmark's own terrain
and on held-out ones of other kinds and seeds (`TERRAINS`: hills, ridges, peaks;
outposts on summits or in valleys, eyes 4-8 m, ranges 3-8 km), each stage per
terrain, the worst terrain's total as the headline beside the own one's
(issue 36: the travel-time stage's cost must not depend on the terrain's luck).
``--endurance MIN`` (with ``--terrains``): instead, the same plans on a battery of
MIN minutes, each terrain planned with and without it in the same run (issue 33:
sorties a battery can fly), and what the sorties cost: planning time, coverage
time, sorties per UAV, the viewpoints beyond one battery.

    .venv/bin/python -m benchmarks scale [--quick | --huge[=N] [--parts=P] [--workers=W]
                                          | --terrains[=N] [--endurance MIN]]

Each size runs in its own process, so its peak resident memory is its own. The
goals (issue 22): 1024² with 8 UAVs under 60 s and 4 GiB on 2 cores, both
cores busy in every stage over a second; 2048² with 12 UAVs under 5 minutes and
8 GiB.
"""

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
UAVS = {256: 4, 512: 6, 1024: 8, 2048: 12, 3072: 16, 4096: 16}
#: name -> (family, seed, where the outposts stand); "own" is `_inputs`' default
TERRAINS = {"own": ("mixed", 11, "anywhere"), "hills": ("hills", 5, "summits"),
            "hills-valleys": ("hills", 23, "valleys"), "ridges": ("ridges", 7, "summits"),
            "peaks": ("peaks", 13, "valleys")}
STAGES = ("terrain", "exposure", "travel graph", "viewpoints", "visibility", "travel times",
          "allocation", "routes", "separation")


def _one(n: int, scheduler: str, parts=None, terrain="own", endurance=None) -> dict:
    """Plan an n x n terrain in this process; per-stage wall/CPU seconds, peak RSS."""
    import resource
    import time
    import warnings

    warnings.simplefilter("ignore")
    from planner.pipeline import allocate, launch_starts, prepare
    from planner.scenario import Scenario

    folder = Path(tempfile.mkdtemp(prefix="bench-scale-"))
    dem, posts, launch = _inputs(n, folder, *TERRAINS[terrain])
    scenario = Scenario(dem=[str(dem)], outposts=str(posts), uavs=UAVS[n], k=1,
                        launch=[launch], parts=parts, endurance_min=endurance).validate()
    marks = {}

    def progress(stage, fraction):
        now = (time.perf_counter(), time.process_time())
        marks.setdefault(stage, [now, now])[1] = now

    where = None if scheduler == "none" else scheduler
    ctx = prepare(scenario, progress, scheduler=where)
    outcome = allocate(ctx, scenario.uavs, launch_starts(ctx), progress=progress,
                       scheduler=where)
    stages = {s: [m[1][0] - m[0][0], m[1][1] - m[0][1]] for s, m in marks.items()}
    if outcome.plan.metrics.get("parts", 1) > 1:
        # in parts, travel times and allocation take turns: the plan's own split of the
        # time; their CPU time is one figure, given to allocation
        cpu = stages["travel times"][1]
        stages["travel times"] = [outcome.plan.timing_s["travel times"], np.nan]
        stages["allocation"] = [outcome.plan.timing_s["allocation"], cpu]
    return {"n": n, "terrain": terrain, "stages": stages, "viewpoints": len(ctx.viewpoints),
            "hidden_pct": 100.0 * float((ctx.surface.regions > 0).mean()),
            "targets": int(ctx.visibility.n_targets),
            "coverage_min": outcome.plan.metrics["coverage_time_s"] / 60,
            "sorties": max((len(v.sorties) or 1 for v in outcome.plan.vehicles), default=0),
            "longest_flight_min": outcome.plan.metrics["battery"]["longest_flight_s"] / 60,
            "beyond_battery": outcome.plan.metrics["battery"].get("beyond_battery", 0),
            "parts": outcome.plan.metrics.get("parts", 1),
            "peak_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
            "worker_peaks_gib": _worker_peaks(where)}


def _worker_peaks(address) -> list:
    """Peak resident memory of each worker of the cluster at ``address``, GiB."""
    if address is None:
        return []
    import resource

    from distributed import Client

    with Client(address) as client:
        peaks = client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
    return [v / 2**20 for v in peaks.values()]


def _inputs(n, folder, family="mixed", seed=11, where="anywhere"):
    """A seeded synthetic DEM in its UTM zone, 5 outposts and a hidden launch point.
    ``where``: "anywhere" (the benchmark's own: eyes 10 m, unlimited range), or
    "summits" / "valleys" (held-out: the highest / lowest cell of each of 5 random
    windows, eyes 4-8 m, ranges 3-8 km, as operators place them)."""
    import rasterio

    from planner.exposure import compute_exposure, load_outposts
    from planner.terrain import synthetic_terrain

    t = synthetic_terrain(n, n, cell=30.0, seed=seed, family=family)
    dem = folder / "dem.tif"
    with rasterio.open(dem, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32",
                       crs=t.crs, transform=t.transform) as ds:
        ds.write(t.height.astype(np.float32), 1)
    rng = np.random.default_rng(2)
    features = []
    for k in range(5):
        cell, props = rng.integers(n // 8, 7 * n // 8, 2), {"height_m": 10}
        if where != "anywhere":
            w = n // 16
            box = t.height[cell[0] - w:cell[0] + w, cell[1] - w:cell[1] + w]
            pick = np.nanargmax(box) if where == "summits" else np.nanargmin(box)
            cell = cell - w + np.array(np.unravel_index(pick, box.shape))
            props = {"height_m": float(rng.uniform(4, 8)),
                     "range_m": float(rng.uniform(3000, 8000))}
        lon, lat = t.to_lonlat(*t.xy(*cell))
        features.append({"type": "Feature", "properties": {"name": f"P{k + 1}", **props},
                         "geometry": {"type": "Point", "coordinates": [float(lon), float(lat)]}})
    posts = folder / "posts.geojson"
    posts.write_text(json.dumps({"type": "FeatureCollection", "features": features}))
    surface = compute_exposure(t, load_outposts(posts, t))
    largest = np.bincount(surface.regions.ravel())[1:].argmax() + 1
    cells = np.argwhere(surface.regions == largest)
    lon, lat = t.to_lonlat(*t.xy(*cells[len(cells) // 2]))
    return dem, posts, (float(lat), float(lon))


def _run(n, scheduler="none", parts=None, terrain="own", endurance=None) -> dict:
    more = (["--parts", str(parts)] if parts else []) + ["--terrain", terrain] + \
        (["--endurance", str(endurance)] if endurance else [])
    out = subprocess.run([sys.executable, __file__, "--one", str(n), "--scheduler", scheduler]
                         + more, stdout=subprocess.PIPE, text=True, cwd=ROOT)  # stderr shown
    if out.returncode:
        raise SystemExit(f"bench_scale: the {n}² run failed (exit {out.returncode})")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="up to 1024² only")
    ap.add_argument("--huge", type=int, nargs="?", const=4096, metavar="N",
                    help="N² (default 4096²) on a LocalCluster of 2, then 1 worker")
    ap.add_argument("--terrains", type=int, nargs="?", const=1024, metavar="N",
                    help="N² (default 1024²) on the own and the held-out terrains")
    ap.add_argument("--terrain", default="own", choices=sorted(TERRAINS),
                    help="with --one: which terrain")
    ap.add_argument("--endurance", type=float, metavar="MIN",
                    help="with --terrains: also plan each terrain on a battery of MIN minutes")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--scheduler", default="none", help=argparse.SUPPRESS)
    ap.add_argument("--parts", type=int, help="with --huge: plan in this many parts "
                                              "(default: by the number of viewpoints)")
    ap.add_argument("--workers", type=int, choices=(1, 2),
                    help="with --huge: only this LocalCluster (a 4096² run takes most of "
                         "an hour per cluster)")
    args, _ = ap.parse_known_args(argv)
    if args.one:
        print(json.dumps(_one(args.one, args.scheduler, args.parts, args.terrain,
                              args.endurance)))
        return
    if args.terrains:
        if args.endurance:
            _sorties(args.terrains, args.endurance)
        else:
            _terrains(args.terrains)
        return
    if args.huge:
        _huge(args.huge, args.parts, (args.workers,) if args.workers else (2, 1))
        return
    sizes = (256, 512, 1024) if args.quick else (256, 512, 1024, 2048)
    runs = [_run(n) for n in sizes]
    head = f"{'stage':<14}" + "".join(f"{f'{n}² wall/cpu s':>20}" for n in sizes) + "  exponent"
    print(head)
    print("-" * len(head))
    cells = np.array([float(n) ** 2 for n in sizes])
    for stage in STAGES:
        walls = np.array([r["stages"].get(stage, [np.nan, np.nan])[0] for r in runs])
        cpus = [r["stages"].get(stage, [np.nan, np.nan])[1] for r in runs]
        ok = walls > 0.05
        p = np.polyfit(np.log(cells[ok]), np.log(walls[ok]), 1)[0] if ok.sum() >= 2 else np.nan
        print(f"{stage:<14}" + "".join(f"{w:12.1f} /{c:6.1f}" for w, c in zip(walls, cpus))
              + f"  {p:8.2f}")
    total = [sum(w for w, _ in r["stages"].values()) for r in runs]
    print(f"{'total':<14}" + "".join(f"{t:20.1f}" for t in total))
    print(f"{'peak GiB':<14}" + "".join(f"{r['peak_gib']:20.2f}" for r in runs))
    print(f"{'viewpoints':<14}" + "".join(f"{r['viewpoints']:20d}" for r in runs))
    print(f"{'UAVs':<14}" + "".join(f"{UAVS[n]:20d}" for n in sizes))
    print("\nchunked stages on a dask LocalCluster, 1024²:")
    for workers in (1, 2):
        r = _cluster_run(1024, workers)
        print(f"  {workers} worker(s): travel graph {r['stages']['travel graph'][0]:.1f} s, "
              f"travel times {r['stages']['travel times'][0]:.1f} s")


def _terrains(n):
    """Every stage of an n² plan on each of `TERRAINS`, and the worst total."""
    runs = {}
    for name in TERRAINS:
        runs[name] = _run(n, terrain=name)
        print(f"{name}: {json.dumps(runs[name])}", flush=True)
    head = f"{'stage':<14}" + "".join(f"{name:>15}" for name in runs)
    print(f"\n{n}², {UAVS[n]} UAVs, k = 1; wall s per stage\n{head}\n" + "-" * len(head))
    for stage in STAGES:
        print(f"{stage:<14}" + "".join(f"{r['stages'].get(stage, [np.nan])[0]:15.1f}"
                                       for r in runs.values()))
    total = {name: sum(w for w, _ in r["stages"].values()) for name, r in runs.items()}
    print(f"{'total':<14}" + "".join(f"{t:15.1f}" for t in total.values()))
    for row in ("viewpoints", "hidden_pct", "peak_gib"):
        print(f"{row:<14}" + "".join(f"{r[row]:15.1f}" for r in runs.values()))
    worst = max(total, key=total.get)
    print(f"\nworst terrain: {worst}, {total[worst]:.1f} s = {total[worst] / total['own']:.2f}"
          f" x the own terrain's {total['own']:.1f} s (goal: under "
          f"{60 if n <= 1024 else 300} s)")


def _sorties(n, endurance):
    """Each terrain planned on an ``endurance``-minute battery, beside its plan without
    one made in the same run."""
    print(f"\n{n}², {UAVS[n]} UAVs, k = 1: unlimited battery vs {endurance:g} min")
    head = (f"{'terrain':<14}{'plan s':>14}{'coverage min':>16}{'sorties/UAV':>13}"
            f"{'longest min':>13}{'beyond':>8}")
    print(head + "\n" + "-" * len(head))
    for name in TERRAINS:
        free, limited = _run(n, terrain=name), _run(n, terrain=name, endurance=endurance)
        walls = [sum(w for w, _ in r["stages"].values()) for r in (free, limited)]
        print(f"{name:<14}{walls[0]:6.1f} ->{walls[1]:6.1f}"
              f"{free['coverage_min']:7.1f} ->{limited['coverage_min']:6.1f}"
              f"{free['sorties']:5d} ->{limited['sorties']:4d}"
              f"{free['longest_flight_min']:6.1f} ->{limited['longest_flight_min']:5.1f}"
              f"{limited['beyond_battery']:8d}", flush=True)


def _huge(n, parts=None, clusters=(2, 1)):
    """Every stage of an n² plan on a LocalCluster of 1 and of 2 workers (the faster
    first: its figures are out sooner)."""
    found = {}
    for workers in clusters:
        found[workers] = _cluster_run(n, workers, parts)
        print(f"{workers} worker(s): {json.dumps(found[workers])}", flush=True)
    if len(found) < 2:
        return
    runs = [found[1], found[2]]
    r = runs[0]
    print(f"{n}², {UAVS[n]} UAVs, {r['viewpoints']:,} viewpoints, {r['targets']:,} targets, "
          f"{r['parts']} parts; wall / CPU s of this process (workers' CPU not in it)")
    head = f"{'stage':<14}{'1 worker':>18}{'2 workers':>18}{'ratio':>8}"
    print(head)
    print("-" * len(head))
    for stage in STAGES:
        one, two = (run["stages"].get(stage, [np.nan, np.nan]) for run in runs)
        print(f"{stage:<14}{one[0]:10.1f} /{one[1]:6.1f}{two[0]:10.1f} /{two[1]:6.1f}"
              f"{two[0] / one[0] if one[0] > 0 else np.nan:8.2f}")
    totals = [sum(w for w, _ in run["stages"].values()) for run in runs]
    print(f"{'total':<14}{totals[0]:18.1f}{totals[1]:18.1f}{totals[1] / totals[0]:8.2f}")
    for run, workers in zip(runs, (1, 2)):
        print(f"{workers} worker(s): coverage {run['coverage_min']:.1f} min; peak memory "
              f"{run['peak_gib']:.2f} GiB here, workers "
              + ", ".join(f"{g:.2f}" for g in run["worker_peaks_gib"]) + " GiB")


def _cluster_run(n, workers, parts=None) -> dict:
    """The plan with its chunked stages on a LocalCluster of ``workers`` processes."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        return _run(n, cluster.scheduler_address, parts)


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    main()
