"""The abstract coverage problem and the resulting allocation.

Everything in :mod:`planner.coverage` works on this combinatorial form: which
targets each viewpoint sees (CSR), hidden travel times between viewpoints, and
optionally per-UAV launch points.  The terrain, visibility and travel stages
build a :class:`CoverageProblem`; the coverage methods turn it into an
:class:`Allocation` (one route of viewpoint ids per UAV).
"""

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

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
    # sorties (`routes.walk`, `battery.Battery`; launch points needed): the flight
    # time of one battery, the time on the ground between two sorties, per UAV the times out of
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
    # a sortie to each viewpoint alone as flown (stops at its waypoints, the slow
    # metres of takeoff and landing), per UAV out of its base [n_uavs, n_vp] and,
    # with ``bases_out``, out of each base [n_bases, n_vp]; 0 where not known: the
    # reach is judged by the larger of it and the travel times
    trip_s: Optional[np.ndarray] = None
    bases_trip_s: Optional[np.ndarray] = None

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
