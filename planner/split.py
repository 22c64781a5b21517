"""A large area planned in parts, joined into one plan.

Every coverage method works on a dense matrix of hidden travel times between the
viewpoints: n² entries, 0.94 GB for the 10,837 viewpoints of a 2048² area, 24 GB
for the 54,908 of a 4096² one. Past `PART_VIEWPOINTS` viewpoints (or with
``--parts N``) a plan is made in parts:

- the viewpoints are split into parts of about equal count by recursive
  bisection across the longer side, so that parts are compact and seams short;
- each target belongs to the part with the most viewpoints that see it (so its
  part can cover it);
- the fleet is split into one group per part, sized so that the estimated part
  makespans balance (transit from the launch plus the visits of a greedy cover);
- each part is a coverage problem of its own: its viewpoints, the targets they
  see and their travel times (shortest paths over one sparse overlay of the
  whole area, `planner.travel.overlay_rows`: a part's two viewpoints are often
  joined only through another part; made in the part's own task on a cluster,
  else here: the overlay is bridged, so no part needs the graph for them);
  its own targets need k + 1 distinct UAVs of its group, the others nothing.
  The parts are solved by the scenario's method, as dask tasks on the plan's
  cluster or here one after another;
- the join, across the seams: a target near a seam is often seen by the next
  group too, so every visit whose targets stay covered as required by the
  plan's coverage time without it is dropped. A dropped visit only makes the rest
  of its route earlier (hidden travel times obey the triangle inequality).

Routes are then flown on the one travel graph of the whole area (a transit from
a shared launch point crosses other parts) and proven like those of any plan.
"""

import time
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np
from numba import njit
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

from common.errors import InputError

from . import coverage
from .coverage.bounds.radius import reach_bound_of
from .coverage.model import CLOSED, achievable, beyond_battery, csc_transpose
from .coverage.model.places import count_with, matched_counts
from .coverage.model.routes import walked
from .coverage.search.setcover import greedy_cover
from .parallel import run_chunks
from .travel import overlay_rows

#: viewpoints per part when the scenario leaves the number of parts open: about
#: the largest problem planned whole within the 2048² goal (10,837 viewpoints,
#: a 0.94 GB travel matrix)
PART_VIEWPOINTS = 12_000


