"""Deconfliction: waits that keep every pair of airborne vehicles apart.

Vehicles are placed on the fleet clock one at a time, in priority order. Each
keeps its path (every leg stays as it was proven hidden and clear) and only
waits: on the ground before it takes off, or hovering at a vertex of its hidden
polyline (a hidden point) before flying on. A vehicle is timed by walking its
first conflict with those already placed (two airborne vehicles closer than the
separation, found exactly: `kernels.first_conflict`) and waiting where it was
before it: at the vertex whose leg meets the other vehicle, or at the one before
when the conflict comes while it holds, or on the ground when it comes in its
takeoff column. Waits are whole seconds (what an ArduPilot waypoint hold keeps),
1, 2, 4, ... at one place but never more than the conflict lasts, and the walk
starts again until none is left.

A base's column is one vehicle's at a time (`columns`): two airborne vehicles in
one column at once are a conflict too. Vehicles sharing a base therefore take off
one at a time, each once the one before has left the column (a separation away
sideways, or above its top), and land one at a time, the later ones holding at a
hidden waypoint while another is in the column. A vehicle
that finds no room after `MAX_WAITS` waits takes off once all the others have
landed. Several priority orders are tried and the best plan kept (`schedule`).
A vehicle flying several sorties (one per battery) is one flight per sortie,
each taking off no sooner than the turnaround after the one before landed.
"""

import math
from dataclasses import dataclass

import numpy as np

from .columns import Occupied, base_columns, profile_bases
from .trajectory import Profile, Trajectory, doing_at

#: metres kept beyond the separation while timing (rounding of saved waypoints)
SLACK_M = 0.05
#: seconds, and the fraction of its flight so far, a vehicle may run early or late
#: against the plan and the fleet still keep the separation (measured: the built-in
#: simulator, started at the planned times, ends its flights within 3 % of them)
DRIFT_S, DRIFT_RATE = 3.0, 0.03
#: waits tried per vehicle before it is sent after every other one has landed
MAX_WAITS = 1000


@dataclass
class Timing:
    """When one vehicle leaves and where it waits."""

    start_s: float           # leaves the ground (or, in flight, its held point) then
    holds: np.ndarray        # s waited at each profile vertex
    trajectory: Trajectory
    earliest_s: float = 0.0  # it could have left then (a later sortie: after its turnaround)

    @property
    def wait_s(self) -> float:
        return float(self.start_s - self.earliest_s + self.holds.sum())


@dataclass
class FleetSchedule:
    timings: list            # `Timing` per vehicle, in the order of the profiles given
    order: list              # priority order (the first placed has right of way)
    min_separation_m: float  # closest approach of two airborne vehicles (inf: never two)
    closest: tuple           # (i, j, t_s) of it, None when never two at once
    wait_s: float            # every start delay and hold, summed

    @property
    def trajectories(self) -> list:
        return [t.trajectory for t in self.timings]


def schedule(profiles, separation_m: float, score=None, after=None,
             turnaround_s=0.0, air_s=math.inf, urgency=None) -> FleetSchedule:
    """Time ``profiles`` (`Profile` per flight) so that no two airborne vehicles
    come closer than ``separation_m``. ``score(timings)``: what a schedule costs
    (default: when the last vehicle is done); the best of a few priority orders
    is kept, a separated one before any other. ``after[i]``: the flight that
    must have landed ``turnaround_s`` before flight i takes off (a vehicle's
    earlier sortie; None: none). ``air_s``: the most a flight from the ground may
    be airborne (a battery): a wait in the air that would take it past that is
    waited on the ground before takeoff instead. ``urgency[i]``: of flights in the
    air now, those of lower urgency go first whatever the order (a battery nearly
    spent: default 0 for all)."""
    score = score or (lambda timings: max((t.trajectory.end for t in timings), default=0.0))
    after = after or [None] * len(profiles)
    # kept with a little room: the waypoints are stored to 1e-7 degrees, and a
    # saved plan's trajectories are proven again from them (`prove_separated`)
    room = separation_m + SLACK_M if separation_m > 0 else 0.0
    columns = base_columns(profile_bases(profiles), room)
    best = None
    for order in _orders(profiles, after, urgency or [0.0] * len(profiles)):
        timings = [None] * len(profiles)
        placed = []
        for i in order:
            earliest = 0.0 if after[i] is None else \
                float(math.ceil(timings[after[i]].trajectory.end + turnaround_s))
            timings[i] = _fit(profiles[i], placed, room, earliest, air_s, columns)
            placed.append(Occupied(timings[i].trajectory, columns))
        d, closest = separation([p.trajectory for p in placed])
        closest = None if closest is None else (order[closest[0]], order[closest[1]],
                                                closest[2])
        key = (d < separation_m - 1e-6, score(timings))
        if best is None or key < best[0]:
            best = (key, FleetSchedule(timings, list(order), d, closest,
                                       float(sum(t.wait_s for t in timings))))
    return best[1]


