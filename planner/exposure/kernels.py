# Over 600 lines, knowingly: the ring sweep and the leg proofs share `ray_max` (the exact
# maximum over a patch, which numba inlines into both) and the safe-side argument below,
# which holds for both only as long as they use the same exact pieces.
"""numba kernels of the exposure surface (see planner.exposure.surface for the model).

Grid coordinates as in planner.exposure.los: ``u`` = column, ``v`` = row, cell centre of
(r, c) at (u, v) = (c, r); distances along a ray in grid units unless a name
ends in ``_m``.

The fast surface: a *lower bound* of the horizon slope H(P) of every cell
----------------------------------------------------------------------------
The lowest altitude an outpost sees at P is ``z0 + D H(P) + drop(D)``, H(P)
the steepest apparent slope of the terrain along the ray O -> P. Every slope
used here is the *exact* apparent slope at a point of P's *own* ray, or its
exact maximum over a stretch of it (closed form per patch, as in planner.exposure.los).
Neither is above the maximum over the whole ray, so the computed altitude is
never above the exact one (up to rounding, ~1e-10 m): safe by construction,
whatever points and stretches are chosen. The choice only decides how tight
the bound is, and that is measured (tests/test_exposure.py, benchmarks/).

Which points: a ring sweep (as in XDraw) visits cells by growing Chebyshev
distance k ("ring") from the outpost cell, in four triangular sectors (right,
down, left, up), each cut into WEDGES wedges of rays that only depend on
themselves, so wedges run in parallel. In a sector's frame a cell is (k, b);
its ray crosses the ring lines a = 1..k-1, where the bilinear surface is the
linear interpolation of two cells: an exact point for two loads. Each cell
passes on the ring of its horizon (its best point) to the next ring; a cell
  - screens the points of its ray on the ring lines of its two parents'
    horizons (the cells of ring k - 1 its ray passes between) and at itself
    (XDraw's neighbours, but on the cell's own ray; ring line k - 1 is the
    horizon of a few tenths of a percent of cells and is left to the near
    stretch below);
  - if that leaves it below the ceiling (ground + ceiling_agl, where E is
    capped) and below what earlier outposts gave it (E is their minimum), is
    refined: the exact maximum over its near stretch (ring line k - 1 to the
    cell) unless the patch's highest corner cannot beat the best point; then
    around the horizon, which drifts from ray to ray: on smooth terrain the
    ring lines either side follow it; where the terrain bends enough between
    ring lines to matter at the cell (REFINE_TOL_M, magnified by x_k / x_horizon)
    the exact maxima between the ring lines around its and its parents' horizons.
A horizon within NEAR_RINGS of the eye can peak inside a patch and is
magnified most: rays whose parents' horizon is there take that stretch exactly.
Rays of the first FULL_RINGS rings are maximised in full. Above the ceiling the
bound may be loose (it is still a lower bound); below it, it is within 2 m of
the exact value on all but a few tenths of a percent of cells
(benchmarks/bench_exposure.py).
"""

import math

import numpy as np
from numba import njit, prange, types
from numba.core import cgutils
from numba.extending import intrinsic

from .los import EARTH_RADIUS_M, EYE_GAP_M, gap_range, line_over_patch, next_patch, sees

FULL_RINGS = 4  # rings around the outpost whose rays are evaluated exactly in full
WEDGES = 4  # wedges per sector: tasks for the threads
NEAR_RINGS = 2  # horizons this close to the eye (rings) are taken exactly
REFINE_TOL_M = 1.0  # terrain bending less than this (seen at the cell): ring lines suffice
NEAR_BIT = 1 << 20  # flag in a cell's horizon ring: its horizon is that close
RING_MASK = NEAR_BIT - 1


# --- exact maximum of the apparent slope over part of a ray ---------------------------

@njit(cache=True, inline="always")
def _piece(h, i, j, u0, v0, du, dv, ta, tb, z0, length_m, curv):
    """(max, argmax t) over t in [ta, tb] of the apparent slope on patch (i, j).

    Along the line the bilinear surface is c0 + c1 t + c2 t^2 and the slope
    is (a t + c1 + e / t) / length_m, a = c2 - curv L^2 / 2R, e = c0 - z0,
    whose only interior stationary point is t* = sqrt(e / a).
    """
    c0, c1, c2 = line_over_patch(h, i, j, u0, v0, du, dv)
    a = c2 - curv * length_m * length_m / (2.0 * EARTH_RADIUS_M)
    e = c0 - z0
    best = (a * ta + c1 + e / ta) / length_m
    t_best = ta
    s = (a * tb + c1 + e / tb) / length_m
    if s > best:
        best = s
        t_best = tb
    if a != 0.0 and e / a > 0.0:
        ts = math.sqrt(e / a)
        if ta < ts < tb:
            s = (a * ts + c1 + e / ts) / length_m
            if s > best:
                best = s
                t_best = ts
    return best, t_best


