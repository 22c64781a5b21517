"""The radio link stage (`planner.link`) against a brute-force reference: the ray
sampled densely over the bilinear terrain with the Earth's bulge, the first
Fresnel zone's radius at each sample. And a vehicle's predicted silences against
the same reference along its trajectory."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.exposure.los import EARTH_RADIUS_M
from planner.link import Antenna, Radio, kernels, silences
from planner.terrain import bilinear, synthetic_terrain

CELL = 30.0
CURV = 0.85714
RADIO = Radio()


def _terrain(seed, rows=40, cols=50):
    rng = np.random.default_rng(seed)
    return 200 + rng.normal(0, 4, (rows, cols)).cumsum(0).cumsum(1) / 5


def sampled_margin(h, a, b, wavelength, fresnel, n=20001) -> float:
    """Least (gap above the ground, bulge counted) - fresnel * zone radius along the
    ray a -> b (grid u, v, altitude), sampled at ``n`` points strictly inside it."""
    t = np.linspace(0.0, 1.0, n)[1:-1]
    u, v = a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])
    length = CELL * math.hypot(b[0] - a[0], b[1] - a[1])
    bulge = CURV * length * length * t * (1 - t) / (2 * EARTH_RADIUS_M)
    gap = a[2] + t * (b[2] - a[2]) - bilinear(h, v, u) - bulge
    return float(np.min(gap - fresnel * np.sqrt(wavelength * length * t * (1 - t))))


points = st.tuples(st.floats(0, 49), st.floats(0, 39), st.floats(0.0, 150.0))


@settings(max_examples=120, deadline=None)
@given(seed=st.integers(0, 10_000), a=points, b=points)
def test_a_clear_ray_is_clear_by_dense_sampling_and_a_margin_is_enough(seed, a, b):
    """`ray_clear` never promises contact dense sampling refutes, and promises it
    wherever sampling finds the zone clear by the most its radius changes over
    `SUB_M` of the ray (the kernel takes the largest radius of each such piece)."""
    h = _terrain(seed)
    (u0, v0, m0), (u1, v1, m1) = a, b
    if math.hypot(u1 - u0, v1 - v0) < 1.0:
        return
    z0 = bilinear(h, [v0], [u0])[0] + m0
    z1 = bilinear(h, [v1], [u1])[0] + m1
    clear = kernels.ray_clear(h, CELL, u0, v0, z0, u1, v1, z1, RADIO.wavelength_m,
                              RADIO.fresnel, CURV)
    margin = sampled_margin(h, (u0, v0, z0), (u1, v1, z1), RADIO.wavelength_m, RADIO.fresnel)
    slack = RADIO.fresnel * math.sqrt(RADIO.wavelength_m * kernels.SUB_M) + 1e-3
    if clear:
        assert margin >= -1e-3, margin
    if margin > slack:
        assert clear, (margin, slack)


def test_a_vehicle_behind_a_ridge_is_silent_there_and_only_there():
    """A ridge between the antenna and a vehicle flying straight past it: the
    predicted silence is the stretch of the trajectory the brute-force ray finds
    blocked, to the sampling step."""
    terrain = synthetic_terrain(60, 60, cell=CELL, seed=5, family="ridges")
    h = terrain.height
    r, c = np.unravel_index(np.argmin(h[5:-5, 5:-5]), (50, 50))
    ax, ay = terrain.xy(r + 5, c + 5)
    alon, alat = terrain.to_lonlat(ax, ay)
    antenna = Antenna(float(alat), float(alon), 2.0)
    # a vehicle 60 m above the highest ground, across the whole grid in 600 s
    x0, y0 = terrain.xy(3, 3)
    x1, y1 = terrain.xy(56, 56)
    alt = float(np.nanmax(h)) - 40.0
    rows = [(0.0, x0, y0, alt), (600.0, x1, y1, alt)]
    found = silences(terrain, [antenna], RADIO, rows, [(0.0, 600.0)])
    t = np.arange(0.0, 600.0, 1.0)
    eye = (c + 5.0, r + 5.0, float(terrain.ground(ax, ay, upper=True)[0]) + 2.0)
    blocked = []
    for s in t:
        x, y = x0 + (x1 - x0) * s / 600, y0 + (y1 - y0) * s / 600
        rr, cc = terrain.rowcol(x, y)
        d = math.dist((x, y, alt), (ax, ay, eye[2]))
        blocked.append(d > RADIO.near_m and (d > RADIO.range_m or sampled_margin(
            h, eye, (float(cc), float(rr), alt), RADIO.wavelength_m, RADIO.fresnel) < 0))
    assert found.silent_s == pytest.approx(sum(blocked), abs=3.0)
    assert 0 < found.silent_s < 600.0, "the case must have both contact and silence"
    for a, b in found.windows:
        assert all(blocked[int(s)] for s in range(int(a), int(b) + 1) if s < 600)
    assert found.airborne_s == 600.0 and found.longest_s <= found.silent_s
