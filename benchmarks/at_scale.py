"""Plan quality at scale (`bench_coverage --at-scale`): per generated problem, the
default plan (ALNS), the lower bound the plan prints, plan / bound, and the bound
without the scattered route bound (`planner.coverage.bounds.scatter`) beside it:
the ratio as it was, on the same plan, in the same run. The independent check:
OR-Tools' routing solver alone (`benchmarks.independent`) at the wall time ALNS
took. RT+LS is the other of our own methods run beside it (its own time, not a time
budget).

The problems: seeded synthetic terrains of `SIZE`² cells (30 m), three outposts,
one or two hidden bases (the roomiest spots of the largest hidden region, the
second far from the first), fleets of 3-8 UAVs, k = 0, 1, 2.

On a battery (`SORTIES`: the battery a multiple of the median round trip to a
viewpoint, 5-min turnarounds): the plan, the bound it prints and the bound
without the sortie bound (`planner.coverage.bounds.sorties`), on the same plan.
"""

import time
import warnings

import numpy as np

#: terrain side in cells, and the viewpoint spacing: a few hundred viewpoints each
SIZE = 300
SPACING_M = 250.0
#: (family, seed) of the terrains, and per terrain the (UAVs, k, bases) planned
TERRAINS = (("ridges", 7), ("hills", 9), ("mixed", 11))
CASES = ((3, 0, 1), (5, 1, 1), (4, 2, 2), (8, 1, 2))
#: (UAVs, k, battery as a multiple of the median round trip to a viewpoint) on a
#: battery, from one base, with `TURNAROUND_S` between sorties
SORTIES, TURNAROUND_S = ((3, 0, 1.5), (4, 1, 2.0)), 300.0


