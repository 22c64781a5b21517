"""The whole planning pipeline: Scenario -> PlanningContext -> Plan.

``prepare`` runs the terrain-bound stages once (terrain, exposure, viewpoints,
visibility, travel graph); ``allocate`` runs a coverage method from given
start states and turns the allocation into hidden 3-D routes. Re-planning in
flight calls ``allocate`` again on the same context with the survivors'
positions and what they have already seen.
"""

import math
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import Callable, Optional

import numpy as np

from common.errors import InputError
from planner.exposure import (
    compute_exposure,
    segments_clear,
    segments_hidden,
)
from planner.exposure.outposts import (
    crop_around,
    place_outposts,
    reaching,
    read_outpost_features,
    sample_outpost_features,
)
from planner.terrain import load_dem, sample_terrain
from planner.terrain.area import area_mask, read_area
from planner.terrain.dem import VOID_FILL_MARGIN_M
from planner.travel import build_travel_graph, landing_time, takeoff_time
from planner.visibility import (
    candidate_viewpoints,
    compute_visibility,
    default_spacing,
    fleet_region,
    launch_cells,
)
from planner.visibility.unseen import area_summary, unseen_reasons

from . import coverage, split
from .context import PlanningContext, outposts_json
from .coverage.insertion import walked
from .coverage.metrics import last_needed_sighting
from .coverage.problem import achievable
from .fleet import FleetSchedule, Profile, schedule, stop_time
from .parallel import dask_client
from .plan import GeoPoint, Plan, VehicleRoute, Waypoint
from .scenario import Scenario

#: progress(stage, fraction) — fraction in [0, 1], 1 when the stage is done
Progress = Callable[[str, float], None]


@dataclass
class Start:
    """Where a UAV's route begins: its launch point (on the ground) or a point in the air."""

    xyz: np.ndarray  # projected x, y and altitude AMSL of the first route vertex
    launch: Optional[np.ndarray] = None  # ground point (x, y, ground AMSL) it returns to
    climb_s: float = 0.0  # vertical takeoff time before xyz, counted in the route's time
    held: Optional[np.ndarray] = None  # in flight: where it stands now (it flies to xyz)
    flown_s: float = 0.0  # in flight: what its battery has flown (a sortie model counts it)
    retired: bool = False  # in flight: it flies home and no more sorties (battery not trusted)


@contextmanager
def _stage(name, timing, progress):
    if progress:
        progress(name, 0.0)
    t0 = time.perf_counter()
    yield
    timing[name] = time.perf_counter() - t0
    if progress:
        progress(name, 1.0)


def prepare(scenario: Scenario, progress: Progress = None, terrain=None,
            outposts=None, scheduler="auto", log=None) -> PlanningContext:
    """Run the terrain-bound stages of ``scenario`` (``terrain`` and ``outposts``
    given directly replace the scenario's files, e.g. for synthetic terrain).

    ``scheduler``: where the chunked stages (travel graph, travel times) run:
    "auto" (in this process, or a local dask cluster on a large area), the
    address of a dask scheduler, a ``distributed.Client``, or None (here).
    ``log(text)`` is told which, when it is not this process."""
    s = scenario
    timing = {}
    polygons = read_area(s.area_file) if s.area_file else None   # a bad file fails first
    surface = exposure_stages(s, progress, timing, terrain, outposts)
    terrain, outposts = surface.terrain, surface.outposts
    area, flight = areas(s, terrain, polygons)
    if flight is not None:
        surface = restrict_surface(surface, flight)
    launch_xy = _launch_xy(terrain, s)
    regions = fleet_region(surface, launch_xy)  # every launch point must be flyable
    with dask_client(scheduler, terrain.height.size, log) as client:
        with _stage("travel graph", timing, progress):
            graph = build_travel_graph(surface, s.travel_params(), client=client,
                                       progress=_fraction(progress, "travel graph"))
        with _stage("viewpoints", timing, progress):
            candidates = candidate_viewpoints(surface, s.viewpoint_spacing_m, regions,
                                              s.sensor_range_m)
            tops = None if launch_xy is None else launch_tops(graph, launch_xy)
            viewpoints = candidates.subset(
                graph.reachable(tops)[graph.nodes_of(candidates.xyz)])
            if not len(viewpoints):
                raise InputError("exposure", "no viewpoint can be reached by hidden flight: "
                                 "the hidden region is too thin or too broken up for legs "
                                 "that keep the clearance and the track tolerance (try a "
                                 "larger --area, a lower --clearance or --track-tolerance)")
        with _stage("visibility", timing, progress):
            visibility = compute_visibility(surface, viewpoints, s.sensor_params())
            if area is not None:
                visibility = visibility.restricted(area)
                if not visibility.n_targets:
                    raise InputError(s.area_file or "--area",
                                     "no target inside the area: no viewpoint the fleet "
                                     "reaches sees any cell in it")
            spacing = s.viewpoint_spacing_m or default_spacing(surface, regions,
                                                                s.sensor_range_m)
            unseen = unseen_reasons(surface, viewpoints, visibility, s.sensor_params(),
                                    spacing, area)
        times = None
        if split.n_parts(len(viewpoints), s) == 1:  # parts make their own (`allocate`)
            with _stage("travel times", timing, progress):
                times = graph.time_matrix(viewpoints.xyz, client=client,
                                          progress=_fraction(progress, "travel times"))
    return PlanningContext(s, terrain, list(outposts), surface, regions, viewpoints,
                           visibility, graph, times, timing_s=timing, unseen=unseen)


