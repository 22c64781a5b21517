"""Routes in as few items as the proofs allow, and routes longer than a vehicle holds.

Fewer items: `fewer_waypoints` leaves out a waypoint that repeats the one before
(a zero-length leg) and, given a prover (`leg_prover`: the planner's own leg
proofs, hidden with the track tolerance around it, clear of the terrain, under
the ceiling), every waypoint that is not a snapshot where the straight leg past
it passes them all. The camera command already comes only after snapshot
waypoints (`missions.build`).

Segments: ArduPilot SITL holds 650 items, a board about 700 (more with
BRD_SD_MISSION); a route may need thousands. `RouteMissions` makes the missions
that fly one route on one vehicle: the whole route when it fits, else
segments. A segment is a run of the route's waypoints that fits the vehicle's
capacity (home, speed, its waypoints and their camera commands; the first one
takes off, the last one lands). It ends at a waypoint, whose leg was proven,
the last that fits whose last leg the plan has in radio contact (the next
segment is uploaded as the vehicle flies it: one ending in a radio shadow
waited there unheard, and was declared lost),
so a vehicle whose next segment is late holds there, hidden; the next segment
flies on to the waypoint the vehicle was flying to when it was held (the end of
the last one at the latest), from where it holds: its first item is that place
on the proven leg (`point_on_leg`), so the leg from there is part of a proven
one. Without it PX4 would climb straight up where it holds, to the next item's
altitude, before flying level (MissionBase::checkClimbRequired on every mission
started in the air), above its proven leg. Every mission made here passes
`check` (the mission gate, `missions.check.checked`): the whole route once,
when made, so every leg of every segment is proven before the first is flown,
and each segment again.
"""


import numpy as np

from common.errors import InputError
from common.geo import LocalFrame, distance_m

from .build import firmware_profile, is_above_launch, lands_from_the_air, route_items

#: waypoints closer than this (m, horizontally and vertically) are the same place
SAME_PLACE_M = 0.01
#: fleet seconds a vehicle may reach a waypoint early or late (the ground station's
#: `gcs.contact.EARLY_LATE_S`): a segment ends this far from a predicted radio shadow
SHADOW_MARGIN_S = 20.0


def fewer_waypoints(route, prove=None) -> list:
    """Indices of the route waypoints a mission must fly (see module doc).

    ``prove(a, b)``: whether the straight leg between waypoints a and b passes
    every proof of a planned leg (None: only repeated places are left out)."""
    w = route.waypoints
    keep = []
    for i, p in enumerate(w):
        if keep and _same_place(w[keep[-1]], p) and not getattr(p, "hold_s", 0.0):
            if p.snapshot and not w[keep[-1]].snapshot:
                keep[-1] = i                    # the snapshot is the one flown
            continue
        keep.append(i)
    if prove is None or len(keep) < 3:
        return keep
    out = [keep[0]]
    for j in range(1, len(keep) - 1):
        i = keep[j]
        # a snapshot is flown, and so is a wait of the fleet's schedule
        if w[i].snapshot or getattr(w[i], "hold_s", 0.0) > 0 or \
                not prove(w[out[-1]], w[keep[j + 1]]):
            out.append(i)
    out.append(keep[-1])
    return out


def _same_place(a, b) -> bool:
    return distance_m(a.lat, a.lon, b.lat, b.lon) < SAME_PLACE_M and \
        abs(b.alt_amsl - a.alt_amsl) < SAME_PLACE_M


def leg_prover(ctx):
    """``prove(a, b)`` for `fewer_waypoints` from a planning context (its travel
    graph's leg proofs, on its terrain's projection)."""
    terrain, graph = ctx.terrain, ctx.graph

    def prove(a, b) -> bool:
        x, y = terrain.from_lonlat(np.array([a.lon, b.lon], float),
                                   np.array([a.lat, b.lat], float))
        xyz = np.stack([x, y, [a.alt_amsl, b.alt_amsl]], axis=1)
        return bool(graph.legs_ok(xyz[:1], xyz[1:])[0])

    return prove


def point_on_leg(a, b, here):
    """The point of the straight leg from waypoint ``a`` to waypoint ``b`` nearest
    ``here`` (lat, lon, alt AMSL), as (lat, lon, alt); None where it is ``b``
    itself (within `SAME_PLACE_M`) or there is no leg (``a`` None)."""
    if a is None:
        return None
    frame = LocalFrame(a.lat, a.lon)
    leg = frame.project([(b.lon, b.lat, b.alt_amsl)])[0] - (0.0, 0.0, a.alt_amsl)
    p = frame.project([(here[1], here[0], here[2])])[0] - (0.0, 0.0, a.alt_amsl)
    u = float(np.clip(p @ leg / (leg @ leg), 0.0, 1.0)) if leg @ leg > 0 else 1.0
    if np.linalg.norm((1.0 - u) * leg) < SAME_PLACE_M:
        return None
    x, y, alt = u * leg
    lat, lon = frame.to_geo(x, y)
    return float(lat), float(lon), float(a.alt_amsl + alt)


