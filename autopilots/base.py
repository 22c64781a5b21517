"""`Autopilot`: what a ground station (and the simulator) must know about one firmware.

A profile is data plus a few methods: where a mission starts (home as item 0 or
not), how modes are named and packed into HEARTBEAT ``custom_mode``, which
modes hold, fly the mission, land or take guided positions, the start sequence
as a list of steps (executed by `gcs.commands.start_mission`), the camera
command written at a snapshot, the yaw written in navigation items, what a
mission read-back keeps (`read_back`: an item as the firmware reports it), how
many items a vehicle holds, how it says so, and how that is raised.

Numbers are MAVLink's (common.xml, `autopilots.mavlink`); nothing here talks to
a vehicle, so `planner`, `missions`, `gcs` and the simulator can all import it.
"""

import re
from dataclasses import dataclass, field

#: a waypoint counts as reached this close (m): ArduPilot's WPNAV_RADIUS and PX4's
#: NAV_ACC_RAD defaults, and the built-in simulator's
ACCEPT_RADIUS_M = 2.0


@dataclass(frozen=True)
class Rates:
    """The vertical rates a firmware flies a mission by, and how it passes a
    waypoint, its parameters at their defaults: what a plan for it assumes unless
    the scenario says otherwise (`planner.scenario`, `planner.rates`).

    A firmware climbs and descends between waypoints at its mission rates, flies
    the lowest metres of a takeoff and of a landing slower (the bands), and loses
    time at each waypoint (`planner.rates.waypoint_stop_s`). Where `gcs fly`
    reads a vehicle's own values: `Autopilot.rate_limits`."""

    climb_mps: float
    descent_mps: float
    takeoff_mps: float          # the lowest ``takeoff_band_m`` of a takeoff
    takeoff_band_m: float
    land_mps: float             # the lowest ``land_band_m`` of a landing
    land_band_m: float
    # how it passes a waypoint (`planner.fleet.stop_time`): None, slowing only to what
    # stops it within the acceptance radius; a jerk (m/s³), to a jerk-limited stop
    jerk_mps3: float | None = None


@dataclass(frozen=True)
class Step:
    """One step of a start sequence (see `gcs.commands.start_mission`).

    ``action``: "set_current" (the first mission item), "mode" (switch to
    ``argument``), "arm", "takeoff" (MAV_CMD_NAV_TAKEOFF to the mission's first
    altitude, relative to home, and wait for the climb), "mission_start"
    (MAV_CMD_MISSION_START; if refused, switch to mode ``argument`` when given),
    "airborne" (wait until the vehicle has left the ground)."""

    action: str
    argument: str | None = None


