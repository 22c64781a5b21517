"""`Autopilot`: what a ground station (and the simulator) must know about one firmware.

A profile is data plus a few methods: where a mission starts (home as item 0 or
not), how modes are named and packed into HEARTBEAT ``custom_mode``, which
modes hold, fly the mission, land or take guided positions, the start sequence
as a list of steps (executed by `gcs.commands.start_mission`), the camera
command written at a snapshot, the yaw written in navigation items, what a
mission read-back keeps, and how many items a vehicle holds.

Numbers are MAVLink's (common.xml); nothing here talks to a vehicle, so
`missions`, `gcs` and the simulator can all import it.
"""

from dataclasses import dataclass

# MAV_FRAME / MAV_CMD numbers used by the profiles (common.xml)
FRAME_GLOBAL = 0
FRAME_MISSION = 2
NAV_LAST = 95                 # MAV_CMD_NAV_LAST: commands below it are navigation
GLOBAL_FRAMES = frozenset({0, 3, 5, 6, 10, 11})
#: MAV_CMD numbers whose x, y, z are a position (waypoint, loiters, land, takeoff, ...)
POSITION_COMMANDS = frozenset({16, 17, 18, 19, 21, 22, 31})


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
    mission_capacity: int | None  # items a vehicle holds by default (None: no limit known)
    hold_mode: str                # where re-tasking holds a vehicle before a new upload
    mission_mode: str             # flies the uploaded mission
    land_mode: str
    rtl_mode: str
    guided_mode: str              # takes position targets (DO_REPOSITION) from the ground
    mission_end_mode: str         # where the autopilot puts itself when a mission ends
    start_sequence: tuple         # of `Step`, after pre-arm readiness
    request_streams: bool         # telemetry must be asked for (REQUEST_DATA_STREAM)
    do_frame_read_back: int | None = None   # DO commands read back in this frame (None: as sent)

    # -- missions -----------------------------------------------------------------
    @property
    def first_item(self) -> int:
        """The first item flown; also the first MISSION_CURRENT / MISSION_ITEM_REACHED
        number of a mission (home is 0 where there is a home item)."""
        return 1 if self.home_item else 0

    def camera_params(self, shot: int) -> tuple:
        """The seven params of the camera command for the ``shot``-th snapshot (from 1)."""
        raise NotImplementedError

    def kept_on_read_back(self, seq: int, command: int, frame: int) -> tuple:
        """(compared, frame_kept): whether item ``seq`` is compared at all after a
        read-back, and whether its frame is (the other fields always are)."""
        if self.home_item and seq == 0:
            return False, False          # home reads back as the real home
        if self.do_frame_read_back is not None and int(command) not in POSITION_COMMANDS \
                and int(frame) not in GLOBAL_FRAMES:
            return True, False           # a DO command comes back in another frame
        return True, True

    # -- modes --------------------------------------------------------------------
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
