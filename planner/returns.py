"""What a firmware's own return flies from each point of a sortie, and where it
stops being the proven one (plan.json ``returns``).

- ArduPilot: SmartRTL retraces the flown path, kept in a buffer of SRTL_POINTS
  points SRTL_ACCURACY apart, simplified within half of that
  (`autopilots.ardupilot.SmartRTL`). A sortie whose path needs more points than
  the buffer holds deactivates SmartRTL where it fills, and from there its
  failsafes take their fallback (BATT_FS_LOW_ACT 4: land where it is).
  `smartrtl_points` counts a sortie's points conservatively from its polyline:
  the polyline simplified as the firmware simplifies, each corner counted twice
  (flown rounded, it leaves a point either side), loops never pruned. So the
  buffer is said full no later than it fills in flight.
- PX4: RTL_TYPE 2 / 4 return along the mission, forward to its landing or
  reversed to home: the legs the plan proved, whatever their number.
"""

import numpy as np

from autopilots import profile
from common.geo import LocalFrame


def simplified_keep(xyz: np.ndarray, epsilon: float) -> np.ndarray:
    """bool per vertex: kept by Ramer-Douglas-Peucker at ``epsilon`` (the ends kept),
    as AP_SmartRTL simplifies its path."""
    keep = np.zeros(len(xyz), bool)
    keep[[0, -1]] = True
    stack = [(0, len(xyz) - 1)]
    while stack:
        first, last = stack.pop()
        if last - first < 2:
            continue
        a, b, inner = xyz[first], xyz[last], xyz[first + 1:last]
        ab = b - a
        t = np.clip((inner - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0)
        d = np.linalg.norm(a + t[:, None] * ab - inner, axis=1)
        at = int(np.argmax(d))
        if d[at] > epsilon:
            keep[first + 1 + at] = True
            stack += [(first, first + 1 + at), (first + 1 + at, last)]
    return keep


def smartrtl_points(xyz: np.ndarray, accuracy_m: float) -> np.ndarray:
    """The SmartRTL points a flight along polyline ``xyz`` (metres) holds on reaching
    each vertex, counted conservatively (see the module doc): home and each
    vertex kept by the simplification, the inner ones twice."""
    keep = simplified_keep(np.asarray(xyz, float), accuracy_m / 2.0)
    per_vertex = np.where(keep, 2, 0)
    per_vertex[0] = 1                              # home, the path's first point
    per_vertex[-1] = 1 if len(xyz) > 1 else per_vertex[-1]
    return np.cumsum(per_vertex)


def sortie_polyline(route) -> np.ndarray:
    """A sortie's path in metres (east, north, up) of its launch: from the ground at
    its base up its column, its waypoints, down to the base it lands at."""
    points = [route.launch] if route.launch is not None else []
    points += list(route.waypoints)
    if route.landing is not None:
        points.append(route.landing)
    frame = LocalFrame(points[0].lat, points[0].lon)
    x, y = frame.to_local(np.array([p.lat for p in points]), np.array([p.lon for p in points]))
    return np.stack([x, y, [p.alt_amsl for p in points]], axis=1)


def smartrtl_budget(route, points: int, accuracy_m: float) -> list:
    """Per sortie of ``route``: {sortie, points (needed), full_at (the waypoint, from
    1 in the sortie, at which the buffer is full: None when it never is)}."""
    out = []
    for j, part in enumerate(route.sortie_routes(), start=1):
        if not part.waypoints:
            continue
        counts = smartrtl_points(sortie_polyline(part), accuracy_m)
        over = np.flatnonzero(counts > points)
        # vertex 0 is the base: waypoint i is vertex i (with a launch point)
        first = int(over[0]) if len(over) else None
        if first is not None and part.launch is None:
            first += 1
        out.append({"sortie": j, "points": int(counts[-1]),
                    "full_at": None if first is None else min(first, len(part.waypoints))})
    return out


def returns(vehicles, firmware: str) -> dict:
    """plan.json's ``returns``: what the firmware's return flies, and for ArduPilot
    each sortie's SmartRTL points against the default buffer."""
    srtl = profile(firmware).smartrtl
    if srtl is None:
        return {"firmware": firmware, "return": "the mission path, forward to its landing or "
                "reversed to home (RTL_TYPE 2 / 4): the proven legs"}
    sorties = [dict(s, vehicle=v.id) for v in vehicles
               for s in smartrtl_budget(v, srtl.points, srtl.accuracy_m)]
    return {"firmware": firmware, "return": "SmartRTL: the flown path back",
            "srtl_points": srtl.points, "srtl_points_max": srtl.points_max,
            "srtl_accuracy_m": srtl.accuracy_m, "sorties": sorties,
            "too_long": [s for s in sorties if s["full_at"] is not None]}


def returns_said(metrics: dict) -> str | None:
    """The plan summary's warning of sorties too long for the SmartRTL buffer (None:
    every sortie fits)."""
    r = metrics.get("returns") or {}
    long = r.get("too_long") or []
    if not long:
        return None
    each = ", ".join(f"vehicle {s['vehicle']} sortie {s['sortie']} ({s['points']} points, full "
                     f"at its waypoint {s['full_at']})" for s in long)
    return (f"warning: SmartRTL buffer: {each} need more than SRTL_POINTS {r['srtl_points']} "
            f"(its default): past that point a failsafe's SmartRTL is gone and it lands where "
            f"it is; set SRTL_POINTS up to {r['srtl_points_max']} (reboot), or fly shorter "
            "sorties (--endurance)")
