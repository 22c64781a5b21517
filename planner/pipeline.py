"""The whole planning pipeline: Scenario -> PlanningContext -> Plan.

``prepare`` runs the terrain-bound stages once (terrain, exposure, viewpoints,
visibility, travel graph); ``allocate`` runs a coverage method from given
start states and turns the allocation into hidden 3-D routes. Re-planning in
flight calls ``allocate`` again on the same context with the survivors'
positions and what they have already seen.

Each stage is a module of its own; this one runs them in order and times them:

| stage | module |
|---|---|
| terrain, exposure | `planner.terrain`, `planner.exposure` |
| viewpoints, visibility, travel graph | `planner.visibility`, `planner.travel` |
| the area of operations | `planner.terrain.area` |
| launch points and bases, each UAV's `Start` | `planner.launch` |
| the coverage problem of the context | `planner.problem` |
| the search (a coverage method; a large area in parts) | `planner.coverage`, `planner.split` |
| the sorties' hidden polylines | `planner.sorties` |
| the fleet clock (separation, turnarounds) | `planner.fleet.clock` |
| check-ins in radio contact (--max-silence) | `planner.link.checkins` |
| the `Plan` and its metrics | `planner.assembly` |
"""

import math
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from common.errors import InputError
from planner.exposure import compute_exposure, restricted
from planner.exposure.outposts import (
    crop_around,
    place_outposts,
    reaching,
    read_outpost_features,
    sample_outpost_features,
)
from planner.link.checkins import keep_in_touch
from planner.terrain import load_dem, sample_terrain
from planner.terrain.area import area_mask, areas, box_ring, read_area
from planner.travel import build_travel_graph
from planner.visibility import (
    candidate_viewpoints,
    compute_visibility,
    default_spacing,
    fleet_region,
)
from planner.visibility.unseen import unseen_reasons

from . import coverage, split
from .assembly import make_plan
from .context import MissingContext, PlanningContext
from .fleet.clock import fleet_clock, over_battery
from .launch import (
    Start,
    above_launch,
    launch_starts,
    launch_tops,
    launch_xy,
    takeoff_delays,
)
from .parallel import dask_client
from .plan import Plan
from .problem import coverage_problem
from .scenario import Scenario
from .sorties import make_sorties, sortie_split, uav_polylines

#: the names other packages and the tests take from here, wherever they now live
__all__ = ["Outcome", "PlanningContext", "Progress", "Start", "above_launch", "allocate",
           "coverage_problem", "exposure_stages", "launch_starts", "launch_tops",
           "load_context", "outpost_features", "plan_mission", "prepare"]

#: progress(stage, fraction) — fraction in [0, 1], 1 when the stage is done
Progress = Callable[[str, float], None]


@contextmanager
def _stage(name, timing, progress):
    """Time the stage ``name`` into ``timing`` (plan.json's ``timing_s``), and tell
    ``progress`` when it starts and ends."""
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
    area, flight = areas(terrain, s.area, s.area_file, s.area_flight, polygons)
    if flight is not None:
        surface = restricted(surface, flight)
    launch = launch_xy(terrain, s)
    regions = fleet_region(surface, launch)  # every launch point must be flyable
    with dask_client(scheduler, terrain.height.size, log) as client:
        with _stage("travel graph", timing, progress):
            graph = build_travel_graph(surface, s.travel_params(), client=client,
                                       progress=_fraction(progress, "travel graph"))
        with _stage("viewpoints", timing, progress):
            candidates = candidate_viewpoints(surface, s.viewpoint_spacing_m, regions,
                                              s.sensor_range_m)
            tops = None if launch is None else launch_tops(graph, launch)
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


def _fraction(progress, stage):
    """``progress`` for one stage: called with (done, total) or with a fraction."""
    if progress is None:
        return None
    return lambda done, total=1: progress(stage, done / max(total, 1))


@dataclass
class Outcome:
    """A plan and what it was made from (for writers, plots and re-planning)."""

    plan: Plan
    problem: coverage.CoverageProblem
    allocation: coverage.Allocation
    polylines: list  # per UAV: (n, 3) projected x, y, alt AMSL
    counts: np.ndarray  # per target: distinct UAVs that see it


#: the scattered route bound's share of the search's time (`coverage.bounds.scatter`),
#: and its least time: what proving a plan's quality may add to planning it
BOUND_SHARE = 0.25
BOUND_MIN_S = 2.0


def bound_budget_s(search_s: float) -> float:
    """Seconds the plan's strongest lower bound may take, given the search's."""
    return max(BOUND_MIN_S, BOUND_SHARE * search_s)