def exposure_stages(scenario: Scenario, progress: Progress = None, timing=None, terrain=None,
                    outposts=None):
    """The first stages of `prepare`, all `gcs exposure` runs: the terrain and the
    outposts of ``scenario`` (unless given), then their exposure surface."""
    s = scenario
    timing = {} if timing is None else timing
    with _stage("terrain", timing, progress):
        features = None if outposts is not None else outpost_features(s)
        if terrain is None:
            crop = s.area if s.area is None or not features else crop_around(s.area, features)
            terrain = (sample_terrain(resolution=s.resolution_m, area=crop) if s.sample else
                       load_dem(s.dem, area=crop, resolution=s.resolution_m,
                                geoid_offset=s.geoid_offset_m, z_unit=s.z_unit))
            if crop != s.area and not (area_mask(terrain, [box_ring(s.area)])
                                       & terrain.valid).any():
                raise InputError("--area", f"{','.join(f'{v:g}' for v in s.area)} does not "
                                           "overlap the DEM (or holds only nodata there)")
        if outposts is None:
            outposts = place_outposts(features, terrain)
    with _stage("exposure", timing, progress):
        return compute_exposure(terrain, outposts, s.exposure_params(),
                                progress=_fraction(progress, "exposure"))


def outpost_features(s: Scenario) -> list:
    """The scenario's outposts as their file says (`PostFeature`): none with
    ``no_outposts``, the file's, or the built-in ones. With an area of operations,
    those whose range ends short of it are left out, with a warning naming them;
    the others are kept wherever they stand (the DEM is read around them too,
    `crop_around`), since a post outside the area still sees into it."""
    if s.no_outposts:
        return []
    features = read_outpost_features(s.outposts) if s.outposts else sample_outpost_features()
    if s.area is None:
        return features
    kept, dropped = reaching(features, s.area)
    for f, d in dropped:
        warnings.warn(f"{f.source}: {f.label} left out: {d / 1000:.1f} km from the area, "
                      f"beyond its {f.range_m / 1000:g} km range", stacklevel=3)
    for f, d in kept:
        if d > 0:   # the DEM is read wider for it: say why the terrain read grew
            reach = "unlimited range" if math.isinf(f.range_m) else \
                f"{f.range_m / 1000:g} km range"
            warnings.warn(f"{f.source}: {f.label} kept: {d / 1000:.1f} km outside the area, "
                          f"its {reach} reaches into it (the DEM is read around it too)",
                          stacklevel=3)
    return [f for f, _ in kept]


def area_of(s: Scenario, terrain, polygons=None):
    """bool [rows, cols] of the cells inside ``s.area_file``'s polygon; None without one."""
    if not s.area_file:
        return None
    inside = area_mask(terrain, polygons if polygons is not None else read_area(s.area_file))
    if not inside.any():
        raise InputError(s.area_file, "the polygon covers no cell of the terrain (outside the "
                                      "DEM or the --area crop?)")
    return inside


def areas(s: Scenario, terrain, polygons=None) -> tuple:
    """(where targets are, where the fleet may fly): bool [rows, cols] masks, None
    where nothing restricts it. Targets lie inside the ``area`` box (the DEM may be
    read wider, around outposts outside it) and the ``area_file`` polygon; flight
    stays inside the box, and inside the polygon with ``area_flight``."""
    box = area_mask(terrain, [box_ring(s.area)]) if s.area is not None else None
    shape = area_of(s, terrain, polygons)
    return _both(box, shape), _both(box, shape if s.area_flight else None)


