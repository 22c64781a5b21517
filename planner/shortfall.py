"""Why a battery leaves a target short of the sightings it needs, in the operator's words.

On one battery a UAV reaches only the viewpoints it can fly to from a base it comes
to and back (`coverage.model.battery.beyond`). A target can then fall short of
its k+1 sightings for two different reasons, which call for different remedies:

- **beyond one battery**: fewer viewpoints that see it are within one battery of
  any base than it needs sightings (another base nearer it, or a larger battery);
- **too few UAVs there**: enough such viewpoints, but the UAVs that reach them
  are fewer than it needs (one UAV at a base of its own, with k = 1: it gives one
  sighting, and the fleet's other UAVs never get there on one battery). Another
  UAV at that base, or a lower k, plans it.

`shortfall` tells them apart target by target, and names the UAVs and bases of
the second kind, so that a plan's area summary can say which base lacks a UAV.
"""

from dataclasses import dataclass, field, replace

import numpy as np
from scipy import sparse

from planner.launch import SAME_PLACE_M

from .coverage.model import CLOSED, achievable
from .coverage.model.battery import beyond


@dataclass
class Shortfall:
    """``short``: bool per target, fewer sightings than required within one battery
    (both kinds); ``few``: [(UAV ids from 1, bool per target)], the targets of the
    second kind, grouped by the UAVs that reach them."""

    short: np.ndarray
    few: list = field(default_factory=list)


def shortfall(problem, usable_s, required) -> Shortfall:
    """The targets of ``problem`` that one battery of ``usable_s`` seconds leaves
    short of ``required`` sightings (per target, from distinct UAVs at distinct
    places), and why (`Shortfall`)."""
    battery = replace(problem, endurance_s=usable_s)
    short = achievable(battery) < required
    if not short.any():
        return Shortfall(short)
    # per UAV, the viewpoints it flies to and back from on one battery
    able = ~beyond(battery) & _not_closed(problem)
    reach = _reaching(problem, able)            # [n_uavs, n_targets]
    indptr = np.asarray(problem.vis_indptr)
    open_ = able.any(axis=0)
    places = np.bincount(np.asarray(problem.vis_indices)[np.repeat(open_, np.diff(indptr))],
                         minlength=int(problem.n_targets))
    few = short & (places >= required) & (reach.sum(axis=0) < required)
    groups = []
    if few.any():
        keys, which = np.unique(reach[:, few].T, axis=0, return_inverse=True)
        ids = np.flatnonzero(few)
        for g, key in enumerate(keys):
            mask = np.zeros(len(short), bool)
            mask[ids[np.ravel(which) == g]] = True
            groups.append(([int(r) + 1 for r in np.flatnonzero(key)], mask))
    return Shortfall(short, groups)


def _not_closed(problem) -> np.ndarray:
    """bool per viewpoint: not closed to every UAV before planning."""
    if problem.owner is None:
        return np.ones(problem.n_viewpoints, bool)
    return np.asarray(problem.owner) != CLOSED


def _reaching(problem, able) -> np.ndarray:
    """bool [n_uavs, n_targets]: the UAVs that can sight each target on one battery
    (fly to a viewpoint that sees it: ``able`` [n_uavs, n_viewpoints]), or saw it
    before planning from a place of their own."""
    indptr = np.asarray(problem.vis_indptr)
    vis = sparse.csr_matrix((np.ones(len(problem.vis_indices), np.int32),
                             np.asarray(problem.vis_indices), indptr),
                            shape=(problem.n_viewpoints, int(problem.n_targets)))
    return ((sparse.csr_matrix(able.astype(np.int32)) @ vis).toarray() > 0) | \
        problem.own_matrix()


def bases_of(starts, to_lonlat) -> list:
    """Per UAV, (base number from 1, lat, lon): its launch point, the bases numbered
    in the order the UAVs first take them (``--launch A A B``: A is 1, B is 2).
    ``to_lonlat``: projected x, y -> lon, lat. Empty without launch points."""
    if not starts or any(s.launch is None for s in starts):
        return []
    seen, out = [], []
    for s in starts:
        xy = np.asarray(s.launch[:2], float)
        number = next((i for i, p in enumerate(seen)
                       if np.hypot(*(p - xy)) <= SAME_PLACE_M), None)
        if number is None:
            seen.append(xy)
            number = len(seen) - 1
        lon, lat = to_lonlat(xy[0], xy[1])
        out.append((number + 1, float(lat), float(lon)))
    return out


def few_reason(uavs, bases, k_plus_1) -> str:
    """What the area summary says of ground only ``uavs`` reach on one battery,
    fewer of them than the ``k_plus_1`` sightings it needs: which UAVs, from which
    bases (``bases``: `bases_of`), and what would plan it."""
    at = sorted({bases[u - 1] for u in uavs}) if bases else []
    who = (f"UAV {uavs[0]}" if len(uavs) == 1 else
           "UAVs " + ", ".join(str(u) for u in uavs))
    if at:
        who += (f" of base{'s' if len(at) > 1 else ''} "
                + " and ".join(f"{n} ({lat:.6f},{lon:.6f})" for n, lat, lon in at))
    more = ("another UAV at that base" if len(at) == 1 else
            "another UAV at one of those bases" if at else "another UAV that reaches it")
    return (f"reached on one battery only by {who}, fewer UAVs than the k+1 = {k_plus_1} "
            f"sightings it needs ({more}, or --k {len(uavs) - 1}, would plan it)")