@dataclass(frozen=True)
class Autopilot:
    """One firmware, as a ground station meets it (subclassed per firmware)."""

    name: str                     # "ardupilot" | "px4": --firmware, plan.json, reports
    title: str                    # for people: "ArduPilot", "PX4"
    mav_autopilot: int            # HEARTBEAT.autopilot (MAV_AUTOPILOT); .plan firmwareType
    home_item: bool               # mission item 0 is home: written, overwritten, not flown;
    #                               else a .waypoints file's home line 0 is not uploaded
    yaw: float                    # param4 of takeoff / waypoint / land items
    camera_command: int           # MAV_CMD written after a snapshot waypoint
    mission_capacity: int | None  # items a vehicle holds by default (None: no limit known);
                                  # a ground station learns each vehicle's own (NO_SPACE)
    hold_mode: str                # where re-tasking holds a vehicle before a new upload
    mission_mode: str             # flies the uploaded mission
    land_mode: str
    rtl_mode: str
    guided_mode: str              # takes position targets (DO_REPOSITION) from the ground
    mission_end_mode: str         # where the autopilot puts itself when a mission ends
    start_sequence: tuple         # of `Step`, after pre-arm readiness
    request_streams: bool         # telemetry must be asked for (REQUEST_DATA_STREAM)
    rates: Rates                  # a mission's vertical rates and stops, at their defaults
    #: STATUSTEXT pattern whose group 1 is the capacity, sent with a NO_SPACE refusal
    capacity_text: str | None = None
    #: how a user raises the capacity (said when a mission does not fit)
    capacity_advice: str = ""
    #: (MAVLink message id, Hz) asked with MAV_CMD_SET_MESSAGE_INTERVAL when the
    #: vehicle is found: what the ground station reads at its rate, and the heavy
    #: streams it does not read slowed down (PX4 SITL sends 50 Hz streams)
    message_rates: tuple = ()
    #: every failsafe that can fire in flight (`autopilots.failsafe.Failsafe`): its
    #: parameters, what each value flies, and the values that keep the vehicle hidden
    failsafes: tuple = ()
    #: mode name -> what the vehicle flies in it, for the modes a failsafe puts it in
    failsafe_modes: dict = field(default_factory=dict)
    #: a STATUSTEXT that says a failsafe fired, or its return is gone (a regex)
    failsafe_texts: str | None = None
    #: the SmartRTL buffer (`autopilots.ardupilot.SmartRTL`); None: the firmware's
    #: return is not its own track
    smartrtl: object = None
    #: an integer parameter's bytes travel in PARAM_VALUE's float (PX4); else its value
    #: cast to a float (ArduPilot)
    params_bytewise: bool = False
    #: a held mission, flown on, goes back first to the position item before the one
    #: it was flying to (PX4 re-flies a leg its camera was triggering on), unless its
    #: current item was set since the hold
    resume_rewinds: bool = False
    #: a mission started in the air more than this many metres below its next
    #: position item first climbs straight up where the vehicle is, to that item's
    #: altitude, and then flies level to it; None: it flies the straight leg from
    #: where it is
    resume_climbs_above_m: float | None = None
    #: (parameter, the plan's rate it caps, its unit in m/s): the autopilot's own
    #: limits on a mission's speed, climb and descent; below the plan's, every leg
    #: they cap takes longer than planned
    rate_limits: tuple = ()
    #: which of its returns fly to a rally point, in words (`missions.rally`): each a
    #: straight line to the closest one, never a return the failsafe profile keeps
    rally_returns: str = ""
    #: how it finds a mission's landing, in words; ``landing_return``: its hidden
    #: return needs one (PX4's RTL_TYPE 2 / 4 fly forward only to a mission landing,
    #: else reversed to home), so a mission that flies to a base lands there as its
    #: last position item (`missions.build`)
    mission_landing: str = ""
    landing_return: bool = False

    # -- missions -----------------------------------------------------------------
    @property
    def first_item(self) -> int:
        """The first item flown; also the first MISSION_CURRENT / MISSION_ITEM_REACHED
        number of a mission (home is 0 where there is a home item)."""
        return 1 if self.home_item else 0

    def camera_params(self, shot: int) -> tuple:
        """The seven params of the camera command for the ``shot``-th snapshot (from 1)."""
        raise NotImplementedError

    def read_back(self, wire: dict):
        """A mission item as the firmware reports it when its mission is read back:
        ``wire`` holds MISSION_ITEM_INT's fields as sent (x, y the wire's integers);
        returns them as they come back (the fields it keeps, as it stores them), or
        None for an item that reads back as something else altogether (ArduPilot's
        home). The ground station compares a read-back with this; the simulator
        stores it."""
        if self.home_item and int(wire["seq"]) == 0:
            return None
        return dict(wire)

    def capacity_said(self, text: str) -> int | None:
        """The capacity a STATUSTEXT states (with a NO_SPACE refusal), else None."""
        if not self.capacity_text:
            return None
        found = re.search(self.capacity_text, str(text))
        return int(found.group(1)) if found else None

    # -- modes --------------------------------------------------------------------
    @property
    def commanded_modes(self) -> frozenset:
        """The modes a ground station puts a flying vehicle in (or the autopilot
        itself at a mission's end): in any other (RTL, LAND, a pilot's mode) it
        flies what nobody proved hidden."""
        return frozenset({self.hold_mode, self.mission_mode, self.guided_mode,
                          self.mission_end_mode})

    def modes(self, mav_type: int = 2) -> dict:
        """Mode name -> HEARTBEAT custom_mode for this vehicle type."""
        raise NotImplementedError

    def mode_number(self, name: str, mav_type: int = 2) -> tuple:
        """(custom_mode, main, sub) of a mode name; KeyError naming the choices."""
        raise NotImplementedError

    def mode_of(self, custom_mode: int, mav_type: int = 2) -> str | None:
        """The name of a HEARTBEAT custom_mode; None when unknown."""
        custom_mode = int(custom_mode)
        for name, number in self.modes(mav_type).items():
            if number == custom_mode:
                return name
        return None

    def mode_name(self, custom_mode: int, mav_type: int = 2) -> str:
        """The name of a HEARTBEAT custom_mode, "MODE(n)" when unknown."""
        name = self.mode_of(custom_mode, mav_type)
        return name if name is not None else f"MODE({int(custom_mode)})"

    def set_mode_params(self, name: str, mav_type: int = 2) -> tuple:
        """(param2, param3) of MAV_CMD_DO_SET_MODE for mode ``name`` (param1 is the
        custom-mode flag)."""
        custom, _, _ = self.mode_number(name, mav_type)
        return float(custom), 0.0

    def mode_from_set_mode(self, param2: float, param3: float) -> int:
        """The custom_mode a MAV_CMD_DO_SET_MODE asks for (vehicle side)."""
        return int(param2)
