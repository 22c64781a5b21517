"""The scattered route bound: the route-pricing relaxation on a few far-apart places of
a large problem, so that the bound of a real area uses the fleet size, k and the
travel times.

**The relaxation.** `routes.route_bound` prices every route set of the useful
viewpoints exactly, which 30 of them allow. Its argument holds on any subset U of
them (`routes._subsets` uses it): a route through S takes at least its time
through S & U (shortcut in the shortest-path closure), and of the q sightings a
target needs, at distinct places, at most one is at each of its viewers outside
U, so q less that many are by distinct UAVs at viewers in U. So the route master
on U alone (`routes.RouteMaster`: each route counts a target once and lasts at
most T; the times T refuted by a dual certificate checked on every route set of
U, `routes.refute`) is a lower bound of the whole problem, however large, and a
time limit stops it with the best time refuted so far (a valid bound at every step).

**Choosing U.** The bound is strong when U holds places a plan cannot avoid, far
from the bases and from each other: then n routes within T must reach them all,
and k+1 distinct routes the viewers of each such target. An *anchor* is a target
with few viewers beyond the sightings it needs (`SLACKS`); all its viewers
go into U, which makes its row ask for all its q sightings. Anchors are taken
farthest first (`scattered_places`: farthest-point sampling in travel time, the
bases counting as taken), until U holds `size` viewpoints.

**Cost.** U of m viewpoints: m Dijkstra rows over the whole travel matrix (the
closure), then the route sets of U within the horizon (`routes.feasible_sets`:
at most 2^m, far fewer on far-apart places) and a small LP per time tried. U
grows (`SIZES`) while the time limit allows and the route sets stay below
`routes.MAX_SETS`; the best bound of the subsets tried is kept.

Not covered: a battery (sorties: 0, as `routes.route_bound`), and what lies
between the anchors (the bound knows only the places in U, so an area swept
densely between them is bounded by the tour through its anchors).
"""

import math
import time

import numpy as np

from .routes import (
    ROUTE_MAX_VIEWPOINTS,
    RouteMaster,
    compile_kernels,
    refute,
    still_needed,
    times_into,
    useful_viewpoints,
)

#: the sizes of U tried, in turn, while time is left
SIZES = (12, 16, 20, 24, 28, 32, 36, 40)
#: an anchor has at most this many viewers beyond the sightings it needs: the first,
#: then the next while room is left (a tighter anchor costs fewer places of U)
SLACKS = (1, 3, 8)
#: how many times longer the route sets of the next size take to find, at most (measured
#: 3-11 times on a 200-viewpoint problem, 12 -> 16 -> 20 -> 24): a size is not tried when
#: its sets would not be found within the time limit (their search is not interruptible)
NEXT_SIZE_COST = 12.0
#: default time limit (seconds); the plan gives its own (`bounds.lower_bounds`)
SCATTER_TIME_LIMIT_S = 4.0


def scatter_bound(prep, lower, time_limit=SCATTER_TIME_LIMIT_S, rel_tol=1e-3, sizes=SIZES,
                  min_useful=ROUTE_MAX_VIEWPOINTS + 1) -> float:
    """The scattered route bound of a prepared problem (module doc), seconds, tried on
    the subsets of ``sizes`` viewpoints in turn: 0 with fewer than ``min_useful``
    useful viewpoints (by default where `routes.route_bound` prices them all), with a
    battery, or when nothing above ``lower`` (a valid bound, > 0) is refuted."""
    p = prep.problem
    if p.n_viewpoints == 0 or p.n_targets == 0 or math.isfinite(p.endurance_s) or lower <= 0:
        return 0.0
    if np.count_nonzero(useful_viewpoints(prep)) < min_useful:
        return 0.0
    compile_kernels()
    deadline = time.perf_counter() + time_limit
    best, tried, columns = 0.0, set(), {}
    for size in sizes:
        if time.perf_counter() >= deadline:
            break
        vps = scattered_places(prep, size)
        if len(vps) < 2 or tuple(vps) in tried or len(vps) > 62:
            continue
        tried.add(tuple(vps))
        missing = [v for v in vps if v not in columns]
        if missing:  # the closure's columns, once each over the sizes
            got = times_into(prep.travel_t, np.array(missing, np.int64))
            columns.update({v: got[:, i] for i, v in enumerate(missing)})
        into = np.stack([columns[v] for v in vps], axis=1)
        rm = RouteMaster(prep, vps, into)
        best = max(best, refute(rm, max(lower, best), rel_tol, deadline))
        if rm.overflowed or time.perf_counter() + NEXT_SIZE_COST * rm.build_s > deadline:
            break   # a larger U has more route sets still: it would overrun the limit
    return best


def scattered_places(prep, size) -> np.ndarray:
    """Sorted viewpoint ids, at most ``size``: the viewers of anchors (targets that
    need sightings, with at most `SLACKS`[i] viewers more than they need, the next
    slack once those are spent), the anchor whose nearest viewer is farthest from
    the bases and from the viewpoints taken first, each anchor's viewers together."""
    need = still_needed(prep)
    indptr = prep.tgt_indptr
    degree = np.diff(indptr)
    # distance of each viewpoint to what is taken: the bases at first (without
    # launch points, its farthest viewpoint: the anchors on the rim come first)
    dist = (prep.launch_out.min(axis=0).copy() if prep.has_launch
            else prep.travel.max(axis=0).copy())
    taken = []
    for slack in SLACKS:
        anchors = np.flatnonzero((need > 0) & (degree > 0) & (degree - need <= slack)
                                 & (degree <= size - len(taken)))
        if len(anchors):
            _take_anchors(prep, anchors, size, dist, taken)
    return np.array(sorted(taken), np.int64)


def _take_anchors(prep, anchors, size, dist, taken) -> None:
    """Farthest-point sampling of ``anchors`` into ``taken`` (at most ``size``
    viewpoints), ``dist`` kept as each viewpoint's distance to what is taken."""
    indptr, indices = prep.tgt_indptr, prep.tgt_indices
    lists = [indices[indptr[c]:indptr[c + 1]].astype(np.int64) for c in anchors]
    flat = np.concatenate(lists)
    starts = np.r_[0, np.cumsum([len(v) for v in lists])[:-1]]
    sizes = np.array([len(v) for v in lists])
    open_ = np.ones(len(anchors), bool)
    while True:
        fits = open_ & (sizes <= size - len(taken))
        if not fits.any():
            return
        score = np.minimum.reduceat(dist[flat], starts)
        a = int(np.flatnonzero(fits)[np.argmax(score[fits])])
        if score[a] <= 0.0:
            return  # every anchor left has a viewer taken already
        open_[a] = False
        new = [int(v) for v in lists[a] if int(v) not in taken]
        taken += new
        for v in new:  # both ways: a route may pass either way
            np.minimum(dist, np.minimum(prep.travel[v], prep.travel_t[v]), out=dist)


__all__ = ["scatter_bound", "scattered_places"]
