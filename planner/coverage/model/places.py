"""Sightings from distinct places: the fault-tolerance rule, counted exactly.

A target needing k+1 sightings needs them from k+1 *distinct UAVs at distinct
viewpoints*: two UAVs photographing it from one place share one fate (one
outpost that spots the place, one collision), so they count once. What counts
for target t is therefore a maximum matching between UAVs and the places they
saw it from (König: with a requirement of 2 it is simply "two UAVs and two
places"). Sightings before planning (a re-plan's survivors) are at the
viewpoint they were taken from (`CoverageProblem.visited`: a visit at time
zero, so a survivor flying a viewpoint another one photographed from shares
its place), or, taken anywhere else, at a place of their own
(`CoverageProblem.seen`).

The methods keep a simpler invariant that implies the rule: each viewpoint is
flown by one UAV (`prepared.owners`), so distinct UAVs are distinct places and
the distinct-UAV counts are exact. On crowded problems that invariant can paint
a search into a corner (a viewpoint that is the last free place of targets that
each need a different UAV); `search.share.share` then lets a second UAV fly a
viewpoint where that gives a short target one more matched sighting. Only targets seen from a
viewpoint flown by two UAVs need the matching (`Places`); all others keep the
distinct-UAV count, which is cheap on the largest areas.
"""

import numpy as np
from numba import njit

from .routes import arrival_times


class Places:
    """Where and when a plan's UAVs photograph, for the exact rule.

    ``routes[r]``: viewpoint ids; ``when[r]``: the time of each visit (None: by
    the travel model of ``prep``); ``visited``: bool [n_uavs, n_viewpoints],
    visits before planning (at time zero). ``shared``: viewpoints flown by two
    or more UAVs; ``at``: [n_uavs, n_viewpoints] first visit times (inf: never)."""

    def __init__(self, n_uavs, n_viewpoints, routes, when, visited=None):
        self.at = np.full((n_uavs, n_viewpoints), np.inf)
        if visited is not None:
            self.at[np.asarray(visited, bool)] = 0.0
        for r, (route, w) in enumerate(zip(routes, when)):
            if len(route):
                _first_visits(np.asarray(route, np.int64), np.asarray(w, float), self.at[r])
        self.shared = (np.isfinite(self.at).sum(axis=0) >= 2)

    @classmethod
    def of(cls, prep, routes, when=None) -> "Places":
        if when is None:
            when = [arrival_times(np.asarray(r, np.int64), prep.travel, prep.battery(u),
                                  prep.has_launch) for u, r in enumerate(routes)]
        return cls(prep.problem.n_uavs, prep.problem.n_viewpoints, routes, when,
                   prep.visited0)

    def affected(self, vis_indptr, vis_indices, n_targets) -> np.ndarray:
        """Targets seen from a shared viewpoint: the only ones whose count is not the
        number of distinct UAVs."""
        mark = np.zeros(n_targets, bool)
        for e in np.flatnonzero(self.shared):
            mark[vis_indices[vis_indptr[e]:vis_indptr[e + 1]]] = True
        return np.flatnonzero(mark)


@njit(cache=True)
def _first_visits(route, when, out):
    for i in range(len(route)):
        if when[i] < out[route[i]]:
            out[route[i]] = when[i]


@njit(cache=True)
def matched_counts(targets, at, tgt_indptr, tgt_indices, seen0, cap):
    """Matched sightings (distinct UAVs at distinct places) of each of ``targets``,
    at most ``cap[t]``, over everything flown."""
    out = np.zeros(len(targets), np.int32)
    for k in range(len(targets)):
        t = targets[k]
        out[k] = count_with(t, at, tgt_indptr, tgt_indices, seen0, -1, -1, cap[t])
    return out


@njit(cache=True)
def matched_times(targets, at, tgt_indptr, tgt_indices, seen0, need):
    """When each of ``targets`` first has ``need[t]`` matched sightings (inf: never)."""
    rows = np.arange(at.shape[0])
    out = np.zeros(len(targets))
    for k in range(len(targets)):
        t = targets[k]
        if need[t] > 0:
            out[k] = matched_time(t, at, rows, tgt_indptr, tgt_indices, seen0, need[t])
    return out


@njit(cache=True)
def matched_time(t, at, row_of, tgt_indptr, tgt_indices, seen0, need):
    """When target t first has ``need`` matched sightings, UAV r photographing
    viewpoint e at ``at[row_of[r], e]`` (UAVs that share a row share their times:
    the reach bound's earliest arrivals, one row per start); inf: never."""
    er, ep, et = _sightings(t, at, row_of, tgt_indptr, tgt_indices, seen0)
    order = np.argsort(et, kind="mergesort")
    er, ep, et = er[order], ep[order], et[order]
    for a in range(need - 1, len(er)):      # fewer sightings than need match fewer
        if max_matching(er, ep, a + 1, len(row_of), need) >= need:
            return et[a]
    return np.inf


@njit(cache=True)
def count_with(t, at, tgt_indptr, tgt_indices, seen0, r, e, cap):
    """Matched sightings of target t, at most ``cap``, with UAV r also photographing
    from viewpoint e (r < 0: nothing more)."""
    er, ep, _ = _sightings(t, at, np.arange(at.shape[0]), tgt_indptr, tgt_indices, seen0)
    if r >= 0:
        er = np.append(er, r)
        ep = np.append(ep, e)
    return max_matching(er, ep, len(er), at.shape[0], cap)


@njit(cache=True)
def _sightings(t, at, row_of, tgt_indptr, tgt_indices, seen0):
    """(uav, place, time) of every sighting of t, UAV r's times ``at[row_of[r]]``: a
    viewpoint's place is its id, an earlier sighting from no viewpoint (``seen0``)
    is at a place of its own (-1 - uav)."""
    n = len(row_of)
    m = 0
    for r in range(n):
        if seen0[r, t]:
            m += 1
    for i in range(tgt_indptr[t], tgt_indptr[t + 1]):
        for r in range(n):
            if at[row_of[r], tgt_indices[i]] < np.inf:
                m += 1
    er = np.empty(m, np.int64)
    ep = np.empty(m, np.int64)
    et = np.empty(m)
    k = 0
    for r in range(n):
        if seen0[r, t]:
            er[k], ep[k], et[k] = r, -1 - r, 0.0
            k += 1
    for i in range(tgt_indptr[t], tgt_indptr[t + 1]):
        e = tgt_indices[i]
        for r in range(n):
            if at[row_of[r], e] < np.inf:
                er[k], ep[k], et[k] = r, e, at[row_of[r], e]
                k += 1
    return er, ep, et


@njit(cache=True)
def max_matching(er, ep, m, n, cap):
    """Size of a maximum matching (at most ``cap``) of the first m sightings
    (Kuhn's augmenting paths from each UAV)."""
    if m == 0:
        return 0
    places = np.unique(ep[:m])
    owner = np.full(len(places), -1, np.int64)          # place -> matched UAV
    size = 0
    for r in range(n):
        if size >= cap:
            break
        seen = np.zeros(len(places), np.bool_)
        if _augment(r, er, ep, m, places, owner, seen):
            size += 1
    return size


@njit(cache=True)
def _augment(r, er, ep, m, places, owner, seen):
    for a in range(m):
        if er[a] != r:
            continue
        p = np.searchsorted(places, ep[a])
        if seen[p]:
            continue
        seen[p] = True
        if owner[p] < 0 or _augment(owner[p], er, ep, m, places, owner, seen):
            owner[p] = r
            return True
    return False