def box_ring(area) -> list:
    """The (south, west, north, east) box as an `area_mask` polygon (lon, lat ring)."""
    s, w, n, e = area
    return [np.array([[w, s], [e, s], [e, n], [w, n]], float)]


def _both(a, b):
    """The intersection of two optional masks (None: no restriction)."""
    return b if a is None else a if b is None else a & b


def restrict_surface(surface, inside):
    """The surface with nothing flyable outside ``inside`` (the polygon); what is
    hidden (``lowest_seen``) is unchanged."""
    from dataclasses import replace

    from scipy import ndimage

    flyable = surface.flyable & inside
    regions, _ = ndimage.label(flyable, structure=np.ones((3, 3), bool))
    return replace(surface, exposure=np.where(flyable, surface.exposure, np.nan),
                   flyable=flyable, regions=regions.astype(np.int32))


def _fraction(progress, stage):
    """``progress`` for one stage: called with (done, total) or with a fraction."""
    if progress is None:
        return None
    return lambda done, total=1: progress(stage, done / max(total, 1))


def _launch_xy(terrain, s: Scenario):
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
    xy = _launch_xy(ctx.terrain, ctx.scenario)
    if xy is None:
        return None
    launch_cells(ctx.surface, xy)  # every launch point must be flyable hidden
    starts = []
    for (x, y), top in zip(xy, launch_tops(ctx.graph, xy)):
        ground = np.array([x, y, float(ctx.terrain.ground(x, y, upper=True)[0])])
        climb = takeoff_time(top[2] - ground[2], ctx.travel_params)
        starts.append(Start(top, ground, climb))
    return starts


@dataclass
class Outcome:
    """A plan and what it was made from (for writers, plots and re-planning)."""

    plan: Plan
    problem: coverage.CoverageProblem
    allocation: coverage.Allocation
    polylines: list  # per UAV: (n, 3) projected x, y, alt AMSL
    counts: np.ndarray  # per target: distinct UAVs that see it


def coverage_problem(ctx: PlanningContext, n_uavs: int, starts=None, k=0, visibility="soft",
                     seen=None, required=None, travel=True, visited=None,
                     battery_scale=(1.0, 1.0)) -> coverage.CoverageProblem:
    """The combinatorial problem: visibility sets, viewpoint times, start/return times
    (``travel`` False: without the viewpoint times, for a plan made in parts), and
    with an endurance the sortie model (`_battery`)."""
    vis = ctx.visibility
    out = back = None
    battery = {}
    if starts:
        vp = ctx.viewpoints.xyz
        climb = np.array([s.climb_s for s in starts])[:, None]
        out = ctx.graph.times_between(np.stack([s.xyz for s in starts]), vp) + climb
        if all(s.launch is not None for s in starts):
            tops = np.stack([above_launch(ctx, s.launch) for s in starts])
            ground = np.array([s.launch[2] for s in starts])
            land = landing_time(tops[:, 2] - ground, ctx.travel_params)
            back = ctx.graph.times_between(vp, tops).T + land[:, None]
            if ctx.scenario.endurance_min is not None:
                battery = _battery(ctx, starts, out, tops, land, battery_scale)
    return coverage.CoverageProblem(vis.indptr, vis.indices, vis.n_targets,
                                    ctx.travel if travel else None, out, back, n_uavs, k,
                                    visibility, required, seen, visited=visited, **battery)


