# Over 600 lines, knowingly: the ALNS kernels share one state layout (R, L, cnt, dc, pc,
# fly and ex, below) and call each other inside numba; apart, that layout would be
# described, and kept in step, in several places.
"""Numba kernels of the ALNS (`search.alns`): repair, redundant-visit removal, route order.

Routes are held in a padded matrix ``R[r, :L[r]]`` (viewpoint ids in flying
order) so that the kernels need no Python lists.  Coverage bookkeeping:
``cnt[r, t]`` = how many of r's visits (plus an earlier snapshot) see target t,
``dc[t]`` = distinct UAVs with ``cnt > 0`` (the local search's), ``fly[e]`` =
(how many UAVs fly viewpoint e or photographed from it before, the bit set of
those UAVs), ``pc[t]`` = distinct places that see t (viewpoints so flown, and
each earlier sighting from no viewpoint: a place of its own). Target t counts the
sightings of `model.places`: the largest
matching of UAVs to distinct places that see it (`met`), and is *short* while
that is below ``req[t]``.  The matching is at most ``min(dc[t], pc[t])`` and
equal to it up to two (König: a matching of size two exists unless one UAV or
one place holds every sighting), and equal to ``dc`` while each viewpoint is
flown by one UAV; only above two, with shared viewpoints, is it computed
(`_matching`, on the bit sets), which the ``ex`` tuple turns on: (exact,
``early[t]`` = the bit set of UAVs with an earlier sighting of t from a
place of its own,
``tgt_indptr``, ``tgt_indices``).  Two UAVs may fly one viewpoint
(``share``) where no target needs more than two sightings, or where the
matching is computed.

Every kernel returns (or adds to) a count of elementary evaluations, the
*work units* the ALNS budget is measured in (deterministic, unlike a clock).
"""

import numpy as np
from numba import njit

from ..model.battery import battery_of, leaving_after, limited
from ..model.problem import CLOSED
from ..model.routes import route_time, walked
from .insertion import insert_cost, removal_saving

START = -1  # a route's start: its launch point, or nowhere (free start) without one
END = -2  # a route's end: free (coverage time stops at the last snapshot)

PTV_MODE, MAKESPAN_MODE, REGRET_MODE = 0, 1, 2


@njit(cache=True, nogil=True)
def leg(u, v, travel, lo, back, has_launch):
    """Time of the leg u -> v, with START / END sentinels (the end free, or, with
    ``back``, the way home: a sortie that is not the last)."""
    if v == END:
        return back[u] if len(back) else 0.0
    if u == START:
        return lo[v] if has_launch else 0.0
    return travel[u, v]


@njit(cache=True, nogil=True)
def time_of(R, L, r, travel, batteries, has_launch):
    return route_time(R[r, :L[r]], travel, battery_of(batteries, r), has_launch)


@njit(cache=True, nogil=True)
def apply_visit(cnt, dc, r, e, delta, vis_indptr, vis_indices):
    """Add (delta = 1) or remove (delta = -1) UAV r's visit of e."""
    for j in range(vis_indptr[e], vis_indptr[e + 1]):
        t = vis_indices[j]
        before = cnt[r, t]
        cnt[r, t] = before + delta
        if before == 0 and delta > 0:
            dc[t] += 1
        elif before + delta == 0 and delta < 0:
            dc[t] -= 1


#: UAVs a bit set holds (``fly[:, 1]``, ``early``): the matching is computed for
#: fleets up to this size only
MASK_UAVS = 62


@njit(cache=True, nogil=True)
def apply_place(pc, fly, r, e, delta, vis_indptr, vis_indices):
    """Add (delta = 1) or remove (delta = -1) UAV r's visit of e from the places."""
    before = fly[e, 0]
    fly[e, 0] = before + delta
    if r < MASK_UAVS:
        fly[e, 1] = fly[e, 1] | (1 << r) if delta > 0 else fly[e, 1] & ~(1 << r)
    if (before == 0 and delta > 0) or (before + delta == 0 and delta < 0):
        for j in range(vis_indptr[e], vis_indptr[e + 1]):
            pc[vis_indices[j]] += delta


