"""numba kernels of the exposure surface (see planner.exposure for the model).

Grid coordinates as in planner.los: ``u`` = column, ``v`` = row, cell centre of
(r, c) at (u, v) = (c, r); distances along a ray in grid units unless a name
ends in ``_m``.

The fast surface: a *lower bound* of the horizon slope H(P) of every cell
----------------------------------------------------------------------------
The lowest altitude an outpost sees at P is ``z0 + D H(P) + drop(D)``, H(P)
the steepest apparent slope of the terrain along the ray O -> P. Every slope
used here is the *exact* apparent slope at a point, or its exact maximum over a
stretch (closed form per patch, as in planner.los), of P's *own* ray. The
maximum over part of the ray is never above the maximum over the whole ray, so the computed
altitude is never above the exact one (up to rounding, ~1e-10 m): safe by
construction, whatever stretches are chosen. The choice only decides how tight
the bound is, and that is measured (tests/test_exposure.py, benchmarks/).

Which stretches: a ring sweep (as in XDraw) visits cells by growing Chebyshev
distance k ("ring") from the outpost cell, in four triangular sectors (right,
down, left, up) that depend only on themselves, so they run in parallel. In a
sector's frame a cell is (k, b), its ray crosses the ring lines a = 1..k-1,
and between two ring lines it crosses one or two patches. Each cell passes on
the rings of its best and second-best features (by nearest ring line); a cell
then
  - screens: the apparent slope of the terrain where its ray crosses the ring
    lines a* - 1 .. a* + 1 around the horizons a* of the two cells of ring
    k - 1 its ray passes between ("parents"), around the nearer parent's
    second feature, and ring line k - 1, and at the cell itself. On a ring line
    the bilinear surface is the linear interpolation of two cells, so each is
    an exact point of the ray: a lower bound of its maximum for two loads.
    When that bound already puts the cell above the ceiling (ground +
    ceiling_agl), E is capped there and the cell is done;
  - otherwise takes the exact maximum of its ray between ring lines a - 1 and
    a + 1 around the parents' features and the two best screened ones, and
    over its near terrain (ring line k - 1 to the cell). (Near the eye a
    horizon peaks inside a patch, which ring-line points miss: there the
    screen takes the first ring interval exactly too.)
A horizon that wins is thus re-evaluated on every following ray and tracked
as it drifts, one ring per step at most; it is lost only where features trade
places between neighbouring rays, by the difference of their slopes there.
Rays of the first FULL_RINGS rings are maximised in full. Above the ceiling
the bound may be loose (it is still a lower bound); at or below it, it is
within 2 m of the exact value on all but a few hundredths of a percent of
cells (benchmarks/bench_exposure.py).
"""

import math

import numpy as np
from numba import njit, prange

from .los import EARTH_RADIUS_M, gap_range, line_over_patch, next_patch, sees

