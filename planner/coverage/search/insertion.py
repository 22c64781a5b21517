"""The edge-breaking insertion rule, removal savings and intra-route improvement.

Edge-breaking rule: a viewpoint is inserted at either end of the route or into
whichever edge gives the least increase in time (the cheapest of them all);
with sorties (a `Battery` that limits the flights), only where its sortie still
fits the battery, or as a new sortie at the end. Route times are the model's
(`planner.coverage.model.routes`: the greedy split into sorties).
"""

import numpy as np
from numba import njit

from ..model.battery import leaving_after, limited
from ..model.routes import route_time, sortie_durations, walked


@njit(cache=True)
def insert_cost(route, e, travel, battery, has_launch):
    """(Δt, position) of the cheapest edge-breaking insertion of e; position p = before route[p]."""
    if limited(battery):
        return _sortie_insert_cost(route, e, travel, battery)
    lo = battery.out
    m = len(route)
    if m == 0:
        return (lo[e] if has_launch else 0.0), 0
    v0 = route[0]
    if has_launch:
        best = lo[e] + travel[e, v0] - lo[v0]
    else:
        best = travel[e, v0]
    pos = 0
    for p in range(1, m):
        a = route[p - 1]
        b = route[p]
        c = travel[a, e] + travel[e, b] - travel[a, b]
        if c < best:
            best = c
            pos = p
    c = travel[route[m - 1], e]
    if c < best:
        best = c
        pos = m
    return best, pos


@njit(cache=True)
def _sortie_insert_cost(route, e, travel, battery):
    """`insert_cost` where a battery limits the sorties (launch points given): each
    slot only where its sortie still fits the battery with e in it, the greedy
    split's own choice at a sortie's ends, and a new sortie after the last."""
    m = len(route)
    if m == 0:
        if battery.used + battery.out[e] + battery.back[e] <= battery.endurance:
            return battery.out[e], 0
        return battery.start_back + battery.turnaround + leaving_after(battery, -1)[e], 0
    arrive, sortie, flown = walked(route, travel, battery, True)
    dur = sortie_durations(route, sortie, flown, battery)
    starts = np.flatnonzero(np.diff(sortie)) + 1
    best, pos = np.inf, -1
    for p in range(1, m):                   # the cheapest edge inside a sortie that fits
        if sortie[p - 1] == sortie[p]:
            a, b = route[p - 1], route[p]
            c = travel[a, e] + travel[e, b] - travel[a, b]
            if c < best and dur[sortie[p]] + c <= battery.endurance:
                best, pos = c, p
    return _sortie_slots(route, e, travel, battery, sortie, flown, dur, starts, best, pos)


@njit(cache=True)
def slot_cost(route, s, e, travel, travel_t, lo, has_launch):
    """Δt of inserting e before route[s] (s = len(route): after the last).

    Reads rows of ``travel`` and of its transpose ``travel_t`` so that loops
    over e stay in cache (the matrices are large).
    """
    m = len(route)
    if m == 0:
        return lo[e] if has_launch else 0.0
    if s == 0:
        v0 = route[0]
        return lo[e] + travel_t[v0, e] - lo[v0] if has_launch else travel_t[v0, e]
    if s == m:
        return travel[route[m - 1], e]
    a, b = route[s - 1], route[s]
    return travel[a, e] + travel_t[b, e] - travel[a, b]


@njit(cache=True)
def middle_costs_all(route, travel, travel_t, lo, has_launch, mid_cost, mid_pos):
    """Cheapest insertion of every viewpoint into an edge of the route (slots 1..m-1)."""
    n_vp = travel.shape[0]
    mid_cost[:] = np.inf
    mid_pos[:] = -1
    for s in range(1, len(route)):
        for e in range(n_vp):
            c = slot_cost(route, s, e, travel, travel_t, lo, has_launch)
            if c < mid_cost[e]:
                mid_cost[e] = c
                mid_pos[e] = s