@njit(cache=True, nogil=True)
def _bits(m):
    c = 0
    while m:
        m &= m - 1
        c += 1
    return c


@njit(cache=True, nogil=True)
def _matching(t, fly, cap, ex):
    """The largest matching of UAVs to distinct places seeing t, up to ``cap``. A
    UAV with a place of its own (an earlier sighting, a viewpoint only it flies)
    is matched there (no other UAV wants that place); the rest by augmenting
    paths over the shared viewpoints."""
    early, tgt_indptr, tgt_indices = ex[1], ex[2], ex[3]
    own = early[t]
    shared = np.empty(tgt_indptr[t + 1] - tgt_indptr[t], np.int64)
    k = 0
    for i in range(tgt_indptr[t], tgt_indptr[t + 1]):
        m = fly[tgt_indices[i], 1]
        if m & (m - 1) == 0:
            own |= m
        else:
            shared[k] = m
            k += 1
    size = _bits(own)
    owner = np.full(MASK_UAVS, -1, np.int64)  # UAV -> the shared place it holds
    back = np.empty(k, np.int64)               # place -> the place it was reached from
    via = np.empty(k, np.int64)                # place -> the UAV it was reached by
    queue = np.empty(k, np.int64)
    for p in range(k):
        if size >= cap:
            break
        back[:] = -2
        back[p], queue[0], head, tail, seen = -1, p, 0, 1, own
        while head < tail:
            q = queue[head]
            head += 1
            m = shared[q] & ~seen
            u = 0
            while m:
                if m & 1:
                    seen |= 1 << u
                    if owner[u] < 0:            # free: flip the path back to p
                        while True:
                            owner[u] = q
                            if q == p:
                                break
                            u, q = via[q], back[q]
                        size += 1
                        head = tail
                        break
                    nq = owner[u]
                    if back[nq] == -2:
                        back[nq], via[nq] = q, u
                        queue[tail] = nq
                        tail += 1
                m >>= 1
                u += 1
    return min(size, cap)


@njit(cache=True, nogil=True)
def met(t, dc, pc, fly, req, ex):
    """Sightings target t counts, up to ``req[t]`` (see the module doc)."""
    m = min(dc[t], pc[t])
    if m <= 2 or req[t] <= 2 or not ex[0]:
        return m
    return _matching(t, fly, req[t], ex)


@njit(cache=True, nogil=True, inline="always")
def _raises_from(now, t, r, e, cnt, dc, pc, fly, req, ex):
    """Whether UAV r's visit of viewpoint e (not flown by r) gives short target t,
    which counts ``now`` sightings (`met`), one more. Inlined, ``now`` hoisted out
    of the loops over every (viewpoint, UAV) pair: a call per pair (its reference
    counts) once cost more than the rest of the search."""
    d = dc[t] + (1 if cnt[r, t] == 0 else 0)
    p = pc[t] + (1 if fly[e, 0] == 0 else 0)
    up = min(d, p)
    if up <= now or up <= 2 or req[t] <= 2 or not ex[0]:
        return up > now
    m = fly[e, 1]
    fly[e, 1] = m | (1 << r)
    after = _matching(t, fly, req[t], ex)
    fly[e, 1] = m
    return after > now


@njit(cache=True, nogil=True)
def _open(e, r, on, fly, owner0, share):
    """Whether UAV r may add viewpoint e: not flown by it nor `CLOSED`, and, unless
    viewpoints may be ``share``d, flown by nobody (now or before)."""
    if on[r, e] or owner0[e] == CLOSED:
        return False
    return share or fly[e, 0] == 0


