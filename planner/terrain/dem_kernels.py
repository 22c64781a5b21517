"""numba kernel for conservative resampling (see planner.terrain.dem).

A working grid resampled from a source DEM has its own bilinear surface W,
which differs from the source's bilinear surface S between the working cell
centres. ``resampling_error`` bounds W - S exactly over every working patch
(the square between four working centres), so that heights lowered (raised)
by the bound give a working surface that is nowhere above (below) the source.

Over a working patch the map from working to source pixel coordinates is
affine up to a fraction of a millimetre (two triangles, each fitted to its
three corners exactly; the rest is charged as a margin). Each triangle is
clipped against the source patches it overlaps; on each convex piece both W
and S are polynomials of degree two in the source coordinates, so the extremes
of W - S over the piece lie at its vertices, at the one stationary point of
each edge, or at the stationary point inside: all are evaluated.
"""

import numpy as np
from numba import njit, prange

#: added to every bound (m): float rounding, and room for the test's sampling
BASE_MARGIN_M = 0.001
_MAX_POLY = 16


@njit(cache=True, parallel=True)
def resampling_error(src, rows, cols, value):
    """Per working patch (n_rows - 1, n_cols - 1): (max of W - S, max of S - W)
    over the patch, each >= 0 plus a margin; NaN where the patch touches a source
    void or leaves the source grid, or a corner has no value.

    ``src``: source heights (NaN = void); ``rows``, ``cols``: source pixel
    centre coordinates of every working cell centre; ``value``: S there.
    """
    n_rows, n_cols = value.shape
    above = np.full((max(n_rows - 1, 0), max(n_cols - 1, 0)), np.nan)
    below = np.full((max(n_rows - 1, 0), max(n_cols - 1, 0)), np.nan)
    for r in prange(n_rows - 1):
        xs = np.empty(_MAX_POLY)
        ys = np.empty(_MAX_POLY)
        tx = np.empty(_MAX_POLY)
        ty = np.empty(_MAX_POLY)
        for c in range(n_cols - 1):
            w = np.array([value[r, c], value[r, c + 1], value[r + 1, c], value[r + 1, c + 1]])
            if not np.all(np.isfinite(w)):
                continue
            px = np.array([cols[r, c], cols[r, c + 1], cols[r + 1, c], cols[r + 1, c + 1]])
            py = np.array([rows[r, c], rows[r, c + 1], rows[r + 1, c], rows[r + 1, c + 1]])
            hi, lo, slope, ok = _patch_extremes(src, w, px, py, xs, ys, tx, ty)
            if not ok:
                continue
            # how far the true map is from the two affine pieces (source pixels)
            bend = 0.5 * np.hypot(px[0] + px[3] - px[1] - px[2], py[0] + py[3] - py[1] - py[2])
            margin = BASE_MARGIN_M + bend * slope
            above[r, c] = max(hi, 0.0) + margin
            below[r, c] = max(-lo, 0.0) + margin
    return above, below


@njit(cache=True)
def _patch_extremes(src, w, px, py, xs, ys, tx, ty):
    """(max, min of W - S, steepest source slope per pixel, ok) over one working patch."""
    hi = -np.inf
    lo = np.inf
    slope = 0.0
    # triangles in (s, t): corners 0 = (0, 0), 1 = (1, 0), 2 = (0, 1), 3 = (1, 1)
    for tri in range(2):
        if tri == 0:
            a, b, cc = 0, 1, 2  # P = P0 + s (P1 - P0) + t (P2 - P0)
            ox, oy = px[0], py[0]
            bx, by = px[1] - px[0], py[1] - py[0]
            cx, cy = px[2] - px[0], py[2] - py[0]
        else:
            a, b, cc = 3, 2, 1  # P = P3 + (s - 1)(P3 - P2) + (t - 1)(P3 - P1)
            bx, by = px[3] - px[2], py[3] - py[2]
            cx, cy = px[3] - px[1], py[3] - py[1]
            ox, oy = px[3] - bx - cx, py[3] - by - cy
        det = bx * cy - by * cx
        if det == 0.0:
            return hi, lo, slope, False
        tri_x = np.array([px[a], px[b], px[cc]])
        tri_y = np.array([py[a], py[b], py[cc]])
        i0 = int(np.floor(tri_x.min()))
        i1 = int(np.floor(tri_x.max()))
        j0 = int(np.floor(tri_y.min()))
        j1 = int(np.floor(tri_y.max()))
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                n = _clip(tri_x, tri_y, i, j, xs, ys, tx, ty)
                if n == 0:
                    continue
                if i < 0 or j < 0 or i + 1 >= src.shape[1] or j + 1 >= src.shape[0]:
                    # the footprint ends at the outer source centres
                    if _area(xs, ys, n) > 1e-12:
                        return hi, lo, slope, False
                    continue
                s00, s01 = src[j, i], src[j, i + 1]
                s10, s11 = src[j + 1, i], src[j + 1, i + 1]
                if not (np.isfinite(s00) and np.isfinite(s01) and np.isfinite(s10)
                        and np.isfinite(s11)):
                    return hi, lo, slope, False
                d = s11 - s10 - s01 + s00
                slope = max(slope, abs(s01 - s00) + abs(d), abs(s10 - s00) + abs(d))
                coef = (s00, s01 - s00, s10 - s00, d, float(i), float(j),
                        w[0], w[1], w[2], w[3], ox, oy, bx, by, cx, cy, det)
                h, l_ = _piece_extremes(coef, xs, ys, n)
                hi = max(hi, h)
                lo = min(lo, l_)
    return hi, lo, slope, True