@njit(cache=True)
def ray_max(h, cell, u0, v0, z0, u1, v1, ta, tb, curv):
    """Exact (max, argmax t) of the apparent slope seen from (u0, v0, z0) along
    the segment to (u1, v1), over t in [ta, tb] (tb <= 1); (-inf, ta) if empty.

    Patches touching a NaN height are skipped, as in planner.exposure.los.max_slope.
    """
    n_rows, n_cols = h.shape
    du = u1 - u0
    dv = v1 - v0
    length_m = cell * math.sqrt(du * du + dv * dv)
    best = -np.inf
    t_best = ta
    if length_m <= 0.0:
        return best, t_best
    t = max(ta, EYE_GAP_M / length_m)
    while t < tb:
        i, j, t_next = next_patch(u0, v0, du, dv, t, n_rows, n_cols)
        t_next = min(t_next, tb)
        s, ts = _piece(h, i, j, u0, v0, du, dv, t, t_next, z0, length_m, curv)
        if s > best:
            best = s
            t_best = ts
        t = t_next
    return best, t_best


# --- the ring sweep ----------------------------------------------------------------------

@njit(cache=True, inline="always")
def _sector_frame(q, c_o, r_o, n_rows, n_cols):
    """Sector q's frame: cell (a, b) (a = ring, b across it) is at flat index
    r_o * n_cols + c_o + sa * a + sb * b. Returns the last ring inside the
    grid, the range of b inside it, sa and sb."""
    if q == 0:  # (dc, dr) = (a, b)
        return n_cols - 1 - c_o, -r_o, n_rows - 1 - r_o, 1, n_cols
    if q == 1:  # (dc, dr) = (-b, a)
        return n_rows - 1 - r_o, c_o - (n_cols - 1), c_o, n_cols, -1
    if q == 2:  # (dc, dr) = (-a, -b)
        return c_o, r_o - (n_rows - 1), r_o, -1, -n_cols
    return r_o, -c_o, n_cols - 1 - c_o, -n_cols, 1  # (dc, dr) = (b, -a)


@njit(cache=True, inline="always")
def _rotate(q, a, b):
    """Sector q's (a, b) -> grid offset (dc, dr), as in _sector_frame."""
    if q == 0:
        return a, b
    if q == 1:
        return -b, a
    if q == 2:
        return -a, -b
    return b, -a


@njit(cache=True, inline="always")
def _interval(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, inv_m, a, z0, cc):
    """Exact (max, argmax X) of the scaled apparent slope of P's ray between
    ring lines a and a + 1 (a >= 0, a + 1 <= P's ring), from 1e-3 rings
    beyond the eye on (the stretch at the eye itself is ray_max's).

    X = distance from the outpost in rings (a - fa at ring line a).
    The ray crosses at most a couple of lines across the sector; on each patch
    the bilinear surface along it is q0 + q1 X + q2 X^2, and the scaled slope
    (T - z0 - cc X^2) / X = (q2 - cc) X + q1 + (q0 - z0) / X peaks at an end
    or, where it is concave (both terms negative), at X* = sqrt((q0 - z0) / (q2 - cc)).
    """
    xl = a - fa  # the ring line
    x1 = max(xl, 1e-3)  # not at the eye itself: (T - z0) / X would be rounding noise
    x2 = xl + 1.0
    if x2 <= x1:
        return -np.inf, x1
    y1 = fb + x1 * m
    y2 = fb + x2 * m
    j_lo = int(math.floor(min(y1, y2)))
    j_hi = int(math.floor(max(y1, y2)))
    best = -np.inf
    x_best = x1
    for j in range(j_lo, j_hi + 1):
        xa = x1
        xb = x2
        if j_hi > j_lo:  # the part of [x1, x2] where j <= y <= j + 1
            ya = (j - fb) * inv_m
            yb = (j + 1 - fb) * inv_m
            xa = max(x1, min(ya, yb))
            xb = min(x2, max(ya, yb))
            if xb < xa:
                continue
        jj = min(max(j, b_lo), b_hi - 1)
        i00 = base + sa * a + sb * jj
        h00 = hf[np.uint64(i00)]
        cx = hf[np.uint64(i00 + sa)] - h00
        cy = hf[np.uint64(i00 + sb)] - h00
        cxy = -cx - hf[np.uint64(i00 + sb)] + hf[np.uint64(i00 + sa + sb)]
        b0 = fb - jj  # across-coordinate in the patch: b0 + m X; along: X - xl
        q0 = h00 - cx * xl + cy * b0 - cxy * xl * b0
        q1 = cx + cy * m + cxy * (b0 - xl * m)
        slope_a = cxy * m - cc
        e = q0 - z0
        best, x_best = _higher(slope_a * xa + q1 + e / xa, xa, best, x_best)
        best, x_best = _higher(slope_a * xb + q1 + e / xb, xb, best, x_best)
        if slope_a < 0.0 and e < 0.0:  # concave: may peak inside
            xs = math.sqrt(e / slope_a)
            if xa < xs < xb:
                best, x_best = _higher(slope_a * xs + q1 + e / xs, xs, best, x_best)
    return best, x_best


@njit(cache=True, inline="always")
def _higher(s, x, best, x_best):
    """(slope, where) of the higher of a new point and the best so far, as a
    select rather than a branch (see _better)."""
    gt = s > best
    return (s if gt else best), (x if gt else x_best)


