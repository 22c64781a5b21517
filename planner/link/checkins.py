"""``--max-silence``: check-ins where a route would be out of radio contact too long.

A route hidden behind a ridge is out of the ground station's radio for as long as
it stays there (on the demo's plan, two vehicles for 17 minutes at a stretch). With a
limit on the silence, `keep_in_touch` breaks each silence longer than the limit by a
check-in (`planner.sorties.CheckIn`): a hidden point the antennas hear (a node of
the travel graph, at the hidden ceiling, `planner.link.in_contact`), flown to and on
from without a photograph. It goes in the latest gap between two stops of the route
from which one is reached after the silence began and before it has run
`AIM` of the limit, at the point of least detour there.

The fleet is timed again after each check-in (separation waits and the slowing at
waypoints move every later time of a vehicle), and the check-in kept only if the
fleet's silences past the limit got shorter in all by more than the coverage time
it added and no vehicle's longest got longer, until no silence is over the limit,
none can be broken, or `ROUNDS` check-ins have been tried. What cannot be met is
said (plan.json's link metrics, the summary): `CheckIns.over_s`, each vehicle's
longest silence less the limit, and `CheckIns.floor_s`, the least longest silence
any route through its viewpoints can have (`_floors`): above the limit, only an
antenna nearer those routes can help.
"""

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse.csgraph import dijkstra

from common.errors import InputError
from planner.sorties import CheckIn, flown_stops

from . import fleet_silences, in_contact

#: check-ins tried at most (each times the fleet again: 0.2-0.5 s on the demo's plan)
ROUNDS = 40
#: of the limit, what a check-in plans to use: the travel times leave out the slowing
#: at waypoints and the separation's waits, which the fleet clock then adds
AIM = 0.8


@dataclass
class CheckIns:
    """What ``--max-silence`` did to the routes."""

    limit_s: float
    checks: list = field(default_factory=list)  # per UAV, its `CheckIn`s by ``before``
    over_s: list = field(default_factory=list)  # per UAV, its longest silence over the limit
    added_s: float = 0.0   # coverage time the check-ins added
    floor_s: list = field(default_factory=list)  # per UAV, the least longest silence any
    #                                              route through its viewpoints can have

    def report(self) -> dict:
        """plan.json's ``link.max_silence``."""
        return {"limit_s": self.limit_s, "check_ins": [len(c) for c in self.checks],
                "met": not any(o > 0 for o in self.over_s),
                "over_s": [round(float(o), 1) for o in self.over_s],
                "floor_s": [round(float(f), 1) for f in self.floor_s],
                "coverage_time_added_s": round(self.added_s, 1)}


@dataclass
class _Gap:
    """Between two stops of a vehicle's route: where a check-in may go."""

    sortie: int         # of `planner.sorties.sortie_split`
    before: int         # the index in the route of the visit after it
    index: int          # the index in the route's check-ins of a check-in put here
    leave_s: float      # when the vehicle leaves the stop before it
    ends: tuple         # (xyz) of the stops before and after it
    from_check: bool    # the stop before it is a check-in

    @property
    def key(self) -> tuple:
        """The gap, whatever is put in the route elsewhere: where its ends stand."""
        return tuple(np.round(np.concatenate(self.ends), 1))


def keep_in_touch(ctx, routes, sortie_of, fleet, retime, limit_s) -> tuple:
    """(fleet, `CheckIns`): the routes (viewpoint ids per UAV, ``sortie_of`` the sortie
    of each visit) with check-ins so that no predicted silence outlasts ``limit_s``
    where one can be found; ``retime(checks) -> Fleet`` times the fleet again with
    the check-ins ``checks`` (per UAV). A check-in is kept only where it shortens
    the fleet's silences past the limit, summed (`_excess`), by more than it adds to
    the coverage time, and makes no vehicle's longest longer (`_better`): one that
    does not (its detour as silent as what it breaks, a wait it makes another
    vehicle take in a shadow, a detour longer than the silence it saves) is taken
    out, and its gap not tried again. A vehicle whose viewpoints no route can keep
    within the limit (`_floors`) is aimed at its floor instead."""
    antennas, radio = ctx.scenario.link()
    heard = in_contact(ctx.terrain, antennas, radio, ctx.graph.node_xyz)

    done = CheckIns(limit_s, [[] for _ in routes], floor_s=_floors(ctx, routes, heard))
    # a silence no route can keep within the limit is brought as near it as it can be
    aim = [max(limit_s, f) for f in done.floor_s]

    def silences_of(fleet) -> list:
        return [fleet_silences(ctx.terrain, antennas, radio, fleet, r)
                for r in range(len(routes))]

    tried = [set() for _ in routes]
    quiet, before_s = silences_of(fleet), fleet.coverage_time_s
    over = [_excess(q, a) for q, a in zip(quiet, aim)]
    for _ in range(ROUNDS):
        got = None
        for r in sorted(range(len(routes)), key=lambda r: -over[r][0]):
            if over[r][0] > 0:
                got = _next_check_in(ctx.graph, fleet, r, routes[r], sortie_of[r],
                                     done.checks[r], heard, quiet[r], tried[r], aim[r])
            if got is not None:
                break
        if got is None:
            break
        gap, xyz = got
        done.checks[r].insert(gap.index, CheckIn(gap.before, gap.sortie, xyz))
        trial = retime(done.checks)
        trial_quiet = silences_of(trial)
        after = [_excess(q, a) for q, a in zip(trial_quiet, aim)]
        if _better(over, after, trial.coverage_time_s - fleet.coverage_time_s):
            fleet, quiet, over = trial, trial_quiet, after
        else:
            del done.checks[r][gap.index]
            tried[r].add(gap.key)
    done.over_s = [max(q.longest_s - limit_s, 0.0) for q in quiet]
    done.added_s = fleet.coverage_time_s - before_s
    return fleet, done


