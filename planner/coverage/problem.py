"""The abstract coverage problem, its parameters and the resulting allocation.

Everything in :mod:`planner.coverage` works on this combinatorial form: which
targets each viewpoint sees (CSR), hidden travel times between viewpoints, and
optionally per-UAV launch points.  The terrain, visibility and travel stages
build a :class:`CoverageProblem`; the coverage methods turn it into an
:class:`Allocation` (one route of viewpoint ids per UAV).
"""

from dataclasses import dataclass, field
from functools import cached_property
from typing import Optional

import numpy as np
from numba import njit

from .insertion import BASE_ROWS

#: `CoverageProblem.owner` values besides a UAV: nobody photographed there; closed to all
FREE, CLOSED = -1, -2


def required_uavs(k: int, n_uavs: int) -> int:
    """How many distinct UAVs must see each target: k + 1, or every UAV when fewer
    are left (after losses: the paper's rule, everywhere it is needed)."""
    return int(min(k + 1, max(n_uavs, 1)))

@dataclass
class CoverageProblem:
    """Viewpoints, targets, travel times and the fault-tolerance requirement.

    The re-planning state is what the survivors photographed so far, at time
    zero: ``visited[r, e]`` is True when UAV r photographed from viewpoint e
    (its sightings of e's targets are at place e, where another UAV's sighting
    shares their fate: `places`), ``seen[r, t]`` when r photographed target t
    from a place that is no viewpoint (a place of its own). ``required[t]`` is
    how many distinct UAVs at distinct places must see t in total (including
    those sightings); it defaults to k+1.

    The methods fly each viewpoint with one UAV (a UAV's sightings then come
    from places of its own: the k+1 sightings of a target are independent
    fates, never two vehicles on one path); ``owner[e]`` is the UAV whose
    viewpoint e already is (re-planning: the first to photograph there; by
    default from ``visited``; `FREE` or None: nobody), left to it by those
    methods; a second UAV may still fly it where only that gives a target its
    sightings (`places.share`, ALNS), counted by the matching. `CLOSED`: closed
    to every UAV of this problem (a UAV outside it, e.g. of another part of a
    large area).
    """

    vis_indptr: np.ndarray
    vis_indices: np.ndarray
    n_targets: int
    travel: np.ndarray
    launch_out: Optional[np.ndarray]
    launch_back: Optional[np.ndarray]
    n_uavs: int
    k: int = 0
    visibility: str = "soft"
    required: Optional[np.ndarray] = None
    seen: Optional[np.ndarray] = None
    owner: Optional[np.ndarray] = None
    visited: Optional[np.ndarray] = None
    # sorties (`insertion.walk`; launch points needed): the flight time of one
    # battery, the time on the ground between two sorties, per UAV the times out of
    # its base for a later sortie (default ``launch_out``: it starts at its base),
    # what its battery has flown at the start, and the time from its start home
    endurance_s: float = np.inf
    turnaround_s: float = 0.0
    reach_s: Optional[float] = None  # longest round trip to one viewpoint (default: endurance_s)
    base_out: Optional[np.ndarray] = None
    used_s: Optional[np.ndarray] = None
    start_back: Optional[np.ndarray] = None
    # the fleet's bases a sortie may land at (None: each UAV lands at its own, at
    # ``launch_back``): the times out of each [n_bases, n_vp] (the climb included)
    # and back to each (the landing included); a sortie lands at the base nearest
    # its last viewpoint, and the next takes off from there (`landing_bases`)
    bases_out: Optional[np.ndarray] = None
    bases_back: Optional[np.ndarray] = None

    @property
    def n_viewpoints(self) -> int:
        return len(self.vis_indptr) - 1

    @property
    def has_launch(self) -> bool:
        return self.launch_out is not None

    def seen_before(self) -> np.ndarray:
        """bool [n_uavs, n_targets]: what each UAV photographed before planning, from
        any place (``seen`` and the targets of the viewpoints it ``visited``)."""
        out = self.own_matrix().copy()
        if self.visited is not None:
            indptr, indices = np.asarray(self.vis_indptr), np.asarray(self.vis_indices)
            for r, e in zip(*np.nonzero(self.visited)):
                out[r, indices[indptr[e]:indptr[e + 1]]] = True
        return out

    def own_matrix(self) -> np.ndarray:
        """bool [n_uavs, n_targets]: ``seen`` (sightings at places of their own), all
        False when None."""
        if self.seen is None:
            return np.zeros((self.n_uavs, self.n_targets), bool)
        return np.asarray(self.seen, bool)

    def visited_matrix(self) -> np.ndarray:
        """bool [n_uavs, n_viewpoints]: ``visited``, all False when None."""
        if self.visited is None:
            return np.zeros((self.n_uavs, self.n_viewpoints), bool)
        return np.asarray(self.visited, bool)

    def needs(self) -> np.ndarray:
        """int32 per target: how many distinct UAVs must see it, ``required`` or
        k + 1 (`required_uavs`); a new array."""
        if self.required is None:
            return np.full(self.n_targets, required_uavs(self.k, self.n_uavs), np.int32)
        return np.array(self.required, dtype=np.int32)


