"""Nothing unproven flies, and every report says what was not done: one test per
hole an operator found (issue 32), each asserting the message, the exit status and
that nothing was written or sent. Judged by the simulated vehicles' own state and
tracks, the files on disk and, for the edited missions, a dense sampling of every
leg with the exact point test (`is_hidden`) and the DEM's own surfaces."""

import json
import re
import subprocess
import sys

import numpy as np
import pytest
from flown import problems_beside_guard
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sim_fleet import quick_fleet

from common.errors import InputError
from gcs.cli import main
from gcs.flight import PLAN_FROM_HERE
from gcs.sim import read_track, track_path
from missions import qgc
from missions.build import MissionOptions, vehicle_mission
from missions.check import checked
from missions.export import export_plan_dir
from missions.items import FRAME_GLOBAL, NAV_LAND, NAV_TAKEOFF, NAV_WAYPOINT, MissionItem
from planner.context import load_surface
from planner.exposure import is_hidden
from planner.plan import PLAN_FILE, TERRAIN_FILE, Plan

pytestmark = pytest.mark.timeout(180)


def _fleet(planned, firmware="ardupilot", offset_m=0.0, vehicles=1, **extra):
    lat, lon, alt = planned.launch
    home = (lat + offset_m / 111_320.0, lon, alt)
    return quick_fleet(vehicles, firmware, homes=[home] * vehicles, **extra)


def _standing(planned, at, vehicles, track_dir):
    """Simulated vehicles standing on the plan's terrain at (lat, lon) ``at``."""
    from gcs.sim import terrain_ground

    ground = terrain_ground(planned.terrain)
    return quick_fleet(vehicles, homes=[(*at, ground(*at))] * vehicles, terrain=ground,
                       track_dir=track_dir)


def _stored(fleet, sysid=1) -> int:
    """Items the simulated vehicle holds (ArduPilot: its home item alone when empty)."""
    return len(fleet.vehicle(sysid).mission.items)


def _one_line_error(capsys, command):
    err = capsys.readouterr().err.strip().splitlines()
    assert err and err[-1].startswith(f"gcs {command}: error: "), err
    return err[-1]


# -- the mission gate -------------------------------------------------------------------
def test_a_waypoint_raised_above_the_ceiling_is_refused(plan_copy, capsys):
    """Hidden (the outpost's range shrunk to 1 m: nothing is seen) and clear, but
    200 m higher than planned: over the plan's 150 m ceiling above the ground."""
    doc = json.loads((plan_copy / PLAN_FILE).read_text())
    for post in doc["outposts"]:
        post["range_m"] = 1.0
    (plan_copy / PLAN_FILE).write_text(json.dumps(doc))
    path = plan_copy / "vehicle-1.plan"
    mission = json.loads(path.read_text())
    wp = [it for it in mission["mission"]["items"] if it["command"] == NAV_WAYPOINT][3]
    wp["params"][6] += 200.0
    path.write_text(json.dumps(mission))
    assert main(["upload", str(path), "--connect", "tcp:127.0.0.1:1"]) == 2
    line = _one_line_error(capsys, "upload")
    assert f"{path}: leg" in line and "rises more than 150 m above the terrain" in line


def test_a_mission_file_of_the_other_firmware_is_refused(planned, plan_copy, capsys):
    px4 = plan_copy / "px4"
    export_plan_dir(px4, planned.plan, "px4", formats=("plan",))
    path = px4 / "vehicle-1.plan"
    fleet = _fleet(planned, "ardupilot")
    try:
        before = _stored(fleet)
        assert main(["upload", str(path), "--plan", str(plan_copy),
                     "--connect", fleet.urls()[0]]) == 2
        line = _one_line_error(capsys, "upload")
        assert line == (f"gcs upload: error: {path}: a PX4 mission, and vehicle 1 runs "
                        "ArduPilot: write an ArduPilot one from its plan with `gcs export "
                        "PLAN_DIR --firmware ardupilot`")
        assert _stored(fleet) == before                # nothing sent
        # and an explicit --firmware that is not the file's: refused before connecting
        assert main(["upload", str(path), "--plan", str(plan_copy), "--firmware", "ardupilot",
                     "--connect", fleet.urls()[0]]) == 2
        assert "a PX4 mission, and --firmware is ardupilot" in _one_line_error(capsys, "upload")
        assert _stored(fleet) == before
    finally:
        fleet.stop()


