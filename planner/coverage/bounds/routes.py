"""The route-pricing lower bound on coverage time: near the optimum on small problems.

**Route sets.** Cut every route of an optimal plan after its last snapshot that
the coverage time counts (as `exact` does): each route then lasts at most OPT,
and its set S of useful viewpoints (those seeing a target that still needs
sightings) takes at least ``time_g(S)``, the least time of a path through
exactly S in the shortest-path closure of travel (and of the launch times) from
the start of the UAV's launch group g: a walk through S, shortcut in the
closure, is such a path. `feasible_sets` finds every set S with ``time_g(S)``
within a horizon, and its time (Held-Karp over those sets alone: a route of a
few of m viewpoints leaves far fewer than 2^m), so the bound is built on up
to `ROUTE_MAX_VIEWPOINTS` useful viewpoints, and not with a battery limit
(sorties).

**Subsets.** Where a horizon the search needs holds more than `MAX_SETS` sets,
the bound is also built on subsets U of `SUBSET_VIEWPOINTS` (`_subsets`) and
the best is kept: a route through S takes at least ``time_g(S & U)`` (shortcut
again), and a target's q pairs at distinct places have at most one at each of
its viewers outside U, so its rows ask q less that many of U.

**Rows (W, b).** A viewpoint mask W and "at least b UAVs' routes fly a
viewpoint of W": for a target with viewers V that needs q more sightings (its
requirement less the UAVs that saw it before: those give at most one pair each
of the matching of distinct UAVs at distinct places, `model.places`), W = V less j of
them with b = q - j (0 <= j < q): of the q new pairs, at distinct places, at
most j lie outside W, and the others are distinct UAVs flying W.

**The certificate.** For a time T and any pi >= 0 on the rows, a plan with
every route within T has ``sum_W b_W pi_W <= sum over its routes of val(S) <=
sum_g n_g max{val(S) : time_g(S) <= T}``, ``val(S)`` the sum of pi_W over the
rows W that S hits. So where ``b.pi`` exceeds the right side, no plan has
makespan <= T, and OPT > T. The maximum is exact (every set within T is
priced, `_values`); pi comes from column generation on the restricted master
(routes as columns, least total shortfall): HiGHS only proposes pi, and the
inequality is checked here, with a margin. This is the Dantzig-Wolfe (route)
relaxation: each route counts a target once and lasts at most T, which the
flow LP of `flow` cannot say (it counts flow, so one route passing twice
counts twice, and bounds only the sum of the routes' times).

**The bound.** The times T tried are the sets' own times
(`RouteMaster.candidates`): if T is certified, some route of the optimal
plan has ``time_g(S) > T``, so OPT is at least the next set time (beyond the
horizon if none is within it: every set within it is known). The least such
time above every time certified, less a relative 1e-6, is returned.

Measured (``bench_coverage --optimal``, 230 proven optima of 8-16 viewpoints;
``--optimal-mid``, 17-30): see docs/benchmarks.md. On larger problems it is
not built, and the bound is the flow LP's.
"""

import itertools
import math
import time

import numpy as np
from numba import njit, types
from numba.typed import Dict
from scipy.optimize import linprog

from .radius import radius_bound

#: built when at most this many viewpoints see a target that needs sightings
ROUTE_MAX_VIEWPOINTS = 30
#: the route sets within the horizon (`feasible_sets`) of a launch group at most;
#: beyond, the bound is built on subsets of SUBSET_VIEWPOINTS viewpoints (at most
#: 2^16 sets each)
MAX_SETS = 1_000_000
SUBSET_VIEWPOINTS = 16
#: up to this many viewpoints `feasible_sets` finds a set by an array over every
#: mask (16 MB at 22), beyond by a hash table
DENSE_BITS = 22
#: its time budget (seconds), and the growth of its search for a time it cannot refute
ROUTE_TIME_LIMIT_S = 4.0
GROWTH = 1.06
#: the horizon is extended this far past the time the search needs (two steps)
HORIZON_AHEAD = GROWTH ** 2
#: the value is lowered by this relative amount for HiGHS's tolerances (as `flow`)
_SAFETY = 1e-6