def _battery(ctx, starts, out, tops, land, scale=(1.0, 1.0)) -> dict:
    """The sortie model of `coverage.CoverageProblem`: the usable flight time of a
    battery for the split and for the round trips that close a viewpoint (each
    times its ``scale``: `allocate` tightens them where the slowing at waypoints
    outgrows the search's estimate), the turnaround, for a vehicle in flight the
    times out of its base for later sorties, its battery flown, its way home, and
    with several bases to land at, the times out of and back to each."""
    s = ctx.scenario
    model = dict(endurance_s=s.usable_s * scale[0], reach_s=s.usable_s * scale[1],
                 turnaround_s=60.0 * s.turnaround_min,
                 used_s=np.array([st.flown_s for st in starts]))
    held = [r for r, st in enumerate(starts) if st.held is not None]
    for r in held:
        if starts[r].retired:         # a whole battery flown: nothing fits but home
            model["used_s"][r] = max(model["used_s"][r], s.usable_s)
    if held:
        base_out, home = out.copy(), np.zeros(len(starts))
        for r in held:
            climb = takeoff_time(tops[r, 2] - starts[r].launch[2], ctx.travel_params)
            base_out[r] = ctx.graph.times_between(tops[r][None], ctx.viewpoints.xyz)[0] + climb
            if starts[r].retired:     # no later sortie
                base_out[r] = np.inf
            home[r] = starts[r].climb_s + float(
                ctx.graph.times_between(starts[r].xyz[None], tops[r][None])[0, 0]) + land[r]
        model.update(base_out=base_out, start_back=home)
    bases = fleet_bases(ctx, starts)
    if len(bases) > 1:
        top = launch_tops(ctx.graph, bases[:, :2])
        model.update(bases_out=ctx.graph.times_between(top, ctx.viewpoints.xyz)
                     + takeoff_time(top[:, 2] - bases[:, 2], ctx.travel_params)[:, None],
                     bases_back=ctx.graph.times_between(ctx.viewpoints.xyz, top).T
                     + landing_time(top[:, 2] - bases[:, 2], ctx.travel_params)[:, None])
    return model


def fleet_bases(ctx, starts) -> np.ndarray:
    """(n_bases, 3) ground points (x, y, ground AMSL) a sortie may land at: with
    ``land_at`` "any", the starts' own bases and the scenario's launch points,
    each once (in that order); with "own", none (each UAV lands at its own)."""
    if ctx.scenario.land_at == "own" or not starts:
        return np.zeros((0, 3))
    xy = _launch_xy(ctx.terrain, ctx.scenario)
    points = [st.launch for st in starts if st.launch is not None]
    if xy is not None:
        points += [np.array([x, y, float(ctx.terrain.ground(x, y, upper=True)[0])])
                   for x, y in xy]
    out = []
    for p in points:
        if not any(np.all(np.abs(p - q) <= SAME_PLACE_M) for q in out):
            out.append(np.asarray(p, float))
    return np.array(out).reshape(-1, 3)


def above_launch(ctx, ground_xyz) -> np.ndarray:
    """The takeoff (and landing approach) point above a launch point (`launch_tops`)."""
    return launch_tops(ctx.graph, np.asarray(ground_xyz, float)[None, :2])[0]


def allocate(ctx: PlanningContext, n_uavs: int, starts=None, seen=None, required=None,
             method=None, progress: Progress = None, budget_fraction=None,
             strong_bound=True, scheduler=None, log=None, visited=None) -> Outcome:
    """Run the scenario's coverage method from ``starts`` and build hidden routes.

    ``budget_fraction`` caps the search budget (`coverage.CoverageParams`);
    ``strong_bound=False`` reports only the quick lower bounds (re-plans in flight).
    A large area is planned in parts (`planner.split`), as dask tasks on
    ``scheduler`` (see `prepare`) when it names one."""
    s = ctx.scenario
    method = method or s.method
    timing = dict(ctx.timing_s)
    params = coverage.CoverageParams(alpha=s.alpha, beta=s.beta,
                                     step_time_cap=s.step_time_cap_s, seed=s.seed,
                                     time_budget_s=s.time_budget_s,
                                     budget_fraction=budget_fraction)
    parts = split.n_parts(len(ctx.viewpoints), s)
    scale, over = np.ones(2), np.zeros(2)
    in_flight = bool(starts and any(st.held is not None for st in starts))
    for attempt in range(BATTERY_TRIES):
        try:
            problem, allocation, prep, sortie_of = _search(
                ctx, parts, n_uavs, starts, seen, required, method, params, timing, progress,
                scheduler, log, visited, scale)
        except ValueError as exc:
            raise InputError("plan", str(exc)) from None
        with _stage("routes", timing, progress):
            sorties = _routes(ctx, problem, allocation.routes, starts,
                              _fraction(progress, "routes"), sortie_of)
            counts = coverage.coverage_counts(problem, allocation)
        with _stage("separation", timing, progress):
            fleet = fleet_clock(ctx, sorties, starts, problem, allocation.routes)
        # the search's times leave out the slowing at the waypoints: plan again with
        # the sorties (or, where one viewpoint alone is too far, the round trips) that
        # much shorter. In flight, not for the separation's waits: a vehicle held in
        # its base column while another comes home waits whatever its sorties (one
        # held 671 s was planned again in 32 one-viewpoint sorties, 161 min instead
        # of 42); the wait past its battery is reported, and the battery watch guards it
        over = _over_battery(fleet, s.usable_s, starts, waits=not in_flight)
        if not over.any():
            break
        # 2 % of room, then 4, 8 %: a method whose split did not move with the first
        # (C kept a 3-viewpoint sortie 0.3 % over through every 2 % step: its polyline's
        # waypoints cost 12 % more than the search counts)
        scale = np.where(over > 0, scale * (1 - 0.02 * 2 ** attempt) / np.maximum(over, 1.0),
                         scale)
    else:
        # a re-plan in flight is flown all the same (the vehicles are in the air, and
        # gcs fly's battery watch brings one home early); a plan on the ground is not
        if not in_flight:
            raise InputError("plan", f"a sortie takes {max(over) * s.usable_s / 60:.1f} min, "
                                     f"more than the {s.usable_s / 60:.1f} min a battery "
                                     f"allows (endurance {s.endurance_min:g} min less "
                                     f"{s.reserve_pct:g} % reserve), after {BATTERY_TRIES} "
                                     "tries: give a longer --endurance")
    # only the reach bound holds for the whole of an area planned in parts
    bounds = ((split.reach_bound(problem),) * 2 if parts > 1
              else coverage.bounds(problem, strong_bound, prep))
    plan = _make_plan(ctx, method, problem, allocation, starts, fleet, counts, timing, bounds)
    over = _over_battery(fleet, s.usable_s, starts)
    if over.any():
        plan.metrics["battery"]["over_battery"] = float(max(over))
    if parts > 1:
        plan.metrics["parts"] = parts
    return Outcome(plan, problem, allocation, uav_polylines(sorties, n_uavs), counts)


