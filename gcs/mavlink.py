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

from autopilots import GENERIC_MODES, profile, profile_of_heartbeat  # noqa: E402

mavutil.set_dialect("ardupilotmega")
mavlink = mavutil.mavlink
M = mavlink

GCS_SYSTEM_ID = 255                                   # as QGroundControl / MAVProxy
GCS_COMPONENT_ID = M.MAV_COMP_ID_MISSIONPLANNER       # 190

# What differs between firmwares lives in one profile each (`autopilots`).
GENERIC = "generic"          # the flavour of an autopilot that is neither: no profile


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
    """The firmware flavour behind a HEARTBEAT's autopilot field ("generic": no profile)."""
    found = profile_of_heartbeat(autopilot)
    return found.name if found is not None else GENERIC


def profile_of(flavour: str):
    """The `autopilots` profile of a flavour name; None for "generic"."""
    try:
        return profile(flavour)
    except KeyError:
        return None


def mode_number(flavour: str, name: str, mav_type: int = M.MAV_TYPE_QUADROTOR) -> tuple:
    """(custom_mode, main, sub) of a mode name; raises KeyError naming the choices.
    A generic autopilot is asked in ArduPilot's numbers (plain custom modes)."""
    return (profile_of(flavour) or profile(GENERIC_MODES)).mode_number(name, mav_type)


def mode_name(flavour: str, custom_mode: int, mav_type: int = M.MAV_TYPE_QUADROTOR) -> str:
    """The name of a HEARTBEAT custom_mode, "MODE(n)" when unknown."""
    found = profile_of(flavour)
    return found.mode_name(custom_mode, mav_type) if found is not None \
        else f"MODE({int(custom_mode)})"


__all__ = ["GCS_COMPONENT_ID", "GCS_SYSTEM_ID", "GENERIC", "M",
           "command_name", "enum_name", "flavour_of", "mavlink", "mavutil",
           "mission_result_name", "mode_name", "mode_number", "profile_of", "result_name"]
