"""Numba kernels of the link stage: a radio ray over the bilinear terrain.

A radio link between an antenna and a vehicle needs more than line of sight: the
first Fresnel zone around the ray (radius sqrt(lambda d1 d2 / D) at distances d1
and d2 from its ends) must be clear of the ground to a stated fraction (0.6, the
usual rule for a link close to free space). Along the ray, within one grid patch,
the ground is a quadratic in the ray's parameter t (`planner.exposure.los`), the
Earth's bulge with refraction ``curv D^2 t (1 - t) / 2R`` another, so the gap
between ray and ground is a quadratic whose least value over the piece is exact
(ends or its one stationary point); the Fresnel radius is taken at its largest
over each `SUB_M` of the piece (t nearest 1/2), so the test errs, by less than the
radius changes over that much of the ray (at most 0.6 sqrt(lambda SUB_M), 1.1 m at
915 MHz, where it changes fastest: at the ends), on the side of a silence. A patch
touching a void is unknown ground: no contact is promised across it.
"""

import math

import numpy as np
from numba import njit, prange

from planner.exposure.los import EARTH_RADIUS_M, line_over_patch, next_patch

#: metres of ray over which the Fresnel zone's radius is taken at its largest
SUB_M = 10.0


@njit(cache=True)
def ray_clear(h, cell, u0, v0, z0, u1, v1, z1, wavelength_m, fresnel, curv):
    """Whether the ray from (u0, v0, z0) to (u1, v1, z1) (grid units, m AMSL) keeps
    ``fresnel`` of its first Fresnel zone clear of the ground everywhere."""
    n_rows, n_cols = h.shape
    du = u1 - u0
    dv = v1 - v0
    dz = z1 - z0
    length = cell * math.sqrt(du * du + dv * dv)
    if length <= 0.0:
        return True
    bulge = curv * length * length / (2.0 * EARTH_RADIUS_M)
    t = 0.0
    while True:
        i, j, t_next = next_patch(u0, v0, du, dv, t, n_rows, n_cols)
        c0, c1, c2 = line_over_patch(h, i, j, u0, v0, du, dv)
        if not (c0 == c0 and c1 == c1 and c2 == c2):
            return False
        # gap(t) = z0 + dz t - ground(t) - bulge t (1 - t): a0 + a1 t + a2 t^2
        a0 = z0 - c0
        a1 = dz - c1 - bulge
        a2 = bulge - c2
        n = max(1, int(math.ceil((t_next - t) * length / SUB_M)))
        for k in range(n):
            sa = t + (t_next - t) * k / n
            sb = t + (t_next - t) * (k + 1) / n
            least = min(a0 + a1 * sa + a2 * sa * sa, a0 + a1 * sb + a2 * sb * sb)
            if a2 > 0.0:
                ts = -a1 / (2.0 * a2)
                if sa < ts < sb:
                    least = min(least, a0 + a1 * ts + a2 * ts * ts)
            mid = min(max(0.5, sa), sb)
            if least < fresnel * math.sqrt(wavelength_m * length * mid * (1.0 - mid)):
                return False
        if t_next >= 1.0:
            return True
        t = t_next


@njit(cache=True)
def reaches(h, cell, antennas, u, v, z, wavelength_m, fresnel, range_m, near_m, curv):
    """Whether some antenna (u, v, z) reaches the point (u, v, z): within ``near_m``
    (slant), or within ``range_m`` and its ray clear (`ray_clear`). One point,
    serially: the simulator's radio asks this of each vehicle many times a second."""
    for a in range(antennas.shape[0]):
        du = (u - antennas[a, 0]) * cell
        dv = (v - antennas[a, 1]) * cell
        dz = z - antennas[a, 2]
        d2 = du * du + dv * dv + dz * dz
        if d2 <= near_m * near_m:
            return True
        if d2 > range_m * range_m:
            continue
        if ray_clear(h, cell, antennas[a, 0], antennas[a, 1], antennas[a, 2], u, v, z,
                     wavelength_m, fresnel, curv):
            return True
    return False


@njit(cache=True, parallel=True)
def in_contact(h, cell, antennas, points, wavelength_m, fresnel, range_m, near_m, curv):
    """For each point (u, v, z), whether some antenna reaches it (`reaches`)."""
    out = np.zeros(points.shape[0], np.bool_)
    for k in prange(points.shape[0]):
        out[k] = reaches(h, cell, antennas, points[k, 0], points[k, 1], points[k, 2],
                         wavelength_m, fresnel, range_m, near_m, curv)
    return out