@njit(cache=True)
def times_into(travel_t, vps):
    """[n, len(vps)]: the shortest time from every viewpoint to each of ``vps``
    over ``travel`` (given transposed), through any viewpoint: a dense Dijkstra
    per viewpoint of ``vps`` (the shortest-path closure, only the columns needed:
    a re-plan's problem may hold thousands of viewpoints and few useful ones)."""
    n = travel_t.shape[0]
    out = np.empty((n, len(vps)))
    for j in range(len(vps)):
        d = np.full(n, np.inf)
        done = np.zeros(n, np.bool_)
        d[vps[j]] = 0.0
        for _ in range(n):
            u, du = -1, np.inf
            for w in range(n):
                if not done[w] and d[w] < du:
                    u, du = w, d[w]
            if u < 0:
                break
            done[u] = True
            for w in range(n):
                v = du + travel_t[u, w]
                if v < d[w]:
                    d[w] = v
        out[:, j] = d
    return out


@njit(cache=True)
def feasible_sets(travel, start, has_start, horizon, max_sets):
    """(masks, times, sizes, True): the sets S of the m viewpoints of ``travel`` (bit i:
    viewpoint i) with a path through exactly S within ``horizon``, from ``start[e]``
    (the launch) or, without, from its first viewpoint at 0, with the least such
    time and |S|. Held-Karp over those sets alone: a path's prefix is within the
    horizon too, so each set grows from another, a viewpoint at a time, and a set
    is done when every set one smaller is (breadth first). A route of a few of
    many viewpoints leaves few such sets, where Held-Karp over all 2^m would
    not finish. Empty arrays and False when there are more than ``max_sets``."""
    m = travel.shape[0]
    singles = 0
    for i in range(m):
        singles += (start[i] if has_start else 0.0) <= horizon
    if singles > max_sets:
        return np.empty(0, np.int64), np.empty(0), np.empty(0, np.int64), False
    cap = min(max(1024, m), max_sets)
    masks = np.empty(cap, np.int64)
    dp = np.full((cap, m), np.inf)
    # where each set is in ``masks``: an array over all 2^m masks when that is small
    dense = m <= DENSE_BITS
    at = np.full(1 << m if dense else 1, -1, np.int32)
    index = Dict.empty(key_type=types.int64, value_type=types.int64)
    n = 0
    for i in range(m):
        t = start[i] if has_start else 0.0
        if t <= horizon:
            masks[n], dp[n, i] = 1 << i, t
            if dense:
                at[1 << i] = n
            else:
                index[1 << i] = n
            n += 1
    k = 0
    while k < n:
        s = masks[k]
        for j in range(m):
            if (s >> j) & 1:
                continue
            t = np.inf
            for i in range(m):
                if (s >> i) & 1 and dp[k, i] + travel[i, j] < t:
                    t = dp[k, i] + travel[i, j]
            if not t <= horizon:
                continue
            grown = s | (1 << j)
            q = -1
            if dense:
                q = at[grown]
            elif grown in index:
                q = index[grown]
            if q < 0:
                if n == cap:
                    if cap == max_sets:
                        return np.empty(0, np.int64), np.empty(0), np.empty(0, np.int64), False
                    cap = min(2 * cap, max_sets)
                    more = np.empty(cap, np.int64)
                    more[:n] = masks[:n]
                    masks = more
                    rows = np.full((cap, m), np.inf)
                    rows[:n] = dp[:n]
                    dp = rows
                q, masks[n] = n, grown
                if dense:
                    at[grown] = n
                else:
                    index[grown] = n
                n += 1
            dp[q, j] = min(dp[q, j], t)
        k += 1
    times = np.empty(n)
    sizes = np.zeros(n, np.int64)
    for k in range(n):
        times[k] = dp[k].min()
        for i in range(m):
            sizes[k] += (masks[k] >> i) & 1
    return masks[:n].copy(), times, sizes, True


def _greedy_path(travel, start, has_start) -> float:
    """The time of a path through every viewpoint of ``travel``, nearest first."""
    here = int(np.argmin(start)) if has_start else 0
    total = float(start[here]) if has_start else 0.0
    left = np.ones(len(travel), bool)
    left[here] = False
    while left.any():
        nxt = int(np.flatnonzero(left)[np.argmin(travel[here, left])])
        total += float(travel[here, nxt])
        left[nxt], here = False, nxt
    return total


