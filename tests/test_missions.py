"""Missions and mission files, judged by independent readers: pymavlink's
MAVWPLoader and MAVSDK 4's QGroundControl / Mission Planner importers; our own
readers round-trip random routes; exposed or low legs are refused unwritten."""

import copy
import json
import math
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mavsdk_judge import mission_raw

from common.errors import InputError
from gcs.mavlink import mavutil  # noqa: F401  (MAVLink 2 and the dialect, before mavwp)
from missions import wpl
from missions.build import MissionOptions, plan_missions, vehicle_mission
from missions.check import check_mission, check_structure
from missions.export import export_plan_dir
from missions.items import (
    DO_CHANGE_SPEED,
    DO_DIGICAM_CONTROL,
    IMAGE_START_CAPTURE,
    NAV_LAND,
    NAV_RETURN_TO_LAUNCH,
    NAV_TAKEOFF,
    NAV_WAYPOINT,
    MissionItem,
    first_difference,
    renumber,
)
from missions.qgc import load_plan_file, read_plan_file
from missions.wpl import read_waypoints
from planner.exposure import ExposureParams, Outpost, compute_exposure
from planner.pipeline import plan_mission
from planner.plan import GeoPoint, VehicleRoute, Waypoint
from planner.scenario import Scenario
from planner.terrain import synthetic_terrain

pytestmark = pytest.mark.timeout(60)

N = 64
CLEARANCE = 20.0
PARAMS = ExposureParams(ceiling_agl_m=150.0, clearance_m=CLEARANCE, hide_margin_m=5.0)


# --- a small planned scenario -------------------------------------------------------------

