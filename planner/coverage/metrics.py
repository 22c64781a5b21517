"""Evaluation of routes (times, coverage) and the lower bound on coverage time."""

import math

import numpy as np
from numba import njit

from .insertion import arrival_times, nearest_other
from .places import Places, _max_matching, matched_counts, matched_times
from .problem import Allocation, CoverageProblem, csc_transpose, prepare


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
    uint8 [UAVs, targets])."""
    t_indptr, t_indices = csc_transpose(np.asarray(problem.vis_indptr, np.int64),
                                        np.asarray(problem.vis_indices), problem.n_targets)
    return t_indptr, t_indices.astype(np.int64), problem.own_matrix().astype(np.uint8)


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
        arrivals.append(arrival_times(arr, prep.travel, prep.frames[r], prep.sorties[r],
                                      prep.has_launch))
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
                                     np.full(problem.n_targets, problem.n_uavs, np.int64))
    return counts


def lower_bound(problem: CoverageProblem) -> float:
    """A lower bound on coverage time (seconds), the larger of two valid bounds.

    * Reach bound (only with launch points): a target t needs ``req[t]``
      distinct UAVs; UAV r reaches it no sooner than the shortest time from
      its launch point to any viewpoint e seeing t (via other viewpoints too,
      in case ``launch_out`` is not closed under shortest paths; 0 if r saw t
      before planning).  The
      req[t]-th smallest of these over UAVs, maximised over targets.
    * Packing bound (any setting): targets no two of which share a viewpoint
      need pairwise different viewpoints.  Every visit of a viewpoint costs at
      least its cheapest way in (the nearest other viewpoint, or launch), the
      first visit of each UAV is free without launch points, and the busiest
      UAV flies at least the average of the total.

    Without launch points the reach bound is 0 (a UAV may start on any
    viewpoint), so only the packing bound remains and it is loose.
    """
    prep = prepare(problem)
    return max(_reach_bound(prep), _packing_bound(prep))


@njit(cache=True)
def _earliest_arrival(lo, travel_t):
    """Shortest time from launch to each viewpoint, also via other viewpoints.

    Bellman-Ford relaxation: one sweep when ``travel`` is already closed under
    shortest paths (as hidden travel times are), more otherwise.
    """
    out = lo.copy()
    n_vp = len(lo)
    changed = True
    while changed:
        changed = False
        for e in range(n_vp):
            best = out[e]
            for f in range(n_vp):
                c = out[f] + travel_t[e, f]
                if c < best:
                    best = c
            if best < out[e]:
                out[e] = best
                changed = True
    return out


#: the reach bound is matched over places (`place_reach_bound`) up to this many
#: (UAV, viewpoint, target) triples; beyond, the distinct-UAV form (a weaker bound)
PLACE_REACH_WORK = 50_000_000


def _reach_bound(prep) -> float:
    if not prep.has_launch:
        return 0.0
    # UAVs sharing a launch point share their earliest arrivals
    rows, uav_row = np.unique(prep.launch_out, axis=0, return_inverse=True)
    arrive = np.array([_earliest_arrival(row, prep.travel_t) for row in rows])
    bound = float(reach_bound_of(arrive, uav_row.ravel(), prep.vis_indptr, prep.vis_indices,
                                 prep.seen0, prep.required))
    if len(prep.tgt_indices) * prep.problem.n_uavs <= PLACE_REACH_WORK:
        bound = max(bound, place_reach_bound(arrive, uav_row.ravel(), prep.tgt_indptr,
                                             prep.tgt_indices, prep.seen0, prep.required))
    return bound


@njit(cache=True)
def place_reach_bound(arrive, row_of, tgt_indptr, tgt_indices, seen, required):
    """The reach bound with the places rule: per target, the earliest time by which
    ``required[t]`` UAVs can each be at a different place seeing it (a bottleneck
    matching of UAVs to its viewpoints, each at its earliest arrival; a sighting
    before planning is a place of its own, at 0); the latest over targets."""
    n = len(row_of)
    worst = 0.0
    for t in range(len(tgt_indptr) - 1):
        q = required[t]
        if q <= 0:
            continue
        deg = tgt_indptr[t + 1] - tgt_indptr[t]
        m = n * deg + n
        er = np.empty(m, np.int64)
        ep = np.empty(m, np.int64)
        et = np.empty(m)
        k = 0
        for u in range(n):
            if seen[u, t]:
                er[k], ep[k], et[k] = u, -1 - u, 0.0
                k += 1
            for i in range(tgt_indptr[t], tgt_indptr[t + 1]):
                e = tgt_indices[i]
                if arrive[row_of[u], e] < np.inf:
                    er[k], ep[k], et[k] = u, e, arrive[row_of[u], e]
                    k += 1
        order = np.argsort(et[:k], kind="mergesort")
        er, ep, et = er[order], ep[order], et[order]
        done = np.inf
        for a in range(q - 1, k):
            if _max_matching(er, ep, a + 1, n, q) >= q:
                done = et[a]
                break
        if done > worst:
            worst = done
    return worst


@njit(cache=True)
def reach_bound_of(arrive, row_of, indptr, indices, seen, required):
    """The reach bound from each UAV u's earliest arrival at every viewpoint,
    ``arrive[row_of[u]]`` (one row per distinct start, not per UAV: [UAVs,
    targets] times would take 2 GiB on a 4096² area): per target, the
    required-th earliest over UAVs of its first sighting (0 if ``seen`` before
    planning); the latest of those over targets."""
    n_rows, n_t = arrive.shape[0], seen.shape[1]
    first = np.full((n_rows, n_t), np.inf)
    for k in range(n_rows):
        for e in range(len(indptr) - 1):
            for j in range(indptr[e], indptr[e + 1]):
                t = indices[j]
                if arrive[k, e] < first[k, t]:
                    first[k, t] = arrive[k, e]
    worst = 0.0
    times = np.empty(len(row_of))
    for t in range(n_t):
        q = required[t]
        if q <= 0:
            continue
        for u in range(len(row_of)):
            times[u] = 0.0 if seen[u, t] else first[row_of[u], t]
        v = np.sort(times)[min(q, len(row_of)) - 1]
        if v > worst:
            worst = v
    return worst


def _packing_bound(prep) -> float:
    n = prep.problem.n_uavs
    if prep.problem.n_viewpoints == 0:
        return 0.0
    way_in = nearest_other(prep.travel, 0)  # cheapest arrival at each viewpoint from another
    if prep.has_launch:
        way_in = np.minimum(way_in, prep.launch_out.min(axis=0))
    degree = np.diff(prep.tgt_indptr)
    blocked = np.zeros(prep.problem.n_viewpoints, dtype=bool)
    costs = []
    for t in np.argsort(degree, kind="stable"):
        need = prep.required[t] - int(prep.seen0[:, t].sum())
        if need <= 0 or degree[t] == 0:
            continue
        vps = prep.tgt_indices[prep.tgt_indptr[t]:prep.tgt_indptr[t + 1]]
        if blocked[vps].any():
            continue
        blocked[vps] = True  # a later packed target may share none of them
        costs.extend([float(way_in[vps].min())] * need)
    costs = np.sort(np.asarray(costs))
    if not prep.has_launch:
        costs = costs[:max(len(costs) - n, 0)]  # the n dearest visits may be free starts
    costs = costs[np.isfinite(costs)]
    return float(costs.sum() / n) if len(costs) else 0.0

