"""The fleet clock in flight: mission seconds since the first takeoff began.

A plan's times are on the fleet clock, which runs at the vehicles' own pace: the
wall clock for real vehicles, faster for a sped-up simulation. The ground station
reads that pace off the vehicles themselves (how fast their boot clocks, in
GLOBAL_POSITION_INT, advance against the wall clock, the median over the fleet),
so the same flight code starts and re-tasks a fleet on time at any speed-up.
"""

import threading

import numpy as np

#: wall seconds of telemetry each vehicle's pace is read from
RATE_WINDOW_S = 3.0


class FleetClock:
    """``now()``: fleet seconds since `start` (None before)."""

    def __init__(self, monitor):
        self.monitor = monitor
        self._lock = threading.Lock()
        self._wall = None        # monitor time of the last reading
        self._t = None           # fleet time then

    def rate(self) -> float:
        """Fleet seconds per wall second, from the vehicles' telemetry (1 without)."""
        rates = []
        with self.monitor._lock:
            tracks = [list(v.track[-64:]) for v in self.monitor.vehicles.values()]
        for track in tracks:
            rows = [r for r in track if r[4] is not None]
            if len(rows) < 2:
                continue
            last = rows[-1]
            first = next((r for r in rows if last[0] - r[0] <= RATE_WINDOW_S), rows[0])
            if last[0] > first[0] and last[4] > first[4]:
                rates.append((last[4] - first[4]) / (last[0] - first[0]))
        return float(np.median(rates)) if rates else 1.0

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
            self._t += (wall - self._wall) * self.rate()
            self._wall = wall
            return self._t

    def wall_seconds(self, fleet_s: float) -> float:
        """About how many wall seconds ``fleet_s`` of fleet time take now."""
        return fleet_s / max(self.rate(), 1e-6)
