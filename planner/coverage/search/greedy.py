"""RT (the paper's reduced-time allocation) and RD, on one greedy engine.

Phase 1 spreads the UAVs out (So = Δd · V^β; with launch points the UAVs
start from them instead).  Phase 2 gives the best (viewpoint, UAV) pair by
M_PTV to its UAV, Δt capped by th_ra; insertions that do not lengthen a route
(Δt <= 0, the hidden metric is not Euclidean) go first.  Phase 3 (threshold
adaptation) then feeds the other UAVs by M_PTV2 while their time stays within
the longest time t_ru.  Phases 2 and 3 alternate until every target has its
required number of distinct viewers.  RD uses the per-distance objective and
no phase 3.

If no pair fits under th_ra while targets remain, the cap is lifted for that
step (the paper leaves this case open; stopping would leave targets uncovered).
"""

import math

import numpy as np
from numba import njit

from ..model.battery import unlimited
from ..model.prepared import owners
from ..model.problem import FREE
from ..model.routes import nearest_other, route_time
from .gains import CoverState
from .insertion import combine_ends, insert_cost, middle_costs_all, update_middle_costs
from .objectives import PER_DISTANCE, PTV, PTV2, best_free_pair, best_pair, best_spread


def default_step_cap(travel: np.ndarray, factor: float) -> float:
    """factor x the median nearest-neighbour travel time between viewpoints."""
    n = travel.shape[0]
    if n < 2:
        return math.inf
    nn = nearest_other(travel)
    nn = nn[np.isfinite(nn)]
    return factor * float(np.median(nn)) if len(nn) else math.inf


def step_cap(prep, params) -> float:
    if params.step_time_cap is not None:
        return float(params.step_time_cap)
    return default_step_cap(prep.travel, params.step_cap_factor)


class RouteSet:
    """The UAVs' routes with their times and cached cheapest insertions.

    ``cost[r, e]``/``pos[r, e]``: Δt and slot of the edge-breaking insertion
    of e into r; the best edge is cached separately (``mid_*``) so that
    growing a route at either end never needs a rescan. A viewpoint in one
    UAV's route is closed to the others (``cost`` inf: `model.prepared.owners`), so no
    two UAVs photograph from one place.
    """

    def __init__(self, prep, routes):
        self.prep = prep
        n, n_vp = prep.problem.n_uavs, prep.problem.n_viewpoints
        self.routes = [list(r) for r in routes]
        self.owner = owners(prep, self.routes)
        # per target, the free viewpoints seeing it: what other UAVs can still use
        self.free = free_counts(prep.tgt_indptr, prep.tgt_indices, self.owner)
        self.times = np.zeros(n)
        self.cost = np.empty((n, n_vp))
        self.pos = np.empty((n, n_vp), dtype=np.int64)
        self.mid_cost = np.empty((n, n_vp))
        self.mid_pos = np.empty((n, n_vp), dtype=np.int64)
        for r in range(n):
            arr = self._array(r)
            middle_costs_all(arr, *self._edges(r), self.mid_cost[r], self.mid_pos[r])
            self._finish(r, arr)

    def _array(self, r):
        return np.asarray(self.routes[r], dtype=np.int64)

    def _edges(self, r):
        p = self.prep
        return p.travel, p.travel_t, p.launch_out[r], p.has_launch

    def _finish(self, r, arr):
        p = self.prep
        battery = p.battery(r)
        self.times[r] = route_time(arr, p.travel, battery, p.has_launch)
        combine_ends(arr, p.travel, p.travel_t, battery, p.has_launch,
                     self.mid_cost[r], self.mid_pos[r], self.cost[r],
                     self.pos[r])
        self.cost[r, (self.owner != FREE) & (self.owner != r)] = np.inf

    def insert(self, e, r):
        s = int(self.pos[r, e])
        self.routes[r].insert(s, int(e))
        self.owner[e] = r
        self.cost[:, e] = np.inf
        p = self.prep
        self.free[p.vis_indices[p.vis_indptr[e]:p.vis_indptr[e + 1]]] -= 1
        arr = self._array(r)
        update_middle_costs(arr, s, *self._edges(r), self.mid_cost[r], self.mid_pos[r])
        self._finish(r, arr)


