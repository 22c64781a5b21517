"""What holding a vehicle and flying it on mean, per firmware: the separation
guard's actions (`Holds` is the `gcs.guard.GuardFleet` of a flight).

A hold is the firmware's hold mode where the vehicle is, on its proven leg. Flying
on is its mission mode again from the item it was flying to, with each firmware's
quirks taken care of (PX4 climbs straight up to a higher next item, or goes back
to the item before: `_fly_on`). A vehicle in its base column with only its
landing left may land from where it stands (`lands_here`).
"""

from common.errors import InputError
from common.geo import distance_m
from gcs import commands
from gcs.guard import GuardFleet
from gcs.mission_protocol import MissionError
from gcs.monitor import FLYING, HOLDING
from missions.items import NAV_LAND
from planner.replan import LAUNCH_COLUMN_M

from .state import homebound, next_waypoint


class Holds(GuardFleet):
    """The guard's view of one flight and its actions on the vehicles. ``segments``:
    the flight's `gcs.segments.Segments`; ``short(sysid)``: short of battery
    (`Batteries.short`); ``waiting(sysid)``: held by a re-plan until its time
    (`Departures.waiting_s`)."""

    def __init__(self, state, segments, short, waiting):
        self.state, self.segments = state, segments
        self.short, self.waiting = short, waiting

    @property
    def monitor(self):
        return self.state.monitor

    def airborne(self) -> list:
        return [s for s, v in self.monitor.vehicles.items()
                if v.state in (FLYING, HOLDING) and v.airborne]

    def on_pad(self, sysid) -> bool:
        return self.monitor.on_pad(sysid)

    def hold(self, sysid) -> None:
        self._set_mode(sysid, "hold_mode", HOLDING)

    def resume(self, sysid) -> None:
        """A vehicle the guard held flies on toward the item it was flying to. Where
        the firmware would climb straight up where it holds, that item being higher
        (`resume_climbs_above_m`, PX4), the rest of its route goes up from where it
        holds (`Segments.fly_on_here`). Where it would go back to the item before
        (`resume_rewinds`, PX4), along no proven leg, its current item is moved away
        and back first: then the mission starts again from where it is."""
        link = self.monitor.links[sysid]
        profile, seq = commands.autopilot(link), link.state.mission_seq
        if self._climbs_first(sysid, profile, seq) and self.segments.can_fly_on_here(sysid):
            try:
                return self.segments.fly_on_here(sysid)
            except (MissionError, InputError) as exc:     # its mission stands as it was
                self.monitor.event(sysid, "upload from where it holds failed: flies on as "
                                          "it is", error=str(exc))
        if profile.resume_rewinds and seq is not None and seq > profile.first_item:
            self._set_current(sysid, seq)
        self._set_mode(sysid, "mission_mode", FLYING)

    def lands_here(self, sysid) -> bool:
        """In its base column (within `LAUNCH_COLUMN_M` of it) with nothing left to
        photograph and only the column's top before the landing its mission ends
        with: landing from where it is flies the rest of its route's proven column
        (hidden because its top is), without the climb to the top."""
        m = self.monitor
        v, state = m.vehicles[sysid], m.links[sysid].state
        base = v.route.landing
        if base is None or state.lat is None or not homebound(m, sysid) or \
                self._land_item(sysid) is None:
            return False
        rest = v.route.waypoints[next_waypoint(m, sysid):]
        return all(distance_m(p.lat, p.lon, base.lat, base.lon) <= LAUNCH_COLUMN_M
                   for p in [state, *rest])

    def land(self, sysid) -> None:
        """Its mission flown on from its landing (`lands_here`; a mission changed
        since without one: flown on as it is)."""
        land = self._land_item(sysid)
        if land is None:
            return self.resume(sysid)
        self._set_current(sysid, land)
        self._set_mode(sysid, "mission_mode", FLYING)

    def _set_mode(self, sysid, which, state) -> None:
        link = self.monitor.links[sysid]
        commands.set_mode(link, getattr(commands.autopilot(link), which),
                          retries=self.state.options.protocol_retries)
        self.monitor.set_state(sysid, state)

    def _set_current(self, sysid, seq) -> None:
        """Its mission's current item ``seq``; where the firmware would go back to the
        item before (`resume_rewinds`), moved there and on: then the mission starts
        again from where it is."""
        link = self.monitor.links[sysid]
        rewinds = commands.autopilot(link).resume_rewinds
        for item in (seq - 1, seq) if rewinds else (seq,):
            commands.set_current(link, item, retries=self.state.options.protocol_retries)

    def _land_item(self, sysid):
        """The sequence number of the landing its mission ends with, None without one."""
        mission = self.monitor.vehicles[sysid].mission
        items = mission.items if mission is not None else []
        return items[-1].seq if items and int(items[-1].command) == NAV_LAND else None

    def _climbs_first(self, sysid, profile, seq) -> bool:
        """Whether ``sysid``, its mission flown on now, would first climb straight up
        where it is: its next position item is higher than it by more than the
        firmware allows (`resume_climbs_above_m`)."""
        climb, alt = profile.resume_climbs_above_m, self.monitor.links[sysid].state.alt_amsl
        mission = self.monitor.vehicles[sysid].mission
        if climb is None or seq is None or alt is None or mission is None:
            return False
        ahead = next((it for it in mission.items[seq:] if it.is_position), None)
        return ahead is not None and ahead.z > alt + climb
