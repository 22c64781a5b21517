"""Entry point: run one coverage method on a problem."""

import time
from dataclasses import replace

from .baselines import solve_b, solve_c
from .greedy import allocate
from .local_search import local_search
from .metrics import evaluate
from .problem import Allocation, CoverageParams, CoverageProblem, prepare

METHODS = ("rt", "rt+ls", "rd", "b", "c")


def solve(problem: CoverageProblem, method: str = "rt", params: CoverageParams = None,
          progress=None) -> Allocation:
    """Allocate viewpoints to UAVs by ``method``; ``progress(fraction)`` is called as RT goes.

    Raises ValueError for an unknown method or k >= n_uavs.
    """
    if method not in METHODS:
        raise ValueError(f"unknown coverage method {method!r}; choose one of {', '.join(METHODS)}")
    params = params or CoverageParams()
    start = time.perf_counter()
    prep = prepare(problem)
    steps = []
    if method == "rt":
        routes, steps = allocate(prep, params, "ptv", progress=progress)
    elif method == "rt+ls":
        routes, steps = _rt_ls(prep, params, progress)
    elif method == "rd":
        routes, steps = allocate(prep, params, "per_distance", progress=progress)
    elif method == "b":
        routes = solve_b(prep, params)
    else:
        routes = solve_c(prep, params)
    return evaluate(prep, routes, method, steps, time.perf_counter() - start)


def _rt_ls(prep, params, progress):
    """RT, then local search; restarted with th_ra halved and doubled, best kept.

    The first start is plain RT with ``params``, so the result is never worse
    than RT.  Restarts only apply when th_ra comes from the factor.
    """
    factors = [params.step_cap_factor]
    if params.step_time_cap is None:
        factors += [params.step_cap_factor * f for f in (0.5, 2.0)][:max(params.ls_starts - 1, 0)]
    best = None
    for i, factor in enumerate(factors):
        p = replace(params, step_cap_factor=factor)
        routes, steps = allocate(prep, p, "ptv", progress=progress if i == 0 else None)
        candidates = [routes, local_search(prep, routes, params.ls_rounds)]
        for r in candidates:
            a = evaluate(prep, r, "rt+ls")
            if a.covered and (best is None or a.coverage_time < best[0] - 1e-9):
                best = (a.coverage_time, r, steps)
    return best[1], best[2]
