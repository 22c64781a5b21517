"""PX4 as a ground station meets it.

- No home item: item 0 is the first flown (the takeoff), and MISSION_CURRENT /
  MISSION_ITEM_REACHED start there. A ``.waypoints`` file still starts with a
  home line 0 (the launch point), as QGroundControl writes and reads them; it is
  dropped on reading (`missions.wpl`), so the takeoff never becomes home.
- Modes: the main mode in bits 16-23 of ``custom_mode``, the sub mode in bits
  24-31 (AUTO.MISSION = main 4, sub 4); MAV_CMD_DO_SET_MODE carries them as
  param2 and param3. A bare AUTO (no sub mode) is reported while holding:
  AUTO.LOITER. Re-tasking holds in AUTO.LOITER; the mission flies in AUTO.MISSION.
- Start: MISSION_START (or the mode AUTO.MISSION where the command is refused),
  then arm: it takes off on its own with the mission's takeoff item.
- Camera: IMAGE_START_CAPTURE, one image (param3 = 1), capture number 1, 2, ...
  (param4). Yaw NaN in navigation items (keep the heading mode).
- Read-back keeps every field as sent (positions come back in
  MAV_FRAME_GLOBAL_INT, the same frame); PX4 SITL holds any number of items, a
  board's dataman 500 with the RAM backend and about 2,000 on the SD card; past
  that MISSION_COUNT gets MAV_MISSION_NO_SPACE without a STATUSTEXT.
- Streams telemetry to its ground-station link by itself; SITL's GCS link sends
  several streams at 50 Hz (of simulated time), which the ground station slows
  to what it reads (MAV_CMD_SET_MESSAGE_INTERVAL).
"""

from dataclasses import dataclass

from .base import Autopilot, Rates, Step
from .failsafe import Failsafe, FailsafeParameter
from .mavlink import IMAGE_START_CAPTURE, MAV_AUTOPILOT_PX4

MAIN = {"MANUAL": 1, "ALTCTL": 2, "POSCTL": 3, "AUTO": 4, "ACRO": 5, "OFFBOARD": 6,
        "STABILIZED": 7, "RATTITUDE": 8}
AUTO_SUB = {"READY": 1, "TAKEOFF": 2, "LOITER": 3, "MISSION": 4, "RTL": 5, "LAND": 6,
            "FOLLOW_TARGET": 8, "PRECLAND": 9}
#: mode name -> (main, sub)
MODES = {name: (main, 0) for name, main in MAIN.items() if name != "AUTO"}
MODES.update({f"AUTO.{sub}": (MAIN["AUTO"], num) for sub, num in AUTO_SUB.items()})


#: what a hidden value still leaves to chance
_LANDS_AWAY = "it lands where it is: hidden (straight down under its proven route), but " \
              "down in the field, away from its base"
#: "Return" as RTL_TYPE 2 or 4 flies it (navigator/rtl.cpp init_rtl_mission_type: the
#: mission forward to its landing, or reversed to home, at the items' altitudes): the
#: path the plan proved; RTL_TYPE is checked as a failsafe of its own
_RETURN = "Return along the mission path (RTL_TYPE)"
_HOLDS_ON = "held by the ground station (Hold: a re-plan, the separation guard) when its " \
            "link is lost, it holds there until its battery failsafe"
_COMMANDER = "src/modules/commander/commander_params.c"

