"""The prepared problem: a `CoverageProblem` validated and laid out for the kernels.

`prepare` checks the problem, builds the arrays every method and bound reads
(the visibility lists both ways, the travel matrix and its transpose, each
UAV's `battery.Battery`, what was seen before), and caps each target's
requirement at what it can achieve (`achievable`: the most sightings from
distinct UAVs at distinct places it can get).
"""

from dataclasses import dataclass, field
from typing import Optional

import numpy as np
from numba import njit

from .battery import Batteries, Battery, beyond, fleet_batteries
from .problem import CLOSED, FREE, CoverageProblem


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
    batteries: Batteries  # each UAV's battery and ways out and back (`battery`)
    seen0: np.ndarray  # uint8 [n_uavs, n_targets]: seen before, from any place
    required: np.ndarray  # int32 [n_targets], reduced to what is achievable
    uncoverable: int  # targets whose requirement cannot be met at all
    soft: bool
    soft_exp: float
    owner0: np.ndarray  # int64 [n_viewpoints]: UAV that photographed there before, FREE, CLOSED
    own0: np.ndarray  # uint8 [n_uavs, n_targets]: seen before from places of their own
    visited0: np.ndarray  # bool [n_uavs, n_viewpoints]: photographed from before
    #: `classes.target_classes` of this problem once built: the search and the bounds of
    #: a plan share it (not a field of `dataclasses.replace`: a problem made from this
    #: one builds its own)
    classes_built: Optional[tuple] = field(default=None, init=False, repr=False,
                                           compare=False)

    def battery(self, r) -> Battery:
        """UAV r's `battery.Battery` (views into ``batteries``)."""
        b = self.batteries
        return Battery(b.out[r], b.base_out[r], b.back[r], b.lands_at[r], b.bases_out[r],
                       float(b.endurance[r]), float(b.turnaround[r]), float(b.used[r]),
                       float(b.start_back[r]))


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
        lo = np.ascontiguousarray(problem.launch_out, dtype=np.float64)   # as travel
        lb = (np.ascontiguousarray(problem.launch_back, dtype=np.float64)
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
    batteries, far = fleet_batteries(problem, lo, lb)
    owner0 = np.where(far.all(axis=0) & (owner0 == FREE), CLOSED, owner0)
    tgt_indptr, tgt_indices = csc_transpose(indptr, indices, n_t)
    # A target seen from fewer places than it needs sightings, or needing more UAVs
    # than exist, is capped at what is achievable and reported as uncoverable.
    achievable = _achievable(tgt_indptr, tgt_indices, owner0, own0.astype(np.bool_), n,
                             ~far)
    uncoverable = int(np.count_nonzero(req > achievable))
    req = np.minimum(req, achievable).astype(np.int32)
    return Prepared(problem, indptr, indices, tgt_indptr, tgt_indices, travel,
                    np.ascontiguousarray(travel.T), lo, lb,
                    has_launch, batteries, seen0, req, uncoverable,
                    problem.visibility == "soft", float(n) / k if k > 0 else 1.0, owner0,
                    own0, visited0)


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
        able = np.ascontiguousarray(~beyond(problem))   # the layout `prepare` gives
        far = np.flatnonzero(~able.any(axis=0))
        owner[far[owner[far] == FREE]] = CLOSED
    return _achievable(tgt_indptr, tgt_indices, owner, own, n, able)


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