def test_export_in_place_keeps_one_truth(planned, plan_copy):
    assert main(["export", str(plan_copy), "--firmware", "px4", "--no-check"]) == 0
    assert Plan.load(plan_copy).params["firmware"] == "px4"
    assert qgc.load_plan_file(plan_copy / "vehicle-1.plan").declared == "px4"
    other = plan_copy.parent / "elsewhere"
    assert main(["export", str(plan_copy), "-o", str(other), "--firmware", "ardupilot",
                 "--no-check"]) == 0
    assert Plan.load(plan_copy).params["firmware"] == "px4"   # its own files are still PX4


# -- the start: only where planned ---------------------------------------------------------
def test_a_vehicle_away_from_its_launch_point_is_refused_before_arming(planned, tmp_path,
                                                                       capsys):
    fleet = _fleet(planned, "px4", offset_m=300.0, vehicles=3, track_dir=tmp_path / "tracks")
    out = tmp_path / "flight"
    try:
        code = main(["fly", str(planned.dir), "--connect", fleet.urls()[0],
                     "--connect-timeout", "30", "--set-failsafes", "-o", str(out)])
        err = capsys.readouterr().err
    finally:
        fleet.stop()
    assert code == 1
    assert re.search(r"vehicle 1 stands 299\.\d m from the launch point of route 1", err)
    assert "within 5 m of where its route starts" in err
    report = json.loads((out / "flight.json").read_text())
    assert not report["outcome"]["ok"]
    for sysid in (1, 2, 3):                # the vehicles' own record: never armed, no mission
        events = [e["event"] for e in read_track(track_path(tmp_path / "tracks", sysid)).events]
        assert "armed" not in events
        assert _stored(fleet, sysid) == 0



def test_without_launch_points_a_vehicle_away_from_its_first_waypoint_is_refused(
        planned, tmp_path, capsys):
    """A plan made without --launch starts each vehicle's climb under its first
    waypoint: one standing elsewhere was armed where it stood and climbed there."""
    from dataclasses import replace

    from gcs.plan_folder import write_plan_folder
    from planner.pipeline import plan_mission
    from planner.scenario import Scenario

    scenario = replace(Scenario.from_params(planned.plan.params), launch=[],
                       sample=True).validate()
    ctx, outcome = plan_mission(scenario, terrain=planned.terrain,
                                outposts=planned.ctx.outposts)
    folder = tmp_path / "plan"
    write_plan_folder(folder, ctx, outcome)
    first = outcome.plan.vehicles[0].waypoints[0]
    fleet = _standing(planned, (first.lat - 300.0 / 111_320.0, first.lon), 1,
                      tmp_path / "tracks")
    out, empty = tmp_path / "flight", _stored(fleet)
    try:
        code = main(["fly", str(folder), "--connect", fleet.urls()[0], "--assign", "1=1",
                     "--connect-timeout", "30", "--set-failsafes", "-o", str(out)])
        err = capsys.readouterr().err
    finally:
        fleet.stop()
    assert code == 1
    assert re.search(r"vehicle 1 stands 29\d\.\d m from under the first waypoint of route 1",
                     err)
    events = [e["event"] for e in read_track(track_path(tmp_path / "tracks", 1)).events]
    assert "armed" not in events and _stored(fleet) == empty


