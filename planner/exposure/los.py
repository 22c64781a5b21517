"""Exact line of sight over the bilinear terrain surface (numba kernels).

The terrain surface is the bilinear interpolation of cell centres. Along a
straight line the surface is a quadratic within each grid patch (the square
between four centres), so the steepest elevation angle seen along a segment is
found exactly, patch by patch, in closed form: no sampling, no step size.

Earth curvature with refraction follows GDAL's viewshed: a point at horizontal
distance d appears lowered by ``curvature_coeff * d**2 / (2 R)``
(``curvature_coeff`` 0.85714 for standard refraction, 0 turns it off).

Coordinates: grid units ``u`` = column, ``v`` = row (cell centre of (r, c) at
(u, v) = (c, r)); heights and altitudes in metres AMSL; ``cell`` is the grid
spacing in metres.
"""

import math

import numpy as np
from numba import njit, prange

EARTH_RADIUS_M = 6378137.0
# Sight lines start this far from the eye: the apparent slope there, (T - z0) / d,
# divides the rounding of T - z0 (an ulp of the terrain height, ~6e-14 m at 300 m)
# by d; from 1e-12 of a ray that was 0.06 m of lowest seen altitude, of either sign,
# for an eye 0 m above the ground. From a millimetre on it is below 1e-6 m.
EYE_GAP_M = 1e-3
DEFAULT_CURVATURE_COEFF = 0.85714


@njit(cache=True, inline="always")
def curvature_drop(d_m, curvature_coeff):
    """How far a point at horizontal distance ``d_m`` appears below its true height."""
    return curvature_coeff * d_m * d_m / (2.0 * EARTH_RADIUS_M)


@njit(cache=True, inline="always")
def next_patch(u0, v0, du, dv, t, n_rows, n_cols):
    """The patch (col i, row j) holding the line (u0, v0) + t (du, dv) just after
    ``t``, and the parameter where the line leaves it (always beyond ``t``)."""
    tm = min(t + 1e-9, 1.0)
    iu = int(math.floor(u0 + tm * du))
    jv = int(math.floor(v0 + tm * dv))
    # A line all but along a grid line (a rounded waypoint: dv of 6e-12 cells over
    # the leg) moves too little in the nudge to leave the cell it is crossing out of
    # by float arithmetic, while its crossing is already behind t: it is in the next
    # cell. Read from the nudged point alone, it was walked in steps of 1e-9 (300,000
    # for one leg, 20 ms: `gcs bases` spent minutes on such legs)
    if du > 0.0 and (iu + 1 - u0) / du <= t:
        iu += 1
    elif du < 0.0 and (iu - u0) / du <= t:
        iu -= 1
    if dv > 0.0 and (jv + 1 - v0) / dv <= t:
        jv += 1
    elif dv < 0.0 and (jv - v0) / dv <= t:
        jv -= 1
    i = min(max(iu, 0), n_cols - 2)
    j = min(max(jv, 0), n_rows - 2)
    # Off the grid the edge patch extends to infinity on its outer side: a line
    # heading further out never crosses that side (taking it as a crossing once
    # walked such a line in steps of 1e-9: minutes for one point off the grid)
    t_next = 1.0
    if du > 0.0 and iu <= n_cols - 2:
        t_next = min(t_next, (i + 1 - u0) / du)
    elif du < 0.0 and iu >= 0:
        t_next = min(t_next, (i - u0) / du)
    if dv > 0.0 and jv <= n_rows - 2:
        t_next = min(t_next, (j + 1 - v0) / dv)
    elif dv < 0.0 and jv >= 0:
        t_next = min(t_next, (j - v0) / dv)
    if t_next <= t:
        t_next = min(1.0, t + 1e-9)
    return i, j, t_next


@njit(cache=True, inline="always")
def line_over_patch(h, i, j, u0, v0, du, dv):
    """The bilinear surface of patch (i, j) along the line: c0 + c1 t + c2 t^2."""
    h00 = h[j, i]
    h10 = h[j, i + 1]
    h01 = h[j + 1, i]
    h11 = h[j + 1, i + 1]
    cx = h10 - h00
    cy = h01 - h00
    cxy = h00 - h10 - h01 + h11
    au = u0 - i
    av = v0 - j
    c0 = h00 + cx * au + cy * av + cxy * au * av
    c1 = cx * du + cy * dv + cxy * (au * dv + av * du)
    return c0, c1, cxy * du * dv


@njit(cache=True)
def gap_range(h, u0, v0, z0, u1, v1, z1, void_is_clear=True):
    """Exact (min, max) over the segment of (altitude - bilinear ground), metres.

    Within a patch the ground along the segment is a quadratic in t and the
    altitude linear, so the extremes of their difference are at a piece's ends
    or its one stationary point. Patches touching a void are skipped, or, with
    ``void_is_clear=False``, give (NaN, NaN): unknown ground is never clear.
    """
    n_rows, n_cols = h.shape
    du = u1 - u0
    dv = v1 - v0
    dz = z1 - z0
    lo = np.inf
    hi = -np.inf
    t = 0.0
    while True:
        i, j, t_next = next_patch(u0, v0, du, dv, t, n_rows, n_cols)
        c0, c1, c2 = line_over_patch(h, i, j, u0, v0, du, dv)
        if not (c0 == c0 and c1 == c1 and c2 == c2):
            if not void_is_clear:
                return np.nan, np.nan
            if t_next >= 1.0:
                return lo, hi
            t = t_next
            continue
        for tt in (t, t_next):
            g = z0 + dz * tt - (c0 + c1 * tt + c2 * tt * tt)
            lo = min(lo, g)
            hi = max(hi, g)
        if c2 != 0.0:  # the one stationary point of the quadratic gap
            ts = (dz - c1) / (2.0 * c2)
            if t < ts < t_next:
                g = z0 + dz * ts - (c0 + c1 * ts + c2 * ts * ts)
                lo = min(lo, g)
                hi = max(hi, g)
        if t_next >= 1.0:
            return lo, hi
        t = t_next


