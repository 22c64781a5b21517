"""What a simulated vehicle streams: one builder per message, from its state.

Rates are wall-clock periods, so a ground station's loss detection sees real
timing whatever the speedup; the time fields carry mission time, as SITL's do.
"""

import math

from pymavlink.dialects.v20 import ardupilotmega as M

from gcs.sim import flavours as fl
from gcs.sim.battery import CAPACITY_MAH

# Default wall-clock periods of the streams (s); SET_MESSAGE_INTERVAL changes them.
STREAMS = {
    M.MAVLINK_MSG_ID_HEARTBEAT: 1.0, M.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 0.2, M.MAVLINK_MSG_ID_ATTITUDE: 0.2,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: 0.5, M.MAVLINK_MSG_ID_VFR_HUD: 0.5,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 1.0, M.MAVLINK_MSG_ID_MISSION_CURRENT: 1.0,
    M.MAVLINK_MSG_ID_HOME_POSITION: 5.0, M.MAVLINK_MSG_ID_EKF_STATUS_REPORT: 1.0,
    M.MAVLINK_MSG_ID_BATTERY_STATUS: 1.0,
}
INT16_UNKNOWN = 32767
ARDUPILOT_ONLY = frozenset({M.MAVLINK_MSG_ID_EKF_STATUS_REPORT})

SENSORS = (M.MAV_SYS_STATUS_SENSOR_3D_GYRO | M.MAV_SYS_STATUS_SENSOR_3D_ACCEL
           | M.MAV_SYS_STATUS_SENSOR_3D_MAG | M.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
           | M.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | M.MAV_SYS_STATUS_SENSOR_BATTERY)
NAV_SENSORS = M.MAV_SYS_STATUS_SENSOR_GPS | M.MAV_SYS_STATUS_AHRS
EKF_OK = (M.EKF_ATTITUDE | M.EKF_VELOCITY_HORIZ | M.EKF_VELOCITY_VERT | M.EKF_POS_HORIZ_REL
          | M.EKF_POS_HORIZ_ABS | M.EKF_POS_VERT_ABS | M.EKF_PRED_POS_HORIZ_REL
          | M.EKF_PRED_POS_HORIZ_ABS)


def _e7(deg: float) -> int:
    return int(round(deg * 1e7))


def heartbeat(v):
    base = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    if v.armed:
        base |= M.MAV_MODE_FLAG_SAFETY_ARMED
    status = M.MAV_STATE_STANDBY if v.landed else M.MAV_STATE_ACTIVE
    return v.mav.heartbeat_encode(M.MAV_TYPE_QUADROTOR, v.flavour.autopilot, base,
                                  v.flavour.custom_mode(v.mode), status)


def sys_status(v):
    """Sensor health: GPS after half the warm-up, AHRS and pre-arm checks when ready."""
    present = SENSORS | NAV_SENSORS | M.MAV_SYS_STATUS_PREARM_CHECK
    health = SENSORS
    if v.gps_fix:
        health |= M.MAV_SYS_STATUS_SENSOR_GPS
    if v.ready:
        health |= M.MAV_SYS_STATUS_AHRS | M.MAV_SYS_STATUS_PREARM_CHECK
    remaining, millivolts, centiamps = _battery(v)
    return v.mav.sys_status_encode(present, present, health, 200, millivolts, centiamps,
                                   remaining, 0, 0, 0, 0, 0, 0)


def _battery(v) -> tuple:
    """(remaining %, millivolts, centiamps) of the pack: a 4S pack from 16.8 V full
    to 14.0 V empty; 15 A in the air, 0.5 A on the ground."""
    remaining = int(round(v.battery.remaining_pct))
    return remaining, 14000 + 28 * remaining, 50 if v.landed else 1500