def test_from_where_they_stand_the_fleet_is_planned_again_there_and_flies_hidden(
        planned, saved_surface, tmp_path, capsys):
    """The same vehicles 300 m from their base, and the operator's
    --from-where-they-stand: the fleet is planned again with its base where they
    stand, written beside the flight report and flown. Judged by the simulator's
    true tracks: each took off and landed where it stood, and every point of every
    track, sampled 1 m apart, is hidden (exact point test) and above the ground."""
    lat, lon = planned.launch[0] - 300.0 / 111_320.0, planned.launch[1]
    fleet = _standing(planned, (lat, lon), 3, tmp_path / "tracks")
    out = tmp_path / "flight"
    try:
        code = main(["fly", str(planned.dir), *[a for u in fleet.urls() for a in ("--connect", u)],
                     "--connect-timeout", "30", "--from-where-they-stand", "--set-failsafes",
                     "-o", str(out)])
        err = capsys.readouterr().err
    finally:
        fleet.stop()
    report = json.loads((out / "flight.json").read_text())
    assert code in (0, 1) and problems_beside_guard(report) == [], err
    assert report["outcome"]["coverage_reached"] and report["outcome"]["in_air"] == []
    here = out / PLAN_FROM_HERE
    assert report["plan"] == str(here)
    said = [e["sysid"] for e in report["events"] if e["event"].startswith(
        "stands 299.") and "planning again from where it stands" in e["event"]]
    assert sorted(said) == [1, 2, 3]
    terrain = saved_surface.terrain
    hx, hy = terrain.from_lonlat(lon, lat)
    for v in Plan.load(here).vehicles:
        assert np.hypot(*np.subtract(terrain.from_lonlat(v.launch.lon, v.launch.lat),
                                     (hx, hy))) < 1.0
    for sysid in (1, 2, 3):
        track = read_track(track_path(tmp_path / "tracks", sysid))
        x, y = terrain.from_lonlat(np.asarray(track.lon), np.asarray(track.lat))
        p = np.stack([x, y, track.alt], axis=1)
        assert np.hypot(*(p[[0, -1], :2] - (hx, hy)).T).max() < 5.0    # off and back here
        assert p[:, 2].max() > p[0, 2] + 20.0                         # and it flew
        up = p[:, 2] > p[0, 2] + 1.0
        a, b = p[:-1][up[:-1] & up[1:]], p[1:][up[:-1] & up[1:]]
        n = np.maximum(2, (np.linalg.norm(b - a, axis=1) / 1.0).astype(int) + 1)
        dense = np.concatenate([a_ + np.linspace(0, 1, k)[:, None] * (b_ - a_)
                                for a_, b_, k in zip(a, b, n)])
        assert is_hidden(saved_surface, dense).all(), sysid
        assert (dense[:, 2] > terrain.ground(dense[:, 0], dense[:, 1], upper=True)).all()


def test_from_where_they_stand_no_hidden_takeoff_is_refused_by_name(planned, tmp_path,
                                                                    capsys):
    """Standing on the outpost's hill, in its view: no plan can start there."""
    post = planned.ctx.outposts[0]
    lon, lat = planned.ctx.terrain.to_lonlat(post.x + 30.0, post.y)   # a cell beside its eye
    fleet = _standing(planned, (float(lat), float(lon)), 1, tmp_path / "tracks")
    out, empty = tmp_path / "flight", _stored(fleet)
    try:
        code = main(["fly", str(planned.dir), "--connect", fleet.urls()[0], "--assign", "1=1",
                     "--connect-timeout", "30", "--from-where-they-stand", "--set-failsafes",
                     "-o", str(out)])
        err = capsys.readouterr().err
    finally:
        fleet.stop()
    assert code == 1
    assert "cannot plan from where the vehicles stand: vehicle 1: launch point" in err
    assert not (out / PLAN_FROM_HERE / PLAN_FILE).exists()
    events = [e["event"] for e in read_track(track_path(tmp_path / "tracks", 1)).events]
    assert "armed" not in events and _stored(fleet) == empty

# -- planning inputs -----------------------------------------------------------------------
def _plan(capsys, tmp_path, *argv):
    out = tmp_path / "out"
    status = main(["plan", *argv, "-o", str(out)])
    return status, capsys.readouterr(), out


def test_outposts_are_an_explicit_choice(tmp_path, capsys, small_dem):
    status, io, out = _plan(capsys, tmp_path, "--dem", str(small_dem), "--uavs", "2")
    assert status == 2 and not out.exists()
    assert io.err.strip().splitlines()[-1] == (
        "gcs plan: error: options: no outposts given: name the observer posts with "
        "--outposts FILE.geojson, or say there are none with --no-outposts")
    status, io, out = _plan(capsys, tmp_path, "--dem", str(small_dem), "--uavs", "2",
                            "--no-outposts", "--viewpoint-spacing", "300")
    assert status == 0, io.err
    assert "no observers: planned with no outposts" in io.out + io.err
    plan = Plan.load(out)
    assert plan.outposts == [] and plan.params["no_outposts"] is True