def _floors(ctx, routes, heard) -> list:
    """Per UAV, the least longest silence any route through its viewpoints can have:
    from the nearest heard point to its farthest viewpoint and on to the nearest
    again (0 where all are heard). What no check-in and no order of visits can
    shorten; only an antenna nearer them can."""
    graph, vp = ctx.graph, ctx.viewpoints.xyz
    sources = np.flatnonzero(heard)
    if not len(sources):
        return [np.inf] * len(routes)
    inward = dijkstra(graph.csr, indices=sources, min_only=True)
    outward = dijkstra(graph.csr.T.tocsr(), indices=sources, min_only=True)
    out = []
    for route in routes:
        nodes = graph.nodes_of(vp[np.asarray(route, np.int64)]) if len(route) else []
        out.append(float(max((inward[n] + outward[n] for n in nodes), default=0.0)))
    return out


def _excess(quiet, limit_s) -> tuple:
    """(seconds of a vehicle's silences past the limit, summed over its silences;
    its longest silence past the limit)."""
    past = [max(b - a - limit_s, 0.0) for a, b in quiet.windows]
    return float(sum(past)), max(past, default=0.0)


def _better(over, after, cost_s) -> bool:
    """Whether the fleet's silences ``after`` a check-in (`_excess` per UAV) are worth
    its ``cost_s`` of coverage time: shorter past the limit in all by more than that,
    and no vehicle's longest longer."""
    return sum(a[0] for a in after) < sum(o[0] for o in over) - max(cost_s, 0.0) and \
        all(a[1] <= o[1] for a, o in zip(after, over))


def _next_check_in(graph, fleet, r, route, of, checks, heard, quiet, tried, limit_s):
    """(`_Gap`, xyz) of UAV r's next check-in: for its first silence over the limit
    that one can break (`_check_in`), None when none can."""
    gaps = None
    for window in quiet.windows:
        if window[1] - window[0] <= limit_s:
            continue
        gaps = gaps or list(_gaps(fleet, r, route, of, checks))
        got = _check_in(graph, gaps, heard, window, window[0] + AIM * limit_s, tried)
        if got is not None:
            return got
    return None


def _check_in(graph, gaps, heard, window, by_s, tried):
    """(`_Gap`, xyz) of the check-in for the silence ``window`` (start s, end s): in
    the latest gap not ``tried`` from which a heard node is reached after the silence
    began and by ``by_s``, the node of least detour there; None when no gap reaches
    one in time. The gap the silence begins in is no place for one when a check-in
    begins it too: the leg out of that check-in is the silence, and another beside
    it would not shorten it."""
    began = max((g for g in gaps if g.leave_s <= window[0]), default=None,
                key=lambda g: g.leave_s)
    for gap in sorted(gaps, key=lambda g: -g.leave_s):
        if gap.leave_s > by_s or (gap.leave_s <= window[0] and gap is not began) or \
                (gap is began and gap.from_check) or gap.key in tried:
            continue
        try:
            out = graph.times_from(gap.ends[0], limit_s=by_s - gap.leave_s)[0]
        except InputError:      # a stop off the graph's cells (a base's column): no gap
            continue
        arrive = gap.leave_s + out
        ok = heard & (arrive > window[0]) & (arrive <= by_s)
        if ok.any():
            back = graph.times_from(gap.ends[1])[0]   # on from it, as far as back to it
            detour = np.where(ok & np.isfinite(back), out + back, np.inf)
            if np.isfinite(detour).any():
                return gap, graph.node_xyz[int(np.argmin(detour))].copy()
    return None


def _gaps(fleet, r, route, of, checks):
    """UAV r's `_Gap`s, in the order flown: between each two stops of each sortie
    (its start and its landing among them, where it has a base)."""
    flown = flown_stops(route, of, checks)
    numbers = [0] + sorted({o for o, _, _ in flown} - {0})   # as make_sorties numbers them
    visits = checks_before = 0
    for i, j in zip(fleet.of(r), numbers):
        sortie = fleet.sorties[i]
        at = list(sortie.stops)
        # (xyz, leaves at, viewpoint id: -1 a check-in, None the start or the landing)
        points = [(sortie.poly[v], t, e) for v, t, (_, e, _) in
                  zip(at, fleet.leave_times(i, at), [x for x in flown if x[0] == j])]
        if sortie.base is not None:
            points = [(sortie.poly[0], fleet.airborne(i)[0], None), *points,
                      (sortie.poly[-1], np.nan, None)]
        for a, b in zip(points[:-1], points[1:]):
            visits += a[2] is not None and a[2] >= 0
            checks_before += a[2] == -1
            yield _Gap(j, visits, checks_before, float(a[1]), (a[0], b[0]), a[2] == -1)
        visits += points[-1][2] is not None and points[-1][2] >= 0
        checks_before += points[-1][2] == -1