FULL_RINGS = 4  # rings around the outpost whose rays are evaluated exactly in full
DISTINCT = 2  # two horizons closer than this (rings) count as one feature


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

    Patches touching a NaN height are skipped, as in planner.los.max_slope.
    """
    n_rows, n_cols = h.shape
    du = u1 - u0
    dv = v1 - v0
    length_m = cell * math.sqrt(du * du + dv * dv)
    best = -np.inf
    t_best = ta
    if length_m <= 0.0:
        return best, t_best
    t = max(ta, 1e-12)
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
    ring lines a and a + 1 (a >= -1, a + 1 <= P's ring), beyond the eye.

    X = distance from the outpost in rings (a - fa at ring line a; ring line -1
    only matters when the eye lies behind ring line 0, and is then on the grid).
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
        h00 = hf[i00]
        cx = hf[i00 + sa] - h00
        cy = hf[i00 + sb] - h00
        cxy = -cx - hf[i00 + sb] + hf[i00 + sa + sb]
        b0 = fb - jj  # across-coordinate in the patch: b0 + m X; along: X - xl
        q0 = h00 - cx * xl + cy * b0 - cxy * xl * b0
        q1 = cx + cy * m + cxy * (b0 - xl * m)
        slope_a = cxy * m - cc
        e = q0 - z0
        s = slope_a * xa + q1 + e / xa
        if s > best:
            best, x_best = s, xa
        s = slope_a * xb + q1 + e / xb
        if s > best:
            best, x_best = s, xb
        if slope_a < 0.0 and e < 0.0:  # concave: may peak inside
            xs = math.sqrt(e / slope_a)
            if xa < xs < xb:
                s = slope_a * xs + q1 + e / xs
                if s > best:
                    best, x_best = s, xs
    return best, x_best


@njit(cache=True, inline="always")
def _window(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, inv_m, z0, cc, lo, hi, k, best_s, best_a,
            second_s, second_a):
    """Fold the exact maximum of P's ray between ring lines lo and hi into the
    top two features (a feature is known by the ring line nearest to it)."""
    lo = max(lo, 0)
    hi = min(hi, k - 1)  # the last ring interval is the cell's own near terrain
    if lo >= hi:
        return best_s, best_a, second_s, second_a
    if lo == 0 and fa < 0.0:
        lo = -1  # the eye is behind ring line 0
    for a in range(lo, hi):
        s, x = _interval(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, inv_m, a, z0, cc)
        best_s, best_a, second_s, second_a = _keep(
            int(math.floor(x + fa + 0.5)), s, best_s, best_a, second_s, second_a)
    return best_s, best_a, second_s, second_a


@njit(cache=True, inline="always")
def _crossing(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, a, z0, cc, inv_a):
    """Scaled apparent slope of the terrain where P's ray crosses ring line a
    (a >= 1): the bilinear surface there is the linear interpolation of ring
    a's two cells either side, so this is exact (a lower bound of the ray's max)."""
    x = a - fa
    y = fb + x * m
    j = min(max(int(math.floor(y)), b_lo), b_hi - 1)
    i = base + sa * a + sb * j
    t = hf[i] + (y - j) * (hf[i + sb] - hf[i])
    return (t - z0) * inv_a[a] - cc * x


@njit(cache=True, inline="always")
def _screen(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, z0, cc, inv_a, k, b, c1, c2, c3):
    """Quick lower bound of the lowest seen altitude at sector cell (k, b), from
    the ray's crossings of ring lines around the parents' horizons and second
    feature, of ring k - 1, and its end. Returns (altitude, best and second
    features' rings)."""
    x_k = k - fa
    best = (hf[base + sa * k + sb * b] - z0) * inv_a[k] - cc * x_k  # the cell itself
    best_a = k - 1
    second = -np.inf
    second_a = -1
    lo = min(c1, c2)
    hi = max(c1, c2)
    if lo < 0:
        lo = hi
    for a in range(max(lo - 1, 1), min(hi + 1, k - 2) + 1):
        if a <= lo + 1 or a >= hi - 1:
            s = _crossing(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, a, z0, cc, inv_a)
            best, best_a, second, second_a = _keep(a, s, best, best_a, second, second_a)
    if 0 <= lo <= 1:  # a horizon next to the eye peaks inside a patch: take it exactly
        inv_m = 1.0 / m if m != 0.0 else np.inf
        for a in range(-1 if fa < 0.0 else 0, 1):
            s, x = _interval(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, inv_m, a, z0, cc)
            best, best_a, second, second_a = _keep(0, s, best, best_a, second, second_a)
    if c3 >= 1 and c3 < k - 1 and (c3 < lo - 1 or c3 > hi + 1):
        s = _crossing(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, c3, z0, cc, inv_a)
        best, best_a, second, second_a = _keep(c3, s, best, best_a, second, second_a)
    s = _crossing(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, k - 1, z0, cc, inv_a)
    best, best_a, second, second_a = _keep(k - 1, s, best, best_a, second, second_a)
    return z0 + x_k * best + cc * x_k * x_k, best_a, second_a


@njit(cache=True, inline="always")
def _cell(h, cell, hf, base, sa, sb, b_lo, b_hi, u0, v0, u1, v1, fa, fb, z0, k_cc, curv,
          inv_a, r2, cap_agl, k, b, c1, c2, c3, c4):
    """Lower bound of the lowest altitude seen at sector cell (k, b), grid (u1, v1).

    c1, c2: horizon rings inherited from the two parents (c1 from the one at
    floor of the ray's crossing), c3, c4: their second features (-1 = none).
    Returns (altitude, or +inf beyond range; its horizon ring; the second
    feature's ring).
    """
    x_k = k - fa
    m = (b - fb) * inv_a[k]
    if x_k * x_k * (1.0 + m * m) > r2:
        return np.inf, -1, -1
    cc = k_cc * (1.0 + m * m)
    if k <= FULL_RINGS:
        kappa = cell * math.sqrt(1.0 + m * m)  # metres per ring along this ray
        s, t = ray_max(h, cell, u0, v0, z0, u1, v1, 0.0, 1.0, curv)
        a = min(max(int(math.floor(fa + t * x_k + 0.5)), 0), k)
        return z0 + x_k * s * kappa + cc * x_k * x_k, a, -1
    # deep in shadow a few exact points of the ray already put the cell above the
    # ceiling, where E is capped: no need to know by how much
    c_second = c3 if c3 >= 0 else c4  # the nearer parent's second feature, else the other's
    z, a1, a2 = _screen(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, z0, cc, inv_a, k, b, c1, c2,
                        c_second)
    if z >= hf[base + sa * k + sb * b] + cap_agl:
        return z, a1, a2
    # else the exact maxima around the features, and of the near terrain
    inv_m = 1.0 / m if m != 0.0 else np.inf
    near_s, x = _interval(hf, base, sa, sb, b_lo, b_hi, fa, fb, m, inv_m, k - 1, z0, cc)
    near_a = int(math.floor(x + fa + 0.5))
    best_s = -np.inf
    best_a = -1
    second_s = -np.inf
    second_a = -1
    # windows around the parents' features (exact argmax rings) and the screened ones
    # (sampled argmax rings), each ring once: a feature is near a ring already done
    rings = (np.int64(c1), np.int64(c2), np.int64(c_second), np.int64(a1), np.int64(a2))
    for n in range(5):
        a = rings[n]
        if a < 0:
            continue
        new = True
        for n_done in range(n):
            if rings[n_done] >= 0 and abs(rings[n_done] - a) <= 1:
                new = False
        if new:
            best_s, best_a, second_s, second_a = _window(
                hf, base, sa, sb, b_lo, b_hi, fa, fb, m, inv_m, z0, cc, a - 1, a + 1, k,
                best_s, best_a, second_s, second_a)
    # the near terrain wins, or only fills an empty second place: the next ring
    # sees it again as its own near terrain anyway
    if near_s > best_s:
        if best_a >= 0:
            second_a = best_a
        best_s, best_a = near_s, near_a
    elif second_a < 0:
        second_a = near_a
    return max(z0 + x_k * best_s + cc * x_k * x_k, z), best_a, second_a  # both lower bounds


@njit(cache=True)
def _sweep_sector(h, cell, u0, v0, z0, c_o, r_o, q, range_m, curv, cap_agl, out):
    """Lower-bound lowest visible altitude for the cells of one sector.

    Sectors 1 and 3 (down, up) run ring by ring, i.e. grid row by grid row;
    sectors 0 and 2 (right, left) run across the rings, grid row by grid row
    outwards from the outpost's row, so that memory is always read along rows.
    """
    n_rows, n_cols = h.shape
    hf = h.ravel()
    of = out.ravel()
    a_last, b_lo, b_hi, sa, sb = _sector_frame(q, c_o, r_o, n_rows, n_cols)
    base = r_o * n_cols + c_o
    fu = u0 - c_o  # outpost offset from its cell centre, in the sector's frame
    fv = v0 - r_o
    if q == 0:
        fa, fb = fu, fv
    elif q == 1:
        fa, fb = fv, -fu
    elif q == 2:
        fa, fb = -fu, -fv
    else:
        fa, fb = -fv, fu
    range_cells = range_m / cell
    if range_cells + 2.0 < a_last:
        a_last = int(range_cells + 2.0)
    if a_last < 1 or b_hi <= b_lo:
        return
    inv_a = np.empty(a_last + 1)
    for a in range(1, a_last + 1):
        inv_a[a] = 1.0 / (a - fa)
    k_cc = curv * cell * cell / (2.0 * EARTH_RADIUS_M)
    r2 = range_cells * range_cells * (1.0 + 1e-9)  # at the limit: in range (safe side)
    if q == 1 or q == 3:
        _by_rings(h, cell, hf, of, q, c_o, r_o, u0, v0, base, sa, sb, a_last, b_lo, b_hi, fa, fb,
                  z0, k_cc, curv, inv_a, r2, cap_agl)
    else:
        _across_rings(h, cell, hf, of, q, c_o, r_o, u0, v0, base, sa, sb, a_last, b_lo, b_hi, fa,
                      fb, z0, k_cc, curv, inv_a, r2, cap_agl)


@njit(cache=True)
def _by_rings(h, cell, hf, of, q, c_o, r_o, u0, v0, base, sa, sb, a_last, b_lo, b_hi, fa, fb, z0,
              k_cc, curv, inv_a, r2, cap_agl):
    width = 2 * a_last + 3
    off = a_last + 1
    prev = np.full((2, width), -1, np.int32)  # horizon rings of ring k-1's cells, by b
    cur = np.full((2, width), -1, np.int32)
    for k in range(1, a_last + 1):
        lo = max(b_lo, -k + 1)
        hi = min(b_hi, k)
        cur[:, :] = -1
        for b in range(lo, hi + 1):
            # the previous ring's cells either side of the ray
            y = fb + (k - 1 - fa) * (b - fb) * inv_a[k]
            p0 = min(max(int(math.floor(y)), -k + 2), k - 1) + off
            p1 = min(max(int(math.floor(y)) + 1, -k + 2), k - 1) + off
            dc, dr = _rotate(q, k, b)
            z, a1, a2 = _cell(h, cell, hf, base, sa, sb, b_lo, b_hi, u0, v0, c_o + dc, r_o + dr,
                              fa, fb, z0, k_cc, curv, inv_a, r2, cap_agl, k, b,
                              prev[0, p0], prev[0, p1], prev[1, p0], prev[1, p1])
            cur[0, b + off] = a1
            cur[1, b + off] = a2
            if z < np.inf:
                of[base + sa * k + sb * b] = z
        prev, cur = cur, prev


@njit(cache=True)
def _across_rings(h, cell, hf, of, q, c_o, r_o, u0, v0, base, sa, sb, a_last, b_lo, b_hi, fa,
                  fb, z0, k_cc, curv, inv_a, r2, cap_agl):
    # rows b = 0, 1, 2, ... then -1, -2, ...; a parent row is this row or the one
    # before it in that order, at ring a - 1
    row0 = np.full((2, a_last + 1), -1, np.int32)
    prev = np.full((2, a_last + 1), -1, np.int32)
    cur = np.full((2, a_last + 1), -1, np.int32)
    for direction in (1, -1):
        if direction == 1:
            b, b_end = 0, min(b_hi, a_last)
        else:
            b, b_end = -1, max(b_lo, -a_last + 1)
            prev[:, :] = row0
        while direction * (b_end - b) >= 0:
            cur[:, :] = -1
            b_near = b - direction if b != 0 else 0  # the row before, towards the outpost
            lo_p = min(b, b_near)
            hi_p = max(b, b_near)
            a_first = b if b > 0 else 1 - b
            for a in range(max(a_first, 1), a_last + 1):
                y = fb + (a - 1 - fa) * (b - fb) * inv_a[a]
                fl = int(math.floor(y))
                p0 = min(max(fl, lo_p, -a + 2), hi_p, a - 1)
                p1 = min(max(fl + 1, lo_p, -a + 2), hi_p, a - 1)
                c1 = cur[0, a - 1] if p0 == b else prev[0, a - 1]
                c3 = cur[1, a - 1] if p0 == b else prev[1, a - 1]
                c2 = cur[0, a - 1] if p1 == b else prev[0, a - 1]
                c4 = cur[1, a - 1] if p1 == b else prev[1, a - 1]
                dc, dr = _rotate(q, a, b)
                z, a1, a2 = _cell(h, cell, hf, base, sa, sb, b_lo, b_hi, u0, v0, c_o + dc,
                                  r_o + dr, fa, fb, z0, k_cc, curv, inv_a, r2, cap_agl, a, b, c1,
                                  c2, c3, c4)
                cur[0, a] = a1
                cur[1, a] = a2
                if z < np.inf:
                    of[base + sa * a + sb * b] = z
            if b == 0:
                row0[:, :] = cur
            prev, cur = cur, prev
            b += direction


@njit(cache=True, inline="always")
def _keep(a, s, best_s, best_a, second_s, second_a):
    """Insert (slope s at ring a) into the top two of distinct features."""
    if s > best_s:
        if abs(a - best_a) >= DISTINCT:
            second_s, second_a = best_s, best_a
        best_s, best_a = s, a
    elif s > second_s and abs(a - best_a) >= DISTINCT:
        second_s, second_a = s, a
    return best_s, best_a, second_s, second_a


@njit(cache=True, parallel=True)
def lowest_seen_batch(h, cell, eyes, curv, cap_agl, out):
    """Lower bounds of the lowest seen altitude, one grid per outpost; tight
    where at most ``cap_agl`` above the ground (above it E is capped anyway).

    eyes: float64 [n, 4] = (u, v, z_eye, range_m); out: float64 [n, rows, cols],
    filled with +inf by the caller. The four sectors of every outpost run in
    parallel; the outpost's own cell is seen at any altitude (-inf).
    """
    n_rows, n_cols = h.shape
    n = eyes.shape[0]
    for task in prange(4 * n):
        o = task // 4
        q = task % 4
        u0, v0, z0, range_m = eyes[o, 0], eyes[o, 1], eyes[o, 2], eyes[o, 3]
        c_o = min(max(int(math.floor(u0 + 0.5)), 0), n_cols - 1)
        r_o = min(max(int(math.floor(v0 + 0.5)), 0), n_rows - 1)
        if q == 0:
            out[o, r_o, c_o] = -np.inf
        _sweep_sector(h, cell, u0, v0, z0, c_o, r_o, q, range_m, curv, cap_agl, out[o])


@njit(cache=True, parallel=True)
def min_over_outposts(grids, into):
    """into = min(into, min over the first axis of grids)."""
    n, n_rows, n_cols = grids.shape
    for r in prange(n_rows):
        for o in range(n):
            for c in range(n_cols):
                if grids[o, r, c] < into[r, c]:
                    into[r, c] = grids[o, r, c]


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


MAX_PIECES = 4000  # pieces per leg and outpost before giving up (answer: not proven)
MIN_PIECE_M = 1e-3


@njit(cache=True)
def _leg_hidden_from(h, cell, grad, g_max, eye, a, b, curv, slack_m):
    """Whether every point within ``slack_m`` (horizontally) of the leg a -> b
    ((u, v, z), grid units and m AMSL) is hidden from one eye (u, v, z, range_m).
    Conservative: False when not proven.

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
    while top > 0:
        top -= 1
        sa = stack_a[top]
        sb = stack_b[top]
        pieces += 1
        if pieces > MAX_PIECES:
            return False
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
        if d_m <= range_m + slack_m:
            if d_m == 0.0:
                return False  # straight above the outpost
            # from 1e-3 grid units on: at the eye (T - z0) / d is rounding noise, and a
            # shorter stretch only lowers zmin (conservative)
            s, t = ray_max(h, cell, u0, v0, z0, um, vm, 1e-3 * cell / d_m, 1.0, curv)
            margin = z0 + d_m * s + curv * d_m * d_m / (2.0 * EARTH_RADIUS_M) - zm
            if not (margin > 0.0):
                return False  # the midpoint is seen
            rho = t * half_h / cell
            lip = _local_gradient(grad, g_max, u0 + t * (um - u0), v0 + t * (vm - v0), rho)
            need = (lip + 2.0 * curv * r_max / EARTH_RADIUS_M) * half_h + half_z
            if margin > need * (1.0 + 1e-9) + 1e-6:
                continue
        if half_h - slack_m + half_z < MIN_PIECE_M or top + 2 > stack_a.shape[0]:
            return False  # grazing: not provable at this resolution
        stack_a[top] = sa
        stack_b[top] = sm
        stack_a[top + 1] = sm
        stack_b[top + 1] = sb
        top += 2
    return True


@njit(cache=True, parallel=True)
def legs_hidden(h, cell, grad, eyes, a, b, curv, slack_m):
    """segment hidden from every eye, for each leg a[k] -> b[k] ((u, v, z) rows)."""
    n = a.shape[0]
    out = np.zeros(n, np.bool_)
    g_max = 0.0
    for j in range(grad.shape[0]):
        for i in range(grad.shape[1]):
            g_max = max(g_max, grad[j, i])
    for k in prange(n):
        ok = True
        for o in range(eyes.shape[0]):
            if not _leg_hidden_from(h, cell, grad, g_max, eyes[o], a[k], b[k], curv, slack_m):
                ok = False
                break
        out[k] = ok
    return out


# --- clearance above the terrain ---------------------------------------------------------------

@njit(cache=True, parallel=True)
def legs_min_height(h, a, b):
    """Min over each leg a[k] -> b[k] ((u, v, z)) of altitude minus the bilinear
    terrain (planner.los.gap_range); NaN next to a void."""
    out = np.empty(a.shape[0])
    for k in prange(a.shape[0]):
        out[k] = gap_range(h, a[k, 0], a[k, 1], a[k, 2], b[k, 0], b[k, 1], b[k, 2], False)[0]
    return out
