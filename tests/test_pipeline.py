"""The whole planning pipeline on small synthetic terrains: coverage, hiddenness, times."""

import numpy as np
import pytest
from quick_plan import plan_routes

from planner.exposure import (
    Outpost,
    is_hidden,
    segment_clear,
    segment_hidden,
    segments_clear,
    segments_hidden,
)
from planner.fleet import stop_time
from planner.pipeline import plan_mission
from planner.scenario import Scenario
from planner.terrain import bilinear, synthetic_terrain
from planner.travel import polyline_time

N = 96


@pytest.fixture(scope="module")
def terrain():
    return synthetic_terrain(N, N, cell=30.0, seed=3, family="hills")


def _outposts(terrain):
    r, c = N // 2, N // 2
    x, y = terrain.xy(r, c)
    return [Outpost(float(x), float(y), 2.0, 2500.0)]


def _scenario(terrain, **kw):
    lon, lat = terrain.to_lonlat(*terrain.xy(5, 5))
    base = dict(sample=True, uavs=3, sensor_range_m=600.0, ceiling_agl_m=150.0, clearance_m=20.0,
                hide_margin_m=5.0)
    base.update(kw)
    return Scenario(**base).validate()


@pytest.fixture(scope="module")
def planned(terrain):
    return plan_mission(_scenario(terrain), terrain=terrain, outposts=_outposts(terrain))


def test_every_target_covered(planned):
    ctx, outcome = planned
    m = outcome.plan.metrics
    assert m["targets"] > 100
    assert m["k_covered"] == m["targets"]
    assert (outcome.counts >= 1).all()


def test_routes_are_hidden_and_clear(planned):
    ctx, outcome = planned
    for poly in outcome.polylines:
        assert len(poly) >= 1
        assert is_hidden(ctx.surface, poly).all()
        for a, b in zip(poly[:-1], poly[1:]):
            assert segment_hidden(ctx.surface, a, b)
            assert segment_clear(ctx.surface, a, b)


def test_legs_stay_under_the_ceiling_all_along(planned):
    """z <= E - hide_margin at every point, E between cell centres being the bilinear
    surface of its cell values (dense sampling; E recomputed from lowest_seen), up
    to what rounding the waypoints for MAVLink moves them (a centimetre at most
    horizontally, times the ceiling's slope)."""
    ctx, outcome = planned
    s, h = ctx.surface, ctx.terrain.height
    ceiling = np.minimum(s.lowest_seen, h + s.params.ceiling_agl_m) - s.params.hide_margin_m
    t = np.linspace(0, 1, 401)[:, None]
    worst = -np.inf
    for poly in outcome.polylines:
        for a, b in zip(poly[:-1], poly[1:]):
            p = a + t * (b - a)
            row, col = ctx.terrain.rowcol(p[:, 0], p[:, 1])
            worst = max(worst, np.max(p[:, 2] - bilinear(ceiling, row, col)))
    assert worst <= 0.02


def test_legs_stay_hidden_within_the_track_tolerance():
    """A vehicle that strays up to track_tolerance_m from a leg is still hidden and
    clear: the leg moved that far, in 8 directions, passes the exact tests without
    slack. (On this terrain 4 moved legs were seen when legs were proven without
    room.)"""
    terrain = synthetic_terrain(N, N, cell=30.0, seed=4, family="mixed")
    ctx, outcome = plan_mission(_scenario(terrain), terrain=terrain,
                                outposts=_outposts(terrain))
    tol = ctx.scenario.track_tolerance_m
    assert tol > 0
    angles = np.arange(8) * np.pi / 4
    shifts = np.c_[np.cos(angles), np.sin(angles), np.zeros(8)] * tol
    legs = [(a, b) for poly in outcome.polylines for a, b in zip(poly[:-1], poly[1:])]
    a = np.array([a for a, _ in legs for _ in shifts]) + np.tile(shifts, (len(legs), 1))
    b = np.array([b for _, b in legs for _ in shifts]) + np.tile(shifts, (len(legs), 1))
    assert len(legs) > 50
    assert segments_hidden(ctx.surface, a, b).all()
    assert segments_clear(ctx.surface, a, b).all()
    # so is every node with an edge (a dip's unchecked vertical part starts there)
    graph = ctx.graph
    linked = np.diff(graph.csr.indptr) > 0
    assert graph.legs_ok(graph.node_xyz[linked], graph.node_xyz[linked]).all()


def test_times_follow_the_travel_model(planned):
    """On the fleet clock: the legs at the travel model's speeds, the slowing at each
    inner waypoint (`stop_time`) and the schedule's holds; a snapshot is taken when
    its waypoint (and hold) is done."""
    ctx, outcome = planned
    params = ctx.scenario.travel_params()
    stop = stop_time(vars(ctx.scenario))
    for poly, vehicle in zip(outcome.polylines, outcome.plan.vehicles):
        w = vehicle.waypoints
        t = [p.t_s for p in w]
        holds = sum(p.hold_s for p in w[:-1])
        assert t[-1] == pytest.approx(t[0] + polyline_time(poly, params) + holds +
                                      stop * (len(w) - 2), rel=1e-9, abs=1e-6)
        assert vehicle.coverage_time_s == pytest.approx(max(p.t_s + p.hold_s for p in w
                                                            if p.snapshot))


def test_deterministic(terrain, planned):
    _, again = plan_routes(_scenario(terrain), terrain, _outposts(terrain))
    first = planned[1].plan
    assert [[(w.lon, w.lat, w.alt_amsl) for w in v.waypoints] for v in first.vehicles] == \
           [[(w.lon, w.lat, w.alt_amsl) for w in v.waypoints] for v in again.plan.vehicles]


