"""The fleet on one clock: the closest-approach proof against dense sampling, the
schedule's waits, and every method's plans separated on generated terrains, judged
again from plan.json's own trajectories with an independent sampler."""

import itertools
import math
from dataclasses import replace

import numpy as np
import places_reference as ref
import pytest
from hills import central_outpost
from hypothesis import given, settings
from hypothesis import strategies as st
from quick_plan import plan_routes
from scipy import ndimage

from autopilots import profile
from planner.fleet import Profile, Trajectory, schedule, separation
from planner.fleet.schedule import drift_s
from planner.pipeline import exposure_stages
from planner.scenario import METHODS, Scenario
from planner.terrain import synthetic_terrain
from planner.travel import TravelParams

pytestmark = pytest.mark.timeout(600)


# -- an independent reference: dense sampling -------------------------------------------
def sampled_closest(a: Trajectory, b: Trajectory, step=0.01) -> float:
    """Least distance of two trajectories while both are airborne, sampled every
    ``step`` seconds (and at every breakpoint of either)."""
    lo, hi = max(a.t[0], b.t[0]), min(a.t[-1], b.t[-1])
    if hi < lo:
        return math.inf
    s = np.unique(np.concatenate([np.arange(lo, hi, step), [hi], a.t, b.t]))
    # a vehicle is on the ground before its first row and after its last: at the
    # instant it lifts off or touches down it is not yet (no longer) in the way
    ends = [a.t[0], a.t[-1], b.t[0], b.t[-1]]
    s = s[(s >= lo) & (s <= hi) & ~np.isin(s, [e for e in ends if e in (lo, hi)])]
    if not len(s):
        return math.inf
    best = math.inf
    for side in ("left", "right"):        # both limits at a breakpoint
        pa, fa = _at(a, s, side)
        pb, fb = _at(b, s, side)
        both = fa & fb
        if both.any():
            best = min(best, float(np.linalg.norm(pa - pb, axis=1)[both].min()))
    return best


def _at(tr, s, side):
    p = np.column_stack([np.interp(s, tr.t, tr.xyz[:, k]) for k in range(3)])
    seg = np.clip(np.searchsorted(tr.t, s, side=side) - (1 if side == "right" else 0) -
                  (0 if side == "right" else 1), 0, len(tr.t) - 2)
    return p, tr.air[seg]


def trajectory(points, times, air=None, holds=()):
    """A trajectory through ``points`` at ``times``, holding ``holds`` [(index, s)]."""
    t, xyz = list(times), [np.asarray(p, float) for p in points]
    for i, h in sorted(holds, reverse=True):
        t = t[:i + 1] + [x + h for x in t[i:]]
        xyz = xyz[:i + 1] + xyz[i:]
    n = len(t)
    return Trajectory(np.array(t, float), np.array(xyz), np.ones(n - 1, bool)
                      if air is None else np.asarray(air, bool))


# -- the proof against sampling -----------------------------------------------------
coords = st.floats(-200, 200)
point = st.tuples(coords, coords, st.floats(0, 120))


@st.composite
def trajectories(draw):
    n = draw(st.integers(2, 6))
    pts = draw(st.lists(point, min_size=n, max_size=n))
    t0 = draw(st.floats(0, 30))
    gaps = draw(st.lists(st.floats(0.5, 25), min_size=n - 1, max_size=n - 1))
    times = np.r_[t0, t0 + np.cumsum(gaps)]
    holds = draw(st.lists(st.tuples(st.integers(0, n - 1), st.floats(0.5, 20)), max_size=2,
                          unique_by=lambda h: h[0]))
    tr = trajectory(pts, times, holds=holds)
    air = draw(st.lists(st.booleans(), min_size=len(tr.t) - 1, max_size=len(tr.t) - 1))
    return Trajectory(tr.t, tr.xyz, np.array(air, bool))