#: plans tried on a smaller battery before a sortie that outgrows it is an error
BATTERY_TRIES = 4


def _search(ctx, parts, n_uavs, starts, seen, required, method, params, timing, progress,
            scheduler, log, visited, scale) -> tuple:
    """(problem, allocation, prepared problem or None for a plan in parts, the
    sortie of each visit per UAV): the coverage method's search, the battery
    ``scale``d (`_battery`)."""
    s = ctx.scenario
    if parts > 1:
        problem, joined = _in_parts(ctx, parts, n_uavs, starts, seen, required, method,
                                    params, timing, progress, scheduler, log, visited, scale)
        return problem, joined.allocation(problem, method), None, joined.sortie_of
    with _stage("allocation", timing, progress):
        problem = coverage_problem(ctx, n_uavs, starts, s.k, s.visibility, seen, required,
                                   visited=visited, battery_scale=scale)
        prep = coverage.prepare(problem)  # once: the bounds below share it
        allocation = coverage.solve(problem, method, params,
                                    progress=(lambda f: progress("allocation", f))
                                    if progress else None, prep=prep)
    return problem, allocation, prep, _sortie_of(prep, allocation.routes)


def _over_battery(fleet, usable_s, starts, waits=True) -> np.ndarray:
    """(sorties of several viewpoints, of one): the longest flight of each kind over
    the usable battery, as a multiple of it (0 where none is over); a vehicle in
    flight has flown part of its first battery already. ``waits``: the holds the
    separation puts on its way counted too."""
    over = np.zeros(2)
    for i, f in enumerate(fleet.sorties):
        if not f.visits and f.first and starts and starts[f.uav].held is not None:
            continue    # in flight with too little battery: home first, whatever it takes
        flown = starts[f.uav].flown_s if starts and f.first else 0.0
        held = 0.0 if waits else float(fleet.schedule.timings[i].holds.sum())
        ratio = (fleet.flight_s(i) - held + flown) / usable_s
        if ratio > 1.0:     # a battery partly flown shares the split's room, not the reach's
            kind = int(len(f.visits) <= 1 and not flown)
            over[kind] = max(over[kind], ratio)
    return over


def _sortie_of(prep, routes) -> list:
    """Per UAV, the sortie of each visit: the greedy split the methods planned with
    (`coverage.insertion.walk`; all 0 with an unlimited battery)."""
    return [walked(np.asarray(route, np.int64), prep.travel, prep.frames[r], prep.sorties[r],
                   prep.has_launch)[1] for r, route in enumerate(routes)]


