"""Re-planning in flight: the survivors' remaining work after a loss.

``replan`` runs the plan's coverage method again, on the plan's
`PlanningContext` (in memory, or `PlanningContext.load` from its folder), for
the survivors only: each starts where it is now (a point in the
hidden volume) and still returns hidden to its base (the one its flight lands
at; with an endurance and several bases, its sorties land at the nearest as a
plan's do); what it has photographed so far counts as seen by it.

It runs the plan's own method with its own budget, scaled down for flight
(`REPLAN_BUDGET_FRACTION`), and reports only the quick lower bounds (reach and
packing; the flow LP is for planning on the ground).

Choices (the paper's assumption): a lost UAV's images are lost with it, so
only the survivors' snapshots count, and every target must be seen by
``min(k + 1, survivors)`` distinct survivors. Snapshot positions are judged
with the planner's own sensor model (`snapshot_sets`).
"""

from dataclasses import dataclass, replace
from typing import Optional

import numpy as np
from scipy.spatial import cKDTree

from common.errors import InputError
from planner.exposure import segments_clear, segments_hidden, segments_under_ceiling
from planner.travel import CLEARANCE_MARGIN_M, leg_time
from planner.visibility import Viewpoints, compute_visibility

from .context import PlanningContext
from .coverage.model import CoverageProblem, required_uavs, sighting_counts
from .launch import Start, above_launch, launch_starts
from .pipeline import allocate

#: a snapshot this close (m, 3-D) to a candidate viewpoint counts as taken there;
#: autopilots accept a waypoint within about 2 m
SNAP_TO_VIEWPOINT_M = 3.0
#: a held vehicle this close (m, horizontally) to its launch point is over it
LAUNCH_COLUMN_M = 3.0
#: nearest graph nodes tried when a survivor's position must be snapped
SNAP_CANDIDATES = 32
#: a re-plan in flight uses the plan's method and search budget (`--method alns`,
#: `--time-budget`), capped at this fraction of the coverage time of the
#: survivors' start solution: they hover, held, while it runs, so a second of
#: search must save more than a second of flight. ALNS flies 4-30 % less than
#: RT (benchmarks/bench_coverage.py), so 1 % of it is repaid several times:
#: 6 s for 10 minutes of flying left, 0.6 s for one (the default budget, at
#: most 5 s, applies below that cap).
REPLAN_BUDGET_FRACTION = 0.01


@dataclass
class Survivor:
    """A UAV still flying, as the ground station knows it when re-planning."""

    vehicle_id: int  # its plan vehicle id
    xyz: np.ndarray  # current position: projected x, y, alt AMSL
    launch: np.ndarray  # ground point it returns to: x, y, ground AMSL
    flown_s: float = 0.0  # of its battery, used already (a plan with an endurance counts it)
    retired: bool = False  # its batteries are not trusted: it only flies home
    legs: Optional[np.ndarray] = None  # [n, 3] the waypoints of the mission it flies now


# --- what has been seen ------------------------------------------------------------------

def snapshot_sets(ctx: PlanningContext, xyz) -> list:
    """Target ids (of ``ctx.visibility``) seen from each snapshot position.

    A position within `SNAP_TO_VIEWPOINT_M` of a candidate viewpoint uses that
    viewpoint's visibility set; any other is evaluated with the same sensor
    model from the cell under it at its own altitude. Positions off the grid
    see nothing.
    """
    xyz = np.atleast_2d(np.asarray(xyz, float)).reshape(-1, 3)
    out = [np.zeros(0, np.int64)] * len(xyz)
    if not len(xyz):
        return out
    others = list(range(len(xyz)))
    if len(ctx.viewpoints):
        d, j = cKDTree(ctx.viewpoints.xyz).query(np.nan_to_num(xyz, nan=np.inf))
        others = []
        for i in range(len(xyz)):
            if d[i] <= SNAP_TO_VIEWPOINT_M:
                out[i] = ctx.visibility.seen_by(int(j[i])).astype(np.int64)
            else:
                others.append(i)
    if others:
        for i, ids in zip(others, _sets_at(ctx, xyz[others])):
            out[i] = ids
    return out