@pytest.fixture(scope="module")
def planned():
    """(context, outcome) of a 2-UAV plan with a launch point on a 64 x 64 synthetic terrain."""
    terrain = synthetic_terrain(N, N, cell=30.0, seed=3, family="hills")
    x, y = terrain.xy(N // 2, N // 2)
    lon, lat = terrain.to_lonlat(x, y)
    outposts = [Outpost(float(x), float(y), 2.0, 1500.0, float(lon), float(lat), "hill")]
    surface = compute_exposure(terrain, outposts, PARAMS)
    rows, cols = np.nonzero(surface.flyable)
    inside = (rows >= 4) & (cols >= 4)
    i = int(np.argmin(rows[inside] + cols[inside]))
    launch = terrain.to_lonlat(*terrain.xy(rows[inside][i], cols[inside][i]))
    scenario = Scenario(sample=True, uavs=2, sensor_range_m=400.0, ceiling_agl_m=150.0,
                        clearance_m=CLEARANCE, hide_margin_m=5.0,
                        launch=[(launch[1], launch[0])]).validate()
    return plan_mission(scenario, terrain=terrain, outposts=outposts)


@pytest.fixture(scope="module")
def plan(planned):
    return planned[1].plan


@pytest.fixture(scope="module")
def surface(planned):
    return planned[0].surface


# --- items per flavour ------------------------------------------------------------------------

def _positions(mission):
    return [(seq, it) for seq, it in enumerate(mission.items) if it.is_position]


@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_item_order_and_commands(plan, firmware):
    speed = plan.params["speed_mps"]
    for route, mission in zip(plan.vehicles, plan_missions(plan, firmware)):
        items = mission.items
        assert [it.seq for it in items] == list(range(len(items)))
        assert items[0].current == 1 and not any(it.current for it in items[1:])
        assert all(it.autocontinue == 1 for it in items)
        assert NAV_RETURN_TO_LAUNCH not in [it.command for it in items]
        launch, first = route.launch, route.waypoints[0]
        if firmware == "ardupilot":
            home, items = items[0], items[1:]
            assert home.command == NAV_WAYPOINT and home.frame == 0
            assert (home.x, home.y, home.z) == pytest.approx((launch.lat, launch.lon,
                                                              launch.alt_amsl), abs=1e-7)
        takeoff, change, land = items[0], items[1], items[-1]
        assert takeoff.command == NAV_TAKEOFF and takeoff.frame == 0
        assert takeoff.z == pytest.approx(first.alt_amsl)
        assert (takeoff.x, takeoff.y) == pytest.approx((launch.lat, launch.lon), abs=1e-7)
        assert change.command == DO_CHANGE_SPEED and change.frame == 2
        assert (change.param1, change.param2) == (1.0, speed)
        assert land.command == NAV_LAND and land.frame == 0
        assert (land.x, land.y, land.z) == pytest.approx((launch.lat, launch.lon,
                                                          launch.alt_amsl), abs=1e-7)
        # one waypoint per route vertex, in order, then a camera item at each snapshot
        body = items[2:-1]
        camera = DO_DIGICAM_CONTROL if firmware == "ardupilot" else IMAGE_START_CAPTURE
        expect = []
        for w in route.waypoints:
            expect.append(NAV_WAYPOINT)
            if w.snapshot:
                expect.append(camera)
        assert [it.command for it in body] == expect
        for it in body:
            assert it.frame == (0 if it.command == NAV_WAYPOINT else 2)
            if it.command == NAV_WAYPOINT:
                assert math.isnan(it.param4) == (firmware == "px4")
        shots = [it for it in body if it.command == camera]
        if firmware == "ardupilot":
            assert all(it.x == 1.0 for it in shots)  # param5: trigger
        else:
            assert [it.param3 for it in shots] == [1.0] * len(shots)  # one image each
            assert [it.param4 for it in shots] == list(range(1, len(shots) + 1))


@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_waypoint_of_item(plan, firmware):
    for route, mission in zip(plan.vehicles, plan_missions(plan, firmware)):
        of = mission.waypoint_of_item
        assert len(of) == len(mission.items)
        assert [i for i in of if i is not None] == list(range(len(route.waypoints)))
        for seq, index in enumerate(of):
            if index is None:
                assert mission.items[seq].command != NAV_WAYPOINT or seq == 0
                continue
            it, w = mission.items[seq], route.waypoints[index]
            assert it.command == NAV_WAYPOINT
            assert (it.x, it.y, it.z) == pytest.approx((w.lat, w.lon, w.alt_amsl), abs=1e-7)


def test_options_hold_speed_camera(plan):
    route = plan.vehicles[0]
    m = vehicle_mission(route, "px4", MissionOptions(hold_s=2.5, speed_mps=None, camera=False))
    assert DO_CHANGE_SPEED not in [it.command for it in m.items]
    assert IMAGE_START_CAPTURE not in [it.command for it in m.items]
    held = [m.items[s].param1 for s, i in enumerate(m.waypoint_of_item) if i is not None
            and route.waypoints[i].snapshot]
    free = [m.items[s].param1 for s, i in enumerate(m.waypoint_of_item) if i is not None
            and not route.waypoints[i].snapshot]
    assert held and set(held) == {2.5} and set(free) <= {0.0}


def test_route_in_the_air_has_no_takeoff_or_land(plan):
    """A re-planned route that starts away from launch gets no takeoff; ArduPilot still
    gets a home item (the autopilot overwrites it)."""
    route = copy.deepcopy(plan.vehicles[0])
    route.waypoints = route.waypoints[3:-3]
    for firmware, first in (("ardupilot", 1), ("px4", 0)):
        m = vehicle_mission(route, firmware, MissionOptions())
        commands = [it.command for it in m.items]
        assert NAV_TAKEOFF not in commands and NAV_LAND not in commands
        assert m.waypoint_of_item[first] == 0


def test_planned_missions_pass_the_check(plan, surface):
    for firmware in ("ardupilot", "px4"):
        for mission in plan_missions(plan, firmware):
            check_mission(mission, surface, CLEARANCE)


# --- independent readers ------------------------------------------------------------------------

@pytest.fixture(scope="module")
def exported(plan, surface, tmp_path_factory):
    out = {}
    for firmware in ("ardupilot", "px4"):
        directory = tmp_path_factory.mktemp(firmware)
        written = export_plan_dir(directory, plan, firmware, surface)
        out[firmware] = (directory, written, plan_missions(plan, firmware))
    return out


def test_export_writes_every_file(exported, plan):
    for firmware, (directory, written, missions) in exported.items():
        names = sorted(Path(p).name for p, _ in written)
        ids = [v.id for v in plan.vehicles]
        assert names == sorted([f"vehicle-{i}.plan" for i in ids]
                               + [f"vehicle-{i}.waypoints" for i in ids]
                               + ["routes.geojson", "routes.kml"])
        assert all(Path(p).parent == directory and Path(p).is_file() for p, _ in written)
        assert not [p for p in directory.iterdir() if p.name.startswith(".")]  # no temp files


def _loader_items(path):
    from pymavlink import mavwp

    loader = mavwp.MAVWPLoader()
    loader.load(str(path))
    return [MissionItem.from_int(loader.wp(i)) for i in range(loader.count())]


def _file_lines(plan, m):
    """What a .waypoints file holds for mission ``m``: line 0 home (the launch point)."""
    launch = next(v.launch for v in plan.vehicles if v.id == m.vehicle_id)
    return wpl.file_items(m.items, m.firmware, (launch.lat, launch.lon, launch.alt_amsl))


def test_waypoints_read_by_pymavlink(exported, plan):
    for firmware, (directory, _, missions) in exported.items():
        for m in missions:
            got = _loader_items(directory / f"vehicle-{m.vehicle_id}.waypoints")
            assert first_difference(_file_lines(plan, m), got) is None, firmware


def test_waypoints_line0_is_home_for_every_firmware(exported, plan):
    """QGroundControl's WPL loader takes line 0 for home: every file starts with the
    launch point at ground altitude, and the PX4 takeoff is line 1, not home."""
    for firmware, (directory, _, missions) in exported.items():
        for m in missions:
            launch = next(v.launch for v in plan.vehicles if v.id == m.vehicle_id)
            lines = read_waypoints(directory / f"vehicle-{m.vehicle_id}.waypoints")
            home = lines[0]
            assert (home.seq, home.command, home.frame) == (0, 16, 0), firmware
            assert (home.x, home.y, home.z) == pytest.approx(
                (launch.lat, launch.lon, launch.alt_amsl), abs=1e-7), firmware
            assert lines[1].command == 22, firmware         # NAV_TAKEOFF: never home
            assert [it.seq for it in lines] == list(range(len(lines)))


def test_waypoints_old_px4_layout_still_read(exported, tmp_path):
    """A PX4 file of the old layout (line 0 the takeoff, no home line) gives the same
    PX4 mission; ArduPilot, whose missions start with home, refuses it by name."""
    directory, _, missions = exported["px4"]
    m = missions[0]
    old = tmp_path / "old.waypoints"
    wpl.write_waypoints(old, m.items)                 # the lines as given: no home line
    assert read_waypoints(old)[0].command == 22
    assert first_difference(m.items, read_waypoints(old, "px4")) is None
    with pytest.raises(InputError, match="old.waypoints: line 2 is not a home position"):
        read_waypoints(old, "ardupilot")
    new = directory / f"vehicle-{m.vehicle_id}.waypoints"
    assert first_difference(m.items, read_waypoints(new, "px4")) is None
    # an ArduPilot file read for PX4 loses its home item, and the reverse gains one
    a = exported["ardupilot"][2][0]
    path = exported["ardupilot"][0] / f"vehicle-{a.vehicle_id}.waypoints"
    px4 = read_waypoints(path, "px4")
    assert first_difference(renumber(copy.deepcopy(a.items[1:])), px4) is None


@pytest.fixture(scope="module")
def mavsdk_importer():
    """MAVSDK's MissionRaw (`mavsdk_judge.mission_raw`): its importers read our files."""
    with mission_raw() as raw:
        yield raw


def _mavsdk_items(items):
    return [MissionItem.from_int(it) for it in items]  # MAVSDK's are MISSION_ITEM_INT


def test_plan_read_by_mavsdk(exported, mavsdk_importer, plan):
    for firmware, (directory, _, missions) in exported.items():
        for m in missions:
            path = directory / f"vehicle-{m.vehicle_id}.plan"
            data = mavsdk_importer.import_qgroundcontrol_mission(str(path))
            got = _mavsdk_items(data.mission_items)
            ours = m.items
            if firmware == "ardupilot":
                # home is plannedHomePosition; MAVSDK re-inserts it only for an ArduPilot
                # system, and ours is not one
                home = json.loads(path.read_text())["mission"]["plannedHomePosition"]
                assert home == pytest.approx([ours[0].x, ours[0].y, ours[0].z], abs=1e-9)
                ours = renumber(copy.deepcopy(ours[1:]))
            assert first_difference(ours, got) is None, firmware
            fence = data.geofence_items
            assert len(fence) == 1 and fence[0].command == 5004  # NAV_FENCE_CIRCLE_EXCLUSION
            o = plan.outposts[0]
            assert fence[0].param1 == pytest.approx(o["range_m"])
            assert (fence[0].x / 1e7, fence[0].y / 1e7) == pytest.approx((o["lat"], o["lon"]),
                                                                         abs=1e-7)


def test_waypoints_read_by_mavsdk(exported, mavsdk_importer, plan):
    for firmware, (directory, _, missions) in exported.items():
        for m in missions:
            path = directory / f"vehicle-{m.vehicle_id}.waypoints"
            data = mavsdk_importer.import_mission_planner_mission(str(path))
            got = _mavsdk_items(data.mission_items)
            assert first_difference(_file_lines(plan, m), got) is None, firmware


def test_our_readers_read_our_files(exported):
    for firmware, (directory, _, missions) in exported.items():
        for m in missions:
            assert first_difference(m.items, read_waypoints(
                directory / f"vehicle-{m.vehicle_id}.waypoints", firmware)) is None
            assert first_difference(m.items, read_plan_file(
                directory / f"vehicle-{m.vehicle_id}.plan")) is None


def test_geojson_and_kml(exported, plan):
    directory = exported["px4"][0]
    doc = json.loads((directory / "routes.geojson").read_text())
    kinds = [f["properties"]["kind"] for f in doc["features"]]
    assert kinds.count("route") == len(plan.vehicles)
    assert kinds.count("snapshot") == sum(len(v.snapshots) for v in plan.vehicles)
    assert kinds.count("outpost") == 1 and kinds.count("outpost range") == 1
    route = next(f for f in doc["features"] if f["properties"]["kind"] == "route")
    v = plan.vehicles[0]
    assert route["geometry"]["coordinates"] == [[w.lon, w.lat, w.alt_amsl] for w in v.waypoints]
    ring = next(f for f in doc["features"] if f["properties"]["kind"] == "outpost range")
    from pyproj import Geod

    lon, lat = np.array(ring["geometry"]["coordinates"]).T
    o = plan.outposts[0]
    _, _, dist = Geod(ellps="WGS84").inv(np.full(lon.size, o["lon"]), np.full(lat.size, o["lat"]),
                                         lon, lat)
    assert dist == pytest.approx(o["range_m"], abs=0.01)
    kml = ET.parse(directory / "routes.kml").getroot()
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    lines = kml.findall(".//k:LineString/k:coordinates", ns)
    assert len(lines) == len(plan.vehicles)
    first = np.array([[float(c) for c in p.split(",")] for p in lines[0].text.split()])
    expect = np.array([[w.lon, w.lat, w.alt_amsl] for w in v.waypoints])
    assert np.abs(first - expect).max() <= 0.005  # 8 decimals of degrees, 2 of metres


# --- QGroundControl's own shape of plan ---------------------------------------------------------

def _qgc_sample(firmware_type=12, **changes):
    """A plan shaped like QGroundControl's samples: takeoff, waypoints, image capture, RTL,
    relative altitudes (frame 3)."""
    def item(jump, command, frame, params, alt=True):
        entry = {"autoContinue": True, "command": command, "doJumpId": jump, "frame": frame,
                 "params": params, "type": "SimpleItem"}
        if alt:
            entry.update({"AMSLAltAboveTerrain": None, "Altitude": params[6],
                          "AltitudeMode": 1})
        return entry

    doc = {
        "fileType": "Plan", "groundStation": "QGroundControl", "version": 1,
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [[47.3985, 8.5455, 30.0]], "version": 2},
        "mission": {
            "cruiseSpeed": 15, "firmwareType": firmware_type, "hoverSpeed": 5,
            "plannedHomePosition": [47.3977419, 8.5455938, 487.989],
            "vehicleType": 2, "version": 2,
            "items": [
                item(1, 22, 3, [0, 0, 0, None, 47.3977419, 8.5455938, 15]),
                item(2, 16, 3, [0, 0, 0, None, 47.3990, 8.5460, 25]),
                item(3, 2000, 2, [0, 0, 1, 0, 0, 0, 0], alt=False),
                item(4, 16, 3, [3, 0, 0, None, 47.3995, 8.5470, 30]),
                item(5, 20, 2, [0, 0, 0, 0, 0, 0, 0], alt=False),
            ],
        },
    }
    doc.update(changes)
    return doc


