"""The sortie bound: under a battery, ground that no one sortie joins costs
sorties, and every sortie but a vehicle's last costs its way home and a turnaround.

**The relaxation.** A sortie leaves a base (or the start), visits viewpoints and
lands at a base, within one battery ``B``. Two targets are *apart* when no sortie
sees both: for every viewpoint a of one and b of the other, in either order,

    out(a) + travel(a, b) + back(b) > B,

with ``out`` the least time out of any start or base and ``back`` the least time
home to any base (both closed under shortest paths here; ``travel`` is, as hidden
travel times are). A set of targets pairwise apart (found greedily, the farthest
first) needs a sortie per sighting it needs: S sorties, each seeing one of them,
each flying at least its target's round trip ``rt`` (the least out + back over its
viewpoints), and the sighting comes at least ``out`` into it.

The vehicle that flies m = ceil(S / n) of them makes its m-th sighting no sooner
than m - 1 of those sorties, each with its turnaround ``T``, plus the way out of
the m-th (the m - 1 shortest round trips, the least way out: ``by_count``). Over
the fleet, n times the coverage time is at least the sum over all S of (rt + T),
less, per vehicle, its last one's way home and turnaround (the fleet average).
Both bound the coverage time of every plan on the battery, takeoff waits aside.

**Cost.** One row of times out of each candidate target's viewpoints to every
viewpoint (|V_t| x viewpoints each), against the rows of the targets chosen so far:
0.17 s on the 8-min sample plan once compiled (2,544 viewpoints, 2,031 target
classes). Targets are
tried the farthest first, within `MAX_WORK` row updates, and at most `MAX_APART`
kept: fewer tried make a smaller set, and a lower bound still.
"""

import math

import numpy as np
from numba import njit

from .radius import earliest_arrival

#: row updates spent trying targets (about 0.5 s), and the most kept apart (a row each)
MAX_WORK, MAX_APART = 400_000_000, 256


def sortie_bound(prep, usable_s: float) -> float:
    """The sortie bound (module doc) of a prepared problem on a battery of
    ``usable_s`` seconds of flight per sortie; 0 without a battery or launch points."""
    p = prep.problem
    if not math.isfinite(usable_s) or not prep.has_launch or p.n_targets == 0:
        return 0.0
    out, back = _ways(prep)
    open_ = out + back <= usable_s
    need = (prep.required - prep.seen0.sum(axis=0)).astype(np.int64)
    rt, way_out = _round_trips(prep.tgt_indptr, prep.tgt_indices, open_, out, back)
    ts = np.flatnonzero((need > 0) & np.isfinite(rt))
    ts = ts[np.argsort(-rt[ts], kind="stable")]
    if len(ts) == 0:
        return 0.0
    chosen = ts[_apart(ts, prep.tgt_indptr, prep.tgt_indices, open_, out, back, prep.travel,
                       usable_s, MAX_APART, MAX_WORK)]
    turnaround = float(np.min(prep.batteries.turnaround))
    jobs = np.repeat(rt[chosen] + turnaround, need[chosen])
    home = jobs - np.repeat(way_out[chosen], need[chosen])   # a last sortie's way home and T
    return max(by_count(jobs, np.min(way_out[chosen]), p.n_uavs),
               (jobs.sum() - p.n_uavs * home.max()) / p.n_uavs)


def by_count(jobs, way_out: float, n_uavs: int) -> float:
    """The vehicle that flies ceil(S / n) of the S ``jobs`` (round trip + turnaround
    each): the shortest of them but its last, then ``way_out``."""
    m = math.ceil(len(jobs) / n_uavs)
    return float(np.sort(jobs)[:m - 1].sum() + way_out) if m else 0.0


def _ways(prep) -> tuple:
    """(out, back) per viewpoint: the least time out of any start or base, and home
    to any base, each closed under shortest paths through the viewpoints."""
    p = prep.problem
    outs = [prep.launch_out] + [np.asarray(a, np.float64) for a in (p.base_out, p.bases_out)
                                if a is not None and len(a)]
    backs = [prep.launch_back] + ([np.asarray(p.bases_back, np.float64)]
                                  if p.bases_back is not None and len(p.bases_back) else [])
    out = earliest_arrival(np.vstack(outs).min(axis=0), prep.travel_t)
    back = earliest_arrival(np.vstack(backs).min(axis=0), prep.travel)
    return out, back


@njit(cache=True)
def _round_trips(tgt_indptr, tgt_indices, open_, out, back):
    """Per target, the least round trip (out + back) and the least way out over its
    open viewpoints (inf: none)."""
    n_t = len(tgt_indptr) - 1
    rt, way_out = np.full(n_t, np.inf), np.full(n_t, np.inf)
    for t in range(n_t):
        for j in range(tgt_indptr[t], tgt_indptr[t + 1]):
            a = tgt_indices[j]
            if open_[a]:
                rt[t] = min(rt[t], out[a] + back[a])
                way_out[t] = min(way_out[t], out[a])
    return rt, way_out


@njit(cache=True)
def _apart(ts, tgt_indptr, tgt_indices, open_, out, back, travel, usable_s, max_apart,
           max_work):
    """Indices into ``ts`` of targets pairwise apart (module doc), greedily in
    ``ts``'s order, at most ``max_apart``, within ``max_work`` row updates."""
    n_vp = len(out)
    rows = np.empty((min(len(ts), max_apart), n_vp))   # a chosen target's times out
    chosen = np.empty(len(rows), np.int64)
    k = 0
    row = np.empty(n_vp)
    for i in range(len(ts)):
        t = ts[i]
        max_work -= (tgt_indptr[t + 1] - tgt_indptr[t]) * n_vp
        if max_work < 0:
            break
        row[:] = np.inf
        for j in range(tgt_indptr[t], tgt_indptr[t + 1]):
            a = tgt_indices[j]
            if open_[a]:
                for b in range(n_vp):
                    row[b] = min(row[b], out[a] + travel[a, b])
        joined = False
        for q in range(k):
            u = ts[chosen[q]]
            if _joins(row, tgt_indptr, tgt_indices, u, open_, back, usable_s) or \
                    _joins(rows[q], tgt_indptr, tgt_indices, t, open_, back, usable_s):
                joined = True
                break
        if not joined:
            rows[k] = row
            chosen[k] = i
            k += 1
            if k == len(rows):
                break
    return chosen[:k]


@njit(cache=True)
def _joins(row, tgt_indptr, tgt_indices, u, open_, back, usable_s) -> bool:
    """Whether one sortie from ``row``'s target (its times out through it) sees
    target ``u`` and is home within ``usable_s``."""
    for j in range(tgt_indptr[u], tgt_indptr[u + 1]):
        b = tgt_indices[j]
        if open_[b] and row[b] + back[b] <= usable_s:
            return True
    return False
