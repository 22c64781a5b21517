"""What a firmware's own return reads from the mission files (issue 60): the fleet's
bases as the ``.plan`` rally points, and the mission landing PX4's Return flies to.

Judged by what did not write them: MAVSDK's QGroundControl importer (the rally
items it would upload), brute-force line of sight over the terrain (each rally
point's column hidden from the outpost), PX4's own rule for a mission's landing
(its first NAV_LAND, mavlink_mission.cpp), MAVSDK as a ground station uploading
them to a simulated PX4 and reading them back, pymavlink driving a simulated
ArduPilot whose RTL flies to the closest of them, read from its track file."""

import json
import math
import os
import time
from dataclasses import replace

import numpy as np
import pytest
from hills import central_outpost
from mavsdk_judge import mission_raw
from pymavlink import mavutil
from pyproj import Geod
from sampled_sight import sampled_lowest
from sim_fleet import quick_fleet

from common.errors import InputError
from gcs.cli import main
from gcs.sim import read_track
from missions.build import MissionOptions, plan_missions
from missions.export import export_plan_dir
from missions.items import DO_LAND_START, NAV_LAND, NAV_TAKEOFF
from missions.qgc import load_plan_file
from missions.returns import landing_gaps, rally_points
from missions.segments import RouteMissions
from planner.bases import suggest_bases
from planner.pipeline import plan_mission, prepare
from planner.scenario import Scenario
from planner.terrain import synthetic_terrain

os.environ.setdefault("MAVLINK20", "1")
mavutil.set_dialect("ardupilotmega")
M = mavutil.mavlink
GEOD = Geod(ellps="WGS84")
N = 60
RALLY_POINT = 5100            # MAV_CMD_NAV_RALLY_POINT
RELATIVE = 3                  # MAV_FRAME_GLOBAL_RELATIVE_ALT

pytestmark = pytest.mark.timeout(180)


@pytest.fixture(scope="module")
def mavsdk_importer():
    """MAVSDK's MissionRaw (`mavsdk_judge.mission_raw`): its importers read our files."""
    with mission_raw() as raw:
        yield raw


@pytest.fixture(scope="module")
def two_bases():
    """(context, plan) of 2 UAVs, one from each of two bases 300 m or more apart."""
    terrain = synthetic_terrain(N, N, cell=30.0, seed=3, family="hills")
    outposts = [central_outpost(terrain)]
    scenario = Scenario(sample=True, uavs=2, sensor_range_m=500.0, ceiling_agl_m=150.0,
                        clearance_m=20.0, hide_margin_m=5.0, method="rt").validate()
    ctx = prepare(scenario, terrain=terrain, outposts=outposts)
    bases = suggest_bases(ctx, count=2, separation_m=300.0, spacing_m=90.0)
    assert len(bases) == 2
    scenario = replace(scenario, launch=[(b.lat, b.lon) for b in bases]).validate()
    ctx, outcome = plan_mission(scenario, terrain=terrain, outposts=outposts)
    return ctx, outcome.plan


@pytest.fixture(scope="module")
def exported(two_bases, tmp_path_factory):
    """firmware -> (folder, its missions), each proven by the export."""
    ctx, plan = two_bases
    out = {}
    for firmware in ("ardupilot", "px4"):
        d = tmp_path_factory.mktemp(firmware)
        export_plan_dir(d, plan, firmware, surface=ctx.surface, formats=("plan",))
        out[firmware] = (d, plan_missions(plan, firmware))
    return out


def _bases(plan) -> list:
    return [(b.lat, b.lon, b.alt_amsl) for b in {(v.launch.lat, v.launch.lon): v.launch
                                                  for v in plan.vehicles}.values()]


def test_each_plan_file_carries_the_fleet_bases_as_rally_points(two_bases, exported):
    _, plan = two_bases
    bases = _bases(plan)
    assert len(bases) == 2
    for firmware, (d, missions) in exported.items():
        for m in missions:
            doc = load_plan_file(d / f"vehicle-{m.vehicle_id}.plan")
            home = next(v.launch for v in plan.vehicles if v.id == m.vehicle_id)
            assert doc.home == pytest.approx((home.lat, home.lon, home.alt_amsl), abs=1e-7)
            # relative to plannedHomePosition, as QGroundControl keeps them
            want = sorted((lat, lon, alt - home.alt_amsl) for lat, lon, alt in bases)
            assert len(doc.rally_points) == 2
            assert np.ravel(sorted(doc.rally_points)) == pytest.approx(np.ravel(want), abs=1e-6)


