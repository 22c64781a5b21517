"""A lower bound on coverage time worth the name: the first-sighting flow LP.

**The relaxation.** Look at one UAV's route e_1, e_2, ..., e_m.  A target t it
sees is seen *first* at some e_i whose predecessor does not see t (or e_i is
the first viewpoint), so t is in the *gain* of the leg that arrives there,
``gain(u -> e) = vis(e) \\ vis(u)`` (a start leg gains all of ``vis(e)``).
So every route is a path of legs; each target t must lie in the gain of legs
of ``need[t]`` distinct routes; and a route's time is the sum of its legs'
times.  Dropping integrality and which route a leg belongs to gives a
linear programme over leg flows ``x``:

    minimise T  subject to
      sum over legs a with t in gain(a) of x_a  >= need[t]       (every target)
      flow out of e <= flow into e                               (paths)
      start legs of UAV r <= 1                                   (one route each)
      sum of time(a) x_a <= n T                                  (the n routes' times)

Only the legs into e from its K nearest viewpoints (in travel time) are
variables.  Any other leg u -> e of a route is replaced by a chain of
variable legs from u to e: its gain is inside the chain's (a target new at
e is new at the first chain viewpoint that sees it), so coverage survives;
its time is at most ``gamma`` times the leg's, where ``gamma`` >= 1 is
certified by `stretch` (an in-neighbour w of e with ``gamma tau(u, w) +
tau(w, e) <= gamma tau(u, e)`` for every pair, by induction on tau(u, .));
legs that fail it are added as variables.  Leg times in the LP are divided
by gamma, so every plan maps to a feasible LP point no slower than itself:
the LP optimum is a lower bound.  On hidden travel times (shortest paths
over the terrain graph) gamma is 1 with K = 24 on the sample terrain.

**With launch points**, a route's LP time of reaching e is at least rho_r(e),
the shortest LP path from r's launch; a viewpoint that no UAV reaches within
T cannot be on a route of time <= T.  The LP solved with those viewpoints
left out gives f(T); every T with f(T) > T is a lower bound (bisection).

**Size.** Targets seen from the same viewpoints give identical rows, so the
LP is built on target classes (`model.classes`).  Classes beyond `MAX_TARGETS`
are thinned evenly over their ids: a bound for fewer targets bounds the
whole.  With launch points the bisection takes `BISECTION_STEPS` LPs.  HiGHS
(highspy) solves it with its cover rows generated (`FlowLP.solve`: the value of
all of them, in less time), starting each solve from the last one's basis; the
value is lowered by a relative 1e-6 for its tolerances.

Not modelled (kept as relaxations): which UAV flies which leg (targets
needing k+1 *distinct* UAVs are only counted), and balancing beyond the sum.
Where at most 30 viewpoints see what is needed, `routes.route_bound` says both (each
route counts a target once and lasts at most T, priced on every route set
within a horizon) and `lower_bounds` takes the larger.
"""

import math
import os
import sys
import threading
import time

import highspy
import numpy as np
from numba import njit
from scipy.sparse import coo_matrix, csr_matrix, vstack
from scipy.sparse.csgraph import dijkstra

#: legs into each viewpoint kept as LP variables (its nearest in travel time)
IN_ARCS = 24
#: at most this many target classes in the LP (evenly thinned beyond)
MAX_TARGETS = 1500
#: bisection steps on T with launch points
BISECTION_STEPS = 4
#: the LP is given up (the other bounds remain) beyond this size, or beyond
#: this many viewpoints. At 4,000 and 4 M it ran on the whole sample's 3,175 (2 s
#: to build, its 8 s of HiGHS: 122 min where the other bounds say 76), 9 s more
#: on a 16 s plan, and the suite, which plans the sample often, went 805 -> 888 s
MAX_NONZEROS = 1_500_000
FLOW_MAX_VIEWPOINTS = 1500
#: HiGHS time for the whole bound (base LP and bisection), seconds: a step
#: that does not finish in what is left is dropped and the bound proven so
#: far stands, and a solve out of time with rows still to add gives the value
#: of the rows it has (so only on problems that large can the value depend on
#: the machine; it is a valid bound either way)
LP_TIME_LIMIT_S = 8.0
#: cover rows the LP starts with, and added at most per round (`FlowLP.solve`): a
#: few hundred of 1,500 decide the value (`bench_coverage --bound`: the same values
#: as the LP whole on 18 problems of 150-800 viewpoints, in 27.5 s instead of 68.5)
FIRST_ROWS = 100
ADD_ROWS = 200
_ROW_TOL = 1e-7
_SAFETY = 1e-6
_BANNER = threading.Lock()
_banner_printed = False


