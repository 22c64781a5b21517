"""Brute-force reference of the fault-tolerance rule, independent of the planner's
matching: a target's sightings count when they come from distinct UAVs at
distinct places (a viewpoint, also for an earlier photograph taken there:
``visited``; an earlier sighting from elsewhere, ``seen``, is a place of its
own), found by trying every subset of its sightings."""

import itertools
import math

import numpy as np


def dense(problem) -> np.ndarray:
    vis = np.zeros((problem.n_viewpoints, problem.n_targets), bool)
    for e in range(problem.n_viewpoints):
        vis[e, problem.vis_indices[problem.vis_indptr[e]:problem.vis_indptr[e + 1]]] = True
    return vis


def sightings(problem, routes, when=None) -> list:
    """target -> [(time, uav, place)], walking the routes (``when[r][i]``: the time of
    visit i of route r; default the travel model)."""
    vis = dense(problem)
    out = [[] for _ in range(problem.n_targets)]
    if problem.seen is not None:
        for r, t in zip(*np.nonzero(problem.seen)):
            out[t].append((0.0, int(r), ("before", int(r))))
    if problem.visited is not None:
        for r, e in zip(*np.nonzero(problem.visited)):
            for t in np.flatnonzero(vis[e]):
                out[t].append((0.0, int(r), int(e)))
    for r, route in enumerate(routes):
        now = 0.0
        for i, e in enumerate(route):
            if when is not None:
                now = float(when[r][i])
            elif i == 0:
                now = problem.launch_out[r, e] if problem.launch_out is not None else 0.0
            else:
                now += problem.travel[route[i - 1], e]
            for t in np.flatnonzero(vis[e]):
                out[t].append((now, r, int(e)))
    return out


def matched(found, cap=math.inf) -> int:
    """The largest set of sightings with distinct UAVs and distinct places (at most
    cap), by trying every subset of the (UAV, place) pairs."""
    pairs = sorted({(u, p) for _, u, p in found}, key=repr)
    cap = min(cap, len({u for u, _ in pairs}), len({p for _, p in pairs}))
    best = 0
    for size in range(1, cap + 1):
        if any(len({u for u, _ in c}) == size == len({p for _, p in c})
               for c in itertools.combinations(pairs, size)):
            best = size
        else:
            break
    return best


def needed_time(found, need) -> float:
    """When the target first has ``need`` counted sightings (inf: never)."""
    if need <= 0:
        return 0.0
    found = sorted(found, key=lambda s: s[0])
    for i in range(len(found)):
        if matched(found[:i + 1], need) >= need:
            return found[i][0]
    return math.inf


def achievable(problem) -> np.ndarray:
    """Per target, the most counted sightings any plan can give it: one per UAV, one
    per place (the viewpoints seeing it, and each earlier sighting's own)."""
    places = dense(problem).sum(axis=0)
    before = (np.zeros(problem.n_targets, int) if problem.seen is None
              else np.asarray(problem.seen, bool).sum(axis=0))
    return np.minimum(problem.n_uavs, places + before)


def requirement(problem) -> np.ndarray:
    """What each target needs of a plan: k + 1 (or ``problem.required``), at most what
    it can get."""
    need = (np.full(problem.n_targets, min(problem.k + 1, problem.n_uavs))
            if problem.required is None else np.asarray(problem.required))
    return np.minimum(need, achievable(problem))


def shortfall(problem, routes) -> int:
    """Targets with fewer sightings from distinct UAVs at distinct places than they
    need (the one rule, or ``problem.required``, at most what they can get)."""
    need = requirement(problem)
    return int(sum(matched(f, q) < q for f, q in zip(sightings(problem, routes), need)))
