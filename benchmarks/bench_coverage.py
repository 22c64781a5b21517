"""Coverage methods compared on seeded synthetic problems (the paper's comparisons).

    .venv/bin/python benchmarks/bench_coverage.py [--quick] [--large] [--sweep]

Prints, per (UAVs, k, visibility) group, the geometric means of coverage time
ratios: RT/RD, RT+LS/RT, RT+LS/B, C/B, each method over the lower bound (with
launch points, where the bound has a reach term), soft/hard for RT and RT+LS,
and planning seconds; then the goals of issue 4 against what was measured.
``--sweep`` runs the step-cap (th_ra) sweep used to pick the default factor,
``--large`` times RT on a 3,000-viewpoint x 50,000-target x 8-UAV problem.
Terrain-based instances are added by the lead.
"""

import argparse
import math
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner.coverage import METHODS, CoverageParams, lower_bound, solve  # noqa: E402
from planner.coverage.instances import FAMILIES, random_problem  # noqa: E402


def gmean(values):
    values = [v for v in values if np.isfinite(v) and v > 0]
    return float(np.exp(np.mean(np.log(values)))) if values else math.nan


def instances(quick):
    seeds = (0,) if quick else (0, 1)
    fleets = (2, 4) if quick else (2, 4, 8)
    for family in FAMILIES:
        for seed in seeds:
            for n in fleets:
                for k in range(min(3, n)):
                    for launch in (False, True):
                        yield dict(family=family, seed=seed, n_uavs=n, k=k, launch=launch)


def run_suite(quick, params):
    rows = []
    for spec in instances(quick):
        for vis in ("hard", "soft"):
            if spec["k"] == 0 and vis == "hard":
                continue  # identical to soft for k = 0
            p = random_problem(n_viewpoints=150, n_targets=1500, visibility=vis, **spec)
            lb = lower_bound(p)
            row = dict(spec, visibility=vis, lb=lb)
            for m in METHODS:
                a = solve(p, m, params)
                assert a.covered, (spec, m)
                row[m] = a.coverage_time
                row[m + "_s"] = a.planning_s
                row[m + "_n"] = a.n_snapshots
            rows.append(row)
            print(".", end="", flush=True)
    print()
    return rows


def report(rows):
    groups = defaultdict(list)
    for r in rows:
        groups[(r["n_uavs"], r["k"], r["visibility"])].append(r)
    head = (f"{'UAVs':>4} {'k':>2} {'vis':>4} {'n':>3} | {'RT/RD':>6} {'LS/RT':>6} {'LS/B':>6} "
            f"{'RT/B':>6} {'C/B':>6} | {'RT/LB':>6} {'LS/LB':>6} {'B/LB':>6} | "
            f"{'snaps RT':>8} {'LS':>5} {'B':>5} | {'s RT':>5} {'LS':>5} {'B':>5} {'C':>5}")
    print(head)
    print("-" * len(head))
    for key in sorted(groups):
        g = groups[key]
        launch = [r for r in g if r["launch"]]

        def ratio(a, b, rs=g):
            return gmean([r[a] / r[b] for r in rs])

        def lbr(m):
            return gmean([r[m] / r["lb"] for r in launch])

        print(f"{key[0]:>4} {key[1]:>2} {key[2]:>4} {len(g):>3} | {ratio('rt', 'rd'):6.3f} "
              f"{ratio('rt+ls', 'rt'):6.3f} {ratio('rt+ls', 'b'):6.3f} {ratio('rt', 'b'):6.3f} "
              f"{ratio('c', 'b'):6.3f} | {lbr('rt'):6.3f} {lbr('rt+ls'):6.3f} {lbr('b'):6.3f} | "
              f"{np.mean([r['rt_n'] for r in g]):8.1f} {np.mean([r['rt+ls_n'] for r in g]):5.1f} "
              f"{np.mean([r['b_n'] for r in g]):5.1f} | "
              + " ".join(f"{np.mean([r[m + '_s'] for r in g]):5.2f}"
                         for m in ("rt", "rt+ls", "b", "c")))


