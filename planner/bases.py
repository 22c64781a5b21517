"""Suggested bases: ground launch points ranked by how fast a fleet could cover the
targets from there (`gcs bases`).

A base is a point ``gcs plan --launch`` accepts, decided by the planner's own
check (`launch.launch_starts`: the cell under it is flyable hidden, the column
above it is hidden and clear up to a takeoff top, and a proven hidden leg joins
that top to the travel graph), which also leaves the plan's context unchanged:
its cell lies in the fleet's flyable region and its top in the strongly
connected part of the graph that holds the viewpoints. Bases are ranked by the
planner's reach bound (`coverage.bounds.radius`): a lower bound on coverage time for
the whole fleet leaving from that base, from the hidden travel times of the
coverage problem `gcs plan` would build (`problem.coverage_problem`). On a battery
a base is first ranked by the ground one battery reaches from it (`Base.reach`),
since its bound is over that ground only.

The exact check costs tenths of a second a point (its proven legs), so not every
cell is checked: candidates on a grid are ordered by a quick estimate (the same
bound from the hidden graph node over the cell, no takeoff), then checked in that
order, kept apart by a least separation, and the checked ones ranked by their
exact bound.
"""

from dataclasses import dataclass, field, replace
from typing import Callable, Optional

import numpy as np

from common.errors import InputError

from .context import PlanningContext
from .coverage.bounds.radius import reach_bound, reach_bound_of
from .coverage.model import achievable
from .coverage.model import prepare as prepare_problem
from .launch import launch_starts
from .problem import coverage_problem
from .split import PART_VIEWPOINTS
from .visibility.unseen import OUTSIDE

#: least distance between two reported bases (m): apart enough that the list offers
#: different places, not one good spot ten times
SEPARATION_M = 500.0
#: at most this many grid cells get the quick estimate (one hidden-graph Dijkstra each)
MAX_CANDIDATES = 200
#: checked bases per reported one: the quick estimate orders the checks, the exact
#: bound of the checked ones decides the ranking
CHECKED_PER_BASE = 2
#: decimals of a base's latitude and longitude as said and as `gcs plan --launch`
#: takes them (0.1 m)
LAUNCH_DECIMALS = 6

Progress = Callable[[str, float], None]


@dataclass
class Base:
    """One suggested base, with what an operator needs to pick it."""

    rank: int  # 1 = the lowest bound
    lat: float
    lon: float
    x: float  # projected, m
    y: float
    ground_m: float  # AMSL
    takeoff_m: float  # AMSL: the top of the hidden, clear column above it
    bound_s: float  # reach bound on the fleet's coverage time from here
    start: object = field(default=None, repr=False, compare=False)  # launch.Start
    # per target, seen from a viewpoint one battery reaches from here (with an endurance)
    reach: Optional[np.ndarray] = field(default=None, repr=False, compare=False)
    reach_km2: Optional[float] = None  # the ground of ``reach`` (None: no endurance)
    reach_pct: Optional[float] = None  # of the ground any hidden viewpoint sees
    inside: bool = True  # in the area of operations (else none there passed the checks)

    @property
    def launch_arg(self) -> str:
        """What to give ``gcs plan --launch``."""
        return f"{self.lat:.{LAUNCH_DECIMALS}f},{self.lon:.{LAUNCH_DECIMALS}f}"


@dataclass
class BaseSet:
    """Bases flown from together, the UAVs taking them in turn (``--launch`` of
    several points: UAV i at base i mod n)."""

    bases: list  # `Base`, in the order given to --launch
    reach_km2: float  # ground seen from a viewpoint one battery reaches from one of them
    reach_pct: float  # of the ground any hidden viewpoint sees (the targets)
    bound_s: float  # reach bound on the fleet's coverage time, spread over them

    @property
    def launch_arg(self) -> str:
        return " ".join(b.launch_arg for b in self.bases)


