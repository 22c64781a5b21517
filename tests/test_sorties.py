"""Sorties a battery can fly (`--endurance`): the shared small plan (tests/conftest.py)
planned again on an 8-minute battery, judged from what plan.json and the mission
files say: each sortie within the battery, from the base and back to it, a
turnaround apart, every mission proven and read back by pymavlink, the fleet
separated across sorties, and every viewpoint beyond one battery reported; and
a fleet from two bases flown on the simulator. The 12-minute battery's flights
are in test_sorties_flown.py."""

import json
import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from flown import problems_beside_guard, takeoffs_on_fresh_batteries

from common.errors import InputError
from gcs.cli import main
from gcs.mavlink import mavutil  # noqa: F401  (MAVLink 2 and the dialect, before mavwp)
from gcs.plan_folder import write_plan_folder
from gcs.sim import free_base_port, read_track, track_path
from missions.items import NAV_LAND, NAV_TAKEOFF, NAV_WAYPOINT
from missions.sources import load_sources
from planner.exposure import is_hidden
from planner.fleet import prove_separated
from planner.pipeline import plan_mission
from planner.plan import GeoPoint, Plan
from planner.scenario import METHODS, Scenario

pytestmark = pytest.mark.timeout(300)
#: a simulated flight of sorties: 60-80 s on a quiet 2-core machine,
#: 200-340 s measured beside other flights and CPU hogs (its re-plans slowed most)
FLIGHT_TIMEOUT = pytest.mark.timeout(600)

ENDURANCE_MIN = 8.0

@pytest.fixture(scope="module")
def sortied(planned, tmp_path_factory):
    """The shared plan's scenario on an 8-minute battery, written as `gcs plan` does."""
    scenario = replace(Scenario.from_params(planned.plan.params), endurance_min=ENDURANCE_MIN,
                       sample=True).validate()
    ctx, outcome = plan_mission(scenario, terrain=planned.terrain,
                                outposts=planned.ctx.outposts)
    d = tmp_path_factory.mktemp("sorties")
    write_plan_folder(d, ctx, outcome)
    return SimpleNamespace(dir=d, plan=Plan.load(d), ctx=ctx, outcome=outcome,
                           scenario=scenario, unlimited=planned.plan)


def _ground(route, rows):
    """Rows of a trajectory standing at the route's launch point (on the ground)."""
    return [abs(r[3] - route.launch.alt_amsl) < 0.01 and
            abs(r[1] - route.launch.lon) < 1e-6 and abs(r[2] - route.launch.lat) < 1e-6
            for r in rows]


def test_each_sortie_flies_from_the_base_and_back_within_one_battery(sortied):
    plan, s = sortied.plan, sortied.scenario
    usable = 60 * ENDURANCE_MIN * (1 - s.reserve_pct / 100)
    assert plan.metrics["battery"]["usable_s"] == pytest.approx(usable)
    # the unlimited plan needs more than one battery per vehicle: this one splits it
    assert max(v.mission_time_s - v.takeoff_s for v in sortied.unlimited.vehicles) > usable
    _assert_sorties_fit(plan, s, usable)
    assert plan.metrics["coverage_time_s"] > sortied.unlimited.metrics["coverage_time_s"]


def _assert_sorties_fit(plan, s, usable, least=2):
    """Each vehicle flies ``least`` sorties or more (some vehicle two or more), each
    from the base and back to it within one battery, a turnaround apart; the
    coverage time on the fleet clock."""
    assert max(len(v.sorties) for v in plan.vehicles) >= 2
    for v in plan.vehicles:
        if not v.sorties and least < 2:        # one flight: plan.json lists no sorties
            assert v.mission_time_s - v.takeoff_s <= usable + 1e-6, v.id
            continue
        assert len(v.sorties) >= least, v.id
        for j, (sortie, part) in enumerate(zip(v.sorties, v.sortie_routes()), start=1):
            rows = [r for r in v.trajectory if sortie["takeoff_s"] - 1e-3 <= r[0]
                    <= sortie["landing_s"] + 1e-3]
            ground = _ground(v, rows)
            # on the ground at the base at both ends, airborne in between
            assert ground[0] and ground[-1] and not any(ground[1:-1]), (v.id, j)
            assert rows[-1][0] - rows[0][0] == pytest.approx(sortie["landing_s"]
                                                             - sortie["takeoff_s"], abs=1e-3)
            assert sortie["flight_s"] <= usable + 1e-6, (v.id, j)
            assert [w.sortie for w in part.waypoints] == [j] * len(part.waypoints)
            # plan.json says where each sortie's waypoints are, and its base
            first, end = sortie["waypoints"]
            assert part.waypoints == v.waypoints[first:end] and end > first
            assert sortie["base"] == [v.launch.lon, v.launch.lat, v.launch.alt_amsl]
        # one battery after another: a turnaround on the ground between two
        for a, b in zip(v.sorties, v.sorties[1:]):
            assert b["takeoff_s"] >= a["landing_s"] + 60 * s.turnaround_min - 1e-6
        assert v.mission_time_s == v.sorties[-1]["landing_s"]
    # the coverage time counts the turnarounds: it is a time on the fleet clock
    last_shot = max(w.t_s for v in plan.vehicles for w in v.waypoints if w.snapshot)
    assert plan.metrics["coverage_time_s"] <= last_shot + 1e-6