def test_mavsdk_imports_them_as_rally_items(exported, mavsdk_importer):
    for firmware, (d, missions) in exported.items():
        for m in missions:
            path = d / f"vehicle-{m.vehicle_id}.plan"
            data = mavsdk_importer.import_qgroundcontrol_mission(str(path))
            said = json.loads(path.read_text())["rallyPoints"]["points"]
            got = [(it.command, it.frame, it.mission_type, it.x, it.y, it.z)
                   for it in data.rally_items]
            assert got == [(RALLY_POINT, RELATIVE, 2, round(lat * 1e7), round(lon * 1e7),
                            pytest.approx(alt, abs=1e-3)) for lat, lon, alt in said]


def test_every_rally_point_is_a_hidden_base_by_brute_force_line_of_sight(two_bases):
    """The column over each rally point, from a metre above the ground to the top of
    its takeoff, is out of the outpost's sight by dense sampling of the terrain."""
    ctx, plan = two_bases
    missions = plan_missions(plan, "px4")
    terrain, k = ctx.terrain, ctx.scenario.curvature_coeff
    cell = abs(terrain.transform.a)
    tops = {(round(it.x, 6), round(it.y, 6)): it.z for m in missions for it in m.items
            if it.command == NAV_TAKEOFF}
    points = rally_points(plan, missions)
    assert len(points) == 2
    for lat, lon, ground in points:
        x, y = terrain.from_lonlat(lon, lat)
        row, col = terrain.rowcol(float(x), float(y))
        top = tops[(round(lat, 6), round(lon, 6))]
        judged = 0
        for o in ctx.outposts:
            if math.hypot(float(x) - o.x, float(y) - o.y) > o.range_m:
                continue
            row0, col0 = terrain.rowcol(o.x, o.y)
            z0 = float(terrain.ground(o.x, o.y)[0]) + o.height_m
            lowest = sampled_lowest(terrain.height, cell, float(col0), float(row0), z0,
                                    float(col), float(row), k, n=4001)
            assert top < lowest and ground + 1.0 < lowest, (lat, lon)
            judged += 1
        assert judged, f"no outpost in range of the base at {lat}, {lon}: nothing judged"


def test_no_rally_point_without_a_proven_column(two_bases):
    """Missions that neither take off nor land (takeoff items left out) prove no base's
    column: no rally point is written, and PX4's Return along such a mission can only
    reverse, then fly straight home: said (unless its home is known to be under its
    start)."""
    _, plan = two_bases
    bare = plan_missions(plan, "px4", MissionOptions(takeoff=False))
    assert rally_points(plan, bare) == []
    gaps = landing_gaps(bare[0])
    assert len(gaps) == 1 and "has no landing" in gaps[0], gaps
    assert "always reversed, it ends with a straight line home from item 0" in gaps[0]
    launch = plan.vehicles[0].launch
    assert landing_gaps(bare[0], home=(launch.lat, launch.lon)) == []


def test_px4_missions_land_at_their_base_and_start_above_home(two_bases):
    """Every PX4 mission from the ground has its mission landing: its first NAV_LAND
    (what PX4 1.17 takes for the landing when there is no DO_LAND_START) stands at the
    base it lands at, the last position item; and it starts with the takeoff over
    its home. ArduPilot's SmartRTL needs neither."""
    _, plan = two_bases
    for m, route in zip(plan_missions(plan, "px4"), plan.vehicles):
        positions = [it for it in m.items if it.is_position]
        land = next(it for it in positions if it.command == NAV_LAND)
        assert land is positions[-1]
        assert (land.x, land.y, land.z) == pytest.approx(
            (route.landing.lat, route.landing.lon, route.landing.alt_amsl), abs=1e-7)
        assert positions[0].command == NAV_TAKEOFF and landing_gaps(m) == []
    assert all(landing_gaps(m) == [] for m in plan_missions(plan, "ardupilot"))


