"""Which silences the plan expects: a vehicle's radio shadows on the monitor's clock.

The plan predicts when each vehicle is out of the ground station's radio contact
(`planner.plan.VehicleRoute.silences`, on the fleet clock: `planner.link`). The
monitor hears a vehicle fall silent on its own clock (seconds since the flight
started). `Contact` joins the two through the vehicle's progress: the planned time
of each waypoint it reached, and when it reached it by the vehicle's own clock
(its reports' time since boot). Its pace (fleet seconds per monitor second) is
its progress on its plan per second of its own clock (1 on schedule, less when
held or slowed) times its clock's rate (a sped-up simulator's speed-up).

The vehicle's own clock, not the moment its reports are read: a ground station
reads them in bursts (six waypoints' reports read within 0.6 s of wall time at
100x put the pace at 1.5 times the speed-up), and its last HEARTBEAT may be
older than its last report (1.5 s of wall time, 150 s of flight, at 100x).

A silence that starts where a shadow is predicted is *out of contact, as
planned*, due back when the shadow ends at that pace; a vehicle not heard by
then, with a margin, is overdue.
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
#: the measured progress on the plan (fleet s per s of the vehicle's own clock) is
#: trusted within these bounds
PACE_RANGE = (0.5, 2.0)


@dataclass(frozen=True)
class Expected:
    """A silence the plan predicts: its window (fleet clock), when the vehicle was last
    heard and when it is due back (monitor clock, at the pace measured then), the
    margin after that before it is overdue, and both as fleet seconds of its plan
    flown since it was heard (``allowed_s``: overdue past that many; the monitor
    counts them at the pace it measures while the vehicle is silent); ``fleet_s``:
    where on its plan it was when last heard."""

    window: tuple
    heard_s: float
    due_s: float
    margin_s: float
    allowed_s: float = float("inf")
    fleet_s: float = 0.0

    @property
    def overdue_s(self) -> float:
        return self.due_s + self.margin_s


class Contact:
    """One vehicle's predicted silences and its progress on the fleet clock."""

    def __init__(self, windows, clock_rate: float = 1.0, trajectory=()):
        self.clock_rate = float(clock_rate)  # its own clock's s per monitor s
        self.restart(windows, trajectory)

    def restart(self, windows, trajectory=()) -> None:
        """A new mission on another clock (a re-plan): its windows and its planned
        trajectory ([t, lon, lat, alt] rows), no progress yet."""
        self.windows = _merged([tuple(map(float, w)) for w in windows or []])
        rows = np.asarray(trajectory, float).reshape(-1, 4)
        # (lon, lat) where the plan enters each shadow
        self._entries = [tuple(float(np.interp(a, rows[:, 0], rows[:, k])) for k in (1, 2))
                         if len(rows) else None for a, _ in self.windows]
        self._marks = []        # those timed: its pace is measured over them
        self._last = None       # the latest, timed or not: where it is on its plan

    def mark(self, monitor_s: float, fleet_s: float, own_s: float | None = None,
             timed: bool = True) -> None:
        """The vehicle was at fleet time ``fleet_s`` of its plan at ``monitor_s``, its
        own clock then at ``own_s`` (None: not reported) (a waypoint reached, a
        liftoff). Not ``timed``: known to be there, but not when it got there, so
        not measured on (a liftoff seen at the HEARTBEAT that says it armed, up to a
        wall second late: 36 s of its clock at 100x, read as twice its pace; a
        waypoint passed in a shadow, found from the next one reported; a hold)."""
        self._last = (float(monitor_s), float(fleet_s), None if own_s is None else float(own_s))
        if timed:
            self._marks.append(self._last)
            del self._marks[:-PACE_MARKS]

    def set_clock_rate(self, rate: float) -> None:
        """The vehicle's own clock against the monitor's (a sped-up simulator)."""
        if rate > 0:
            self.clock_rate = float(rate)

    @property
    def progress(self) -> float:
        """Fleet seconds of its plan per second of its own clock, measured over the
        latest marks (on the monitor's clock where its own is not reported); 1 where
        they span too little of the plan."""
        if len(self._marks) >= 2:
            (t0, f0, o0), (t1, f1, o1) = self._marks[0], self._marks[-1]
            if f1 - f0 >= EARLY_LATE_S:
                if o0 is not None and o1 is not None and o1 > o0:
                    rate = (f1 - f0) / (o1 - o0)
                elif t1 > t0:
                    rate = (f1 - f0) / (t1 - t0) / self.clock_rate
                else:
                    return 1.0
                lo, hi = PACE_RANGE
                return min(max(rate, lo), hi)
        return 1.0

    @property
    def pace(self) -> float:
        """Fleet seconds of its plan per monitor second."""
        return self.progress * self.clock_rate

    def fleet_time(self, monitor_s: float, own_s: float | None = None) -> Optional[float]:
        """Where on its plan's clock the vehicle is at ``monitor_s`` (its own clock then
        at ``own_s``, when known); None before any progress on this mission."""
        if self._last is None:
            return None
        t, f, o = self._last
        if own_s is not None and o is not None:
            return f + (own_s - o) * self.progress
        return f + (monitor_s - t) * self.pace

    def expected(self, heard_s: float, lost_after_s: float, where=None,
                 own_s: float | None = None) -> Optional[Expected]:
        """The predicted silence a vehicle last heard at ``heard_s`` (at ``where``: lat,
        lon; its own clock then at ``own_s``) is in, or None: its silence is not the
        plan's. It is in one when its plan's clock is there, or when it was heard
        where its plan enters one."""
        clock = self.fleet_time(heard_s, own_s)
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
                                + lost_after_s * self.pace, fleet_s=at)
        return None


def _merged(windows) -> list:
    """``windows`` (sorted) with those less than `EARLY_LATE_S` apart taken as one: a
    contact the plan predicts for a few seconds between two shadows may come early
    or late by as much, or pass unheard between two HEARTBEATs (12 s of flight, 0.6 s
    of wall time at 20x: one silence, which read as overdue on the first shadow)."""
    out = []
    for a, b in windows:
        if out and a - out[-1][1] <= EARLY_LATE_S:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out