def allocate(ctx: PlanningContext, n_uavs: int, starts=None, seen=None, required=None,
             method=None, progress: Progress = None, budget_fraction=None,
             strong_bound=True, scheduler=None, log=None, visited=None) -> Outcome:
    """Run the scenario's coverage method from ``starts`` and build hidden routes.

    ``budget_fraction`` caps the search budget (`coverage.methods.alns.AlnsParams`);
    ``strong_bound=False`` reports only the quick lower bounds (re-plans in flight).
    A large area is planned in parts (`planner.split`), as dask tasks on
    ``scheduler`` (see `prepare`) when it names one."""
    s = ctx.scenario
    method = method or s.method
    timing = dict(ctx.timing_s)
    # the scenario's method settings: each method takes those it has (`coverage.solve`)
    params = {"alpha": s.alpha, "beta": s.beta, "step_time_cap": s.step_time_cap_s,
              "seed": s.seed, "time_budget_s": s.time_budget_s,
              "budget_fraction": budget_fraction}
    request = SearchRequest(ctx, n_uavs, starts, seen, required, visited, method, params,
                            scheduler, log)
    parts = split.n_parts(len(ctx.viewpoints), s)
    problem, allocation, prep, sorties, counts, fleet, checkins = _fleet(request, parts,
                                                                          timing, progress)
    # only the reach bound holds for the whole of an area planned in parts; the bounds
    # are of the timed plan: a base's vehicles wait for its column (`bounds.takeoffs`)
    with _stage("lower bound", timing, progress):
        bounds = ((split.reach_bound(problem),) * 2 if parts > 1
                  else coverage.lower_bounds(problem, strong_bound, prep,
                                             bound_budget_s(allocation.planning_s),
                                             takeoff_delays(starts, s.separation_m),
                                             s.usable_s))
    plan = make_plan(ctx, method, problem, allocation, starts, fleet, counts, timing, bounds,
                     checkins)
    over = over_battery(fleet, s.usable_s, starts)
    if over.any():
        plan.metrics["battery"]["over_battery"] = float(max(over))
    if parts > 1:
        plan.metrics["parts"] = parts
    return Outcome(plan, problem, allocation, uav_polylines(sorties, n_uavs), counts)


def _fleet(request, parts, timing, progress) -> tuple:
    """(problem, allocation, prepared problem, sorties, sightings per target, `Fleet`,
    `CheckIns` or None): the search, its sorties and their fleet clock (with the
    check-ins of --max-silence), searched again on a smaller battery while a sortie
    outgrows it (`BATTERY_TRIES` in all)."""
    ctx, starts = request.ctx, request.starts
    s = ctx.scenario
    scale, over = np.ones(2), np.zeros(2)
    checkins = None
    in_flight = bool(starts and any(st.held is not None for st in starts))
    for attempt in range(BATTERY_TRIES):
        try:
            problem, allocation, prep, sortie_of = _search(request, parts, scale, timing,
                                                           progress)
        except ValueError as exc:
            raise InputError("plan", str(exc)) from None
        with _stage("routes", timing, progress):
            sorties = make_sorties(ctx, problem, allocation.routes, starts,
                                   _fraction(progress, "routes"), sortie_of)
            counts = coverage.coverage_counts(problem, allocation)
        with _stage("separation", timing, progress):
            fleet = fleet_clock(ctx, sorties, starts, problem, allocation.routes)
        if s.max_silence_s is not None and parts == 1:
            with _stage("check-ins", timing, progress):
                fleet, checkins = _checked_in(ctx, problem, allocation.routes, sortie_of,
                                              fleet, starts)
        sorties = fleet.sorties
        # the search's times leave out the slowing at the waypoints: plan again with
        # the sorties (or, where one viewpoint alone is too far, the round trips) that
        # much shorter. In flight, not for the separation's waits: a vehicle held in
        # its base column while another comes home waits whatever its sorties (one
        # held 671 s was planned again in 32 one-viewpoint sorties, 161 min instead
        # of 42); the wait past its battery is reported, and the battery watch guards it
        over = over_battery(fleet, s.usable_s, starts, waits=not in_flight)
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
    return problem, allocation, prep, sorties, counts, fleet, checkins


def _checked_in(ctx, problem, routes, sortie_of, fleet, starts) -> tuple:
    """(fleet, `CheckIns`): the fleet with check-ins that keep the scenario's
    --max-silence where they can (`planner.link.checkins`)."""
    def retime(checks):
        sorties = make_sorties(ctx, problem, routes, starts, None, sortie_of, checks)
        return fleet_clock(ctx, sorties, starts, problem, routes)

    try:
        return keep_in_touch(ctx, routes, sortie_of, fleet, retime, ctx.scenario.max_silence_s)
    except ValueError as exc:     # an antenna off the terrain
        raise InputError("--antenna", str(exc)) from None


#: plans tried on a smaller battery before a sortie that outgrows it is an error
BATTERY_TRIES = 4


