"""A vehicle's hidden route becomes its list of MAVLink mission items.

Per vehicle, in order (what differs per firmware comes from its `autopilots`
profile):

- where the firmware keeps home as item 0 (ArduPilot): home, which the
  autopilot overwrites;
- ``NAV_TAKEOFF`` straight up to the first waypoint's altitude, when the route
  starts above its launch point;
- ``DO_CHANGE_SPEED`` to the speed the plan assumed (optional);
- one ``NAV_WAYPOINT`` per vertex of the hidden polyline (``param1`` = the hold
  the fleet's schedule puts there, plus a hover at a snapshot if asked), followed
  at each snapshot by the firmware's camera command:
  ``DO_DIGICAM_CONTROL`` (ArduPilot) or ``IMAGE_START_CAPTURE`` (PX4);
- ``NAV_LAND`` at the base it lands at (its launch point, or for a sortie the
  base it names: `VehicleRoute.landing`), when the route ends above it. Never
  ``RETURN_TO_LAUNCH``: the autopilot would fly straight at its RTL altitude.
- where the firmware's return flies the mission to its landing (PX4,
  ``landing_return``) and the mission lands but does not take off (a re-task or
  a segment flown from the air): ``DO_LAND_START`` first. PX4's Return
  (RTL_TYPE 4) then flies on to the landing from anywhere past the first item,
  never reversed to the mission's start, from where it would fly straight home
  (`missions.returns`).

Positions are absolute (MAV_FRAME_GLOBAL, metres AMSL) like the exposure
surface; commands without a position use MAV_FRAME_MISSION as PX4 requires.
"""

from dataclasses import dataclass, field
from typing import Optional

from autopilots import NAMES, firmware_of, profile
from autopilots.mavlink import (
    DO_CHANGE_SPEED,
    DO_LAND_START,
    FRAME_GLOBAL,
    FRAME_MISSION,
    NAV_LAND,
    NAV_TAKEOFF,
    NAV_WAYPOINT,
)
from common.errors import InputError
from common.geo import distance_m

from .items import MissionItem, renumber

FIRMWARES = NAMES
SPEED_TYPE_GROUND = 1.0  # DO_CHANGE_SPEED param1
NO_THROTTLE_CHANGE = -1.0  # DO_CHANGE_SPEED param3
ABOVE_LAUNCH_M = 1.0  # a waypoint this close (horizontally) to launch is above it


@dataclass(frozen=True)
class MissionOptions:
    camera: bool = True  # trigger the camera at every snapshot waypoint
    hold_s: float = 0.0  # hover this long at a snapshot before triggering (0 = fly through)
    speed_mps: Optional[float] = None  # DO_CHANGE_SPEED to this ground speed; None = no item
    takeoff: bool = True  # NAV_TAKEOFF / NAV_LAND when the route starts / ends above launch
    acceptance_m: float = 0.0  # waypoint acceptance radius, 0 = the autopilot's default


@dataclass
class VehicleMission:
    vehicle_id: int
    firmware: str
    items: list  # [MissionItem], seq 0..n-1
    # per seq: index into route.waypoints of that position item, None otherwise
    waypoint_of_item: list = field(default_factory=list)
    # a segment of a route too long for its vehicle (`missions.segments`): which one
    # (0 = the first, or the whole route), the route waypoints it flies (first and
    # last index), and whether it is the last one (it lands)
    segment: int = 0
    first_waypoint: int = 0
    last_waypoint: int | None = None
    final: bool = True
    sortie: int = 0  # of a route flown on several batteries: which one (1, 2, ...)

    @property
    def name(self) -> str:
        return f"vehicle {self.vehicle_id}" + (f" sortie {self.sortie}" if self.sortie else "")


def vehicle_mission(route, firmware: str, options: MissionOptions = MissionOptions(),
                    fly=None) -> VehicleMission:
    """The mission items that fly ``route`` (a planner.plan.VehicleRoute).

    ``fly``: the indices of the route waypoints to fly (in order; default: all);
    the others are left out, e.g. where `missions.segments.fewer_waypoints`
    proved the straight leg past them (snapshot waypoints are always flown)."""
    fly = list(range(len(route.waypoints))) if fly is None else list(fly)
    return route_items(route, firmware, options, fly, takeoff=True, land=True)