def _landings(ctx, problem, starts, route, of, r) -> list:
    """The ground point each sortie of UAV r's route lands at (index: the sortie of
    `_sortie_of`): the base nearest its last viewpoint (`coverage.problem.
    landing_bases`) where the fleet's bases are several, else its own; the start's
    flight home without a visit (sortie 0 before a route of later sorties) lands
    at its own."""
    own = starts[r].launch
    n = int(of[-1]) + 1 if len(of) else 1
    if problem.bases_back is None:
        return [own] * n
    bases, at = fleet_bases(ctx, starts), coverage.problem.landing_bases(problem)
    out = [own] * n
    for e, j in zip(route, of):
        out[int(j)] = bases[at[e]]       # the last visit of each sortie decides
    return out


def _in_parts(ctx, parts, n_uavs, starts, seen, required, method, params, timing, progress,
              scheduler, log, visited=None, scale=(1.0, 1.0)):
    """`allocate`'s search for an area planned in ``parts`` parts (`planner.split`):
    the problem of the whole area (without viewpoint times) and the joined routes
    (`split.Joined`); each part splits its routes into sorties on the battery
    ``scale``d as `_battery` says."""
    s = ctx.scenario
    for stage in ("travel times", "allocation"):
        if progress:
            progress(stage, 0.0)
    start = time.perf_counter()
    with dask_client(scheduler, ctx.terrain.height.size, log) as client:
        problem = coverage_problem(ctx, n_uavs, starts, s.k, s.visibility, seen, required,
                                   travel=False, visited=visited, battery_scale=scale)
        pieces = split.make_parts(problem, ctx.viewpoints.xyz[:, :2], parts)
        # one sparse overlay of the whole area: the parts' times go through any viewpoint
        overlay = ctx.viewpoint_overlay(client, _fraction(progress, "travel times"))
        overlay_s = time.perf_counter() - start
        # on a cluster a part's times are made in its task, from the overlay alone
        joined = split.solve_parts(problem, pieces, method, params, lambda ids, on: (
            None if client is not None else ctx.graph.overlay_times(overlay, ids, on)),
            s.speed_mps, client, progress, overlay)
    timing["travel times"] = overlay_s + joined.travel_s
    timing["allocation"] = time.perf_counter() - start - timing["travel times"]
    for stage in ("travel times", "allocation"):
        if progress:
            progress(stage, 1.0)
    if log is not None:
        log(f"planned in {parts} parts of {', '.join(str(len(g)) for g in joined.groups)} "
            f"UAVs; the join dropped {joined.dropped} visits it made redundant")
    return problem, joined


@dataclass
class Sortie:
    """One flight of a UAV's route, takeoff to touchdown (one battery)."""

    uav: int
    number: int          # 1, 2, ... along the route
    visits: list         # viewpoint ids photographed, in order
    poly: np.ndarray     # its hidden polyline (projected x, y, alt AMSL), rounded and proven
    snap: np.ndarray     # the polyline vertex of each visit
    first: bool          # the route's first: from its start (the others from a base)
    base: Optional[np.ndarray] = None   # ground point it takes off from (x, y, ground AMSL)
    lands: Optional[np.ndarray] = None  # ground point it lands at (None: no base)


def _sortie_points(ctx, route, start, of, lands) -> list:
    """[(visits, points, base, lands)] per sortie of one route: each from its start
    (the first) or the point above the base the one before landed at, through its
    viewpoints, to the point above the base it lands at (``lands``: per sortie,
    `_landings`). ``of``: the sortie of each visit (0: the flight under way at the
    start; a vehicle in flight whose battery cannot take it to its first viewpoint
    flies home first, a sortie without visits)."""
    vp = ctx.viewpoints.xyz
    if start is None:
        return [(list(route), vp[list(route)], None, None)]
    out, base = [], start.launch
    for j in range(int(of[-1]) + 1 if len(of) else 1):
        visits = [e for e, o in zip(route, of) if o == j]
        if not visits and j > 0:
            continue
        p = [start.xyz if j == 0 else above_launch(ctx, base)] + [vp[e] for e in visits]
        if lands[j] is not None:
            p.append(above_launch(ctx, lands[j]))
        out.append((visits, np.array(p, float).reshape(-1, 3), base, lands[j]))
        base = lands[j]
    return out