@njit(cache=True)
def _values(sets, masks, pi):
    """Per set, the sum of pi over the rows (``masks``) it hits."""
    out = np.zeros(len(sets))
    for r in range(len(masks)):
        if pi[r] > 0.0:
            for f in range(len(sets)):
                if sets[f] & masks[r]:
                    out[f] += pi[r]
    return out


def still_needed(prep) -> np.ndarray:
    """Per target, the sightings needed beyond the UAVs that saw it before."""
    return prep.required.astype(np.int64) - prep.seen0.sum(axis=0)


def useful_viewpoints(prep) -> np.ndarray:
    """Per viewpoint, whether it sees a target that still needs sightings."""
    useful = np.zeros(prep.problem.n_viewpoints, bool)
    needed = np.repeat(still_needed(prep) > 0, np.diff(prep.tgt_indptr))
    useful[prep.tgt_indices[needed]] = True
    return useful


def _hit_rows(prep, vps, max_subset_rows=64):
    """Rows (viewpoint mask W over ``vps``, rhs b) of the route master: every plan
    has at least b UAVs whose routes visit a viewpoint of W (see `route_bound`)."""
    local = np.full(prep.problem.n_viewpoints, -1, np.int64)
    local[vps] = np.arange(len(vps))
    need = still_needed(prep)
    # only targets with fewer viewers outside ``vps`` than sightings needed give a row:
    # found at once (a large problem priced on a few of its viewpoints has many targets)
    degree = np.diff(prep.tgt_indptr)
    counted = np.r_[0, np.cumsum(local[prep.tgt_indices] >= 0)]
    inside = counted[prep.tgt_indptr[1:]] - counted[prep.tgt_indptr[:-1]]
    rows = {}
    for c in np.flatnonzero((need > 0) & (inside > 0) & (need - degree + inside > 0)):
        viewers = local[prep.tgt_indices[prep.tgt_indptr[c]:prep.tgt_indptr[c + 1]]]
        # a viewer left out of ``vps`` gives at most one of the q pairs (distinct places)
        q = int(need[c]) - int(np.count_nonzero(viewers < 0))
        viewers = viewers[viewers >= 0]
        if not len(viewers) or q <= 0:
            continue
        deg = len(viewers)
        bits = [1 << int(v) for v in viewers]
        full = sum(bits)
        rows[full] = max(rows.get(full, 0), q)
        # W = viewers less j of them (1 <= j < q): at least q - j routes hit W
        drop = 1
        while drop < q and math.comb(deg, drop) <= max_subset_rows:
            for out in itertools.combinations(bits, drop):
                w = full - sum(out)
                rows[w] = max(rows.get(w, 0), q - drop)
            drop += 1
    masks = np.fromiter(rows.keys(), np.int64, len(rows))
    rhs = np.fromiter(rows.values(), np.float64, len(rows))
    return masks, rhs


