"""The time a vehicle loses at a waypoint, and the vertical rates a scenario names.

Each firmware's rates at their defaults are its profile's (`autopilots`:
``profile(name).rates``); a scenario takes them for the rates it does not give
(`planner.scenario`). `waypoint_stop_s` is what passing a waypoint costs,
beyond cruising past it, the way the firmware passes one.
"""

from autopilots import ACCEPT_RADIUS_M, PROFILES, Rates

#: the vertical rates a scenario and plan.json name, each firmware's in its profile
VERTICAL_RATES = ("climb_mps", "descent_mps", "takeoff_mps", "land_mps")
#: each firmware's rates by name, from the profiles (kept for `gcs.sim.vehicle`)
FIRMWARE_RATES = {name: p.rates for name, p in PROFILES.items()}

__all__ = [
    "ACCEPT_RADIUS_M",
    "FIRMWARE_RATES",
    "VERTICAL_RATES",
    "Rates",
    "defaults_text",
    "waypoint_stop_s",
]


def defaults_text(name: str) -> str:
    """Each firmware's default of rate ``name``, for help texts: "ArduPilot 0.5 below
    10 m, PX4 0.7 below 7.5 m"."""
    band = {"takeoff_mps": "takeoff_band_m", "land_mps": "land_band_m"}.get(name)
    out = []
    for p in PROFILES.values():
        below = getattr(p.rates, band) if band else 0.0
        out.append(f"{p.title} {getattr(p.rates, name):g}"
                   + (f" below {below:g} m" if below else ""))
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
