"""The optimum of tiny coverage problems by exhaustive enumeration of every plan:
the reference the lower bounds and the exact solver are judged by."""

import itertools
import math

import numpy as np
import places_reference as ref

from planner.coverage.model.instances import random_problem


def tiny(seed, n_vp, n_uavs, k, launch, n_targets=12, sensor_m=450.0):
    return random_problem(n_viewpoints=n_vp, n_targets=n_targets, n_uavs=n_uavs, k=k,
                          seed=seed, launch=launch, size_m=900.0, sensor_m=sensor_m,
                          see_prob=0.9, family=("uniform", "clustered", "corridor")[seed % 3])


def exhaustive_optimum(problem):
    """The least coverage time over every plan: each UAV flies an ordered
    sequence of distinct viewpoints (revisits add nothing), all combinations,
    two UAVs at one viewpoint included; a target is covered once it has its
    requirement of sightings from distinct UAVs at distinct places, tried
    over every assignment of UAVs to places. Earlier sightings count at time
    zero: from a viewpoint (``visited``), and from a place of the UAV's own
    (``seen``: one more place per UAV, only its own)."""
    n_vp, n_t, n = problem.n_viewpoints, problem.n_targets, problem.n_uavs
    vis = np.vstack([ref.dense(problem), problem.own_matrix().astype(bool)])
    seqs = [s for m in range(n_vp + 1) for s in itertools.permutations(range(n_vp), m)]
    need = ref.requirement(problem)
    visits = []  # per UAV: [n_seqs, n_viewpoints] when it first flies each viewpoint
    for r in range(n):
        f = np.full((len(seqs), n_vp), np.inf)
        for i, s in enumerate(seqs):
            now = 0.0
            for j, e in enumerate(s):
                if j == 0:
                    now = problem.launch_out[r, e] if problem.launch_out is not None else 0.0
                else:
                    now += problem.travel[s[j - 1], e]
                f[i, e] = min(f[i, e], now)
        f[:, problem.visited_matrix()[r]] = 0.0
        own = np.full((len(seqs), n), np.inf)
        own[:, r] = 0.0
        visits.append(np.hstack([f, own]))
    best = math.inf
    grids = np.meshgrid(*[np.arange(len(seqs))] * n, indexing="ij")
    combo = np.stack([g.ravel() for g in grids], axis=1)
    for chunk in np.array_split(combo, max(1, len(combo) // 20000)):
        at = np.stack([visits[r][chunk[:, r]] for r in range(n)], axis=1)  # [c, n, vp]
        worst = np.zeros(len(chunk))
        for t in range(n_t):
            if need[t] == 0:
                continue
            places = np.flatnonzero(vis[:, t])
            done = np.full(len(chunk), np.inf)
            for uavs in itertools.permutations(range(n), int(need[t])):
                for spots in itertools.permutations(places, int(need[t])):
                    done = np.minimum(done, at[:, uavs, spots].max(axis=1))
            worst = np.maximum(worst, done)
        best = min(best, float(worst.min()))
    return best


CASES = [  # (seed, viewpoints, UAVs, k, launch)
    (0, 5, 2, 0, False), (1, 5, 2, 1, True), (2, 5, 2, 0, True), (3, 5, 2, 1, False),
    (4, 4, 3, 1, True), (5, 4, 3, 2, True), (6, 4, 3, 0, False), (7, 5, 2, 0, True),
    (8, 4, 3, 1, False), (9, 5, 2, 1, True)]
