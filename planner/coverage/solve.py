"""Entry point: run one registered coverage method on a problem.

Each method lives with the code it is made of and registers itself there
(`methods.register`): rt and rd in greedy, rt+ls in local_search, b and c in
baselines. Importing them here fills the registry; `METHODS` is its order.
"""

import time

from . import baselines, greedy, local_search  # noqa: F401 - they register the methods
from .methods import REGISTRY, method
from .metrics import evaluate
from .problem import Allocation, CoverageParams, CoverageProblem, prepare

METHODS = tuple(REGISTRY)


def solve(problem: CoverageProblem, name: str = "rt", params: CoverageParams = None,
          progress=None) -> Allocation:
    """Allocate viewpoints to UAVs by the method ``name``; ``progress(fraction)`` is
    called as it goes. Raises ValueError for an unknown method or k >= n_uavs."""
    chosen = method(name)
    params = params or CoverageParams()
    start = time.perf_counter()
    prep = prepare(problem)
    routes, steps = chosen.run(prep, params, progress)
    return evaluate(prep, routes, name, steps, time.perf_counter() - start)
