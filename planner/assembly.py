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
from common.errors import InputError
from planner.link import fleet_silences
from planner.terrain.dem import VOID_FILL_MARGIN_M
from planner.visibility.unseen import OUTSIDE, area_summary

from .context import outposts_json
from .coverage.model import achievable, beyond_battery
from .plan import GeoPoint, Plan, VehicleRoute, Waypoint
from .returns import returns
from .shortfall import bases_of, few_reason, shortfall


def make_plan(ctx, method, problem, allocation, starts, fleet, counts, timing, bounds,
              checkins=None):
    """The `Plan`; ``bounds``: (radius bound, best lower bound) of its coverage time;
    ``checkins``: what --max-silence did (`planner.link.checkins.CheckIns`)."""
    s = ctx.scenario
    # k + 1 (or the re-plan's need), or one per place where fewer places see it; a
    # target only a viewpoint beyond one battery sees still counts as not covered
    places = achievable(replace(problem, endurance_s=np.inf))
    required = np.minimum(problem.needs(), places)
    lack = _short_of_battery(ctx, problem, required)
    short = None if lack is None else lack.short
    ranks = list(dict.fromkeys(fleet.sorties[i].uav for i in fleet.schedule.order))
    vehicles = [_vehicle(ctx, r, fleet, starts[r] if starts else None, ranks)
                for r in range(len(allocation.routes))]
    link = _link(ctx, fleet, vehicles, checkins)
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
        "battery": _battery_metrics(ctx, problem, fleet, short),
        # what the firmware's own return flies; for SmartRTL, each sortie's buffer
        "returns": returns(vehicles, firmware_of(s.params())),
    }
    if link is not None:
        metrics["link"] = link
    if ctx.terrain.meta.get("z_units"):
        metrics["z_units"] = ctx.terrain.meta["z_units"]
    if ctx.terrain.meta.get("filled_at"):
        metrics["filled_voids"] = {"at": ctx.terrain.meta["filled_at"],
                                   "margin_m": VOID_FILL_MARGIN_M}
    if ctx.unseen is not None:
        few = [] if lack is None else [
            (few_reason(uavs, bases_of(starts, ctx.terrain.to_lonlat), int(s.k) + 1), mask)
            for uavs, mask in lack.few]
        metrics["area"] = area_summary(ctx.terrain.cell_size, ctx.unseen,
                                       ctx.visibility.target_cells, counts, required, short,
                                       few)
    metrics["radius_bound_s"], metrics["lower_bound_s"] = bounds
    # under a battery the bounds ask of each target only what one battery reaches:
    # they are bounds over that share of the targets, said beside them
    metrics["bound_targets_pct"] = 100.0 if short is None or not len(short) else \
        round(100.0 * (1.0 - np.count_nonzero(short) / len(short)), 2)
    metrics["ratio_to_lower_bound"] = (metrics["coverage_time_s"] / metrics["lower_bound_s"]
                                       if metrics["lower_bound_s"] > 0 else None)
    timing["total"] = float(sum(timing.values()))
    return Plan(method=method, params=s.params(), crs=ctx.terrain.crs,
                outposts=outposts_json(ctx.outposts),
                vehicles=vehicles, metrics=metrics, timing_s=timing)


def _short_of_battery(ctx, problem, required):
    """The targets one battery leaves short of their ``required`` sightings, and
    why (`planner.shortfall.Shortfall`: beyond one battery of any base, or reached
    by too few UAVs); None without a battery."""
    if ctx.scenario.endurance_min is None:
        return None
    return shortfall(problem, ctx.scenario.usable_s, required)