@njit(cache=True, inline="always")
def _cross(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, a, z0, cc, inv_a):
    """Scaled apparent slope where P's ray crosses ring line a (1 <= a < P's
    ring): the linear interpolation of ring a's two cells either side."""
    x = a - fa
    y = fb + x * m
    j = min(max(int(math.floor(y)), b_lo), b_hi - 1)
    i = base + sa * a + sb * j
    # unsigned indices: numba then skips its negative-index wraparound (measured
    # ~15 % of the sweep)
    h0 = hf[np.uint64(i)]
    t = h0 + (y - j) * (hf[np.uint64(i + sb)] - h0)
    return (t - z0) * inv_a[np.uint64(a)] - cc * x


@njit(cache=True, inline="always")
def _bend_at(y, b_lo, b_hi):
    """The cell across ring lines where _bend looks for b = y."""
    return min(max(int(math.floor(y)), b_lo + 1), b_hi - 2)


@njit(cache=True, inline="always")
def _bend(hf, base, sa, sb, b_lo, b_hi, a, j):
    """How far the terrain around cell (a, j .. j + 1) can rise above a straight
    line between points a cell apart: a quarter of its largest second difference
    (along and across the rings, and the patches' twist)."""
    if b_hi - b_lo < 3:
        return np.inf  # too narrow to look around: take it exactly
    i = base + sa * a + sb * j
    h0 = hf[np.uint64(i)]
    h1 = hf[np.uint64(i + sb)]
    d = abs(hf[np.uint64(i - sa)] - 2.0 * h0 + hf[np.uint64(i + sa)])
    d = max(d, abs(hf[np.uint64(i - sa + sb)] - 2.0 * h1 + hf[np.uint64(i + sa + sb)]))
    d = max(d, abs(hf[np.uint64(i - sb)] - 2.0 * h0 + h1))
    d = max(d, abs(h0 - 2.0 * h1 + hf[np.uint64(i + 2 * sb)]))
    d = max(d, abs(hf[np.uint64(i + sa + sb)] - hf[np.uint64(i + sa)] - h1 + h0))
    d = max(d, abs(h1 - h0 - hf[np.uint64(i - sa + sb)] + hf[np.uint64(i - sa)]))
    return 0.25 * d


@njit(cache=True, inline="always")
def _near_patch_bound(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, k, z0, cc, inv_a):
    """Upper bound of the scaled apparent slope over P's near stretch (ring
    line k - 1 to P): it crosses one patch, the surface is at most its highest
    corner, and 1 / x and -cc x are largest at ring line k - 1."""
    j = min(max(int(math.floor(fb + (k - 1 - fa) * m)), b_lo), b_hi - 1)
    i = base + sa * (k - 1) + sb * j
    top = max(max(hf[np.uint64(i)], hf[np.uint64(i + sb)]),
              max(hf[np.uint64(i + sa)], hf[np.uint64(i + sa + sb)]))
    inv = inv_a[np.uint64(k - 1)] if top >= z0 else inv_a[np.uint64(k)]
    return (top - z0) * inv - cc * (k - 1 - fa)


@njit(cache=True, inline="always")
def _beyond(b, fb, ia, x_k, r2):
    """Whether cell b of the ring at x_k is out of range."""
    m = (b - fb) * ia
    return x_k * x_k * (1.0 + m * m) > r2


@njit(cache=True, inline="always")
def _better(a, s, best, a_best):
    """(slope, ring) of the higher of a new point and the best so far.

    Without a branch: on rough terrain which point wins is a coin toss, and the
    mispredictions measured 20 % of the sample's sweep."""
    gt = s > best
    return (s if gt else best), a_best + np.int64(gt) * (a - a_best)


@njit(cache=True, inline="always")
def _wedge_ring(k, m_lo, m_hi, first, last, b_lo, b_hi):
    """Cells b_first..b_last of ring k with m_lo <= b / k < m_hi (the first and
    last wedges reach the sector's edges), inside the grid. By the cell, not
    the eye's offset (fa, fb): a re-planned outpost a rounding error away must
    get the same wedges."""
    lo = -k + 1 if first else int(math.ceil(k * m_lo))
    hi = k if last else int(math.ceil(k * m_hi)) - 1
    return max(lo, -k + 1, b_lo), min(hi, k, b_hi)


