"""Prove a mission before it is written or uploaded: a refused plan is never flown.

Checks, in order: sequence numbers are 0..n-1; no command whose flight is not
a straight leg (RETURN_TO_LAUNCH, loiter turns or circles, splines, DO_JUMP, a
moved home, any NAV command but waypoints, takeoff, landing, loiters at the
point, ROI and delay); every
position is a valid latitude / longitude / finite altitude in MAV_FRAME_GLOBAL
(absolute, like the exposure surface); and every straight 3-D leg between
consecutive position items is hidden (`planner.exposure.segments_hidden`), at
least ``clearance_m`` above the terrain (`segments_clear`) and at most the
plan's ``ceiling_agl_m`` above it (`segments_under_ceiling`): the ceiling is the
legal limit the plan was made under, and a mission over it is refused like one
in view.

How legs are flown: a home item (seq 0, where the firmware's `autopilots`
profile has one: ArduPilot) is not flown to. A takeoff
climbs straight up at the launch point, hidden because the top of the climb is
(visibility only grows with altitude) and exempt from the clearance rule; a
landing first flies level to above its point (a checked leg) and then descends
straight down, hidden for the same reason.
"""

from dataclasses import replace

import numpy as np

from autopilots import profile
from autopilots.mavlink import (
    DO_CHANGE_SPEED,
    FRAME_GLOBAL,
    GLOBAL_FRAMES,
    NAV_LAND,
    NAV_LAST,
    NAV_POSITION_COMMANDS,
    NAV_RETURN_TO_LAUNCH,
    NAV_TAKEOFF,
    NAV_WAYPOINT,
)
from common.errors import InputError
from planner.exposure import is_hidden, segments_clear, segments_hidden, segments_under_ceiling

# Commands whose flight is not a straight leg between mission positions.
UNPROVABLE = {
    NAV_RETURN_TO_LAUNCH: "RETURN_TO_LAUNCH: the autopilot would fly straight home at its RTL "
                          "altitude and may be seen",
    18: "NAV_LOITER_TURNS: its circles are not legs that can be proven hidden",
    82: "NAV_SPLINE_WAYPOINT: its curves are not legs that can be proven hidden",
    177: "DO_JUMP: the legs it adds cannot be proven hidden",
    179: "DO_SET_HOME: a home moved elsewhere is where a failsafe flies, unproven",
    186: "DO_CHANGE_ALTITUDE: a climb or descent that is not a proven leg",
    191: "DO_GO_AROUND: a climb that is not a proven leg",
    192: "DO_REPOSITION: a flight to a point that is not a proven leg",
}
#: NAV commands (MAVLink numbers them up to MAV_CMD_NAV_LAST, 95) whose flight the
#: check proves: a straight leg to their position, or standing still; any other
#: moves the vehicle some way the check does not know (NAV_CONTINUE_AND_CHANGE_ALT,
#: NAV_GUIDED_ENABLE, the VTOL and payload commands, ...) and is refused
PROVEN_NAV = frozenset({NAV_WAYPOINT, 17, 19, NAV_LAND, NAV_TAKEOFF, 31, 80, 93})
#: m/s a DO_CHANGE_SPEED may differ from the plan's speed (float32 rounding)
SPEED_TOLERANCE_MPS = 0.01
#: loiters and the parameter of their radius: a circle is not a proven leg
LOITER_RADIUS_PARAM = {17: "param3", 19: "param3", 31: "param2"}


def check_mission(mission, surface, clearance_m=None) -> None:
    """Raise InputError naming the vehicle and the first bad item or leg."""
    check_items(mission.items, surface, clearance_m, name=mission.name,
                has_home=profile(mission.firmware).home_item)