@settings(max_examples=150, deadline=None)
@given(trajectories(), trajectories())
def test_closest_approach_is_the_sampled_one(a, b):
    d, when = a.closest_approach(b)
    ref = sampled_closest(a, b)
    if not math.isfinite(ref):
        assert not math.isfinite(d)
        return
    # exact: never above a sampled distance, and within what 10 ms of motion can hide
    speed = max(np.abs(np.diff(x.xyz, axis=0)).sum(axis=1).max() /
                max(np.diff(x.t).min(), 1e-9) for x in (a, b) if len(x.t) > 1)
    assert d <= ref + 1e-6
    assert d >= ref - 0.02 * speed - 1e-6


@pytest.mark.parametrize("case", ["crossing", "head-on", "parallel", "one holding"])
def test_closest_approach_in_the_classic_encounters(case):
    if case == "crossing":          # x-axis and y-axis at 10 m/s, through the origin at t = 10
        a = trajectory([(-100, 0, 50), (100, 0, 50)], [0, 20])
        b = trajectory([(0, -100, 50), (0, 100, 50)], [2, 22])
        want = math.hypot(10, 10)                   # at t = 11 s
    elif case == "head-on":
        a = trajectory([(-100, 0, 50), (100, 0, 50)], [0, 20])
        b = trajectory([(100, 5, 50), (-100, 5, 50)], [0, 20])
        want = 5.0
    elif case == "parallel":        # in trail, 15 s behind at 10 m/s
        a = trajectory([(0, 0, 50), (300, 0, 50)], [0, 30])
        b = trajectory([(0, 0, 50), (300, 0, 50)], [15, 45])
        want = 150.0
    else:                           # b holds at (50, 3, 50) while a flies past
        a = trajectory([(0, 0, 50), (100, 0, 50)], [0, 10])
        b = trajectory([(50, 3, 50), (50, 3, 50)], [0, 60])
        want = 3.0
    d, _ = a.closest_approach(b)
    assert d == pytest.approx(want, abs=1e-6)
    assert d == pytest.approx(sampled_closest(a, b, 0.001), abs=0.02)
    begin, end = a.first_conflict(b, want + 1.0)
    assert begin <= end and math.isfinite(begin)
    assert not math.isfinite(a.first_conflict(b, want - 0.5)[0])


def _vertical_reference(height, band, slow, rate, dt=1e-3):
    """(times, heights above the ground) of a column flown up from the ground (or
    down to it, read backwards) at ``slow`` m/s below ``band`` and ``rate`` above,
    by small steps: the reference the profile's closed form is judged by."""
    h, t, out = 0.0, 0.0, [(0.0, 0.0)]
    while h < height:
        h = min(height, h + dt * (slow if h < band else rate))
        t += dt
        out.append((t, h))
    return np.array(out).T


@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_a_takeoff_and_a_landing_fly_their_lowest_metres_at_the_firmwares_rates(firmware):
    """A sortie's takeoff and landing in its profile, against a step-by-step
    reference of the firmware's rates (PX4: 1.5 m/s for the lowest 10 m of a
    takeoff; ArduPilot: 0.5 m/s for the lowest 10 m of a landing): the same
    times to the top and to touchdown, and the same height at every moment."""
    rates = profile(firmware).rates
    params = Scenario(sample=True, firmware=firmware).travel_params()
    base = np.array([0.0, 0.0, 100.0])
    poly = np.array([[0, 0, 220.0], [600, 0, 220.0], [0, 0, 220.0]])
    tr = Profile.of_route(poly, params, launch=base).timed(0.0)
    up_t, up_h = _vertical_reference(120.0, rates.takeoff_band_m, rates.takeoff_mps,
                                     rates.climb_mps)
    down_t, down_h = _vertical_reference(120.0, rates.land_band_m, rates.land_mps,
                                         rates.descent_mps)
    at_top = tr.t[tr.xyz[:, 2] == 220.0]
    assert at_top[0] == pytest.approx(up_t[-1], abs=0.01)
    assert tr.end - at_top[-1] == pytest.approx(down_t[-1], abs=0.01)
    assert np.interp(up_t, tr.t, tr.xyz[:, 2]) - 100.0 == pytest.approx(up_h, abs=0.01)
    landing = tr.end - down_t
    assert np.interp(landing, tr.t, tr.xyz[:, 2]) - 100.0 == pytest.approx(down_h, abs=0.01)
    assert tr.xyz[0, 2] == tr.xyz[-1, 2] == 100.0