class RouteMissions:
    """The missions that fly ``route`` on one vehicle (see module doc).

    ``check(mission) -> CheckedMission`` is the mission gate; ``fly`` the route
    waypoints to fly (default: `fewer_waypoints` without a prover)."""

    def __init__(self, route, firmware, options, check, fly=None):
        self.route, self.firmware, self.options, self.check = route, firmware, options, check
        self.fly = list(fewer_waypoints(route) if fly is None else fly)
        if not self.fly:
            raise InputError(f"vehicle {route.id}", "route has no waypoints")
        self.profile = firmware_profile(firmware)
        self.whole = check(route_items(route, firmware, options, self.fly))

    def __len__(self) -> int:
        """Items of the whole route as one mission."""
        return len(self.whole)

    def fits(self, capacity) -> bool:
        return capacity is None or len(self.whole) <= capacity

    def first(self, capacity):
        """The mission to upload before takeoff: the whole route if it fits."""
        return self.whole if self.fits(capacity) else self.segment(capacity, self.fly[0], 0)

    def segment(self, capacity: int, start: int, index: int, taken: bool = False,
                here=None):
        """Segment ``index``: the checked mission from route waypoint ``start`` (one
        of ``fly``) on, as long as ``capacity`` items allow; ``taken``: the snapshot
        at ``start`` is taken already (no camera command there); ``here``: (lat,
        lon, alt AMSL) where the vehicle holds, flown first as its place on the leg
        into ``start`` (`point_on_leg`)."""
        if start not in self.fly:
            raise ValueError(f"waypoint {start} is not one the route flies")
        k = self.fly.index(start)
        if here is not None:
            here = point_on_leg(self.route.waypoints[self.fly[k - 1]] if k else None,
                                self.route.waypoints[start], here)
        fly, land = self._span(k, capacity - (here is not None))
        shots = sum(1 for i in self.fly[:k] if self.route.waypoints[i].snapshot)
        mission = route_items(self.route, self.firmware, self.options, fly,
                              takeoff=k == 0, land=land, segment=index, shots_before=shots,
                              skip_camera={start} if taken else (), here=here)
        if len(mission.items) > capacity:       # the counting below is wrong: never upload
            raise AssertionError(f"segment of {len(mission.items)} items > {capacity}")
        return self.check(mission)

    def unheard_ends(self, capacity: int) -> list:
        """Route waypoints where a segment of at most ``capacity`` items ends on a leg
        its plan has in a radio shadow (no end in contact within its reach): the
        vehicle waits there for its next segment, unheard."""
        w, ends, k = self.route.waypoints, [], 0
        while True:
            fly, land = self._span(k, capacity)
            if land:
                return ends
            if not _in_contact(w[fly[-2]].t_s, w[fly[-1]].t_s, self.route.silences):
                ends.append(fly[-1])
            k = self.fly.index(fly[-1])

    def _span(self, k: int, capacity: int) -> tuple:
        """The waypoints (indices) of the longest segment from fly[k] that fits, and
        whether it lands (it reaches the route's end)."""
        w, o = self.route.waypoints, self.options
        used = (1 if self.profile.home_item else 0) + (1 if o.speed_mps else 0)
        takes_off = k == 0 and o.takeoff and is_above_launch(self.route.launch, w[0])
        used += 1 if takes_off else 0
        landing = 1 if o.takeoff and is_above_launch(self.route.landing, w[-1]) else 0
        # and the DO_LAND_START of a segment that lands without taking off (PX4)
        landing += 1 if lands_from_the_air(self.profile, takes_off, landing) else 0
        end = k
        for j in range(k, len(self.fly)):
            cost = 1 + (1 if w[self.fly[j]].snapshot and o.camera else 0)
            last = j == len(self.fly) - 1
            if used + cost + (landing if last else 0) > capacity:
                break
            used += cost
            end = j + 1
        if end == len(self.fly):
            return self.fly[k:], True
        heard = [j for j in range(k + 2, end + 1)
                 if _in_contact(w[self.fly[j - 2]].t_s, w[self.fly[j - 1]].t_s,
                                self.route.silences)]
        if heard:       # the next segment is uploaded on this one's last leg: not in a shadow
            end = heard[-1]
        if end - k < 2:
            raise InputError(f"vehicle {self.route.id}",
                             f"the vehicle holds {capacity} mission items: too few for a "
                             f"segment of two waypoints from waypoint {self.fly[k]}")
        return self.fly[k:end], False


def _in_contact(t0: float, t1: float, silences) -> bool:
    """From fleet time ``t0`` to ``t1`` its plan has the vehicle in radio contact, with
    a margin either side."""
    return not any(a - SHADOW_MARGIN_S <= t1 and t0 <= b + SHADOW_MARGIN_S
                   for a, b in silences or ())


__all__ = ["RouteMissions", "fewer_waypoints", "leg_prover", "point_on_leg"]