def test_misspelt_outpost_properties_are_refused(tmp_path, capsys, small_dem):
    posts = tmp_path / "posts.geojson"
    lon, lat = _centre(small_dem)
    posts.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": "Ridge", "height": 8, "range": 5000,
                                           "marker-color": "#f00"},
         "geometry": {"type": "Point", "coordinates": [lon, lat]}}]}))
    status, io, out = _plan(capsys, tmp_path, "--dem", str(small_dem), "--outposts", str(posts))
    assert status == 2 and not out.exists()
    assert io.err.strip().splitlines()[-1] == (
        f"gcs plan: error: {posts}: feature 0 (Ridge): unknown properties 'height', 'range'; "
        "an outpost has height_m, name, range_m (and map styling such as marker-color)")


def test_an_outpost_outside_the_area_still_sees_into_it(tmp_path, capsys):
    """The sample's South summit post (8 km range) stands west of this area: kept,
    the DEM read around it, its sight lines proven against; targets and flight
    stay inside the area."""
    area = (36.49, -84.24, 36.56, -84.18)
    status, io, out = _plan(capsys, tmp_path, "--sample", "--area", ",".join(map(str, area)),
                            "--uavs", "2", "--viewpoint-spacing", "600", "--method", "rt")
    assert status == 0, io.err
    plan = Plan.load(out)
    names = [o["name"] for o in plan.outposts]
    assert "South summit" in names
    south = next(o for o in plan.outposts if o["name"] == "South summit")
    assert south["lon"] < area[1]                                  # outside the area
    assert "Pine Mountain" not in names and "Pine Mountain) left out" in io.err
    for v in plan.vehicles:
        for w in v.waypoints:
            assert area[0] <= w.lat <= area[2] and area[1] <= w.lon <= area[3]
    assert plan.metrics["area"]["area_km2"] == pytest.approx(
        (area[2] - area[0]) * 111.0 * (area[3] - area[1]) * 111.0 * np.cos(np.radians(36.525)),
        rel=0.03)


def test_unseen_ground_is_accounted_for(planned):
    """The plan's numbers add up to the area of operations, and unseen.tif says why."""
    a = planned.plan.metrics["area"]
    parts = a["visible"]["km2"] + sum(p["km2"] for p in a["unseen"].values())
    assert parts == pytest.approx(a["area_km2"], abs=0.01)
    assert 0 < a["planned"]["km2"] <= a["visible"]["km2"] < a["area_km2"]
    unseen = planned.ctx.unseen
    assert (unseen[np.unravel_index(planned.ctx.visibility.target_cells, unseen.shape)]
            == 0).all()


def test_a_filled_void_is_reported_where_and_flown_higher_over(tmp_path, capsys):
    from planner.terrain.dem import VOID_FILL_MARGIN_M

    dem, void_lonlat = _dem_with_void(tmp_path)
    status, io, out = _plan(capsys, tmp_path, "--dem", str(dem), "--no-outposts", "--uavs", "2",
                            "--viewpoint-spacing", "300")
    assert status == 0, io.err
    assert "filled 1 small void(s) (30 source cells) by interpolation at" in io.err
    plan = Plan.load(out)
    at = plan.metrics["filled_voids"]["at"]
    assert len(at) == 1 and at[0]["cells"] == 30
    assert abs(at[0]["lon"] - void_lonlat[0]) < 1e-3 and abs(at[0]["lat"] - void_lonlat[1]) < 1e-3
    import rasterio

    with rasterio.open(out / "voids.tif") as ds:
        voids = ds.read(1)
    with rasterio.open(out / TERRAIN_FILE) as ds:
        lower, upper = ds.read(1), ds.read(2)
    assert (voids == 1).sum() >= 30
    np.testing.assert_allclose((upper - lower)[voids == 1], 2 * VOID_FILL_MARGIN_M, atol=1e-6)
    assert "DEM voids filled by interpolation at" in io.out + io.err


def test_the_base_is_one_ground(planned):
    """Vehicles take off from and land on the same ground: the plan's launch
    altitude is the ground the simulator stands them on (the ground for clearance)."""
    from gcs.sim import terrain_ground

    lat, lon, alt = planned.launch
    assert terrain_ground(planned.terrain)(lat, lon) == pytest.approx(alt, abs=1e-6)
    mission = vehicle_mission(planned.plan.vehicles[0], "ardupilot")
    land = [it for it in mission.items if it.command == NAV_LAND]
    assert land and land[0].z == pytest.approx(alt)


