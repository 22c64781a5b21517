"""Lower bounds on coverage time, and the proven optimum of small problems.

Modules, one bound each: radius (the reach and packing bounds: quick, for any
problem), flow (the first-sighting flow LP), routes (route pricing, where at most
30 viewpoints see what is needed), scatter (route pricing on a few far-apart places
of a larger problem), sorties (on a battery: targets no one sortie joins, and the
turnarounds between their sorties), takeoffs (the vehicles of a base take off one at a time: the
bounds of the timed plan), exact (the proven optimum of small plain
problems: the oracle of the tests and of ``bench_coverage --optimal``).
A new bound is a module here, taken into `lower_bounds`.
"""

from ..model.classes import target_classes
from ..model.prepared import prepare
from ..model.problem import CoverageProblem
from .flow import flow_bound
from .radius import radius_bound
from .routes import route_bound
from .scatter import SCATTER_TIME_LIMIT_S, scatter_bound
from .sorties import sortie_bound
from .takeoffs import delayed


def lower_bound(problem: CoverageProblem, strong: bool = True) -> float:
    """The best lower bound on coverage time we have (seconds): the largest of
    the reach and packing bounds (`radius.radius_bound`) and, with ``strong``,
    the first-sighting flow LP (`flow.flow_bound`; a few seconds of HiGHS on the
    largest problems) and, where at most 30 viewpoints see what is needed, the
    route-pricing bound (`routes.route_bound`: 0.3 s in the median case of
    17-30, a budget of 4 s), and beyond, the route-pricing bound on far-apart
    places (`scatter.scatter_bound`, within ``budget_s``).  The bounds work on
    target classes (`model.classes.target_classes`: identical rows, so the same
    bound at a fraction of the size)."""
    return lower_bounds(problem, strong)[1]


def lower_bounds(problem: CoverageProblem, strong: bool = True, prep=None,
                 budget_s: float = SCATTER_TIME_LIMIT_S, delays=None, usable_s=None) -> tuple:
    """(radius bound, best bound) in seconds: see `lower_bound`. ``prep``: the
    problem already prepared (`model.prepared.prepare`), to share its target classes;
    ``budget_s``: the scattered bound's time (a plan gives a share of its search's);
    ``delays``: per UAV, the least wait for its base before its takeoff on the fleet
    clock (`takeoffs`): the bounds are then of the timed plan; ``usable_s``: the
    flight one sortie of the plan may take (default the problem's endurance: a
    search on a battery scaled down for the flown sorties' slowing has less)."""
    prep = prep if prep is not None else prepare(problem)
    cprep = target_classes(prep)[0] if problem.n_targets else prep
    # a takeoff's wait is not flight: the battery's reach is judged without it
    sorties = sortie_bound(cprep, problem.endurance_s if usable_s is None else usable_s) \
        if strong else 0.0
    cprep = delayed(cprep, delays)
    radius = radius_bound(cprep)
    best = max(radius, flow_bound(cprep), sorties) if strong else radius
    if strong:
        best = max(best, route_bound(cprep, best))
        best = max(best, scatter_bound(cprep, best, budget_s))
    return float(radius), float(best)


__all__ = ["flow_bound", "lower_bound", "lower_bounds", "radius_bound", "route_bound",
           "scatter_bound", "sortie_bound"]