def separation(trajectories) -> tuple:
    """(least distance of two airborne vehicles, (i, j, t) of it or None)."""
    best, where = math.inf, None
    for i in range(len(trajectories)):
        for j in range(i + 1, len(trajectories)):
            d, t = trajectories[i].closest_approach(trajectories[j])
            if d < best:
                best, where = float(d), (i, j, float(t))
    return best, where


def _orders(profiles, after, urgency) -> list:
    """Priority orders worth trying: the longest vehicles' flights first (they set
    the makespan; a wait there costs most), the shortest first, and as given; a
    vehicle's sorties one after the other, in their order. Flights of vehicles
    in the air now (a re-plan) go before every other, the most urgent first: they
    cannot wait on the ground, and every hold draws their battery (placed after
    another vehicle's sorties, one hovering in its base column once waited 107
    min for five of them to pass through it)."""
    chains = [[i] for i in range(len(profiles)) if after[i] is None]
    for chain in chains:
        while (nxt := [j for j, a in enumerate(after) if a == chain[-1]]):
            chain.append(nxt[0])
    total = [sum(float(profiles[i].duration.sum()) for i in c) for c in chains]
    n = len(chains)
    airborne = sorted((c[0] for c in chains if not profiles[c[0]].on_ground[0]),
                      key=lambda i: (urgency[i], i))
    out = []
    for order in (sorted(range(n), key=lambda i: (-total[i], i)),
                  sorted(range(n), key=lambda i: (total[i], i)), list(range(n))):
        flat = airborne + [i for c in order for i in chains[c] if i not in airborne]
        if flat not in out:
            out.append(flat)
    return out


def _fit(profile: Profile, placed, separation_m, earliest=0.0, air_s=math.inf,
         columns=()) -> Timing:
    """`Timing` of one flight among those ``placed`` (`Occupied`), leaving at
    ``earliest`` or later, airborne at most ``air_s`` when it leaves the ground, never
    in one of ``columns`` with another (see the module doc and `schedule`)."""
    holds = np.zeros(profile.n)
    start = earliest
    where, step = None, 1.0
    for _ in range(MAX_WAITS):
        trajectory = profile.timed(start, holds)
        begin, end = _first_conflict(Occupied(trajectory, columns), placed, separation_m)
        if not math.isfinite(begin):
            return Timing(start, holds, trajectory, earliest)
        vertex, holding = doing_at(trajectory, begin)
        if holding:
            vertex -= 1                  # arrive later where it held
        if profile.on_ground[0] and vertex <= profile.route[0]:
            vertex = -1                  # on the ground: its takeoff column is in use
        elif vertex < 0:
            break                        # in flight, met where it already stands
        # waits of 1, 2, 4, ... s at one place, never more than the conflict lasts:
        # the least wait that clears it, within a factor of two
        step = step * 2 if vertex == where else 1.0
        step = min(step, float(max(1.0, math.ceil(end - begin))))
        where = vertex
        if vertex < 0:
            start += step
        elif profile.on_ground[0] and \
                trajectory.end - start + step > air_s + 1e-9:
            start += holds.sum() + step  # the battery has no room for it: wait on the ground
            holds[:] = 0.0
        else:
            holds[vertex] += step
    return _after_everyone(profile, placed, earliest)


def _after_everyone(profile, placed, earliest=0.0) -> Timing:
    """Leave once every placed vehicle has landed (in flight: hold until then)."""
    last = max([p.trajectory.end for p in placed] + [earliest])
    holds = np.zeros(profile.n)
    start = 0.0
    if profile.on_ground[0]:
        start = float(math.ceil(last))
    else:
        holds[0] = float(math.ceil(last))
    return Timing(start, holds, profile.timed(start, holds), earliest)


def drift_s(trajectory) -> float:
    """How far off its schedule a vehicle may be by the end of this trajectory:
    `DRIFT_S`, and `DRIFT_RATE` of its flight (its speeds, its waypoints' slowing
    and its start are only as exact as the model of them)."""
    return DRIFT_S + DRIFT_RATE * (trajectory.end - trajectory.start)


def _first_conflict(occupied, placed, separation_m) -> tuple:
    """The earliest (start, end) of a conflict with any placed trajectory (closer
    than the separation, or in one column at once), with this one on time and
    `drift_s` early and late: a schedule the vehicles keep only to the second would
    not hold in the air."""
    best = (math.inf, math.inf)
    trajectory = occupied.trajectory
    drift = drift_s(trajectory)
    for shift in (0.0, -drift, drift):
        moved = Trajectory(trajectory.t + shift, trajectory.xyz, trajectory.air,
                           trajectory.vertex)
        for other in placed:
            for begin, end in (moved.first_conflict(other.trajectory, separation_m),
                               occupied.first_shared(other, shift)):
                if begin - shift < best[0]:
                    best = (begin - shift, end - shift)
    return best
