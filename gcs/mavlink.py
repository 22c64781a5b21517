"""The one place that chooses MAVLink 2 and the ardupilotmega dialect.

pymavlink picks its wire version from the MAVLINK20 environment variable when
`mavutil` is first imported, and its message set from `set_dialect`. Import
`mavutil` and `mavlink` from here (never `pymavlink` directly) so every module
of the ground station speaks the same protocol:

    from gcs.mavlink import mavlink as M, mavutil
"""

import os

os.environ["MAVLINK20"] = "1"      # before pymavlink is imported anywhere

from pymavlink import mavutil  # noqa: E402

mavutil.set_dialect("ardupilotmega")
mavlink = mavutil.mavlink
M = mavlink

GCS_SYSTEM_ID = 255                                   # as QGroundControl / MAVProxy
GCS_COMPONENT_ID = M.MAV_COMP_ID_MISSIONPLANNER       # 190

ARDUPILOT, PX4, GENERIC = "ardupilot", "px4", "generic"

# PX4 packs its main mode in bits 16-23 of custom_mode and its sub mode in 24-31.
_PX4_MAIN = {"MANUAL": 1, "ALTCTL": 2, "POSCTL": 3, "AUTO": 4, "ACRO": 5, "OFFBOARD": 6,
             "STABILIZED": 7, "RATTITUDE": 8}
_PX4_AUTO_SUB = {"READY": 1, "TAKEOFF": 2, "LOITER": 3, "MISSION": 4, "RTL": 5, "LAND": 6,
                 "FOLLOW_TARGET": 8, "PRECLAND": 9}
PX4_MODES = {name: (main, 0) for name, main in _PX4_MAIN.items() if name != "AUTO"}
PX4_MODES.update({f"AUTO.{sub}": (_PX4_MAIN["AUTO"], num) for sub, num in _PX4_AUTO_SUB.items()})


def enum_name(enum: str, value: int) -> str:
    """`enum_name("MAV_RESULT", 4)` -> "MAV_RESULT_FAILED"; unknown values stay readable."""
    entry = M.enums.get(enum, {}).get(int(value))
    return entry.name if entry is not None else f"{enum}({int(value)})"


def result_name(value: int) -> str:
    """A COMMAND_ACK result by name."""
    return enum_name("MAV_RESULT", value)


def mission_result_name(value: int) -> str:
    """A MISSION_ACK result (MAV_MISSION_RESULT) by name."""
    return enum_name("MAV_MISSION_RESULT", value)


def command_name(command: int) -> str:
    return enum_name("MAV_CMD", command)


def flavour_of(autopilot: int) -> str:
    """The firmware flavour behind a HEARTBEAT's autopilot field."""
    if autopilot == M.MAV_AUTOPILOT_ARDUPILOTMEGA:
        return ARDUPILOT
    if autopilot == M.MAV_AUTOPILOT_PX4:
        return PX4
    return GENERIC


def px4_custom_mode(main: int, sub: int = 0) -> int:
    return (int(main) << 16) | (int(sub) << 24)


def ardupilot_modes(mav_type: int = M.MAV_TYPE_QUADROTOR) -> dict:
    """ArduPilot mode name -> custom_mode for this vehicle type (copter by default)."""
    return dict(mavutil.mode_mapping_byname(mav_type)
                or mavutil.mode_mapping_byname(M.MAV_TYPE_QUADROTOR))


def mode_number(flavour: str, name: str, mav_type: int = M.MAV_TYPE_QUADROTOR) -> tuple:
    """(custom_mode, main, sub) of a mode name; raises KeyError naming the choices."""
    name = name.upper()
    if flavour == PX4:
        if name not in PX4_MODES:
            raise KeyError(f"unknown PX4 mode {name!r}; known: {', '.join(sorted(PX4_MODES))}")
        main, sub = PX4_MODES[name]
        return px4_custom_mode(main, sub), main, sub
    modes = ardupilot_modes(mav_type)
    if name not in modes:
        raise KeyError(f"unknown ArduPilot mode {name!r}; known: {', '.join(sorted(modes))}")
    return modes[name], modes[name], 0


def mode_name(flavour: str, custom_mode: int, mav_type: int = M.MAV_TYPE_QUADROTOR) -> str:
    """The name of a HEARTBEAT custom_mode, "MODE(n)" when unknown."""
    custom_mode = int(custom_mode)
    if flavour == PX4:
        main, sub = (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
        for name, (m, s) in PX4_MODES.items():
            if (m, s) == (main, sub):
                return name
        if main == _PX4_MAIN["AUTO"] and sub == 0:
            return "AUTO.LOITER"          # PX4 reports bare AUTO while holding
        return f"MODE({main}.{sub})"
    if flavour == ARDUPILOT:
        for name, number in ardupilot_modes(mav_type).items():
            if number == custom_mode:
                return name
    return f"MODE({custom_mode})"


__all__ = ["ARDUPILOT", "GCS_COMPONENT_ID", "GCS_SYSTEM_ID", "GENERIC", "M", "PX4",
           "PX4_MODES", "ardupilot_modes", "command_name", "enum_name", "flavour_of",
           "mavlink", "mavutil", "mission_result_name", "mode_name", "mode_number",
           "px4_custom_mode", "result_name"]