FAILSAFES = (
    Failsafe("low battery", (FailsafeParameter(
        # commander_params.c COM_LOW_BAT_ACT; failsafe/failsafe.cpp
        # fromBatteryWarningActParam: nothing at the low level, the action at the
        # critical (BAT_CRIT_THR) and emergency (BAT_EMERGEN_THR) levels
        "COM_LOW_BAT_ACT", {
            0: "a warning only: it flies on until the pack is empty",
            1: f"{_RETURN} at the critical and the emergency level (deprecated)",
            2: "LAND where it is at the critical level",
            3: f"{_RETURN} at the critical level, LAND where it is at the emergency level"},
        frozenset({0, 1, 2, 3}), 3, f"{_COMMANDER} COM_LOW_BAT_ACT; failsafe/failsafe.cpp",
        risks={0: "it flies on until the pack is empty", 2: _LANDS_AWAY,
               3: "at the emergency level " + _LANDS_AWAY}),)),
    Failsafe("return path", (FailsafeParameter(
        # src/modules/navigator/rtl_params.c RTL_TYPE, rtl.cpp init_rtl_mission_type
        "RTL_TYPE", {
            0: "a climb to RTL_RETURN_ALT and a straight line to home or a rally point",
            1: "a climb to RTL_RETURN_ALT and a straight line to the mission landing or a "
               "rally point",
            2: "the mission path forward to its landing, else reversed to home",
            3: "a straight line to the closest of home, the mission landing or a rally "
               "point",
            4: "the mission path, forward to its landing or reversed to home, whichever "
               "is closer"},
        frozenset({2, 4}), 4, "src/modules/navigator/rtl_params.c RTL_TYPE",
        # rtl_mission_fast(_reverse).cpp on_activation: from the mission it goes on from
        # its current item; from any other mode (a hold) setMissionToClosestItem
        risks={v: "a Return from outside the mission (a hold) first flies straight to the "
                  "mission item closest to it; reversed along a segment flown from the "
                  "air that does not land, it ends with a straight line home "
                  "(rtl_mission_fast_reverse.cpp handleLanding)" for v in (2, 4)}),)),
    Failsafe("ground-station link loss", (
        FailsafeParameter("NAV_DLL_ACT", {
            0: "disabled: it flies on", 1: "Hold where it is", 2: _RETURN,
            3: "LAND where it is", 5: "terminate: motors off, it falls where it is",
            6: "disarm: it falls where it is"},
            frozenset({0, 1, 2, 3}), 2, f"{_COMMANDER} NAV_DLL_ACT",
            # in a mission the exception flies it on; in Hold nothing moves it
            risks={0: _HOLDS_ON, 1: _HOLDS_ON, 3: _LANDS_AWAY}),
        # failsafe/failsafe.cpp: dll_loss_ignored_mission, DatalinkLossExceptionBits
        FailsafeParameter("COM_DLL_EXCEPT", {0: "in a mission it flies the mission on",
                                             1: "in Hold it holds on",
                                             2: "in Offboard it flies on"},
                          frozenset(), 0, f"{_COMMANDER} COM_DLL_EXCEPT", bits=0b1))),
    Failsafe("RC loss", (
        FailsafeParameter("NAV_RCL_ACT", {
            1: "Hold where it is", 2: _RETURN, 3: "LAND where it is",
            5: "terminate: motors off, it falls where it is",
            6: "disarm: it falls where it is"},
            frozenset({1, 2, 3}), 2, f"{_COMMANDER} NAV_RCL_ACT", risks={3: _LANDS_AWAY}),
        FailsafeParameter("COM_RCL_EXCEPT", {0: "in a mission it flies the mission on",
                                             1: "in Hold it holds on",
                                             2: "in Offboard it flies on",
                                             3: "in an external mode it flies on",
                                             4: "in Altitude Cruise it flies on"},
                          frozenset(), 0, f"{_COMMANDER} COM_RCL_EXCEPT", bits=0b1))),
    Failsafe("geofence breach", (FailsafeParameter(
        "GF_ACTION", {0: "none: it flies on", 1: "a warning: it flies on",
                      2: "Hold where it is", 3: _RETURN,
                      4: "terminate: motors off, it falls where it is",
                      5: "LAND where it is"},
        frozenset({0, 1, 2, 3, 5}), 3, "src/modules/navigator/geofence_params.c GF_ACTION",
        risks={5: _LANDS_AWAY}),)),
    Failsafe("low position accuracy", (FailsafeParameter(
        # only with COM_POS_LOW_EPH set (-1, its default, turns it off)
        "COM_POS_LOW_ACT", {0: "none: it flies on", 1: "a warning: it flies on",
                            2: "Hold where it is", 3: _RETURN, 4: "terminate: it falls",
                            5: "LAND where it is"},
        frozenset({5}), 5, f"{_COMMANDER} COM_POS_LOW_ACT, COM_POS_LOW_EPH",
        risks={5: _LANDS_AWAY}, off=(("COM_POS_LOW_EPH", lambda v: v < 0),)),),
        risk="without a good position no path is flown as proven: it lands where it "
             "drifts as it descends"),
)


def custom_mode(main: int, sub: int = 0) -> int:
    """PX4 packs its main mode in bits 16-23 of custom_mode and its sub mode in 24-31."""
    return (int(main) << 16) | (int(sub) << 24)


@dataclass(frozen=True)
class PX4(Autopilot):
    def camera_params(self, shot: int) -> tuple:
        # camera id 0 (all), interval 0, one image, capture sequence number from 1
        return (0.0, 0.0, 1.0, float(shot), 0.0, 0.0, 0.0)

    def modes(self, mav_type: int = 2) -> dict:
        return {name: custom_mode(main, sub) for name, (main, sub) in MODES.items()}

    def mode_number(self, name: str, mav_type: int = 2) -> tuple:
        name = name.upper()
        if name not in MODES:
            raise KeyError(f"unknown PX4 mode {name!r}; known: {', '.join(sorted(MODES))}")
        main, sub = MODES[name]
        return custom_mode(main, sub), main, sub

    def mode_of(self, custom: int, mav_type: int = 2) -> str | None:
        custom = int(custom)
        main, sub = (custom >> 16) & 0xFF, (custom >> 24) & 0xFF
        for name, (m, s) in MODES.items():
            if (m, s) == (main, sub):
                return name
        if main == MAIN["AUTO"] and sub == 0:
            return "AUTO.LOITER"          # PX4 reports bare AUTO while holding
        return None

    def mode_name(self, custom: int, mav_type: int = 2) -> str:
        name = self.mode_of(custom, mav_type)
        if name is not None:
            return name
        return f"MODE({(int(custom) >> 16) & 0xFF}.{(int(custom) >> 24) & 0xFF})"

    def set_mode_params(self, name: str, mav_type: int = 2) -> tuple:
        _, main, sub = self.mode_number(name, mav_type)
        return float(main), float(sub)

    def mode_from_set_mode(self, param2: float, param3: float) -> int:
        return custom_mode(int(param2), int(param3))