@njit(cache=True, nogil=True)
def _add_gains(t, now, sign, gain, cand_of, cands, cnt, dc, pc, fly, req, weight, tgt_indptr,
               tgt_indices, ex):
    """Add (sign 1) or take away (-1) what short target t, which counts ``now``
    sightings (`met`, its callers' test), gives each candidate pair."""
    n = gain.shape[1]
    for i in range(tgt_indptr[t], tgt_indptr[t + 1]):
        c = cand_of[tgt_indices[i]]
        if c < 0:
            continue
        for r in range(n):
            if _raises_from(now, t, r, cands[c], cnt, dc, pc, fly, req, ex):
                gain[c, r] += sign * weight[t]


@njit(cache=True, nogil=True)
def _score(mode, g, dt, t_r, t_max, alpha, lam, eps):
    if mode == PTV_MODE:
        return g ** alpha / max(t_r + dt, eps) ** (1.0 - alpha)
    # makespan-aware cheapest insertion per target gained
    grow = max(t_r + dt - t_max, 0.0) + lam * max(dt, 0.0)
    return g / (grow + eps)


@njit(cache=True, nogil=True)
def repair(R, L, times, cnt, dc, pc, fly, req, weight, short, vis_indptr, vis_indices,
           tgt_indptr, tgt_indices, travel, batteries, has_launch, mode, alpha, lam, eps,
           noise, rnd, owner0, share, ex):
    """Insert visits until no target in ``short`` (and no other) is short.

    Candidates are the (viewpoint, UAV) pairs that give a short target one more
    sighting (`_raises_from`), from a viewpoint the UAV may add (`_open`: not
    `problem.CLOSED` in ``owner0``, and no other UAV flies it or photographed
    from it before unless ``share``); each is inserted at its cheapest
    edge-breaking slot.
    ``mode``: PTV (the paper's M_PTV on the short targets gained), MAKESPAN
    (targets gained per growth of the makespan plus ``lam`` x the added
    time), REGRET (the short target whose best option is most ahead of its
    second best is covered first, by its best option, costed as MAKESPAN).
    ``noise`` in [0, 1) scales scores by 1 +- noise (``rnd``: uniforms).
    ``weight[t]``: cells in target class t (`model.classes`; ones for plain targets);
    gains count cells.
    Returns (ok, work); ok is False if some short target has no option left.
    """
    n = R.shape[0]
    n_vp = travel.shape[0]
    on = np.zeros((n, n_vp), np.bool_)
    for r in range(n):
        for i in range(L[r]):
            on[r, R[r, i]] = True
    cand_of = np.full(n_vp, -1, np.int64)
    cands = np.empty(n_vp, np.int64)
    nc = 0
    for s in range(len(short)):
        t = short[s]
        for i in range(tgt_indptr[t], tgt_indptr[t + 1]):
            x = tgt_indices[i]
            if cand_of[x] < 0:
                cand_of[x] = nc
                cands[nc] = x
                nc += 1
    gain = np.zeros((nc, n), np.int64)
    remaining = 0
    for s in range(len(short)):
        t = short[s]
        now = met(t, dc, pc, fly, req, ex)
        if now >= req[t]:
            continue
        remaining += 1
        _add_gains(t, now, 1, gain, cand_of, cands, cnt, dc, pc, fly, req, weight, tgt_indptr,
                   tgt_indices, ex)
    dt = np.full((nc, n), np.inf)
    pos = np.zeros((nc, n), np.int64)
    work = 2 * len(short) + (tgt_indptr[short + 1] - tgt_indptr[short]).sum() * (n + 1)
    for r in range(n):
        work += _slots(R, L, r, cands, nc, gain, dt, pos, on, fly, owner0, share, travel,
                       batteries, has_launch)
    k = 0
    while remaining > 0:
        t_max = times.max()
        bc, br = -1, -1
        if mode == REGRET_MODE:
            best_regret, best_first = -1.0, np.inf
            for s in range(len(short)):
                t = short[s]
                now = met(t, dc, pc, fly, req, ex)
                if now >= req[t]:
                    continue
                c1, c2, o_c, o_r = np.inf, np.inf, -1, -1
                for i in range(tgt_indptr[t], tgt_indptr[t + 1]):
                    c = cand_of[tgt_indices[i]]
                    for r in range(n):
                        if not np.isfinite(dt[c, r]) or \
                                not _raises_from(now, t, r, cands[c], cnt, dc, pc, fly, req, ex):
                            continue
                        cost = 1.0 / _score(MAKESPAN_MODE, gain[c, r], dt[c, r], times[r],
                                            t_max, alpha, lam, eps)
                        if noise > 0.0:
                            cost *= 1.0 + noise * (2.0 * rnd[k % len(rnd)] - 1.0)
                            k += 1
                        if cost < c1:
                            c2 = c1
                            c1, o_c, o_r = cost, c, r
                        elif cost < c2:
                            c2 = cost
                work += (tgt_indptr[t + 1] - tgt_indptr[t]) * n + 1
                if o_c < 0:
                    continue
                regret = c2 - c1 if np.isfinite(c2) else 1e300
                if regret > best_regret or (regret == best_regret and c1 < best_first):
                    best_regret, best_first, bc, br = regret, c1, o_c, o_r
        else:
            best = -1.0
            for c in range(nc):
                for r in range(n):
                    g = gain[c, r]
                    if g <= 0 or not np.isfinite(dt[c, r]):
                        continue
                    sc = _score(mode, float(g), dt[c, r], times[r], t_max, alpha, lam, eps)
                    if noise > 0.0:
                        sc *= 1.0 + noise * (2.0 * rnd[k % len(rnd)] - 1.0)
                        k += 1
                    if sc > best:
                        best, bc, br = sc, c, r
            work += nc * n
        if bc < 0:
            return False, work
        # insert cands[bc] into route br
        x = cands[bc]
        r = br
        p = pos[bc, r]
        for i in range(L[r], p, -1):
            R[r, i] = R[r, i - 1]
        R[r, p] = x
        L[r] += 1
        on[r, x] = True
        times[r] = time_of(R, L, r, travel, batteries, has_launch)
        # coverage and gains: what x's targets gave, taken away, and given again
        lo, hi = vis_indptr[x], vis_indptr[x + 1]
        was = np.empty(hi - lo, np.bool_)  # which of x's targets were short
        for j in range(lo, hi):
            t = vis_indices[j]
            now = met(t, dc, pc, fly, req, ex)
            was[j - lo] = now < req[t]
            if was[j - lo]:
                _add_gains(t, now, -1, gain, cand_of, cands, cnt, dc, pc, fly, req, weight,
                           tgt_indptr, tgt_indices, ex)
                work += (tgt_indptr[t + 1] - tgt_indptr[t]) * n
        apply_visit(cnt, dc, r, x, 1, vis_indptr, vis_indices)
        apply_place(pc, fly, r, x, 1, vis_indptr, vis_indices)
        for j in range(lo, hi):
            t = vis_indices[j]
            if not was[j - lo]:
                continue
            now = met(t, dc, pc, fly, req, ex)
            if now < req[t]:
                _add_gains(t, now, 1, gain, cand_of, cands, cnt, dc, pc, fly, req, weight,
                           tgt_indptr, tgt_indices, ex)
                work += (tgt_indptr[t + 1] - tgt_indptr[t]) * n
            else:
                remaining -= 1
        work += 2 * (hi - lo) + nc
        if not share:               # closed to the other UAVs from now on
            for q in range(n):
                if q != r:
                    dt[bc, q] = np.inf
        work += _slots(R, L, r, cands, nc, gain, dt, pos, on, fly, owner0, share, travel,
                       batteries, has_launch)
    return True, work


