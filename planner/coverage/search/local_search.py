"""A local search that cuts the longest coverage time (after RT: the method RT+LS).

RT's greedy adds a viewpoint whenever its time-weighted gain is best, so it
ends up visiting many more viewpoints than a set cover needs.  The moves, all
of which keep every target seen by its required number of *distinct* UAVs:

* **drop** a visit whose targets the UAV sees elsewhere or other UAVs cover
  often enough;
* **relocate** a visit of the longest route to another route;
* **swap** a visit of the longest route with one of another route;
* **replace** a visit of the longest route by a different viewpoint (in any
  route) that sees every target the removal would leave short;
* **re-optimise** every route's order (2-opt / or-opt).

A move between two routes is taken only if it lowers the larger of their two
times, so the sorted vector of route times decreases lexicographically and the
search terminates.  Coverage bookkeeping: ``cnt[r, t]`` = how many of r's
visits (plus an earlier snapshot) see t, ``dc[t]`` = distinct UAVs with
``cnt > 0``.  The result is never worse than the RT allocation it starts from.
"""

import numpy as np
from numba import njit

from ..model.problem import FREE
from ..model.routes import route_time
from .alns_kernels import apply_visit
from .insertion import improve_route, insert_cost, removal_savings

_EPS = 1e-6


@njit(cache=True)
def _ok(dc, req, e, vis_indptr, vis_indices):
    for j in range(vis_indptr[e], vis_indptr[e + 1]):
        t = vis_indices[j]
        if dc[t] < req[t]:
            return False
    return True


@njit(cache=True)
def _covers_all(candidates, short, n_short, vis_indptr, vis_indices):
    """Mask of candidate viewpoints that see every target flagged in ``short``."""
    out = np.zeros(len(candidates), dtype=np.bool_)
    for i in range(len(candidates)):
        e = candidates[i]
        hit = 0
        for j in range(vis_indptr[e], vis_indptr[e + 1]):
            if short[vis_indices[j]]:
                hit += 1
        out[i] = hit == n_short
    return out