@dataclass
class CoverageParams:
    """Planning parameters.

    ``step_time_cap`` is th_ra in seconds; None picks ``step_cap_factor`` times
    the median nearest-neighbour travel time between viewpoints (chosen by
    benchmarks/bench_coverage.py), ``math.inf`` disables the cap.
    ``routing_solutions`` bounds each OR-Tools search (deterministic);
    ``routing_time_s`` is a safety-net time limit (None: scale with size).
    RT+LS runs ``ls_starts`` RT starts (th_ra factor x1, x0.5, x2), each
    followed by ``ls_rounds`` rounds of local search, and keeps the best.
    ``time_budget_s`` is the ALNS budget (`alns`; None: scaled to the problem);
    ``budget_fraction`` caps it at that fraction of the start plan's coverage
    time (re-planning in flight).
    """

    alpha: float = 0.55
    beta: float = 0.3
    step_time_cap: Optional[float] = None
    step_cap_factor: float = 4.0
    seed: int = 0
    threshold_adaptation: bool = True
    routing_time_s: Optional[float] = None
    routing_solutions: int = 20
    ls_rounds: int = 20
    ls_starts: int = 3
    time_budget_s: Optional[float] = None
    budget_fraction: Optional[float] = None


@dataclass
class Allocation:
    """Routes and their times.

    ``times[r]`` is UAV r's coverage time (arrival at its last snapshot,
    including transit from launch); ``return_times[r]`` adds the hidden return
    to launch (equal to ``times`` without launch points).  ``coverage_time`` is
    the moment the last target is first seen by as many distinct UAVs as it
    requires, ``mission_time`` the latest return.
    """

    method: str
    routes: list
    times: np.ndarray
    return_times: np.ndarray
    coverage_time: float
    mission_time: float
    sum_time: float
    n_snapshots: int
    covered: bool
    uncoverable: int
    planning_s: float = 0.0
    # greedy insertions (phase, uav, viewpoint, uav time after it); phase 0 = Δt <= 0 first
    steps: list = field(default_factory=list)

    def summary(self) -> dict:
        return {
            "method": self.method,
            "coverage_time_s": self.coverage_time,
            "mission_time_s": self.mission_time,
            "sum_time_s": self.sum_time,
            "snapshots": self.n_snapshots,
            "covered": self.covered,
            "planning_s": self.planning_s,
        }