# -- the command line ------------------------------------------------------------------------
def test_a_misspelt_option_gets_its_command_and_a_suggestion(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["plan", "--sample", "--uvas", "4", "-o", "x"])
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert err.strip().splitlines() == [  # one line: no usage block (--help shows it)
        "gcs plan: error: unrecognized arguments: --uvas (did you mean --uavs?)"]
    with pytest.raises(SystemExit):             # no abbreviations: --uav is not --uavs
        main(["plan", "--sample", "--uav", "3", "-o", "x"])
    assert "unrecognized arguments: --uav" in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["--sample", "--k", "3", "--uavs", "3"], "--k: must be a whole number at least 0 and "
                                              "less than --uavs"),
    (["--sample", "--speed", "0"], "--speed: must be a positive number")])
def test_option_errors_come_before_any_heavy_import(tmp_path, argv, message):
    """Judged by what the process had imported when it stopped, not by a timer."""
    code = ("import sys; from gcs.cli import main; status = main(sys.argv[1:]); "
            "heavy = [m for m in ('numba', 'rasterio', 'scipy', 'planner.pipeline', "
            "'matplotlib') if m in sys.modules]; print('HEAVY', heavy); sys.exit(status)")
    run = subprocess.run([sys.executable, "-c", code, "plan", *argv, "-o",
                          str(tmp_path / "o")], capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and message in run.stderr
    assert "HEAVY []" in run.stdout


# -- edited missions: the gate against a dense sampling of every leg ---------------------------
EDITS = ("up", "down", "sideways", "frame", "insert", "firmware")


@pytest.fixture(scope="module")
def saved_surface(planned):
    """The surface a saved plan's missions are proven against (as `gcs upload` loads it)."""
    return load_surface(planned.dir, planned.plan)


@settings(max_examples=300, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(edit=st.sampled_from(EDITS), index=st.integers(0, 10 ** 6),
       amount=st.floats(1.0, 400.0))
def test_the_gate_refuses_every_edit_that_leaves_the_proven_volume(planned, saved_surface, edit,
                                                                   index, amount):
    surface = saved_surface
    clearance = planned.plan.params["clearance_m"]
    route = planned.plan.vehicles[index % len(planned.plan.vehicles)]
    mission = vehicle_mission(route, "ardupilot", MissionOptions(speed_mps=12.0))
    assert _passes_unedited(route.id, mission, surface, clearance)
    items = [MissionItem(**vars(it)) for it in mission.items]
    flown = [n for n, it in enumerate(items) if it.command == NAV_WAYPOINT and n > 0]
    n = flown[index % len(flown)]
    firmware = "ardupilot"
    if edit in ("up", "down"):
        items[n].z += amount if edit == "up" else -amount
    elif edit == "sideways":
        items[n].x += amount / 111_320.0
    elif edit == "frame":
        items[n].frame = 3                             # relative altitude
    elif edit == "insert":
        p = items[n]
        items.insert(n, MissionItem(0, FRAME_GLOBAL, NAV_WAYPOINT, 0, 1, 0, 0, 0, 0,
                                    p.x + amount / 111_320.0, p.y, p.z + amount / 4))
    else:
        firmware = "px4"                               # ArduPilot's items as a PX4 mission
    for k, it in enumerate(items):
        it.seq = k
    edited = type(mission)(mission.vehicle_id, firmware, items, [None] * len(items))
    try:
        checked(edited, surface, clearance)
        accepted = True
    except InputError:
        accepted = False
    if edit == "frame" or edit == "firmware":
        assert not accepted                 # a relative frame; a home item PX4 would fly to
        return
    if not _inside_by_sampling(surface, items, clearance):
        assert not accepted


@pytest.mark.parametrize("command, params, why", [
    (19, {"param3": 800.0}, "loiters on a circle of 800 m"),          # NAV_LOITER_TIME
    (31, {"param2": 800.0}, "loiters on a circle of 800 m"),          # NAV_LOITER_TO_ALT
    (30, {}, "a NAV command whose flight is not a straight leg"),     # CONTINUE_AND_CHANGE_ALT
    (92, {"param1": 1.0}, "a NAV command whose flight is not a straight leg"),
    (179, {}, "DO_SET_HOME"), (186, {"param1": 300.0}, "DO_CHANGE_ALTITUDE"),
    (192, {}, "DO_REPOSITION")])
def test_the_gate_refuses_commands_that_move_the_vehicle_unproven(planned, saved_surface,
                                                                  command, params, why):
    """Found passing the gate as "verified": each inserted after a waypoint of a
    proven mission moves the vehicle (or its home) some way no leg proof covers."""
    route = planned.plan.vehicles[0]
    mission = vehicle_mission(route, "ardupilot", MissionOptions(speed_mps=12.0))
    items = [MissionItem(**vars(it)) for it in mission.items]
    n = [k for k, it in enumerate(items) if it.command == NAV_WAYPOINT and k > 0][2]
    p = items[n]
    extra = MissionItem(0, FRAME_GLOBAL, command, 0, 1, 0, 0, 0, 0, p.x, p.y, p.z)
    for key, value in params.items():
        setattr(extra, key, value)
    items.insert(n + 1, extra)
    for k, it in enumerate(items):
        it.seq = k
    edited = type(mission)(mission.vehicle_id, "ardupilot", items, [None] * len(items))
    with pytest.raises(InputError, match=why):
        checked(edited, saved_surface, planned.plan.params["clearance_m"])


_UNEDITED_PASSED = set()


def _passes_unedited(vehicle_id, mission, surface, clearance) -> bool:
    """Every unedited mission passes the gate (judged once per vehicle, not per example)."""
    if vehicle_id not in _UNEDITED_PASSED and checked(mission, surface, clearance):
        _UNEDITED_PASSED.add(vehicle_id)
    return vehicle_id in _UNEDITED_PASSED


def _inside_by_sampling(surface, items, clearance) -> bool:
    """Every point sampled 2 m apart along every flown leg hidden (exact point test),
    at least ``clearance`` above the ground for clearance and at most the ceiling
    above the terrain: the reference the gate is held to."""
    terrain = surface.terrain
    pos = [it for it in items[1:] if it.is_position]
    xs, ys = terrain.from_lonlat(np.array([it.y for it in pos]), np.array([it.x for it in pos]))
    pts = np.stack([xs, ys, [it.z for it in pos]], axis=1)
    legs = []
    for (a, b), it in zip(zip(pts[:-1], pts[1:]), pos[1:]):
        if it.command == NAV_LAND:
            b = np.array([b[0], b[1], a[2]])
        if it.command == NAV_TAKEOFF:
            continue
        n = max(2, int(np.linalg.norm(b - a) / 2.0) + 1)
        legs.append(a + np.linspace(0, 1, n)[:, None] * (b - a))
    p = np.concatenate(legs)            # every leg's samples at once: one kernel call
    ground = terrain.ground(p[:, 0], p[:, 1], upper=True)
    low = terrain.ground(p[:, 0], p[:, 1])
    return bool(is_hidden(surface, p).all() and (p[:, 2] - ground >= clearance - 1e-6).all()
                and (p[:, 2] - low <= surface.params.ceiling_agl_m + 1e-6).all())


# -- inputs made here ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def small_dem(tmp_path_factory):
    """A hilly 60 x 60 UTM DEM at 30 m (synthetic), as a GeoTIFF."""
    from planner.terrain import synthetic_terrain, write_grid

    terrain = synthetic_terrain(60, 60, cell=30.0, seed=5, family="hills")
    path = tmp_path_factory.mktemp("dem") / "hills.tif"
    write_grid(path, terrain.height.astype(np.float32), terrain)
    return path


def _centre(dem):
    import rasterio
    from pyproj import Transformer

    with rasterio.open(dem) as ds:
        x, y = ds.xy(ds.height // 2, ds.width // 2)
        crs = ds.crs
    return Transformer.from_crs(crs, "EPSG:4326", always_xy=True).transform(x, y)


def _dem_with_void(tmp_path):
    """A hilly DEM with a 6 x 5-cell void; (lon, lat) of the void's centre."""
    import rasterio
    from pyproj import Transformer

    from planner.terrain import synthetic_terrain, write_grid

    terrain = synthetic_terrain(60, 60, cell=30.0, seed=7, family="hills")
    height = terrain.height.astype(np.float32)
    height[30:36, 20:25] = -9999.0
    path = tmp_path / "void.tif"
    write_grid(path, height, terrain, nodata=-9999.0)
    with rasterio.open(path) as ds:
        x, y = ds.xy(32.5, 22)
        crs = ds.crs
    lon, lat = Transformer.from_crs(crs, "EPSG:4326", always_xy=True).transform(x, y)
    return path, (lon, lat)
