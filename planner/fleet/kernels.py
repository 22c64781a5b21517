"""Numba kernels of the fleet stage: closest approach of two 4-D trajectories.

A trajectory is piecewise linear in time: rows ``t[i]``, ``p[i]`` (x, y, z) and
``air[i]``, whether the vehicle is airborne on the segment from row i to row
i + 1 (a hold is two rows at one place). Before its first row and after its last
the vehicle stands on the ground, not airborne.

Two trajectories are compared on the merged breakpoints of both: on each interval
both move linearly, so their offset d(t) = d0 + v (t - t0) is linear and
|d(t)|² a convex quadratic, whose minimum and whose stretch below a distance
are closed forms. Nothing is sampled.
"""

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _at(t, p, i, s):
    """Position on segment i of (t, p) at time s (t[i] <= s <= t[i + 1])."""
    span = t[i + 1] - t[i]
    f = 0.0 if span <= 0.0 else (s - t[i]) / span
    return (p[i, 0] + f * (p[i + 1, 0] - p[i, 0]), p[i, 1] + f * (p[i + 1, 1] - p[i, 1]),
            p[i, 2] + f * (p[i + 1, 2] - p[i, 2]))


@njit(cache=True)
def _intervals(ta, tb):
    """The merged breakpoints of two trajectories where both are defined."""
    lo = max(ta[0], tb[0])
    hi = min(ta[-1], tb[-1])
    if hi < lo:
        return np.zeros(0)
    marks = np.concatenate((ta, tb))
    marks = marks[(marks >= lo) & (marks <= hi)]
    marks = np.unique(marks)
    if len(marks) == 0 or marks[0] > lo:
        marks = np.concatenate((np.array([lo]), marks))
    return marks


@njit(cache=True)
def _offset(ta, pa, aa, tb, pb, ab, s0, s1, ia, ib):
    """On [s0, s1]: (airborne both, d0 (3), v (3)) of the offset b - a, advancing the
    segment indices ``ia``, ``ib`` (arrays of one, updated in place)."""
    while ia[0] + 2 < len(ta) and ta[ia[0] + 1] <= s0:
        ia[0] += 1
    while ib[0] + 2 < len(tb) and tb[ib[0] + 1] <= s0:
        ib[0] += 1
    i, j = ia[0], ib[0]
    a0 = _at(ta, pa, i, s0)
    a1 = _at(ta, pa, i, s1)
    b0 = _at(tb, pb, j, s0)
    b1 = _at(tb, pb, j, s1)
    span = s1 - s0
    d0 = np.empty(3)
    v = np.empty(3)
    for k in range(3):
        d0[k] = b0[k] - a0[k]
        v[k] = 0.0 if span <= 0.0 else ((b1[k] - a1[k]) - d0[k]) / span
    return aa[i] and ab[j], d0, v


@njit(cache=True)
def closest_approach(ta, pa, aa, tb, pb, ab):
    """(least distance, when) of two trajectories while both are airborne;
    (inf, nan) if they never are at once."""
    marks = _intervals(ta, tb)
    best, when = np.inf, np.nan
    ia = np.zeros(1, np.int64)
    ib = np.zeros(1, np.int64)
    for k in range(len(marks) - 1):
        s0, s1 = marks[k], marks[k + 1]
        both, d0, v = _offset(ta, pa, aa, tb, pb, ab, s0, s1, ia, ib)
        if not both:
            continue
        vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
        dv = d0[0] * v[0] + d0[1] * v[1] + d0[2] * v[2]
        u = 0.0 if vv <= 0.0 else min(max(-dv / vv, 0.0), s1 - s0)
        d = np.sqrt((d0[0] + u * v[0]) ** 2 + (d0[1] + u * v[1]) ** 2 + (d0[2] + u * v[2]) ** 2)
        if d < best:
            best, when = d, s0 + u
    return best, when


@njit(cache=True)
def first_conflict(ta, pa, aa, tb, pb, ab, sep):
    """(start, end) of the first stretch of time in which both are airborne and
    less than ``sep`` apart (end: when that stretch ends); (inf, inf) if none."""
    marks = _intervals(ta, tb)
    start = np.inf
    ia = np.zeros(1, np.int64)
    ib = np.zeros(1, np.int64)
    for k in range(len(marks) - 1):
        s0, s1 = marks[k], marks[k + 1]
        both, d0, v = _offset(ta, pa, aa, tb, pb, ab, s0, s1, ia, ib)
        lo, hi = np.inf, -np.inf
        if both:
            lo, hi = _below(d0, v, sep, s1 - s0)
        if lo <= hi:
            if start == np.inf:
                start = s0 + lo
            if hi < s1 - s0 - 1e-9:
                return start, s0 + hi
        elif start < np.inf:
            return start, s0
    if start < np.inf:
        return start, marks[-1]
    return np.inf, np.inf


@njit(cache=True)
def _below(d0, v, sep, span):
    """The stretch [lo, hi] of [0, span] where |d0 + u v| < sep (lo > hi: none)."""
    a = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    b = 2.0 * (d0[0] * v[0] + d0[1] * v[1] + d0[2] * v[2])
    c = d0[0] * d0[0] + d0[1] * d0[1] + d0[2] * d0[2] - sep * sep
    if a <= 1e-18:
        return (0.0, span) if c < 0.0 else (np.inf, -np.inf)
    disc = b * b - 4.0 * a * c
    if disc <= 0.0:
        return np.inf, -np.inf
    root = np.sqrt(disc)
    u0 = (-b - root) / (2.0 * a)
    u1 = (-b + root) / (2.0 * a)
    lo, hi = max(u0, 0.0), min(u1, span)
    return (lo, hi) if lo < hi else (np.inf, -np.inf)