@dataclass(frozen=True)
class SearchRequest:
    """What `allocate` asks of the search: the fleet and what it has done so far,
    the coverage method and its settings, where the work runs."""

    ctx: PlanningContext
    n_uavs: int
    starts: Optional[list]             # `Start` per UAV, None: the paper's free starts
    seen: Optional[np.ndarray]         # bool [UAVs, targets] photographed before
    required: Optional[np.ndarray]     # sightings each target needs (None: k + 1)
    visited: Optional[np.ndarray]      # bool [UAVs, viewpoints] photographed from before
    method: str
    params: dict                       # the method's settings (`coverage.solve`)
    scheduler: object                  # where plans in parts run (see `prepare`)
    log: Optional[Callable]

    trips: dict = field(default_factory=dict, compare=False)   # of the first problem

    def problem(self, scale, travel=True) -> coverage.CoverageProblem:
        """The coverage problem on the battery ``scale``d (`planner.problem._battery`);
        ``travel`` False: without the viewpoint times (a plan in parts). Its
        one-viewpoint sorties as flown are found once (they do not scale)."""
        s = self.ctx.scenario
        problem = coverage_problem(self.ctx, self.n_uavs, self.starts, s.k, s.visibility,
                                   self.seen, self.required, travel=travel,
                                   visited=self.visited, battery_scale=scale,
                                   trips=self.trips or None)
        if problem.trip_s is not None and not self.trips:
            self.trips.update(trip_s=problem.trip_s, bases_trip_s=problem.bases_trip_s)
        return problem


def _search(request, parts, scale, timing, progress) -> tuple:
    """(problem, allocation, prepared problem or None for a plan in parts, the
    sortie of each visit per UAV): the coverage method's search, the battery
    ``scale``d."""
    if parts > 1:
        problem, joined = _in_parts(request, parts, scale, timing, progress)
        return problem, joined.allocation(problem, request.method), None, joined.sortie_of
    with _stage("allocation", timing, progress):
        problem = request.problem(scale)
        prep = coverage.prepare(problem)  # once: the bounds below share it
        allocation = coverage.solve(problem, request.method, request.params,
                                    progress=(lambda f: progress("allocation", f))
                                    if progress else None, prep=prep)
    return problem, allocation, prep, sortie_split(prep, allocation.routes)


def _in_parts(request, parts, scale, timing, progress):
    """`allocate`'s search for an area planned in ``parts`` parts (`planner.split`):
    the problem of the whole area (without viewpoint times) and the joined routes
    (`split.Joined`); each part splits its routes into sorties on the battery
    ``scale``d."""
    ctx = request.ctx
    for stage in ("travel times", "allocation"):
        if progress:
            progress(stage, 0.0)
    start = time.perf_counter()
    with dask_client(request.scheduler, ctx.terrain.height.size, request.log) as client:
        problem = request.problem(scale, travel=False)
        pieces = split.make_parts(problem, ctx.viewpoints.xyz[:, :2], parts)
        # one sparse overlay of the whole area: the parts' times go through any viewpoint
        overlay = ctx.viewpoint_overlay(client, _fraction(progress, "travel times"))
        overlay_s = time.perf_counter() - start
        # on a cluster a part's times are made in its task, from the overlay alone
        joined = split.solve_parts(problem, pieces, request.method, request.params,
                                   lambda ids, on: (None if client is not None else
                                                    ctx.graph.overlay_times(overlay, ids, on)),
                                   ctx.scenario.speed_mps, client, progress, overlay)
    timing["travel times"] = overlay_s + joined.travel_s
    timing["allocation"] = time.perf_counter() - start - timing["travel times"]
    for stage in ("travel times", "allocation"):
        if progress:
            progress(stage, 1.0)
    if request.log is not None:
        request.log(f"planned in {parts} parts of "
                    f"{', '.join(str(len(g)) for g in joined.groups)} UAVs; the join "
                    f"dropped {joined.dropped} visits it made redundant")
    return problem, joined


def load_context(directory, plan: Optional[Plan] = None) -> PlanningContext:
    """The context a saved plan was made in, from its folder (`PlanningContext.load`);
    a folder without the files that keep it (copied without them, or written by an
    older version) gets its stages run again from its terrain and outposts."""
    try:
        return PlanningContext.load(directory, plan)
    except MissingContext as missing:
        surface = missing.surface
        return prepare(missing.scenario, terrain=surface.terrain, outposts=surface.outposts)


def plan_mission(scenario: Scenario, progress: Progress = None, terrain=None, outposts=None,
                 scheduler="auto", log=None):
    """Scenario -> (PlanningContext, Outcome): the whole of `gcs plan` (``scheduler``,
    ``log``: see `prepare`)."""
    ctx = prepare(scenario, progress, terrain, outposts, scheduler, log)
    starts = launch_starts(ctx)
    return ctx, allocate(ctx, scenario.uavs, starts, progress=progress, scheduler=scheduler,
                         log=log)