def test_segments_after_the_first_do_not_start_above_home(two_bases):
    """A route in segments of 12 items (`missions.segments`): the first takes off
    (reversed, its Return comes down over home), the middle ones start in the air
    with no landing (reversed, it ends in a straight line home: said), the last
    lands from the air and is marked (DO_LAND_START first: always forward)."""
    _, plan = two_bases
    route = plan.vehicles[0]
    options = MissionOptions(speed_mps=plan.params["speed_mps"])
    rm = RouteMissions(route, "px4", options, lambda mission: mission)
    segments = [rm.segment(12, rm.fly[0], 0)]
    while not segments[-1].final:
        segments.append(rm.segment(12, segments[-1].last_waypoint, len(segments)))
    assert len(segments) > 2
    assert all(len(s.items) <= 12 for s in segments)
    first, middle, last = (landing_gaps(s) for s in (segments[0], segments[1], segments[-1]))
    assert first == [] and last == []
    assert len(middle) == 1 and "starts in the air and has no landing" in middle[0]
    assert [it.command for it in segments[-1].items[:1]] == [DO_LAND_START]
    assert not any(it.command == DO_LAND_START for s in segments[:-1] for it in s.items)


def test_the_monitor_says_each_new_gap_of_the_return_as_a_known_risk(two_bases):
    """The ground station's monitor, given the missions a PX4 vehicle flies in turn:
    the whole route and the first segment say nothing; the middle segments' gap is
    said once (they repeat it); the last, marked, says nothing."""
    from types import SimpleNamespace

    from gcs.monitor import Monitor

    _, plan = two_bases
    route = plan.vehicles[0]
    rm = RouteMissions(route, "px4", MissionOptions(speed_mps=plan.params["speed_mps"]),
                       lambda mission: mission)
    segments = [rm.segment(12, rm.fly[0], 0)]
    while not segments[-1].final:
        segments.append(rm.segment(12, segments[-1].last_waypoint, len(segments)))
    assert len(segments) > 3
    link = SimpleNamespace(sysid=1, flavour="px4", subscribe=lambda cb: (lambda: None),
                           state=SimpleNamespace(mission_seq=None))
    monitor = Monitor()
    monitor.follow(link, route.id, route, None)
    monitor.set_mission(1, rm.whole)
    assert monitor.events == []
    monitor.set_mission(1, segments[0])
    for segment in segments[1:]:
        monitor.next_segment(1, segment)
    said = [e["return_gaps"] for e in monitor.events]
    assert [e["event"].startswith("known risk: its Return along this mission: ")
            for e in monitor.events] == [True]
    assert said == [landing_gaps(segments[1])] and said[0]


