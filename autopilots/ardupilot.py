"""ArduPilot (ArduCopter) as a ground station meets it.

- Mission item 0 is home: the vehicle overwrites it with the real home and
  reads it back so; item 1 is the first flown, and MISSION_CURRENT /
  MISSION_ITEM_REACHED count home as 0. In a ``.waypoints`` file home is line 0,
  uploaded as item 0.
- Modes are plain numbers in ``custom_mode`` (pymavlink's table per vehicle
  type). Re-tasking holds in GUIDED; the mission flies in AUTO; a finished
  mission leaves the copter in LOITER.
- Start: it refuses to arm in AUTO (unless AUTO_OPTIONS allows), and a copter
  armed on the ground in AUTO waits for MISSION_START, so it takes off in
  GUIDED first (MAV_CMD_NAV_TAKEOFF relative to home), then AUTO and
  MISSION_START. The current item is set first: after a new upload ArduPilot
  resumes at the old index.
- Camera: DO_DIGICAM_CONTROL with param5 = 1 (shoot). Yaw 0 in navigation
  items (ignored: WP_YAW_BEHAVIOR rules).
- Read-back (AP_Mission stores each command in 15 bytes, so it keeps what
  that holds): commands without a position come back in frame 0 whatever frame
  they were sent in, with x, y, z zero unless the command stores them
  (DO_DIGICAM_CONTROL keeps x and y); of params 1-4 only those the command
  stores come back (NAV_WAYPOINT: the hold, in whole seconds; NAV_TAKEOFF:
  param1; NAV_LAND: param1, and param4 as -1 or 1), the rest as 0; altitudes
  in whole centimetres, cut toward zero. As read from ArduPilot 4.7's
  AP_Mission::mission_cmd_to_mavlink_int and checked against its SITL.
- Capacity: SITL holds 650 items counting home (boards: about 700-724 in
  internal storage); a longer upload gets MAV_MISSION_NO_SPACE at once and the
  STATUSTEXT "Only 650 items are supported". BRD_SD_MISSION moves missions to
  the SD card (64 kB: about 4,368 items).
- Telemetry streams only what a ground station asks for (REQUEST_DATA_STREAM).
"""

import math
import struct
from dataclasses import dataclass

from .base import Autopilot, Rates, Step
from .failsafe import Failsafe, FailsafeParameter
from .mavlink import (
    DO_DIGICAM_CONTROL,
    FRAME_GLOBAL,
    MAV_AUTOPILOT_ARDUPILOTMEGA,
    MAV_TYPE_QUADROTOR,
    NAV_POSITION_COMMANDS,
)

#: commands whose x, y, z are kept as a location (AP_Mission::stored_in_location)
IN_LOCATION = NAV_POSITION_COMMANDS | {30, 82, 84, 85, 92, 94, 179, 188, 189, 191, 195, 201}
#: per command, the fields besides the location that a read-back returns, each
#: with the conversion its storage applies (mission_cmd_to_mavlink_int); a
#: command missing here is compared as sent (frame aside)
_int = int
_sign = lambda v: -1.0 if v < 0 else 1.0        # noqa: E731 - NaN is not negative
KEPT = {
    16: {"param1": lambda v: float(min(max(_int(v), 0), 65535))},   # hold, whole s
    19: {"param1": float, "param3": _sign, "param4": float},
    20: {},
    21: {"param1": float, "param4": _sign},
    22: {"param1": float},
    31: {"param2": float, "param4": float},
    82: {"param1": float},
    112: {"param1": float},
    115: {"param1": float, "param2": float, "param3": float, "param4": float},
    177: {"param1": float, "param2": float},
    178: {"param1": lambda v: float(_int(v) & 0xFF), "param2": float, "param3": float},
    183: {"param1": float, "param2": float},
    201: {"param1": float},
    203: {"param1": lambda v: float(_int(v) & 0xFF), "param2": lambda v: float(_int(v) & 0xFF),
          "param3": float, "param4": lambda v: float(_int(v) & 0xFF),
          "x": lambda v: _int(v) & 0xFF, "y": lambda v: _int(v) & 0xFF},   # x, y: wire ints
    206: {"param1": float, "param3": float},
    2000: {"param1": lambda v: float(_int(v) & 0xFF), "param2": float,
           "param3": lambda v: float(_int(v) & 0xFFFF),
           "param4": lambda v: float(_int(v) & 0xFFFF)},
}


