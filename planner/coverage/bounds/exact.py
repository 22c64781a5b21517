"""The optimum of a small coverage problem, proven: the oracle of the tests and
of ``bench_coverage --optimal``.

**The optimum is a makespan.** Coverage time is when the last target first has
its required sightings. Cut every route of an optimal plan after its last
snapshot taken by then: nothing counted is lost, and no route lasts longer
than the coverage time. So the optimum is the least *makespan* (the longest
route's time to its last snapshot) over plans whose routes see every target
from as many distinct UAVs at distinct places as it needs (`model.places`).

**Choosing sets, then proving them flyable** (a logic-based Benders scheme).
A route is a set of viewpoints flown in the best order; its least time is a
Held-Karp dynamic programme over the set (`route_time`), and a subset never
takes longer (travel times are shortest paths, so skipping a viewpoint never
costs time). For a time T, a *master* (CP-SAT, boolean) chooses per UAV the set
of viewpoints it flies such that every target class (`_needed_classes`) has a
matching of ``required`` (UAV, viewpoint) pairs, distinct UAVs at distinct
viewpoints among its viewers, each UAV flying its viewpoint (the rule
`model.evaluation.evaluate` counts by). Each chosen set is then timed: a set slower than
T is cut down to a minimal slow subset (deleting viewpoints while it stays
slow) and forbidden to that UAV, and to every UAV with the same launch times.
A choice that all UAVs fly within T is a plan: T drops below its makespan and
the master is asked again. The master's "no choice" is the proof: no plan beats
the incumbent. Forbidden sets stay forbidden as T falls.
Whenever T falls, every viewpoint and pair already slower than T is forbidden
up front, and each UAV's set must fit a knapsack relaxation of its route
(each viewpoint entered by its cheapest way in: `_knapsack`). UAVs without
launch points are interchangeable: only one order of them is searched.

Written from the problem's definition; checked against enumeration of every
plan on tiny problems (tests/test_exact.py). Plain problems only: no earlier
sightings, owners or battery limit (re-planning and sorties are not this
oracle's).
"""

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit
from ortools.sat.python import cp_model

from ..model.classes import target_classes
from ..model.evaluation import evaluate
from ..model.prepared import prepare
from ..model.problem import CoverageProblem

#: a plan must beat the incumbent by this much (seconds) to count as better
TOLERANCE_S = 1e-6


@dataclass
class Optimum:
    """What the solver found: ``value`` is the coverage time of ``routes``
    (`evaluate`); ``proven`` when no plan is quicker by more than
    `TOLERANCE_S`, else the time limit came first and ``lower`` is what is
    known below (0 when nothing is)."""

    value: float
    lower: float
    routes: list
    proven: bool
    seconds: float
    rounds: int


@njit(cache=True)
def route_time(vs, travel, start, has_launch):
    """(least time of a route through exactly the viewpoints ``vs``, that order):
    Held-Karp over subsets, the route starting at ``start[e]`` from the launch
    point (or at its first viewpoint without launch points)."""
    m = len(vs)
    if m == 0:
        return 0.0, np.empty(0, np.int64)
    full = 1 << m
    dp = np.full((full, m), np.inf)
    for i in range(m):
        dp[1 << i, i] = start[vs[i]] if has_launch else 0.0
    for mask in range(1, full):
        for i in range(m):
            here = dp[mask, i]
            if not (mask >> i) & 1 or not np.isfinite(here):
                continue
            for j in range(m):
                if (mask >> j) & 1:
                    continue
                t = here + travel[vs[i], vs[j]]
                if t < dp[mask | (1 << j), j]:
                    dp[mask | (1 << j), j] = t
    last = int(np.argmin(dp[full - 1]))
    best = dp[full - 1, last]
    order = np.empty(m, np.int64)
    mask = full - 1
    for pos in range(m - 1, -1, -1):  # walk the table back
        order[pos] = vs[last]
        prev_mask = mask ^ (1 << last)
        if prev_mask == 0:
            break
        for i in range(m):
            if (prev_mask >> i) & 1 and \
                    dp[prev_mask, i] + travel[vs[i], vs[last]] == dp[mask, last]:
                mask, last = prev_mask, i
                break
    return best, order


