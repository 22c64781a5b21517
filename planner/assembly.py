"""The `Plan` of a timed fleet: each vehicle's waypoints on the fleet clock, and the metrics.

`make_plan` is the last stage of `planner.pipeline.allocate`: the sorties and
their schedule (`planner.fleet.clock.Fleet`) become the vehicles of plan.json,
each with its waypoints (snapshots, holds, the sortie each is flown on), its
trajectory ground to ground and its sorties, and the plan's metrics: coverage
and mission time, what the k+1 rule achieved, separation, battery, bounds.
"""

from dataclasses import replace
from typing import Optional

import numpy as np

from autopilots import firmware_of
from planner.terrain.dem import VOID_FILL_MARGIN_M
from planner.visibility.unseen import area_summary

from .context import outposts_json
from .coverage.model import achievable, beyond_battery
from .plan import GeoPoint, Plan, VehicleRoute, Waypoint
from .returns import returns


def make_plan(ctx, method, problem, allocation, starts, fleet, counts, timing, bounds):
    """The `Plan`; ``bounds``: (radius bound, best lower bound) of its coverage time."""
    s = ctx.scenario
    # k + 1 (or the re-plan's need), or one per place where fewer places see it; a
    # target only a viewpoint beyond one battery sees still counts as not covered
    places = achievable(replace(problem, endurance_s=np.inf))
    required = np.minimum(problem.needs(), places)
    ranks = list(dict.fromkeys(fleet.sorties[i].uav for i in fleet.schedule.order))
    vehicles = [_vehicle(ctx, r, fleet, starts[r] if starts else None, ranks)
                for r in range(len(allocation.routes))]
    lengths = [v.path_length_m for v in vehicles]
    sched = fleet.schedule
    closest = None if sched.closest is None else \
        (fleet.sorties[sched.closest[0]].uav, fleet.sorties[sched.closest[1]].uav,
         sched.closest[2])
    metrics = {
        "coverage_time_s": fleet.coverage_time_s,
        "mission_time_s": max((v.mission_time_s for v in vehicles), default=0.0),
        "sum_length_m": float(sum(lengths)),
        "targets": int(problem.n_targets),
        "covered": int((counts >= 1).sum()),
        "k": int(s.k),
        "k_covered": int((counts >= required).sum()),
        "snapshots": int(allocation.n_snapshots),
        "k_impossible": int(np.count_nonzero(problem.needs() > places)),
        "min_separation_m": sched.min_separation_m,
        "closest_approach": None if closest is None else
        {"vehicles": [closest[0] + 1, closest[1] + 1], "t_s": closest[2]},
        "wait_s": sched.wait_s,
        "sorties": len(fleet.sorties),
        "battery": _battery_metrics(ctx, problem, fleet, required),
        # what the firmware's own return flies; for SmartRTL, each sortie's buffer
        "returns": returns(vehicles, firmware_of(s.params())),
    }
    if ctx.terrain.meta.get("z_units"):
        metrics["z_units"] = ctx.terrain.meta["z_units"]
    if ctx.terrain.meta.get("filled_at"):
        metrics["filled_voids"] = {"at": ctx.terrain.meta["filled_at"],
                                   "margin_m": VOID_FILL_MARGIN_M}
    if ctx.unseen is not None:
        metrics["area"] = area_summary(ctx.terrain.cell_size, ctx.unseen,
                                       ctx.visibility.target_cells, counts, required)
    metrics["radius_bound_s"], metrics["lower_bound_s"] = bounds
    metrics["ratio_to_lower_bound"] = (metrics["coverage_time_s"] / metrics["lower_bound_s"]
                                       if metrics["lower_bound_s"] > 0 else None)
    timing["total"] = float(sum(timing.values()))
    return Plan(method=method, params=s.params(), crs=ctx.terrain.crs,
                outposts=outposts_json(ctx.outposts),
                vehicles=vehicles, metrics=metrics, timing_s=timing)


def _battery_metrics(ctx, problem, fleet, required) -> dict:
    """What the battery allows and what the sorties take (plan.json ``battery``):
    the viewpoints no base reaches and leaves on one battery (``beyond_battery_at``:
    [lat, lon] of each), and the targets that lose sightings for it."""
    s = ctx.scenario
    longest = max((fleet.flight_s(i) for i in range(len(fleet.sorties))), default=0.0)
    if s.endurance_min is None:
        return {"endurance_min": None, "longest_flight_s": longest}
    problem = replace(problem, endurance_s=s.usable_s)
    far = beyond_battery(problem)
    return {"endurance_min": s.endurance_min, "reserve_pct": s.reserve_pct,
            "usable_s": s.usable_s, "turnaround_min": s.turnaround_min,
            "longest_flight_s": longest, "beyond_battery": int(len(far)),
            "beyond_battery_at": [[round(float(b), 7), round(float(a), 7)] for a, b in
                                  zip(*_lonlat(ctx, ctx.viewpoints.xyz[far]))],
            "targets_short": int(np.count_nonzero(achievable(problem) < required))}