def _routes(ctx, problem, routes, starts, progress=None, sortie_of=None) -> list:
    """The `Sortie`s of every route: hidden polylines through its viewpoints, one
    per battery (``sortie_of[r]``: the sortie of each visit; default one flight).

    Waypoints are rounded as MAVLink carries them (1e-7 degrees, float32
    altitudes) and every leg is proven again, rounded, by the same tests the
    mission check runs (`planner.exposure.segments_hidden`, `segments_clear`)."""
    wanted = []
    for r, route in enumerate(routes):
        start = starts[r] if starts else None
        if route or start is not None:    # a UAV without viewpoints takes off and lands
            of = np.zeros(len(route), int) if sortie_of is None else sortie_of[r]
            lands = None if start is None else _landings(ctx, problem, starts, route, of, r)
            wanted += [(r, *w) for w in _sortie_points(ctx, route, start, of, lands)]
    found = ctx.graph.route_polylines([w[2] for w in wanted],
                                      (lambda f: progress(0.8 * f)) if progress else None)
    sorties, number = [], {}
    for n, ((r, visits, _, base, lands), got) in enumerate(zip(wanted, found)):
        if got is None:
            raise InputError("plan", f"UAV {r + 1}: two of its viewpoints are not joined by a "
                                     "hidden path (a defect: the planner only pairs reachable "
                                     "viewpoints)")
        poly, stops = got
        poly, stops = _fewest_vertices(ctx, _rounded_for_mavlink(ctx, poly), stops)
        _prove(ctx, r, poly)
        if progress is not None:
            progress(0.8 + 0.2 * (n + 1) / len(wanted))
        number[r] = number.get(r, 0) + 1
        snap = stops[1:len(visits) + 1] if starts else stops[:len(visits)]
        sorties.append(Sortie(r, number[r], visits, poly, np.asarray(snap, np.int64),
                              number[r] == 1, base, lands))
    return sorties


def uav_polylines(sorties, n_uavs) -> list:
    """Per UAV, its sorties' polylines one after the other (for maps and checks)."""
    out = [[] for _ in range(n_uavs)]
    for f in sorties:
        out[f.uav].append(f.poly)
    return [np.vstack(p) if p else np.zeros((0, 3)) for p in out]


#: vertices closer than this (m, horizontally and vertically) are one place
SAME_PLACE_M = 0.01
#: a survivor held this close (m, each axis) to its launch point stands on the ground
GROUND_M = 0.5


def _fewest_vertices(ctx, poly, stops) -> tuple:
    """The polyline with only the vertices a mission must fly: the ``stops`` (start,
    snapshots, end), and a vertex between them only where the straight leg past it
    fails the planned legs' proofs (`TravelGraph.legs_ok`); a vertex repeating the
    one before is one. A vehicle stops at each waypoint it flies, so these are
    the waypoints its missions carry and its schedule counts (`missions.segments`
    finds nothing more to leave out)."""
    must = np.zeros(len(poly), bool)
    must[stops] = True
    keep = [0]
    for j in range(1, len(poly)):
        if np.all(np.abs(poly[j] - poly[keep[-1]]) < SAME_PLACE_M):
            if must[j]:
                keep[-1] = j          # the stop is the one flown
            continue
        keep.append(j)
    out = [keep[0]]
    for i, j in enumerate(keep[1:-1], start=1):
        if must[j] or not ctx.graph.legs_ok(poly[out[-1]], poly[keep[i + 1]])[0]:
            out.append(j)
    if len(keep) > 1:
        out.append(keep[-1])
    index = np.full(len(poly), -1, np.int64)
    index[out] = np.arange(len(out))
    # a stop merged into the same place as another keeps that one's index
    for j in np.flatnonzero(must & (index < 0)):
        index[j] = index[max(k for k in out if k <= j)] if any(k <= j for k in out) else 0
    return poly[out], index[stops]


def _rounded_for_mavlink(ctx, poly) -> np.ndarray:
    """The polyline as MAVLink carries it: latitude and longitude in 1e-7 degrees,
    altitudes as float32 rounded down (lower is never less hidden; the planner
    keeps a clearance margin far larger than a float32 step)."""
    lon, lat = ctx.terrain.to_lonlat(poly[:, 0], poly[:, 1])
    lon = np.round(np.asarray(lon, float) * 1e7) / 1e7
    lat = np.round(np.asarray(lat, float) * 1e7) / 1e7
    alt = poly[:, 2].astype(np.float32)
    alt = np.where(alt.astype(float) > poly[:, 2], np.nextafter(alt, np.float32(-np.inf)), alt)
    x, y = ctx.terrain.from_lonlat(lon, lat)
    return np.stack([np.asarray(x, float), np.asarray(y, float), alt.astype(float)], axis=1)