def n_parts(n_viewpoints: int, scenario) -> int:
    """How many parts a plan over ``n_viewpoints`` is made in: the scenario's
    ``parts``, else enough for `PART_VIEWPOINTS` each; at most as many as leave
    every part the k + 1 UAVs its targets need (fewer after losses in flight).
    1: the whole area is one problem."""
    wanted = (scenario.parts if scenario.parts is not None
              else -(-int(n_viewpoints) // PART_VIEWPOINTS))
    return max(1, min(int(wanted), scenario.uavs // (scenario.k + 1)))


def split_viewpoints(xy: np.ndarray, parts: int) -> np.ndarray:
    """Part label per viewpoint: recursive bisection at the (weighted) median
    across the longer side of each part; counts differ by at most one per cut."""
    labels = np.zeros(len(xy), np.int64)
    _bisect(np.asarray(xy, float), np.arange(len(xy)), parts, 0, labels)
    return labels


def _bisect(xy, idx, parts, first, labels):
    if parts == 1 or len(idx) == 0:
        labels[idx] = first
        return
    pts = xy[idx]
    axis = int(np.ptp(pts[:, 0]) < np.ptp(pts[:, 1]))
    order = idx[np.lexsort((pts[:, 1 - axis], pts[:, axis]))]
    left = parts // 2
    cut = int(round(len(order) * left / parts))
    _bisect(xy, order[:cut], left, first, labels)
    _bisect(xy, order[cut:], parts - left, first + left, labels)


@njit(cache=True)
def _shares(vis_indptr, vis_indices, labels, required, parts, flyable):
    """[n_targets, parts]: the sightings each part's group owes each target. A
    target's k+1 sightings come from distinct places, so no part can owe more
    than it has viewpoints seeing the target (``flyable`` ones: within a battery):
    the part with the most of them owes what it can, the next the rest, and so on
    (in all, what the area can give)."""
    n_t = len(required)
    votes = np.zeros((n_t, parts), np.int32)
    for e in np.flatnonzero(flyable):
        for j in range(vis_indptr[e], vis_indptr[e + 1]):
            votes[vis_indices[j], labels[e]] += 1
    owed = np.zeros((n_t, parts), np.int32)
    for t in range(n_t):
        left = required[t]
        for p in np.argsort(-votes[t], kind="mergesort"):
            give = min(left, votes[t, p])
            owed[t, p] = give
            left -= give
    return owed


@dataclass
class Part:
    """One part: global ids of its viewpoints and of the targets they see, and
    what each of those targets needs from this part's group."""

    viewpoints: np.ndarray
    targets: np.ndarray
    vis_indptr: np.ndarray  # CSR rows of its viewpoints over its own target ids
    vis_indices: np.ndarray
    required: np.ndarray  # per own target id: the sightings this part's group owes it
    spacing_m: float  # median distance from a viewpoint to its nearest other one

    @property
    def need(self) -> int:
        return int(self.required.max(initial=0))


def make_parts(problem, xy: np.ndarray, parts: int) -> list:
    """The parts of ``problem`` (a `coverage.CoverageProblem` of the whole area;
    its travel matrix is not used) with viewpoints at ``xy``."""
    labels = split_viewpoints(xy, parts)
    indptr = np.asarray(problem.vis_indptr, np.int64)
    indices = np.asarray(problem.vis_indices)
    # a part owing a target only a viewpoint beyond one battery sees in it would
    # leave it unseen where another part has one within reach
    flyable = np.ones(len(indptr) - 1, bool)
    if problem.endurance_s < np.inf:
        flyable[beyond_battery(problem)] = False
    owed = _shares(indptr, indices, labels, problem.needs(), parts, flyable)
    out = []
    for p in range(parts):
        vps = np.flatnonzero(labels == p)
        rows = [indices[indptr[e]:indptr[e + 1]] for e in vps]
        targets = np.unique(np.concatenate(rows)) if rows else np.zeros(0, indices.dtype)
        sub_indptr = np.r_[0, np.cumsum([len(r) for r in rows])].astype(np.int64)
        sub_indices = (np.searchsorted(targets, np.concatenate(rows)).astype(np.int32)
                       if rows else np.zeros(0, np.int32))
        need = owed[targets, p]
        out.append(Part(vps, targets, sub_indptr, sub_indices, need, _spacing(xy[vps])))
    return out


def _spacing(xy) -> float:
    if len(xy) < 2:
        return 0.0
    nearest, _ = cKDTree(xy).query(xy, k=2)
    return float(np.median(nearest[:, 1]))


def group_sizes(parts: list, n_uavs: int, transit: np.ndarray, speed_mps: float) -> np.ndarray:
    """UAVs per part: each part first gets the k + 1 its targets need, then every
    further UAV goes to the part with the longest estimated makespan, transit +
    need x (greedy cover size) x (viewpoint spacing / speed) / UAVs."""
    need = np.array([p.need for p in parts])
    if need.sum() > n_uavs:
        raise InputError("--parts", f"{len(parts)} parts need {int(need.sum())} UAVs (each part "
                                    f"k + 1 of its own), only {n_uavs} given: use fewer parts "
                                    "or more UAVs")
    work = np.array([_visit_work(p) / speed_mps for p in parts])
    sizes = need.copy()
    for _ in range(n_uavs - int(need.sum())):
        estimate = transit + work / np.maximum(sizes, 1)
        estimate[need == 0] = -np.inf  # nothing to do there
        if not np.isfinite(estimate).any():
            estimate = -sizes.astype(float)  # spare UAVs: spread them
        sizes[int(np.argmax(estimate))] += 1
    return sizes


def _visit_work(part: Part) -> float:
    """need x greedy cover size x viewpoint spacing: the flying a part needs, in
    UAV-metres (an estimate for sizing groups, nothing more)."""
    if part.need == 0:
        return 0.0
    tgt_indptr, tgt_indices = csc_transpose(part.vis_indptr, part.vis_indices,
                                            len(part.targets))
    cover = greedy_cover(part.vis_indptr, part.vis_indices, tgt_indptr, tgt_indices,
                         (part.required > 0).astype(np.int64),
                         np.ones(len(part.viewpoints), np.bool_))
    return part.need * len(cover) * part.spacing_m


def assign_uavs(sizes: np.ndarray, transit: Optional[np.ndarray]) -> list:
    """UAV ids per part: ``sizes[p]`` each, by least total transit (``transit[u, p]``:
    median time from UAV u's start to part p's viewpoints); in order without it."""
    slots = np.repeat(np.arange(len(sizes)), sizes)
    cost = np.zeros((len(slots), len(slots))) if transit is None else transit[:, slots]
    uavs, slot = linear_sum_assignment(cost)
    return [np.sort(uavs[slots[slot] == p]) for p in range(len(sizes))]


def _median_finite(times: np.ndarray) -> np.ndarray:
    t = np.where(np.isfinite(times), times, np.nan)
    with np.errstate(all="ignore"):
        m = np.nanmedian(t, axis=1) if t.shape[1] else np.zeros(len(t))
    return np.nan_to_num(m, nan=1e12)


def part_problem(problem, part: Part, uavs: np.ndarray, travel: np.ndarray):
    """The coverage problem of one part for its group ``uavs``, with the travel
    times between its viewpoints."""
    def rows(a):
        return None if a is None else np.asarray(a)[uavs][:, part.viewpoints]

    seen = None if problem.seen is None else np.asarray(problem.seen)[uavs][:, part.targets]
    owner = None
    if problem.owner is not None:       # another group's viewpoint is closed to this one
        local = np.full(problem.n_uavs, CLOSED, np.int64)
        local[uavs] = np.arange(len(uavs))
        given = np.asarray(problem.owner, np.int64)[part.viewpoints]
        owner = np.where(given >= 0, local[np.maximum(given, 0)], given)
    def per_uav(a):
        return None if a is None else np.asarray(a)[uavs]

    def columns(a):         # per base: its part's viewpoints
        return None if a is None else np.asarray(a)[:, part.viewpoints]

    return coverage.CoverageProblem(part.vis_indptr, part.vis_indices, len(part.targets),
                                    travel, rows(problem.launch_out),
                                    rows(problem.launch_back), len(uavs),
                                    min(problem.k, len(uavs) - 1), problem.visibility,
                                    part.required, seen, owner,
                                    endurance_s=problem.endurance_s,
                                    turnaround_s=problem.turnaround_s,
                                    reach_s=problem.reach_s, base_out=rows(problem.base_out),
                                    visited=rows(problem.visited),
                                    used_s=per_uav(problem.used_s),
                                    start_back=per_uav(problem.start_back),
                                    bases_out=columns(problem.bases_out),
                                    bases_back=columns(problem.bases_back),
                                    trip_s=rows(problem.trip_s),
                                    bases_trip_s=columns(problem.bases_trip_s))


def _solve_part(method, params, report, n, overlay, chunk):
    """One part solved (on a dask worker or here): its routes in its own viewpoint
    ids, the arrival time at every snapshot and the sortie of each visit (the
    battery's split the method planned with; all 0 without an endurance), its
    coverage time. ``report(fraction)``
    of all ``n`` parts, here. A problem without travel times gets them here, over
    ``overlay``, for its viewpoints ``ids`` (`planner.travel.overlay_rows`)."""
    k, problem, ids = chunk
    if problem.travel is None:
        problem = replace(problem, travel=overlay_rows(overlay, ids))
    on = (lambda f: report((k + f) / n)) if report is not None else None
    allocation = coverage.solve(problem, method, params, progress=on)
    prep = coverage.prepare(problem)
    walks = [walked(np.asarray(r, np.int64), prep.travel, prep.battery(u), prep.has_launch)[:2]
             for u, r in enumerate(allocation.routes)]
    return allocation.routes, walks, allocation.coverage_time


@dataclass
class Joined:
    """The parts' routes over the whole area's viewpoints, joined."""

    routes: list  # per UAV: global viewpoint ids
    arrivals: list  # per UAV: estimated arrival time at each snapshot (an upper bound)
    sortie_of: list  # per UAV: the sortie of each visit (`planner.sorties.make_sorties`)
    groups: list  # per part: its UAV ids
    part_times: list  # per part: its coverage time as solved
    dropped: int  # visits the join made redundant
    travel_s: float = 0.0  # of the time, making the parts' travel times

    def allocation(self, problem, method: str) -> coverage.Allocation:
        """The joined routes as an `coverage.Allocation`; its times come from the
        parts' travel matrices (upper bounds of the times flown)."""
        times = np.array([a[-1] if len(a) else 0.0 for a in self.arrivals])
        back = times.copy()
        if problem.launch_back is not None:
            for u, r in enumerate(self.routes):
                back[u] += problem.launch_back[u, r[-1]] if r else 0.0
        cover = max(self.part_times, default=0.0)
        return coverage.Allocation(method, self.routes, times, back, float(cover),
                                   float(back.max(initial=0.0)), float(times.sum()),
                                   sum(len(r) for r in self.routes), bool(np.isfinite(cover)),
                                   0)


def solve_parts(problem, parts: list, method: str, params, matrix, speed_mps: float,
                client=None, progress=None, overlay=None) -> Joined:
    """Size and place the groups, then for each part in turn make its travel times
    and solve it: here, or as a dask task on ``client`` (its problem sent to a
    worker when one is free), so that this process holds one part's travel times
    at a time; then join. ``matrix(viewpoint ids, progress)`` makes a part's times
    here, or returns None: they are then made in the part's task, over ``overlay``
    (`planner.travel.overlay_rows`), so that parts on a cluster make their times
    side by side (their time then counts in the allocation's). ``parts`` is
    consumed: each part is let go once its problem is made.
    ``progress(stage, fraction)`` for "travel times" and "allocation"."""
    out = None if problem.launch_out is None else np.asarray(problem.launch_out)
    transit = (None if out is None else  # [UAVs, parts]
               np.stack([_median_finite(out[:, p.viewpoints]) for p in parts], axis=1))
    typical = np.zeros(len(parts)) if transit is None else np.median(transit, axis=0)
    groups = assign_uavs(group_sizes(parts, problem.n_uavs, typical, speed_mps), transit)
    index = [i for i, g in enumerate(groups) if len(g)]
    viewpoints = [p.viewpoints for p in parts]
    spent = [0.0]

    def made(k, i):
        start = time.perf_counter()
        travel = matrix(parts[i].viewpoints, _sub(progress, "travel times", k, len(index)))
        spent[0] += time.perf_counter() - start
        out = (k, part_problem(problem, parts[i], groups[i], travel),
               parts[i].viewpoints if travel is None else None)
        parts[i] = None  # let go: the problem holds what it needs
        return out

    def problems():  # no local keeps a part's problem while the next one is made
        for k, i in enumerate(index):
            yield made(k, i)

    here = client is None
    report = _sub(progress, "allocation", 0, 1) if here and progress else None
    solved = run_chunks(_solve_part, problems(), (method, params, report, len(index), overlay),
                        client, None if here or not progress else
                        _sub(progress, "allocation", 0, 1), total=len(index), scatter=True)
    routes = [[] for _ in range(problem.n_uavs)]
    arrivals, sortie_of = [np.zeros(0)] * problem.n_uavs, [np.zeros(0, np.int64)] * problem.n_uavs
    for i, (part_routes, walks, _) in zip(index, solved):
        for u, r, (a, of) in zip(groups[i], part_routes, walks):
            routes[u] = [int(viewpoints[i][e]) for e in r]
            arrivals[u], sortie_of[u] = a, of
    times = [t for _, _, t in solved]
    keep = drop_redundant(problem, routes, arrivals, max(times, default=0))
    kept = [np.asarray(r, np.int64)[k].tolist() for r, k in zip(routes, keep)]
    in_flight = problem.start_back is not None
    sortie_of = [_renumbered(of[k], in_flight and problem.start_back[u] > 0)
                 for u, (of, k) in enumerate(zip(sortie_of, keep))]
    return Joined(kept, [a[k] for a, k in zip(arrivals, keep)], sortie_of, groups, times,
                  int(sum((~k).sum() for k in keep)), spent[0])


def _renumbered(of, keeps_first: bool) -> np.ndarray:
    """Sorties numbered 0, 1, ... again once the join emptied some (dropping a
    visit only shortens its sortie); ``keeps_first``: a vehicle in flight, whose
    sortie 0 is the flight under way even when none of its visits are left."""
    values = np.unique(of)
    if keeps_first and (not len(values) or values[0] != 0):
        values = np.concatenate([[0], values])
    return np.searchsorted(values, of).astype(np.int64)


def _sub(progress, stage, k, n):
    """``progress`` for item k of n of ``stage``, as a fraction of the item."""
    if progress is None:
        return None
    return lambda f: progress(stage, (k + f) / n)


def drop_redundant(problem, routes, arrivals, by: float):
    """Drop every visit whose targets stay seen by their required number of
    distinct UAVs at distinct places by time ``by`` without it; long routes first, early visits
    first (they delay the most). Returns per route whether each visit is kept (the
    arrivals of kept visits stay upper bounds)."""
    uav = np.concatenate([np.full(len(r), u, np.int64) for u, r in enumerate(routes)]
                         + [np.zeros(0, np.int64)])
    vp = np.concatenate([np.asarray(r, np.int64) for r in routes] + [np.zeros(0, np.int64)])
    when = np.concatenate([np.asarray(a, float) for a in arrivals] + [np.zeros(0)])
    seen = problem.seen_before()
    own = problem.own_matrix().astype(np.uint8)   # as `coverage.prepare` types it
    length = np.array([a[-1] if len(a) else 0.0 for a in arrivals])
    pos = np.concatenate([np.arange(len(r)) for r in routes] + [np.zeros(0, np.int64)])
    order = np.lexsort((pos, -length[uav])) if len(uav) else np.zeros(0, np.int64)
    indptr, indices = np.asarray(problem.vis_indptr, np.int64), np.asarray(problem.vis_indices)
    # where two UAVs fly one viewpoint (a share repair) distinct UAVs are not distinct
    # places: what such a viewpoint sees is counted by the exact matching rule
    at = np.where(problem.visited_matrix(), 0.0, np.inf)
    np.minimum.at(at, (uav, vp), np.where(when <= by, when, np.inf))
    shared = np.zeros(problem.n_targets, bool)
    for e in np.flatnonzero(np.isfinite(at).sum(axis=0) >= 2):
        shared[indices[indptr[e]:indptr[e + 1]]] = True
    tgt_indptr, tgt_indices = csc_transpose(indptr, indices, int(problem.n_targets))
    need = problem.needs()      # a short target keeps all it has
    some = np.flatnonzero(shared)
    need[some] = matched_counts(some, at, tgt_indptr, tgt_indices, own, need)
    keep = _droppable(uav, vp, when, order, indptr, indices, seen, own, need, float(by),
                      shared, at, tgt_indptr, tgt_indices)
    return np.split(keep, np.cumsum([len(r) for r in routes])[:-1])


@njit(cache=True)
def _droppable(uav, vp, when, order, indptr, indices, seen, own, required, by, shared, at,
               tgt_indptr, tgt_indices):
    """Keep flag per visit (see `drop_redundant`): ``mult[u, t]`` counts u's
    sightings of t by ``by`` (``seen``: before planning), ``count[t]`` the
    distinct UAVs with one; a ``shared`` target is counted by `places.count_with`
    on ``at`` (first visit times, kept up to date; ``own``: earlier sightings
    from places of their own) instead."""
    n_uavs, n_t = seen.shape
    mult = np.zeros((n_uavs, n_t), np.int16)  # a UAV sees a target from few viewpoints
    for u in range(n_uavs):
        for t in range(n_t):
            if seen[u, t]:
                mult[u, t] = 1
    for i in range(len(vp)):
        if when[i] <= by:
            for j in range(indptr[vp[i]], indptr[vp[i] + 1]):
                mult[uav[i], indices[j]] += 1
    count = np.zeros(n_t, np.int32)
    for u in range(n_uavs):
        for t in range(n_t):
            if mult[u, t] > 0:
                count[t] += 1
    keep = np.ones(len(vp), np.bool_)
    for i in order:
        if when[i] > by:
            continue
        u, e = uav[i], vp[i]
        ok = True
        for j in range(indptr[e], indptr[e + 1]):
            t = indices[j]
            if not shared[t] and mult[u, t] == 1 and count[t] <= required[t]:
                ok = False
                break
        if ok and at[u, e] == when[i]:      # its first visit there: the place may go
            at[u, e] = np.inf
            for j in range(indptr[e], indptr[e + 1]):
                t = indices[j]
                if shared[t] and count_with(t, at, tgt_indptr, tgt_indices, own, -1, -1,
                                            required[t]) < required[t]:
                    ok = False
                    break
            if not ok:
                at[u, e] = when[i]
        if ok:
            keep[i] = False
            for j in range(indptr[e], indptr[e + 1]):
                t = indices[j]
                mult[u, t] -= 1
                if mult[u, t] == 0:
                    count[t] -= 1
    return keep


def reach_bound(problem) -> float:
    """A lower bound on the coverage time of the whole area: the reach bound
    (`coverage.bounds.radius.reach_bound_of`) with ``launch_out`` as the earliest
    arrivals (exact hidden times: no detour
    through other viewpoints is shorter); 0 without launch points. The parts' own
    bounds are not bounds of the whole area."""
    if problem.launch_out is None:
        return 0.0
    rows, of = np.unique(np.asarray(problem.launch_out), axis=0, return_inverse=True)
    seen = problem.seen_before().astype(np.uint8)   # as `coverage.prepare` types them
    indices = np.asarray(problem.vis_indices)
    need = np.minimum(problem.needs(), achievable(problem))  # as `coverage.prepare` caps it
    return float(reach_bound_of(rows, of.ravel(), np.asarray(problem.vis_indptr, np.int64),
                                indices, seen, need.astype(np.int32)))