def _sets_at(ctx, xyz) -> list:
    """Visibility sets computed for arbitrary points (at the centre of their cell)."""
    terrain = ctx.terrain
    inside = terrain.contains_xy(xyz[:, 0], xyz[:, 1]) & np.isfinite(xyz[:, 2])
    result = [np.zeros(0, np.int64)] * len(xyz)
    idx = np.flatnonzero(inside)
    if not idx.size:
        return result
    row, col = terrain.rowcol(xyz[idx, 0], xyz[idx, 1])
    cells = np.stack([np.rint(row), np.rint(col)], axis=1).astype(np.int64)
    points = Viewpoints(indices=cells, xyz=xyz[idx].copy(), region=np.zeros(len(idx), np.int32))
    vis = compute_visibility(ctx.surface, points, ctx.scenario.sensor_params())
    known = ctx.visibility.target_cells
    order = np.argsort(known)
    for k, i in enumerate(idx):
        cells_seen = vis.target_cells[vis.seen_by(k)]
        pos = np.searchsorted(known[order], cells_seen)
        pos = np.minimum(pos, len(known) - 1)
        hit = known[order][pos] == cells_seen
        result[i] = np.sort(order[pos[hit]]).astype(np.int64)
    return result


def seen_matrix(ctx: PlanningContext, snapshots_per_uav) -> np.ndarray:
    """bool [n_uavs, n_targets]: which targets each UAV's snapshots (xyz arrays) saw."""
    seen = np.zeros((len(snapshots_per_uav), ctx.visibility.n_targets), bool)
    for r, xyz in enumerate(snapshots_per_uav):
        for ids in snapshot_sets(ctx, np.asarray(xyz, float).reshape(-1, 3)):
            seen[r, ids] = True
    return seen


def coverable_targets(ctx: PlanningContext) -> int:
    """Targets some candidate viewpoint sees (the others nobody can cover)."""
    return int((np.diff(ctx.visibility.target_indptr) > 0).sum())


def coverage_summary(ctx: PlanningContext, snapshots_per_uav, k: int, counts=None) -> dict:
    """How well targets are covered by the snapshots (xyz arrays, one per UAV):
    ``k_covered`` counts the targets seen by min(k + 1, UAVs) of them from as many
    distinct places (`place_counts`, or ``counts`` where the caller has them), or
    by one per place where fewer places see them; ``k_impossible``: how many have
    fewer places than that."""
    n = int(ctx.visibility.n_targets)
    counts = place_counts(ctx, snapshots_per_uav) if counts is None else counts
    need = required_uavs(k, len(snapshots_per_uav))
    places = np.diff(ctx.visibility.target_indptr)
    wanted = np.minimum(need, places)
    return {"targets": n, "covered": int((counts >= 1).sum()),
            "k": int(k), "required_uavs": int(need),
            "k_covered": int((counts >= wanted).sum()),
            "k_impossible": int(((places > 0) & (places < need)).sum()),
            "fraction_k_covered": float((counts >= wanted).sum() / n) if n else 1.0}


# --- re-planning ------------------------------------------------------------------------

def survivor_start(ctx: PlanningContext, survivor: Survivor) -> Start:
    """`_start_of` the survivor, with the battery it has flown."""
    return replace(_start_of(ctx, survivor), flown_s=float(survivor.flown_s),
                   retired=bool(survivor.retired))


def _start_of(ctx: PlanningContext, survivor: Survivor) -> Start:
    """A survivor's start: its own position when the hidden graph can take it from
    there, else the nearest graph node reachable by a straight hidden leg (the
    time of that leg counted as ``climb_s``). A vehicle held over its launch
    point on its final descent climbs back to the takeoff top instead.

    A vehicle held where it strayed from its leg may have no first leg that
    passes the planner's strict checks (track tolerance, ceiling); that one
    short leg is then proven on its own (the vehicle is there already) and the
    route starts at that leg's node: routes start with a strict leg otherwise.
    Then a vehicle hovering by a node over the edge of a void (`_beside_node`). Last,
    one held on a leg of the mission it flies (within the track tolerance the leg is
    proven with) goes back or on along it to that leg's waypoint, a node of the
    graph: the way there lies inside the leg's proven tube (a convex set holding
    both ends), and is checked hidden and clear again (`_along_own_leg`)."""
    graph = ctx.graph
    xyz = np.asarray(survivor.xyz, float)
    launch = np.asarray(survivor.launch, float)
    climb = _climb_at_launch(ctx, xyz, launch)
    if climb is not None:
        return climb
    node = _node_under(graph, xyz)
    if node >= 0 and graph.legs_ok(xyz, graph.node_xyz[node])[0]:
        return Start(xyz, launch, 0.0, held=xyz)
    for strict in (True, False, None):
        target = _beside_node(ctx, xyz, node) if strict is None else \
            _nearest_reachable_node(graph, xyz, strict)
        if target is not None:
            return _joined_at(ctx, xyz, target, launch)
    target = _along_own_leg(ctx, xyz, survivor.legs)
    if target is not None:
        return _joined_at(ctx, xyz, target, launch)
    raise InputError(f"vehicle {survivor.vehicle_id}",
                     "its position is not joined to the hidden volume by a hidden leg")