@njit(cache=True, nogil=True)
def _slots(R, L, r, cands, nc, gain, dt, pos, on, fly, owner0, share, travel, batteries,
           has_launch):
    """Cheapest insertion of each candidate into route r (``dt``, ``pos``; inf where
    it may not go). Without ``share`` only the pairs that gain now are costed (a
    gain never appears later); with it every open pair (a place added elsewhere
    can make one gain). Returns work."""
    work = 0
    route = R[r, :L[r]]
    battery = battery_of(batteries, r)
    for c in range(nc):
        if (gain[c, r] > 0 or share) and _open(cands[c], r, on, fly, owner0, share):
            dt[c, r], pos[c, r] = insert_cost(route, cands[c], travel, battery, has_launch)
            work += L[r] + 1
        else:
            dt[c, r] = np.inf
    return work


@njit(cache=True, nogil=True)
def _removable(cnt, dc, pc, fly, req, r, e, vis_indptr, vis_indices, ex):
    """Whether UAV r's visit of e can go without leaving a target short by it."""
    for j in range(vis_indptr[e], vis_indptr[e + 1]):
        t = vis_indices[j]
        d = dc[t] - (1 if cnt[r, t] == 1 else 0)
        p = pc[t] - (1 if fly[e, 0] == 1 else 0)
        after = min(d, p)
        if after > 2 and req[t] > 2 and ex[0]:
            m = fly[e, 1]
            fly[e, 1] = m & ~(1 << r)
            after = _matching(t, fly, req[t], ex)
            fly[e, 1] = m
        if after < req[t] and after < met(t, dc, pc, fly, req, ex):
            return False
    return True


