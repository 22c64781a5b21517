"""The whole planner on real terrain: `gcs plan --sample` timing and the methods compared.

    .venv/bin/python benchmarks/bench_plan.py [--quick]

1. `plan_mission` on the built-in sample terrain with 4 UAVs and k = 1, cold
   (numba kernels compiled or loaded from cache) and warm, per stage: the goal
   is under 20 s warm on 2 cores.
2. Every method on the sample terrain problems (the full DEM without launch
   points, and the demo area with one base), k = 0 and 1: coverage time, ratio
   to RT and to the makespan lower bound, snapshots, planning seconds.
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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="k = 0 only")
    args, _ = ap.parse_known_args(argv)  # options of other benchmarks run with it
    warnings.simplefilter("ignore", UserWarning)
    time_gcs_plan()
    print()
    compare_methods(args.quick)


if __name__ == "__main__":
    main()
