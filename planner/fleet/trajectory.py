"""A vehicle's flight on the fleet clock: its path with the time of every part.

`Profile` is the path a route flies and how long each part takes at the planned
speeds, before any wait: from the ground at its launch point (or a point in the
air, for a vehicle re-tasked in flight), up the takeoff column, along the hidden
polyline, and down to the ground again. `Profile.timed` places it on the fleet
clock with a start time and a hold at route vertices, giving the `Trajectory`:
piecewise linear rows (t, x, y, z), a hold being two rows at one place, and which
segments are flown (on the ground a vehicle is not airborne).
"""

from dataclasses import dataclass

import numpy as np

from planner.travel import leg_time

from . import kernels


@dataclass(frozen=True, eq=False)
class Trajectory:
    t: np.ndarray    # float64 [m]: fleet clock, s (t = 0: the first takeoff)
    xyz: np.ndarray  # float64 [m, 3]: projected x, y and altitude AMSL
    air: np.ndarray  # bool [m - 1]: airborne on the segment from row i to row i + 1
    vertex: np.ndarray = None  # int [m]: the `Profile` vertex of each row (if made from one)

    @property
    def start(self) -> float:
        return float(self.t[0])

    @property
    def end(self) -> float:
        return float(self.t[-1])

    def closest_approach(self, other: "Trajectory") -> tuple:
        """(least distance m, when s) to ``other`` while both are airborne."""
        return kernels.closest_approach(self.t, self.xyz, self.air, other.t, other.xyz,
                                        other.air)

    def first_conflict(self, other: "Trajectory", separation_m: float) -> tuple:
        """(start, end) s of the first time both are airborne closer than
        ``separation_m``; (inf, inf) if never."""
        return kernels.first_conflict(self.t, self.xyz, self.air, other.t, other.xyz,
                                      other.air, float(separation_m))


@dataclass(frozen=True, eq=False)
class Profile:
    """A path and the time each of its segments takes, before any wait.

    ``xyz`` [n, 3]: its vertices; ``duration`` [n - 1]: seconds per segment;
    ``on_ground`` (first, last): whether it starts and ends on the ground (a
    takeoff and a landing at a launch point); ``route`` (first, last): the
    vertex indices of the hidden polyline (holds are allowed at its vertices)."""

    xyz: np.ndarray
    duration: np.ndarray
    on_ground: tuple
    route: tuple

    @classmethod
    def of_route(cls, polyline, travel_params, launch=None, start=None,
                 stop_s=0.0, land=None) -> "Profile":
        """The profile of a hidden polyline (its first vertex the top of the takeoff,
        its last the point above the base where the landing starts): with ``launch``
        (x, y, ground AMSL), from and to the ground there (to ``land`` where given:
        a sortie landing at another base); with ``start`` (x, y, alt) instead of a
        takeoff, from that point in the air (a vehicle held in flight), flown
        straight to the polyline's first vertex. ``stop_s``: what
        slowing to a stop at a vertex and speeding up again costs (speed / the
        acceleration: a multicopter flying a mission stops at each waypoint),
        added to each leg that leaves a polyline vertex but the first. The lowest
        metres of a takeoff and of a landing are flown at the firmware's slower
        rates (`TravelParams.takeoff_band_m`, ``land_band_m``): a vertex where each
        band begins."""
        poly = np.asarray(polyline, float).reshape(-1, 3)
        tp = travel_params
        land = launch if land is None else land
        up = launch is not None and start is None
        down = land is not None and len(poly) > 0
        pts, rate = [], []      # vertices; the vertical rate of the leg leaving each
        if start is not None:
            pts, rate = [np.asarray(start, float)], [None]
        elif up:
            pts, rate = [np.asarray(launch, float)], [None]
            if len(poly):
                mid, rate[0] = _slow_band(launch, poly[0], tp.takeoff_band_m, tp.takeoff_mps)
                if mid is not None:
                    pts, rate = pts + [mid], rate + [None]
        first = len(pts)
        pts, rate = pts + list(poly), rate + [None] * len(poly)
        if down:
            mid, slow = _slow_band(land, poly[-1], tp.land_band_m, tp.land_mps)
            if mid is None:
                rate[-1] = slow
            else:
                pts, rate = pts + [mid], rate + [slow]
            pts, rate = pts + [np.asarray(land, float)], rate + [None]
        xyz = np.vstack(pts)
        d = np.diff(xyz, axis=0)
        duration = leg_time(np.hypot(d[:, 0], d[:, 1]), d[:, 2], tp).astype(float)
        for i, r in enumerate(rate[:-1]):      # the lowest metres of a takeoff or landing
            if r:
                duration[i] = abs(d[i, 2]) / r
        last = first + len(poly) - 1
        duration[first + 1:last] += stop_s       # the legs out of inner polyline vertices
        return cls(xyz, duration, (up, down), (first, last))

    @property
    def n(self) -> int:
        return len(self.xyz)

    def arrivals(self, start_s=0.0, holds=None) -> tuple:
        """(arrival, departure) s at each vertex when it leaves at ``start_s`` and
        waits ``holds[i]`` at vertex i."""
        holds = np.zeros(self.n) if holds is None else np.asarray(holds, float)
        arrive = np.empty(self.n)
        leave = np.empty(self.n)
        t = float(start_s)
        for i in range(self.n):
            arrive[i] = t
            leave[i] = t + holds[i]
            if i + 1 < self.n:
                t = leave[i] + self.duration[i]
        return arrive, leave

    def timed(self, start_s=0.0, holds=None) -> Trajectory:
        """The trajectory when it leaves at ``start_s`` (on the ground, or where it
        stands in the air) and waits ``holds[i]`` at vertex i."""
        arrive, leave = self.arrivals(start_s, holds)
        waits = leave > arrive
        rows = np.repeat(np.arange(self.n), 1 + waits)
        t = np.empty(len(rows))
        t[0] = arrive[0]
        first = np.r_[True, rows[1:] != rows[:-1]]
        t[first] = arrive
        t[~first] = leave[waits]
        # every segment is flown: before its start and after its end the vehicle
        # stands on the ground (or, re-tasked in flight, it held where it is)
        air = np.ones(max(len(rows) - 1, 0), bool)
        return Trajectory(t, self.xyz[rows].copy(), air, rows)


