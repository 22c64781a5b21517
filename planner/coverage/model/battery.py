"""What a UAV's battery allows, and its ways out of and back to its bases.

A route is flown in sorties: out of a base (the first out of its start), through
viewpoints, back to a base, one battery each (`routes.walk`). What the search
needs of a UAV for that is its `Battery`, a record of arrays and numbers that
the numba kernels read by name:

| field | per | meaning |
|---|---|---|
| ``out`` | viewpoint | time from its start to the viewpoint (the climb included) |
| ``base_out`` | viewpoint | from its own base, for a sortie after the start's way home |
| ``back`` | viewpoint | to the base a sortie ending there lands at (the landing included) |
| ``lands_at`` | viewpoint | which base that is (the nearest of the fleet's, or its own: 0) |
| ``bases_out`` | base, viewpoint | out of each base (a sortie leaves where the one before landed) |
| ``endurance`` | | the flight time one battery allows (inf: unlimited, one flight) |
| ``turnaround`` | | the time on the ground between two sorties |
| ``used`` | | what the battery flying at the start has flown already (a re-plan in flight) |
| ``start_back`` | | the time from the start back to its own base |

`Batteries` is the same record for the whole fleet, each field with a leading
UAV axis; `battery_of` takes one UAV's out of it (in the kernels; `Prepared.battery`
in Python). A viewpoint that no base reaches and leaves on one battery is
closed: inf out of the start and of every base (`fleet_batteries`).
"""

from collections import namedtuple

import numpy as np
from numba import njit

_FIELDS = ("out", "base_out", "back", "lands_at", "bases_out", "endurance", "turnaround",
           "used", "start_back")
#: one UAV's (see the module doc): float64 arrays, ``lands_at`` int64, numbers float
Battery = namedtuple("Battery", _FIELDS)
#: the fleet's: every field of `Battery` with a leading UAV axis
Batteries = namedtuple("Batteries", _FIELDS)


@njit(cache=True)
def battery_of(batteries, r):
    """UAV r's `Battery` (views into the fleet's arrays)."""
    return Battery(batteries.out[r], batteries.base_out[r], batteries.back[r],
                   batteries.lands_at[r], batteries.bases_out[r], batteries.endurance[r],
                   batteries.turnaround[r], batteries.used[r], batteries.start_back[r])


@njit(cache=True)
def limited(battery) -> bool:
    """Whether the battery splits a route into sorties (a finite endurance)."""
    return battery.endurance < np.inf


@njit(cache=True)
def leaving_after(battery, a):
    """The times out of the base that a sortie whose last viewpoint is ``a`` lands
    at (a < 0: the start's way home, to its own base): where the next one leaves."""
    if a < 0 or battery.bases_out.shape[0] == 0:      # no bases listed: its own only
        return battery.base_out
    return battery.bases_out[battery.lands_at[a]]


def unlimited(battery) -> Battery:
    """``battery`` without a limit: one flight, nothing flown, no way home counted."""
    return battery._replace(endurance=np.inf, turnaround=0.0, used=0.0, start_back=0.0)


def fleet_batteries(problem, lo, lb) -> tuple:
    """(`Batteries` of ``problem``'s UAVs, bool [n_uavs, n_vp]: the viewpoints beyond
    each one's battery). ``lo``, ``lb``: the times out of each start and back to its
    own base. Per UAV its times out of its start and of its own base, back to the
    base its sortie lands at and which that is, and out of every base; viewpoints no
    base reaches and leaves on one battery closed (inf out of the start and the
    bases)."""
    n = int(problem.n_uavs)
    endurance = float(problem.endurance_s)
    if endurance < np.inf and problem.launch_out is None:
        raise ValueError("an endurance needs launch points (bases to come back to)")
    base = lo if problem.base_out is None else np.asarray(problem.base_out, np.float64)
    if base.shape != lo.shape:
        raise ValueError(f"base_out must be {lo.shape}")
    back, at, bases_out = _landings(problem, base, lb)
    # copies in C order whatever the callers' layouts (a problem cut into parts has
    # transposed ones): the kernels are compiled once per layout, a minute each new one
    out, base_out = np.array(lo, np.float64, order="C"), np.array(base, np.float64, order="C")
    back, at = np.array(back, np.float64, order="C"), np.array(at, np.int64, order="C")
    bases_out = np.array(bases_out, np.float64, order="C")
    reach = endurance if problem.reach_s is None else problem.reach_s
    trip = np.zeros_like(base_out) if problem.trip_s is None else \
        np.asarray(problem.trip_s, np.float64)
    trips = trip[:, None, :] if problem.bases_trip_s is None else \
        np.asarray(problem.bases_trip_s, np.float64)[None]
    # per UAV, base, viewpoint: its round trip, as flown where known
    far = np.maximum(bases_out + back[:, None, :], trips) > reach
    own = np.maximum(base_out + back, trip) > reach
    if problem.bases_out is not None:       # a base it never comes to is no start
        far |= ~_bases_reached(at, ~own, ~far)[:, :, None]
    bases_out[far] = np.inf
    out[own], base_out[own] = np.inf, np.inf
    used = np.zeros(n) if problem.used_s is None else np.array(problem.used_s, np.float64)
    home = np.zeros(n) if problem.start_back is None else \
        np.array(problem.start_back, np.float64)
    batteries = Batteries(out, base_out, back, at, bases_out, np.full(n, endurance),
                          np.full(n, float(problem.turnaround_s)), used, home)
    return batteries, far.all(axis=1)


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


def landing_bases(problem) -> np.ndarray:
    """int per viewpoint: the base (of ``bases_back``) a sortie whose last viewpoint
    it is lands at, the nearest on its hidden way home (all 0 without bases)."""
    if problem.bases_back is None:
        return np.zeros(problem.n_viewpoints, np.int64)
    return np.argmin(np.asarray(problem.bases_back, np.float64), axis=0)


def beyond_battery(problem) -> np.ndarray:
    """Ids of the viewpoints no UAV can fly to from a base and back on one
    battery: no plan visits them (a plan reports them)."""
    return np.flatnonzero(beyond(problem).all(axis=0))


def beyond(problem) -> np.ndarray:
    """bool [n_uavs, n_vp]: the viewpoints beyond each UAV's battery (`fleet_batteries`)."""
    lo = np.asarray(problem.launch_out, np.float64) if problem.launch_out is not None \
        else np.zeros((problem.n_uavs, problem.n_viewpoints))
    lb = np.asarray(problem.launch_back, np.float64) if problem.launch_back is not None \
        else np.zeros_like(lo)
    return fleet_batteries(problem, lo, lb)[1]