# FMA contraction only (one rounding where there were two, ~1e-13 m): 9-16 % faster
# on every bench row, the same tightness; no other fast-math flag (inf and NaN matter).
# error_model="numpy": no check before each division (none divides by zero; 1-2 %)
@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def _sweep_wedge(h, cell, hf, acc, q, c_o, r_o, u0, v0, z0, base, sa, sb, a_last, b_lo, b_hi,
                 fa, fb, k_cc, curv, inv_a, r2, cap_agl, m_lo, m_hi, first, last, fresh, fprev,
                 fcur, todo_b, todo_s):
    """Lower the lowest seen altitudes ``acc`` (flat) over one wedge of sector q
    (``fresh``: write them, acc holds nothing yet).

    fprev / fcur: scratch, the horizon ring of each cell of rings k - 1 and k
    by b (+ NEAR_BIT when next to the eye; 0 = none, as the eye's ring);
    todo_b / todo_s: scratch, ring k's cells to refine and their screened
    slopes (refined after the screen of the whole ring, which measured faster
    than in line).
    """
    off = a_last + 1
    plo, phi = 0, -1  # ring k - 1's cells in this wedge
    hz0 = np.empty_like(fcur)  # the horizons of each cell's two parents, by b
    hz1 = np.empty_like(fcur)
    for k in range(1, a_last + 1):
        lo, hi = _wedge_ring(k, m_lo, m_hi, first, last, b_lo, b_hi)
        x_k = k - fa
        ia = inv_a[k]
        if k <= FULL_RINGS:
            _full_rays(h, cell, acc, q, c_o, r_o, u0, v0, z0, base, sa, sb, fa, fb, k_cc,
                       curv, ia, r2, k, lo, hi, off, fresh, fcur)
            plo, phi = lo, hi
            fprev, fcur = fcur, fprev
            continue
        if plo > phi:  # no parents in this wedge: a dummy slot holding no horizon
            plo = phi = -off
            fprev[0] = 0
        # cells out of range are at the ends of the ring (distance grows with |b - fb|)
        first_b, last_b = lo, hi
        while first_b <= last_b and _beyond(first_b, fb, ia, x_k, r2):
            fcur[first_b + off] = 0
            first_b += 1
        while last_b >= first_b and _beyond(last_b, fb, ia, x_k, r2):
            fcur[last_b + off] = 0
            last_b -= 1
        # the parents' horizons first, in a loop of their own: a cell's chain of
        # dependent steps (parent, its horizon, the crossing there, its heights)
        # is longer than the processor can overlap across cells; split in two it
        # overlaps (measured 12-17 % faster on every bench row)
        for b in range(first_b, last_b + 1):
            m = (b - fb) * ia
            p0 = min(max(int(math.floor(fb + (k - 1 - fa) * m)), plo), phi)
            hz0[np.uint64(b + off)] = fprev[np.uint64(p0 + off)]
            hz1[np.uint64(b + off)] = fprev[np.uint64(min(p0 + 1, phi) + off)]
        n_todo = 0
        for b in range(first_b, last_b + 1):
            m = (b - fb) * ia
            cc = k_cc * (1.0 + m * m)
            f0 = hz0[np.uint64(b + off)]
            f1 = hz1[np.uint64(b + off)]
            c0 = max(f0 & RING_MASK, 1)  # ring k - 1 hands on rings up to k - 1
            c1 = max(f1 & RING_MASK, 1)
            i = np.uint64(base + sa * k + sb * b)
            g = hf[i]
            # the cell itself and the parents' horizons (c0 even when it is k - 1: no
            # branch to mispredict). Not ring line k - 1 otherwise: it is the horizon
            # of 0.2-0.3 % of cells, and those below the ceiling get it exactly from
            # the near stretch below
            best = (g - z0) * ia - cc * x_k
            a_best = k
            s = _cross(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, c0, z0, cc, inv_a)
            best, a_best = _better(c0, s, best, a_best)
            # c1 on ring line k - 1 is left out too: taking it there makes it the
            # horizon handed on, which skips the windows around the real one
            # (measured: 300 rough terrains 98.75 -> 98.69 % within 2 m)
            if c1 != c0 and c1 != k - 1:
                s = _cross(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, c1, z0, cc, inv_a)
                best, a_best = _better(c1, s, best, a_best)
            z = z0 + x_k * best + cc * x_k * x_k
            fcur[np.uint64(b + off)] = a_best | ((f0 | f1) & NEAR_BIT)  # near if a parent is
            # a fresh grid is not read: reading lines another core wrote last, then
            # writing them, measured 22 % of a first outpost's sweep on the sample
            # terrain (none measurable on 1024^2, which does not fit in cache)
            low = np.inf if fresh else acc[i]
            if z < min(g + cap_agl, low):  # it matters: refine it below
                todo_b[n_todo] = b
                todo_s[n_todo] = best
                n_todo += 1
            elif z < low:
                acc[i] = z
            elif fresh:
                acc[i] = np.inf  # a void cell (z is NaN): unseen, as when not fresh
        a_bent, j_bent, bend = -1, 0, 0.0
        for n in range(n_todo):
            b = todo_b[n]
            best = todo_s[n]
            f = fcur[np.uint64(b + off)]
            near = f >= NEAR_BIT
            a_best = f & RING_MASK
            a0 = a_best
            m = (b - fb) * ia
            cc = k_cc * (1.0 + m * m)
            i = np.uint64(base + sa * k + sb * b)
            inv_m = 1.0 / m if m != 0.0 else np.inf
            # the near stretch: exactly, unless its patch's highest corner could
            # not outdo the best point
            if _near_patch_bound(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, k, z0, cc,
                                 inv_a) > best:
                s, x = _interval(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, inv_m, k - 1, z0,
                                 cc)
                best, a_best = _better(int(math.floor(x + fa + 0.5)), s, best, a_best)
            if 2 <= a0 <= k - 2:
                # around the horizon, which drifts from ray to ray: on smooth terrain
                # the ring lines either side find it; where the terrain bends enough
                # between them to matter at the cell (times x_k / x_horizon), exact
                # maxima around the horizons of the cell and of its parents
                j = _bend_at(fb + (a0 - fa) * m, b_lo, b_hi)
                if a0 != a_bent or j != j_bent:  # neighbours often share it
                    bend = _bend(hf, base, sa, sb, b_lo, b_hi, a0, j)
                    a_bent, j_bent = a0, j
                if bend * x_k * inv_a[np.uint64(a0)] <= REFINE_TOL_M:
                    s = _cross(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, a0 - 1, z0, cc, inv_a)
                    best, a_best = _better(a0 - 1, s, best, a_best)
                    s = _cross(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, a0 + 1, z0, cc, inv_a)
                    best, a_best = _better(a0 + 1, s, best, a_best)
                else:
                    c0 = hz0[np.uint64(b + off)] & RING_MASK
                    c1 = hz1[np.uint64(b + off)] & RING_MASK
                    for n_ring in range(3):
                        r = a0 if n_ring == 0 else (c0 if n_ring == 1 else c1)
                        if r < 1 or r > k - 2 or (n_ring >= 1 and abs(r - a0) <= 1) or (
                                n_ring == 2 and abs(r - c0) <= 1):
                            continue
                        for a in range(r - 1, min(r + 1, k - 1)):
                            s, x = _interval(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, inv_m, a,
                                             z0, cc)
                            best, a_best = _better(int(math.floor(x + fa + 0.5)), s, best,
                                                   a_best)
            if near:  # next to the eye a horizon peaks inside a patch: take it exactly,
                # from a millimetre off the eye as planner.exposure.los does (a 0 m eye on a
                # rise is blocked by the first centimetres), up to ring line NEAR_RINGS
                dc, dr = _rotate(q, k, b)
                s, x = ray_max(h, cell, u0, v0, z0, c_o + dc, r_o + dr, 0.0,
                               min((NEAR_RINGS - fa) / x_k, 1.0), curv)
                s_near = s * cell * math.sqrt(1.0 + m * m)  # per metre -> scaled
                # still the horizon, or a sampled point there is (computed another
                # way it may tie s_near to within rounding)
                near = s_near >= best or a_best <= NEAR_RINGS
                best = max(best, s_near)
            z = z0 + x_k * best + cc * x_k * x_k
            fcur[np.uint64(b + off)] = a_best + NEAR_BIT if near else a_best
            if fresh or z < acc[i]:
                acc[i] = z
        plo, phi = lo, hi
        fprev, fcur = fcur, fprev


