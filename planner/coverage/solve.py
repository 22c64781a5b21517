"""Entry point: run one registered coverage method on a problem.

Each method lives with the code it is made of and registers itself there
(`methods.register`): rt and rd in greedy, rt+ls in local_search, b and c in
baselines, alns in alns. Importing them here fills the registry; `METHODS` (from
planner.scenario, light to import for the command line) is the order users see.
"""

import time

from . import alns, baselines, greedy, local_search  # noqa: F401 - they register the methods
from .methods import METHODS, REGISTRY, method
from .metrics import evaluate, sighting_counts
from .places import share
from .problem import Allocation, CoverageParams, CoverageProblem, prepare

assert set(REGISTRY) == set(METHODS), "every listed method registers itself"


def solve(problem: CoverageProblem, name: str = "rt", params: CoverageParams = None,
          progress=None, prep=None) -> Allocation:
    """Allocate viewpoints to UAVs by the method ``name``; ``progress(fraction)`` is
    called as it goes; ``prep``: the problem already prepared (`prepare`). Raises
    ValueError for an unknown method or k >= n_uavs."""
    chosen = method(name)
    params = params or CoverageParams()
    start = time.perf_counter()
    prep = prep if prep is not None else prepare(problem)
    routes, steps = chosen.run(prep, params, progress)
    allocation = evaluate(prep, routes, name, steps)
    if not allocation.covered:     # a viewpoint a second UAV must fly (`places.share`)
        routes = share(prep, routes, sighting_counts(prep.problem, routes))
        allocation = evaluate(prep, routes, name, steps)
    allocation.planning_s = time.perf_counter() - start
    return allocation