def _prove(ctx, r, poly) -> None:
    """Every leg hidden and clear, by the mission check's own tests."""
    if len(poly) < 2:
        return
    ok = segments_hidden(ctx.surface, poly[:-1], poly[1:]) & \
        segments_clear(ctx.surface, poly[:-1], poly[1:])
    if not ok.all():
        n = int(np.flatnonzero(~ok)[0])
        raise InputError("plan", f"UAV {r + 1}: leg {n + 1} of its route fails the hidden and "
                                 "clearance proof once rounded for MAVLink (a planner defect: "
                                 "please report it with the scenario)")


@dataclass
class Fleet:
    """The routes as one fleet on the fleet clock (`planner.fleet`), one flight per
    `Sortie`."""

    sorties: list       # `Sortie` per flight
    schedule: FleetSchedule   # its timings per flight
    profiles: list      # `Profile` per flight
    coverage_time_s: float

    def of(self, r) -> list:
        """Indices of UAV r's flights, in order."""
        return [i for i, f in enumerate(self.sorties) if f.uav == r]

    def snapshot_times(self, r) -> np.ndarray:
        """Fleet-clock time of UAV r's snapshots: when it leaves them (a camera
        fires once its waypoint, hold included, is done)."""
        out = [np.zeros(0)]
        for i in self.of(r):
            t, profile = self.schedule.timings[i], self.profiles[i]
            out.append(profile.arrivals(t.start_s, t.holds)[1][self.sorties[i].snap
                                                               + profile.route[0]])
        return np.concatenate(out)

    def flight_s(self, i) -> float:
        """Flight i's time from takeoff (or, in flight, from now) to touchdown, waits
        in the air included."""
        t = self.schedule.timings[i]
        return float(t.trajectory.end - t.start_s)


def _on_ground(start) -> bool:
    """A re-plan's survivor standing at its base (landed): it takes off, and waits
    on the ground, not in the air where it would fill its column from the start."""
    return start.held is not None and start.launch is not None and \
        bool(np.all(np.abs(np.asarray(start.held) - start.launch) <= GROUND_M))


def fleet_clock(ctx, sorties, starts, problem, routes) -> Fleet:
    """Every sortie on the fleet clock with the waits that keep the fleet separated
    (`planner.fleet.schedule`, ``separation_m`` of the scenario), a vehicle's
    sorties a turnaround apart, the waits chosen for the earliest coverage time."""
    s = ctx.scenario
    profiles = []
    for f in sorties:
        start = starts[f.uav] if starts else None
        profiles.append(Profile.of_route(
            f.poly, ctx.travel_params, launch=f.base, land=f.lands,
            start=None if start is None or not f.first or _on_ground(start) else start.held,
            stop_s=stop_time(vars(s))))
    after = [None if f.first else i - 1 for i, f in enumerate(sorties)]
    need = np.minimum(problem.needs(), achievable(problem))   # as the methods aim at

    def coverage_time(timings) -> float:
        fleet = Fleet(sorties, FleetSchedule(timings, [], 0.0, None, 0.0), profiles, 0.0)
        when = [fleet.snapshot_times(r) for r in range(len(routes))]
        return last_needed_sighting(problem, routes, when, need)

    # in the air, the battery most flown goes first (one retired from its battery
    # flies home before all): a hold draws what it has left
    urgency = [-math.inf if f.first and starts and starts[f.uav].retired else
               -(starts[f.uav].flown_s if f.first and starts else 0.0) for f in sorties]
    sched = schedule(profiles, s.separation_m, coverage_time, after,
                     60.0 * s.turnaround_min, s.usable_s, urgency)
    return Fleet(sorties, sched, profiles, coverage_time(sched.timings) if sorties else 0.0)


def _make_plan(ctx, method, problem, allocation, starts, fleet, counts, timing, bounds):
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
    far = coverage.problem.beyond_battery(problem)
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


def plan_mission(scenario: Scenario, progress: Progress = None, terrain=None, outposts=None,
                 scheduler="auto", log=None):
    """Scenario -> (PlanningContext, Outcome): the whole of `gcs plan` (``scheduler``,
    ``log``: see `prepare`)."""
    ctx = prepare(scenario, progress, terrain, outposts, scheduler, log)
    starts = launch_starts(ctx)
    return ctx, allocate(ctx, scenario.uavs, starts, progress=progress, scheduler=scheduler,
                         log=log)