def doing_at(trajectory: Trajectory, when: float) -> tuple:
    """(vertex, holding) of a profile's trajectory at time ``when``: flying the
    segment that leaves that vertex, or holding at it."""
    row = int(np.searchsorted(trajectory.t, when, side="right") - 1)
    row = min(max(row, 0), len(trajectory.t) - 2)
    v = trajectory.vertex
    return int(v[row]), bool(v[row] == v[row + 1])


def route_profile(route, terrain, travel_params, stop_s=0.0) -> Profile:
    """The `Profile` a saved route (`planner.plan.VehicleRoute`) flies: its waypoints
    on ``terrain``'s grid, from and to the ground at its launch point."""
    w = route.waypoints
    x, y = terrain.from_lonlat(np.array([p.lon for p in w], float),
                               np.array([p.lat for p in w], float))
    poly = np.stack([x, y, [p.alt_amsl for p in w]], axis=1)
    return Profile.of_route(poly, travel_params, launch=_ground(terrain, route.launch),
                            stop_s=stop_s, land=_ground(terrain, route.land))


def _ground(terrain, point):
    """A `planner.plan.GeoPoint` on ``terrain``'s grid (x, y, alt AMSL), or None."""
    if point is None:
        return None
    x, y = terrain.from_lonlat(point.lon, point.lat)
    return np.array([float(x), float(y), point.alt_amsl])


def route_trajectory(route, terrain, travel_params, stop_s=0.0) -> Trajectory:
    """The trajectory a saved route flies: leaving at its ``takeoff_s``, waiting its
    waypoints' ``hold_s`` (what its missions carry)."""
    profile = route_profile(route, terrain, travel_params, stop_s)
    holds = np.zeros(profile.n)
    holds[profile.route[0]:profile.route[1] + 1] = [p.hold_s for p in route.waypoints]
    return profile.timed(route.takeoff_s, holds)


def _slow_band(ground, top, band_m, slow_mps) -> tuple:
    """(the point ``band_m`` above ``ground`` under ``top``, the rate below it) of a
    takeoff or landing column whose lowest metres are flown at ``slow_mps``; (None,
    that rate) when the whole column is in the band; (None, None) without one."""
    if not slow_mps or band_m <= 0:
        return None, None
    if top[2] - ground[2] <= band_m:
        return None, slow_mps
    return np.array([top[0], top[1], ground[2] + band_m], float), slow_mps
