"""Evaluation of routes: their times, each target's sightings, the coverage time.

A target's sightings count distinct UAVs at distinct places (`places`); the
coverage time is when the last target first has all it needs.
"""

import math

import numpy as np
from numba import njit

from .places import Places, matched_counts, matched_times
from .prepared import csc_transpose
from .problem import Allocation, CoverageProblem
from .routes import arrival_times


@njit(cache=True)
def _first_seen(route, arrivals, vis_indptr, vis_indices, first_r):
    for i in range(len(route)):
        e = route[i]
        for j in range(vis_indptr[e], vis_indptr[e + 1]):
            t = vis_indices[j]
            if arrivals[i] < first_r[t]:
                first_r[t] = arrivals[i]


def last_needed_sighting(problem: CoverageProblem, routes, arrivals, need) -> float:
    """When the last target with ``need[t]`` > 0 first has need[t] sightings from
    distinct UAVs at distinct places (`places`), from each route's snapshot times
    ``arrivals[r]`` (inf if never)."""
    times = needed_times(problem, routes, arrivals, need)
    return float(times[np.asarray(need) > 0].max(initial=0.0))


def needed_times(problem: CoverageProblem, routes, arrivals, need) -> np.ndarray:
    """Per target, when it first has ``need[t]`` sightings from distinct UAVs at
    distinct places (inf: never; 0 when it needs none). The distinct-UAV count,
    one UAV at a time keeping the need earliest per target (a [UAVs, targets]
    table of times would take 2 GiB on a 4096² area), is exact except for
    targets seen from a viewpoint two UAVs fly: those are matched (`places`)."""
    need = np.asarray(need)
    q = int(np.max(need, initial=0))
    out = np.zeros(problem.n_targets)
    if q == 0:
        return out
    best = np.full((q, problem.n_targets), np.inf)
    first = np.empty(problem.n_targets)
    before = problem.seen_before() if problem.seen is not None or problem.visited is not None \
        else None
    for r, route in enumerate(routes):
        first.fill(np.inf)
        if before is not None:
            first[before[r]] = 0.0
        _first_seen(np.asarray(route, np.int64), np.asarray(arrivals[r], float),
                    problem.vis_indptr, problem.vis_indices, first)
        _keep_earliest(best, first)
    rows = np.clip(need, 1, q) - 1
    out = np.where(need > 0, best[rows, np.arange(len(need))], 0.0)
    places = Places(problem.n_uavs, problem.n_viewpoints, routes, arrivals, problem.visited)
    if places.shared.any():
        t_indptr, t_indices, own = _columns(problem)
        hit = places.affected(problem.vis_indptr, problem.vis_indices, problem.n_targets)
        out[hit] = matched_times(hit, places.at, t_indptr, t_indices, own, need)
    return out


def _columns(problem):
    """(target -> viewpoints CSC, seen before planning from places of their own as
    uint8 [UAVs, targets]): the types `prepare` gives the same kernels (each other
    set of types is compiled again, seconds to a minute)."""
    t_indptr, t_indices = csc_transpose(np.asarray(problem.vis_indptr, np.int64),
                                        np.asarray(problem.vis_indices), problem.n_targets)
    return t_indptr, t_indices, problem.own_matrix().astype(np.uint8)


@njit(cache=True)
def _keep_earliest(best, first):
    """Insert first[t] into the ascending column best[:, t]."""
    q = best.shape[0]
    for t in range(best.shape[1]):
        v = first[t]
        i = q
        while i > 0 and best[i - 1, t] > v:
            i -= 1
        if i < q:
            for j in range(q - 1, i, -1):
                best[j, t] = best[j - 1, t]
            best[i, t] = v


def evaluate(prep, routes, method: str, steps=None, planning_s=0.0) -> Allocation:
    """Times and coverage of ``routes`` recomputed from the travel model, sightings
    counted by the places rule (`places`)."""
    n = prep.problem.n_uavs
    times = np.zeros(n)
    back = np.zeros(n)
    arrivals = []
    for r, route in enumerate(routes):
        arr = np.asarray(route, dtype=np.int64)
        arrivals.append(arrival_times(arr, prep.travel, prep.battery(r), prep.has_launch))
        times[r] = arrivals[-1][-1] if len(arr) else 0.0
        back[r] = times[r] + (prep.launch_back[r, arr[-1]] if prep.has_launch and len(arr) else 0.0)
    counts = sighting_counts(prep.problem, routes)
    covered = bool(np.all(counts >= prep.required))
    cov_t = (needed_times(prep.problem, routes, arrivals, prep.required).max(initial=0.0)
             if covered else math.inf)
    return Allocation(method=method, routes=[list(map(int, r)) for r in routes], times=times,
                      return_times=back, coverage_time=float(cov_t),
                      mission_time=float(back.max()) if n else 0.0, sum_time=float(times.sum()),
                      n_snapshots=int(sum(len(r) for r in routes)), covered=covered,
                      uncoverable=prep.uncoverable, planning_s=planning_s,
                      steps=list(steps or []))


def coverage_counts(problem: CoverageProblem, allocation: Allocation) -> np.ndarray:
    """Per target, its sightings from distinct UAVs at distinct places (including
    earlier snapshots)."""
    return sighting_counts(problem, allocation.routes)


def sighting_counts(problem: CoverageProblem, routes) -> np.ndarray:
    """Per target, its sightings from distinct UAVs at distinct places: the number
    of distinct UAVs, matched where a viewpoint is flown by two (`places`)."""
    indptr, indices = problem.vis_indptr, problem.vis_indices
    seen = problem.seen_before()
    for r, route in enumerate(routes):
        if len(route):
            seen[r, np.concatenate([indices[indptr[e]:indptr[e + 1]] for e in route])] = True
    counts = seen.sum(axis=0)
    places = Places(problem.n_uavs, problem.n_viewpoints, routes,
                    [np.zeros(len(r)) for r in routes], problem.visited)
    if places.shared.any():
        t_indptr, t_indices, own = _columns(problem)
        hit = places.affected(indptr, indices, problem.n_targets)
        counts[hit] = matched_counts(hit, places.at, t_indptr, t_indices, own,
                                     np.full(problem.n_targets, problem.n_uavs, np.int32))
    return counts