PROFILE = PX4(
    name="px4",
    title="PX4",
    mav_autopilot=MAV_AUTOPILOT_PX4,
    home_item=False,
    yaw=float("nan"),
    camera_command=IMAGE_START_CAPTURE,
    mission_capacity=None,
    hold_mode="AUTO.LOITER",
    mission_mode="AUTO.MISSION",
    land_mode="AUTO.LAND",
    rtl_mode="AUTO.RTL",
    guided_mode="AUTO.LOITER",
    mission_end_mode="AUTO.LOITER",
    resume_rewinds=True,    # MissionBase::on_activation, camera triggering: replay
    resume_climbs_above_m=0.8,  # MissionBase::checkClimbRequired, NAV_MC_ALT_RAD's default
    # (defaults 12, 3, 1.5, 1.5, 0.7 m/s: ``rates``)
    rate_limits=(("MPC_XY_VEL_MAX", "speed_mps", 1.0), ("MPC_Z_V_AUTO_UP", "climb_mps", 1.0),
                 ("MPC_Z_V_AUTO_DN", "descent_mps", 1.0), ("MPC_TKO_SPEED", "takeoff_mps", 1.0),
                 ("MPC_LAND_SPEED", "land_mps", 1.0)),
    start_sequence=(Step("set_current"), Step("mission_start", "AUTO.MISSION"), Step("arm"),
                    Step("airborne")),
    request_streams=False,
    # MPC_Z_V_AUTO_UP 3, MPC_Z_V_AUTO_DN 1.5 m/s; FlightTaskAuto: a takeoff climbs at
    # MPC_TKO_SPEED 1.5 m/s below MPC_LAND_ALT1 (10 m); a landing slows from 1.5 m/s
    # at MPC_LAND_ALT1 to MPC_LAND_SPEED 0.7 m/s at MPC_LAND_ALT2 (5 m) and below:
    # 11.9 s from 10 m, taken as 0.7 m/s below 7.5 m (12.4 s: never shorter). A
    # mission's waypoints are flown to a near stop, jerk limited by MPC_JERK_AUTO 4:
    # PX4 v1.17 SITL lost 2-4 s more a waypoint than slowing within NAV_ACC_RAD costs
    rates=Rates(climb_mps=3.0, descent_mps=1.5, takeoff_mps=1.5, takeoff_band_m=10.0,
                land_mps=0.7, land_band_m=7.5, jerk_mps3=4.0),
    capacity_advice="a board keeps missions in its dataman: on the SD card (SYS_DM_BACKEND 0) "
                    "it holds more than in RAM",
    failsafes=FAILSAFES,
    # commander/failsafe/framework.cpp: "Failsafe activated: ..." (most of its failsafe
    # notices travel as events, which gcs does not read)
    failsafe_texts=r"^Failsafe",
    params_bytewise=True,       # src/modules/mavlink/mavlink_main.cpp: ENCODE_BYTEWISE
    # navigator/rtl.cpp: findRtlDestination (safe points) runs for RTL_TYPE 0, 1, 3 only
    rally_returns="Return with RTL_TYPE 0, 1 or 3: a climb and a straight line to the "
                  "closest rally point; RTL_TYPE 2 and 4, the hidden returns, do not "
                  "consider them",
    # mavlink/mavlink_mission.cpp: land_start_index is the first DO_LAND_START, else the
    # first NAV_LAND (land_index); rtl.cpp hasMissionLandStart, reverseIsFurther
    mission_landing="the first NAV_LAND of the mission (or a DO_LAND_START before it): "
                    "RTL_TYPE 4 flies the mission forward to it when it is fewer items "
                    "away than the mission's start, else reversed to the start and home",
    landing_return=True,
    failsafe_modes={"AUTO.RTL": "Return (RTL_TYPE: along the mission path, or a climb "
                                "and a straight line home)",
                    "AUTO.LAND": "LAND where it is", "AUTO.LOITER": "Hold where it is"},
    # GLOBAL_POSITION_INT at the ground station's rate; POSITION_TARGET_LOCAL_NED,
    # LOCAL_POSITION_NED, ATTITUDE, ATTITUDE_QUATERNION, ATTITUDE_TARGET,
    # SERVO_OUTPUT_RAW, RC_CHANNELS, OPTICAL_FLOW_RAD (unread) at 1 Hz
    message_rates=((33, 4.0), (85, 1.0), (32, 1.0), (30, 1.0), (31, 1.0), (83, 1.0),
                   (36, 1.0), (65, 1.0), (106, 1.0)),
)