def _highs():
    """A silent HiGHS. The first `highspy.Highs` of a process prints a banner on the C
    standard output whatever its options (its callbacks, turned on as it is made, log
    it): that one is made with the descriptor pointed away."""
    global _banner_printed
    with _BANNER:
        if _banner_printed:
            h = highspy.Highs()
        else:
            sys.stdout.flush()
            saved, null = os.dup(1), os.open(os.devnull, os.O_WRONLY)
            try:
                os.dup2(null, 1)
                h = highspy.Highs()
            finally:
                os.dup2(saved, 1)
                os.close(saved)
                os.close(null)
            _banner_printed = True
    h.silent()
    return h


@njit(cache=True)
def stretch(travel, in_nbr, explicit):
    """Per pair (u, e), the least gamma the induction certifies (see module doc):
    min over in-neighbours w of e of tau(w, e) / (tau(u, e) - tau(u, w)).
    Returns the matrix (1 on explicit legs and unreachable pairs)."""
    n = travel.shape[0]
    out = np.ones((n, n))
    for e in range(n):
        for u in range(n):
            if u == e or explicit[u, e] or not np.isfinite(travel[u, e]):
                continue
            tue = travel[u, e]
            best = np.inf
            for j in range(in_nbr.shape[1]):
                w = in_nbr[e, j]
                if w < 0:
                    continue
                d = tue - travel[u, w]
                if d > 0.0:
                    g = travel[w, e] / d
                    if g < best:
                        best = g
            out[u, e] = max(best, 1.0)
    return out


@njit(cache=True)
def leg_gains(tails, heads, vis_indptr, vis_indices, row_of):
    """COO (row, leg) of each target row in gain(tail -> head); tail < 0: a start."""
    n_t = len(row_of)
    mark = np.zeros(n_t, np.bool_)
    total = 0
    for a in range(len(heads)):
        total += vis_indptr[heads[a] + 1] - vis_indptr[heads[a]]
    rows = np.empty(total, np.int64)
    cols = np.empty(total, np.int64)
    k = 0
    for a in range(len(heads)):
        u, e = tails[a], heads[a]
        if u >= 0:
            for j in range(vis_indptr[u], vis_indptr[u + 1]):
                mark[vis_indices[j]] = True
        for j in range(vis_indptr[e], vis_indptr[e + 1]):
            t = vis_indices[j]
            if row_of[t] >= 0 and not mark[t]:
                rows[k] = row_of[t]
                cols[k] = a
                k += 1
        if u >= 0:
            for j in range(vis_indptr[u], vis_indptr[u + 1]):
                mark[vis_indices[j]] = False
    return rows[:k], cols[:k]


def _targets(prep, need, max_targets):
    ids = np.flatnonzero((need > 0) & (np.diff(prep.tgt_indptr) > 0))
    if len(ids) > max_targets:
        ids = ids[np.unique(np.linspace(0, len(ids) - 1, max_targets).round().astype(np.int64))]
    return ids


