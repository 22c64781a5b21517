"""The fleet clock in flight: mission seconds since the first takeoff began.

A plan's times are on the fleet clock, which runs at the vehicles' own pace: the
wall clock for real vehicles, faster for a sped-up simulation. The ground station
reads it off the vehicles themselves: between two readings the fleet clock moves
as far as their boot clocks (GLOBAL_POSITION_INT) moved, the median over the
fleet, so the same flight code starts and re-tasks a fleet on time at any
speed-up, and through a spell where a simulator slowed to real time (`gcs.busy`).
Its rate (fleet seconds per wall second, for horizons and waits) is read from
the last few seconds of their reports, after the ground station's last busy spell.
"""

import threading
import time

import numpy as np

from gcs import busy

#: wall seconds of telemetry each vehicle's pace is read from
RATE_WINDOW_S = 3.0
#: the least span of reports after a busy spell a pace is read from
RATE_MIN_SPAN_S = 0.5
#: wall seconds a rate read is reused for: it is asked several times per loop of the
#: flight, and each read walks seconds of every vehicle's reports
RATE_REUSE_S = 0.05


class FleetClock:
    """``now()``: fleet seconds since `start` (None before)."""

    def __init__(self, monitor):
        self.monitor = monitor
        self._lock = threading.Lock()
        self._wall = None        # monitor time of the last reading
        self._t = None           # fleet time then
        self._rate = (-np.inf, 1.0)  # (monitor time, rate) of the last read

    def rate(self) -> float:
        """Fleet seconds per wall second, from the vehicles' telemetry (1 without)."""
        at, rate = self._rate
        if self.monitor.now() - at < RATE_REUSE_S:
            return rate
        rates = [r for r in map(self._pace, self._tracks(RATE_WINDOW_S)) if r is not None]
        rate = float(np.median(rates)) if rates else 1.0
        self._rate = (self.monitor.now(), rate)
        return rate

    def _tracks(self, back_s: float) -> list:
        """Each vehicle's reports (monitor time, own clock) of the last ``back_s``
        monitor seconds, and the one before them; own clock known."""
        out = []
        since = self.monitor.now() - back_s
        with self.monitor._lock:
            for v in self.monitor.vehicles.values():
                i = len(v.track)
                while i > 0 and v.track[i - 1][0] >= since:
                    i -= 1
                out.append([(r[0], r[4]) for r in v.track[max(0, i - 1):] if r[4] is not None])
        return out

    def _pace(self, rows):
        """A vehicle's own seconds per wall second over ``rows``, from the end of
        the ground station's last busy spell where it has enough reports since."""
        if len(rows) < 2:
            return None
        calm = self.monitor.now() - (time.monotonic() - busy.last_end())
        after = [r for r in rows if r[0] >= calm]
        if len(after) >= 2 and after[-1][0] - after[0][0] >= RATE_MIN_SPAN_S:
            rows = after
        (w0, own0), (w1, own1) = rows[0], rows[-1]
        return (own1 - own0) / (w1 - w0) if w1 > w0 and own1 > own0 else None

    def _moved(self, wall0: float, wall1: float) -> float:
        """Fleet seconds between monitor times ``wall0`` and ``wall1``: how far the
        vehicles' own clocks moved, the median over those reporting across the span
        (one rebooted is left out), each extrapolated at its pace from its last
        report; the rate times the span where none did."""
        moved = []
        for rows in self._tracks(self.monitor.now() - wall0):
            if len(rows) < 2 or rows[0][0] > wall0:
                continue
            pace = self._pace(rows[-8:]) or 1.0
            a, b = _own_at(rows, wall0, pace), _own_at(rows, wall1, pace)
            if b >= a:
                moved.append(b - a)
        return float(np.median(moved)) if moved else (wall1 - wall0) * self.rate()

    def start(self, at: float = 0.0) -> None:
        """The fleet clock reads ``at`` now (t = 0: the first takeoff begins)."""
        with self._lock:
            self._wall, self._t = self.monitor.now(), float(at)

    @property
    def started(self) -> bool:
        return self._t is not None

    def now(self):
        with self._lock:
            if self._t is None:
                return None
            wall = self.monitor.now()
            self._t += self._moved(self._wall, wall)
            self._wall = wall
            return self._t

    def wall_seconds(self, fleet_s: float) -> float:
        """About how many wall seconds ``fleet_s`` of fleet time take now."""
        return fleet_s / max(self.rate(), 1e-6)


def _own_at(rows, wall: float, pace: float) -> float:
    """A vehicle's own clock at monitor time ``wall``: between its reports ``rows``
    ((monitor time, own clock), in order, the first at or before ``wall``), or
    ``pace`` times the wall time on from the last."""
    for (w0, own0), (w1, own1) in zip(rows, rows[1:]):
        if w0 <= wall <= w1:
            return own0 + (own1 - own0) * (wall - w0) / (w1 - w0) if w1 > w0 else own0
    return rows[-1][1] + (wall - rows[-1][0]) * pace
