"""Where the fleet starts: its launch points, the takeoff above each, its bases.

A launch point must be inside the DEM (`launch_xy`), its cell flyable hidden,
and the column above it must rise to a point a hidden leg joins to the travel
graph (`launch_tops`): each check fails with a one-line error naming the point.
`launch_starts` turns the scenario's launch points into the `Start` of each
UAV; `fleet_bases` lists the bases a sortie may land at.
"""

from dataclasses import dataclass
from typing import Optional

import numpy as np

from common.errors import InputError
from planner.travel import takeoff_time
from planner.visibility import launch_cells

from .context import PlanningContext
from .scenario import Scenario

#: vertices closer than this (m, horizontally and vertically) are one place
SAME_PLACE_M = 0.01


@dataclass
class Start:
    """Where a UAV's route begins: its launch point (on the ground) or a point in the air."""

    xyz: np.ndarray  # projected x, y and altitude AMSL of the first route vertex
    launch: Optional[np.ndarray] = None  # ground point (x, y, ground AMSL) it returns to
    climb_s: float = 0.0  # vertical takeoff time before xyz, counted in the route's time
    held: Optional[np.ndarray] = None  # in flight: where it stands now (it flies to xyz)
    flown_s: float = 0.0  # in flight: what its battery has flown (a sortie model counts it)
    retired: bool = False  # in flight: it flies home and no more sorties (battery not trusted)


def launch_xy(terrain, s: Scenario) -> Optional[np.ndarray]:
    """(n, 2) projected x, y of the scenario's launch points (one per UAV), None
    without any; InputError naming the first outside the DEM."""
    if not s.launch_points:
        return None
    lat = np.array([p[0] for p in s.launch_points])
    lon = np.array([p[1] for p in s.launch_points])
    x, y = terrain.from_lonlat(lon, lat)
    inside = terrain.contains_xy(x, y)
    if not inside.all():
        i = int(np.flatnonzero(~inside)[0])
        swapped = "; as LON,LAT it would be inside: --launch takes LAT,LON" \
            if terrain.swapped_inside(lon[i], lat[i]) else ""
        raise InputError("--launch", f"launch point {lat[i]:.6f},{lon[i]:.6f} is outside the DEM"
                                     + swapped)
    return np.stack([x, y], axis=1)


def launch_tops(graph, launch_xy) -> np.ndarray:
    """(n, 3): the top of the takeoff above each launch point, the highest altitude
    there hidden and clear with the track tolerance, which a hidden leg joins to
    the travel graph. InputError naming the launch point where there is none."""
    tops = []
    for i, (x, y) in enumerate(np.asarray(launch_xy, float).reshape(-1, 2)):
        top = np.array([x, y, graph.column_top(x, y)])
        if not np.isfinite(top[2]):
            why = ("no altitude above it is hidden from the outposts and clear of the "
                   "terrain with the track tolerance")
        elif graph.attach(top) is None:
            why = "no hidden leg joins the takeoff above it to the hidden cells around it"
        else:
            tops.append(top)
            continue
        lon, lat = graph.surface.terrain.to_lonlat(x, y)
        raise InputError("launch", f"launch point {i + 1} ({float(lat):.6f},{float(lon):.6f})"
                                   f": {why}; move it further into the hidden area (see "
                                   "exposure.tif) or lower --track-tolerance")
    return np.array(tops).reshape(-1, 3)


def launch_starts(ctx: PlanningContext) -> Optional[list]:
    """Starts at the scenario's launch points: vertical takeoff to the hidden ceiling."""
    xy = launch_xy(ctx.terrain, ctx.scenario)
    if xy is None:
        return None
    launch_cells(ctx.surface, xy)  # every launch point must be flyable hidden
    starts = []
    for (x, y), top in zip(xy, launch_tops(ctx.graph, xy)):
        ground = np.array([x, y, float(ctx.terrain.ground(x, y, upper=True)[0])])
        climb = takeoff_time(top[2] - ground[2], ctx.travel_params)
        starts.append(Start(top, ground, climb))
    return starts


def takeoff_delays(starts, separation_m: float) -> Optional[np.ndarray]:
    """Per UAV of ``starts`` (one `Start` each), the least time it waits on the ground
    for its base's column on the fleet clock (`planner.fleet.columns`: one airborne
    vehicle in it at a time, and a vehicle is in it all its vertical takeoff): the
    i-th of the UAVs on one base (i = 0, 1, ...) waits i takeoffs, whichever of them
    goes first (they are interchangeable). 0 for a UAV in the air (a re-plan); None
    without starts or without a separation to keep (no columns)."""
    if not starts or separation_m <= 0:
        return None
    delays = np.zeros(len(starts))
    taken = {}
    for r, st in enumerate(starts):
        if st.launch is None or st.held is not None:
            continue
        key = (tuple(np.round(np.asarray(st.launch, float) / SAME_PLACE_M).astype(int)),
               round(st.climb_s / SAME_PLACE_M))
        delays[r] = taken.get(key, 0) * st.climb_s
        taken[key] = taken.get(key, 0) + 1
    return delays


def above_launch(ctx, ground_xyz) -> np.ndarray:
    """The takeoff (and landing approach) point above a launch point (`launch_tops`)."""
    return launch_tops(ctx.graph, np.asarray(ground_xyz, float)[None, :2])[0]


def fleet_bases(ctx, starts) -> np.ndarray:
    """(n_bases, 3) ground points (x, y, ground AMSL) a sortie may land at: with
    ``land_at`` "any", the starts' own bases and the scenario's launch points,
    each once (in that order); with "own", none (each UAV lands at its own)."""
    if ctx.scenario.land_at == "own" or not starts:
        return np.zeros((0, 3))
    xy = launch_xy(ctx.terrain, ctx.scenario)
    points = [st.launch for st in starts if st.launch is not None]
    if xy is not None:
        points += [np.array([x, y, float(ctx.terrain.ground(x, y, upper=True)[0])])
                   for x, y in xy]
    out = []
    for p in points:
        if not any(np.all(np.abs(p - q) <= SAME_PLACE_M) for q in out):
            out.append(np.asarray(p, float))
    return np.array(out).reshape(-1, 3)
