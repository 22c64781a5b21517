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
from .mavlink import IMAGE_START_CAPTURE, MAV_AUTOPILOT_PX4

MAIN = {"MANUAL": 1, "ALTCTL": 2, "POSCTL": 3, "AUTO": 4, "ACRO": 5, "OFFBOARD": 6,
        "STABILIZED": 7, "RATTITUDE": 8}
AUTO_SUB = {"READY": 1, "TAKEOFF": 2, "LOITER": 3, "MISSION": 4, "RTL": 5, "LAND": 6,
            "FOLLOW_TARGET": 8, "PRECLAND": 9}
#: mode name -> (main, sub)
MODES = {name: (main, 0) for name, main in MAIN.items() if name != "AUTO"}
MODES.update({f"AUTO.{sub}": (MAIN["AUTO"], num) for sub, num in AUTO_SUB.items()})


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
    battery_failsafes=(("COM_LOW_BAT_ACT", {
        0: "a warning only: it flies on",
        2: "LAND where it is",
        3: "RTL at the critical level (a climb to RTL_RETURN_ALT and a straight line "
           "home), LAND at the emergency level",
    }),),
    # GLOBAL_POSITION_INT at the ground station's rate; POSITION_TARGET_LOCAL_NED,
    # LOCAL_POSITION_NED, ATTITUDE, ATTITUDE_QUATERNION, ATTITUDE_TARGET,
    # SERVO_OUTPUT_RAW, RC_CHANNELS, OPTICAL_FLOW_RAD (unread) at 1 Hz
    message_rates=((33, 4.0), (85, 1.0), (32, 1.0), (30, 1.0), (31, 1.0), (83, 1.0),
                   (36, 1.0), (65, 1.0), (106, 1.0)),
)