def sampled_in_column(tr: Trajectory, s, centre, radius, top) -> np.ndarray:
    """Whether ``tr`` is airborne within ``radius`` of ``centre`` across the ground
    and below ``top`` at each time of ``s`` (strictly inside its span)."""
    inside = np.zeros(len(s), bool)
    span = (s > tr.t[0]) & (s < tr.t[-1])
    p, _ = _at(tr, s[span], "left")
    inside[span] = (np.hypot(p[:, 0] - centre[0], p[:, 1] - centre[1]) < radius) & \
        (p[:, 2] < top)
    return inside


def test_one_base_one_vehicle_in_its_column_at_a_time():
    """Two vehicles of one base, flying out east and north and back: the one
    waiting on the ground is not airborne; the other takes off once the first has
    left the column (a separation away across the ground, issue 62: stacked a
    separation apart in it, two real ArduPilot copters met 4-6 m apart at its
    top), and lands once the first has landed or left. Judged by sampling."""
    params = TravelParams()
    base = np.array([0.0, 0.0, 100.0])
    east = np.array([[0, 0, 220.0], [600, 0, 220.0], [0, 0, 220.0]])
    north = np.array([[0, 0, 220.0], [0, 600, 220.0], [0, 0, 220.0]])
    profiles = [Profile.of_route(p, params, launch=base) for p in (east, north)]
    fleet = schedule(profiles, 30.0)
    a, b = fleet.trajectories
    assert fleet.min_separation_m >= 30.0
    assert sampled_closest(a, b) >= 30.0 - 1e-6
    s = np.arange(0.0, max(a.end, b.end), 0.01)
    both = sampled_in_column(a, s, base, 30.0, 250.0) & sampled_in_column(b, s, base, 30.0,
                                                                          250.0)
    assert not both.any(), f"both in the column at t = {s[both][0]:.2f} s"
    # the first leaves the column 30 m along its first leg after its 120 m climb;
    # the second takes off then and the drift either may have on its schedule
    # later, give or take the whole seconds and the doubling of the waits
    first = min(fleet.timings, key=lambda t: t.start_s).trajectory
    inside = sampled_in_column(first, s, base, 30.0, 250.0)
    out = s[np.argmax(inside & ~np.r_[inside[1:], False])]     # the end of its climb out
    starts = sorted(t.start_s for t in fleet.timings)
    late = out + drift_s(b)
    assert starts[0] == 0.0 and late - 0.01 <= starts[1] <= 2 * late + 1.0
    same = schedule([profiles[0], profiles[0]], 30.0).trajectories
    assert same[1].start >= same[0].end or same[0].start >= same[1].end   # one path: in turn


def test_a_vehicle_in_the_air_goes_before_those_on_the_ground():
    """A re-plan: one vehicle hovers in the air, its way home crossing the path of
    another standing at its base with three sorties to fly. The one in the air
    flies on at once and the other waits on the ground, even where the coverage
    time would gain from the other order (here the last sortie's end alone
    counts): a hold draws the battery of the one in the air. (Placed after the
    ground chain, it held 21 s here; in a re-plan of `gcs fly` it once hovered
    over the base for all the other's sorties.)"""
    params = TravelParams()
    base = np.array([0.0, 0.0, 100.0])
    out = np.array([[0, 0, 220.0], [900, 0, 220.0], [0, 0, 220.0]])
    home = np.array([[450, -800, 220.0], [450, 300, 220.0]])
    held = Profile.of_route(home, params, launch=np.array([450.0, 300.0, 100.0]),
                            start=np.array([450.0, -840.0, 220.0]))
    ground = [Profile.of_route(out, params, launch=base) for _ in range(3)]
    fleet = schedule([held] + ground, 30.0, lambda timings: timings[3].trajectory.end,
                     after=[None, None, 1, 2], turnaround_s=60.0)
    assert fleet.order[0] == 0 and fleet.timings[0].wait_s == 0.0
    assert fleet.timings[1].start_s > 0.0 and fleet.min_separation_m >= 30.0


