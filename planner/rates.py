"""The vertical rates each firmware flies a mission by, its parameters at their
defaults: what a plan for it assumes unless the scenario says otherwise.

A firmware climbs and descends between waypoints at its mission rates, and flies
the lowest metres of a takeoff and of a landing slower (`TravelParams`'s bands).
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
    # 11.9 s from 10 m, taken as 0.7 m/s below 7.5 m (12.4 s: never shorter)
    "px4": Rates(climb_mps=3.0, descent_mps=1.5, takeoff_mps=1.5, takeoff_band_m=10.0,
                 land_mps=0.7, land_band_m=7.5),
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