def test_k1_with_launch_points(terrain):
    lon, lat = terrain.to_lonlat(*terrain.xy(8, 8))
    scenario = _scenario(terrain, k=1, launch=[(lat, lon)], method="rt+ls")
    ctx, outcome = plan_mission(scenario, terrain=terrain, outposts=_outposts(terrain))
    m = outcome.plan.metrics
    # every target has two sightings from two UAVs at two places, or all its places
    places = np.diff(ctx.visibility.target_indptr)
    assert (outcome.counts >= np.minimum(2, places)).all()
    assert m["k_covered"] == m["targets"] and m["k_impossible"] == (places < 2).sum()
    for v in outcome.plan.vehicles:
        assert v.launch is not None
        first, last = v.waypoints[0], v.waypoints[-1]
        # the same point, both rounded to MAVLink's 1e-7 degrees
        assert (first.lon, first.lat) == pytest.approx((v.launch.lon, v.launch.lat), abs=2e-7)
        assert (last.lon, last.lat) == pytest.approx((v.launch.lon, v.launch.lat), abs=2e-7)
        assert v.mission_time_s > v.coverage_time_s
    assert m["lower_bound_s"] <= m["coverage_time_s"]


def test_every_viewpoint_is_reachable_hidden_from_launch(terrain):
    """Regions are connected as cells; viewpoints must also be joined by hidden legs."""
    from planner.pipeline import coverage_problem, launch_starts, prepare

    lon, lat = terrain.to_lonlat(*terrain.xy(8, 8))
    ctx = prepare(_scenario(terrain, launch=[(lat, lon)]), terrain=terrain,
                  outposts=_outposts(terrain))
    problem = coverage_problem(ctx, 3, launch_starts(ctx))
    assert np.isfinite(problem.launch_out).all()
    assert np.isfinite(problem.launch_back).all()
    assert np.isfinite(ctx.travel).all()


def test_cropped_sample_keeps_the_outposts_inside():
    from planner.exposure import sample_outposts
    from planner.terrain import sample_terrain

    area = (36.49, -84.28, 36.56, -84.18)
    terrain = sample_terrain(area=area)
    with pytest.warns(UserWarning, match="2 outpost"):
        posts = sample_outposts(terrain)
    assert {p.name for p in posts} == {"South summit", "Fault gap"}
    south, west, north, east = area
    lon, lat = terrain.to_lonlat(*terrain.xy(np.array([0, terrain.shape[0] - 1]),
                                              np.array([0, terrain.shape[1] - 1])))
    assert lat[0] >= north - 0.01 and lat[1] <= south + 0.01
    assert lon[0] <= west + 0.01 and lon[1] >= east - 0.01


def test_allocation_and_routes_report_progress_as_they_go(terrain):
    """Bars move during the long stages, not only at their ends: fractions strictly
    between 0 and 1, never going back."""
    from planner.pipeline import allocate, launch_starts, prepare

    reports = {}
    lon, lat = terrain.to_lonlat(*terrain.xy(8, 8))
    scenario = _scenario(terrain, launch=[(lat, lon)])
    ctx = prepare(scenario, terrain=terrain, outposts=_outposts(terrain))
    allocate(ctx, scenario.uavs, launch_starts(ctx),
             progress=lambda stage, f: reports.setdefault(stage, []).append(f))
    for stage in ("allocation", "routes"):
        seen = reports[stage]
        assert seen[0] == 0.0 and seen[-1] == 1.0
        assert len([f for f in seen if 0.0 < f < 1.0]) >= 3, (stage, seen)
        assert all(b >= a for a, b in zip(seen, seen[1:])), (stage, seen)


def test_the_first_plan_after_an_install_says_it_compiles(tmp_path, monkeypatch, capsys):
    """An empty kernel cache (a fresh install, or new sources): `gcs plan` and `gcs
    demo` say why their first plan takes minutes; once numba has cached a kernel
    there, they do not."""
    from gcs.progress import note_first_compile

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    note_first_compile()
    assert "numba compiles its kernels" in capsys.readouterr().err
    (tmp_path / "coverage_x").mkdir()
    (tmp_path / "coverage_x" / "insertion.walk-1.py311.nbi").write_bytes(b"")
    note_first_compile()
    assert capsys.readouterr().err == ""
    # a folder numba cannot write (it compiles into __pycache__ then): nothing claimed
    monkeypatch.setenv("NUMBA_CACHE_DIR", "/proc/no-such-folder")
    note_first_compile()
    assert capsys.readouterr().err == ""


def test_fewer_bases_than_uavs_the_uavs_take_them_in_turn(terrain):
    """Three UAVs from two bases: UAVs 1 and 3 fly from the first, 2 from the
    second, each route starting and ending at its own base; more bases than UAVs
    is refused, naming the parameter."""
    from common.errors import InputError

    a = terrain.to_lonlat(*terrain.xy(8, 8))[::-1]
    b = terrain.to_lonlat(*terrain.xy(N - 9, 8))[::-1]
    scenario = _scenario(terrain, launch=[a, b], method="rt")
    assert scenario.launch_points == [a, b, a]
    _, outcome = plan_mission(scenario, terrain=terrain, outposts=_outposts(terrain))
    for v, base in zip(outcome.plan.vehicles, (a, b, a)):
        assert (v.launch.lat, v.launch.lon) == pytest.approx(base, abs=2e-7)
        first, last = v.waypoints[0], v.waypoints[-1]
        assert (first.lat, first.lon) == pytest.approx(base, abs=2e-7)
        assert (last.lat, last.lon) == pytest.approx(base, abs=2e-7)
    assert outcome.plan.params["launch"] == [list(p) for p in (a, b, a)]
    with pytest.raises(InputError, match="launch.*at most one launch point per UAV"):
        _scenario(terrain, uavs=1, launch=[a, b])