def context(family, seed):
    """Planning context of one terrain, with two bases (stages up to travel times)."""
    from scipy.ndimage import minimum_filter

    from planner.exposure import Outpost, compute_exposure
    from planner.pipeline import prepare
    from planner.scenario import Scenario
    from planner.terrain import synthetic_terrain

    warnings.simplefilter("ignore")
    terrain = synthetic_terrain(SIZE, SIZE, cell=30.0, seed=seed, family=family)
    rng = np.random.default_rng(seed)
    posts = []
    for i in range(3):
        x, y = terrain.xy(*rng.integers(SIZE // 5, 4 * SIZE // 5, 2))
        lon, lat = terrain.to_lonlat(x, y)
        posts.append(Outpost(float(x), float(y), 5.0, 3000.0, float(lon), float(lat), f"P{i}"))
    surface = compute_exposure(terrain, posts)
    largest = np.bincount(surface.regions.ravel())[1:].argmax() + 1
    room = np.where(surface.regions == largest, surface.ceiling - surface.floor, -np.inf)
    room = minimum_filter(room, size=5)
    first = np.unravel_index(np.argmax(room), room.shape)
    # the second base: the roomiest spot at least a third of the terrain away
    rows, cols = np.indices(room.shape)
    far = np.hypot(rows - first[0], cols - first[1]) >= SIZE / 3
    second = np.unravel_index(np.argmax(np.where(far, room, -np.inf)), room.shape)
    launch = [tuple(reversed(terrain.to_lonlat(*terrain.xy(*rc)))) for rc in (first, second)]
    # one start per base (the scenario's fleet: its size takes one launch point each)
    scenario = Scenario(sample=True, uavs=2, sensor_range_m=700.0,
                        viewpoint_spacing_m=SPACING_M,
                        launch=[(float(a), float(b)) for a, b in launch]).validate()
    return prepare(scenario, terrain=terrain, outposts=posts)


def run_case(ctx, starts, n, k, bases) -> dict:
    """One problem: the plan, its bounds before and after, OR-Tools, RT+LS."""
    from benchmarks.independent import ortools_plan
    from planner.coverage import lower_bounds, prepare, solve
    from planner.pipeline import bound_budget_s, coverage_problem

    fleet = [starts[r % bases] for r in range(n)]
    p = coverage_problem(ctx, n, fleet, k, "soft")
    row = dict(n=n, k=k, bases=bases, viewpoints=p.n_viewpoints)
    a = solve(p, "alns")
    row["alns"], row["alns_s"] = a.coverage_time, a.planning_s
    prep = prepare(p)
    t0 = time.perf_counter()
    row["radius"], row["before"] = lower_bounds(p, True, prep, budget_s=0.0)
    row["before_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    row["bound"] = lower_bounds(p, True, prep, budget_s=bound_budget_s(a.planning_s))[1]
    row["bound_s"] = time.perf_counter() - t0
    o, row["ortools_rounds"] = ortools_plan(prep, a.planning_s)
    row["ortools"] = o.coverage_time if o is not None else float("nan")
    row["ortools_s"] = o.planning_s if o is not None else float("nan")
    row["ortools_short"] = short_targets(prep, o)
    b = solve(p, "rt+ls")
    row["rt_ls"], row["rt_ls_s"] = b.coverage_time, b.planning_s
    return row


def short_targets(prep, allocation) -> int:
    """Targets of ``allocation`` short of their distinct UAVs (all of them: None)."""
    from planner.coverage.model.evaluation import sighting_counts

    if allocation is None:
        return prep.problem.n_targets
    return int(np.count_nonzero(sighting_counts(prep.problem, allocation.routes)
                                < prep.required))


def ortools_cell(r) -> str:
    """OR-Tools' coverage time and wall time; where targets are left short of their
    distinct UAVs (its plan covers nothing then), how many."""
    if r["ortools_short"] == 0:
        return f"{r['ortools']:.0f} ({r['ortools_s']:.0f} s)"
    return f"short {r['ortools_short']} ({r['ortools_s']:.0f} s)"


def run() -> list:
    from planner.pipeline import launch_starts

    rows = []
    print("| terrain | vps | UAVs | k | bases | ALNS s (time) | bound s (time) | ratio | "
          "bound before | ratio before | OR-Tools s (time) | RT+LS s (time) |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|", flush=True)
    for family, seed in TERRAINS:
        ctx = context(family, seed)
        starts = launch_starts(ctx)
        for n, k, bases in CASES:
            r = run_case(ctx, starts, n, k, bases)
            r["terrain"] = f"{family} s{seed}"
            rows.append(r)
            print(f"| {r['terrain']} | {r['viewpoints']} | {n} | {k} | {bases} | "
                  f"{r['alns']:.0f} ({r['alns_s']:.0f} s) | {r['bound']:.0f} "
                  f"({r['bound_s']:.1f} s) | {r['alns'] / r['bound']:.2f} | {r['before']:.0f} "
                  f"| {r['alns'] / r['before']:.2f} | {ortools_cell(r)} "
                  f"| {r['rt_ls']:.0f} ({r['rt_ls_s']:.0f} s) |",
                  flush=True)
    ratios = [r["alns"] / r["bound"] for r in rows]
    before = [r["alns"] / r["before"] for r in rows]
    print(f"\nplan / bound: median {np.median(ratios):.2f}, worst {max(ratios):.2f} "
          f"(before: median {np.median(before):.2f}, worst {max(before):.2f}); "
          f"{len(rows)} problems")
    both = [r["alns"] / r["ortools"] for r in rows if r["ortools_short"] == 0]
    if both:
        print(f"ALNS / OR-Tools where OR-Tools covers ({len(both)} of {len(rows)}): "
              f"median {np.median(both):.3f}, worst {max(both):.3f}")
    return rows + run_sorties()


def run_sorties() -> list:
    """The `SORTIES` table: per terrain and case, the plan on a battery, its bound,
    and the bound without the sortie bound."""
    from dataclasses import replace

    from planner.coverage import lower_bounds, prepare, solve
    from planner.pipeline import coverage_problem, launch_starts
    from planner.sorties import sortie_split

    rows = []
    print("\n| terrain | UAVs | k | battery s | ALNS s (sorties) | bound s (time) | ratio | "
          "bound without sorties | ratio without |\n|---|---|---|---|---|---|---|---|---|",
          flush=True)
    for family, seed in TERRAINS:
        ctx = context(family, seed)
        starts = launch_starts(ctx)
        for n, k, times in SORTIES:
            p = coverage_problem(ctx, n, [starts[0]] * n, k, "soft")
            battery = times * float(np.median((p.launch_out + p.launch_back).min(axis=0)))
            p = replace(p, endurance_s=battery, turnaround_s=TURNAROUND_S)
            a, prep = solve(p, "alns"), prepare(p)
            sorties = sum(len(np.unique(of)) for of in sortie_split(prep, a.routes))
            t0 = time.perf_counter()
            bound = lower_bounds(p, True, prep, budget_s=0.0)[1]
            took = time.perf_counter() - t0
            without = lower_bounds(p, True, prep, budget_s=0.0, usable_s=np.inf)[1]
            rows.append(dict(terrain=f"{family} s{seed}", n=n, k=k, battery=battery,
                             alns=a.coverage_time, bound=bound, without=without))
            print(f"| {family} s{seed} | {n} | {k} | {battery:.0f} | {a.coverage_time:.0f} "
                  f"({sorties}) | {bound:.0f} ({took:.1f} s) | {a.coverage_time / bound:.2f} | "
                  f"{without:.0f} | {a.coverage_time / without:.2f} |", flush=True)
    ratios = [r["alns"] / r["bound"] for r in rows]
    before = [r["alns"] / r["without"] for r in rows]
    print(f"\non a battery, plan / bound: median {np.median(ratios):.2f}, worst "
          f"{max(ratios):.2f} (without the sortie bound: median {np.median(before):.2f}, "
          f"worst {max(before):.2f}); {len(rows)} problems")
    return rows