@njit(cache=True, nogil=True)
def drop_redundant(R, L, times, cnt, dc, pc, fly, req, vis_indptr, vis_indices, travel,
                   batteries, has_launch, ex):
    """Remove visits coverage does not need, largest saving first (the longest
    route's first); returns work."""
    n = R.shape[0]
    work = 0
    while True:
        r_max = np.argmax(times)
        best, bi, br = -1.0, -1, -1
        for r in range(n):
            route = R[r, :L[r]]
            battery = battery_of(batteries, r)
            work += L[r]
            for i in range(L[r]):
                s = removal_saving(route, i, travel, battery, has_launch)
                if s < -1e-9:
                    continue
                key = s + (1e12 if r == r_max else 0.0)
                if key <= best:
                    continue
                e = R[r, i]
                work += (vis_indptr[e + 1] - vis_indptr[e]) // 4
                if _removable(cnt, dc, pc, fly, req, r, e, vis_indptr, vis_indices, ex):
                    best, bi, br = key, i, r
        if bi < 0:
            return work
        e = R[br, bi]
        for i in range(bi, L[br] - 1):
            R[br, i] = R[br, i + 1]
        L[br] -= 1
        R[br, L[br]] = -1
        apply_visit(cnt, dc, br, e, -1, vis_indptr, vis_indices)
        apply_place(pc, fly, br, e, -1, vis_indptr, vis_indices)
        times[br] = time_of(R, L, br, travel, batteries, has_launch)


@njit(cache=True, nogil=True)
def _prefix(a, m, travel, pf, pb):
    for i in range(1, m):
        pf[i] = pf[i - 1] + travel[a[i - 1], a[i]]
        pb[i] = pb[i - 1] + travel[a[i], a[i - 1]]