def soft_vs_hard(rows):
    pairs = defaultdict(dict)
    for r in rows:
        if r["k"] >= 1:
            key = (r["family"], r["seed"], r["n_uavs"], r["k"], r["launch"])
            pairs[key][r["visibility"]] = r
    out = {}
    for m in ("rt", "rt+ls"):
        out[m] = gmean([p["soft"][m] / p["hard"][m] for p in pairs.values()])
    return out


def goals(rows):
    big = [r for r in rows if r["n_uavs"] >= 4]
    big_launch = [r for r in big if r["launch"]]
    sh = soft_vs_hard(rows)
    checks = [
        ("RT/RD <= 0.80", gmean([r["rt"] / r["rd"] for r in rows]), 0.80),
        ("RT+LS/B <= 0.90 (>= 4 UAVs)", gmean([r["rt+ls"] / r["b"] for r in big]), 0.90),
        ("RT+LS/LB <= 1.10 (>= 4 UAVs, launch points)",
         gmean([r["rt+ls"] / r["lb"] for r in big_launch]), 1.10),
        ("RT+LS/RT <= 0.90", gmean([r["rt+ls"] / r["rt"] for r in rows]), 0.90),
        ("soft/hard <= 0.93 at k >= 1 (RT)", sh["rt"], 0.93),
        ("soft/hard <= 0.93 at k >= 1 (RT+LS)", sh["rt+ls"], 0.93),
    ]
    print("\nGoals (geometric means over the suite):")
    for name, value, target in checks:
        print(f"  {name:<45} {value:6.3f}  {'met' if value <= target else 'NOT met'}")
    print(f"  worst single RT+LS/B: {max(r['rt+ls'] / r['b'] for r in rows):.3f}, "
          f"best: {min(r['rt+ls'] / r['b'] for r in rows):.3f}")


def sweep(quick):
    """Coverage time of RT for th_ra = factor x median nearest-neighbour time."""
    factors = (1.0, 2.0, 4.0, 8.0, 16.0, math.inf)
    table = defaultdict(list)
    for spec in instances(quick):
        if spec["k"] > 1:
            continue
        p = random_problem(n_viewpoints=150, n_targets=1500, **spec)
        base = solve(p, "rt", CoverageParams(step_time_cap=math.inf)).coverage_time
        for f in factors:
            a = solve(p, "rt", CoverageParams(step_cap_factor=f)) if np.isfinite(f) else None
            table[f].append((a.coverage_time if a else base) / base)
    print("\nStep-cap sweep: RT coverage time / RT without cap (geometric mean)")
    for f in factors:
        print(f"  th_ra = {f:>4} x median NN time: {gmean(table[f]):.3f}  "
              f"(worst {max(table[f]):.3f}, best {min(table[f]):.3f})")


def large():
    t0 = time.perf_counter()
    p = random_problem(n_viewpoints=3000, n_targets=50000, n_uavs=8, k=1, seed=0,
                       size_m=12000.0, sensor_m=900.0, launch=True)
    print(f"\nLarge problem: 3000 viewpoints x 50000 targets x 8 UAVs, k=1, "
          f"{len(p.vis_indices)} visibility pairs (built in {time.perf_counter() - t0:.1f} s)")
    solve(random_problem(30, 100, 8, k=1, launch=True), "rt")  # warm the kernels
    for m in ("rt", "rd", "rt+ls"):
        a = solve(p, m)
        print(f"  {m:6s} coverage {a.coverage_time:8.1f} s  snapshots {a.n_snapshots:5d}  "
              f"planning {a.planning_s:6.2f} s")
    t0 = time.perf_counter()
    lb = lower_bound(p)
    print(f"  lower bound {lb:.1f} s ({time.perf_counter() - t0:.2f} s)")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer seeds and fleets")
    ap.add_argument("--sweep", action="store_true", help="also sweep the step cap th_ra")
    ap.add_argument("--large", action="store_true", help="also time the 3000 x 50000 problem")
    args, _ = ap.parse_known_args(argv)  # options of other benchmarks run with it
    params = CoverageParams()
    t0 = time.perf_counter()
    rows = run_suite(args.quick, params)
    report(rows)
    goals(rows)
    if args.sweep:
        sweep(args.quick)
    if args.large:
        large()
    print(f"\n(total {time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