def test_a_vehicle_in_the_air_never_waits_for_anothers_later_sorties():
    """Two vehicles in the air over one base: B, its battery the more flown, comes
    home first; A hovers 15 m up in the column. B's two later sorties from that
    base come after A's flight, not before it (placed with B's whole chain, A
    hovered 590 s here for them, and in a re-plan of `gcs fly` 8809 s)."""
    params = TravelParams()
    base = np.array([0.0, 0.0, 100.0])
    out = np.array([[0, 0, 220.0], [900, 0, 220.0], [0, 0, 220.0]])
    short = np.array([[0, 0, 220.0], [0, 300, 220.0], [0, 0, 220.0]])
    a = Profile.of_route(short, params, launch=base, start=base + [0.0, 0.0, 15.0])
    b_home = Profile.of_route(np.array([[100, 0, 220.0], [0, 0, 220.0]]), params,
                              launch=base, start=np.array([100.0, 0.0, 220.0]))
    b_later = [Profile.of_route(out, params, launch=base) for _ in range(2)]
    fleet = schedule([a, b_home] + b_later, 30.0, after=[None, None, 1, 2],
                     urgency=[-10.0, -100.0, 0.0, 0.0])
    assert fleet.order[:2] == [1, 0] and fleet.timings[1].wait_s == 0.0
    assert fleet.timings[0].trajectory.end < fleet.timings[2].trajectory.end
    # (A waits for B to land through the column it hovers in: no order keeps them
    # apart there, the guard acts in flight)
    assert fleet.timings[0].wait_s < 120.0


# -- every method, on generated terrains ----------------------------------------------
def _plan(method, k, seed, separation_m=30.0, **more):
    terrain = synthetic_terrain(56, 56, cell=30.0, seed=seed, family="hills")
    post = central_outpost(terrain)
    s = Scenario(sample=True, uavs=3, k=k, sensor_range_m=500.0, ceiling_agl_m=150.0,
                 clearance_m=20.0, hide_margin_m=5.0, method=method,
                 separation_m=separation_m, time_budget_s=0.2, **more)
    # one base for the fleet: the flyable cell nearest a corner with room around it
    flyable = exposure_stages(s.validate(), terrain=terrain, outposts=[post]).flyable
    room = ndimage.binary_erosion(flyable, np.ones((5, 5), bool))
    rows, cols = np.nonzero(room)
    i = int(np.argmin(rows + cols))
    llon, llat = terrain.to_lonlat(*terrain.xy(rows[i], cols[i]))
    s = replace(s, launch=[(float(llat), float(llon))]).validate()
    return plan_routes(s, terrain=terrain, outposts=[post])