@njit(cache=True, nogil=True)
def improve_order(R, L, r, travel, lo, back, has_launch, max_passes):
    """2-opt and or-opt (segments of 1-3, either way round) on route r, O(1) per
    candidate (prefix sums of the legs both ways, so asymmetric travel is
    exact); a pass applies every improving move it meets and goes on.  Passes
    repeat until one finds nothing (at most ``max_passes``).  Returns work."""
    m = L[r]
    work = 0
    if m < 2:
        return work
    a = R[r, :m].copy()
    pf = np.zeros(m)
    pb = np.zeros(m)
    out = np.empty(m, np.int64)
    for _ in range(max_passes):
        improved = False
        _prefix(a, m, travel, pf, pb)
        # 2-opt: reverse a[i..j]
        for i in range(m - 1):
            prev = a[i - 1] if i > 0 else START
            for j in range(i + 1, m):
                nxt = a[j + 1] if j < m - 1 else END
                old = (leg(prev, a[i], travel, lo, back, has_launch) + pf[j] - pf[i]
                       + leg(a[j], nxt, travel, lo, back, has_launch))
                new = (leg(prev, a[j], travel, lo, back, has_launch) + pb[j] - pb[i]
                       + leg(a[i], nxt, travel, lo, back, has_launch))
                if new < old - 1e-9:
                    a[i:j + 1] = a[i:j + 1][::-1].copy()
                    _prefix(a, m, travel, pf, pb)
                    improved = True
                    work += 2 * m
            work += 8 * (m - i)
        # or-opt: move a[i..i+s-1] into another gap, forward or reversed
        for s in range(1, 4):
            i = 0
            while i <= m - s:
                j = i + s - 1
                prev = a[i - 1] if i > 0 else START
                nxt = a[j + 1] if j < m - 1 else END
                if prev == START and nxt == END:
                    i += 1
                    continue
                inner_f = pf[j] - pf[i]
                inner_b = pb[j] - pb[i]
                removed = (leg(prev, a[i], travel, lo, back, has_launch) + inner_f
                           + leg(a[j], nxt, travel, lo, back, has_launch)
                           - leg(prev, nxt, travel, lo, back, has_launch))
                best, best_g, best_rev = removed - 1e-9, -1, False
                for g in range(m + 1):
                    if i <= g <= j + 1:
                        continue
                    left = a[g - 1] if g > 0 else START
                    right = a[g] if g < m else END
                    base = leg(left, right, travel, lo, back, has_launch)
                    fwd = (leg(left, a[i], travel, lo, back, has_launch) + inner_f
                           + leg(a[j], right, travel, lo, back, has_launch) - base)
                    if fwd < best:
                        best, best_g, best_rev = fwd, g, False
                    if s > 1:
                        bwd = (leg(left, a[j], travel, lo, back, has_launch) + inner_b
                               + leg(a[i], right, travel, lo, back, has_launch) - base)
                        if bwd < best:
                            best, best_g, best_rev = bwd, g, True
                work += (16 if s > 1 else 10) * m
                if best_g < 0:
                    i += 1
                    continue
                w = 0
                for q in range(m + 1):
                    if q == best_g:
                        for z in range(s):
                            out[w] = a[j - z] if best_rev else a[i + z]
                            w += 1
                    if q < m and (q < i or q > j):
                        out[w] = a[q]
                        w += 1
                a[:] = out
                _prefix(a, m, travel, pf, pb)
                improved = True
                work += 2 * m
                i += 1
        if not improved:
            break
    R[r, :m] = a
    return work


NO_BACK = np.zeros(0)


@njit(cache=True, nogil=True)
def improve_sorties(R, L, r, travel, batteries, has_launch, max_passes):
    """`improve_order` on route r, one sortie at a time where a battery splits it:
    each keeps its base at both ends (the way home counted, but in the last,
    whose end is free as without sorties) and a reorder that would no longer
    fit the battery is undone. Returns work."""
    battery = battery_of(batteries, r)
    if not limited(battery) or L[r] < 2:
        return improve_order(R, L, r, travel, battery.out, NO_BACK, has_launch, max_passes)
    route = R[r, :L[r]].copy()
    _, sortie, _ = walked(route, travel, battery, True)
    work = 0
    first = 0
    one = np.empty((1, L[r]), np.int64)
    for i in range(1, L[r] + 1):
        if i < L[r] and sortie[i] == sortie[first]:
            continue
        m = i - first
        one[0, :m] = route[first:i]
        # out of its start, or of the base the sortie before landed at
        lo = battery.out if sortie[first] == 0 else \
            leaving_after(battery, route[first - 1] if first > 0 else -1)
        last = i == L[r]
        work += improve_order(one, np.array([m]), 0, travel, lo,
                              NO_BACK if last else battery.back, True, max_passes)
        trial = route.copy()
        trial[first:i] = one[0, :m]
        if route_time(trial, travel, battery, True) <= \
                route_time(route, travel, battery, True) + 1e-9:
            route = trial
        first = i
    R[r, :L[r]] = route
    return work