def suggest_bases(ctx: PlanningContext, count: int = 10, separation_m: float = SEPARATION_M,
                  spacing_m: Optional[float] = None, progress: Progress = None) -> list:
    """Up to ``count`` bases, best (lowest reach bound) first, at least
    ``separation_m`` apart; candidates every ``spacing_m`` (default: automatic,
    at most `MAX_CANDIDATES` of them). InputError when no point passes."""
    if len(ctx.viewpoints) > PART_VIEWPOINTS:
        # the reach bound needs the travel times between all viewpoints, which an
        # area planned in parts never makes (4 GB at 20,000 viewpoints)
        raise InputError("bases", f"{len(ctx.viewpoints):,} viewpoints: too large an area to "
                                  f"rank bases over (at most {PART_VIEWPOINTS:,}); choose "
                                  "a smaller --area around where the base may stand")
    # a base stands in the area of operations (one 3 km outside it, in the DEM's
    # corner, was once suggested best); only where none passes there, outside it
    area, bases = in_area(ctx), []
    for inside in (True, False):
        rows, cols = candidate_cells(ctx, spacing_m, inside)
        if not len(rows):
            continue
        quick = quick_bounds(ctx, rows, cols, progress)
        order = np.argsort(quick, kind="stable")
        order = order[np.isfinite(quick[order])]   # inf: the targets are out of hidden reach
        checked = check_in_order(ctx, rows[order], cols[order], CHECKED_PER_BASE * count,
                                 separation_m, progress)
        bases = [replace(b, inside=bool(area[_cell(ctx, b)])) for b in
                 (_base(ctx, *found) for found in checked) if np.isfinite(b.bound_s)]
        if bases or area.all():
            break
    if not bases:
        raise InputError("bases", "no ground point passes the launch checks: nowhere is the "
                                  "column above the ground hidden, clear and joined to the "
                                  "hidden area the fleet flies in (try a lower --clearance "
                                  "or --track-tolerance, or a larger area)")
    # on a battery a base from which no sortie sees a target plans nothing (its bound,
    # over no ground, read 0.0 min)
    useful = [b for b in bases if b.reach is None or b.reach.any()]
    if not useful:
        raise InputError("--endurance", f"no base found reaches a target on one battery "
                                        f"({ctx.scenario.endurance_min:g} min less "
                                        f"{ctx.scenario.reserve_pct:g} % reserve): give a "
                                        "longer --endurance")
    useful.sort(key=_rank_key)
    return [replace(b, rank=n + 1) for n, b in enumerate(useful[:count])]


def _cell(ctx: PlanningContext, base: Base) -> tuple:
    """(row, col) of the grid cell a base stands in."""
    return tuple(int(v) for v in np.rint(ctx.terrain.rowcol(base.x, base.y)))


def _rank_key(base: Base) -> tuple:
    """Best first: on a battery, the base that reaches the most ground, then the
    lowest bound (which is over that ground only: a base that reaches little has
    a small bound, and ranked by it alone came first); without one, the lowest
    bound."""
    return (-(base.reach_km2 or 0.0), base.bound_s)


def check_in_order(ctx: PlanningContext, rows, cols, wanted: int, separation_m: float,
                   progress: Progress = None) -> list:
    """[(start, lat, lon)] of the first ``wanted`` cells, in the given order, that
    pass `checked_start` at least ``separation_m`` from those passed before."""
    x, y = ctx.terrain.xy(rows, cols)
    checked = []
    for i, (px, py) in enumerate(zip(np.atleast_1d(x), np.atleast_1d(y))):
        if progress:
            progress("launch checks", i / max(len(rows), 1))
        if any(np.hypot(px - s.launch[0], py - s.launch[1]) < separation_m for s, *_ in checked):
            continue
        found = checked_start(ctx, float(px), float(py))
        if found is not None:
            checked.append(found)
            if len(checked) >= wanted:
                break
    if progress:
        progress("launch checks", 1.0)
    return checked


def in_area(ctx: PlanningContext) -> np.ndarray:
    """bool [rows, cols]: the area of operations (``--area``, ``--area-file``; the
    whole grid without one)."""
    if ctx.unseen is None:
        return np.ones(ctx.terrain.shape, bool)
    return ctx.unseen != OUTSIDE


def candidate_cells(ctx: PlanningContext, spacing_m: Optional[float] = None,
                    inside: bool = False) -> tuple:
    """(rows, cols) of grid cells worth checking: every ``spacing_m`` (coarser
    when more than `MAX_CANDIDATES` would pass), in the fleet's flyable region
    and over a node of the hidden travel graph (a launch there would be refused);
    ``inside``: in the area of operations only."""
    terrain, graph = ctx.terrain, ctx.graph
    usable = np.isin(ctx.surface.regions, np.asarray(ctx.regions)) & (graph.node_of_cell >= 0)
    if inside:
        usable &= in_area(ctx)
    stride = max(1, int(round((spacing_m or 0.0) / terrain.cell_size)))
    # the grid is sparse enough for the quick estimate when a stride^2 cell block
    # holds one candidate on average: start from there
    stride = max(stride, int(np.sqrt(usable.sum() / MAX_CANDIDATES)))
    while True:
        half = stride // 2
        grid = np.zeros_like(usable)
        grid[half::stride, half::stride] = True
        rows, cols = np.nonzero(usable & grid)
        if len(rows) <= MAX_CANDIDATES:
            return rows, cols
        stride += 1