def optimum(problem: CoverageProblem, time_limit_s: float = 60.0, hint=None) -> Optimum:
    """The least coverage time of ``problem`` (see module doc). ``hint``: routes
    of a known plan (the first incumbent: the search then only looks below it).
    Raises ValueError for a problem this oracle does not model."""
    if problem.seen is not None or problem.owner is not None or problem.visited is not None \
            or math.isfinite(problem.endurance_s):
        raise ValueError("the exact solver takes plain problems: no seen, visited, owner or "
                         "endurance")
    start = time.perf_counter()
    prep = prepare(problem)
    master = _Master(prep)
    best_routes, best = None, math.inf
    if hint is not None:
        best_routes = [list(map(int, r)) for r in hint]
        best = evaluate(prep, best_routes, "exact").coverage_time
    rounds, proven = 0, False
    while True:
        left = time_limit_s - (time.perf_counter() - start)
        if left <= 0:
            break
        rounds += 1
        chosen = master.choose(best - TOLERANCE_S, left)
        if chosen is None:  # out of time
            break
        if chosen is False:  # nothing beats the incumbent
            proven = True
            break
        routes, slow = master.check(chosen, best - TOLERANCE_S)
        if not slow:
            value = evaluate(prep, routes, "exact").coverage_time
            if value < best:
                best, best_routes = value, routes
    if best_routes is None:
        raise ValueError(f"no plan found in {time_limit_s} s")
    return Optimum(best, best if proven else 0.0, best_routes, proven,
                   time.perf_counter() - start, rounds)


class _Master:
    """The set-choosing CP-SAT model, grown by forbidden sets (see module doc)."""

    def __init__(self, prep):
        self.prep = prep
        p = prep.problem
        self.n, self.m = p.n_uavs, p.n_viewpoints
        self.model = cp_model.CpModel()
        self.visit = [[self.model.new_bool_var(f"v{r},{e}") for e in range(self.m)]
                      for r in range(self.n)]
        self.twins = _twins(prep)
        self.forbidden = set()
        self.small_limit = math.inf
        self.entries = _entries(prep)
        self.entered = self._entered()
        self._coverage()
        self._order_twins()

    def _coverage(self):
        md, visit = self.model, self.visit
        for viewers, need in _needed_classes(self.prep):
            if need == 1:
                md.add_bool_or([visit[r][e] for r in range(self.n) for e in viewers])
                continue
            # a matching of `need` (UAV, place) pairs: distinct UAVs at distinct places
            pick = {(r, e): md.new_bool_var("") for r in range(self.n) for e in viewers}
            for (r, e), y in pick.items():
                md.add_implication(y, visit[r][e])
            for r in range(self.n):
                md.add_at_most_one(pick[r, e] for e in viewers)
            for e in viewers:
                md.add_at_most_one(pick[r, e] for r in range(self.n))
            md.add(sum(pick.values()) >= need)

    def _order_twins(self):
        """UAVs that fly alike are interchangeable: keep only the order of them by
        the lowest viewpoint each flies (a UAV's lowest no lower than the previous
        twin's)."""
        for r in range(self.n):
            later = [s for s in self.twins[r] if s > r]
            if not later:
                continue
            s = min(later)
            for e in range(self.m):
                self.model.add_bool_or([~self.visit[s][e]] + self.visit[r][:e + 1])

    def forbid(self, r, vs, limit=None):
        """No UAV flying like r flies all of ``vs``; with ``limit``, nor any other UAV
        for which that set is slower than it too."""
        others = [s for s in range(self.n) if s not in self.twins[r]] if limit is not None else []
        for uav in self.twins[r] + [s for s in others if self._slow(s, vs, limit)]:
            key = (uav, tuple(vs))
            if key not in self.forbidden:
                self.forbidden.add(key)
                self.model.add_bool_or([~self.visit[uav][e] for e in vs])

    def choose(self, limit, left):
        """Per UAV the set it flies (a list of arrays), False if no choice is left,
        None if the time ran out. Sets forbidden so far are avoided and so is every
        viewpoint (and pair) no UAV reaches (and flies) within ``limit``."""
        self._forbid_small(limit)
        solver = cp_model.CpSolver()
        solver.parameters.max_time_in_seconds = left
        solver.parameters.num_workers = 1
        solver.parameters.cp_model_presolve = False  # many quick solves of a growing model
        status = solver.solve(self.model)
        if status == cp_model.INFEASIBLE:
            return False
        if status not in (cp_model.OPTIMAL, cp_model.FEASIBLE):
            return None
        return [np.array([e for e in range(self.m) if solver.boolean_value(self.visit[r][e])],
                         np.int64) for r in range(self.n)]

    def _forbid_small(self, limit):
        if limit >= self.small_limit:
            return
        self.small_limit = limit
        self._knapsack(limit)
        for r in range(self.n):
            if self.twins[r][0] != r:
                continue
            for e in range(self.m):
                if self._slow(r, [e], limit):
                    self.forbid(r, [e])
                    continue
                for f in range(e + 1, self.m):
                    if (r, (f,)) not in self.forbidden and self._slow(r, [e, f], limit):
                        self.forbid(r, [e, f])

    def _knapsack(self, limit):
        """A route enters each viewpoint it flies once: the first from its start,
        the others from another viewpoint, so it takes at least the sum of their
        cheapest ways in from a viewpoint (`_entries`) less, for the first, what
        that exceeds its time from the start (in whole milliseconds, rounded
        to keep it a relaxation)."""
        cap = int(math.ceil(limit * 1000.0))
        for entered in self.entered:
            self.model.add(entered <= cap)

    def _entered(self):
        """Per UAV, the knapsack's left side (see `_knapsack`), built once."""
        out = []
        for r in range(self.n):
            into, spare = self.entries[r]
            first = self.model.new_int_var(int(min(spare.min(initial=0), 0)),
                                           int(max(spare.max(initial=0), 0)), "")
            self.model.add_max_equality(first, [int(c) * x for c, x in zip(spare, self.visit[r])])
            out.append(sum(int(c) * x for c, x in zip(into, self.visit[r])) - first)
        return out

    def _slow(self, r, vs, limit):
        p = self.prep
        return route_time(np.asarray(vs, np.int64), p.travel, p.launch_out[r],
                          p.has_launch)[0] > limit

    def check(self, chosen, limit):
        """(routes in their best order, whether some set was slower than
        ``limit``); a slow set is forbidden by a minimal slow subset of it."""
        routes, slow = [], False
        for r, vs in enumerate(chosen):
            t, order = route_time(vs, self.prep.travel, self.prep.launch_out[r],
                                  self.prep.has_launch)
            routes.append(list(map(int, order)))
            rest, slow_here = list(vs), t > limit
            while slow_here:  # forbid disjoint minimal slow subsets while any is left
                slow = True
                cut = self._minimal(r, rest, limit)
                self.forbid(r, cut, limit)
                rest = [e for e in rest if e not in cut]
                slow_here = self._slow(r, rest, limit)
        return routes, slow

    def _minimal(self, r, vs, limit):
        for e in list(vs):
            rest = [f for f in vs if f != e]
            if self._slow(r, rest, limit):
                vs = rest
        return vs