@njit(cache=True)
def _full_rays(h, cell, acc, q, c_o, r_o, u0, v0, z0, base, sa, sb, fa, fb, k_cc, curv, ia, r2,
               k, lo, hi, off, fresh, fcur):
    """Cells lo..hi of ring k (one of the first FULL_RINGS): the exact maximum
    over the whole ray, and its ring."""
    x_k = k - fa
    for b in range(lo, hi + 1):
        fcur[b + off] = 0
        if _beyond(b, fb, ia, x_k, r2):
            continue
        m = (b - fb) * ia
        dc, dr = _rotate(q, k, b)
        s, t = ray_max(h, cell, u0, v0, z0, c_o + dc, r_o + dr, 0.0, 1.0, curv)
        z = z0 + x_k * s * cell * math.sqrt(1.0 + m * m) + k_cc * (1.0 + m * m) * x_k * x_k
        a = min(max(int(math.floor(fa + t * x_k + 0.5)), 0), k)
        fcur[b + off] = a + NEAR_BIT if t * x_k < NEAR_RINGS else a
        i = base + sa * k + sb * b
        if fresh or z < acc[i]:
            acc[i] = z


@njit(cache=True, inline="always")
def _eye_frame(q, u0, v0, c_o, r_o):
    """The eye's offset from its cell centre in sector q's frame (fa, fb)."""
    fu = u0 - c_o
    fv = v0 - r_o
    if q == 0:
        return fu, fv
    if q == 1:
        return fv, -fu
    if q == 2:
        return -fu, -fv
    return -fv, fu


@njit(cache=True)
def _wedge_cells(a_last, m_lo, m_hi, first, last, b_lo, b_hi):
    """How many cells a wedge holds: its share of the work."""
    n = 0
    for k in range(1, a_last + 1):
        lo, hi = _wedge_ring(k, m_lo, m_hi, first, last, b_lo, b_hi)
        n += max(hi - lo + 1, 0)
    return n


@njit(cache=True, inline="always")
def _last_ring(a_end, range_cells):
    """The last ring to sweep: the grid's edge, or just beyond the range."""
    if range_cells + 2.0 < a_end:
        return int(range_cells + 2.0)
    return a_end


@njit(cache=True, inline="always")
def _wedge_slopes(w):
    """Wedge w's range of b / k: equal slices of the sector's [-1, 1]."""
    return -1.0 + 2.0 * w / WEDGES, -1.0 + 2.0 * (w + 1) / WEDGES


