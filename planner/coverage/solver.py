"""Entry point: run one registered coverage method on a problem.

Each method is a module of `methods`, registered there with its own settings;
`solve` looks it up, gives it its settings, runs it and evaluates its routes by
the model's rule (`model.evaluation`), with the last-resort repair of every
method where a target is left short (`search.share`).
"""

import time

from .methods import method
from .model.evaluation import evaluate, sighting_counts
from .model.prepared import prepare
from .model.problem import Allocation, CoverageProblem
from .search.share import share


def solve(problem: CoverageProblem, name: str = "rt", params=None, progress=None,
          prep=None) -> Allocation:
    """Allocate viewpoints to UAVs by the method ``name``; ``params``: its settings
    (its params dataclass, or a dict of settings by name, those of other methods
    left to them; None: the defaults); ``progress(fraction)`` is called as it goes;
    ``prep``: the problem already prepared (`prepare`). Raises ValueError for an
    unknown method or setting, or k >= n_uavs."""
    chosen = method(name)
    params = chosen.settings(params)
    start = time.perf_counter()
    prep = prep if prep is not None else prepare(problem)
    routes, steps = chosen.run(prep, params, progress)
    allocation = evaluate(prep, routes, name, steps)
    if not allocation.covered:     # a viewpoint a second UAV must fly (`search.share`)
        routes = share(prep, routes, sighting_counts(prep.problem, routes))
        allocation = evaluate(prep, routes, name, steps)
    allocation.planning_s = time.perf_counter() - start
    return allocation