# combine_ends and update_middle_costs run once per insertion, thousands of times a
# plan, on well under a millisecond of work each: on one core. As numba parallel loops they
# waited on their threads at every call, and on a busy machine (one other job on
# one of 2 cores) the whole sample's plan took 59 s instead of 32 s, 15 s of it
# in each of the two.
@njit(cache=True)
def combine_ends(route, travel, travel_t, battery, has_launch, mid_cost, mid_pos, cost, pos):
    """Edge-breaking rule: the cheapest of front, best edge and back (with sorties:
    `_sortie_slots`)."""
    m = len(route)
    lo = battery.out
    if limited(battery) and m > 0:
        arrive, sortie, flown = walked(route, travel, battery, True)
        dur = sortie_durations(route, sortie, flown, battery)
        starts = np.flatnonzero(np.diff(sortie)) + 1
        for e in range(travel.shape[0]):
            cost[e], pos[e] = _sortie_slots(route, e, travel, battery, sortie, flown, dur,
                                            starts, mid_cost[e], mid_pos[e])
        return
    for e in range(travel.shape[0]):
        c, p = slot_cost(route, 0, e, travel, travel_t, lo, has_launch), 0
        if mid_cost[e] < c:
            c, p = mid_cost[e], mid_pos[e]
        if m > 0:
            cb = slot_cost(route, m, e, travel, travel_t, lo, has_launch)
            if cb < c:
                c, p = cb, m
        cost[e] = c
        pos[e] = p


@njit(cache=True)
def _sortie_slots(route, e, travel, battery, sortie, flown, dur, starts, mid_c, mid_p):
    """(Δt, position) of e among the slots `_sortie_insert_cost` weighs, the edges
    inside sorties by their cached best (``mid_c`` at ``mid_p``) only: that edge
    if its sortie still fits, else the front, the sorties' ends and the back.
    Exact where travel keeps the triangle inequality, with one base; where a
    sortie's end decides the base the next one leaves from, that sortie may split
    anew and the cost is an estimate (`walk` times the route)."""
    endurance, back = battery.endurance, battery.back
    m = len(route)
    best, pos = np.inf, m
    if 0 < mid_p < m and sortie[mid_p - 1] == sortie[mid_p] and \
            dur[sortie[mid_p]] + mid_c <= endurance:
        best, pos = mid_c, mid_p
    a = route[m - 1]
    if flown[m - 1] + travel[a, e] + back[e] <= endurance:
        c = travel[a, e]
    else:
        c = back[a] + battery.turnaround + leaving_after(battery, a)[e]
    if c < best:
        best, pos = c, m
    for k in range(len(starts) + 1):
        p = 0 if k == 0 else starts[k - 1]
        b, j = route[p], sortie[p]
        if p == 0 and j == 0:
            c = battery.out[e] + travel[e, b] - battery.out[b]
            if dur[0] + c > endurance:
                continue
            if c < best:
                best, pos = c, p
            continue
        # e at the end of the flight before sortie j (then home from e, and sortie j
        # out of the base e's way home lands at), or at the start of sortie j
        a = route[p - 1] if p > 0 else -1
        if p == 0:
            end_c = battery.out[e] + back[e] - battery.start_back
            before = battery.used + battery.out[e] + back[e] <= endurance
        else:
            end_c = travel[a, e] + back[e] - back[a]
            before = dur[sortie[p - 1]] + end_c <= endurance
        moved = leaving_after(battery, e)[b] - leaving_after(battery, a)[b]  # sortie j's way out
        if before:      # the split flies e there: sortie j then leaves the base e's lands at
            if moved > 0 and dur[j] + moved > endurance:
                continue
            c = end_c + moved
        else:
            out = leaving_after(battery, a)
            c = out[e] + travel[e, b] - out[b]
            if dur[j] + c > endurance:
                continue
        if c < best:
            best, pos = c, p
    return best, pos