def _expected_sample():
    nan = math.nan
    rows = [(3, 22, 0, 0, 0, nan, 47.3977419, 8.5455938, 15),
            (3, 16, 0, 0, 0, nan, 47.3990, 8.5460, 25),
            (2, 2000, 0, 0, 1, 0, 0, 0, 0),
            (3, 16, 3, 0, 0, nan, 47.3995, 8.5470, 30),
            (2, 20, 0, 0, 0, 0, 0, 0, 0)]
    return renumber([MissionItem(0, f, c, 0, 1, *rest) for f, c, *rest in rows])


def test_reads_qgroundcontrol_sample(tmp_path, mavsdk_importer):
    path = tmp_path / "sample.plan"
    path.write_text(json.dumps(_qgc_sample()))
    plan = load_plan_file(path)
    assert plan.firmware == "px4" and plan.home == (47.3977419, 8.5455938, 487.989)
    assert plan.rally_points == [(47.3985, 8.5455, 30.0)]
    assert first_difference(_expected_sample(), plan.items) is None
    theirs = _mavsdk_items(mavsdk_importer.import_qgroundcontrol_mission(str(path)).mission_items)
    assert first_difference(plan.items, theirs) is None
    # an ArduPilot plan gets its home back as item 0
    path.write_text(json.dumps(_qgc_sample(firmware_type=3)))
    items = read_plan_file(path)
    assert items[0].command == NAV_WAYPOINT and (items[0].x, items[0].y) == (47.3977419,
                                                                             8.5455938)
    assert first_difference(_expected_sample(), renumber(items[1:])) is None
    # and our check refuses what it cannot prove: relative altitudes, RTL
    with pytest.raises(InputError, match="RETURN_TO_LAUNCH"):
        check_structure(renumber(copy.deepcopy(plan.items[2:])), "sample")
    with pytest.raises(InputError, match="frame 3"):
        check_structure(plan.items[:2], "sample")


