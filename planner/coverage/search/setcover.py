"""Greedy dominating set: the fewest viewpoints that see every target (k+1 times).

The classic greedy set cover (ln-approximation): repeatedly take the
viewpoint that sees the most targets still short of cover.  For k > 0 it is a
multicover: each target needs ``need[t]`` *different* viewpoints; giving those
to distinct UAVs is left to the assignment (and its repair).
"""

import numpy as np
from numba import njit

from ..model.problem import FREE


@njit(cache=True)
def greedy_cover(vis_indptr, vis_indices, tgt_indptr, tgt_indices, need, allowed):
    """Viewpoint ids chosen in greedy order; ``need`` is consumed (left > 0 = uncoverable)."""
    n_vp = len(vis_indptr) - 1
    gain = np.zeros(n_vp, dtype=np.int64)
    for e in range(n_vp):
        if allowed[e]:
            for j in range(vis_indptr[e], vis_indptr[e + 1]):
                if need[vis_indices[j]] > 0:
                    gain[e] += 1
    chosen = []
    while True:
        best, be = 0, -1
        for e in range(n_vp):
            if gain[e] > best:
                best, be = gain[e], e
        if be < 0:
            break
        chosen.append(be)
        gain[be] = 0
        allowed[be] = False
        for j in range(vis_indptr[be], vis_indptr[be + 1]):
            t = vis_indices[j]
            if need[t] <= 0:
                continue
            need[t] -= 1
            if need[t] == 0:
                for i in range(tgt_indptr[t], tgt_indptr[t + 1]):
                    x = tgt_indices[i]
                    if allowed[x]:
                        gain[x] -= 1
    return np.array(chosen, dtype=np.int64)


def dominating_set(prep, need=None, allowed=None) -> np.ndarray:
    """Greedy (multi)cover of the targets' remaining requirement, from the viewpoints
    ``allowed`` that are free: a viewpoint beyond one battery is closed to all, and
    one photographed from before gives its owner nothing new and the others only a
    shared place (left to `places.share`), and the routing that follows may give
    a viewpoint to any UAV."""
    if need is None:
        need = prep.required - prep.seen0.sum(axis=0)
    need = np.maximum(np.asarray(need, dtype=np.int64), 0)
    open_ = prep.owner0 == FREE
    allowed = open_ if allowed is None else allowed & open_
    return greedy_cover(prep.vis_indptr, prep.vis_indices, prep.tgt_indptr, prep.tgt_indices,
                        need, allowed)