@njit(cache=True, parallel=True)
def lowest_seen_into(h, cell, eye, curv, cap_agl, acc, n_slots, fresh):
    """acc = min(acc, a lower bound of the lowest altitude the eye
    (u, v, z_eye, range_m) sees at each cell), tight where below both
    ``cap_agl`` above the ground and acc's old value (elsewhere the minimum, or
    E capped, does not need it); ``fresh``: acc's old values are ignored (as if
    +inf). The outpost's own cell is seen at any altitude (-inf). Wedges run in
    parallel on ``n_slots`` threads, each taking the next wedge, the largest
    first, when it is done with one: refinement makes some wedges cost more per
    cell, and a split made in advance by cell counts lost up to a fifth of two
    threads' time.
    """
    n_rows, n_cols = h.shape
    hf = h.ravel()
    af = acc.ravel()
    u0, v0, z0, range_m = eye[0], eye[1], eye[2], eye[3]
    if fresh and not (math.isinf(range_m) and n_rows >= 2 and n_cols >= 2):
        for r in prange(n_rows):  # cells the sweep does not reach
            acc[r, :] = np.inf
    c_o = min(max(int(math.floor(u0 + 0.5)), 0), n_cols - 1)
    r_o = min(max(int(math.floor(v0 + 0.5)), 0), n_rows - 1)
    af[r_o * n_cols + c_o] = -np.inf
    range_cells = range_m / cell
    n_w = 4 * WEDGES
    counts = np.zeros(n_w, np.int64)
    for q in range(4):
        a_end, b_lo, b_hi, sa, sb = _sector_frame(q, c_o, r_o, n_rows, n_cols)
        a_last = _last_ring(a_end, range_cells)
        for w in range(WEDGES):
            m_lo, m_hi = _wedge_slopes(w)
            if a_last >= 1 and b_hi > b_lo:
                counts[q * WEDGES + w] = _wedge_cells(a_last, m_lo, m_hi, w == 0,
                                                      w == WEDGES - 1, b_lo, b_hi)
    order = np.argsort(-counts)  # the largest first, each to the next free thread
    k_cc = curv * cell * cell / (2.0 * EARTH_RADIUS_M)
    r2 = range_cells * range_cells * (1.0 + 1e-9)  # at the limit: in range (safe side)
    taken = np.zeros(1, np.int64)
    for slot in prange(n_slots):
        width = 2 * max(n_rows, n_cols) + 8
        fprev = np.zeros(width, np.int32)
        fcur = np.zeros(width, np.int32)
        todo_b = np.empty(width, np.int64)
        todo_s = np.empty(width)
        n = _fetch_add(taken, 1)
        while n < n_w and counts[order[n]] > 0:
            q = order[n] // WEDGES
            w = order[n] % WEDGES
            a_end, b_lo, b_hi, sa, sb = _sector_frame(q, c_o, r_o, n_rows, n_cols)
            a_last = _last_ring(a_end, range_cells)
            fa, fb = _eye_frame(q, u0, v0, c_o, r_o)
            inv_a = np.empty(a_last + 1)
            inv_a[0] = 0.0
            for a in range(1, a_last + 1):
                inv_a[a] = 1.0 / (a - fa)
            m_lo, m_hi = _wedge_slopes(w)
            _sweep_wedge(h, cell, hf, af, q, c_o, r_o, u0, v0, z0, r_o * n_cols + c_o, sa, sb,
                         a_last, b_lo, b_hi, fa, fb, k_cc, curv, inv_a, r2, cap_agl, m_lo, m_hi,
                         w == 0, w == WEDGES - 1, fresh, fprev, fcur, todo_b, todo_s)
            n = _fetch_add(taken, 1)


@intrinsic
def _fetch_add(typingctx, counter, value):
    """Atomically counter[0] += value; returns the old counter[0]."""
    def codegen(context, builder, sig, args):
        ary = context.make_array(sig.args[0])(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, sig.args[0], ary,
                                       [context.get_constant(types.intp, 0)])
        return builder.atomic_rmw("add", ptr, args[1], "seq_cst")
    return types.int64(counter, types.int64), codegen


# --- points -----------------------------------------------------------------------------------

@njit(cache=True, parallel=True)
def points_hidden(h, cell, eyes, pts, curv):
    """Exact: for each point (u, v, z), that no eye (u, v, z, range_m) sees it."""
    out = np.ones(pts.shape[0], np.bool_)
    for k in prange(pts.shape[0]):
        for o in range(eyes.shape[0]):
            if sees(h, cell, eyes[o, 0], eyes[o, 1], eyes[o, 2], pts[k, 0], pts[k, 1],
                    pts[k, 2], eyes[o, 3], curv):
                out[k] = False
                break
    return out


# --- proving a straight 3-D leg hidden -----------------------------------------------------