class RouteMaster:
    """The route-pricing relaxation of a small prepared problem (see `route_bound`),
    on the route sets within a horizon (`extend`)."""

    def __init__(self, prep, vps, into):
        """``vps``: the useful viewpoints (`useful_viewpoints`) priced, sorted; ``into``: the
        times from every viewpoint to each of them (`times_into`)."""
        p = prep.problem
        self.prep = prep
        self.vps = vps
        self.m = len(self.vps)
        self.sub = np.ascontiguousarray(into[self.vps])
        if prep.has_launch:  # via any viewpoint
            lo = (prep.launch_out[:, :, None] + into[None, :, :]).min(axis=1)
            self.starts, self.count = np.unique(lo, axis=0, return_counts=True)
        else:
            self.starts, self.count = np.zeros((1, self.m)), np.array([p.n_uavs])
        self.masks, self.rhs = _hit_rows(prep, self.vps)
        # no route set takes longer than a path through all of them
        self.longest = max(_greedy_path(self.sub, r, prep.has_launch) for r in self.starts)
        self.horizon = -math.inf
        self.overflowed = False  # a horizon had too many route sets
        self.build_s = 0.0       # the seconds the last horizon's sets took
        self.cols = []  # (group, set mask, its time): the column pool, kept across times

    def extend(self, horizon) -> bool:
        """The route sets of every launch group within ``horizon``, sorted by time
        (`feasible_sets`); False, and the sets as they were, when a group has more
        than `MAX_SETS`."""
        if horizon <= self.horizon:
            return True
        began = time.perf_counter()
        found = [feasible_sets(self.sub, np.ascontiguousarray(r), self.prep.has_launch,
                               horizon, MAX_SETS) for r in self.starts]
        self.build_s = time.perf_counter() - began
        if not all(f[3] for f in found):
            self.overflowed = True
            return False
        self.sets, self.times, self.sizes = [], [], []
        for masks, times, sizes, _ in found:
            order = np.argsort(times, kind="stable")
            self.sets.append(masks[order])
            self.times.append(times[order])
            self.sizes.append(sizes[order])
        # every route set's time within the horizon, sorted, once each
        self.candidates = np.unique(np.concatenate(self.times))
        self.horizon = horizon
        return True

    def _within(self, g, t) -> int:
        return int(np.searchsorted(self.times[g], t, side="right"))

    def _add(self, g, i):
        key = (g, int(self.sets[g][i]))
        if key not in self._have:
            self._have.add(key)
            self.cols.append((g, key[1], float(self.times[g][i])))

    def infeasible(self, t, deadline=math.inf, max_rounds=60, per_group=4):
        """True when no plan has every route within ``t`` (at most the horizon;
        certified by a dual vector and exact pricing, see `route_bound`); False
        when the LP is feasible at ``t`` or the rounds run out."""
        self._have = {(g, s) for g, s, _ in self.cols}
        within = [self._within(g, t) for g in range(len(self.sets))]
        n_rows, n_g = len(self.rhs), len(self.count)
        for g in range(n_g):  # a first column per group: its largest set within t
            if within[g]:
                self._add(g, int(np.argmax(self.sizes[g][:within[g]])))
        for _ in range(max_rounds):
            if time.perf_counter() > deadline:
                return False
            cols = [(g, s) for g, s, ts in self.cols if ts <= t]
            nc = len(cols)
            gs = np.array([g for g, _ in cols], np.int64)
            ss = np.array([s for _, s in cols], np.int64)
            hit = ((self.masks[:, None] & ss[None, :]) != 0).astype(float)
            # min sum slack: hit lam + slack >= rhs, sum of a group's lam <= its count
            a_cover = np.hstack([-hit, -np.eye(n_rows)])
            a_conv = np.zeros((n_g, nc + n_rows))
            a_conv[gs, np.arange(nc)] = 1.0
            c = np.r_[np.zeros(nc), np.ones(n_rows)]
            res = linprog(c, A_ub=np.vstack([a_cover, a_conv]),
                          b_ub=np.r_[-self.rhs, self.count.astype(float)],
                          bounds=(0, None), method="highs")
            if res.status != 0:
                return False
            if res.fun <= 1e-7:
                return False  # the LP has a plan of routes within t
            pi = np.clip(-res.ineqlin.marginals[:n_rows], 0.0, None)
            lag = float(self.rhs @ pi)
            new = []
            for g in range(n_g):
                v = _values(self.sets[g][:within[g]], self.masks, pi)
                best = float(v.max()) if len(v) else 0.0
                lag -= self.count[g] * max(best, 0.0)
                mu = max(-res.ineqlin.marginals[n_rows + g], 0.0)
                if best > mu + 1e-9:
                    top = (np.argpartition(-v, per_group)[:per_group] if len(v) > per_group
                           else np.arange(len(v)))
                    new += [(g, int(i)) for i in top if v[i] > mu + 1e-9]
            if lag > 1e-6 * max(1.0, float(self.rhs @ pi)):
                return True  # a certificate: rhs.pi > every plan's sum of values
            if not new:
                return False
            for g, i in new:
                self._add(g, i)
        return False