def _entries(prep):
    """Per UAV (into, spare), whole milliseconds: the cheapest way into each
    viewpoint from another one (rounded down), and that less the UAV's time
    from its start (rounded up; its start costs nothing without launch points)."""
    tt = prep.travel.copy()
    np.fill_diagonal(tt, np.inf)
    into = tt.min(axis=0) if len(tt) else np.zeros(0)
    into = np.floor(np.where(np.isfinite(into), into, 0.0) * 1000.0)
    out = []
    for r in range(prep.problem.n_uavs):
        lo = np.ceil(np.where(np.isfinite(prep.launch_out[r]), prep.launch_out[r], 0.0) * 1000.0)
        out.append((into.astype(np.int64), (into - lo).astype(np.int64)))
    return out


def _twins(prep):
    """Per UAV, the UAVs whose routes take the same times (all, without launch
    points), itself first."""
    n = prep.problem.n_uavs
    if not prep.has_launch:
        return [[r] + [s for s in range(n) if s != r] for r in range(n)]
    same = [[s for s in range(n) if np.array_equal(prep.launch_out[r], prep.launch_out[s])]
            for r in range(n)]
    return [[r] + [s for s in group if s != r] for r, group in enumerate(same)]


def _needed_classes(prep):
    """(viewers, need) per target class that must be covered and is not implied
    by another (a class whose viewers include another's and needs no more: a
    matching for that one serves it too). Built on `model.classes.target_classes`
    (targets seen from the same viewpoints), which the problem keeps anyway."""
    cp, _, _ = target_classes(prep)
    need = cp.required
    seen = {}
    for t in range(len(need)):
        if need[t] <= 0:
            continue
        viewers = tuple(cp.tgt_indices[cp.tgt_indptr[t]:cp.tgt_indptr[t + 1]])
        seen[viewers] = max(seen.get(viewers, 0), int(need[t]))
    kept = []
    for viewers, q in sorted(seen.items(), key=lambda c: len(c[0])):
        s = set(viewers)
        if not any(q <= kq and ks <= s for ks, kq in kept):
            kept.append((s, q))
    return [(sorted(s), q) for s, q in kept]