def _legs(prep, k_in, max_gamma=1.05, max_rounds=3):
    """Variable legs (tail, head, LP time) and the certified gamma."""
    travel = prep.travel
    n_vp = travel.shape[0]
    tt = travel.copy()
    np.fill_diagonal(tt, np.inf)
    k_in = min(k_in, n_vp - 1)
    explicit = np.zeros((n_vp, n_vp), np.bool_)
    if k_in > 0:
        nbr = np.argpartition(tt, k_in - 1, axis=0)[:k_in].T  # nbr[e] = nearest tails
        nbr = np.where(np.isfinite(tt[nbr, np.arange(n_vp)[:, None]]), nbr, -1)
        for e in range(n_vp):
            explicit[nbr[e][nbr[e] >= 0], e] = True
    gamma = 1.0
    for _ in range(max_rounds):
        in_nbr = _in_lists(explicit)
        g = stretch(travel, in_nbr, explicit)
        gamma = float(g.max()) if n_vp else 1.0
        if gamma <= max_gamma:
            break
        # add the worst legs into each viewpoint as variables, and certify again
        bad = g > max_gamma
        for e in np.flatnonzero(bad.any(axis=0)):
            us = np.flatnonzero(bad[:, e])
            worst = us[np.argsort(-g[us, e], kind="stable")[:max(k_in // 2, 4)]]
            explicit[worst, e] = True
    tails, heads = np.nonzero(explicit)
    return tails.astype(np.int64), heads.astype(np.int64), travel[tails, heads], gamma


def _in_lists(explicit):
    n = explicit.shape[0]
    deg = explicit.sum(axis=0)
    out = np.full((n, max(int(deg.max()) if n else 0, 1)), -1, np.int64)
    for e in range(n):
        us = np.flatnonzero(explicit[:, e])
        out[e, :len(us)] = us
    return out


class FlowLP:
    """The first-sighting flow LP of a prepared problem, ready to solve for any pruning."""

    def __init__(self, prep, max_targets=MAX_TARGETS, k_in=IN_ARCS):
        p = prep.problem
        self.prep = prep
        self.n = p.n_uavs
        n_vp = p.n_viewpoints
        need = np.maximum(prep.required.astype(np.int64) - prep.seen0.sum(axis=0), 0)
        self.tids = _targets(prep, need, max_targets)
        self.need = need[self.tids].astype(float)
        tails, heads, times, self.gamma = _legs(prep, k_in)
        # start legs: per UAV from its launch (time launch_out), or free starts
        starts_r = np.repeat(np.arange(self.n), n_vp)
        starts_e = np.tile(np.arange(n_vp), self.n)
        if prep.has_launch:
            st_time = prep.launch_out[starts_r, starts_e]
        else:
            st_time = np.zeros(len(starts_r))
        ok = np.isfinite(st_time)
        starts_r, starts_e, st_time = starts_r[ok], starts_e[ok], st_time[ok]
        self.tails = np.concatenate([-1 - starts_r, tails])
        self.heads = np.concatenate([starts_e, heads])
        self.times = np.concatenate([st_time, times / self.gamma])
        self.n_starts = len(starts_r)
        row_of = np.full(p.n_targets, -1, np.int64)
        row_of[self.tids] = np.arange(len(self.tids))
        self.cover_rows, self.cover_cols = leg_gains(self.tails, self.heads, prep.vis_indptr,
                                                     prep.vis_indices, row_of)
        self.nonzeros = len(self.cover_rows) + 3 * len(self.heads)
        self._h = None

    # -- pruning by LP-world reach (launch points) --------------------------------------
    def reach(self):
        """rho[r, e]: least LP time for UAV r to reach e (inf if not reachable)."""
        p = self.prep
        n_vp = p.problem.n_viewpoints
        vp = self.tails >= 0
        rho = np.empty((self.n, n_vp))
        for r in range(self.n):
            st = self.tails == -1 - r  # node n_vp is r's launch
            rows = np.concatenate([self.tails[vp], np.full(int(st.sum()), n_vp)])
            cols = np.concatenate([self.heads[vp], self.heads[st]])
            w = np.maximum(np.concatenate([self.times[vp], self.times[st]]), 1e-12)
            g = csr_matrix((w, (rows, cols)), shape=(n_vp + 1, n_vp + 1))
            rho[r] = dijkstra(g, directed=True, indices=n_vp)[:n_vp]
        return rho

    # -- the LP, its cover rows generated (`FIRST_ROWS`, `ADD_ROWS`) ------------------
    def base_rows(self) -> tuple:
        """(A, upper): the LP's rows but its cover rows, A x <= upper over x = (legs,
        T): the path rows (into a viewpoint no more than out of it), a start per UAV,
        and the time row (the legs' time no more than n T)."""
        n_legs, n_vp = len(self.heads), self.prep.problem.n_viewpoints
        nx = n_legs + 1
        vp = np.flatnonzero(self.tails >= 0)
        flow = coo_matrix((np.concatenate([np.ones(len(vp)), -np.ones(n_legs)]),
                           (np.concatenate([self.tails[vp], self.heads]),
                            np.concatenate([vp, np.arange(n_legs)]))), shape=(n_vp, nx))
        st = np.flatnonzero(self.tails < 0)
        starts = coo_matrix((np.ones(len(st)), (-1 - self.tails[st], st)), shape=(self.n, nx))
        time_row = coo_matrix((np.r_[self.times, -float(self.n)],
                               (np.zeros(nx, np.int64), np.arange(nx))), shape=(1, nx))
        return (vstack([flow, starts, time_row]),
                np.concatenate([np.zeros(n_vp), np.ones(self.n), [0.0]]))

    def legs_allowed(self, allowed) -> np.ndarray:
        """bool per leg: both its ends in ``allowed`` [n_uavs, n_vp] for some UAV (a
        start leg: for its own UAV); all True when ``allowed`` is None."""
        if allowed is None:
            return np.ones(len(self.heads), bool)
        ok_any = allowed.any(axis=0)
        ok = ok_any[self.heads] & np.where(self.tails >= 0,
                                           ok_any[np.maximum(self.tails, 0)], True)
        st = self.tails < 0
        ok[st] &= allowed[-1 - self.tails[st], self.heads[st]]
        return ok

    def _model(self):
        """HiGHS holding the LP without its cover rows: the path and time rows."""
        n_legs, nx = len(self.heads), len(self.heads) + 1
        a, upper = self.base_rows()
        a = a.tocsc()
        lp = highspy.HighsLp()
        lp.num_col_, lp.num_row_ = nx, a.shape[0]
        lp.col_cost_ = np.r_[np.zeros(n_legs), 1.0]
        lp.col_lower_, lp.col_upper_ = np.zeros(nx), np.full(nx, highspy.kHighsInf)
        lp.row_lower_ = np.full(a.shape[0], -highspy.kHighsInf)
        lp.row_upper_ = upper
        lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
        lp.a_matrix_.start_, lp.a_matrix_.index_, lp.a_matrix_.value_ = a.indptr, a.indices, a.data
        h = _highs()
        h.passModel(lp)
        self.cover = csr_matrix((np.ones(len(self.cover_rows)),
                                 (self.cover_rows, self.cover_cols)), shape=(len(self.tids), nx))
        self.in_lp = np.zeros(len(self.tids), bool)
        # the hardest targets first: fewest legs gaining them per sighting needed
        legs = np.diff(self.cover.indptr) / np.maximum(self.need, 1.0)
        self._add_rows(h, np.argsort(legs, kind="stable")[:FIRST_ROWS])
        return h

    def _add_rows(self, h, ids):
        sub = self.cover[ids]
        h.addRows(len(ids), self.need[ids], np.full(len(ids), highspy.kHighsInf), sub.nnz,
                  sub.indptr[:-1].astype(np.int32), sub.indices.astype(np.int32), sub.data)
        self.in_lp[ids] = True

    def solve(self, allowed=None, time_limit=LP_TIME_LIMIT_S):
        """min T with legs into viewpoints outside ``allowed`` [n_uavs, n_vp] left
        out; returns T (inf if infeasible, None if HiGHS gives up before a solve
        finishes).

        The cover rows are generated: the LP is solved with some, the rows its
        solution falls short on are added, and so on until none is (so the value is
        the whole LP's; HiGHS starts each solve from the last basis). Rows added stay
        for later solves: every one is a constraint of every pruning. Out of time
        with rows still short, the last solve's value is returned: the optimum of
        fewer rows, so no more than the whole LP's, a bound all the same."""
        deadline = time.perf_counter() + time_limit
        if self._h is None:
            self._h = self._model()
        h, n_legs = self._h, len(self.heads)
        ub = np.where(self.legs_allowed(allowed), highspy.kHighsInf, 0.0)
        h.changeColsBounds(n_legs, np.arange(n_legs, dtype=np.int32), np.zeros(n_legs), ub)
        value = None
        while True:
            # HiGHS's time limit is on its clock of every run of this instance
            h.setOptionValue("time_limit",
                             h.getRunTime() + max(deadline - time.perf_counter(), 0.01))
            h.run()
            status = h.getModelStatus()
            if status == highspy.HighsModelStatus.kInfeasible:
                return math.inf    # infeasible on some rows: on all of them too
            if status != highspy.HighsModelStatus.kOptimal:
                return value
            value = h.getInfo().objective_function_value * (1.0 - _SAFETY)
            short = self.need - self.cover @ np.asarray(h.getSolution().col_value)
            missing = np.flatnonzero((short > _ROW_TOL) & ~self.in_lp)
            if len(missing) == 0 or time.perf_counter() >= deadline:
                return value
            self._add_rows(h, missing[np.argsort(-short[missing], kind="stable")[:ADD_ROWS]])


def flow_bound(prep, max_targets=MAX_TARGETS, k_in=IN_ARCS, steps=BISECTION_STEPS) -> float:
    """The first-sighting flow LP bound (0 when nothing is needed or the LP is too large)."""
    p = prep.problem
    if p.n_viewpoints == 0 or p.n_targets == 0 or p.n_viewpoints > FLOW_MAX_VIEWPOINTS:
        return 0.0
    lp = FlowLP(prep, max_targets, k_in)
    if len(lp.tids) == 0 or lp.nonzeros > MAX_NONZEROS:
        return 0.0
    deadline = time.perf_counter() + LP_TIME_LIMIT_S
    base = lp.solve(time_limit=LP_TIME_LIMIT_S)
    if base is None:
        return 0.0
    if not prep.has_launch or not math.isfinite(base):
        return base if math.isfinite(base) else 0.0
    rho = lp.reach()

    def f(t):
        left = deadline - time.perf_counter()
        return lp.solve(rho <= t, time_limit=left) if left > 0.05 else None

    best = base
    hi = None
    t = base
    for _ in range(steps):  # grow until f(T) <= T, then bisect
        probe = t * 1.15 if hi is None else 0.5 * (best + hi)
        v = f(probe)
        if v is None:
            break
        if v > probe:
            best = probe
            t = probe
        else:
            hi = probe
    return best