def _joined_at(ctx, xyz, target, launch) -> Start:
    """A start at graph point ``target``, reached from ``xyz`` by one straight leg."""
    d = target - xyz
    return Start(target, launch, float(leg_time(np.hypot(d[0], d[1]), d[2], ctx.travel_params)),
                 held=xyz)


def _along_own_leg(ctx, xyz, legs):
    """The graph node at an end of the mission leg ``xyz`` is held on (within the track
    tolerance of it), the way there hidden and clear; None if there is none. A
    vehicle the re-plan held mid-leg over ground where no new leg passes the
    planner's checks (a float32 waypoint a few millimetres off its node, a thin
    hidden layer) is still on the leg its mission was proven on."""
    if legs is None or len(legs) < 2:
        return None
    graph, room = ctx.graph, ctx.scenario.track_tolerance_m
    a, b = np.asarray(legs[:-1], float), np.asarray(legs[1:], float)
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", xyz - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab),
                                                                 1e-12), 0.0, 1.0)
    off = np.linalg.norm(a + t[:, None] * ab - xyz, axis=1)
    for k in np.argsort(off):
        if off[k] > room:
            break
        for end in (b[k], a[k]) if t[k] >= 0.5 else (a[k], b[k]):
            node = _node_under(graph, end)
            if node < 0 or np.linalg.norm(graph.node_xyz[node] - end) > room:
                continue
            target = graph.node_xyz[node]
            # the tests the mission check proved the leg with (`missions.check`)
            a_, b_ = xyz[None], target[None]
            if segments_hidden(ctx.surface, a_, b_)[0] and \
                    segments_clear(ctx.surface, a_, b_)[0] and \
                    segments_under_ceiling(ctx.surface, a_, b_)[0]:
                return target.copy()
    return None


def _climb_at_launch(ctx, xyz, launch):
    """A vehicle held over its launch point below the takeoff top (on its final
    descent): its start is that top, reached by climbing straight back up as at
    takeoff (hidden because the top is; exempt from the clearance rule)."""
    top = above_launch(ctx, launch)
    if np.hypot(*(xyz[:2] - launch[:2])) > LAUNCH_COLUMN_M or xyz[2] >= top[2]:
        return None
    if not segments_hidden(ctx.surface, xyz[None], top[None])[0]:
        return None
    return Start(top, launch, float(leg_time(0.0, top[2] - xyz[2], ctx.travel_params)),
                 held=xyz)


def _beside_node(ctx, xyz, node):
    """The node a vehicle hovers beside, when no leg to it passes the checks: within
    the room around it that the node's own check proves hidden and clear (its
    `slack_m` disc, at its altitude), no lower than it by more than the clearance
    margin, and hidden on the straight way there. A vehicle held at a waypoint on
    the edge of a void (a nodata margin) drifts a few centimetres over ground the
    checks call unknown, at the mission item's float32 altitude (hundredths of a
    millimetre under the node): it is still where the node's proof holds."""
    graph = ctx.graph
    if node < 0:
        return None
    target = graph.node_xyz[node]
    if np.hypot(*(xyz[:2] - target[:2])) > graph.params.slack_m or \
            xyz[2] < target[2] - CLEARANCE_MARGIN_M:
        return None
    if not (graph.legs_ok(target, target)[0]
            and segments_hidden(ctx.surface, xyz[None], target[None])[0]):
        return None
    return target.copy()


def _node_under(graph, xyz) -> int:
    row, col = graph.surface.terrain.rowcol(xyz[0], xyz[1])
    r, c = int(np.rint(row)), int(np.rint(col))
    n_rows, n_cols = graph.node_of_cell.shape
    if 0 <= r < n_rows and 0 <= c < n_cols:
        return int(graph.node_of_cell[r, c])
    return -1


def _nearest_reachable_node(graph, xyz, strict):
    d = np.linalg.norm(graph.node_xyz - xyz, axis=1)
    near = np.argsort(d)[:SNAP_CANDIDATES]
    ok = graph.legs_ok(np.repeat(xyz[None], len(near), axis=0), graph.node_xyz[near],
                       strict)
    hits = near[ok]
    return graph.node_xyz[hits[0]].copy() if hits.size else None


def requirement(ctx: PlanningContext, n_survivors: int) -> tuple:
    """(k used for the survivors, required distinct survivors per target)."""
    k = int(ctx.scenario.k)
    need = required_uavs(k, n_survivors)
    return min(k, n_survivors - 1), np.full(ctx.visibility.n_targets, need, np.int32)


