"""What differs between the ArduPilot and PX4 flavours of a simulated copter.

Modes are held inside the vehicle by name; a flavour turns names into the
HEARTBEAT custom_mode of its autopilot and back, and says which protocol quirks
apply (home as mission item 0, legacy MISSION_REQUEST, which modes may arm).
"""

from dataclasses import dataclass, field

from pymavlink.dialects.v20 import ardupilotmega as mavlink

# What a mode makes the vehicle do (see vehicle.py).
MANUAL, GUIDED, AUTO, RTL, LAND, TAKEOFF = "manual", "guided", "auto", "rtl", "land", "takeoff"


def px4_custom_mode(main: int, sub: int = 0) -> int:
    """PX4 packs its main mode in bits 16-23 and its sub mode in bits 24-31."""
    return (main << 16) | (sub << 24)


@dataclass(frozen=True)
class Flavour:
    name: str
    autopilot: int
    modes: dict                    # mode name -> custom_mode
    behaviour: dict                # mode name -> MANUAL | GUIDED | AUTO | RTL | LAND | TAKEOFF
    initial_mode: str
    hold_mode: str                 # where a finished mission or a reposition leaves the vehicle
    armable: frozenset             # modes that allow arming (AUTO on ArduPilot: see AUTO_OPTIONS)
    home_item: bool                # mission item 0 is home (ArduPilot)
    legacy_request: bool           # asks for items with MISSION_REQUEST, not _INT (ArduPilot)
    reached_do_items: bool         # MISSION_ITEM_REACHED also for DO commands (PX4)
    resume_old_index: bool         # a new upload keeps the current index (ArduPilot)
    arm_in_auto_starts: bool       # arming in the mission mode takes off at once (PX4)
    deny_result: int               # COMMAND_ACK result of a refused arm
    params: dict = field(default_factory=dict)

    def custom_mode(self, mode: str) -> int:
        return self.modes[mode]

    def mode_named(self, custom_mode: int) -> str | None:
        for name, value in self.modes.items():
            if value == custom_mode:
                return name
        if self.name == "px4" and custom_mode & 0xFF000000 == 0:
            # A main mode without a sub mode: AUTO alone means AUTO.LOITER on PX4.
            main = (custom_mode >> 16) & 0xFF
            return "AUTO.LOITER" if main == 4 else None
        return None

    def mode_from_command(self, param2: float, param3: float) -> str | None:
        """MAV_CMD_DO_SET_MODE: custom mode in param2; PX4 puts its sub mode in param3."""
        if self.name == "px4":
            return self.mode_named(px4_custom_mode(int(param2), int(param3)))
        return self.mode_named(int(param2))


ARDUPILOT = Flavour(
    name="ardupilot",
    autopilot=mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
    modes={"STABILIZE": 0, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6, "LAND": 9},
    behaviour={"STABILIZE": MANUAL, "AUTO": AUTO, "GUIDED": GUIDED, "LOITER": GUIDED,
               "RTL": RTL, "LAND": LAND},
    initial_mode="STABILIZE",
    hold_mode="LOITER",
    armable=frozenset({"STABILIZE", "GUIDED", "LOITER"}),
    home_item=True,
    legacy_request=True,
    reached_do_items=False,
    resume_old_index=True,
    arm_in_auto_starts=False,
    deny_result=mavlink.MAV_RESULT_FAILED,
    params={"AUTO_OPTIONS": 0.0, "WPNAV_RADIUS": 200.0, "RTL_ALT": 1500.0,
            "DISARM_DELAY": 10.0},
)

PX4 = Flavour(
    name="px4",
    autopilot=mavlink.MAV_AUTOPILOT_PX4,
    modes={"MANUAL": px4_custom_mode(1), "POSCTL": px4_custom_mode(3),
           "AUTO.TAKEOFF": px4_custom_mode(4, 2), "AUTO.LOITER": px4_custom_mode(4, 3),
           "AUTO.MISSION": px4_custom_mode(4, 4), "AUTO.RTL": px4_custom_mode(4, 5),
           "AUTO.LAND": px4_custom_mode(4, 6)},
    behaviour={"MANUAL": MANUAL, "POSCTL": MANUAL, "AUTO.TAKEOFF": TAKEOFF,
               "AUTO.LOITER": GUIDED, "AUTO.MISSION": AUTO, "AUTO.RTL": RTL,
               "AUTO.LAND": LAND},
    initial_mode="AUTO.LOITER",
    hold_mode="AUTO.LOITER",
    armable=frozenset({"MANUAL", "POSCTL", "AUTO.TAKEOFF", "AUTO.LOITER", "AUTO.MISSION"}),
    home_item=False,
    legacy_request=False,
    reached_do_items=True,
    resume_old_index=False,
    arm_in_auto_starts=True,
    deny_result=mavlink.MAV_RESULT_DENIED,
    params={"NAV_ACC_RAD": 2.0, "RTL_RETURN_ALT": 15.0, "COM_DISARM_PRFLT": 10.0},
)

FLAVOURS = {"ardupilot": ARDUPILOT, "px4": PX4}