def quick_bounds(ctx: PlanningContext, rows, cols, progress: Progress = None) -> np.ndarray:
    """Per candidate cell, the reach bound (single base, no takeoff time) from
    the hidden graph node over it: an estimate to order the exact checks by."""
    graph = ctx.graph
    if progress:
        progress("candidate bases", 0.0)
    nodes = graph.node_of_cell[rows, cols]
    # a node is joined to the graph as itself: no attach legs to prove here
    times = graph.times_between(graph.node_xyz[nodes], ctx.viewpoints.xyz)
    prep = prepare_problem(coverage_problem(ctx, ctx.scenario.uavs, None, ctx.scenario.k,
                                            ctx.scenario.visibility))
    one_base = np.zeros(ctx.scenario.uavs, np.int64)  # every UAV leaves from the same row
    out = np.empty(len(nodes))
    for i, row in enumerate(times):
        out[i] = reach_bound_of(row[None], one_base, prep.vis_indptr, prep.vis_indices,
                                prep.seen0, prep.required)
        if progress:
            progress("candidate bases", (i + 1) / len(nodes))
    return out


def checked_start(ctx: PlanningContext, x: float, y: float):
    """(start, lat, lon) of a launch at (x, y) if ``gcs plan --launch`` takes it
    there and plans in this same context, else None. The check is the planner's:
    `launch_starts` on the scenario with this launch point."""
    lon, lat = ctx.terrain.to_lonlat(x, y)
    # the point `gcs plan` takes from `Base.launch_arg` (6 decimals), not 5 cm off:
    # the reach said is that of its takeoff column and of the paths out of its top
    lat, lon = round(float(lat), LAUNCH_DECIMALS), round(float(lon), LAUNCH_DECIMALS)
    trial = replace(ctx, scenario=replace(ctx.scenario, launch=[(lat, lon)]))
    # a plan from here must plan in this context (else its targets differ): the cell
    # in the fleet's region, and (below) the top reaching the viewpoints and reached
    # back from them, i.e. in their strongly connected part of the graph
    row, col = (int(v) for v in np.rint(ctx.terrain.rowcol(x, y)))
    if int(ctx.surface.regions[row, col]) not in ctx.regions:
        return None
    try:
        start = launch_starts(trial)[0]
    except InputError:
        return None
    vp = ctx.viewpoints.xyz[:1]
    if not (np.isfinite(ctx.graph.times_between(start.xyz[None], vp)).all()
            and np.isfinite(ctx.graph.times_between(vp, start.xyz[None])).all()):
        return None
    return start, lat, lon


def _base(ctx: PlanningContext, start, lat, lon) -> Base:
    """The base of a checked start, with its reach bound from the coverage problem
    `gcs plan` builds for the fleet leaving from it."""
    s = ctx.scenario
    problem = coverage_problem(ctx, s.uavs, [start] * s.uavs, s.k, s.visibility)
    bound = float(reach_bound(prepare_problem(problem)))
    # the planner's own battery rule: a target no sortie from here can see has none
    reach = achievable(problem) > 0 if s.endurance_min is not None else None
    km2, pct = (None, None) if reach is None else _ground(ctx, reach)
    return Base(0, lat, lon, float(start.launch[0]), float(start.launch[1]),
                float(start.launch[2]), float(start.xyz[2]), bound, start, reach, km2, pct)


def _ground(ctx: PlanningContext, targets) -> tuple:
    """(km², % of the targets) of the target cells ``targets`` (bool per target)."""
    total, n = ctx.visibility.n_targets, int(np.count_nonzero(targets))
    return (round(n * ctx.terrain.cell_size ** 2 / 1e6, 3),
            round(100.0 * n / total, 1) if total else 0.0)


def suggest_sets(ctx: PlanningContext, bases: list) -> list:
    """Sets of the ranked ``bases`` that together reach more of the ground than
    one: grown one base at a time (up to one per UAV), each time by the base that
    adds the most ground a battery reaches (`Base.reach`; of equals, the better
    ranked), while one adds any: the first set is the one base that reaches the
    most. Without an endurance every base reaches everything: the best one, alone."""
    s, total = ctx.scenario, ctx.visibility.n_targets
    reach = {id(b): np.ones(total, bool) if b.reach is None else b.reach for b in bases}
    chosen, seen = [], np.zeros(total, bool)
    while len(chosen) < min(s.uavs, len(bases)):
        gains = [(int((reach[id(b)] & ~seen).sum()), -b.rank, b) for b in bases
                 if b not in chosen]
        gain, _, best = max(gains, key=lambda g: g[:2])
        if chosen and gain == 0:
            break
        chosen.append(best)
        seen |= reach[id(best)]
    out = []
    for n in range(1, len(chosen) + 1):
        starts = [chosen[i % n].start for i in range(s.uavs)]
        covered = np.logical_or.reduce([reach[id(b)] for b in chosen[:n]])
        problem = coverage_problem(ctx, s.uavs, starts, s.k, s.visibility)
        out.append(BaseSet(chosen[:n], *_ground(ctx, covered),
                           float(reach_bound(prepare_problem(problem)))))
    return out

