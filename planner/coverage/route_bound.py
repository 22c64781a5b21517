"""The route-pricing lower bound on coverage time: near the optimum on small problems.

**Route sets.** Cut every route of an optimal plan after its last snapshot that
the coverage time counts (as `exact` does): each route then lasts at most OPT,
and its set S of useful viewpoints (those seeing a target that still needs
sightings) takes at least ``time_g(S)``, the least time of a path through
exactly S in the shortest-path closure of travel (and of the launch times) from
the start of the UAV's launch group g: a walk through S, shortcut in the
closure, is such a path. `set_times` computes it for all 2^m subsets
(Held-Karp), so the bound is built on at most `ROUTE_MAX_VIEWPOINTS` useful
viewpoints, and not with a battery limit (sorties).

**Subsets.** With more useful viewpoints (up to `SUBSET_MAX_VIEWPOINTS`) it is
built on subsets U of that size (`_subsets`) and the best is kept: a route
through S takes at least ``time_g(S & U)`` (shortcut again), and a target's q
pairs at distinct places have at most one at each of its viewers outside U, so
its rows ask q less that many of U.

**Rows (W, b).** A viewpoint mask W and "at least b UAVs' routes fly a
viewpoint of W": for a target with viewers V that needs q more sightings (its
requirement less the UAVs that saw it before: those give at most one pair each
of the matching of distinct UAVs at distinct places, `places`), W = V less j of
them with b = q - j (0 <= j < q): of the q new pairs, at distinct places, at
most j lie outside W, and the others are distinct UAVs flying W.

**The certificate.** For a time T and any pi >= 0 on the rows, a plan with
every route within T has ``sum_W b_W pi_W <= sum over its routes of val(S) <=
sum_g n_g max{val(S) : time_g(S) <= T}``, ``val(S)`` the sum of pi_W over the
rows W that S hits. So where ``b.pi`` exceeds the right side, no plan has
makespan <= T, and OPT > T. The maximum is exact (a subset-sum transform over
all 2^m sets, `RouteMaster.price`); pi comes from column generation on the
restricted master (routes as columns, least total shortfall): HiGHS only
proposes pi, and the inequality is checked here, with a margin. This is the
Dantzig-Wolfe (route) relaxation: each route counts a target once and lasts at
most T, which the flow LP of `bounds` cannot say (it counts flow, so one route
passing twice counts twice, and bounds only the sum of the routes' times).

**The bound.** The times T tried are the sets' own times
(`RouteMaster.candidate_times`): if T is certified, some route of the optimal
plan has ``time_g(S) > T``, so OPT is at least the next candidate time. The
least such time the search cannot refute, less a relative 1e-6, is returned.

Measured (``bench_coverage --optimal``, 230 proven optima of 8-16 viewpoints;
``--optimal-mid``, 17-30): see docs/benchmarks.md. On larger problems it is
not built, and the bound is the flow LP's.
"""

import itertools
import math
import time

import numpy as np
from numba import njit
from scipy.optimize import linprog

#: built when at most this many viewpoints see a target that needs sightings
#: (2^m subsets are enumerated per launch group); up to SUBSET_MAX_VIEWPOINTS, on
#: subsets of them (on 31-40, measured, two subsets of 16 raised no bound)
ROUTE_MAX_VIEWPOINTS = 16
SUBSET_MAX_VIEWPOINTS = 30
#: its time budget (seconds), and the growth of its search for a time it cannot refute
ROUTE_TIME_LIMIT_S = 4.0
GROWTH = 1.06
#: the value is lowered by this relative amount for HiGHS's tolerances (as `bounds`)
_SAFETY = 1e-6


@njit(cache=True)
def _times_into(travel_t, vps):
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
def set_times(travel, start, has_start):
    """Per subset S of the m viewpoints of ``travel`` (bit i: viewpoint i), the
    least time of a path through exactly S (Held-Karp), from ``start[e]`` (the
    launch) or, without, from its first viewpoint at 0; inf for the empty set."""
    m = travel.shape[0]
    full = 1 << m
    dp = np.full((full, m), np.inf)
    for i in range(m):
        dp[1 << i, i] = start[i] if has_start else 0.0
    for mask in range(1, full):
        for i in range(m):
            here = dp[mask, i]
            if not (mask >> i) & 1 or not here < np.inf:
                continue
            for j in range(m):
                if (mask >> j) & 1:
                    continue
                t = here + travel[i, j]
                if t < dp[mask | (1 << j), j]:
                    dp[mask | (1 << j), j] = t
    out = np.empty(full)
    out[0] = np.inf
    for mask in range(1, full):
        best = np.inf
        for i in range(m):
            if dp[mask, i] < best:
                best = dp[mask, i]
        out[mask] = best
    return out