def _battery_metrics(ctx, problem, fleet, short) -> dict:
    """What the battery allows and what the sorties take (plan.json ``battery``):
    the viewpoints no base reaches and leaves on one battery (``beyond_battery_at``:
    [lat, lon] of each), and the targets that lose sightings for it (``short``:
    `_short_of_battery`)."""
    s = ctx.scenario
    longest = max((fleet.flight_s(i) for i in range(len(fleet.sorties))), default=0.0)
    if s.endurance_min is None:
        return {"endurance_min": None, "longest_flight_s": longest}
    problem = replace(problem, endurance_s=s.usable_s)
    far = _telling(ctx, problem, beyond_battery(problem))
    return {"endurance_min": s.endurance_min, "reserve_pct": s.reserve_pct,
            "usable_s": s.usable_s, "turnaround_min": s.turnaround_min,
            "longest_flight_s": longest, "beyond_battery": int(len(far)),
            "beyond_battery_at": [[round(float(b), 7), round(float(a), 7)] for a, b in
                                  zip(*_lonlat(ctx, ctx.viewpoints.xyz[far]))],
            "targets_short": int(np.count_nonzero(short))}


def _telling(ctx, problem, far) -> np.ndarray:
    """Of the viewpoints ``far`` (ids), those that tell the operator something: they
    see a target, and they stand in the area of operations (a map full of far
    points that see nothing, outside the area, said nothing)."""
    indptr = np.asarray(problem.vis_indptr)
    keep = indptr[far + 1] > indptr[far]
    if ctx.unseen is not None:
        r, c = ctx.viewpoints.indices[far].T
        keep &= ctx.unseen[r, c] != OUTSIDE
    return far[keep]


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
        sorties.append({"takeoff_s": fleet.airborne(i)[0], "landing_s": trajectory.end,
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


def _link(ctx, fleet, vehicles, checkins) -> Optional[dict]:
    """Each vehicle's predicted silences (`VehicleRoute.silences`, set here) and the
    metrics of the link: None without an antenna (no --antenna, no --launch); with
    --max-silence, what its check-ins kept of it (``max_silence``; an area planned in
    parts has none: its parts' routes are joined after their travel times are gone)."""
    antennas, radio = ctx.scenario.link()
    if not antennas:
        return None
    per_vehicle = []
    for r, v in enumerate(vehicles):
        if not fleet.of(r):
            continue
        try:
            quiet = fleet_silences(ctx.terrain, antennas, radio, fleet, r)
        except ValueError as exc:
            raise InputError("--antenna", str(exc)) from None
        v.silences = [[round(a, 1), round(b, 1)] for a, b in quiet.windows]
        per_vehicle.append({"vehicle": v.id, "share": round(quiet.share, 4),
                            "silent_s": quiet.silent_s, "longest_s": quiet.longest_s,
                            "airborne_s": quiet.airborne_s})
    airborne = sum(x["airborne_s"] for x in per_vehicle)
    out = {"antennas": [[a.lat, a.lon, a.mast_m] for a in antennas],
           "radio": {"mhz": radio.frequency_mhz, "range_m": radio.range_m,
                     "fresnel": radio.fresnel, "near_m": radio.near_m},
           "share": round(sum(x["silent_s"] for x in per_vehicle) / airborne, 4)
           if airborne else 0.0,
           "longest_s": max((x["longest_s"] for x in per_vehicle), default=0.0),
           "vehicles": per_vehicle}
    if ctx.scenario.max_silence_s is not None:
        out["max_silence"] = _max_silence(ctx, checkins)
    return out


def _max_silence(ctx, checkins) -> dict:
    """plan.json's ``link.max_silence``: `CheckIns.report` and where each vehicle's
    check-ins stand ([lat, lon, alt AMSL])."""
    if checkins is None:
        return {"limit_s": ctx.scenario.max_silence_s, "check_ins": [], "met": False,
                "over_s": [], "not_applied": "planned in parts"}
    at = []
    for checks in checkins.checks:
        xyz = np.array([c.xyz for c in checks], float).reshape(-1, 3)
        lon, lat = _lonlat(ctx, xyz)
        at.append([[float(a), float(b), round(float(z), 2)]
                   for a, b, z in zip(lat, lon, xyz[:, 2])])
    return {**checkins.report(), "at": at}


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


def _lonlat(ctx, xyz):
    """Longitudes and latitudes of projected points, as MAVLink carries them (1e-7°)."""
    if not len(xyz):
        return np.zeros(0), np.zeros(0)
    lon, lat = ctx.terrain.to_lonlat(xyz[:, 0], xyz[:, 1])
    return np.round(np.asarray(lon) * 1e7) / 1e7, np.round(np.asarray(lat) * 1e7) / 1e7
