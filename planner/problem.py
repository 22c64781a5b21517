"""The coverage problem of a planning context: what the allocation methods see.

`coverage_problem` turns the context (visibility sets, hidden travel times)
and the fleet's starts into the combinatorial `planner.coverage.CoverageProblem`:
the times out of each start and back to each base, and with an endurance the
sortie model (`_battery`): how long one battery flies, the turnaround, what a
vehicle in flight has flown, and the bases a sortie may land at.
"""

import numpy as np

from planner.travel import landing_time, takeoff_time

from . import coverage
from .context import PlanningContext
from .launch import above_launch, fleet_bases, launch_tops


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
    times its ``scale``: `planner.pipeline.allocate` tightens them where the slowing at waypoints
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