@njit(cache=True)
def _subset_sums(h, m):
    """In place: h[U] becomes the sum of h[W] over W contained in U (zeta transform)."""
    full = 1 << m
    for i in range(m):
        bit = 1 << i
        for u in range(full):
            if u & bit:
                h[u] += h[u ^ bit]


def _still_needed(prep) -> np.ndarray:
    """Per target, the sightings needed beyond the UAVs that saw it before."""
    return prep.required.astype(np.int64) - prep.seen0.sum(axis=0)


def _useful(prep) -> np.ndarray:
    """Per viewpoint, whether it sees a target that still needs sightings."""
    useful = np.zeros(prep.problem.n_viewpoints, bool)
    needed = np.repeat(_still_needed(prep) > 0, np.diff(prep.tgt_indptr))
    useful[prep.tgt_indices[needed]] = True
    return useful


def _hit_rows(prep, vps, max_subset_rows=64):
    """Rows (viewpoint mask W over ``vps``, rhs b) of the route master: every plan
    has at least b UAVs whose routes visit a viewpoint of W (see `route_bound`)."""
    local = np.full(prep.problem.n_viewpoints, -1, np.int64)
    local[vps] = np.arange(len(vps))
    need = _still_needed(prep)
    rows = {}
    for c in np.flatnonzero(need > 0):
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
    """The route-pricing relaxation of a small prepared problem (see `route_bound`)."""

    def __init__(self, prep, vps, into):
        """``vps``: the useful viewpoints (`_useful`) priced, sorted; ``into``: the
        times from every viewpoint to each of them (`_times_into`)."""
        p = prep.problem
        self.prep = prep
        self.vps = vps
        self.m = len(self.vps)
        sub = np.ascontiguousarray(into[self.vps])
        if prep.has_launch:  # via any viewpoint
            lo = (prep.launch_out[:, :, None] + into[None, :, :]).min(axis=1)
            rows, self.count = np.unique(lo, axis=0, return_counts=True)
        else:
            rows, self.count = np.zeros((1, self.m)), np.array([p.n_uavs])
        self.times = [set_times(sub, np.ascontiguousarray(r), prep.has_launch) for r in rows]
        self.masks, self.rhs = _hit_rows(prep, self.vps)
        every = np.arange(1 << self.m)
        self.sizes = sum((every >> i) & 1 for i in range(self.m))   # |S| per subset
        self.cols = []  # (group, subset): the column pool, kept across times

    def candidate_times(self):
        t = np.concatenate(self.times)
        return np.unique(t[np.isfinite(t)])

    def price(self, pi):
        """Per group, the subsets' values sum of pi[W] over rows W they hit."""
        h = np.zeros(1 << self.m)
        np.add.at(h, self.masks, pi)
        total = float(pi.sum())
        _subset_sums(h, self.m)
        full = (1 << self.m) - 1
        return total - h[full ^ np.arange(1 << self.m)]

    def _add(self, g, s):
        if (g, s) not in self._have:
            self._have.add((g, s))
            self.cols.append((g, s))

    def infeasible(self, t, deadline=math.inf, max_rounds=60, per_group=4):
        """True when no plan has every route within ``t`` (certified by a dual
        vector and exact pricing, see `route_bound`); False when the LP is
        feasible at ``t`` or the rounds run out."""
        self._have = set(self.cols)
        ok = [ts <= t for ts in self.times]
        n_rows, n_g = len(self.rhs), len(self.count)
        for g in range(n_g):  # a first column per group: its largest set within t
            if ok[g].any():
                idx = np.flatnonzero(ok[g])
                self._add(g, int(idx[np.argmax(self.sizes[idx])]))
        for _ in range(max_rounds):
            if time.perf_counter() > deadline:
                return False
            cols = [(g, s) for g, s in self.cols if self.times[g][s] <= t]
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
            val = self.price(pi)
            lag = float(self.rhs @ pi)
            new = []
            for g in range(n_g):
                v = np.where(ok[g], val, -np.inf)
                best = float(v.max())
                lag -= self.count[g] * max(best, 0.0)
                mu = max(-res.ineqlin.marginals[n_rows + g], 0.0)
                if best > mu + 1e-9:
                    top = (np.argpartition(-v, per_group)[:per_group] if len(v) > per_group
                           else np.arange(len(v)))
                    new += [(g, int(s)) for s in top if v[s] > mu + 1e-9]
            if lag > 1e-6 * max(1.0, float(self.rhs @ pi)):
                return True  # a certificate: rhs.pi > every plan's sum of values
            if not new:
                return False
            for g, s in new:
                self._add(g, s)
        return False


