"""The independent check of the plans at scale (issue 63): OR-Tools' routing solver
plans the same problem at the wall time ALNS took, and `at_scale` prints its plan
beside ALNS's.

**The model.** The viewpoints are chosen first, as the field's two-stage coverage
planners do: the greedy (k+1)-fold cover at distinct places (`setcover.dominating_set`:
each target gets k+1 different viewpoints). OR-Tools then assigns and orders them over
the fleet (every chosen viewpoint a visit, each UAV from its launch, open routes: a
free end, as coverage time stops at the last snapshot), the makespan as a global span
cost on the time dimension, guided local search. That a target's k+1 sightings come
from *distinct* UAVs is said to the solver as constraints on the vehicle variables:
the k+1 places the cover chose for a target (its first viewers in the cover's order)
all on different UAVs (`AllDifferentExcept`, a visit left out being on none); every
visit is optional at a penalty above any makespan, so that a first solution exists.
A target still short (a visit left out) gets the constraint again on its first
chosen viewers and the model is solved again in the time left (lazy constraints); a
plan that covers is improved from there in the rest of the time. None of our search
(insertion, ALNS, local search) is used; the plan is timed and checked by
`model.evaluation.evaluate` like every other.
"""

import time
from dataclasses import replace

import numpy as np
from ortools.constraint_solver import pywrapcp, routing_enums_pb2

from planner.coverage.model.evaluation import evaluate, sighting_counts
from planner.coverage.search.routing import FORBIDDEN, SPAN_WEIGHT, solved_routes, transit_matrix
from planner.coverage.search.setcover import dominating_set

#: rounds of lazy distinct-UAV constraints at most
ROUNDS = 3


def ortools_plan(prep, time_limit_s: float):
    """(allocation, rounds): the OR-Tools plan of a prepared problem within about
    ``time_limit_s`` seconds (module doc); the allocation's ``covered`` is False
    when the time ran out with a target short of distinct UAVs."""
    began = time.perf_counter()
    chosen = dominating_set(prep)
    uavs = list(range(prep.problem.n_uavs))
    groups = _designated_groups(prep, chosen)
    alloc, rounds = None, 0
    while rounds < ROUNDS:
        left = time_limit_s - (time.perf_counter() - began)
        if left <= 0.5 and alloc is not None:
            break
        # the time left shared by the rounds left: a round with more constraints follows
        routes = _solve(prep, chosen, uavs, groups, max(left / (ROUNDS - rounds), 0.5))
        rounds += 1
        if routes is None:
            break
        alloc = evaluate(prep, routes, "ortools", planning_s=time.perf_counter() - began)
        if alloc.covered:   # the rest of the time: the search goes on from this plan
            left = time_limit_s - (time.perf_counter() - began)
            if left > 0.5:
                better = _solve(prep, chosen, uavs, groups, left, initial=routes)
                if better is not None:
                    other = evaluate(prep, better, "ortools",
                                     planning_s=time.perf_counter() - began)
                    alloc = other if other.covered and other.coverage_time <= \
                        alloc.coverage_time else replace(alloc, planning_s=other.planning_s)
            break
        groups |= _short_groups(prep, chosen, routes)
    return alloc, rounds


def _designated_groups(prep, chosen) -> set:
    """Per target needing two or more UAVs, its designated places: the first of its
    viewers in the greedy cover's order, as many as it needs (those the cover chose
    for it), as positions in ``chosen``: they must lie on distinct UAVs."""
    pos = np.full(prep.problem.n_viewpoints, len(chosen), np.int64)
    pos[chosen] = np.arange(len(chosen))     # greedy order; not chosen: last
    need = prep.required.astype(np.int64) - prep.seen0.sum(axis=0)
    groups = set()
    for t in np.flatnonzero(need >= 2):
        viewers = np.sort(pos[prep.tgt_indices[prep.tgt_indptr[t]:prep.tgt_indptr[t + 1]]])
        viewers = viewers[viewers < len(chosen)][:int(need[t])]
        if len(viewers) >= 2:
            groups.add(tuple(int(v) for v in viewers))
    return groups


def _short_groups(prep, chosen, routes) -> set:
    """For each target short of distinct UAVs in ``routes``: the first of its chosen
    viewers, as many as it needs, to lie on distinct UAVs."""
    counts = sighting_counts(prep.problem, routes)
    pos = np.full(prep.problem.n_viewpoints, -1, np.int64)
    pos[chosen] = np.arange(len(chosen))
    groups = set()
    for t in np.flatnonzero(counts < prep.required):
        viewers = pos[prep.tgt_indices[prep.tgt_indptr[t]:prep.tgt_indptr[t + 1]]]
        viewers = np.sort(viewers[viewers >= 0])[:int(prep.required[t])]
        if len(viewers) >= 2:
            groups.add(tuple(int(v) for v in viewers))
    return groups


def _solve(prep, chosen, uavs, groups, time_limit_s, initial=None):
    """Routes (viewpoint ids) of every chosen viewpoint over ``uavs``, the ``groups``
    on distinct UAVs, min makespan, from the routes ``initial`` if given; None when
    OR-Tools finds none in time."""
    mat, starts, end = transit_matrix(prep, np.asarray(chosen, np.int64), uavs)
    manager = pywrapcp.RoutingIndexManager(len(mat), len(uavs), starts, [end] * len(uavs))
    model = pywrapcp.RoutingModel(manager)
    transit = model.RegisterTransitMatrix(mat.tolist())
    model.SetArcCostEvaluatorOfAllVehicles(transit)
    model.AddDimension(transit, 0, int(mat[mat < FORBIDDEN].sum()) + 1, True, "time")
    model.GetDimensionOrDie("time").SetGlobalSpanCostCoefficient(SPAN_WEIGHT)
    # every visit optional at a penalty above any makespan, so that a first solution
    # exists under the distinct-UAV constraints (a visit left out: coverage short)
    penalty = SPAN_WEIGHT * (int(mat[mat < FORBIDDEN].sum()) + 1)
    for i in range(len(chosen)):
        model.AddDisjunction([manager.NodeToIndex(i)], penalty)
    solver = model.solver()
    for g in groups:   # -1: a visit left out, on no UAV
        solver.Add(solver.AllDifferentExcept(
            [model.VehicleVar(manager.NodeToIndex(i)) for i in g], -1))
    params = pywrapcp.DefaultRoutingSearchParameters()
    params.first_solution_strategy = (
        routing_enums_pb2.FirstSolutionStrategy.PARALLEL_CHEAPEST_INSERTION)
    params.local_search_metaheuristic = (
        routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH)
    params.time_limit.FromMilliseconds(int(time_limit_s * 1000))
    if initial is not None:
        index = {int(e): i for i, e in enumerate(chosen)}
        model.CloseModelWithParameters(params)
        start = model.ReadAssignmentFromRoutes(
            [[manager.NodeToIndex(index[e]) for e in r] for r in initial], True)
        solution = model.SolveFromAssignmentWithParameters(start, params) if start else None
    else:
        solution = model.SolveWithParameters(params)
    if solution is None:
        return None
    return solved_routes(model, manager, solution, len(uavs), chosen)