@dataclass(frozen=True)
class ArduPilot(Autopilot):
    def camera_params(self, shot: int) -> tuple:
        # session, zoom pos, zoom step, focus lock, shoot = 1, command id, shot id
        return (0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0)

    def modes(self, mav_type: int = MAV_TYPE_QUADROTOR) -> dict:
        from pymavlink import mavutil  # at run time: gcs.mavlink picks the wire version

        return dict(mavutil.mode_mapping_byname(mav_type)
                    or mavutil.mode_mapping_byname(MAV_TYPE_QUADROTOR))

    def mode_number(self, name: str, mav_type: int = MAV_TYPE_QUADROTOR) -> tuple:
        name = name.upper()
        modes = self.modes(mav_type)
        if name not in modes:
            raise KeyError(f"unknown ArduPilot mode {name!r}; known: {', '.join(sorted(modes))}")
        return modes[name], modes[name], 0

    def read_back(self, wire: dict):
        if int(wire["seq"]) == 0:
            return None                  # home reads back as the real home
        command = int(wire["command"])
        kept = KEPT.get(command)
        located = command in IN_LOCATION
        out = dict(wire)
        if kept is None:                 # not modelled: as sent, DO commands in frame 0
            if not located:
                out["frame"] = FRAME_GLOBAL
            return out
        for name in ("param1", "param2", "param3", "param4"):
            out[name] = 0.0
        for name, convert in kept.items():
            value = float(wire[name])
            out[name] = convert(value) if math.isfinite(value) or convert in (float, _sign) \
                else 0.0
        if located:
            # centimetres in an int32: the wire's float32 times 100, cut toward zero
            out["z"] = math.trunc(_float32(_float32(wire["z"]) * 100.0)) / 100.0
        else:
            out["frame"] = FRAME_GLOBAL
            out["x"] = int(out["x"]) if "x" in kept else 0
            out["y"] = int(out["y"]) if "y" in kept else 0
            out["z"] = 0.0
        return out


#: BATT_FS_LOW_ACT and BATT_FS_CRT_ACT (Copter's values for both: Copter::FailsafeAction,
#: ArduCopter/Copter.h; libraries/AP_BattMonitor/AP_BattMonitor_Params.cpp), in words
#: that say where the vehicle would fly. A battery failsafe has no "continue in AUTO"
#: (ArduCopter/events.cpp, handle_battery_failsafe)
_BATTERY_ACTIONS = {
    0: "a warning only: it flies on",
    1: "LAND where it is",
    2: "RTL: a climb to RTL_ALT and a straight line home",
    3: "SmartRTL (its own track back) or, its buffer full, RTL: a climb to RTL_ALT and a "
       "straight line home",
    4: "SmartRTL (its own track back) or, its buffer full, LAND where it is",
    5: "terminate: motors off, it falls where it is",
    6: "the mission's DO_LAND_START (ours have none) or RTL: a climb to RTL_ALT and a "
       "straight line home",
    7: "brake where it is, then LAND",
}
#: what a hidden value still leaves to chance (ArduCopter/events.cpp)
_LANDS_AWAY = "it lands where it is: hidden (straight down under its proven route), but " \
              "down in the field, away from its base"
_SMARTRTL_OR_LAND = "if SmartRTL is unavailable (its buffer full, SRTL_POINTS 0) it lands " \
                    "where it is, away from its base"
_RISKS = {1: _LANDS_AWAY, 4: _SMARTRTL_OR_LAND, 5: _LANDS_AWAY, 7: _LANDS_AWAY}
#: a link loss with no action: in AUTO the mission flies on, but a vehicle the ground
#: station holds (GUIDED, for a re-plan or the separation guard) stays where it is
_HOVERS = "held by the ground station (GUIDED: a re-plan, the separation guard) when " \
          "its link is lost, it hovers there until its battery failsafe"
_BATTERY_SOURCE = "ArduCopter/events.cpp handle_battery_failsafe; AP_BattMonitor_Params.cpp"