@dataclass
class Prepared:
    """Validated arrays shared by every method (built once per solve)."""

    problem: CoverageProblem
    vis_indptr: np.ndarray  # int64
    vis_indices: np.ndarray  # int32 or int64
    tgt_indptr: np.ndarray  # CSC transpose: target -> viewpoints that see it
    tgt_indices: np.ndarray  # int32
    travel: np.ndarray  # float64 [n_vp, n_vp]
    travel_t: np.ndarray  # its transpose, C-contiguous (column reads in the kernels)
    launch_out: np.ndarray  # float64 [n_uavs, n_vp] (zeros if no launch)
    launch_back: np.ndarray
    has_launch: bool
    frames: np.ndarray  # float64 [n_uavs, BASE_ROWS + n_bases, n_vp] (`insertion`)
    sorties: np.ndarray  # float64 [n_uavs, 4]: `insertion.walk`'s sortie model per UAV
    seen0: np.ndarray  # uint8 [n_uavs, n_targets]: seen before, from any place
    required: np.ndarray  # int32 [n_targets], reduced to what is achievable
    uncoverable: int  # targets whose requirement cannot be met at all
    soft: bool
    soft_exp: float
    owner0: np.ndarray  # int64 [n_viewpoints]: UAV that photographed there before, FREE, CLOSED
    own0: np.ndarray  # uint8 [n_uavs, n_targets]: seen before from places of their own
    visited0: np.ndarray  # bool [n_uavs, n_viewpoints]: photographed from before

    @cached_property
    def classes(self) -> tuple:
        """`classes.target_classes` of this problem, built once: the search and the
        bounds of a plan share it."""
        from .classes import target_classes

        return target_classes(self)


def prepare(problem: CoverageProblem) -> Prepared:
    """Validate the problem and build the arrays the kernels need."""
    n, k = int(problem.n_uavs), int(problem.k)
    if n < 1:
        raise ValueError("n_uavs must be at least 1")
    if k < 0:
        raise ValueError("k must be >= 0")
    if k >= n:
        raise ValueError(
            f"fault tolerance k={k} needs at least k+1={k + 1} UAVs, but only {n} given"
        )
    if problem.visibility not in ("soft", "hard"):
        raise ValueError(f"visibility must be 'soft' or 'hard', not {problem.visibility!r}")
    indptr = np.asarray(problem.vis_indptr, dtype=np.int64)
    indices = np.asarray(problem.vis_indices)  # int32 as the visibility stage keeps them
    if indices.dtype not in (np.int32, np.int64):
        indices = indices.astype(np.int64)
    n_vp, n_t = len(indptr) - 1, int(problem.n_targets)
    # C order whatever the caller's layout: the kernels are compiled for one layout
    # (a transposed matrix would compile every kernel again on first use)
    travel = np.ascontiguousarray(problem.travel, dtype=np.float64)
    if travel.shape != (n_vp, n_vp):
        raise ValueError(f"travel must be [{n_vp}, {n_vp}], got {travel.shape}")
    if len(indices) and (indices.min() < 0 or indices.max() >= n_t):
        raise ValueError("vis_indices hold target ids outside 0..n_targets-1")
    has_launch = problem.launch_out is not None
    if has_launch:
        lo = np.asarray(problem.launch_out, dtype=np.float64)
        lb = (np.asarray(problem.launch_back, dtype=np.float64)
              if problem.launch_back is not None else np.zeros_like(lo))
        if lo.shape != (n, n_vp) or lb.shape != (n, n_vp):
            raise ValueError(f"launch_out/launch_back must be [{n}, {n_vp}]")
    else:
        lo = np.zeros((n, n_vp))
        lb = np.zeros((n, n_vp))
    own0 = np.zeros((n, n_t), dtype=np.uint8)
    if problem.seen is not None:
        s = np.asarray(problem.seen, dtype=bool)
        if s.shape != (n, n_t):
            raise ValueError(f"seen must be [{n}, {n_t}]")
        own0[s] = 1
    visited0 = problem.visited_matrix()
    if visited0.shape != (n, n_vp):
        raise ValueError(f"visited must be [{n}, {n_vp}]")
    seen0 = problem.seen_before().astype(np.uint8)
    req = problem.needs()
    if req.shape != (n_t,):
        raise ValueError(f"required must have one entry per target ({n_t})")
    owner0 = np.full(n_vp, FREE, np.int64) if problem.owner is None else \
        np.asarray(problem.owner, np.int64)
    if owner0.shape != (n_vp,) or owner0.max(initial=FREE) >= n or owner0.min(initial=0) < CLOSED:
        raise ValueError(f"owner must hold one UAV, FREE or CLOSED per viewpoint ({n_vp})")
    first = np.where(visited0.any(axis=0), visited0.argmax(axis=0), FREE)
    owner0 = np.where(owner0 == FREE, first, owner0)     # the first visitor's, by default
    frames, sorties, beyond = _sortie_model(problem, lo, lb)
    owner0 = np.where(beyond.all(axis=0) & (owner0 == FREE), CLOSED, owner0)
    tgt_indptr, tgt_indices = csc_transpose(indptr, indices, n_t)
    # A target seen from fewer places than it needs sightings, or needing more UAVs
    # than exist, is capped at what is achievable and reported as uncoverable.
    achievable = _achievable(tgt_indptr, tgt_indices, owner0, own0.astype(np.bool_), n,
                             ~beyond)
    uncoverable = int(np.count_nonzero(req > achievable))
    req = np.minimum(req, achievable).astype(np.int32)
    return Prepared(problem, indptr, indices, tgt_indptr, tgt_indices, travel,
                    np.ascontiguousarray(travel.T), lo, lb,
                    has_launch, frames, sorties, seen0, req, uncoverable,
                    problem.visibility == "soft", float(n) / k if k > 0 else 1.0, owner0,
                    own0, visited0)