@njit(cache=True, inline="always")
def _f(coef, x, y):
    """W - S at source pixel coordinates (x, y), both as polynomials (not clamped)."""
    a0, a1, a2, a3, i, j, w0, w1, w2, w3, ox, oy, bx, by, cx, cy, det = coef
    dx = x - ox
    dy = y - oy
    s = (dx * cy - dy * cx) / det
    t = (bx * dy - by * dx) / det
    wv = w0 * (1 - s) * (1 - t) + w1 * s * (1 - t) + w2 * (1 - s) * t + w3 * s * t
    u = x - i
    v = y - j
    return wv - (a0 + a1 * u + a2 * v + a3 * u * v)


@njit(cache=True)
def _piece_extremes(coef, xs, ys, n):
    hi = -np.inf
    lo = np.inf
    cxm = 0.0
    cym = 0.0
    for k in range(n):
        g = _f(coef, xs[k], ys[k])
        hi = max(hi, g)
        lo = min(lo, g)
        cxm += xs[k] / n
        cym += ys[k] / n
        # the stationary point of the quadratic along the edge k -> k + 1
        x1, y1 = xs[(k + 1) % n], ys[(k + 1) % n]
        g1 = _f(coef, x1, y1)
        gm = _f(coef, 0.5 * (xs[k] + x1), 0.5 * (ys[k] + y1))
        qa = 2.0 * g + 2.0 * g1 - 4.0 * gm
        qb = 4.0 * gm - 3.0 * g - g1
        if qa != 0.0:
            lam = -qb / (2.0 * qa)
            if 0.0 < lam < 1.0:
                e = _f(coef, xs[k] + lam * (x1 - xs[k]), ys[k] + lam * (y1 - ys[k]))
                hi = max(hi, e)
                lo = min(lo, e)
    # the stationary point inside: f is quadratic, so unit steps give its derivatives exactly
    f0 = _f(coef, cxm, cym)
    fxp = _f(coef, cxm + 1.0, cym)
    fxm = _f(coef, cxm - 1.0, cym)
    fyp = _f(coef, cxm, cym + 1.0)
    fym = _f(coef, cxm, cym - 1.0)
    fxy = _f(coef, cxm + 1.0, cym + 1.0)
    hxx = fxp + fxm - 2.0 * f0
    hyy = fyp + fym - 2.0 * f0
    hxy = fxy - fxp - fyp + f0
    gx = 0.5 * (fxp - fxm)
    gy = 0.5 * (fyp - fym)
    det = hxx * hyy - hxy * hxy
    if det != 0.0:
        sx = cxm - (hyy * gx - hxy * gy) / det
        sy = cym - (hxx * gy - hxy * gx) / det
        if _inside(xs, ys, n, sx, sy):
            e = _f(coef, sx, sy)
            hi = max(hi, e)
            lo = min(lo, e)
    return hi, lo


@njit(cache=True)
def _inside(xs, ys, n, x, y):
    sign = 0.0
    for k in range(n):
        x0, y0 = xs[k], ys[k]
        x1, y1 = xs[(k + 1) % n], ys[(k + 1) % n]
        cross = (x1 - x0) * (y - y0) - (y1 - y0) * (x - x0)
        if cross != 0.0:
            if sign == 0.0:
                sign = cross
            elif cross * sign < 0.0:
                return False
    return True


@njit(cache=True)
def _area(xs, ys, n):
    s = 0.0
    for k in range(n):
        s += xs[k] * ys[(k + 1) % n] - xs[(k + 1) % n] * ys[k]
    return abs(s) / 2.0


@njit(cache=True)
def _clip(tri_x, tri_y, i, j, xs, ys, tx, ty):
    """Triangle ∩ square [i, i+1] x [j, j+1] (Sutherland-Hodgman) into xs, ys; its
    vertex count (0: they do not meet)."""
    n = 3
    for k in range(3):
        xs[k] = tri_x[k]
        ys[k] = tri_y[k]
    for edge in range(4):
        m = 0
        for k in range(n):
            x0, y0 = xs[k], ys[k]
            x1, y1 = xs[(k + 1) % n], ys[(k + 1) % n]
            d0 = _side(edge, x0, y0, i, j)
            d1 = _side(edge, x1, y1, i, j)
            if d0 >= 0.0:
                tx[m] = x0
                ty[m] = y0
                m += 1
            if (d0 >= 0.0) != (d1 >= 0.0):
                lam = d0 / (d0 - d1)
                tx[m] = x0 + lam * (x1 - x0)
                ty[m] = y0 + lam * (y1 - y0)
                m += 1
        n = m
        for k in range(n):
            xs[k] = tx[k]
            ys[k] = ty[k]
        if n == 0:
            return 0
    return n


@njit(cache=True, inline="always")
def _side(edge, x, y, i, j):
    if edge == 0:
        return x - i
    if edge == 1:
        return i + 1 - x
    if edge == 2:
        return y - j
    return j + 1 - y
