"""The vertical rates each firmware flies a mission by, and how it passes a
waypoint, its parameters at their defaults: what a plan for it assumes unless the
scenario says otherwise.

A firmware climbs and descends between waypoints at its mission rates, flies the
lowest metres of a takeoff and of a landing slower (`TravelParams`'s bands), and
loses time at each waypoint (`waypoint_stop_s`).
Read in each firmware's source (ArduPilot 4.7, PX4 1.17); the parameter names
are in `autopilots` (``rate_limits``), where `gcs fly` reads a vehicle's own.
"""

from dataclasses import dataclass


@dataclass(frozen=True)
class Rates:
    climb_mps: float
    descent_mps: float
    takeoff_mps: float          # the lowest ``takeoff_band_m`` of a takeoff
    takeoff_band_m: float
    land_mps: float             # the lowest ``land_band_m`` of a landing
    land_band_m: float
    # how it passes a waypoint (`planner.fleet.stop_time`): None, slowing only to what
    # stops it within the acceptance radius; a jerk (m/s³), to a jerk-limited stop
    jerk_mps3: float | None = None


#: a waypoint counts as reached this close (m): ArduPilot's WPNAV_RADIUS and PX4's
#: NAV_ACC_RAD defaults, and the built-in simulator's
ACCEPT_RADIUS_M = 2.0


#: the vertical rates a scenario and plan.json name, each firmware's in `FIRMWARE_RATES`
VERTICAL_RATES = ("climb_mps", "descent_mps", "takeoff_mps", "land_mps")

FIRMWARE_RATES = {
    # WPNAV_SPEED_UP 250, WPNAV_SPEED_DN 150 cm/s (NAV_TAKEOFF climbs at the first);
    # NAV_LAND descends at LAND_SPEED 50 cm/s below LAND_ALT_LOW 1000 cm
    "ardupilot": Rates(climb_mps=2.5, descent_mps=1.5, takeoff_mps=2.5, takeoff_band_m=0.0,
                       land_mps=0.5, land_band_m=10.0),
    # MPC_Z_V_AUTO_UP 3, MPC_Z_V_AUTO_DN 1.5 m/s; FlightTaskAuto: a takeoff climbs at
    # MPC_TKO_SPEED 1.5 m/s below MPC_LAND_ALT1 (10 m); a landing slows from 1.5 m/s
    # at MPC_LAND_ALT1 to MPC_LAND_SPEED 0.7 m/s at MPC_LAND_ALT2 (5 m) and below:
    # 11.9 s from 10 m, taken as 0.7 m/s below 7.5 m (12.4 s: never shorter). A
    # mission's waypoints are flown to a near stop, jerk limited by MPC_JERK_AUTO 4:
    # PX4 v1.17 SITL lost 2-4 s more a waypoint than slowing within NAV_ACC_RAD costs
    "px4": Rates(climb_mps=3.0, descent_mps=1.5, takeoff_mps=1.5, takeoff_band_m=10.0,
                 land_mps=0.7, land_band_m=7.5, jerk_mps3=4.0),
}


def defaults_text(name: str) -> str:
    """Each firmware's default of rate ``name``, for help texts: "ArduPilot 0.5 below
    10 m, PX4 0.7 below 7.5 m"."""
    band = {"takeoff_mps": "takeoff_band_m", "land_mps": "land_band_m"}.get(name)
    out = []
    for firmware, title in (("ardupilot", "ArduPilot"), ("px4", "PX4")):
        rates = FIRMWARE_RATES[firmware]
        below = getattr(rates, band) if band else 0.0
        out.append(f"{title} {getattr(rates, name):g}" + (f" below {below:g} m" if below else ""))
    return ", ".join(out)


def waypoint_stop_s(speed_mps: float, accel_mps2: float, jerk_mps3=None) -> float:
    """What a waypoint costs at cruise speed v and acceleration a, s. Without a jerk
    (ArduPilot, the simulator's point mass): slowing to what stops it within the
    acceptance radius r, sqrt(2 a r), and speeding up again loses (v - sqrt(2 a r))²
    / (a v). With a jerk j (PX4): a full stop and start, each ramped by the jerk,
    loses v / a + a / j."""
    v, a = speed_mps, accel_mps2
    if a <= 0:
        return 0.0
    if jerk_mps3:
        return v / a + a / jerk_mps3
    slow = min(v, (2.0 * a * ACCEPT_RADIUS_M) ** 0.5)
    return (v - slow) ** 2 / (a * v)