@njit(cache=True)
def patch_gradient_bound(h, cell):
    """Max |grad| (m/m) of the bilinear surface over each patch; inf next to voids.

    The gradient is affine on a patch, so |grad| is convex and peaks at a corner.
    """
    n_rows, n_cols = h.shape
    g = np.empty((n_rows - 1, n_cols - 1))
    for j in range(n_rows - 1):
        for i in range(n_cols - 1):
            h00 = h[j, i]
            h10 = h[j, i + 1]
            h01 = h[j + 1, i]
            h11 = h[j + 1, i + 1]
            cx = h10 - h00
            cy = h01 - h00
            cxy = h00 - h10 - h01 + h11
            m = 0.0
            for cu in range(2):
                for cv in range(2):
                    gx = cx + cxy * cv
                    gy = cy + cxy * cu
                    m = max(m, math.sqrt(gx * gx + gy * gy))
            g[j, i] = m / cell if m == m else np.inf
    return g


@njit(cache=True, inline="always")
def _local_gradient(grad, g_max, u, v, rho):
    """Max gradient over the patches within rho (grid units) of (u, v)."""
    if rho > 3.0:
        return g_max
    n_j, n_i = grad.shape
    i0 = min(max(int(math.floor(u - rho)), 0), n_i - 1)
    i1 = min(max(int(math.floor(u + rho)), 0), n_i - 1)
    j0 = min(max(int(math.floor(v - rho)), 0), n_j - 1)
    j1 = min(max(int(math.floor(v + rho)), 0), n_j - 1)
    m = 0.0
    for j in range(j0, j1 + 1):
        for i in range(i0, i1 + 1):
            if grad[j, i] > m:
                m = grad[j, i]
    return m


#: a piece's proof first tries the terrain within this many cells of a hinted horizon
HINT_CELLS = 2.0
PROVEN, SEEN, UNPROVEN = 1, 0, -1


@njit(cache=True, inline="always")
def _piece_proof(h, cell, grad, g_max, u0, v0, z0, um, vm, zm, d_m, ta, tb, curv, half_h,
                 half_z, r_max):
    """(PROVEN | SEEN | UNPROVEN, t) of a piece of a leg (see `_leg_hidden_from`) by
    the highest terrain point of the ray to its midpoint over t in [ta, tb], at t.
    SEEN (the midpoint is seen) is certain only when [ta, tb] is the whole ray."""
    s, t = ray_max(h, cell, u0, v0, z0, um, vm, ta, tb, curv)
    margin = z0 + d_m * s + curv * d_m * d_m / (2.0 * EARTH_RADIUS_M) - zm
    if not (margin > 0.0):
        return SEEN, t
    rho = t * half_h / cell
    lip = _local_gradient(grad, g_max, u0 + t * (um - u0), v0 + t * (vm - v0), rho)
    need = (lip + 2.0 * curv * r_max / EARTH_RADIUS_M) * half_h + half_z
    if margin > need * (1.0 + 1e-9) + 1e-6:
        return PROVEN, t
    return UNPROVEN, t


MAX_PIECES = 4000  # pieces per leg and outpost before giving up (answer: not proven)
MIN_PIECE_M = 1e-3


