"""The last resort of every method: a second UAV flies a viewpoint another one flies.

The methods give each viewpoint to one UAV (`model.prepared.owners`); on
crowded problems that can leave a target short of sightings that only a
viewpoint already flown could give. `share` then adds the fewest extra visits
that give every short target its requirement by the exact count
(`model.places`: distinct UAVs at distinct places, matched).
"""

import numpy as np

from ..model.places import Places, count_with, matched_counts
from ..model.problem import CLOSED
from ..model.routes import route_time
from .insertion import insert_cost


def share(prep, routes, counts) -> list:
    """``routes`` with the fewest extra visits, each at its cheapest slot, that give
    every short target its requirement by the exact count (``counts``: the
    current count of every target): the longest route grows least first. A
    target no visit can help stays short."""
    routes = [np.asarray(r, np.int64) for r in routes]
    counts = np.array(counts, np.int32)
    n = prep.problem.n_uavs
    while True:
        short = np.flatnonzero(counts < prep.required)
        if not len(short):
            break
        at = Places.of(prep, routes).at
        times = np.array([route_time(r, prep.travel, prep.battery(u), prep.has_launch)
                          for u, r in enumerate(routes)])
        best = None
        for t in short:
            for e in prep.tgt_indices[prep.tgt_indptr[t]:prep.tgt_indptr[t + 1]]:
                for r in range(n):
                    if np.isfinite(at[r, e]) or prep.owner0[e] == CLOSED:
                        continue
                    if count_with(t, at, prep.tgt_indptr, prep.tgt_indices, prep.own0, r, e,
                                  prep.required[t]) <= counts[t]:
                        continue
                    dt, pos = insert_cost(routes[r], e, prep.travel, prep.battery(r),
                                          prep.has_launch)
                    if not np.isfinite(dt):     # beyond r's battery from its bases
                        continue
                    key = (max(times[r] + dt, times.max()), dt)
                    if best is None or key < best[0]:
                        best = (key, r, int(e), int(pos))
        if best is None:
            break
        _, r, e, pos = best
        routes[r] = np.insert(routes[r], pos, e)
        at = Places.of(prep, routes).at
        touched = prep.vis_indices[prep.vis_indptr[e]:prep.vis_indptr[e + 1]].astype(np.int64)
        counts[touched] = np.maximum(counts[touched], matched_counts(
            touched, at, prep.tgt_indptr, prep.tgt_indices, prep.own0, prep.required))
    return [list(map(int, r)) for r in routes]