def _sortie_model(problem: CoverageProblem, lo, lb) -> tuple:
    """(frames, sorties) of `Prepared` (see `insertion`): per UAV its times out of
    its start and of its own base, back to the base its sortie lands at and which
    that is, and out of every base; viewpoints no base reaches and leaves on one
    battery closed (inf out of the start and the bases), and [n_uavs, n_vp] where
    none is: beyond its battery."""
    n = int(problem.n_uavs)
    endurance = float(problem.endurance_s)
    if endurance < np.inf and problem.launch_out is None:
        raise ValueError("an endurance needs launch points (bases to come back to)")
    base = lo if problem.base_out is None else np.asarray(problem.base_out, np.float64)
    if base.shape != lo.shape:
        raise ValueError(f"base_out must be {lo.shape}")
    back, at, out = _landings(problem, base, lb)
    frames = np.empty((n, BASE_ROWS + out.shape[1], lo.shape[1]))
    frames[:, 0], frames[:, 1], frames[:, 2], frames[:, 3] = lo, base, back, at
    frames[:, BASE_ROWS:] = out
    sorties = np.zeros((n, 4))
    sorties[:, 0] = endurance
    sorties[:, 1] = problem.turnaround_s
    if problem.used_s is not None:
        sorties[:, 2] = problem.used_s
    if problem.start_back is not None:
        sorties[:, 3] = problem.start_back
    reach = endurance if problem.reach_s is None else problem.reach_s
    far = frames[:, BASE_ROWS:] + frames[:, 2:3] > reach      # per UAV, base, viewpoint
    own = frames[:, 1] + frames[:, 2] > reach
    if problem.bases_out is not None:       # a base it never comes to is no start
        far |= ~_bases_reached(frames[:, 3].astype(np.int64), ~own, ~far)[:, :, None]
    frames[:, BASE_ROWS:][far] = np.inf
    frames[:, :2][np.broadcast_to(own[:, None], frames[:, :2].shape)] = np.inf
    return frames, sorties, far.all(axis=1)


