"""ArduPilot's SmartRTL path, as the simulated copter keeps it and flies it back
(libraries/AP_SmartRTL/AP_SmartRTL.cpp, ArduCopter/mode_smart_rtl.cpp).

From arming, the vehicle's position is saved as a point whenever it is at least
SRTL_ACCURACY metres from the last one; the first point is home. When the
buffer (SRTL_POINTS) has only ``CLEANUP_START_MARGIN`` free slots, the path is
simplified (Ramer-Douglas-Peucker at half of SRTL_ACCURACY). A point that still
finds no room deactivates SmartRTL for the flight ("SmartRTL deactivated: buffer
full"; the firmware waits SMARTRTL_TIMEOUT, 15 s, of such points first), after
which a failsafe's "SmartRTL or ..." takes its fallback. The firmware also prunes
loops (where the path comes back within SRTL_ACCURACY of itself); the simulator
does not, so it keeps at least as many points: it runs out of room no later.

Flying it back pops the points newest first; the last (home) is flown to 2 m
above it, and the vehicle lands there.
"""

import math

#: AP_SmartRTL.h
CLEANUP_START_MARGIN = 10
#: mode_smart_rtl.cpp: the last point is flown to this many metres above home
PRELAND_M = 2.0


def path_of(flavour, params: dict, home):
    """A new flight's `SmartPath` for a flavour that keeps one (ArduPilot: its
    profile's ``smartrtl``), sized by the vehicle's own SRTL_POINTS and
    SRTL_ACCURACY; None for one that does not."""
    srtl = flavour.profile.smartrtl
    if srtl is None:
        return None
    points = min(int(params.get(srtl.points_param, srtl.points)), srtl.points_max)
    return SmartPath(points, float(params.get(srtl.accuracy_param, srtl.accuracy_m)), home)


class SmartPath:
    """The saved path of one flight; ``active`` False once deactivated (or with
    SRTL_POINTS 0: SmartRTL disabled)."""

    def __init__(self, points_max: int, accuracy_m: float, home):
        self.points_max = int(points_max)
        self.accuracy_m = float(accuracy_m)
        self.points = []
        self.active = self.points_max > 0
        if self.active:
            self.points.append(tuple(home))

    def add(self, pos) -> bool:
        """Save ``pos`` if it is far enough from the last point; True when this point
        found no room and SmartRTL was deactivated now."""
        if not self.active or math.dist(pos, self.points[-1]) < self.accuracy_m:
            return False
        if len(self.points) >= self.points_max - CLEANUP_START_MARGIN:
            self.points = simplified(self.points, self.accuracy_m / 2.0)
        if len(self.points) >= self.points_max:
            self.active = False
            return True
        self.points.append(tuple(pos))
        return False

    def way_back(self) -> list:
        """The points to fly, newest first, home last (``PRELAND_M`` above it)."""
        back = list(reversed(self.points))
        x, y, z = back[-1]
        back[-1] = (x, y, z + PRELAND_M)
        return back


def simplified(points, epsilon: float) -> list:
    """Ramer-Douglas-Peucker in 3-D: the points whose removal would move the path
    more than ``epsilon``, the ends kept (AP_SmartRTL::detect_simplifications)."""
    keep = [False] * len(points)
    keep[0] = keep[-1] = True
    stack = [(0, len(points) - 1)]
    while stack:
        first, last = stack.pop()
        worst, at = 0.0, None
        for i in range(first + 1, last):
            d = _to_segment(points[i], points[first], points[last])
            if d > worst:
                worst, at = d, i
        if at is not None and worst > epsilon:
            keep[at] = True
            stack += [(first, at), (at, last)]
    return [p for p, k in zip(points, keep) if k]


def _to_segment(p, a, b) -> float:
    ab = [bi - ai for ai, bi in zip(a, b)]
    ap = [pi - ai for ai, pi in zip(a, p)]
    length2 = sum(c * c for c in ab)
    t = 0.0 if length2 == 0 else max(0.0, min(1.0, sum(u * v for u, v in zip(ab, ap)) / length2))
    return math.dist(p, [ai + t * c for ai, c in zip(a, ab)])
