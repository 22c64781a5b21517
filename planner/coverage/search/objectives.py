"""The greedy objectives of RT and RD, and the kernels that pick the best pair.

Each objective is a small scoring function of the gain V (see gains.py), the
UAV's time t_r and the insertion time Δt (or, in phase 1, the growth Δd of the
path through the chosen starts):

* ``spread``       So     = Δd · V^β                       (phase 1)
* ``ptv``          M_PTV  = V^α / (t_r + Δt)^(1-α)          (phase 2 of RT)
* ``ptv2``         M_PTV2 = V^α / Δt^(1-α)                  (phase 3 of RT)
* ``per_distance`` M_RD   = V^α / Δt^(1-α), no t_r, no cap  (RD, see below)

RD is the paper's per-distance baseline: it rates a pair by visibility per
extra distance flown (here the extra hidden time, the same quantity) with the
same α coupling, and has no threshold adaptation; without the t_r term
nothing balances the UAVs' loads.  Only pairs with V > 0 and finite Δt are
candidates; α = 1 ignores time and α = 0 ignores visibility.
"""

import numpy as np
from numba import njit

from .gains import POSITIVE

PTV, PTV2, PER_DISTANCE = 0, 1, 2
_TINY = 1e-9


@njit(cache=True)
def spread(v, dd, beta):
    return dd * v ** beta


@njit(cache=True)
def score(metric, v, t, dt, alpha):
    if metric == PTV:
        return v ** alpha / max(t + dt, _TINY) ** (1.0 - alpha)
    return v ** alpha / max(dt, _TINY) ** (1.0 - alpha)


@njit(cache=True)
def best_pair(gains, cost, times, metric, alpha, cap, exclude, t_limit):
    """Best (viewpoint, UAV) by ``metric`` among pairs with V > 0, Δt <= cap,
    UAV != exclude and t_r + Δt <= t_limit.  Returns (-1, -1) if none."""
    n_vp, n_uavs = gains.shape
    best, be, br = -1.0, -1, -1
    for e in range(n_vp):
        for r in range(n_uavs):
            v = gains[e, r]
            if v <= POSITIVE or r == exclude:
                continue
            dt = cost[r, e]
            if not np.isfinite(dt) or dt > cap or times[r] + dt > t_limit:
                continue
            s = score(metric, v, times[r], dt, alpha)
            if s > best:
                best, be, br = s, e, r
    return be, br


@njit(cache=True)
def best_free_pair(gains, cost):
    """Highest-V pair whose insertion does not lengthen the route (Δt <= 0)."""
    n_vp, n_uavs = gains.shape
    best, be, br = POSITIVE, -1, -1
    for e in range(n_vp):
        for r in range(n_uavs):
            if cost[r, e] <= 0.0 and gains[e, r] > best:
                best, be, br = gains[e, r], e, r
    return be, br


@njit(cache=True)
def best_spread(gains_r, chain, travel, beta):
    """Phase 1: the viewpoint maximising So = Δd · V^β against the chain of starts."""
    n_vp = len(gains_r)
    best, be = -1.0, -1
    for e in range(n_vp):
        v = gains_r[e]
        if v <= POSITIVE:
            continue
        if len(chain) == 0:
            s = v  # nothing chosen yet: highest V first
        else:
            dd = _chain_growth(chain, e, travel)
            if not np.isfinite(dd):
                continue
            s = spread(v, dd, beta)
        if s > best:
            best, be = s, e
    return be


@njit(cache=True)
def _chain_growth(chain, e, travel):
    """Edge-breaking growth of the open path through the chosen starts."""
    m = len(chain)
    best = min(travel[e, chain[0]], travel[chain[m - 1], e])
    for p in range(1, m):
        a, b = chain[p - 1], chain[p]
        best = min(best, travel[a, e] + travel[e, b] - travel[a, b])
    return best