def test_an_area_planned_in_parts_flies_sorties_too(planned, sortied):
    """The same battery with the area in two parts (what a large area is planned
    in): each part splits its routes into sorties, and joined they still fit the
    battery, are separated and pass the mission check, and cover every target
    the battery lets them (counted again from the snapshots)."""
    from missions.build import plan_missions
    from missions.check import check_mission

    s = replace(sortied.scenario, parts=2).validate()
    ctx, outcome = plan_mission(s, terrain=planned.terrain, outposts=planned.ctx.outposts)
    plan, usable = outcome.plan, sortied.plan.metrics["battery"]["usable_s"]
    assert plan.metrics["parts"] == 2
    _assert_sorties_fit(plan, s, usable, least=1)   # a small part may fit one battery
    assert prove_separated(plan, ctx.terrain, s.travel_params()) >= s.separation_m - 1e-6
    for mission in plan_missions(plan):
        check_mission(mission, ctx.surface)
    b, m = plan.metrics["battery"], plan.metrics
    assert m["k_covered"] == m["targets"] - b["targets_short"] > 0.75 * m["targets"]
    vis, seen = ctx.visibility, np.zeros(ctx.visibility.n_targets, bool)
    for w in (w for v in plan.vehicles for w in v.waypoints if w.snapshot):
        at = np.array(ctx.terrain.from_lonlat(w.lon, w.lat))
        off = np.hypot(*(ctx.viewpoints.xyz[:, :2] - at).T)
        e = int(np.argmin(off))
        assert off[e] < 0.1                  # a viewpoint, as rounded for MAVLink
        seen[vis.indices[vis.indptr[e]:vis.indptr[e + 1]]] = True
    assert seen.sum() >= m["k_covered"]


@pytest.mark.parametrize("method", METHODS)
def test_every_method_plans_sorties_the_battery_can_fly(planned, sortied, method):
    """On the terrain, not only on abstract problems: B and C once chose viewpoints
    beyond one battery (their greedy cover took every viewpoint) and were refused
    after four tries. Each method's sorties fit, and it flies no viewpoint beyond."""
    s = replace(sortied.scenario, method=method, time_budget_s=1.0).validate()
    ctx, outcome = plan_mission(s, terrain=planned.terrain, outposts=planned.ctx.outposts)
    plan = outcome.plan
    usable = plan.metrics["battery"]["usable_s"]
    assert all(f["flight_s"] <= usable + 1e-6 for v in plan.vehicles for f in v.sorties)
    far = {tuple(np.round(p, 6)) for p in plan.metrics["battery"]["beyond_battery_at"]}
    shots = {(round(w.lat, 6), round(w.lon, 6)) for v in plan.vehicles for w in v.waypoints
             if w.snapshot}
    assert far and not shots & far
    b = plan.metrics["battery"]
    assert plan.metrics["k_covered"] == plan.metrics["targets"] - b["targets_short"]
    # the sortie bound holds for each method's sorties, as flown on the fleet clock (on
    # 2026-12-07: 1,475 s against 5,445-7,446 s; the radius bound said 177 s)
    m = plan.metrics
    assert m["radius_bound_s"] < m["lower_bound_s"] <= m["coverage_time_s"]


def test_sorties_are_separated_on_the_fleet_clock(sortied):
    """Proven again from the saved missions, one trajectory per sortie."""
    d = prove_separated(sortied.plan, sortied.ctx.terrain,
                        sortied.scenario.travel_params(), source="plan.json")
    assert d >= sortied.plan.params["separation_m"] - 1e-6
    assert d == pytest.approx(sortied.plan.metrics["min_separation_m"], abs=0.05)


