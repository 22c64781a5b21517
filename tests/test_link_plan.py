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


@settings(max_examples=12, deadline=None)
@given(family=st.sampled_from(["hills", "ridges", "peaks"]), seed=st.integers(0, 1000),
       ends=st.tuples(*[st.integers(2, 37)] * 6), above=st.floats(5.0, 120.0))
def test_predicted_silences_match_the_brute_force_ray_on_generated_terrains(family, seed,
                                                                            ends, above):
    """On generated terrains, an antenna on a 2 m mast and a vehicle flying straight
    across at a height above the highest ground: every second the plan calls silent
    the brute-force ray finds blocked (or beyond the range), and every second the ray
    clears by more than the kernel's sub-step slack is heard."""
    terrain = synthetic_terrain(40, 40, cell=CELL, seed=seed, family=family)
    h = terrain.height
    (ar, ac, r0, c0, r1, c1) = ends
    ax, ay = terrain.xy(ar, ac)
    alon, alat = terrain.to_lonlat(ax, ay)
    eye = (float(ac), float(ar), float(terrain.ground(ax, ay, upper=True)[0]) + 2.0)
    (x0, y0), (x1, y1) = terrain.xy(r0, c0), terrain.xy(r1, c1)
    alt = float(np.nanmax(h)) - 60.0 + above
    span = 120.0
    found = silences(terrain, [Antenna(float(alat), float(alon), 2.0)], RADIO,
                     [(0.0, x0, y0, alt), (span, x1, y1, alt)], [(0.0, span)])
    silent = np.zeros(int(span), bool)
    for a, b in found.windows:
        silent[int(a):int(b) + 1] = True
    slack = RADIO.fresnel * math.sqrt(RADIO.wavelength_m * kernels.SUB_M) + 1e-3
    for s in range(int(span)):
        x, y = x0 + (x1 - x0) * s / span, y0 + (y1 - y0) * s / span
        d = math.dist((x, y, alt), (ax, ay, eye[2]))
        if d <= RADIO.near_m:
            assert not silent[s]
            continue
        rr, cc = terrain.rowcol(x, y)
        margin = sampled_margin(h, eye, (float(cc), float(rr), alt), RADIO.wavelength_m,
                                RADIO.fresnel, n=4001)
        if silent[s]:
            assert d > RADIO.range_m or margin < slack, (s, margin)
        elif d <= RADIO.range_m:
            assert margin >= -1e-3 - slack, (s, margin)


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


def _excess(plan, aims) -> float:
    """Seconds of the plan's predicted silences past each vehicle's aim, summed."""
    return sum(max(b - a - aim, 0.0) for v, aim in zip(plan.vehicles, aims)
               for a, b in v.silences)


def test_max_silence_checks_in_where_the_antenna_hears_and_keeps_the_photographs(planned):
    """--max-silence on the shared plan (silences of 3-7 min): the check-ins stand where
    the brute-force ray from the antenna clears the Fresnel zone, the silences past
    the limit are shorter in all than without them, each vehicle's overrun is said as
    its longest silence less the limit, nothing photographed is lost, and the
    missions written from the plan pass their proofs."""
    from dataclasses import replace

    from gcs.plan_folder import write_plan_folder
    from planner.link import antenna_eyes
    from planner.pipeline import plan_mission

    limit = 120.0
    terrain = planned.terrain
    ctx, outcome = plan_mission(replace(planned.ctx.scenario, max_silence_s=limit),
                                terrain=terrain, outposts=planned.ctx.outposts)
    link, before = outcome.plan.metrics["link"], planned.plan
    kept = link["max_silence"]
    assert sum(kept["check_ins"]) > 0, "the shared plan has silences a check-in breaks"
    # the floor is a lower bound: no plan through the same viewpoints is under it
    for plan in (before, outcome.plan):
        for v, floor in zip(plan.metrics["link"]["vehicles"], kept["floor_s"]):
            assert v["longest_s"] >= floor - 2.0
    aims = [max(limit, f) for f in kept["floor_s"]]
    assert _excess(outcome.plan, aims) < _excess(before, aims)
    for v, over in zip(link["vehicles"], kept["over_s"]):
        assert over == pytest.approx(max(v["longest_s"] - limit, 0.0))
    assert kept["met"] == (max(v["longest_s"] for v in link["vehicles"]) <= limit)
    eye = antenna_eyes(terrain, ctx.scenario.link()[0])[0]
    slack = RADIO.fresnel * math.sqrt(RADIO.wavelength_m * kernels.SUB_M) + 1e-3
    for lat, lon, alt in (p for at in kept["at"] for p in at):
        row, col = terrain.rowcol(*terrain.from_lonlat(lon, lat))
        if CELL * math.hypot(col - eye[0], row - eye[1]) > RADIO.near_m:
            assert sampled_margin(terrain.height, eye, (float(col), float(row), alt),
                                  RADIO.wavelength_m, RADIO.fresnel, n=4001) >= -slack
    # check-ins take no photographs: every viewpoint and target as before
    shots = [sorted((w.lat, w.lon) for w in v.waypoints if w.snapshot) for v in before.vehicles]
    assert [sorted((w.lat, w.lon) for w in v.waypoints if w.snapshot)
            for v in outcome.plan.vehicles] == shots
    for key in ("covered", "k_covered", "snapshots"):
        assert outcome.plan.metrics[key] == before.metrics[key]
    write_plan_folder(planned.dir.parent / "checked-in", ctx, outcome)


def test_max_silence_needs_a_radio_to_be_heard_by():
    """Without an antenna or a base there is no silence to keep short: refused, named."""
    from common.errors import InputError
    from planner.scenario import Scenario

    with pytest.raises(InputError, match="max_silence_s needs an antenna"):
        Scenario(sample=True, max_silence_s=60.0).validate()
    with pytest.raises(InputError, match="positive number of seconds"):
        Scenario(sample=True, max_silence_s=-1.0, launch=[(36.5, -84.2)]).validate()
