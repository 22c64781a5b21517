"""Where a vehicle's flight is proven: its route's legs, with the room they are proven with.

Every leg of a mission is proven hidden and clear with the plan's track tolerance
of room around it; so are the columns above the launch and landing points (the
takeoff climbs straight up to the route's first waypoint, the landing descends
straight down from its last) and, after a re-plan, the one straight leg from
where the vehicle was held to the new route. A vehicle further than that from
every one of them (beyond `POSITION_MARGIN_M` for its own position's error)
flies where nothing was proven: the monitor says so as it happens, and the
flight's outcome counts it as a problem.
"""

import numpy as np

from common.geo import LocalFrame

#: what a reported position may be off by (GNSS, the report's latency) before a
#: vehicle counts as off its proven legs (m)
POSITION_MARGIN_M = 3.0
#: how far below the first and last waypoints the takeoff and landing columns reach (m):
#: down to any ground (a vehicle under its terrain is a crash, judged on its own)
COLUMN_M = 10_000.0


class ProvenPath:
    """A route's proven legs on a local frame, and how far a position is from them."""

    def __init__(self, route, start=None):
        """``route``: the `planner.plan.VehicleRoute` flown; ``start``: (lat, lon,
        alt AMSL) the vehicle flies straight from to the route's first waypoint (a
        re-plan's held position); None: it climbs to it from the ground."""
        way = [(w.lat, w.lon, w.alt_amsl) for w in route.waypoints] or \
            [start or (route.launch.lat, route.launch.lon, route.launch.alt_amsl)]
        first, last = way[0], way[-1]
        head = [start] if start is not None else [(first[0], first[1], first[2] - COLUMN_M)]
        geo = np.array(head + way + [(last[0], last[1], last[2] - COLUMN_M)], float)
        self.frame = LocalFrame(geo[0, 0], geo[0, 1])
        p = self._local(geo)
        self._a, self._ab = p[:-1], np.diff(p, axis=0)
        self._ab2 = np.maximum((self._ab ** 2).sum(axis=1), 1e-12)

    def _local(self, geo) -> np.ndarray:
        """(lat, lon, alt) rows as metres east, north, up of the path's first point."""
        return self.frame.project(geo[:, [1, 0, 2]])

    def distance_m(self, lat, lon, alt) -> float:
        """Least distance (m) from the position to the path's legs."""
        q = self._local(np.array([[lat, lon, alt]], float))[0]
        t = np.clip(((q - self._a) * self._ab).sum(axis=1) / self._ab2, 0.0, 1.0)
        return float(np.min(np.linalg.norm(self._a + t[:, None] * self._ab - q, axis=1)))
