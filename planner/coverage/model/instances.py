"""Seeded synthetic coverage problems for tests and benchmarks.

Viewpoints and targets are points in a square of side ``size_m``; a viewpoint
sees a target within ``sensor_m`` with a probability falling off with
distance (terrain occlusion stand-in), and every target is seen by at least
its nearest viewpoint.  Travel between viewpoints flies at ``speed`` with a
random per-viewpoint altitude: climbing costs ``1/climb`` s/m, descending
``1/descent`` s/m, so times are asymmetric; each direct leg gets a random
detour factor (hidden paths bend round terrain) and the matrix is closed
under shortest paths, as a real travel-time graph is.

Families: ``uniform`` (viewpoints spread evenly), ``clustered`` (viewpoints
gathered in a few valleys), ``corridor`` (a 4:1 strip).
"""

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path
from scipy.spatial import cKDTree

from .problem import CoverageProblem

FAMILIES = ("uniform", "clustered", "corridor")


def random_problem(n_viewpoints=150, n_targets=1500, n_uavs=4, k=0, visibility="soft",
                   family="uniform", seed=0, launch=False, size_m=3000.0, sensor_m=500.0,
                   speed=15.0, climb=3.0, descent=5.0, see_prob=0.8) -> CoverageProblem:
    rng = np.random.default_rng(seed)
    extent = np.array([4 * size_m, size_m / 2]) if family == "corridor" else np.array([size_m] * 2)
    vp = _viewpoint_xy(rng, n_viewpoints, family, extent)
    tg = rng.uniform(0, 1, (n_targets, 2)) * extent
    alt = rng.uniform(0, 150, n_viewpoints)
    indptr, indices = _visibility(rng, vp, tg, sensor_m, see_prob)
    travel = _travel(rng, vp, alt, speed, climb, descent)
    lo = lb = None
    if launch:
        pads = np.column_stack([rng.uniform(0, extent[0], n_uavs), np.zeros(n_uavs)])
        d = np.linalg.norm(pads[:, None, :] - vp[None, :, :], axis=2)
        lo = d / speed + alt[None, :] / climb
        lb = d / speed + alt[None, :] / descent
    return CoverageProblem(indptr, indices, n_targets, travel, lo, lb, n_uavs, k, visibility)


def _viewpoint_xy(rng, n, family, extent):
    if family != "clustered":
        return rng.uniform(0, 1, (n, 2)) * extent
    centres = rng.uniform(0.15, 0.85, (5, 2)) * extent
    pick = rng.integers(0, len(centres), n)
    return np.clip(centres[pick] + rng.normal(0, 0.12 * extent[0], (n, 2)), 0, extent)


def _visibility(rng, vp, tg, sensor_m, see_prob):
    near = cKDTree(vp).sparse_distance_matrix(cKDTree(tg), sensor_m, output_type="ndarray")
    keep = rng.uniform(size=len(near)) < see_prob * (1 - near["v"] / sensor_m)
    nearest = cKDTree(vp).query(tg)[1]
    e = np.concatenate([near["i"][keep], nearest]).astype(np.int64)
    t = np.concatenate([near["j"][keep], np.arange(len(tg))]).astype(np.int64)
    key = np.unique(e * len(tg) + t)  # sorted by viewpoint, then target; no duplicates
    e, t = key // len(tg), key % len(tg)
    indptr = np.zeros(len(vp) + 1, dtype=np.int64)
    np.cumsum(np.bincount(e, minlength=len(vp)), out=indptr[1:])
    return indptr, t.astype(np.int32)


def _travel(rng, vp, alt, speed, climb, descent):
    d = np.linalg.norm(vp[:, None, :] - vp[None, :, :], axis=2)
    dh = alt[None, :] - alt[:, None]
    direct = (d * rng.uniform(1.0, 1.5, d.shape) / speed
              + np.maximum(dh, 0) / climb + np.maximum(-dh, 0) / descent)
    # Only legs to the nearest viewpoints are flown directly; longer ones go
    # via other viewpoints.
    n = len(vp)
    nbr = cKDTree(vp).query(vp, k=min(n, 13))[1][:, 1:]
    rows = np.repeat(np.arange(n), nbr.shape[1])
    cols = nbr.ravel()
    graph = csr_matrix((np.concatenate([direct[rows, cols], direct[cols, rows]]),
                        (np.concatenate([rows, cols]), np.concatenate([cols, rows]))),
                       shape=(n, n))
    return shortest_path(graph, method="D", directed=True)


def optimality_case(seed, min_viewpoints=8, max_viewpoints=16) -> tuple:
    """(name, problem): one of the small problems whose optimum is proven
    (`exact.optimum`) to judge the methods by. The seed draws the size (viewpoints,
    10 to 25 targets per viewpoint), the fleet (2-4 UAVs), k (0 to n-1), launch
    points or none, and the family (in turn)."""
    rng = np.random.default_rng([seed, 34])
    n_vp = int(rng.integers(min_viewpoints, max_viewpoints + 1))
    n_uavs = int(rng.integers(2, 5))
    k = int(rng.integers(0, n_uavs))
    launch = bool(rng.integers(0, 2))
    family = FAMILIES[seed % len(FAMILIES)]
    n_targets = int(rng.integers(10, 26)) * n_vp
    name = f"{family}-{n_vp}vp-{n_uavs}uav-k{k}{'-launch' if launch else ''}-s{seed}"
    return name, random_problem(n_vp, n_targets, n_uavs, k, family=family, seed=seed,
                                launch=launch)