def check_items(items, surface, clearance_m=None, name="mission", has_home=False,
                speed_mps=None) -> None:
    """`check_mission` for a bare item list (e.g. read from a file)."""
    check_structure(items, name, speed_mps)
    flown = [it for it in items[1 if has_home else 0:] if it.is_position]
    if not flown:
        return
    xyz = _projected(surface, flown)
    a, b, labels = _legs(flown, xyz)
    if flown[0].command == NAV_TAKEOFF:
        if not is_hidden(surface, xyz[:1])[0]:
            raise InputError(name, f"takeoff (item {flown[0].seq}) climbs to "
                                   f"{_where(flown[0])}, which an outpost sees")
        if not segments_under_ceiling(surface, xyz[:1], xyz[:1])[0]:
            raise InputError(name, f"takeoff (item {flown[0].seq}) climbs to "
                                   f"{_where(flown[0])}, more than "
                                   f"{surface.params.ceiling_agl_m:g} m above the terrain "
                                   "(the plan's ceiling_agl_m)")
    if not len(a):
        return
    hidden = segments_hidden(surface, a, b)
    clear = segments_clear(_with_clearance(surface, clearance_m), a, b)
    under = segments_under_ceiling(surface, a, b)
    for n in range(len(a)):
        if not hidden[n]:
            raise InputError(name, f"{labels[n]} is not hidden from the outposts")
        if not clear[n]:
            floor = surface.params.clearance_m if clearance_m is None else clearance_m
            raise InputError(name, f"{labels[n]} passes closer than {floor:g} m to the terrain")
        if not under[n]:
            raise InputError(name, f"{labels[n]} rises more than "
                                   f"{surface.params.ceiling_agl_m:g} m above the terrain "
                                   "(the plan's ceiling_agl_m)")


def check_structure(items, name="mission", speed_mps=None) -> None:
    """Sequence numbers, frames, coordinates and commands, without the terrain;
    with ``speed_mps`` (the plan's), no DO_CHANGE_SPEED to another speed: the plan's
    schedule, and the separation of the fleet kept on it, are timed at that one."""
    for n, it in enumerate(items):
        if int(it.seq) != n:
            raise InputError(name, f"item {n} has sequence number {it.seq}: not contiguous")
        why = UNPROVABLE.get(int(it.command))
        if why:
            raise InputError(name, f"item {n} is {why}")
        if int(it.command) <= NAV_LAST and int(it.command) not in PROVEN_NAV:
            raise InputError(name, f"item {n} is {it.name}: a NAV command whose flight is "
                                   "not a straight leg to a position, which cannot be proven "
                                   "hidden")
        if speed_mps and int(it.command) == DO_CHANGE_SPEED and float(it.param2) > 0 and \
                abs(float(it.param2) - float(speed_mps)) > SPEED_TOLERANCE_MPS:
            raise InputError(name, f"item {n} is DO_CHANGE_SPEED to {float(it.param2):g} m/s, "
                                   f"not the plan's {float(speed_mps):g} m/s: the fleet's "
                                   "schedule and its separation are timed at the plan's speed")
        radius = getattr(it, LOITER_RADIUS_PARAM.get(int(it.command), ""), 0.0)
        if radius:
            raise InputError(name, f"item {n} ({it.name}) loiters on a circle of "
                                   f"{abs(float(radius)):g} m: a circle is not a leg that can "
                                   "be proven hidden (0: at the point)")
    for n, it in enumerate(items):
        if int(it.command) not in NAV_POSITION_COMMANDS:
            continue
        if int(it.frame) not in GLOBAL_FRAMES:
            raise InputError(name, f"item {n} ({it.name}) has frame {it.frame}, not a "
                                   "global position")
        if int(it.frame) not in (FRAME_GLOBAL, 5) and not (n == 0 and it.command == NAV_WAYPOINT):
            raise InputError(name, f"item {n} ({it.name}) has frame {it.frame}: only absolute "
                                   "altitudes (MAV_FRAME_GLOBAL, AMSL) can be proven hidden")
        if not _valid_position(it):
            raise InputError(name, f"item {n} ({it.name}) has an invalid position "
                                   f"lat {it.x!r}, lon {it.y!r}, alt {it.z!r}")


def _valid_position(it) -> bool:
    lat, lon, alt = float(it.x), float(it.y), float(it.z)
    return (np.isfinite([lat, lon, alt]).all() and -90 <= lat <= 90 and -180 <= lon <= 180
            and not (lat == 0 and lon == 0))


def _projected(surface, items) -> np.ndarray:
    lat = np.array([it.x for it in items], float)
    lon = np.array([it.y for it in items], float)
    x, y = surface.terrain.from_lonlat(lon, lat)
    return np.stack([np.asarray(x, float), np.asarray(y, float),
                     np.array([it.z for it in items], float)], axis=1)