@pytest.mark.parametrize("change, message", [
    ({"version": 2}, "plan version 2 not supported"),
    ({"mission": None}, 'no "mission"'),
    ({"fileType": "Survey"}, "not a QGroundControl plan"),
])
def test_refuses_bad_plan_files(tmp_path, change, message):
    doc = _qgc_sample(**change)
    if doc["mission"] is None:
        del doc["mission"]
    path = tmp_path / "bad.plan"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=message) as err:
        read_plan_file(path)
    assert str(path) in str(err.value)


def test_refuses_bad_mission_version_and_files(tmp_path):
    doc = _qgc_sample()
    doc["mission"]["version"] = 1
    path = tmp_path / "old.plan"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match="mission version 1 not supported"):
        read_plan_file(path)
    path.write_text("{not json")
    with pytest.raises(InputError, match="invalid JSON"):
        read_plan_file(path)
    wp = tmp_path / "x.waypoints"
    wp.write_text("QGC WPL 100\n")
    with pytest.raises(InputError, match="not a QGC WPL 110 file"):
        read_waypoints(wp)
    wp.write_text("QGC WPL 110\n0\t1\t0\t16\t0\t0\n")
    with pytest.raises(InputError, match="line 2: 6 values"):
        read_waypoints(wp)


# --- round trips over random routes ------------------------------------------------------------