def route_items(route, firmware, options, fly, takeoff=True, land=True, segment=0,
                shots_before=0, skip_camera=(), here=None) -> VehicleMission:
    """The items of route waypoints ``fly`` (indices): the whole route, or one
    segment of it (`missions.segments`). ``takeoff``: it starts the route (a
    takeoff first when it starts above launch); ``land``: it ends the route (the
    landing when it ends above launch: the last segment); ``shots_before``
    snapshots precede it (PX4 numbers its images); no camera command at the
    waypoints in ``skip_camera`` (taken already); ``here``: (lat, lon, alt AMSL),
    a point on the leg into ``fly[0]`` where a vehicle in the air starts it (a
    waypoint of no route index, flown first)."""
    autopilot = firmware_profile(firmware)
    if not route.waypoints:
        raise InputError(f"vehicle {route.id}", "route has no waypoints")
    yaw = autopilot.yaw  # ArduPilot: 0 (ignored); PX4: NaN keeps its heading mode
    out = _Builder()
    waypoints = route.waypoints
    first, last = waypoints[0], waypoints[-1]
    base = route.landing        # its launch point, or the base a sortie lands at
    takes_off = options.takeoff and takeoff and is_above_launch(route.launch, first)
    lands = options.takeoff and land and is_above_launch(base, last)
    if autopilot.home_item:
        home = route.launch or first
        out.add(_position(NAV_WAYPOINT, home.lat, home.lon, home.alt_amsl))
    if lands_from_the_air(autopilot, takes_off, lands):
        out.add(_command(DO_LAND_START))
    if takes_off:
        out.add(_position(NAV_TAKEOFF, route.launch.lat, route.launch.lon, first.alt_amsl,
                          p4=yaw))
    if options.speed_mps:
        out.add(_command(DO_CHANGE_SPEED, SPEED_TYPE_GROUND, float(options.speed_mps),
                         NO_THROTTLE_CHANGE, 0.0))
    if here is not None:
        out.add(_position(NAV_WAYPOINT, *here, p2=float(options.acceptance_m), p4=yaw))
    shots = shots_before
    for index in fly:
        w = waypoints[index]
        # the plan's own wait there (the fleet's schedule), and a hover before the shot
        hold = float(getattr(w, "hold_s", 0.0)) + (float(options.hold_s) if w.snapshot else 0.0)
        out.add(_position(NAV_WAYPOINT, w.lat, w.lon, w.alt_amsl, p1=hold,
                          p2=float(options.acceptance_m), p4=yaw), waypoint=index)
        if w.snapshot and options.camera:
            shots += 1
            if index not in skip_camera:
                out.add(_command(autopilot.camera_command, *autopilot.camera_params(shots)))
    if lands:
        out.add(_position(NAV_LAND, base.lat, base.lon, base.alt_amsl, p4=yaw))
    return VehicleMission(route.id, autopilot.name, renumber(out.items), out.waypoint_of_item,
                          segment=segment, first_waypoint=fly[0] if fly else 0,
                          last_waypoint=fly[-1] if fly else None, final=bool(land))


def lands_from_the_air(autopilot, takes_off: bool, lands: bool) -> bool:
    """Whether a mission starts with ``DO_LAND_START`` (see the module doc): its firmware's
    return flies the mission to its landing, and it lands without taking off first."""
    return bool(autopilot.landing_return and lands and not takes_off)


def firmware_profile(firmware: str):
    """The `autopilots` profile of ``firmware``; InputError naming the choices."""
    try:
        return profile(firmware)
    except KeyError:
        raise InputError("--firmware", f"must be one of {', '.join(FIRMWARES)}, "
                                       f"got {firmware!r}") from None


def plan_missions(plan, firmware: Optional[str] = None, options: Optional[MissionOptions] = None
                  ) -> list:
    """One `VehicleMission` per vehicle of ``plan``, or per sortie of a vehicle that
    flies several (each takes off from its base and lands at the base its sortie
    names: the same, or another of the fleet's; firmware default:
    the plan's; options default: fly the plan's speed, trigger the camera, no hold)."""
    firmware = firmware_of(plan.params, firmware)
    if options is None:
        options = MissionOptions(speed_mps=plan.params.get("speed_mps"))
    return [mission for route in plan.vehicles if route.waypoints
            for mission in sortie_missions(route, firmware, options)]


def sortie_missions(route, firmware, options) -> list:
    """One mission per sortie of ``route`` (the whole route when it flies one)."""
    parts = route.sortie_routes()
    missions = [vehicle_mission(part, firmware, options) for part in parts]
    if len(parts) > 1:
        for j, mission in enumerate(missions, start=1):
            mission.sortie = j
    return missions


class _Builder:
    def __init__(self):
        self.items, self.waypoint_of_item = [], []

    def add(self, item, waypoint=None):
        self.items.append(item)
        self.waypoint_of_item.append(waypoint)


def is_above_launch(launch, w) -> bool:
    """Whether waypoint ``w`` stands over the launch point (within `ABOVE_LAUNCH_M`
    horizontally): the takeoff's top or the landing's approach (`missions.segments`
    asks too)."""
    if launch is None:
        return False
    return distance_m(w.lat, w.lon, launch.lat, launch.lon) <= ABOVE_LAUNCH_M


def _position(command, lat, lon, alt, p1=0.0, p2=0.0, p3=0.0, p4=0.0) -> MissionItem:
    # degE7 is what the wire and the files keep: quantise once, here
    return MissionItem(0, FRAME_GLOBAL, command, 0, 1, p1, p2, p3, p4,
                       round(float(lat) * 1e7) / 1e7, round(float(lon) * 1e7) / 1e7,
                       float(alt))


def _command(command, p1=0.0, p2=0.0, p3=0.0, p4=0.0, p5=0.0, p6=0.0, p7=0.0) -> MissionItem:
    return MissionItem(0, FRAME_MISSION, command, 0, 1, p1, p2, p3, p4, p5, p6, p7)