@njit(cache=True)
def update_middle_costs(route, s, travel, travel_t, lo, has_launch, mid_cost, mid_pos):
    """Refresh edge insertions after route[s] was inserted (``route`` is the new route).

    Front or back insertions only add one edge; a middle insertion splits
    edge s into s and s+1 and shifts later ones, and only the viewpoints whose
    best edge was s need a rescan.
    """
    n_vp = travel.shape[0]
    m = len(route)
    if m < 2:
        return
    if s == 0 or s == m - 1:
        new_edge = 1 if s == 0 else m - 1
        for e in range(n_vp):
            if s == 0 and mid_pos[e] >= 1:
                mid_pos[e] += 1
            c = slot_cost(route, new_edge, e, travel, travel_t, lo, has_launch)
            if c < mid_cost[e]:
                mid_cost[e] = c
                mid_pos[e] = new_edge
        return
    edge = np.empty(m - 1)
    for q in range(1, m):
        edge[q - 1] = travel[route[q - 1], route[q]]
    for e in range(n_vp):
        if mid_pos[e] == s:  # its edge was split: rescan (rows e stay in cache)
            best, best_q = np.inf, -1
            for q in range(1, m):
                c = travel_t[e, route[q - 1]] + travel[e, route[q]] - edge[q - 1]
                if c < best:
                    best, best_q = c, q
            mid_cost[e] = best
            mid_pos[e] = best_q
            continue
        if mid_pos[e] > s:
            mid_pos[e] += 1
        # the two new edges, s then s+1 (once e's best is s, s+1 is not tried: as
        # RT has always done, kept so that its plans stay the same)
        for q in range(s, s + 2):
            c = slot_cost(route, q, e, travel, travel_t, lo, has_launch)
            if mid_pos[e] != s and c < mid_cost[e]:
                mid_cost[e] = c
                mid_pos[e] = q


@njit(cache=True)
def removal_saving(route, i, travel, battery, has_launch):
    """Time saved by removing route[i] and joining its neighbours (with sorties: the
    route walked again without it, its sorties split anew)."""
    m = len(route)
    e = route[i]
    if limited(battery):
        rest = np.concatenate((route[:i], route[i + 1:]))
        return route_time(route, travel, battery, True) - route_time(rest, travel, battery, True)
    lo = battery.out
    if m == 1:
        return lo[e] if has_launch else 0.0
    if i == 0:
        nxt = route[1]
        if has_launch:
            return lo[e] + travel[e, nxt] - lo[nxt]
        return travel[e, nxt]
    prev = route[i - 1]
    if i == m - 1:
        return travel[prev, e]
    nxt = route[i + 1]
    return travel[prev, e] + travel[e, nxt] - travel[prev, nxt]


@njit(cache=True)
def removal_savings(route, travel, battery, has_launch):
    """`removal_saving` of every visit of the route, in one call (a call from Python
    per visit cost more than the savings themselves on routes of hundreds)."""
    out = np.empty(len(route))
    for i in range(len(route)):
        out[i] = removal_saving(route, i, travel, battery, has_launch)
    return out


#: how far an estimated candidate time may be from the summed one (rounding over a
#: route's edges is far below it): a candidate estimated above the best by more is
#: not summed
_ESTIMATE_SLACK_S = 1e-6


