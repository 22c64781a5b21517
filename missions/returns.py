"""What a firmware's own return reads from the mission files: the mission landing,
and the rally points (issue 60).

- **Rally points** (`rally_points`): the places a firmware's plain return may fly
  to instead of home. Every return that uses them is a climb and a straight line
  to the closest one (the profile's ``rally_returns``: ArduPilot's RTL, PX4's
  Return with RTL_TYPE 0, 1 or 3), and no such return is hidden, whatever the
  point: the failsafe profile never keeps one (SmartRTL and RTL_TYPE 2 / 4 do not
  read them). So the ``.plan`` files carry the fleet's bases as rally points and
  nothing else: a base whose column a mission of the plan climbs or descends in,
  proven with that mission. What QGroundControl then shows, and uploads, are the
  fleet's hidden landing places, and a return that goes to one lands at a base.
  `gcs fly` uploads none: with the failsafes it keeps, no return reads them.
- **The mission landing** (`landing_gaps`): PX4's Return along the mission (RTL_TYPE
  4) flies forward to the mission's landing or reversed to the mission's start,
  then straight home. Both are the proven legs when the mission starts above its
  home: each mission built here from a plan on the ground (`missions.build`:
  NAV_TAKEOFF at its base, NAV_LAND at the base it lands at). One flown from the
  air (a re-task, a segment after the first) is reversed into view, so the builder
  marks its landing's start at its first item (DO_LAND_START): the Return then
  always flies forward. What stays (a segment from the air that does not land
  has nothing to fly forward to) is said, as a known risk of that return.
"""

from autopilots import profile
from autopilots.mavlink import DO_LAND_START, NAV_LAND, NAV_TAKEOFF
from common.geo import distance_m

from .build import ABOVE_LAUNCH_M


def rally_points(plan, missions) -> list:
    """The fleet's bases as rally points: [(lat, lon, ground m AMSL)], each once, in
    the order the routes name them; only a base where one of ``missions`` (built from
    ``plan``) takes off or lands, so that its column is part of that mission's proof."""
    columns = [(it.x, it.y) for m in missions for it in m.items
               if int(it.command) in (NAV_TAKEOFF, NAV_LAND)]
    out = []
    for route in plan.vehicles:
        for part in route.sortie_routes():
            for base in (part.launch, part.landing):
                if base is None or _near(base, out):
                    continue
                if any(distance_m(lat, lon, base.lat, base.lon) <= ABOVE_LAUNCH_M
                       for lat, lon in columns):
                    out.append((base.lat, base.lon, base.alt_amsl))
    return out


def _near(base, points) -> bool:
    return any(distance_m(lat, lon, base.lat, base.lon) <= ABOVE_LAUNCH_M
               for lat, lon, _ in points)


def landing_gaps(mission, home=None) -> list:
    """Where the firmware's return along ``mission`` (a `VehicleMission` or
    `CheckedMission`) would leave the proven legs, in words ([]: nowhere, or a
    firmware whose return does not follow the mission). ``home``: (lat, lon) where
    the vehicle armed, when known; default the mission's takeoff point.

    PX4 (rtl.cpp, RTL_TYPE 4): forward to the landing while the landing's start (the
    first DO_LAND_START, else the first NAV_LAND) is fewer items ahead than the
    current item's number, else reversed to the first position item and from there
    straight home. Along a mission that starts above home both ways are the proven
    legs; along one that starts in the air only the forward way is."""
    autopilot = profile(mission.firmware)
    if not autopilot.landing_return:
        return []
    items = mission.items[1 if autopilot.home_item else 0:]
    flown = [it for it in items if it.is_position]
    if not flown:
        return []
    first = flown[0]
    start = home or ((first.x, first.y) if int(first.command) == NAV_TAKEOFF else None)
    if start is not None and distance_m(first.x, first.y, *start) <= ABOVE_LAUNCH_M:
        return []
    land = next((it.seq for it in flown if int(it.command) == NAV_LAND), None)
    mark = next((it.seq for it in items if int(it.command) == DO_LAND_START), land)
    home_words = f"reversed, it ends with a straight line home from item {first.seq}"
    if land is None:
        return [f"it starts in the air and has no landing: its Return is always {home_words}"]
    if mark <= first.seq:
        return []        # marked at its start: forward to the landing from past item 0
    return [f"it starts in the air: a Return before item {mark // 2 + 1} is {home_words}"]
