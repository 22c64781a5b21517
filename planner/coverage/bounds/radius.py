"""The radius bound on coverage time: the larger of the reach and packing bounds.

* Reach bound (only with launch points): a target t needs ``req[t]``
  distinct UAVs; UAV r reaches it no sooner than the shortest time from
  its launch point to any viewpoint e seeing t (via other viewpoints too,
  in case ``launch_out`` is not closed under shortest paths; 0 if r saw t
  before planning).  The req[t]-th smallest of these over UAVs, maximised
  over targets; matched over places (`place_reach_bound`: distinct UAVs at
  distinct viewpoints) where that is affordable.
* Packing bound (any setting): targets no two of which share a viewpoint
  need pairwise different viewpoints.  Every visit of a viewpoint costs at
  least its cheapest way in (the nearest other viewpoint, or launch), the
  first visit of each UAV is free without launch points, and the busiest
  UAV flies at least the average of the total.

Without launch points the reach bound is 0 (a UAV may start on any
viewpoint), so only the packing bound remains and it is loose. Both are quick;
`flow` and `routes` are the strong bounds.
"""

import numpy as np
from numba import njit

from ..model.places import matched_time
from ..model.routes import nearest_other


def radius_bound(prep) -> float:
    """The larger of the reach and packing bounds of a prepared problem, seconds."""
    return max(reach_bound(prep), packing_bound(prep))


@njit(cache=True)
def earliest_arrival(lo, travel_t):
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


def reach_bound(prep) -> float:
    """The reach bound of a prepared problem (module doc), 0 without launch points."""
    if not prep.has_launch:
        return 0.0
    # UAVs sharing a launch point share their earliest arrivals
    rows, uav_row = np.unique(prep.launch_out, axis=0, return_inverse=True)
    arrive = np.array([earliest_arrival(row, prep.travel_t) for row in rows])
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
    worst = 0.0
    for t in range(len(tgt_indptr) - 1):
        if required[t] > 0:
            worst = max(worst, matched_time(t, arrive, row_of, tgt_indptr, tgt_indices, seen,
                                            required[t]))
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


def packing_bound(prep) -> float:
    """The packing bound of a prepared problem (module doc)."""
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