def spread_out(prep, params, state, steps):
    """Phase 1: one start per UAV, or none when the UAVs leave from launch points."""
    n = prep.problem.n_uavs
    routes = [[] for _ in range(n)]
    if prep.has_launch:
        return routes
    chain = np.zeros(0, dtype=np.int64)
    free = unlimited(prep.battery(0))       # the chain is not a route: no battery limits it
    closed = prep.owner0 != FREE            # and, as they are chosen, the other starts
    for r in range(n):
        if state.done:
            break
        gains = np.where(closed, 0.0, state.gains[:, r])
        gains[chain] = 0.0
        e = best_spread(gains, chain, prep.travel, params.beta)
        if e < 0:
            break
        _, p = insert_cost(chain, e, prep.travel, free, False)
        chain = np.insert(chain, p, e)
        routes[r].append(int(e))
        state.take(e, r)
        steps.append((1, r, int(e), 0.0))
    return routes


def allocate(prep, params, objective="ptv", routes=None, state=None, progress=None):
    """Run the greedy phases; returns (routes, steps).

    ``routes``/``state`` continue from a partial allocation (used to repair
    baselines); otherwise phase 1 chooses the starts.
    """
    steps = []
    state = state if state is not None else CoverState(prep)
    if routes is None:
        routes = spread_out(prep, params, state, steps)
    rs = RouteSet(prep, routes)
    cap = step_cap(prep, params)
    metric = PTV if objective == "ptv" else PER_DISTANCE
    adapt = objective == "ptv" and params.threshold_adaptation   # RD has no such setting
    total = max(state.remaining, 1)
    while not state.done:
        e, r, phase = _next_pair(rs, state, metric, params.alpha, cap)
        if e < 0:
            break  # what is left is unreachable
        _give(rs, state, steps, phase, e, r)
        if adapt and phase == 2:
            _threshold_adaptation(rs, state, steps, params)
        if progress is not None:
            progress(1.0 - state.remaining / total)
    return rs.routes, steps


def _next_pair(rs, state, metric, alpha, cap):
    """(viewpoint, UAV, phase) of phase 2: a free insertion (Δt <= 0) first, then
    the best by ``metric`` under the cap, then without it. A pair that would leave
    some target fewer free viewpoints than the distinct UAVs it still needs
    (`blocks`) is closed for that UAV and the next best taken."""
    while True:
        e, r = best_free_pair(state.gains, rs.cost)
        phase = 0
        if e < 0:
            phase = 2
            e, r = best_pair(state.gains, rs.cost, rs.times, metric, alpha, cap, -1, np.inf)
            if e < 0:
                e, r = best_pair(state.gains, rs.cost, rs.times, metric, alpha,
                                 np.inf, -1, np.inf)
        if e < 0 or not _blocks(rs, state, e, r):
            return e, r, phase
        rs.cost[r, e] = np.inf


def _blocks(rs, state, e, r) -> bool:
    p = rs.prep
    return blocks(e, r, p.vis_indptr, p.vis_indices, state.seen, state.count, p.required,
                  rs.free)


def _give(rs, state, steps, phase, e, r):
    rs.insert(e, r)
    state.take(e, r)
    steps.append((phase, int(r), int(e), float(rs.times[r])))


def _threshold_adaptation(rs, state, steps, params):
    """Phase 3: the other UAVs catch up to the longest time t_ru by M_PTV2."""
    ru = int(np.argmax(rs.times))
    t_ru = rs.times[ru]
    while not state.done:
        e, r = best_pair(state.gains, rs.cost, rs.times, PTV2, params.alpha, np.inf, ru, t_ru)
        if e < 0:
            return
        if _blocks(rs, state, e, r):
            rs.cost[r, e] = np.inf
            continue
        _give(rs, state, steps, 3, e, r)


@njit(cache=True)
def free_counts(tgt_indptr, tgt_indices, owner):
    """Per target, how many viewpoints seeing it nobody has taken."""
    n_t = len(tgt_indptr) - 1
    out = np.zeros(n_t, np.int64)
    for t in range(n_t):
        for i in range(tgt_indptr[t], tgt_indptr[t + 1]):
            if owner[tgt_indices[i]] == FREE:
                out[t] += 1
    return out


@njit(cache=True)
def blocks(e, r, vis_indptr, vis_indices, seen, count, req, free):
    """Whether UAV r taking viewpoint e leaves a short target of e fewer free
    viewpoints than the distinct UAVs it still needs (each viewpoint serves one
    UAV: taken for nothing, it is lost to the others)."""
    for j in range(vis_indptr[e], vis_indptr[e + 1]):
        t = vis_indices[j]
        still = req[t] - count[t] - (0 if seen[r, t] else 1)
        if still > 0 and free[t] - 1 < still:
            return True
    return False
