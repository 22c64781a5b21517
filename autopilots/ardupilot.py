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
- Read-back: commands without a position come back in frame 0 whatever frame
  they were sent in; their other fields are kept.
- Capacity: SITL holds 650 items by default (boards with more storage hold more).
- Telemetry streams only what a ground station asks for (REQUEST_DATA_STREAM).
"""

from dataclasses import dataclass

from .base import FRAME_GLOBAL, Autopilot, Step

MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_TYPE_QUADROTOR = 2
DO_DIGICAM_CONTROL = 203


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
    do_frame_read_back=FRAME_GLOBAL,
)