FAILSAFES = (
    Failsafe("low battery", (FailsafeParameter(
        "BATT_FS_LOW_ACT", _BATTERY_ACTIONS, frozenset({0, 1, 4, 7}), 4, _BATTERY_SOURCE,
        risks={**_RISKS, 0: "it flies on to the critical level"}),)),
    # the critical level comes after the low one fired: a second SmartRTL would race an
    # empty pack; straight down is hidden (its risk said)
    Failsafe("critical battery", (FailsafeParameter(
        "BATT_FS_CRT_ACT", _BATTERY_ACTIONS, frozenset({0, 1, 4, 7}), 1, _BATTERY_SOURCE,
        risks={**_RISKS, 0: "it flies on until the pack is empty"}),)),
    Failsafe("ground-station link loss", (
        # ArduCopter/Parameters.cpp FS_GCS_ENABLE, ArduCopter/defines.h FS_GCS_ENABLED_*
        FailsafeParameter("FS_GCS_ENABLE", {
            0: "disabled: it flies on",
            1: "RTL: a climb to RTL_ALT and a straight line home",
            2: "RTL (2 was 'continue in AUTO', removed in 4.0: FS_OPTIONS does it)",
            3: "SmartRTL (its own track back) or RTL: a climb to RTL_ALT and a straight "
               "line home",
            4: "SmartRTL (its own track back) or LAND where it is",
            5: "LAND where it is",
            6: "the mission's DO_LAND_START (ours have none) or RTL: a climb to RTL_ALT "
               "and a straight line home",
            7: "brake where it is, then LAND"},
            frozenset({0, 4, 5, 7}), 4,
            "ArduCopter/Parameters.cpp FS_GCS_ENABLE; events.cpp failsafe_gcs_on_event",
            risks={**_RISKS, 0: _HOVERS}),)),
    Failsafe("RC loss", (
        # ArduCopter/Parameters.cpp FS_THR_ENABLE, ArduCopter/defines.h FS_THR_ENABLED_*
        FailsafeParameter("FS_THR_ENABLE", {
            0: "disabled: it flies on",
            1: "RTL: a climb to RTL_ALT and a straight line home",
            2: "RTL (2 was 'continue in AUTO', removed in 4.0: FS_OPTIONS does it)",
            3: "LAND where it is",
            4: "SmartRTL (its own track back) or RTL: a climb to RTL_ALT and a straight "
               "line home",
            5: "SmartRTL (its own track back) or LAND where it is",
            6: "the mission's DO_LAND_START (ours have none) or RTL: a climb to RTL_ALT "
               "and a straight line home",
            7: "brake where it is, then LAND"},
            frozenset({0, 3, 5, 7}), 5,
            "ArduCopter/Parameters.cpp FS_THR_ENABLE; events.cpp failsafe_radio_on_event",
            risks={3: _LANDS_AWAY, 5: _SMARTRTL_OR_LAND, 7: _LANDS_AWAY}),)),
    # a link or RC loss in AUTO changes nothing: the mission flies on, hidden (bits 0
    # and 1 of Copter::FailsafeOption, ArduCopter/Copter.h; events.cpp checks them
    # before the action); a battery failsafe has no such option
    Failsafe("RC or link loss in a mission", (FailsafeParameter(
        "FS_OPTIONS", {0: "an RC loss in AUTO flies the mission on",
                       1: "a link loss in AUTO flies the mission on",
                       2: "an RC loss in GUIDED flies on", 3: "a landing lands on",
                       4: "a link loss in a pilot's mode flies on",
                       5: "releases the gripper"},
        frozenset(), 0, "ArduCopter/Copter.h FailsafeOption; Parameters.cpp FS_OPTIONS",
        bits=0b11),)),
    Failsafe("geofence breach", (FailsafeParameter(
        # libraries/AC_Fence/AC_Fence.cpp ACTION, AC_Fence.h AC_FENCE_ACTION_*
        "FENCE_ACTION", {0: "report only: it flies on",
                         1: "RTL: a climb to RTL_ALT and a straight line home, or LAND",
                         2: "LAND where it is",
                         3: "SmartRTL (its own track back), or RTL: a climb to RTL_ALT "
                            "and a straight line home",
                         4: "brake where it is, then LAND",
                         5: "SmartRTL (its own track back) or LAND where it is"},
        frozenset({0, 2, 4, 5}), 5, "libraries/AC_Fence/AC_Fence.cpp ACTION",
        risks={2: _LANDS_AWAY, 4: _LANDS_AWAY, 5: _SMARTRTL_OR_LAND},
        off=(("FENCE_ENABLE", lambda v: int(v) == 0),)),)),
    Failsafe("EKF (position) failure", (FailsafeParameter(
        # ArduCopter/Parameters.cpp FS_EKF_ACTION, defines.h FS_EKF_ACTION_*
        "FS_EKF_ACTION", {1: "LAND where it is",
                          2: "ALT_HOLD: it holds its height and drifts with the wind",
                          3: "LAND where it is (even in STABILIZE)"},
        frozenset({1, 3}), 1, "ArduCopter/Parameters.cpp FS_EKF_ACTION"),),
        risk="without a position no path is flown as proven: it lands where the wind "
             "takes it as it descends"),
)


