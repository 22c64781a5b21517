"""Which silences the plan expects: a vehicle's radio shadows on the monitor's clock.

The plan predicts when each vehicle is out of the ground station's radio contact
(`planner.plan.VehicleRoute.silences`, on the fleet clock: `planner.link`). The
monitor hears a vehicle fall silent on its own clock (seconds since the flight
started). `Contact` joins the two through the vehicle's progress: the planned time
of each waypoint it reached, when it reached it, and the pace it flew between them
(fleet seconds per monitor second: the simulator's speed-up and the vehicle's own
lag or lead on its plan). A silence that starts where a shadow is predicted is
*out of contact, as planned*, due back when the shadow ends at that pace; a
vehicle not heard by then, with a margin, is overdue.
"""

from dataclasses import dataclass
from typing import Optional

import numpy as np

from common.geo import distance_m

#: fleet seconds a vehicle may enter a shadow before or after its predicted start
#: (the guard's holds, the pace measured over few waypoints)
EARLY_LATE_S = 20.0
#: a vehicle last heard this close (m, across the ground) to where its plan enters a
#: shadow is entering it, whatever the clock says (a late liftoff, a slow machine)
ENTRY_M = 150.0
#: of a shadow's predicted remaining length, this much more time before overdue
WIDEN = 0.25
#: marks of progress the pace is measured over (the latest)
PACE_MARKS = 6
#: the measured pace is trusted within this factor of the vehicle's clock rate
PACE_RANGE = (0.5, 2.0)


@dataclass(frozen=True)
class Expected:
    """A silence the plan predicts: its window (fleet clock), when the vehicle was last
    heard and when it is due back (monitor clock, at the pace measured then), the
    margin after that before it is overdue, and both as fleet seconds of its plan
    flown since it was heard (``allowed_s``: overdue past that many; the monitor
    counts them at the pace it measures while the vehicle is silent)."""

    window: tuple
    heard_s: float
    due_s: float
    margin_s: float
    allowed_s: float = float("inf")

    @property
    def overdue_s(self) -> float:
        return self.due_s + self.margin_s


class Contact:
    """One vehicle's predicted silences and its progress on the fleet clock."""

    def __init__(self, windows, clock_rate: float = 1.0, trajectory=()):
        self.clock_rate = float(clock_rate)  # fleet s per monitor s before any progress
        self.restart(windows, trajectory)

    def restart(self, windows, trajectory=()) -> None:
        """A new mission on another clock (a re-plan): its windows and its planned
        trajectory ([t, lon, lat, alt] rows), no progress yet."""
        self.windows = [tuple(map(float, w)) for w in windows or []]
        rows = np.asarray(trajectory, float).reshape(-1, 4)
        # (lon, lat) where the plan enters each shadow
        self._entries = [tuple(float(np.interp(a, rows[:, 0], rows[:, k])) for k in (1, 2))
                         if len(rows) else None for a, _ in self.windows]
        self._marks = []

    def mark(self, monitor_s: float, fleet_s: float) -> None:
        """The vehicle was at fleet time ``fleet_s`` of its plan at ``monitor_s`` (a
        waypoint reached, a liftoff)."""
        self._marks.append((float(monitor_s), float(fleet_s)))
        del self._marks[:-PACE_MARKS]

    def set_clock_rate(self, rate: float) -> None:
        """The vehicle's own clock against the monitor's (a sped-up simulator)."""
        if rate > 0:
            self.clock_rate = float(rate)

    @property
    def pace(self) -> float:
        """Fleet seconds per monitor second, measured over the latest marks; the clock
        rate where they span too little of the plan."""
        if len(self._marks) >= 2:
            (t0, f0), (t1, f1) = self._marks[0], self._marks[-1]
            if f1 - f0 >= EARLY_LATE_S and t1 > t0:
                lo, hi = PACE_RANGE
                return min(max((f1 - f0) / (t1 - t0), lo * self.clock_rate),
                           hi * self.clock_rate)
        return self.clock_rate

    def fleet_time(self, monitor_s: float) -> Optional[float]:
        """Where on its plan's clock the vehicle is at ``monitor_s``; None before any
        progress on this mission."""
        if not self._marks:
            return None
        t, f = self._marks[-1]
        return f + (monitor_s - t) * self.pace

    def expected(self, heard_s: float, lost_after_s: float, where=None) -> Optional[Expected]:
        """The predicted silence a vehicle last heard at ``heard_s`` (at ``where``: lat,
        lon) is in, or None: its silence is not the plan's. It is in one when its
        plan's clock is there, or when it was heard where its plan enters one."""
        clock = self.fleet_time(heard_s)
        for (a, b), entry in zip(self.windows, self._entries):
            at = clock
            if where is not None and entry is not None and (at is None or not a <= at <= b) \
                    and distance_m(where[0], where[1], entry[1], entry[0]) <= ENTRY_M:
                at = a
            if at is not None and a - EARLY_LATE_S <= at <= b:
                left = (b - at) / self.pace
                late = EARLY_LATE_S / self.pace
                return Expected((a, b), heard_s, heard_s + left + late,
                                lost_after_s + WIDEN * left,
                                (b - at) * (1.0 + WIDEN) + EARLY_LATE_S
                                + lost_after_s * self.pace)
        return None
