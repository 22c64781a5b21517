"""The MAVLink numbers the project writes and reads (common.xml), each defined once.

Frames, commands and the HEARTBEAT numbers the profiles, the mission files, the
mission check and the simulator use. Plain numbers, so that nothing here pulls
in pymavlink (the ground station picks its wire version when it starts).
"""

# MAV_FRAME
FRAME_GLOBAL = 0                # x, y latitude, longitude; z metres AMSL
FRAME_MISSION = 2               # a command without a position: x, y are param5, param6
#: frames whose x / y are latitude / longitude
GLOBAL_FRAMES = frozenset({0, 3, 5, 6, 10, 11})
#: frames whose x / y are metres (LOCAL_NED, LOCAL_ENU, LOCAL_OFFSET_NED, BODY_*)
LOCAL_FRAMES = frozenset({1, 4, 7, 8, 9, 12, 20, 21})
#: the deprecated _INT variants of frames mean the same as the plain ones
SAME_FRAME = {5: 0, 6: 3, 11: 10}

# MAV_CMD
NAV_WAYPOINT = 16
NAV_RETURN_TO_LAUNCH = 20
NAV_LAND = 21
NAV_TAKEOFF = 22
NAV_LAST = 95                   # MAV_CMD_NAV_LAST: commands up to it are navigation
DO_CHANGE_SPEED = 178
DO_LAND_START = 189             # marks where a mission's landing begins
DO_DIGICAM_CONTROL = 203        # ArduPilot's camera command
IMAGE_START_CAPTURE = 2000      # PX4's camera command
#: commands whose x, y, z are a place the vehicle flies to (waypoint, loiters, land,
#: takeoff, ...): the legs the mission check proves
NAV_POSITION_COMMANDS = frozenset({NAV_WAYPOINT, 17, 18, 19, NAV_LAND, NAV_TAKEOFF, 31})
#: the names said in messages
COMMAND_NAMES = {
    NAV_WAYPOINT: "NAV_WAYPOINT", NAV_RETURN_TO_LAUNCH: "NAV_RETURN_TO_LAUNCH",
    NAV_LAND: "NAV_LAND", NAV_TAKEOFF: "NAV_TAKEOFF", DO_CHANGE_SPEED: "DO_CHANGE_SPEED",
    DO_DIGICAM_CONTROL: "DO_DIGICAM_CONTROL", IMAGE_START_CAPTURE: "IMAGE_START_CAPTURE",
    DO_LAND_START: "DO_LAND_START",
}

# HEARTBEAT
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_PX4 = 12
MAV_TYPE_QUADROTOR = 2