@dataclass(frozen=True)
class SmartRTL:
    """ArduPilot's SmartRTL buffer (libraries/AP_SmartRTL/AP_SmartRTL.h, .cpp): it
    keeps the flown path as points no closer than SRTL_ACCURACY metres, simplified
    (Ramer-Douglas-Peucker at half of it) and loop-pruned; with the buffer full for
    15 s (SMARTRTL_TIMEOUT) SmartRTL is deactivated for the flight ("SmartRTL
    deactivated: buffer full") and its failsafes take their fallback."""

    points_param: str = "SRTL_POINTS"
    accuracy_param: str = "SRTL_ACCURACY"
    points: int = 300                 # SMARTRTL_POINTS_DEFAULT
    points_max: int = 500             # SMARTRTL_POINTS_MAX (@Range 0 500)
    accuracy_m: float = 2.0           # SMARTRTL_ACCURACY_DEFAULT


def _float32(value: float) -> float:
    return struct.unpack("f", struct.pack("f", float(value)))[0]


PROFILE = ArduPilot(
    name="ardupilot",
    title="ArduPilot",
    mav_autopilot=MAV_AUTOPILOT_ARDUPILOTMEGA,
    home_item=True,
    yaw=0.0,
    camera_command=DO_DIGICAM_CONTROL,
    mission_capacity=650,
    hold_mode="GUIDED",
    mission_mode="AUTO",
    land_mode="LAND",
    rtl_mode="RTL",
    guided_mode="GUIDED",
    mission_end_mode="LOITER",
    start_sequence=(Step("set_current"), Step("mode", "GUIDED"), Step("arm"),
                    Step("takeoff"), Step("mode", "AUTO"), Step("mission_start")),
    request_streams=True,
    # WPNAV_SPEED_UP 250, WPNAV_SPEED_DN 150 cm/s (NAV_TAKEOFF climbs at the first);
    # NAV_LAND descends at LAND_SPEED 50 cm/s below LAND_ALT_LOW 1000 cm (ArduPilot 4.7)
    rates=Rates(climb_mps=2.5, descent_mps=1.5, takeoff_mps=2.5, takeoff_band_m=0.0,
                land_mps=0.5, land_band_m=10.0),
    capacity_text=r"Only (\d+) items are supported",
    capacity_advice="raise it with the parameter BRD_SD_MISSION (kB of the SD card kept for "
                    "missions: 64 holds about 4,368 items), then reboot",
    failsafes=FAILSAFES,
    # Mode::Number (ArduCopter/mode.h): the modes a failsafe puts it in
    failsafe_modes={"SMART_RTL": "SmartRTL: its own flown track back",
                    "RTL": "RTL: a climb to RTL_ALT and a straight line home",
                    "LAND": "LAND where it is", "BRAKE": "brake where it is"},
    smartrtl=SmartRTL(),
    # Copter::announce_failsafe ("Battery Failsafe - ..."); AP_SmartRTL::deactivate,
    # Copter::set_mode_SmartRTL_or_* ("SmartRTL deactivated: buffer full", "SmartRTL
    # Unavailable, Trying RTL Mode")
    failsafe_texts=r"\bFailsafe\b|^SmartRTL (deactivated|Unavailable)",
    # ArduCopter/mode_rtl.cpp compute_return_target: AP_Rally::calc_best_rally_or_home_
    # location (RALLY_INCL_HOME 1: home when closer); mode_smart_rtl.cpp never reads them
    rally_returns="RTL: a climb to RTL_ALT and a straight line to the closest rally point "
                  "(or home, when closer); SmartRTL, the hidden return, does not use them",
    # AP_Mission::jump_to_landing_sequence: only action 6 (not hidden) jumps to one
    mission_landing="a DO_LAND_START, used only by the failsafe action 6, which flies "
                    "straight to it from where the vehicle is; SmartRTL needs none",
    # the mission's DO_CHANGE_SPEED sets the speed; climbs and descents keep these
    # (defaults 250, 150, 50 cm/s: ``rates``)
    rate_limits=(("WPNAV_SPEED_UP", "climb_mps", 0.01), ("WPNAV_SPEED_DN", "descent_mps", 0.01),
                 ("LAND_SPEED", "land_mps", 0.01)),
)
