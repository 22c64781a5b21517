"""Stage 6, fleet: the routes of one allocation as one fleet on one clock.

The other stages plan each UAV's hidden route; this one makes them a fleet that
can share the sky. Every vehicle's flight, ground to ground, is a trajectory on
the fleet clock (t = 0 when the first takeoff starts), and the fleet is
*separated* when no two airborne vehicles ever come closer than the separation,
proven exactly on those piecewise-linear trajectories, as legs are proven hidden.
Waits keep it so (start delays on the ground, holds at hidden waypoints): they
never touch a proven leg.

Modules: trajectory (`Profile`, a route's path with its times; `Trajectory`, on
the clock), kernels (closest approach of two trajectories, numba), columns (a
base's column, one vehicle in it at a time), schedule (the waits: `schedule`,
`separation`).
"""

from autopilots import PROFILES, firmware_of
from planner.rates import waypoint_stop_s

from .columns import Column, base_columns, first_shared_column, profile_bases
from .schedule import FleetSchedule, Timing, schedule, separation
from .trajectory import Profile, Trajectory, doing_at, route_profile, route_trajectory

__all__ = ["Column", "FleetSchedule", "Profile", "Timing", "Trajectory", "base_columns",
           "doing_at", "prove_separated", "route_profile", "route_trajectory", "schedule",
           "separation", "stop_time"]


def stop_time(params: dict) -> float:
    """What flying through a waypoint costs beyond cruising past it, s
    (`waypoint_stop_s` at the firmware's way of passing one, `Profile.of_route`).
    From a scenario's or a plan's parameters (a plan naming no firmware: the default's,
    `autopilots.firmware_of`; one naming an unknown firmware: no jerk limit)."""
    firmware = PROFILES.get(firmware_of(params))
    return waypoint_stop_s(float(params["speed_mps"]), params.get("accel_mps2") or 0.0,
                           firmware.rates.jerk_mps3 if firmware is not None else None)


def prove_separated(plan, terrain, travel_params, source="plan.json") -> float:
    """The closest approach of two airborne vehicles of a saved plan, from what its
    missions fly (waypoints, holds, takeoff times); InputError naming the two
    vehicles when it is less than the plan's ``separation_m``, or when two are in
    one base's column at once (`columns`)."""
    from common.errors import InputError

    # one trajectory per sortie: a vehicle is on the ground between two
    routes = [s for v in plan.vehicles if v.waypoints for s in v.sortie_routes()]
    stop = stop_time(plan.params)
    profiles = [route_profile(v, terrain, travel_params, stop) for v in routes]
    flights = [route_trajectory(v, terrain, travel_params, stop) for v in routes]
    d, where = separation(flights)
    need = float(plan.params.get("separation_m", 0.0))
    if where is not None and d < need - 1e-6:
        a, b, t = routes[where[0]].id, routes[where[1]].id, where[2]
        raise InputError(source, f"vehicles {a} and {b} come {d:.1f} m apart at t = {t:.0f} s "
                                 f"on the fleet clock, closer than the plan's separation "
                                 f"({need:g} m)")
    shared = first_shared_column(flights, base_columns(profile_bases(profiles), need))
    if shared is not None:
        i, j, _, t = shared
        raise InputError(source, f"vehicles {routes[i].id} and {routes[j].id} are both in "
                                 f"one base's column at t = {t:.0f} s on the fleet clock "
                                 "(one vehicle at a time climbs or descends there): plan "
                                 "it again with this version")
    return d