@njit(cache=True, nogil=True)
def restore_counts(R, L, R0, L0, cnt, dc, pc, fly, vis_indptr, vis_indices, mark):
    """Coverage counts back to the routes (R0, L0): visits in R but not R0 are
    removed, visits in R0 but not R are added (per UAV; ``mark`` is scratch of
    n_viewpoints zeros, left zero)."""
    for r in range(R.shape[0]):
        for i in range(L0[r]):
            mark[R0[r, i]] = 1
        for i in range(L[r]):
            e = R[r, i]
            if mark[e] == 1:
                mark[e] = 2  # in both
            else:
                apply_visit(cnt, dc, r, e, -1, vis_indptr, vis_indices)
                apply_place(pc, fly, r, e, -1, vis_indptr, vis_indices)
        for i in range(L0[r]):
            e = R0[r, i]
            if mark[e] == 1:
                apply_visit(cnt, dc, r, e, 1, vis_indptr, vis_indices)
                apply_place(pc, fly, r, e, 1, vis_indptr, vis_indices)
            mark[e] = 0


@njit(cache=True, nogil=True)
def savings_all(R, L, travel, batteries, has_launch):
    """Removal saving of every visit, routes in order (the `visits` order)."""
    out = np.empty(L.sum())
    k = 0
    for r in range(R.shape[0]):
        route = R[r, :L[r]]
        battery = battery_of(batteries, r)
        for i in range(L[r]):
            out[k] = removal_saving(route, i, travel, battery, has_launch)
            k += 1
    return out


@njit(cache=True, nogil=True)
def remove_visits(R, L, rs, idx, cnt, dc, pc, fly, vis_indptr, vis_indices, removed):
    """Remove visits (rs[k], idx[k]) (distinct), updating coverage; their
    viewpoints go to ``removed``; returns how many."""
    n = R.shape[0]
    k = 0
    for r in range(n):
        m = L[r]
        drop = np.zeros(m, np.bool_)
        any_ = False
        for q in range(len(rs)):
            if rs[q] == r:
                drop[idx[q]] = True
                any_ = True
        if not any_:
            continue
        w = 0
        for i in range(m):
            e = R[r, i]
            if drop[i]:
                apply_visit(cnt, dc, r, e, -1, vis_indptr, vis_indices)
                apply_place(pc, fly, r, e, -1, vis_indptr, vis_indices)
                removed[k] = e
                k += 1
            else:
                R[r, w] = e
                w += 1
        for i in range(w, m):
            R[r, i] = -1
        L[r] = w
    return k


@njit(cache=True, nogil=True)
def short_targets(removed, dc, pc, fly, req, vis_indptr, vis_indices, mark, ex):
    """Targets seen from ``removed`` viewpoints that are now short (``mark``:
    scratch of n_targets zeros, left zero)."""
    total = 0
    for e in removed:
        total += vis_indptr[e + 1] - vis_indptr[e]
    out = np.empty(total, np.int64)
    k = 0
    for e in removed:
        for j in range(vis_indptr[e], vis_indptr[e + 1]):
            t = vis_indices[j]
            if mark[t] == 0 and met(t, dc, pc, fly, req, ex) < req[t]:
                mark[t] = 1
                out[k] = t
                k += 1
    for i in range(k):
        mark[out[i]] = 0
    return out[:k]


@njit(cache=True, nogil=True)
def n_short(dc, pc, fly, req, ex):
    """How many targets are short."""
    k = 0
    for t in range(len(req)):
        if met(t, dc, pc, fly, req, ex) < req[t]:
            k += 1
    return k
