"""The time of a route: its visits flown in sorties by the greedy split.

A route is an array of viewpoint ids in visiting order. Its time runs from the
start (``battery.out[e]``: the transit from the start to e) or, without launch
points, from the first viewpoint (the paper's setting), to the last snapshot.
Travel may be asymmetric, so every time is taken in flight direction.

**Sorties.** A route is flown in sorties by the greedy split: the UAV flies on
while the next viewpoint and the way home from it still fit its battery
(`battery.Battery`), and otherwise goes home, takes the turnaround and a new
battery, and flies out to it from the base it landed at (`walk`). With an
unlimited endurance (inf) that is one flight, and every time is what it was
without sorties.
"""

import numpy as np
from numba import njit

from .battery import leaving_after, limited


@njit(cache=True)
def walk(route, travel, battery, has_launch, arrive, sortie, flown) -> int:
    """Fly ``route`` by the greedy split: ``arrive[i]`` the time of visit i since the
    start (turnarounds included), ``sortie[i]`` its sortie (0: the flight under
    way at the start; a route whose first viewpoint does not fit what is left
    of that battery starts with sortie 1), ``flown[i]`` the flight time of its
    sortie at the visit. Returns the number of sorties."""
    m = len(route)
    if m == 0:
        return 0
    t, s, j = 0.0, battery.used, 0
    for i in range(m):
        e = route[i]
        if i == 0:
            out = battery.out[e] if has_launch else 0.0
            home = battery.start_back
        else:
            out = travel[route[i - 1], e]
            home = battery.back[route[i - 1]]
        if s + out + battery.back[e] > battery.endurance:   # home, a new battery, out again
            s = leaving_after(battery, route[i - 1] if i > 0 else -1)[e]
            t += home + battery.turnaround + s
            j += 1
        else:
            t += out
            s += out
        arrive[i], sortie[i], flown[i] = t, j, s
    return j + 1


@njit(cache=True)
def walked(route, travel, battery, has_launch):
    """`walk`'s (arrive, sortie, flown) as new arrays."""
    m = len(route)
    arrive, sortie, flown = np.empty(m), np.empty(m, np.int64), np.empty(m)
    walk(route, travel, battery, has_launch, arrive, sortie, flown)
    return arrive, sortie, flown


@njit(cache=True)
def route_time(route, travel, battery, has_launch):
    """Time of the route's last snapshot (0 for an empty route)."""
    if len(route) == 0:
        return 0.0
    if not limited(battery):
        t = battery.out[route[0]] if has_launch else 0.0
        for i in range(len(route) - 1):
            t += travel[route[i], route[i + 1]]
        return t
    return walked(route, travel, battery, has_launch)[0][-1]


@njit(cache=True)
def arrival_times(route, travel, battery, has_launch):
    """Time of each snapshot along the route."""
    if limited(battery):
        return walked(route, travel, battery, has_launch)[0]
    out = np.empty(len(route))
    t = 0.0
    for i in range(len(route)):
        if i == 0:
            t = battery.out[route[0]] if has_launch else 0.0
        else:
            t += travel[route[i - 1], route[i]]
        out[i] = t
    return out


@njit(cache=True)
def sortie_durations(route, sortie, flown, battery) -> np.ndarray:
    """Flight time of each sortie of a walked route, the way home included (a
    sortie without a visit, the start's flight home, is left 0)."""
    m = len(route)
    out = np.zeros(sortie[m - 1] + 1 if m else 0)
    for i in range(m):
        if i == m - 1 or sortie[i + 1] != sortie[i]:
            out[sortie[i]] = flown[i] + battery.back[route[i]]
    return out


@njit(cache=True)
def nearest_other(travel, axis=1):
    """Per viewpoint, the least time to (axis=1) or from (axis=0) another one
    (the matrix is too large to copy with its diagonal masked)."""
    n = travel.shape[0]
    out = np.full(n, np.inf)
    for a in range(n):
        for b in range(n):
            if a != b:
                t = travel[a, b]
                i = a if axis == 1 else b
                if t < out[i]:
                    out[i] = t
    return out