def _bases_reached(at, first, near) -> np.ndarray:
    """bool [n_uavs, n_bases]: the bases each UAV can land at, and so take off from:
    those where a sortie out of its own base (``first`` [n_uavs, n_vp]: the
    viewpoints it reaches and leaves on one battery) lands, and where one out of
    those lands (``near`` [n_uavs, n_bases, n_vp] the same out of each base;
    ``at``: the base a sortie ending at each viewpoint lands at)."""
    n, n_bases = near.shape[:2]
    out = np.zeros((n, n_bases), bool)
    for r in range(n):
        todo = set(at[r][first[r]].tolist())
        while todo:
            b = todo.pop()
            if not out[r, b]:
                out[r, b] = True
                todo |= set(at[r][near[r, b]].tolist())
    return out


def _landings(problem, base, lb) -> tuple:
    """(back [n_uavs, n_vp]: the way home from each viewpoint, landing included;
    at: the base it lands at; out [n_uavs, n_bases, n_vp]: out of each base)."""
    if problem.bases_out is None:           # its own base only
        return lb, np.zeros(lb.shape), base[:, None, :]
    bo = np.asarray(problem.bases_out, np.float64)
    bb = np.asarray(problem.bases_back, np.float64)
    if bo.shape != bb.shape or bo.shape[1:] != base.shape[1:]:
        raise ValueError(f"bases_out and bases_back must be [n_bases, {base.shape[1]}]")
    at = landing_bases(problem)
    back = np.take_along_axis(bb, at[None], axis=0)[0]
    n = base.shape[0]
    return np.broadcast_to(back, base.shape), np.broadcast_to(at, base.shape), \
        np.broadcast_to(bo, (n,) + bo.shape)


def landing_bases(problem: CoverageProblem) -> np.ndarray:
    """int per viewpoint: the base (of ``bases_back``) a sortie whose last viewpoint
    it is lands at, the nearest on its hidden way home (all 0 without bases)."""
    if problem.bases_back is None:
        return np.zeros(problem.n_viewpoints, np.int64)
    return np.argmin(np.asarray(problem.bases_back, np.float64), axis=0)


def beyond_battery(problem: CoverageProblem) -> np.ndarray:
    """Ids of the viewpoints no UAV can fly to from a base and back on one
    battery: no plan visits them (a plan reports them)."""
    return np.flatnonzero(_beyond(problem).all(axis=0))


def _beyond(problem) -> np.ndarray:
    """bool [n_uavs, n_vp]: the viewpoints beyond each UAV's battery (`_sortie_model`)."""
    lo = np.asarray(problem.launch_out, np.float64) if problem.launch_out is not None \
        else np.zeros((problem.n_uavs, problem.n_viewpoints))
    lb = np.asarray(problem.launch_back, np.float64) if problem.launch_back is not None \
        else np.zeros_like(lo)
    return _sortie_model(problem, lo, lb)[2]


def achievable(problem: CoverageProblem) -> np.ndarray:
    """int32 per target: the most sightings from distinct UAVs at distinct places
    it can get (what `prepare` caps the requirement at), without the travel
    times `prepare` checks."""
    n, n_t = int(problem.n_uavs), int(problem.n_targets)
    indptr, indices = np.asarray(problem.vis_indptr, np.int64), np.asarray(problem.vis_indices)
    tgt_indptr, tgt_indices = csc_transpose(indptr, indices, n_t)
    own = problem.own_matrix()
    owner = (np.full(len(indptr) - 1, FREE, np.int64) if problem.owner is None
             else np.array(problem.owner, np.int64))
    able = np.ones((n, len(indptr) - 1), np.bool_)
    if problem.endurance_s < np.inf:
        able = ~_beyond(problem)
        far = np.flatnonzero(~able.any(axis=0))
        owner[far[owner[far] == FREE]] = CLOSED
    return _achievable(tgt_indptr, tgt_indices, owner, own, n, able)