@njit(cache=True)
def improve_route(route, travel, battery, has_launch):
    """Or-opt (move segments of 1-3, also reversed) and 2-opt until no gain.

    Full re-evaluation per candidate keeps it exact for asymmetric travel. Without
    sorties a candidate's time is first estimated from the route's prefix sums
    (O(1)), and only one that may improve is summed: the same moves as summing every
    candidate, which was cubic in the route's length (7 of 16 s of RT+LS on the
    whole sample).
    """
    best = route.copy()
    best_t = route_time(best, travel, battery, has_launch)
    m = len(best)
    fast = not limited(battery)
    fwd, rev = _prefix_times(best, travel)
    worth = best_t - 1e-9 + _ESTIMATE_SLACK_S
    improved = True
    while improved:
        improved = False
        # 2-opt: reverse best[i..j]
        for i in range(m - 1):
            for j in range(i + 1, m):
                if fast and _reversed_time(best, i, j, fwd, rev, travel, battery.out,
                                           has_launch, best_t) >= worth:
                    continue
                cand = best.copy()
                cand[i:j + 1] = best[i:j + 1][::-1]
                t = route_time(cand, travel, battery, has_launch)
                if t < best_t - 1e-9:
                    best, best_t, improved = cand, t, True
                    fwd, rev = _prefix_times(best, travel)
                    worth = best_t - 1e-9 + _ESTIMATE_SLACK_S
        # or-opt: move a segment of length 1..3 elsewhere (optionally reversed)
        for seg in range(1, 4):
            for i in range(m - seg + 1):
                segment = best[i:i + seg].copy()
                rest = np.concatenate((best[:i], best[i + seg:]))
                rest_t = _without_time(best, i, seg, fwd, travel, battery.out, has_launch,
                                       best_t) if fast else 0.0
                moved = False
                for rev_seg in range(2):
                    s = segment if rev_seg == 0 else segment[::-1].copy()
                    inner = fwd[i + seg - 1] - fwd[i] if rev_seg == 0 else \
                        rev[i + seg - 1] - rev[i]
                    for p in range(len(rest) + 1):
                        if p == i and rev_seg == 0:
                            continue
                        if fast and rest_t + _inserted_time(rest, p, s[0], s[-1], inner,
                                                            travel, battery.out,
                                                            has_launch) >= worth:
                            continue
                        cand = np.concatenate((rest[:p], s, rest[p:]))
                        t = route_time(cand, travel, battery, has_launch)
                        if t < best_t - 1e-9:
                            best, best_t, improved, moved = cand, t, True, True
                            fwd, rev = _prefix_times(best, travel)
                            worth = best_t - 1e-9 + _ESTIMATE_SLACK_S
                            break
                    if moved:
                        break
    return best


@njit(cache=True)
def _prefix_times(route, travel):
    """(forward, reversed): the time from route[0] to route[q] along the route, and
    the same edges each flown the other way."""
    fwd = np.zeros(len(route))
    rev = np.zeros(len(route))
    for q in range(1, len(route)):
        fwd[q] = fwd[q - 1] + travel[route[q - 1], route[q]]
        rev[q] = rev[q - 1] + travel[route[q], route[q - 1]]
    return fwd, rev


@njit(cache=True)
def _first_leg(e, lo, has_launch):
    return lo[e] if has_launch else 0.0


@njit(cache=True)
def _reversed_time(route, i, j, fwd, rev, travel, lo, has_launch, route_t):
    """The time of the route with route[i..j] reversed (no sorties), estimated."""
    t = route_t + (rev[j] - rev[i]) - (fwd[j] - fwd[i])
    if i > 0:
        t += travel[route[i - 1], route[j]] - travel[route[i - 1], route[i]]
    else:
        t += _first_leg(route[j], lo, has_launch) - _first_leg(route[i], lo, has_launch)
    if j < len(route) - 1:
        t += travel[route[i], route[j + 1]] - travel[route[j], route[j + 1]]
    return t


@njit(cache=True)
def _without_time(route, i, seg, fwd, travel, lo, has_launch, route_t):
    """The time of the route without route[i:i + seg] (no sorties), estimated."""
    m = len(route)
    if m == seg:
        return 0.0
    a, b = route[i], route[i + seg - 1]
    t = route_t - (fwd[i + seg - 1] - fwd[i])
    t -= travel[route[i - 1], a] if i > 0 else _first_leg(a, lo, has_launch)
    if i + seg < m:
        nxt = route[i + seg]
        t -= travel[b, nxt]
        t += travel[route[i - 1], nxt] if i > 0 else _first_leg(nxt, lo, has_launch)
    return t


@njit(cache=True)
def _inserted_time(rest, p, first, last, inner, travel, lo, has_launch):
    """What flying a segment (``first`` .. ``last``, ``inner`` between them) before
    rest[p] adds to rest's time (no sorties), estimated."""
    t = inner + (travel[rest[p - 1], first] if p > 0 else _first_leg(first, lo, has_launch))
    if p < len(rest):
        after = rest[p]
        t += travel[last, after]
        t -= travel[rest[p - 1], after] if p > 0 else _first_leg(after, lo, has_launch)
    return t