@njit(cache=True)
def _leg_hidden_from(h, cell, grad, g_max, eye, a, b, curv, slack_m, hint):
    """(hidden, horizon): whether every point within ``slack_m`` (horizontally) of
    the leg a -> b ((u, v, z), grid units and m AMSL) is hidden from one eye
    (u, v, z, range_m), and the distance (m) from the eye of the horizon of the
    whole leg: found by walking its ray, else ``hint``. Conservative: False when
    not proven.

    A piece of the leg is proven by its midpoint m: if the terrain point X* at
    fraction t* of the ray O -> m (its horizon) rises `margin` = zmin(m) - z(m)
    above the sight line at the same fraction, then for a point p of the piece
    (horizontal offset dh <= half_h, vertical dz <= half_z) the ray O -> p
    passes X' = X* + t* dh, where the terrain is at most L t* dh lower
    (L: gradient bound within t* half_h of X*) and the sight line at most
    t* dz higher, curvature terms changing by at most 2 curv r_max dh t* / R.
    Dividing by t*, p is hidden when
        margin > (L + 2 curv r_max / R) half_h + half_z.
    With a slack, half_h grows by ``slack_m`` and ranges by as much, so that
    the leg's ends may move that far (e.g. rounded to degE7) and stay hidden.
    Pieces that fail are halved; a midpoint seen (margin <= 0) ends the test.
    The terrain proof does not need the range: a piece across an outpost's range
    circle with its midpoint beyond it is proven by the terrain too, or halved
    (halving alone never ends at the circle: it gave up at a millimetre).

    The proof holds for any terrain point X on the ray, not only the horizon,
    so a piece is first tried with the highest slope within `HINT_CELLS` of the
    distance ``hint`` (m; NaN: none) from the eye, a few patches instead of the
    whole ray: legs next to each other share their horizon (``hint`` is the
    horizon of a neighbouring leg, then of the whole leg). Only when that fails
    is the whole ray walked, as without a hint, so a hint never loses a proof.
    """
    u0, v0, z0, range_m = eye[0], eye[1], eye[2], eye[3]
    stack_a = np.empty(64)
    stack_b = np.empty(64)
    stack_a[0] = 0.0
    stack_b[0] = 1.0
    top = 1
    pieces = 0
    leg_h = cell * math.sqrt((b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2)
    leg_z = abs(b[2] - a[2])
    horizon = hint  # replaced by the whole leg's horizon if its ray is walked
    walked = False
    while top > 0:
        top -= 1
        sa = stack_a[top]
        sb = stack_b[top]
        pieces += 1
        if pieces > MAX_PIECES:
            return False, horizon
        # horizontal distance from the outpost to the piece's ends and nearest point
        ua = a[0] + sa * (b[0] - a[0])
        va = a[1] + sa * (b[1] - a[1])
        ub = a[0] + sb * (b[0] - a[0])
        vb = a[1] + sb * (b[1] - a[1])
        ex = ub - ua
        ey = vb - va
        ee = ex * ex + ey * ey
        w = 0.0
        if ee > 0.0:
            w = min(max(((u0 - ua) * ex + (v0 - va) * ey) / ee, 0.0), 1.0)
        r_near = cell * math.sqrt((ua + w * ex - u0) ** 2 + (va + w * ey - v0) ** 2)
        if r_near > range_m + slack_m:
            continue  # the whole piece is out of range
        r_max = cell * max(math.sqrt((ua - u0) ** 2 + (va - v0) ** 2),
                           math.sqrt((ub - u0) ** 2 + (vb - v0) ** 2))
        sm = 0.5 * (sa + sb)
        um = a[0] + sm * (b[0] - a[0])
        vm = a[1] + sm * (b[1] - a[1])
        zm = a[2] + sm * (b[2] - a[2])
        half_h = 0.5 * (sb - sa) * leg_h + slack_m
        half_z = 0.5 * (sb - sa) * leg_z
        d_m = cell * math.sqrt((um - u0) ** 2 + (vm - v0) ** 2)
        if d_m == 0.0:
            return False, horizon  # straight above the outpost
        # from 1e-3 grid units on: at the eye (T - z0) / d is rounding noise, and a
        # shorter stretch only lowers zmin (conservative)
        t_eye = 1e-3 * cell / d_m
        if hint == hint:
            lo = max(t_eye, (hint - HINT_CELLS * cell) / d_m)
            hi = min(1.0, (hint + HINT_CELLS * cell) / d_m)
            if lo < hi and _piece_proof(h, cell, grad, g_max, u0, v0, z0, um, vm, zm, d_m,
                                        lo, hi, curv, half_h, half_z, r_max)[0] == PROVEN:
                continue
        found, t = _piece_proof(h, cell, grad, g_max, u0, v0, z0, um, vm, zm, d_m,
                                t_eye, 1.0, curv, half_h, half_z, r_max)
        hint = d_m * t
        if not walked:
            horizon, walked = hint, True
        if found == PROVEN:
            continue
        if found == SEEN and d_m <= range_m + slack_m:
            return False, horizon  # the midpoint is seen
        if half_h - slack_m + half_z < MIN_PIECE_M or top + 2 > stack_a.shape[0]:
            return False, horizon  # grazing: not provable at this resolution
        stack_a[top] = sa
        stack_b[top] = sm
        stack_a[top + 1] = sm
        stack_b[top + 1] = sb
        top += 2
    return True, horizon


@njit(cache=True, parallel=True)
def legs_hidden(h, cell, grad, eyes, a, b, curv, slack_m, horizons):
    """segment hidden from every eye, for each leg a[k] -> b[k] ((u, v, z) rows).

    ``horizons`` [n legs, n eyes]: in, a hinted horizon distance (m; NaN: none)
    of each leg from each eye (`_leg_hidden_from`); out, the horizon of the whole
    leg (found, else the hint; NaN after an eye that saw the leg)."""
    n = a.shape[0]
    out = np.zeros(n, np.bool_)
    g_max = 0.0
    for j in range(grad.shape[0]):
        for i in range(grad.shape[1]):
            g_max = max(g_max, grad[j, i])
    for k in prange(n):
        ok = True
        for o in range(eyes.shape[0]):
            hidden, horizons[k, o] = _leg_hidden_from(h, cell, grad, g_max, eyes[o], a[k],
                                                      b[k], curv, slack_m, horizons[k, o])
            if not hidden:
                ok = False
                for rest in range(o + 1, eyes.shape[0]):
                    horizons[k, rest] = np.nan
                break
        out[k] = ok
    return out


# --- clearance above the terrain ---------------------------------------------------------------

@njit(cache=True, parallel=True)
def legs_height_range(h, a, b):
    """(min, max) over each leg a[k] -> b[k] ((u, v, z)) of altitude minus the
    bilinear terrain (planner.exposure.los.gap_range), as [n, 2]; NaN next to a void."""
    out = np.empty((a.shape[0], 2))
    for k in prange(a.shape[0]):
        lo, hi = gap_range(h, a[k, 0], a[k, 1], a[k, 2], b[k, 0], b[k, 1], b[k, 2], False)
        out[k, 0] = lo
        out[k, 1] = hi
    return out