def test_one_mission_file_per_sortie_read_back_by_pymavlink(sortied):
    from pymavlink import mavwp

    for v in sortied.plan.vehicles:
        assert not (sortied.dir / f"vehicle-{v.id}.waypoints").exists()
        for j, part in enumerate(v.sortie_routes(), start=1):
            path = sortied.dir / f"vehicle-{v.id}-sortie-{j}.waypoints"
            loader = mavwp.MAVWPLoader()
            loader.load(str(path))
            items = [loader.wp(i) for i in range(1, loader.count())]   # line 0: home
            assert items[0].command == NAV_TAKEOFF and items[-1].command == NAV_LAND
            assert (items[-1].x, items[-1].y) == pytest.approx((v.launch.lat, v.launch.lon),
                                                               abs=1e-6)
            flown = [(i.x, i.y) for i in items if i.command == NAV_WAYPOINT]
            np.testing.assert_allclose(flown, [(w.lat, w.lon) for w in part.waypoints],
                                       atol=1e-6)
            # the file of one sortie is proven against the plan beside it, as its vehicle's
            source, = load_sources([sortied.dir / f"vehicle-{v.id}-sortie-{j}.plan"])
            assert source.proof.surface is not None


def test_viewpoints_beyond_one_battery_are_reported_and_never_flown(sortied):
    b = sortied.plan.metrics["battery"]
    assert b["beyond_battery"] == len(b["beyond_battery_at"]) > 0
    shots = {(round(w.lat, 6), round(w.lon, 6)) for v in sortied.plan.vehicles
             for w in v.waypoints if w.snapshot}
    assert not shots & {(round(lat, 6), round(lon, 6)) for lat, lon in b["beyond_battery_at"]}
    m = sortied.plan.metrics
    # the targets only they see are not counted as covered
    assert b["targets_short"] > 0
    assert m["k_covered"] <= m["targets"] - b["targets_short"]
    # each one said sees a target (by the context's own visibility sets): a far
    # point that sees nothing tells the operator nothing
    ctx = sortied.ctx
    lon, lat = np.array(b["beyond_battery_at"], float)[:, ::-1].T
    x, y = ctx.terrain.from_lonlat(lon, lat)
    xy = ctx.viewpoints.xyz[:, :2]
    ids = [int(np.argmin(np.hypot(xy[:, 0] - a, xy[:, 1] - c))) for a, c in zip(x, y)]
    assert all(len(ctx.visibility.seen_by(i)) for i in ids)


def test_the_overview_draws_the_viewpoints_beyond_one_battery(sortied):
    """Each one, where plan.json puts it, and the battery in the title."""
    from gcs.plots import overview_figure

    plan = sortied.plan
    fig = overview_figure(sortied.ctx.terrain, sortied.ctx.surface, plan)
    ax = fig.axes[0]
    drawn = [line for line in ax.lines if "beyond one battery" in (line.get_label() or "")]
    b = plan.metrics["battery"]
    assert len(drawn) == 1 and len(drawn[0].get_xdata()) == b["beyond_battery"]
    assert f"battery {ENDURANCE_MIN:g} min" in ax.get_title()
    share = plan.metrics["bound_targets_pct"]
    assert share < 100 and f"over the {share:.0f} % of targets one battery reaches" in \
        ax.get_title()
    assert any("sorties" in (line.get_label() or "") for line in ax.lines)


def test_an_unlimited_battery_is_said_and_plans_as_before(planned):
    from gcs.cli.views import battery_line

    assert all(not v.sorties for v in planned.plan.vehicles)
    assert planned.plan.metrics["battery"]["endurance_min"] is None
    assert battery_line(planned.plan).startswith("battery: unlimited (no --endurance given)")


def test_upload_of_a_plan_folder_of_several_sorties_is_refused(sortied):
    with pytest.raises(InputError, match="upload one sortie's mission at a time"):
        load_sources([sortied.dir])