@pytest.mark.slow
@pytest.mark.parametrize("method,k", [(m, k) for m in METHODS for k in (0, 1, 2)])
def test_every_method_plans_a_separated_fleet(method, k):
    ctx, outcome = _plan(method, k, seed=11 + k)
    plan = outcome.plan
    # judged from plan.json's trajectories alone (rows [t, lon, lat, alt], linear)
    trajs = []
    for v in plan.vehicles:
        rows = np.array(v.trajectory, float)
        x, y = ctx.terrain.from_lonlat(rows[:, 1], rows[:, 2])
        trajs.append(Trajectory(rows[:, 0], np.column_stack([x, y, rows[:, 3]]),
                                np.ones(len(rows) - 1, bool)))
        # from the ground at the base to the ground, through every waypoint in order
        assert rows[0, 3] == pytest.approx(v.launch.alt_amsl) == rows[-1, 3]
        assert rows[0, 0] == pytest.approx(v.takeoff_s)
        at = {round(w.t_s, 3): (w.lon, w.lat) for w in v.waypoints}
        for t, (lon, lat) in at.items():
            row = rows[np.argmin(np.abs(rows[:, 0] - t))]
            assert (row[1], row[2]) == pytest.approx((lon, lat), abs=2e-7)
    for a, b in itertools.combinations(trajs, 2):
        assert sampled_closest(a, b, 0.05) >= 30.0 - 0.05
    # one vehicle at a time in the column above the base: within the separation of
    # it across the ground, below the first waypoint + the separation
    base = plan.vehicles[0].launch
    centre = ctx.terrain.from_lonlat(base.lon, base.lat)
    top = max(v.waypoints[0].alt_amsl for v in plan.vehicles if v.waypoints) + 30.0
    s = np.arange(0.0, max(t.end for t in trajs), 0.05)
    inside = np.array([sampled_in_column(t, s, centre, 30.0, top) for t in trajs])
    assert (inside.sum(axis=0) <= 1).all(), s[inside.sum(axis=0) > 1][:3]
    assert plan.metrics["min_separation_m"] >= 30.0
    assert min(v.takeoff_s for v in plan.vehicles) == 0.0
    # a target's counted sightings are from distinct UAVs at distinct places (brute
    # force), and every target has what its places allow of k + 1
    found = ref.sightings(outcome.problem, outcome.allocation.routes)
    counts = [ref.matched(f) for f in found]
    np.testing.assert_array_equal(outcome.counts, counts)
    assert (np.asarray(counts) >= ref.requirement(outcome.problem)).all()


def test_the_separation_costs_waits_and_zero_keeps_none():
    _, apart = _plan("rt", 1, seed=12)
    _, close = _plan("rt", 1, seed=12, separation_m=0.0)
    assert close.plan.metrics["wait_s"] == 0.0
    assert all(v.takeoff_s == 0.0 for v in close.plan.vehicles)
    assert apart.plan.metrics["wait_s"] > 0.0
    assert apart.plan.metrics["coverage_time_s"] >= close.plan.metrics["coverage_time_s"]
    assert separation([Trajectory(np.array([0.0, 1.0]), np.zeros((2, 3)),
                                  np.ones(1, bool))])[1] is None


def _flown_closest(ctx, plan) -> float:
    """The closest two of plan.json's trajectories come, sampled every 0.05 s."""
    trajs = []
    for v in plan.vehicles:
        rows = np.array(v.trajectory, float)
        x, y = ctx.terrain.from_lonlat(rows[:, 1], rows[:, 2])
        trajs.append(Trajectory(rows[:, 0], np.column_stack([x, y, rows[:, 3]]),
                                np.ones(len(rows) - 1, bool)))
    return min(sampled_closest(a, b, 0.05) for a, b in itertools.combinations(trajs, 2))


def test_plans_keep_the_margin_beyond_the_separation():
    """A plan is timed for the separation and its margin (params say both), so the
    guard has nothing to do on a flight that keeps to its usual spread; margin 0
    times it for the separation alone."""
    ctx, kept = _plan("rt", 1, seed=12, separation_margin_m=20.0)
    ctx0, bare = _plan("rt", 1, seed=12, separation_margin_m=0.0)
    assert kept.plan.params["separation_m"] == 30.0
    assert kept.plan.params["separation_margin_m"] == 20.0
    assert _flown_closest(ctx, kept.plan) >= 50.0 - 0.05
    assert kept.plan.metrics["min_separation_m"] >= 50.0 - 1e-6
    assert _flown_closest(ctx0, bare.plan) >= 30.0 - 0.05
    assert kept.plan.metrics["wait_s"] >= bare.plan.metrics["wait_s"]