def route_bound(prep, lower=0.0, rel_tol=1e-3, time_limit=ROUTE_TIME_LIMIT_S) -> float:
    """The route-pricing bound (module doc): the least route-set time above every
    time the route master certifies, searched from ``lower`` (a valid bound; at
    least the radius bound) up by `GROWTH` then by bisection to ``rel_tol``, on
    every useful viewpoint, or where their route sets are too many, the best of
    the bounds on a few subsets of `SUBSET_VIEWPOINTS` (`_subsets`). 0 when the
    problem is too large for it, or has a battery."""
    p = prep.problem
    if p.n_viewpoints == 0 or p.n_targets == 0 or math.isfinite(p.endurance_s):
        return 0.0
    useful = np.flatnonzero(useful_viewpoints(prep))
    if not len(useful) or len(useful) > ROUTE_MAX_VIEWPOINTS:
        return 0.0
    if lower <= 0.0:  # `lower_bounds` gives these and more; a caller on its own, not
        lower = radius_bound(prep)
    if lower <= 0.0:
        return 0.0
    into = times_into(prep.travel_t, useful)   # once: every subset's columns are in it
    compile_kernels()
    deadline = time.perf_counter() + time_limit
    whole = RouteMaster(prep, useful, into)
    best = refute(whole, lower, rel_tol, deadline)
    if whole.overflowed and len(useful) > SUBSET_VIEWPOINTS:
        for pick in _subsets(prep, useful, into):
            if time.perf_counter() >= deadline:
                break
            rm = RouteMaster(prep, useful[pick], into[:, pick])
            best = max(best, refute(rm, max(lower, best), rel_tol, deadline))
    return best


def compile_kernels() -> None:
    """The kernels compiled (or loaded from numba's cache) before the budget starts:
    the first bound of a process after a change would spend it in the compiler
    (about 5 s on 2 cores) and fall back to the flow bound."""
    feasible_sets(np.zeros((1, 1)), np.zeros(1), True, 1.0, 2)
    _values(np.ones(1, np.int64), np.ones(1, np.int64), np.ones(1))


def _subsets(prep, useful, into):
    """Viewpoint sets to price where the whole set has too many route sets, as
    sorted positions in ``useful`` (``into``: the times to each, `times_into`):
    of `SUBSET_VIEWPOINTS` each, the viewers of the targets that need the most
    sightings from the fewest viewers (first), and the viewpoints farthest from the
    bases (or from each other). Any subset U gives a valid bound: a plan's pairs
    for a target at viewpoints outside U are at most one per such viewpoint
    (`_hit_rows`), and a route's time through S is at least its time through the
    part of S in U (shortcut in the closure)."""
    size = SUBSET_VIEWPOINTS
    need = still_needed(prep)
    degree = np.diff(prep.tgt_indptr)
    hard = []
    for c in np.lexsort((degree - need, -need)):
        if need[c] <= 0 or len(hard) >= size:
            break
        viewers = prep.tgt_indices[prep.tgt_indptr[c]:prep.tgt_indptr[c + 1]]
        hard += [int(v) for v in viewers if int(v) not in hard][:size - len(hard)]
    far = prep.launch_out.min(axis=0)[useful] if prep.has_launch else into[useful].max(axis=0)
    return [np.searchsorted(useful, np.sort(hard)), np.sort(np.argsort(-far)[:size])]


def refute(rm, lower, rel_tol, deadline) -> float:
    """The least route-set time of ``rm`` above every time it certifies (see
    `route_bound`), searched from ``lower`` (> 0) up by `GROWTH`, the horizon
    extended as it goes, then by bisection; 0 when none is certified."""
    best, hi, grow = lower, math.inf, 0  # best: certified (or below lower); hi: not
    certified = False
    cand = np.empty(0)
    while time.perf_counter() < deadline:
        if hi == math.inf:  # grow until a time is not certified
            target = lower * GROWTH ** grow
            grow += 1
            if target > rm.horizon:
                if time.perf_counter() + 2 * rm.build_s > deadline:
                    break  # a larger horizon takes longer to build than the last
                if not (rm.extend(min(target * HORIZON_AHEAD, rm.longest)) or rm.extend(target)):
                    break
            cand = rm.candidates
            ahead = cand[(cand > best) & (cand <= target)]
            if not len(ahead):
                if target >= rm.longest:
                    break  # every route set is within the horizon
                continue
            t = float(ahead[-1])
        else:
            between = cand[(cand > best) & (cand < hi)]
            if not len(between) or hi <= between[0] * (1 + rel_tol):
                break
            t = float(between[len(between) // 2])
        if rm.infeasible(t, deadline):
            best, certified = t, True
        else:
            hi = t
    if not certified:
        return 0.0
    # some route set of every plan takes longer than ``best``: at least the next set
    # time, or beyond the horizon if none is within it (every set within it is known)
    above = cand[cand > best]
    return float(above[0] if len(above) else rm.horizon) * (1.0 - _SAFETY)


__all__ = ["route_bound"]