def _legs(items, xyz):
    """Straight legs (a, b) as flown, with a label naming each."""
    a, b, labels = [], [], []
    for n in range(1, len(items)):
        start, end = xyz[n - 1], xyz[n].copy()
        if items[n].command == NAV_LAND:
            end[2] = start[2]  # level to above the landing point, then straight down
        a.append(start)
        b.append(end)
        labels.append(f"leg {n} (item {items[n - 1].seq} -> item {items[n].seq}, "
                      f"{_where(items[n - 1])} -> {_where(items[n])})")
    return np.array(a).reshape(-1, 3), np.array(b).reshape(-1, 3), labels


def _where(it) -> str:
    return f"{it.x:.7f},{it.y:.7f} at {it.z:.1f} m"


def _with_clearance(surface, clearance_m):
    if clearance_m is None or clearance_m == surface.params.clearance_m:
        return surface
    return replace(surface, params=replace(surface.params, clearance_m=float(clearance_m)))


# --- the gate: only a checked mission is uploaded -----------------------------------------

_TOKEN = object()


class CheckedMission:
    """A mission that passed the check: the only thing the upload path takes
    (`gcs.mission_protocol.upload` / `upload_verified`).

    Made only by `checked` (legs proven hidden and clear against a surface) or
    `unproven` (structure only, at the user's explicit request); it keeps its own
    copy of the items, so what was proven is what is sent. ``proven`` names what
    the check covered; ``unproven_note`` what it did not (None when everything was).
    """

    __slots__ = ("vehicle_id", "firmware", "name", "_items", "waypoint_of_item", "proven",
                 "unproven_note", "segment", "first_waypoint", "last_waypoint", "final")

    def __init__(self, mission, proven: str, unproven_note, name, _token=None):
        if _token is not _TOKEN:
            raise TypeError("a CheckedMission is made only by missions.check.checked() "
                            "(or unproven())")
        self.vehicle_id = mission.vehicle_id
        self.firmware = mission.firmware
        self.name = name or mission.name
        self._items = tuple(replace(it) for it in mission.items)
        self.waypoint_of_item = list(getattr(mission, "waypoint_of_item", None)
                                     or [None] * len(self._items))
        self.proven = proven
        self.unproven_note = unproven_note
        # which segment of its route it is (`missions.segments`; 0 and final: the whole)
        self.segment = getattr(mission, "segment", 0)
        self.first_waypoint = getattr(mission, "first_waypoint", 0)
        self.last_waypoint = getattr(mission, "last_waypoint", None)
        self.final = getattr(mission, "final", True)

    @property
    def items(self) -> list:
        """Copies of the checked items (changing them changes nothing uploaded)."""
        return [replace(it) for it in self._items]

    def __len__(self) -> int:
        return len(self._items)

    def __repr__(self) -> str:
        return (f"CheckedMission({self.name}, {self.firmware}, {len(self._items)} items, "
                f"{self.proven})")


def checked(mission, surface, clearance_m=None, name=None, speed_mps=None) -> CheckedMission:
    """Prove ``mission`` (a `missions.build.VehicleMission`) hidden and clear
    against ``surface`` (`check_mission`), at the plan's ``speed_mps`` where given;
    InputError naming the item or leg if not."""
    if surface is None:
        raise TypeError("checked() needs the exposure surface to prove the legs against; "
                        "unproven() is the structure-only check")
    check_items(mission.items, surface, clearance_m, name=name or mission.name,
                has_home=profile(mission.firmware).home_item, speed_mps=speed_mps)
    return CheckedMission(mission, "structure and legs (hidden, clear)", None, name, _TOKEN)


def unproven(mission, reason: str, name=None) -> CheckedMission:
    """The structure-only check (`check_structure`: sequence, frames, commands,
    coordinates) for a mission with no terrain and outposts to prove its legs
    against; ``reason`` says why, and the result says what was not proven. Only
    for a user's explicit ``--unchecked``."""
    check_structure(mission.items, name or mission.name)
    note = f"legs not proven hidden from outposts nor clear of the terrain ({reason})"
    return CheckedMission(mission, "structure only", note, name, _TOKEN)