_lat = st.floats(-60.0, 60.0)
_lon = st.floats(-179.0, 179.0)


@st.composite
def routes(draw):
    lat0, lon0 = draw(_lat), draw(_lon)
    n = draw(st.integers(1, 25))
    offsets = st.floats(-0.05, 0.05)
    alts = st.floats(-400.0, 8000.0)
    waypoints = [Waypoint(lon0 + draw(offsets), lat0 + draw(offsets), draw(alts), float(i),
                          draw(st.booleans())) for i in range(n)]
    launch = None
    if draw(st.booleans()):  # take off from below the first waypoint, land below the last
        waypoints[-1] = Waypoint(waypoints[0].lon, waypoints[0].lat, draw(alts), float(n), False)
        launch = GeoPoint(waypoints[0].lon, waypoints[0].lat, waypoints[0].alt_amsl - 50.0)
    return VehicleRoute(draw(st.integers(1, 99)), launch, waypoints, 0.0, 0.0, 0.0)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(route=routes(), firmware=st.sampled_from(["ardupilot", "px4"]),
       hold=st.sampled_from([0.0, 1.5]), speed=st.sampled_from([None, 7.25]))
def test_round_trip_random_routes(route, firmware, hold, speed):
    from missions import qgc, wpl

    mission = vehicle_mission(route, firmware, MissionOptions(hold_s=hold, speed_mps=speed))
    home = (route.launch.lat, route.launch.lon, route.launch.alt_amsl) if route.launch else None
    with tempfile.TemporaryDirectory() as tmp:
        plan_path, wp_path = Path(tmp) / "v.plan", Path(tmp) / "v.waypoints"
        qgc.write_plan_file(plan_path, mission, speed, home=home)
        wpl.write_waypoints(wp_path, mission.items, firmware, home)
        lines = wpl.file_items(mission.items, firmware, home)
        assert first_difference(lines, _loader_items(wp_path)) is None
        for back in (qgc.read_plan_file(plan_path), wpl.read_waypoints(wp_path, firmware)):
            assert first_difference(mission.items, back) is None
            # lossless against the route itself: 1e-7 degrees, 1 cm
            for seq, index in enumerate(mission.waypoint_of_item):
                if index is None:
                    continue
                w, it = route.waypoints[index], back[seq]
                assert abs(it.x - w.lat) <= 1e-7 and abs(it.y - w.lon) <= 1e-7
                assert abs(it.z - w.alt_amsl) <= 0.01


