"""The fleet clock of one plan: its sorties timed as one fleet, kept apart.

`fleet_clock` gives every sortie (`planner.sorties.Sortie`) its `Profile` and
lets `schedule` choose the waits that keep airborne vehicles separated, a
vehicle's sorties a turnaround apart, and the coverage time earliest; the
result is a `Fleet`. `over_battery` says which flights the waits or the
slowing at waypoints have made longer than a battery allows.
"""

import math
from dataclasses import dataclass

import numpy as np

from planner.coverage.model import achievable, last_needed_sighting

from . import FleetSchedule, Profile, schedule, stop_time

#: a survivor held this close (m, each axis) to its launch point stands on the ground
GROUND_M = 0.5


@dataclass
class Fleet:
    """The routes as one fleet on the fleet clock (`planner.fleet`), one flight per
    `Sortie`."""

    sorties: list       # `Sortie` per flight
    schedule: FleetSchedule   # its timings per flight
    profiles: list      # `Profile` per flight
    coverage_time_s: float

    def of(self, r) -> list:
        """Indices of UAV r's flights, in order."""
        return [i for i, f in enumerate(self.sorties) if f.uav == r]

    def snapshot_times(self, r) -> np.ndarray:
        """Fleet-clock time of UAV r's snapshots: when it leaves them (a camera
        fires once its waypoint, hold included, is done)."""
        return np.concatenate([np.zeros(0)] + [self.leave_times(i) for i in self.of(r)])

    def leave_times(self, i, vertices=None) -> np.ndarray:
        """Fleet-clock time flight i leaves each of its visits (as `snapshot_times`), or
        each of its polyline's ``vertices``."""
        t, profile = self.schedule.timings[i], self.profiles[i]
        at = self.sorties[i].snap if vertices is None else np.asarray(vertices, np.int64)
        return profile.arrivals(t.start_s, t.holds)[1][at + profile.route[0]]

    def airborne(self, i) -> tuple:
        """(leaves its start, touches down) of flight i on the fleet clock: it leaves
        the ground, or (in flight) where it holds first."""
        t, profile = self.schedule.timings[i], self.profiles[i]
        return (float(t.start_s + (0.0 if profile.on_ground[0] else t.holds[0])),
                float(t.trajectory.end))

    def track(self, r) -> np.ndarray:
        """UAV r's trajectory rows (t, x, y, alt AMSL) on the fleet clock, its flights
        one after the other."""
        rows = [np.column_stack([t.trajectory.t, t.trajectory.xyz])
                for t in (self.schedule.timings[i] for i in self.of(r))]
        return np.concatenate(rows) if rows else np.zeros((0, 4))

    def flight_s(self, i) -> float:
        """Flight i's time from takeoff (or, in flight, from now) to touchdown, waits
        in the air included."""
        t = self.schedule.timings[i]
        return float(t.trajectory.end - t.start_s)


def _on_ground(start) -> bool:
    """A re-plan's survivor standing at its base (landed): it takes off, and waits
    on the ground, not in the air where it would fill its column from the start."""
    return start.held is not None and start.launch is not None and \
        bool(np.all(np.abs(np.asarray(start.held) - start.launch) <= GROUND_M))


def fleet_clock(ctx, sorties, starts, problem, routes) -> Fleet:
    """Every sortie on the fleet clock with the waits that keep the fleet separated
    (`planner.fleet.schedule`, the scenario's separation and its margin), a vehicle's
    sorties a turnaround apart, the waits chosen for the earliest coverage time."""
    s = ctx.scenario
    profiles = []
    for f in sorties:
        start = starts[f.uav] if starts else None
        profiles.append(Profile.of_route(
            f.poly, ctx.travel_params, launch=f.base, land=f.lands,
            start=None if start is None or not f.first or _on_ground(start) else start.held,
            stop_s=stop_time(vars(s))))
    after = [None if f.first else i - 1 for i, f in enumerate(sorties)]
    need = np.minimum(problem.needs(), achievable(problem))   # as the methods aim at

    def coverage_time(timings) -> float:
        fleet = Fleet(sorties, FleetSchedule(timings, [], 0.0, None, 0.0), profiles, 0.0)
        when = [fleet.snapshot_times(r) for r in range(len(routes))]
        return last_needed_sighting(problem, routes, when, need)

    # in the air, the battery most flown goes first (one retired from its battery
    # flies home before all): a hold draws what it has left
    urgency = [-math.inf if f.first and starts and starts[f.uav].retired else
               -(starts[f.uav].flown_s if f.first and starts else 0.0) for f in sorties]
    sched = schedule(profiles, s.planned_separation_m, coverage_time, after,
                     60.0 * s.turnaround_min, s.usable_s, urgency)
    return Fleet(sorties, sched, profiles, coverage_time(sched.timings) if sorties else 0.0)


def over_battery(fleet, usable_s, starts, waits=True) -> np.ndarray:
    """(sorties of several viewpoints, of one): the longest flight of each kind over
    the usable battery, as a multiple of it (0 where none is over); a vehicle in
    flight has flown part of its first battery already. ``waits``: the holds the
    separation puts on its way counted too."""
    over = np.zeros(2)
    for i, f in enumerate(fleet.sorties):
        if not f.visits and f.first and starts and starts[f.uav].held is not None:
            continue    # in flight with too little battery: home first, whatever it takes
        flown = starts[f.uav].flown_s if starts and f.first else 0.0
        held = 0.0 if waits else float(fleet.schedule.timings[i].holds.sum())
        ratio = (fleet.flight_s(i) - held + flown) / usable_s
        if ratio > 1.0:     # a battery partly flown shares the split's room, not the reach's
            kind = int(len(f.visits) <= 1 and not flown)
            over[kind] = max(over[kind], ratio)
    return over
