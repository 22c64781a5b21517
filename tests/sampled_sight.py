"""Line of sight by dense sampling of the bilinear surface: an independent
reference for planner.exposure.los, which solves it in closed form."""

import math

import numpy as np

from planner.exposure.los import EARTH_RADIUS_M
from planner.terrain import bilinear


def _crossings(a0, a1):
    """Fractions of the way a0 -> a1 at which it crosses a whole number."""
    if a0 == a1:
        return np.empty(0)
    whole = np.arange(math.ceil(min(a0, a1)), math.floor(max(a0, a1)) + 1)
    return (whole - a0) / (a1 - a0)


def sampled_lowest(h, cell, u0, v0, z0, u1, v1, k, n=20001):
    """The lowest altitude at grid point (u1, v1) seen from an eye at (u0, v0, z0).

    Sampling can only miss an obstacle: a lower bound of the exact value. The
    bilinear surface creases where the ray crosses a grid line; those points are
    sampled exactly, since a crease a few metres from the eye, missed by a
    centimetre, moves the answer by up to a metre."""
    t = np.concatenate([np.linspace(0, 1, n), _crossings(u0, u1), _crossings(v0, v1)])
    t = t[(t > 0) & (t <= 1)]
    u, v = u0 + t * (u1 - u0), v0 + t * (v1 - v0)
    dist = cell * math.hypot(u1 - u0, v1 - v0)
    d = t * dist
    slope = (bilinear(h, v, u) - k * d * d / (2 * EARTH_RADIUS_M) - z0) / d
    return z0 + dist * slope.max() + k * dist * dist / (2 * EARTH_RADIUS_M)
