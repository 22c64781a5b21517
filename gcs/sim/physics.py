"""Point-mass flight along straight 3-D legs, with speed, climb, descent and
acceleration limits.

The vehicle tracks the straight line from a leg's origin to its destination
(as ArduPilot's waypoint navigation does), so a track flown between two planned
waypoints stays on the planned segment; cross-track error left by a change of
leg is pulled back at a finite acceleration. Positions are local metres (x east,
y north) around the vehicle's home (`common.geo.LocalFrame`, the ground
station's own), altitude metres AMSL.
"""

import math
from dataclasses import dataclass, fields, replace

from planner.rates import VERTICAL_RATES

DEFAULT_HOME = (-35.363261, 149.165230, 584.0)      # ArduPilot SITL's default (CMAC)

_CROSS_GAIN = 1.0      # 1/s: cross-track error -> correcting velocity
_POS_GAIN = 2.0        # 1/s: linear speed profile close to the destination


#: the rates a plan states (plan.json ``params``), by the names `Limits` has too
PLANNED_RATES = ("speed_mps",) + VERTICAL_RATES


@dataclass(frozen=True)
class Limits:
    """What the vehicle flies by; a rate left None is its firmware's at its defaults
    (`autopilots.Autopilot.rates`, `of_firmware`): the lowest metres of a takeoff and a
    landing at their slower rates."""
    speed_mps: float = 12.0
    climb_mps: float | None = None
    descent_mps: float | None = None
    accel_mps2: float = 3.0
    takeoff_mps: float | None = None
    takeoff_band_m: float | None = None
    land_mps: float | None = None
    land_band_m: float | None = None
    jerk_mps3: float | None = None      # a jerk-limited stop at each waypoint (PX4)

    def of_firmware(self, rates) -> "Limits":
        """These limits, each rate not given taken from ``rates``."""
        return replace(self, **{f.name: getattr(rates, f.name) for f in fields(rates)
                                if getattr(self, f.name) is None})


class PointMass:
    """State [x, y, z] and velocity; `go_to` sets the leg, `step` integrates."""

    def __init__(self, pos, limits: Limits):
        self.pos = list(pos)
        self.vel = [0.0, 0.0, 0.0]
        self.limits = limits
        self.speed_mps = limits.speed_mps       # cruise speed, DO_CHANGE_SPEED changes it
        self.climb_mps = limits.climb_mps       # a takeoff lowers it near the ground
        self.descent_mps = limits.descent_mps   # and so does a landing
        self.origin = list(pos)
        self.dest = list(pos)

    def set_speed(self, mps: float) -> None:
        """Cruise at ``mps`` (DO_CHANGE_SPEED), no faster than the airframe flies
        (``limits.speed_mps``): PX4 SITL's SIH quad, drag limited, cruised 9-10 m/s
        on missions asking 12."""
        self.speed_mps = min(float(mps), self.limits.speed_mps)

    def go_to(self, dest, origin=None) -> None:
        self.origin = list(origin if origin is not None else self.pos)
        self.dest = list(dest)

    def hold(self) -> None:
        """Brake and come back to where the vehicle is now."""
        self.go_to(self.pos)

    def distance_to_dest(self) -> float:
        return math.dist(self.pos, self.dest)

    def speed(self) -> float:
        return math.hypot(*self.vel)

    def step(self, dt: float) -> None:
        want = self._desired_velocity()
        dv = [w - v for w, v in zip(want, self.vel)]
        norm = math.hypot(*dv)
        cap = self.limits.accel_mps2 * dt
        if norm > cap:
            dv = [d * cap / norm for d in dv]
        self.vel = [v + d for v, d in zip(self.vel, dv)]
        self.pos = [p + v * dt for p, v in zip(self.pos, self.vel)]

    def _desired_velocity(self) -> list:
        leg = [d - o for d, o in zip(self.dest, self.origin)]
        length = math.hypot(*leg)
        if length < 1e-6:
            u, along = [0.0, 0.0, 0.0], 0.0
        else:
            u = [c / length for c in leg]
            along = sum((p - o) * c for p, o, c in zip(self.pos, self.origin, u))
        remaining = length - along
        closest = [o + along * c for o, c in zip(self.origin, u)]
        cross = [c - p for c, p in zip(closest, self.pos)]
        if length < 1e-6:      # hold: head for the point itself
            cross = [d - p for d, p in zip(self.dest, self.pos)]
        a = self.limits.accel_mps2
        v = min(self._line_speed(u), math.sqrt(2.0 * a * abs(remaining)),
                _POS_GAIN * abs(remaining))
        v = math.copysign(v, remaining)
        want = [c * v + _CROSS_GAIN * e for c, e in zip(u, cross)]
        return self._clamp(want)

    def _line_speed(self, u) -> float:
        """Fastest speed along direction u within the horizontal and vertical limits."""
        cap = math.inf
        horizontal = math.hypot(u[0], u[1])
        if horizontal > 1e-9:
            cap = self.speed_mps / horizontal
        if u[2] > 1e-9:
            cap = min(cap, self.climb_mps / u[2])
        elif u[2] < -1e-9:
            cap = min(cap, self.descent_mps / -u[2])
        return cap if math.isfinite(cap) else 0.0

    def _clamp(self, want) -> list:
        vx, vy, vz = want
        h = math.hypot(vx, vy)
        if h > self.speed_mps:
            vx, vy = vx * self.speed_mps / h, vy * self.speed_mps / h
        vz = min(max(vz, -self.descent_mps), self.climb_mps)
        return [vx, vy, vz]
