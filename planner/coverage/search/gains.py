"""Fault-tolerant visibility V(e, r), kept up to date incrementally.

V is evaluated per (viewpoint, UAV) because ``seen_count`` counts distinct
UAVs: a target UAV r has already seen adds nothing to r's gain.  A target t
still short of its requirement ``req[t]`` with ``c`` distinct viewers weighs

* hard: 1,
* soft: ``(req[t] - c) ** (n/k)`` (the paper's ``(k+1 - seen_count)^(n/k)``),

and 0 once ``c >= req[t]``.  For k = 0 both count unseen targets.

Gains only decrease as targets get covered, so instead of a lazy heap the
exact V matrix is maintained: when UAV r takes viewpoint e, each target of e
that r had not seen changes weight, and the change is pushed to every
viewpoint that sees it (the CSC lists).  Each target changes at most
``req[t]`` times, so the total work is O(nnz * (k+1) * n_uavs) over a run.
"""

import numpy as np
from numba import njit

# V below this is zero: every positive weight is >= 1, float drift is tiny.
POSITIVE = 0.5


@njit(cache=True)
def target_weight(c, req, soft, p):
    if c >= req:
        return 0.0
    if soft:
        return float(req - c) ** p
    return 1.0


@njit(cache=True)
def initial_gains(vis_indptr, vis_indices, seen, count, req, soft, p):
    n_vp = len(vis_indptr) - 1
    n_uavs = seen.shape[0]
    gains = np.zeros((n_vp, n_uavs))
    for e in range(n_vp):
        for j in range(vis_indptr[e], vis_indptr[e + 1]):
            t = vis_indices[j]
            w = target_weight(count[t], req[t], soft, p)
            if w == 0.0:
                continue
            for r in range(n_uavs):
                if seen[r, t] == 0:
                    gains[e, r] += w
    return gains


@njit(cache=True)
def take_viewpoint(e, r, vis_indptr, vis_indices, tgt_indptr, tgt_indices,
                   seen, count, req, gains, soft, p):
    """UAV r photographs from viewpoint e; returns how many targets became satisfied."""
    n_uavs = seen.shape[0]
    satisfied = 0
    for j in range(vis_indptr[e], vis_indptr[e + 1]):
        t = vis_indices[j]
        if seen[r, t]:
            continue
        seen[r, t] = 1
        c = count[t]
        count[t] = c + 1
        w_old = target_weight(c, req[t], soft, p)
        if w_old == 0.0:
            continue
        w_new = target_weight(c + 1, req[t], soft, p)
        if w_new == 0.0:
            satisfied += 1
        drop = w_old - w_new
        for i in range(tgt_indptr[t], tgt_indptr[t + 1]):
            x = tgt_indices[i]
            gains[x, r] -= w_old
            if drop != 0.0:
                for q in range(n_uavs):
                    if q != r and seen[q, t] == 0:
                        gains[x, q] -= drop
    return satisfied


class CoverState:
    """Who has seen what, how often, and the current gains V(e, r)."""

    def __init__(self, prep):
        self.prep = prep
        self.seen = prep.seen0.copy()
        self.count = self.seen.sum(axis=0, dtype=np.int32)
        self.gains = initial_gains(prep.vis_indptr, prep.vis_indices, self.seen, self.count,
                                   prep.required, prep.soft, prep.soft_exp)
        self.remaining = int(np.count_nonzero(self.count < prep.required))

    def take(self, e: int, r: int) -> None:
        p = self.prep
        self.remaining -= take_viewpoint(e, r, p.vis_indptr, p.vis_indices, p.tgt_indptr,
                                         p.tgt_indices, self.seen, self.count, p.required,
                                         self.gains, p.soft, p.soft_exp)

    @property
    def done(self) -> bool:
        return self.remaining == 0
