"""Every method and the best bound against proven optima (``bench_coverage --optimal``).

The instances are `instances.optimality_case` for seeds 0..N-1 (8-16
viewpoints, 2-4 UAVs, k = 0..n-1, launch points or none, the three families).
Their optima come from `planner.coverage.bounds.exact.optimum` (started from the
default method's plan) and are kept in `CACHE` with the solver's proof status
and time: an instance is solved once, and again only if it was not proven. Per
method: median and worst coverage time / optimum, how many plans are optimal
(within 1e-6), median planning time; the best lower bound's median and lowest
ratio to the optimum and its median time. Only proven instances with a
non-zero optimum count. The table is given twice: for the seeds below `TUNED`,
which the methods' settings were chosen on, and for the seeds held out from that
(130-229, added on 2026-11-29 after ALNS's restarts were chosen on 0-129).
"""

import json
import time
from pathlib import Path

import numpy as np

from planner.coverage import METHODS, lower_bound, solve
from planner.coverage.bounds.exact import optimum
from planner.coverage.model.instances import optimality_case
from planner.scenario import Scenario

CACHE = Path(__file__).resolve().parent / "coverage_optimal.json"
#: the mid-size set (``--optimal-mid``): 17-30 viewpoints, seeds from MID_FIRST, none
#: of them tuned on; its optima take up to minutes each, and some are not proven
MID_CACHE = CACHE.with_name("coverage_optimal_mid.json")
MID_FIRST, MID_SIZES = 1000, (17, 30)
EQUAL = 1e-6
DEFAULT_METHOD = Scenario.method
#: seeds 0..TUNED-1 are the instances ALNS's settings were chosen on; the rest are held out
TUNED = 130


def _load(cache: Path) -> dict:
    return json.loads(cache.read_text())["cases"] if cache.exists() else {}


def _save(cases: dict, cache: Path) -> None:
    cache.write_text(json.dumps({"solver": "planner.coverage.bounds.exact.optimum",
                                 "cases": dict(sorted(cases.items()))}, indent=1) + "\n")


def optima(problems, limit_s: float, cache: Path = CACHE, seeds=None) -> dict:
    """name -> cached record of each (name, problem), solving what is missing or
    unproven (saved as it goes; records of other problems are dropped)."""
    cases = {name: rec for name, rec in _load(cache).items() if name in dict(problems)}
    seeds = range(len(problems)) if seeds is None else seeds
    for seed, (name, problem) in zip(seeds, problems):
        if cases.get(name, {}).get("proven"):
            continue
        start = solve(problem, DEFAULT_METHOD)
        found = optimum(problem, time_limit_s=limit_s, hint=start.routes)
        cases[name] = {"seed": seed, "value": found.value, "proven": found.proven,
                       "seconds": round(found.seconds, 2), "rounds": found.rounds}
        print(f"  {name}: optimum {found.value:.3f} s "
              f"{'proven' if found.proven else 'NOT proven'} in {found.seconds:.1f} s", flush=True)
        _save(cases, cache)
    return cases


def run(count: int = 230, limit_s: float = 60.0, mid: bool = False) -> dict:
    """The tables for seeds 0..count-1 of 8-16 viewpoints, or with ``mid`` for
    ``count`` seeds from `MID_FIRST` of 17-30 viewpoints (all held out)."""
    cache = MID_CACHE if mid else CACHE
    seeds = range(MID_FIRST, MID_FIRST + count) if mid else range(count)
    print(f"\n== Against proven optima ({count} instances, {cache.name}) ==", flush=True)
    problems = [optimality_case(seed, *MID_SIZES) if mid else optimality_case(seed)
                for seed in seeds]
    cases = optima(problems, limit_s, cache, seeds)
    rows, unproven = [], 0
    for seed, (name, problem) in zip(seeds, problems):
        rec = cases[name]
        if not rec["proven"] or rec["value"] <= 0:
            unproven += not rec["proven"]
            continue
        row = {"seed": seed}
        for m in METHODS:
            plan = solve(problem, m)
            row[m] = (plan.coverage_time / rec["value"], plan.planning_s)
        t = time.perf_counter()
        row["bound"] = (lower_bound(problem) / rec["value"], time.perf_counter() - t)
        rows.append(row)
    print(f"{len(rows)} instances with a proven non-zero optimum ({unproven} not proven)")
    if mid:
        _table(f"seeds {seeds[0]}-{seeds[-1]}, 17-30 viewpoints (held out)", rows)
        return {"rows": rows}
    for title, part in ((f"seeds 0-{TUNED - 1} (settings tuned on them)",
                         [r for r in rows if r["seed"] < TUNED]),
                        (f"seeds {TUNED}-{count - 1} (held out)",
                         [r for r in rows if r["seed"] >= TUNED])):
        if part:
            _table(title, part)
    return {"rows": rows}


def _table(title, rows) -> None:
    print(f"\n{title}: {len(rows)} instances")
    print(f"{'method':8s} {'median/OPT':>10s} {'worst/OPT':>10s} {'= OPT':>6s} {'plan s':>7s}")
    for m in METHODS:
        r = np.array([row[m][0] for row in rows])
        worst = rows[int(np.argmax(r))]["seed"]
        print(f"{m:8s} {np.median(r):10.3f} {r.max():10.3f} {int((r <= 1 + EQUAL).sum()):6d} "
              f"{np.median([row[m][1] for row in rows]):7.2f}   worst: seed {worst}")
    b = np.array([row["bound"][0] for row in rows])
    print(f"{'bound':8s} {np.median(b):10.3f} {b.min():10.3f} (lowest) "
          f"{int((b >= 1 - EQUAL).sum()):4d} {np.median([row['bound'][1] for row in rows]):7.2f}")