def _vehicle(ctx, r, fleet, start, ranks) -> VehicleRoute:
    """UAV r's route: its waypoints with their fleet-clock times and holds, each
    with its sortie, and its trajectory ground to ground (the turnarounds on the
    ground between its sorties)."""
    launch = None if start is None else _geo(ctx, start.launch)
    flights = fleet.of(r)
    if not flights:
        return VehicleRoute(id=r + 1, launch=launch, waypoints=[], coverage_time_s=0.0,
                            mission_time_s=0.0, path_length_m=0.0)
    waypoints, rows, sorties = [], [], []
    for i in flights:
        f, profile, timing = fleet.sorties[i], fleet.profiles[i], fleet.schedule.timings[i]
        first = profile.route[0]
        arrive, _ = profile.arrivals(timing.start_s, timing.holds)
        snapshot = np.zeros(profile.n, bool)
        snapshot[f.snap + first] = True
        lon, lat = _lonlat(ctx, f.poly)
        first_waypoint = len(waypoints)
        waypoints += [Waypoint(float(a), float(b), float(z), float(ts), bool(p), float(h),
                               f.number)
                      for a, b, z, ts, p, h in zip(lon, lat, f.poly[:, 2], arrive[first:],
                                                   snapshot[first:], timing.holds[first:])]
        trajectory = timing.trajectory
        tlon, tlat = _lonlat(ctx, trajectory.xyz)
        rows += [[round(float(t), 3), float(a), float(b), float(z)]
                 for t, a, b, z in zip(trajectory.t, tlon, tlat, trajectory.xyz[:, 2])]
        sorties.append({"takeoff_s": _leaves(profile, timing), "landing_s": trajectory.end,
                        "flight_s": fleet.flight_s(i), "length_m": _length(f.poly),
                        "waypoints": [first_waypoint, len(waypoints)],
                        "base": _lonlat_alt(_geo(ctx, f.base)),
                        "lands_at": _lonlat_alt(_geo(ctx, f.lands))})
    shots = fleet.snapshot_times(r)
    land = _geo(ctx, fleet.sorties[flights[-1]].lands)
    return VehicleRoute(id=r + 1, launch=launch, waypoints=waypoints,
                        coverage_time_s=float(shots.max()) if len(shots) else 0.0,
                        mission_time_s=sorties[-1]["landing_s"],
                        path_length_m=sum(x["length_m"] for x in sorties),
                        takeoff_s=sorties[0]["takeoff_s"], trajectory=rows,
                        priority=ranks.index(r) + 1,
                        sorties=sorties if len(sorties) > 1 else [],
                        land=land if land != launch else None)


def _geo(ctx, ground) -> Optional[GeoPoint]:
    """A projected ground point (x, y, ground AMSL) as a `GeoPoint`, or None."""
    if ground is None:
        return None
    lon, lat = ctx.terrain.to_lonlat(ground[0], ground[1])
    return GeoPoint(float(lon), float(lat), float(ground[2]))


def _lonlat_alt(point) -> Optional[list]:
    return None if point is None else [point.lon, point.lat, point.alt_amsl]


def _length(poly) -> float:
    d = np.diff(poly, axis=0)
    return float(np.sqrt((d ** 2).sum(axis=1)).sum()) if len(poly) > 1 else 0.0


def _leaves(profile, timing) -> float:
    """When a vehicle leaves its start: the ground, or (in flight) where it holds."""
    return float(timing.start_s + (0.0 if profile.on_ground[0] else timing.holds[0]))


def _lonlat(ctx, xyz):
    """Longitudes and latitudes of projected points, as MAVLink carries them (1e-7°)."""
    if not len(xyz):
        return np.zeros(0), np.zeros(0)
    lon, lat = ctx.terrain.to_lonlat(xyz[:, 0], xyz[:, 1])
    return np.round(np.asarray(lon) * 1e7) / 1e7, np.round(np.asarray(lat) * 1e7) / 1e7