def earlier_sightings(ctx: PlanningContext, snapshots_per_uav) -> tuple:
    """What the survivors photographed, by place (`planner.coverage.model.places`):
    (visited, seen), bool [n_survivors, n_viewpoints] the candidate viewpoints
    each took a snapshot at (within `SNAP_TO_VIEWPOINT_M`), and bool
    [n_survivors, n_targets] what it saw from anywhere else (places of their
    own). Two survivors' snapshots at one viewpoint are one place: they count
    once, and a third survivor flying there adds no place either."""
    snapped = _snapped(ctx, snapshots_per_uav)
    visited = np.zeros((len(snapped), len(ctx.viewpoints)), bool)
    elsewhere = []
    for r, (xyz, at) in enumerate(zip(snapshots_per_uav, snapped)):
        visited[r, at[at >= 0]] = True
        elsewhere.append(np.asarray(xyz, float).reshape(-1, 3)[at < 0])
    return visited, seen_matrix(ctx, elsewhere)


def _snapped(ctx: PlanningContext, snapshots_per_uav) -> list:
    """Per survivor, the viewpoint each snapshot was taken at (-1: none within
    `SNAP_TO_VIEWPOINT_M`)."""
    tree = cKDTree(ctx.viewpoints.xyz) if len(ctx.viewpoints) else None
    out = []
    for xyz in snapshots_per_uav:
        xyz = np.asarray(xyz, float).reshape(-1, 3)
        at = np.full(len(xyz), -1, np.int64)
        if tree is not None and len(xyz):
            d, j = tree.query(np.nan_to_num(xyz, nan=np.inf))
            at = np.where(d <= SNAP_TO_VIEWPOINT_M, j, -1)
        out.append(at)
    return out


def place_counts(ctx: PlanningContext, snapshots_per_uav) -> np.ndarray:
    """Per target, its sightings in ``snapshots_per_uav`` (xyz arrays per UAV) from
    distinct UAVs at distinct places (`earlier_sightings`, counted by the
    matching of `planner.coverage.model.places`)."""
    visited, seen = earlier_sightings(ctx, snapshots_per_uav)
    vis = ctx.visibility
    problem = CoverageProblem(vis.indptr, vis.indices, vis.n_targets, None, None, None,
                              len(visited), seen=seen, visited=visited)
    return sighting_counts(problem, [[]] * len(visited))


def replan(ctx: PlanningContext, survivors: list, seen=None, method=None,
           progress=None, required=None, snapshots=None):
    """Routes for ``survivors`` (list of `Survivor`) from where they are.

    ``snapshots``: where each has photographed so far (xyz arrays per survivor),
    counted by place (`earlier_sightings`); or, without them, ``seen``: bool
    [n_survivors, n_targets] (`seen_matrix`), each sighting a place of its own;
    None for nothing. ``required`` overrides the per-target requirement (all
    zeros: straight home along hidden paths). Returns the
    `planner.pipeline.Outcome` with vehicle ids renumbered to the survivors' plan
    ids; each route starts at the survivor's (possibly snapped) position and ends
    above its launch.
    """
    if not survivors:
        raise InputError("replan", "no surviving vehicle to re-plan")
    k, need = requirement(ctx, len(survivors))
    required = need if required is None else np.asarray(required, np.int32)
    sub = replace(ctx, scenario=replace(ctx.scenario, k=k, uavs=len(survivors)))
    starts = [survivor_start(ctx, s) for s in survivors]
    visited = None
    if snapshots is not None:
        visited, seen = earlier_sightings(ctx, snapshots)
    outcome = allocate(sub, len(survivors), starts, seen=seen, required=required,
                       method=method, progress=progress,
                       budget_fraction=REPLAN_BUDGET_FRACTION, strong_bound=False,
                       visited=visited)
    for r, (vehicle, s) in enumerate(zip(outcome.plan.vehicles, survivors)):
        vehicle.id = int(s.vehicle_id)
    return outcome


class BaseRefused(InputError):
    """No hidden takeoff from the base of vehicle ``index`` (`plan_from_bases`)."""

    def __init__(self, index, exc: InputError):
        super().__init__(exc.source, exc.problem)
        self.index = index


def plan_from_bases(ctx: PlanningContext, launch: list, moved=(), log=None):
    """The context's scenario planned again for the whole fleet from ``launch``
    ((lat, lon) of each vehicle's base, in order): vehicles standing elsewhere than
    planned, before their takeoff. Each base of ``moved`` (indices) is checked alone
    first, so that one from which no hidden takeoff is possible is named
    (`BaseRefused`); returns the (context, `planner.pipeline.Outcome`)."""
    for i in moved:
        try:
            launch_starts(replace(ctx, scenario=replace(ctx.scenario, launch=[launch[i]],
                                                        uavs=1)))
        except InputError as exc:
            raise BaseRefused(i, exc) from None
    ctx = replace(ctx, scenario=replace(ctx.scenario, launch=list(launch)))
    return ctx, allocate(ctx, len(launch), launch_starts(ctx), log=log)