@njit(cache=True)
def _achievable(tgt_indptr, tgt_indices, owner0, own0, n, able):
    """Per target, the most sightings from distinct UAVs at distinct places it can
    get: one per UAV that saw it from a place of its own (``own0``), and the
    largest matching of the other UAVs to the viewpoints seeing it that are not
    `CLOSED` and that each may fly (``able`` [n, n_vp]: within its battery from
    a base it comes to; a second UAV may fly one another photographed from before:
    `places.share`). Where every UAV may fly every one, that is one per place, at
    most one per UAV (n)."""
    n_t = len(tgt_indptr) - 1
    out = np.empty(n_t, np.int32)
    match = np.empty(n, np.int64)
    everyone = np.ones(able.shape[1], np.bool_)     # every UAV may fly the viewpoint
    for r in range(n):
        everyone &= able[r]
    for t in range(n_t):
        places, uniform = 0, True
        for r in range(n):
            places += own0[r, t]
        for i in range(tgt_indptr[t], tgt_indptr[t + 1]):
            e = tgt_indices[i]
            if owner0[e] != CLOSED:
                places += 1
                uniform &= everyone[e]
        if uniform or places == 0:
            out[t] = min(n, places)
            continue
        match[:] = -1           # viewpoint each UAV sights t from
        got = 0
        for r in range(n):
            if own0[r, t] or _match(r, t, tgt_indptr, tgt_indices, owner0, able, match,
                                    np.zeros(n, np.bool_)):
                got += 1
        out[t] = got
    return out


@njit(cache=True)
def _match(r, t, tgt_indptr, tgt_indices, owner0, able, match, tried):
    """An augmenting path from UAV r in `_achievable`'s matching of target t."""
    for i in range(tgt_indptr[t], tgt_indptr[t + 1]):
        e = tgt_indices[i]
        if owner0[e] == CLOSED or not able[r, e]:
            continue
        holder = -1
        for u in range(len(match)):
            if match[u] == e:
                holder = u
        if holder == r:
            continue
        if holder >= 0:
            if tried[holder]:
                continue
            tried[holder] = True
            if not _match(holder, t, tgt_indptr, tgt_indices, owner0, able, match, tried):
                continue
        match[r] = e
        return True
    return False


def owners(prep: "Prepared", routes) -> np.ndarray:
    """int64 per viewpoint: the UAV whose route visits it (or that photographed
    there before, `Prepared.owner0`), -1 for none. ValueError when two UAVs
    share one (a defect of the method that made ``routes``)."""
    owner = prep.owner0.copy()
    for r, route in enumerate(routes):
        for e in route:
            if owner[e] != FREE and owner[e] != r:
                raise ValueError(f"viewpoint {int(e)} is visited by UAV {int(owner[e]) + 1} "
                                 f"and UAV {r + 1}: no two UAVs may photograph from one "
                                 "place (a coverage method defect)")
            owner[e] = r
    return owner


def csc_transpose(indptr: np.ndarray, indices: np.ndarray, n_targets: int):
    """Target -> viewpoint lists (the CSC form of the visibility matrix), each list
    ascending, viewpoint ids as int32: a counting sort, linear in the nonzeros (an
    argsort of them took most of a 2048² plan's allocation set-up)."""
    return _counting_transpose(np.asarray(indptr, np.int64), np.asarray(indices),
                               int(n_targets))


@njit(cache=True)
def _counting_transpose(indptr, indices, n_targets):
    t_indptr = np.zeros(n_targets + 1, np.int64)
    for j in range(len(indices)):
        t_indptr[indices[j] + 1] += 1
    for t in range(n_targets):
        t_indptr[t + 1] += t_indptr[t]
    fill = t_indptr[:-1].copy()
    rows = np.empty(len(indices), np.int32)  # viewpoint ids: half the memory of int64
    for e in range(len(indptr) - 1):  # rows in order: each list comes out ascending
        for j in range(indptr[e], indptr[e + 1]):
            t = indices[j]
            rows[fill[t]] = e
            fill[t] += 1
    return t_indptr, rows