class Search:
    """Routes, their times and the coverage bookkeeping of one local search."""

    def __init__(self, prep, routes, select="all", budget=None):
        self.p = prep
        # "all": drop and replace viewpoints (RT+LS); "drop": only drop redundant
        # visits; "none": only re-route
        self.select = select
        self.budget = budget if budget is not None else 4_000_000
        n = prep.problem.n_uavs
        self.routes = [np.asarray(r, dtype=np.int64) for r in routes]
        # each UAV's battery once: built per call, it cost as much as the moves it priced
        self.batteries = [prep.battery(r) for r in range(n)]
        self.cnt = prep.seen0.astype(np.int32)
        self.dc = (self.cnt > 0).sum(axis=0).astype(np.int32)
        for r in range(n):
            for e in self.routes[r]:
                self._apply(r, e, 1)
        self.times = np.array([self._time(r, self.routes[r]) for r in range(n)])

    # -- bookkeeping -------------------------------------------------------
    def _apply(self, r, e, delta):
        apply_visit(self.cnt, self.dc, r, e, delta, self.p.vis_indptr, self.p.vis_indices)

    def _ok(self, *viewpoints):
        return all(_ok(self.dc, self.p.required, e, self.p.vis_indptr, self.p.vis_indices)
                   for e in viewpoints)

    def _time(self, r, route):
        return route_time(route, self.p.travel, self.batteries[r], self.p.has_launch)

    def _savings(self, r):
        """The time each visit of route r saves when removed."""
        return removal_savings(self.routes[r], self.p.travel, self.batteries[r],
                               self.p.has_launch)

    def _insertion(self, r, route, e):
        self.budget -= len(route) + 1
        return insert_cost(route, e, self.p.travel, self.batteries[r], self.p.has_launch)

    def _legal(self, removals, additions):
        """Apply removals/additions tentatively; keep them if coverage holds."""
        for r, e in removals:
            self._apply(r, e, -1)
        for r, e in additions:
            self._apply(r, e, 1)
        if self._ok(*[e for _, e in removals]):
            return True
        for r, e in additions:
            self._apply(r, e, -1)
        for r, e in removals:
            self._apply(r, e, 1)
        return False

    def _set(self, r, route):
        self.routes[r] = route
        self.times[r] = self._time(r, route)

    # -- moves -------------------------------------------------------------
    def optimise_orders(self):
        improved = False
        for r in range(len(self.routes)):
            new = improve_route(self.routes[r], self.p.travel, self.batteries[r],
                                self.p.has_launch)
            t = self._time(r, new)
            if t < self.times[r] - _EPS:
                self._set(r, new)
                improved = True
        return improved

    def drop_redundant(self):
        """Drop visits that coverage does not need, biggest saving first, longest routes first."""
        improved = False
        if self.select == "none":
            return improved
        for r in np.argsort(-self.times, kind="stable"):
            # drops only lower the counts, so a visit coverage needs stays needed:
            # it is not tried again (the same drops as trying it each time, in a
            # fraction of the time on routes of hundreds)
            needed = set()
            dropped = True
            while dropped and len(self.routes[r]):
                dropped = False
                route = self.routes[r]
                savings = self._savings(r)
                for i in np.argsort(-savings, kind="stable"):
                    if savings[i] < -_EPS:
                        break
                    if route[i] in needed:
                        continue
                    if self._legal([(r, route[i])], []):
                        self._set(r, np.delete(route, i))
                        improved = dropped = True
                        break
                    needed.add(route[i])
        return improved

    def improve_longest(self):
        """One improving relocate / swap / replace on the longest route, if any."""
        if self.budget <= 0:
            return False
        r1 = int(np.argmax(self.times))
        return (self._relocate(r1) or (self.select == "all" and self._replace(r1))
                or self._swap(r1))

    def _relocate(self, r1):
        route1 = self.routes[r1]
        savings = self._savings(r1)
        for i in np.argsort(-savings, kind="stable"):
            e = route1[i]
            t1 = self.times[r1] - savings[i]
            best = None
            for r2 in range(len(self.routes)):
                if r2 == r1 or e in self.routes[r2]:
                    continue
                dt, pos = self._insertion(r2, self.routes[r2], e)
                new_max = max(t1, self.times[r2] + dt)
                if new_max < max(self.times[r1], self.times[r2]) - _EPS and (
                        best is None or new_max < best[0]):
                    best = (new_max, r2, pos)
            if best is not None and self._legal([(r1, e)], [(best[1], e)]):
                _, r2, pos = best
                self._set(r1, np.delete(route1, i))
                self._set(r2, np.insert(self.routes[r2], pos, e))
                return True
        return False

    def _swap(self, r1):
        route1 = self.routes[r1]
        for i in range(len(route1)):
            e1 = route1[i]
            rest1 = np.delete(route1, i)
            for r2 in range(len(self.routes)):
                if r2 == r1:
                    continue
                route2 = self.routes[r2]
                old = max(self.times[r1], self.times[r2])
                for j in range(len(route2)):
                    e2 = route2[j]
                    if e2 == e1 or e2 in rest1 or e1 in route2:
                        continue
                    dt1, p1 = self._insertion(r1, rest1, e2)
                    t1 = self._time(r1, rest1) + dt1
                    if t1 >= old - _EPS:
                        continue
                    rest2 = np.delete(route2, j)
                    dt2, p2 = self._insertion(r2, rest2, e1)
                    t2 = self._time(r2, rest2) + dt2
                    if t2 >= old - _EPS:
                        continue
                    if self._legal([(r1, e1), (r2, e2)], [(r1, e2), (r2, e1)]):
                        self._set(r1, np.insert(rest1, p1, e2))
                        self._set(r2, np.insert(rest2, p2, e1))
                        return True
        return False

    def _replace(self, r1):
        p = self.p
        route1 = self.routes[r1]
        for i in np.argsort(-self._savings(r1), kind="stable"):
            e = route1[i]
            rest1 = np.delete(route1, i)
            t1 = self._time(r1, rest1)
            self._apply(r1, e, -1)
            ts = p.vis_indices[p.vis_indptr[e]:p.vis_indptr[e + 1]]
            short = ts[self.dc[ts] < p.required[ts]]
            move = self._best_replacement(r1, rest1, t1, e, short) if len(short) else None
            self._apply(r1, e, 1)
            if move is not None:
                e2, r2, pos = move
                self._apply(r1, e, -1)
                self._apply(r2, e2, 1)
                self._set(r1, rest1)
                self._set(r2, np.insert(self.routes[r2], pos, e2))
                return True
        return False

    def _best_replacement(self, r1, rest1, t1, e, short):
        p = self.p
        t0 = short[np.argmin(np.diff(p.tgt_indptr)[short])]
        cands = p.tgt_indices[p.tgt_indptr[t0]:p.tgt_indptr[t0 + 1]]
        mask = np.zeros(p.problem.n_targets, dtype=np.bool_)
        mask[short] = True
        cands = cands[(cands != e) & _covers_all(cands, mask, len(short), p.vis_indptr,
                                                 p.vis_indices)]
        best = None
        # a viewpoint in another route, or photographed from before, is not free
        taken = set(np.concatenate([rest1] + [q for k, q in enumerate(self.routes) if k != r1]
                                   ).tolist()) | set(np.flatnonzero(p.owner0 != FREE).tolist())
        for r2 in range(len(self.routes)):
            if np.any(self.cnt[r2, short] > 0):
                continue  # r2 would not add a distinct viewer
            route2 = rest1 if r2 == r1 else self.routes[r2]
            base2 = t1 if r2 == r1 else self.times[r2]
            old = self.times[r1] if r2 == r1 else max(self.times[r1], self.times[r2])
            for e2 in cands:
                if e2 in taken:
                    continue
                dt, pos = self._insertion(r2, route2, e2)
                new = base2 + dt if r2 == r1 else max(t1, base2 + dt)
                if new < old - _EPS and (best is None or new < best[0]):
                    best = (new, int(e2), r2, pos)
        return None if best is None else best[1:]


def local_search(prep, routes, rounds=20, select="all", budget=None):
    """Improve ``routes``; ``select`` limits the selection moves ("all", "drop", "none").

    ``budget`` bounds the work (insertion evaluations x route length), which
    keeps the search deterministic and its time bounded on large problems.
    """
    s = Search(prep, routes, select, budget)
    for _ in range(max(rounds, 1)):
        changed = s.drop_redundant()
        changed |= s.optimise_orders()
        while s.improve_longest():
            changed = True
        if not changed or s.budget <= 0:
            break
    return [list(map(int, r)) for r in s.routes]