# --- refusals: nothing is written -------------------------------------------------------------

def _bad_plan(plan, surface, how):
    bad = copy.deepcopy(plan)
    route = bad.vehicles[-1]
    k = len(route.waypoints) // 2
    w = route.waypoints[k]
    if how == "exposed":  # right above the outpost, in its plain view
        o = bad.outposts[0]
        x, y = surface.terrain.from_lonlat(o["lon"], o["lat"])
        ground = float(surface.terrain.ground(x, y)[0])
        route.waypoints[k] = Waypoint(o["lon"], o["lat"], ground + 60.0, w.t_s, w.snapshot)
    else:  # two metres above the ground: hidden, but too low
        x, y = surface.terrain.from_lonlat(w.lon, w.lat)
        route.waypoints[k] = Waypoint(w.lon, w.lat, float(surface.terrain.ground(x, y)[0]) + 2,
                                      w.t_s, w.snapshot)
    return bad, route.id, k


@pytest.mark.parametrize("how, message", [("exposed", "is not hidden from the outposts"),
                                          ("low", "passes closer than 20 m to the terrain")])
def test_bad_leg_is_refused_and_nothing_written(plan, surface, tmp_path, how, message):
    bad, vid, k = _bad_plan(plan, surface, how)
    (tmp_path / "vehicle-1.plan").write_text("old")
    with pytest.raises(InputError, match=message) as err:
        export_plan_dir(tmp_path, bad, "px4", surface)
    assert str(err.value).startswith(f"vehicle {vid}: leg ")
    # the leg named is the one into the bad waypoint
    seq = plan_missions(bad, "px4")[vid - 1].waypoint_of_item.index(k)
    assert f"-> item {seq}, " in str(err.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["vehicle-1.plan"]
    assert (tmp_path / "vehicle-1.plan").read_text() == "old"


def test_check_refuses_broken_sequences(plan, surface):
    mission = plan_missions(plan, "px4")[0]
    broken = copy.deepcopy(mission)
    broken.items[3].seq = 7
    with pytest.raises(InputError, match="item 3 has sequence number 7"):
        check_mission(broken, surface, CLEARANCE)
    broken = copy.deepcopy(mission)
    broken.items[2].x = 95.0
    with pytest.raises(InputError, match="invalid position"):
        check_mission(broken, surface, CLEARANCE)


# --- the command line ------------------------------------------------------------------------

@pytest.fixture(scope="module")
def plan_dir(planned, tmp_path_factory):
    from gcs.plan_folder import write_plan_folder

    directory = tmp_path_factory.mktemp("plan")
    write_plan_folder(directory, *planned)
    return directory


def test_cli_export(plan_dir, tmp_path, capsys):
    from gcs.cli import main

    for p in plan_dir.glob("vehicle-*"):
        p.unlink()
    assert main(["export", str(plan_dir)]) == 0
    assert sorted(p.name for p in plan_dir.glob("vehicle-*.plan")) == ["vehicle-1.plan",
                                                                       "vehicle-2.plan"]
    out = tmp_path / "px4"
    assert main(["export", str(plan_dir), "-o", str(out), "--firmware", "px4",
                 "--format", "plan", "--hold", "2", "--no-check"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["vehicle-1.plan", "vehicle-2.plan"]
    doc = json.loads((out / "vehicle-1.plan").read_text())
    assert doc["mission"]["firmwareType"] == 12
    assert doc["mission"]["items"][0]["command"] == NAV_TAKEOFF


def test_cli_export_errors(plan_dir, tmp_path, capsys):
    from gcs.cli import main

    assert main(["export", str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("gcs export: error:") and "not a plan directory" in err
    assert len(err.splitlines()) == 1
    assert main(["export", str(plan_dir), "-o", str(tmp_path / "x"), "--format", "pdf"]) == 2
    assert "unknown format 'pdf'" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