def route_bound(prep, lower=0.0, rel_tol=1e-3, time_limit=ROUTE_TIME_LIMIT_S) -> float:
    """The route-pricing bound (module doc): the least candidate time the route
    master cannot refute, searched from ``lower`` (a valid bound) up by
    `GROWTH` then by bisection to ``rel_tol``. Over `ROUTE_MAX_VIEWPOINTS` useful
    viewpoints (up to `SUBSET_MAX_VIEWPOINTS`) the best of the bounds of a few
    subsets of that size (`_subsets`). 0 when the problem is too large for it, or
    has a battery."""
    p = prep.problem
    if p.n_viewpoints == 0 or p.n_targets == 0 or math.isfinite(p.endurance_s):
        return 0.0
    useful = np.flatnonzero(_useful(prep))
    if not len(useful) or len(useful) > SUBSET_MAX_VIEWPOINTS:
        return 0.0
    deadline = time.perf_counter() + time_limit
    into = _times_into(prep.travel_t, useful)   # once: every subset's columns are in it
    best = 0.0
    for pick in _subsets(prep, useful, into):
        if time.perf_counter() >= deadline:
            break
        rm = RouteMaster(prep, useful[pick], into[:, pick])
        best = max(best, _refute(rm, max(lower, best), rel_tol, deadline))
    return best


def _subsets(prep, useful, into):
    """The viewpoint sets to price, as sorted positions in ``useful`` (``into``: the
    times to each, `_times_into`): all of them if they are few enough; else, of
    `ROUTE_MAX_VIEWPOINTS` each, the viewers of the targets that need the most
    sightings from the fewest viewers (first), and the viewpoints farthest from the
    bases (or from each other). Any subset U gives a valid bound: a plan's pairs
    for a target at viewpoints outside U are at most one per such viewpoint
    (`_hit_rows`), and a route's time through S is at least its time through the
    part of S in U (shortcut in the closure)."""
    size = ROUTE_MAX_VIEWPOINTS
    if len(useful) <= size:
        return [np.arange(len(useful))]
    need = _still_needed(prep)
    degree = np.diff(prep.tgt_indptr)
    hard = []
    for c in np.lexsort((degree - need, -need)):
        if need[c] <= 0 or len(hard) >= size:
            break
        viewers = prep.tgt_indices[prep.tgt_indptr[c]:prep.tgt_indptr[c + 1]]
        hard += [int(v) for v in viewers if int(v) not in hard][:size - len(hard)]
    far = prep.launch_out.min(axis=0)[useful] if prep.has_launch else into[useful].max(axis=0)
    return [np.searchsorted(useful, np.sort(hard)), np.sort(np.argsort(-far)[:size])]


def _refute(rm, lower, rel_tol, deadline) -> float:
    """The least candidate time of ``rm`` it cannot certify infeasible, searched
    from ``lower`` (see `route_bound`); 0 when none is certified."""
    cand = rm.candidate_times()
    if not len(cand):
        return 0.0
    # cand[i] certified infeasible for i <= lo_i (below ``lower``: no plan is that
    # quick anyway); not certified at hi_i. The bound is cand[lo_i + 1] once a
    # time is certified: ``lower`` alone says nothing of the candidate after it (a
    # subset's times need not include the optimum).
    lo_i = first = int(np.searchsorted(cand, lower, side="left")) - 1
    hi_i = len(cand)
    base = cand[lo_i + 1] if lo_i + 1 < len(cand) else cand[-1]
    grow = 0
    while lo_i + 1 < hi_i and time.perf_counter() < deadline:
        if hi_i == len(cand):  # grow until a time is not certified
            i = int(np.searchsorted(cand, base * GROWTH ** grow, side="right")) - 1
            i = min(max(i, lo_i + 1), len(cand) - 1)
            grow += 1
        else:
            if cand[hi_i] <= cand[lo_i + 1] * (1 + rel_tol):
                break
            i = (lo_i + hi_i) // 2
        if rm.infeasible(float(cand[i]), deadline):
            lo_i = i
        else:
            hi_i = i
    if lo_i == first or lo_i + 1 >= len(cand):
        return 0.0
    return float(cand[lo_i + 1]) * (1.0 - _SAFETY)


__all__ = ["route_bound"]