def battery_status(v):
    """The pack as BATTERY_STATUS (id 0) reports it: what it holds, what was drawn."""
    remaining, millivolts, centiamps = _battery(v)
    cells = [millivolts // 4] * 4 + [65535] * 6
    drawn_mah = int(round(v.battery.used_fraction * CAPACITY_MAH))
    return v.mav.battery_status_encode(0, M.MAV_BATTERY_FUNCTION_ALL, M.MAV_BATTERY_TYPE_LIPO,
                                       INT16_UNKNOWN, cells, centiamps, drawn_mah, -1, remaining)


def global_position(v):
    lat, lon, alt = v.position()
    east, north, up = v.body.vel
    if not v.has_origin:             # ArduPilot before its EKF origin: zeros
        return v.mav.global_position_int_encode(int(v.t * 1000), 0, 0, 0, 0, 0, 0, 0,
                                                65535)
    return v.mav.global_position_int_encode(
        int(v.t * 1000), _e7(lat), _e7(lon), int(round(alt * 1000)),
        int(round((alt - v.home[2]) * 1000)), int(north * 100), int(east * 100),
        int(-up * 100), int(v.heading * 100))


def attitude(v):
    return v.mav.attitude_encode(int(v.t * 1000), 0.0, 0.0, math.radians(v.heading),
                                 0.0, 0.0, 0.0)


def gps_raw(v):
    lat, lon, alt = v.position()
    fix = M.GPS_FIX_TYPE_3D_FIX if v.gps_fix else M.GPS_FIX_TYPE_NO_FIX
    return v.mav.gps_raw_int_encode(
        int(v.t * 1e6), fix, _e7(lat), _e7(lon), int(round(alt * 1000)), 80, 120,
        int(v.body.speed() * 100), int(v.heading * 100), 12 if v.gps_fix else 0)


def vfr_hud(v):
    speed = math.hypot(v.body.vel[0], v.body.vel[1])
    return v.mav.vfr_hud_encode(speed, speed, int(v.heading), 0 if v.landed else 50,
                                v.body.pos[2], v.body.vel[2])


def extended_sys_state(v):
    kind = v.task["kind"] if v.task else None
    if v.landed:
        state = M.MAV_LANDED_STATE_ON_GROUND
    elif kind == "takeoff":
        state = M.MAV_LANDED_STATE_TAKEOFF
    elif kind == "land":
        state = M.MAV_LANDED_STATE_LANDING
    else:
        state = M.MAV_LANDED_STATE_IN_AIR
    return v.mav.extended_sys_state_encode(M.MAV_VTOL_STATE_UNDEFINED, state)


def mission_current(v):
    total = len(v.mission.items)
    if total <= int(v.flavour.home_item):
        state = M.MISSION_STATE_NO_MISSION
    elif v.behaviour() == fl.AUTO and v.armed:
        state = M.MISSION_STATE_ACTIVE
    else:
        state = M.MISSION_STATE_NOT_STARTED
    return v.mav.mission_current_encode(v.current, total, state)


def home_position(v):
    lat, lon, alt = v.home_geo()
    return v.mav.home_position_encode(_e7(lat), _e7(lon), int(round(alt * 1000)),
                                      0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0,
                                      int(v.t * 1e6))


def ekf_status(v):
    flags = EKF_OK if v.ready else M.EKF_ATTITUDE
    return v.mav.ekf_status_report_encode(flags, 0.02, 0.02, 0.02, 0.02, 0.0)


def autopilot_version(v):
    caps = (M.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT | M.MAV_PROTOCOL_CAPABILITY_MISSION_INT
            | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT | M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
            | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT)
    major, minor = v.flavour.version
    return v.mav.autopilot_version_encode(caps, (major << 24) | (minor << 16), 0, 0, 0,
                                          [0] * 8, [0] * 8, [0] * 8, 0, 0, v.sysid)


BUILDERS = {
    M.MAVLINK_MSG_ID_HEARTBEAT: heartbeat,
    M.MAVLINK_MSG_ID_SYS_STATUS: sys_status,
    M.MAVLINK_MSG_ID_BATTERY_STATUS: battery_status,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: global_position,
    M.MAVLINK_MSG_ID_ATTITUDE: attitude,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: gps_raw,
    M.MAVLINK_MSG_ID_VFR_HUD: vfr_hud,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: extended_sys_state,
    M.MAVLINK_MSG_ID_MISSION_CURRENT: mission_current,
    M.MAVLINK_MSG_ID_HOME_POSITION: home_position,
    M.MAVLINK_MSG_ID_EKF_STATUS_REPORT: ekf_status,
    M.MAVLINK_MSG_ID_AUTOPILOT_VERSION: autopilot_version,
}