@njit(cache=True, inline="always")
def piece_max_slope(h, i, j, u0, v0, du, dv, ta, tb, z0, length_m, curv):
    """Max over t in [ta, tb] of (T(t) - drop(d) - z0) / d on patch (col i, row j).

    T(t) = c0 + c1 t + c2 t^2 (bilinear along the line), d = t * length_m, so
    slope(t) = (a t + c1 + e / t) / length_m with a = c2 - curv L^2 / 2R and
    e = c0 - z0; its only interior stationary point is t* = sqrt(e / a).
    """
    c0, c1, c2 = line_over_patch(h, i, j, u0, v0, du, dv)
    a = c2 - curv * length_m * length_m / (2.0 * EARTH_RADIUS_M)
    e = c0 - z0
    best = (a * ta + c1 + e / ta) / length_m
    s = (a * tb + c1 + e / tb) / length_m
    if s > best:
        best = s
    if a != 0.0 and e / a > 0.0:
        ts = math.sqrt(e / a)
        if ta < ts < tb:
            s = (a * ts + c1 + e / ts) / length_m
            if s > best:
                best = s
    return best


@njit(cache=True)
def max_slope(h, cell, u0, v0, z0, u1, v1, t_from, curvature_coeff):
    """Steepest apparent slope (rise / horizontal run) of the terrain seen from
    (u0, v0, z0) along the segment to (u1, v1), over t in [t_from, 1].

    The target is visible from the eye when its own apparent slope,
    ``(z1 - drop(D) - z0) / D``, is at least this value. Returns -inf for a
    segment of zero length. Patches touching a NaN height are skipped (a void
    is no obstacle: the safe side for the exposure surface).
    """
    n_rows, n_cols = h.shape
    du = u1 - u0
    dv = v1 - v0
    length_m = cell * math.sqrt(du * du + dv * dv)
    best = -np.inf
    if length_m <= 0.0:
        return best
    t = max(t_from, EYE_GAP_M / length_m)
    while t < 1.0:
        i, j, t_next = next_patch(u0, v0, du, dv, t, n_rows, n_cols)
        s = piece_max_slope(h, i, j, u0, v0, du, dv, t, t_next, z0, length_m,
                             curvature_coeff)
        if s > best:
            best = s
        t = t_next
    return best


@njit(cache=True)
def lowest_visible_altitude(h, cell, u0, v0, z0, u1, v1, range_m, curvature_coeff):
    """Lowest altitude (m AMSL) at (u1, v1) that the eye at (u0, v0, z0) sees.

    +inf beyond ``range_m``. Never below the terrain surface at the target,
    since the segment's end point is part of the terrain it must clear.
    """
    d = cell * math.sqrt((u1 - u0) ** 2 + (v1 - v0) ** 2)
    if d > range_m:
        return np.inf
    if d == 0.0:
        return -np.inf
    s = max_slope(h, cell, u0, v0, z0, u1, v1, 0.0, curvature_coeff)
    return z0 + d * s + curvature_drop(d, curvature_coeff)


@njit(cache=True)
def sees(h, cell, u0, v0, z0, u1, v1, z1, range_m, curvature_coeff):
    """Whether the eye at (u0, v0, z0) sees the point (u1, v1, z1).

    The segment must stay on or above the terrain surface everywhere before
    the target point itself (which may stand on the ground).
    """
    d = cell * math.sqrt((u1 - u0) ** 2 + (v1 - v0) ** 2)
    if d > range_m:
        return False
    if d == 0.0:
        return True
    target = (z1 - curvature_drop(d, curvature_coeff) - z0) / d
    # exclude the last millimetre so a point on the ground does not hide itself
    t_end = max(0.0, 1.0 - 1e-3 / d)
    s = max_slope(h, cell, u0, v0, z0, u0 + t_end * (u1 - u0), v0 + t_end * (v1 - v0),
                  0.0, curvature_coeff)
    return s <= target + 1e-12


@njit(cache=True, parallel=True)
def lowest_visible_grid(h, cell, u0, v0, z0, range_m, curvature_coeff):
    """Exact lowest visible altitude for every cell centre (the brute-force reference)."""
    n_rows, n_cols = h.shape
    out = np.empty((n_rows, n_cols))
    for r in prange(n_rows):
        for c in range(n_cols):
            out[r, c] = lowest_visible_altitude(h, cell, u0, v0, z0, float(c), float(r),
                                                range_m, curvature_coeff)
    return out