@pytest.mark.parametrize("flags,message", [
    (["--endurance", "0"], "--endurance: must be a positive number of minutes"),
    (["--endurance", "nan"], "--endurance: must be a positive number"),
    (["--reserve", "95"], "--reserve: must be from 0 to 90"),
    (["--turnaround", "-1"], "--turnaround: must not be negative"),
])
def test_bad_battery_flags_are_one_line_errors(planned, tmp_path, capsys, flags, message):
    lat, lon, _ = planned.launch
    code = main(["plan", "--sample", "--launch", f"{lat},{lon}", *flags,
                 "-o", str(tmp_path / "p")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and message in err[-1] and not (tmp_path / "p").exists()


def test_an_endurance_needs_a_base(tmp_path, capsys):
    code = main(["plan", "--sample", "--endurance", "20", "-o", str(tmp_path / "p")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and "--endurance: needs launch points (--launch)" in err[-1]


def test_summary_says_the_sorties(sortied):
    from gcs.cli.views import battery_line

    line = battery_line(sortied.plan)
    usable = sortied.plan.metrics["battery"]["usable_s"] / 60
    assert line.startswith(f"battery: {ENDURANCE_MIN:g} min less 25 % reserve = "
                           f"{usable:.1f} min a sortie; sorties vehicle 1: ")
    assert "viewpoints beyond one battery" in line
    assert math.isfinite(sortied.plan.metrics["battery"]["longest_flight_s"])
    assert json.loads((sortied.dir / "plan.json").read_text())["vehicles"][0]["sorties"]
    assert np.all([w["sortie"] >= 1 for w in
                   json.loads((sortied.dir / "plan.json").read_text())["vehicles"][0]
                   ["waypoints"]])


@pytest.fixture(scope="module")
def two_bases(planned, tmp_path_factory):
    """The shared terrain with two bases 1.4 km apart, a UAV at each, on a 12-minute
    battery, k = 0: a sortie may land at either (the default), written as `gcs
    plan` does; and the same plan with each landing at its own (``own``)."""
    t = planned.terrain
    bases = [tuple(map(float, t.to_lonlat(*t.xy(i, j))))[::-1] for i, j in ((6, 6), (6, 53))]
    scenario = replace(Scenario.from_params(planned.plan.params), sample=True, uavs=2,
                       launch=bases, endurance_min=12.0).validate()
    ctx, outcome = plan_mission(scenario, terrain=t, outposts=planned.ctx.outposts)
    d = tmp_path_factory.mktemp("two_bases")
    write_plan_folder(d, ctx, outcome)
    own = plan_mission(replace(scenario, land_at="own"), terrain=t,
                       outposts=planned.ctx.outposts)[1].plan
    return SimpleNamespace(dir=d, plan=Plan.load(d), ctx=ctx, scenario=scenario,
                           bases=bases, own=own)


def _at(point, lat, lon, m=1.0) -> bool:
    """``point`` (a GeoPoint, or [lon, lat, alt]) within ``m`` of lat, lon."""
    plon, plat = (point.lon, point.lat) if hasattr(point, "lon") else point[:2]
    return math.hypot((plat - lat) * 111_195.0,
                      (plon - lon) * 111_195.0 * math.cos(math.radians(lat))) <= m


def test_a_sortie_lands_at_another_base_and_the_next_takes_off_there(two_bases):
    """With two bases a sortie lands at the one nearest its last viewpoint: some land
    at the other, and the next takes off there. Each sortie stands on the ground
    at its base and at the base it lands at, within one battery; its mission
    file (read back by pymavlink) takes off at the one and lands at the other,
    passes the mission check, and the fleet stays separated. Measured against
    the same plan landing each at its own base: covered sooner, and no worse."""
    from pymavlink import mavwp

    from gcs.cli.views import battery_line
    from missions.build import plan_missions
    from missions.check import check_mission

    plan, usable = two_bases.plan, two_bases.plan.metrics["battery"]["usable_s"]
    elsewhere = 0
    for v in plan.vehicles:
        assert v.sorties and v.sorties[0]["base"][:2] == [v.launch.lon, v.launch.lat]
        for a, b in zip(v.sorties, v.sorties[1:]):
            assert b["base"] == a["lands_at"]
        for j, (sortie, part) in enumerate(zip(v.sorties, v.sortie_routes()), start=1):
            assert any(_at(sortie["lands_at"], *b) for b in two_bases.bases)
            elsewhere += sortie["lands_at"] != sortie["base"]
            assert sortie["flight_s"] <= usable + 1e-6
            rows = [r for r in v.trajectory if sortie["takeoff_s"] - 1e-3 <= r[0]
                    <= sortie["landing_s"] + 1e-3]
            for row, end in ((rows[0], sortie["base"]), (rows[-1], sortie["lands_at"])):
                assert row[1:] == pytest.approx(end, abs=1e-6), (v.id, j)
            loader = mavwp.MAVWPLoader()
            loader.load(str(two_bases.dir / f"vehicle-{v.id}-sortie-{j}.waypoints"))
            items = [loader.wp(i) for i in range(1, loader.count())]
            assert items[0].command == NAV_TAKEOFF and items[-1].command == NAV_LAND
            assert _at(sortie["base"], items[0].x, items[0].y, 0.05)
            assert _at(sortie["lands_at"], items[-1].x, items[-1].y, 0.05)
            assert (part.launch, part.landing) == tuple(
                GeoPoint(*sortie[k]) for k in ("base", "lands_at"))
        assert v.landing == GeoPoint(*v.sorties[-1]["lands_at"])
    assert elsewhere >= 1
    for mission in plan_missions(plan):
        check_mission(mission, two_bases.ctx.surface)
    s = two_bases.scenario
    assert prove_separated(plan, two_bases.ctx.terrain, s.travel_params()) >= \
        s.separation_m - 1e-6
    own = two_bases.own
    assert all(f["lands_at"] == f["base"] for v in own.vehicles for f in v.sorties)
    assert plan.metrics["coverage_time_s"] < own.metrics["coverage_time_s"]
    assert plan.metrics["k_covered"] >= own.metrics["k_covered"]
    assert f"{elsewhere} sorties land at another base" in battery_line(plan)


@FLIGHT_TIMEOUT
def test_a_vehicle_flies_its_next_sortie_from_the_base_it_landed_at(two_bases, tmp_path):
    """`gcs fly` of the two-base plan on the simulator: each vehicle lands where its
    sortie lands, at the other base too, is not taken for lost there, and takes off
    from there on a fresh battery, to its planned height above that base (the
    takeoff once climbed the two bases' height difference too high: the home heard
    before the landing); its tracks hidden and clear throughout. At 50 times real
    time: the guard's loop is 5 s of the fleet's (the demo's 100 s loops let two
    vehicles converging on one base come within 21 m)."""
    out = tmp_path / "flight"
    code = main(["fly", str(two_bases.dir), "--sim", "2", "--speedup", "50",
                 "--auto-turnaround", "--sim-base-port", str(free_base_port(10, 2)),
                 "-o", str(out)])
    report = json.loads((out / "flight.json").read_text())
    assert report["outcome"]["lost"] == [] and report["outcome"]["coverage_reached"]
    assert report["outcome"]["in_air"] == [] and not report["replans"]
    assert [p for p in problems_beside_guard(report)] == [], report["outcome"]
    assert code == (0 if report["outcome"]["ok"] else 1)
    surface, terrain = two_bases.ctx.surface, two_bases.ctx.terrain
    for v in two_bases.plan.vehicles:
        track = read_track(track_path(out / "tracks", v.id))
        assert takeoffs_on_fresh_batteries(track) == len(v.sorties)
        x, y = terrain.from_lonlat(np.asarray(track.lon), np.asarray(track.lat))
        p = np.stack([x, y, track.alt], axis=1)
        ground = terrain.ground(x, y, upper=True)
        down = np.flatnonzero(np.diff((p[:, 2] - ground < 1.0).astype(int)) == 1) + 1
        stood = [(track.lat[i], track.lon[i]) for i in down]   # each touchdown
        assert len(stood) == len(v.sorties)
        for (lat, lon), f in zip(stood, v.sorties):
            assert _at(f["lands_at"], lat, lon, 3.0), (v.id, f["lands_at"], lat, lon)
        # never higher above a base than its planned takeoff: the takeoff's column
        for f in v.sorties:
            top = max(w.alt_amsl for w in v.waypoints[slice(*f["waypoints"])])
            assert p[:, 2].max() <= max(top, max(w.alt_amsl for w in v.waypoints)) + 2.0
        up = p[:, 2] - ground > 1.0
        assert is_hidden(surface, p[up]).all(), v.id
        columns = np.zeros(len(p), bool)      # climbs and descents: no clearance rule
        for lat, lon in two_bases.bases:
            columns |= np.hypot(*(p[:, :2] - terrain.from_lonlat(lon, lat)).T) < 10.0
        clear = up & ~columns
        assert (p[clear, 2] - ground[clear] >= surface.params.clearance_m - 3.0).all(), v.id
    d = report["separation"]["closest_m"]
    assert d is None or d >= two_bases.scenario.separation_m / 2