def test_a_malformed_rally_point_is_one_line_naming_the_file(exported, tmp_path, capsys):
    d, missions = exported["px4"]
    doc = json.loads((d / f"vehicle-{missions[0].vehicle_id}.plan").read_text())
    doc["rallyPoints"]["points"] = [[36.6, "west", 300.0]]
    bad = tmp_path / "bad.plan"
    bad.write_text(json.dumps(doc))
    with pytest.raises(InputError, match="bad.plan: rally point 1 is not"):
        load_plan_file(bad)
    assert main(["upload", str(bad), "--unchecked", "--connect", "tcp:127.0.0.1:1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.plan: rally point 1 is not [lat, lon, alt]" in err[0]


# -- the simulator --------------------------------------------------------------------
def test_the_simulator_takes_rally_points_from_mavsdk_and_gives_them_back(exported):
    """MAVSDK as the ground station uploads a .plan's rally items to a simulated PX4
    (as QGroundControl does beside the mission) and downloads them again."""
    from mavsdk import ComponentType, Configuration, Mavsdk
    from mavsdk.plugins.mission_raw import MissionRaw

    d, missions = exported["px4"]
    fleet = quick_fleet(1, "px4")
    ground = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    try:
        url = fleet.urls()[0].replace("udpin:", "udpin://")
        ground.add_any_connection(url)
        system = ground.first_autopilot(10.0)
        assert system is not None, "MAVSDK found no simulated autopilot"
        raw = MissionRaw(system)
        path = d / f"vehicle-{missions[0].vehicle_id}.plan"
        items = raw.import_qgroundcontrol_mission(str(path)).rally_items
        assert len(items) == 2
        raw.upload_rally_points(items)
        back = raw.download_rallypoints()
        key = [(it.x, it.y, round(it.z, 3), it.frame) for it in items]
        assert [(it.x, it.y, round(it.z, 3), it.frame) for it in back] == key
        held = fleet.vehicle(1).mission.rally()
        assert [(round(a * 1e7), round(b * 1e7), round(z, 3), f) for a, b, z, f in held] == key
    finally:
        ground.destroy()
        fleet.stop()


def _upload_rally(m, points, command=RALLY_POINT) -> int:
    """Rally points [(lat, lon, alt above home)] by the mission protocol, by hand
    (MAV_MISSION_TYPE_RALLY), as ``command`` items; the MISSION_ACK's result."""
    return _upload(m, [dict(frame=RELATIVE, command=command, current=0, autocontinue=1,
                            param1=0, param2=0, param3=0, param4=0, x=round(lat * 1e7),
                            y=round(lon * 1e7), z=alt) for lat, lon, alt in points],
                   M.MAV_MISSION_TYPE_RALLY)


def _upload(m, items, kind=0) -> int:
    """``items`` (MISSION_ITEM_INT's fields) by the mission protocol, by hand, as
    mission type ``kind``; the MISSION_ACK's result."""
    m.mav.mission_count_send(1, 1, len(items), kind)
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        msg = m.recv_match(type=["MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"],
                           blocking=True, timeout=1)
        if msg is None or msg.mission_type != kind:
            continue
        if msg.get_type() == "MISSION_ACK":
            return msg.type
        f = items[msg.seq]
        m.mav.mission_item_int_send(1, 1, msg.seq, f["frame"], f["command"], f["current"],
                                    f["autocontinue"], f["param1"], f["param2"], f["param3"],
                                    f["param4"], f["x"], f["y"], f["z"], kind)
    raise AssertionError("no MISSION_ACK to the upload")


def _command(m, cmd, *params) -> int:
    p = list(params) + [0.0] * (7 - len(params))
    m.mav.command_long_send(1, 1, cmd, 0, *p)
    ack = m.recv_match(type="COMMAND_ACK", condition=f"COMMAND_ACK.command=={cmd}",
                       blocking=True, timeout=5)
    return ack.result


def test_a_plain_rtl_flies_straight_to_the_closest_rally_point(tmp_path):
    """ArduPilot's RTL goes to the closest rally point when it is closer than home
    (RALLY_INCL_HOME 1): the simulator's vehicle, sent 150 m north, RTLs to the
    rally point 200 m north, not home, and lands there. A straight line, proven
    nothing: the reason no failsafe the profile keeps is an RTL."""
    home = (36.6, -84.25, 300.0)
    north, far = (GEOD.fwd(home[1], home[0], 0.0, d)[:2] for d in (150.0, 200.0))
    fleet = quick_fleet(1, "ardupilot", homes=[home], track_dir=tmp_path, speedup=20.0)
    m = mavutil.mavlink_connection(fleet.urls()[0], source_system=250, source_component=190)
    try:
        m.mav.request_data_stream_send(0, 0, M.MAV_DATA_STREAM_ALL, 4, 1)
        m.recv_match(type="SYS_STATUS", blocking=True, timeout=10,
                     condition="SYS_STATUS.onboard_control_sensors_health & 268435456")
        # a rally list of anything but rally points is refused, as both firmwares do
        assert _upload_rally(m, [(far[1], far[0], 0.0)], command=M.MAV_CMD_NAV_WAYPOINT) \
            == M.MAV_MISSION_UNSUPPORTED
        assert _upload_rally(m, [(far[1], far[0], 0.0)]) == M.MAV_MISSION_ACCEPTED
        assert _command(m, M.MAV_CMD_DO_SET_MODE, 1, 4) == M.MAV_RESULT_ACCEPTED  # GUIDED
        assert _command(m, M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
        assert _command(m, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 20) == M.MAV_RESULT_ACCEPTED
        m.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=20,
                     condition="GLOBAL_POSITION_INT.relative_alt > 19000")
        m.mav.set_position_target_global_int_send(
            0, 1, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0b110111111000,
            round(north[1] * 1e7), round(north[0] * 1e7), 20.0, 0, 0, 0, 0, 0, 0, 0, 0)
        reached = f"abs(GLOBAL_POSITION_INT.lat - {round(north[1] * 1e7)}) < 50"
        assert m.recv_match(type="GLOBAL_POSITION_INT", condition=reached, blocking=True,
                            timeout=30) is not None
        assert _command(m, M.MAV_CMD_NAV_RETURN_TO_LAUNCH) == M.MAV_RESULT_ACCEPTED
        m.recv_match(type="EXTENDED_SYS_STATE", blocking=True, timeout=60,
                     condition="EXTENDED_SYS_STATE.landed_state == 1")
    finally:
        m.close()
        fleet.stop()
    track = read_track(tmp_path / "vehicle_1.json")
    last = (float(track.lat[-1]), float(track.lon[-1]))
    assert GEOD.inv(last[1], last[0], far[0], far[1])[2] < 3.0
    assert abs(float(track.alt[-1]) - home[2]) < 0.5
    assert "landed" in [e["event"] for e in track.events]


def test_px4_s_return_along_a_mission_flown_from_the_air_flies_on_to_its_landing(tmp_path):
    """A simulated PX4 (RTL_TYPE 4) in the air flies a mission that starts there (as
    a re-task or a later segment does): its Return, asked 3 items into 7, flies on
    to the landing at its base (the mission's DO_LAND_START, first, makes the rest
    of the mission the shorter way), never back to the mission's start and straight
    home. Without the mark it turned back (rtl.cpp reverseIsFurther: 6 - 3 < 3 is
    false). Judged on the simulator's track: after the Return it passes over the
    mission's next two waypoints and lands at home."""
    from missions.build import route_items
    from planner.plan import GeoPoint, VehicleRoute, Waypoint

    home = (36.6, -84.25, 300.0)
    def at(north, east):
        lon, lat, _ = GEOD.fwd(home[1], home[0], 0.0, north)
        lon, lat, _ = GEOD.fwd(lon, lat, 90.0, east)
        return lat, lon
    corners = [(0, 0), (150, 0), (250, 0), (250, 150), (100, 150), (0, 0)]
    waypoints = [Waypoint(lon, lat, home[2] + 30.0, 10.0 * i)
                 for i, (lat, lon) in enumerate(at(n, e) for n, e in corners)]
    route = VehicleRoute(1, GeoPoint(home[1], home[0], home[2]), waypoints, 60.0, 80.0, 900.0)
    mission = route_items(route, "px4", MissionOptions(speed_mps=8.0), [2, 3, 4, 5],
                          takeoff=False, land=True, segment=1)
    commands = [it.command for it in mission.items]
    assert commands == [DO_LAND_START, 178, 16, 16, 16, 16, NAV_LAND]
    assert landing_gaps(mission) == []
    fleet = quick_fleet(1, "px4", homes=[home], track_dir=tmp_path, speedup=20.0)
    fleet.vehicle(1).params["RTL_TYPE"] = 4
    m = mavutil.mavlink_connection(fleet.urls()[0], source_system=250, source_component=190)
    try:
        m.recv_match(type="SYS_STATUS", blocking=True, timeout=10,
                     condition="SYS_STATUS.onboard_control_sensors_health & 268435456")
        assert _upload(m, [it.to_int() for it in mission.items]) == M.MAV_MISSION_ACCEPTED
        assert _command(m, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, home[2] + 30.0) == \
            M.MAV_RESULT_ACCEPTED
        assert _command(m, M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
        m.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=20,
                     condition="GLOBAL_POSITION_INT.relative_alt > 29000")
        assert _command(m, M.MAV_CMD_DO_SET_MODE, 1, 4, 4) == M.MAV_RESULT_ACCEPTED
        m.recv_match(type="MISSION_CURRENT", blocking=True, timeout=30,
                     condition="MISSION_CURRENT.seq == 3")
        assert _command(m, M.MAV_CMD_NAV_RETURN_TO_LAUNCH) == M.MAV_RESULT_ACCEPTED
        asked = time.time()
        m.recv_match(type="EXTENDED_SYS_STATE", blocking=True, timeout=60,
                     condition="EXTENDED_SYS_STATE.landed_state == 1")
    finally:
        m.close()
        fleet.stop()
    track = read_track(tmp_path / "vehicle_1.json")
    assert any(e["event"].startswith("return along the mission") for e in track.events)
    after = track.wall >= asked
    for lat, lon in (at(250, 150), at(100, 150)):
        closest = min(GEOD.inv(lon, lat, b, a)[2]
                      for a, b in zip(track.lat[after], track.lon[after]))
        assert closest < 5.0, (lat, lon, closest)
    assert GEOD.inv(home[1], home[0], float(track.lon[-1]), float(track.lat[-1]))[2] < 3.0
