"""Every failsafe keeps the vehicle hidden (issue 60).

The profiles' failsafe parameters are judged against the firmwares' own sources
(ArduPilot 4.7 at /opt/ardupilot, PX4 1.17 at /opt/px4: each value's meaning as
the parameter's documentation there says it; skipped where absent); the
preflight against the simulated vehicles, by what they hold afterwards and by
their own tracks (nothing armed when refused)."""

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from sampled_sight import sampled_lowest
from sim_fleet import quick_fleet

from autopilots import ACCEPT_RADIUS_M, profile
from gcs.cli import main
from gcs.sim import read_track, track_path
from gcs.sim.battery import CAPACITY_MAH
from gcs.sim.flavours import flavour

pytestmark = pytest.mark.timeout(180)

ARDUPILOT_SRC = Path("/opt/ardupilot")
PX4_SRC = Path("/opt/px4")


# -- the profiles, against the firmwares' sources -----------------------------------------
def _ardupilot_doc(file: str, param: str) -> str:
    """The documentation block of ArduPilot parameter ``param`` (its @Param: name
    inside the group) in ``file``."""
    text = (ARDUPILOT_SRC / file).read_text()
    found = re.search(rf"// @Param: {param}\n(.*?)AP_GROUPINFO|// @Param: {param}\n(.*?)"
                      r"GSCALAR", text, re.S)
    assert found, f"{param} not documented in {file}"
    return found.group(1) or found.group(2)


def _ardupilot_values(doc: str, tag: str = "Values") -> dict:
    line = re.search(rf"// @{tag}(?:{{Copter[^}}]*}})?: (.*)", doc).group(1)
    return {int(k): v.strip() for k, v in (item.split(":", 1) for item in line.split(","))}


ARDUPILOT_PARAMS = {      # profile name -> (file, name in its group)
    "BATT_FS_LOW_ACT": ("libraries/AP_BattMonitor/AP_BattMonitor_Params.cpp", "FS_LOW_ACT"),
    "BATT_FS_CRT_ACT": ("libraries/AP_BattMonitor/AP_BattMonitor_Params.cpp", "FS_CRT_ACT"),
    "FS_GCS_ENABLE": ("ArduCopter/Parameters.cpp", "FS_GCS_ENABLE"),
    "FS_THR_ENABLE": ("ArduCopter/Parameters.cpp", "FS_THR_ENABLE"),
    "FS_EKF_ACTION": ("ArduCopter/Parameters.cpp", "FS_EKF_ACTION"),
    "FENCE_ACTION": ("libraries/AC_Fence/AC_Fence.cpp", "ACTION"),
}
#: the hidden-safe value's meaning, as the firmware's documentation names it
ARDUPILOT_SAFE = {"BATT_FS_LOW_ACT": "SmartRTL or Land", "BATT_FS_CRT_ACT": "Land",
                  "FS_GCS_ENABLE": "SmartRTL or Land", "FS_THR_ENABLE": "SmartRTL or Land",
                  "FS_EKF_ACTION": "Land", "FENCE_ACTION": "SmartRTL or Land"}


def _parameters(firmware):
    return {p.name: p for f in profile(firmware).failsafes for p in f.parameters}


@pytest.mark.skipif(not ARDUPILOT_SRC.is_dir(), reason="no ArduPilot sources at /opt/ardupilot")
def test_ardupilot_failsafes_are_the_firmware_s_own():
    params = _parameters("ardupilot")
    assert set(ARDUPILOT_PARAMS) | {"FS_OPTIONS"} == set(params)
    for name, (file, local) in ARDUPILOT_PARAMS.items():
        values = _ardupilot_values(_ardupilot_doc(file, local))
        assert set(params[name].actions) == set(values), name
        safe = int(params[name].safe)
        assert re.fullmatch(rf"(Enabled always )?{ARDUPILOT_SAFE[name]}", values[safe],
                            re.I), (name, values[safe])
        assert params[name].is_hidden(safe)
    # FS_OPTIONS: bit 0 continues the mission on an RC loss, bit 1 on a link loss
    bits = _ardupilot_values(_ardupilot_doc("ArduCopter/Parameters.cpp", "FS_OPTIONS"),
                             "Bitmask")
    assert bits[0] == "Continue if in Auto on RC failsafe"
    assert bits[1] == "Continue if in Auto on GCS failsafe"
    copter = (ARDUPILOT_SRC / "ArduCopter/Copter.h").read_text()
    assert re.search(r"RC_CONTINUE_IF_AUTO\s*= \(1<<0\)", copter)
    assert re.search(r"GCS_CONTINUE_IF_AUTO\s*= \(1<<1\)", copter)
    assert params["FS_OPTIONS"].bits == 0b11
    # SmartRTL's buffer, as AP_SmartRTL.h defines it
    smart = (ARDUPILOT_SRC / "libraries/AP_SmartRTL/AP_SmartRTL.h").read_text()
    srtl = profile("ardupilot").smartrtl
    assert re.search(rf"SMARTRTL_POINTS_DEFAULT\s+{srtl.points}\b", smart)
    assert re.search(rf"SMARTRTL_POINTS_MAX\s+{srtl.points_max}\b", smart)
    assert re.search(rf"SMARTRTL_ACCURACY_DEFAULT\s+{srtl.accuracy_m:g}\.0f", smart)


def _px4_values(name: str) -> dict:
    """{value: meaning} (or {bit: meaning}) of PX4 parameter ``name``, from its
    definition's comment block."""
    for path in (PX4_SRC / "src/modules").rglob("*_params.c"):
        text = path.read_text(errors="replace")
        found = re.search(rf"/\*\*((?:(?!\*/).)*)\*/\s*PARAM_DEFINE_INT32\({name},", text, re.S)
        if found:
            return {int(k): v.strip() for k, v in
                    re.findall(r"@(?:value|bit) (\d+) ([^\n]*)", found.group(1))}
    raise AssertionError(f"{name} not defined in {PX4_SRC}")


#: the hidden-safe value's meaning, as PX4's documentation says it
PX4_SAFE = {"COM_LOW_BAT_ACT": "Return at critical level, land at emergency level",
            "RTL_TYPE": "reverse mission path, whichever is closer",
            "NAV_DLL_ACT": "Return mode", "NAV_RCL_ACT": "Return mode",
            "GF_ACTION": "Return mode", "COM_POS_LOW_ACT": "Land"}


@pytest.mark.skipif(not PX4_SRC.is_dir(), reason="no PX4 sources at /opt/px4")
def test_px4_failsafes_are_the_firmware_s_own():
    params = _parameters("px4")
    assert set(PX4_SAFE) | {"COM_DLL_EXCEPT", "COM_RCL_EXCEPT"} == set(params)
    for name, meaning in PX4_SAFE.items():
        values = _px4_values(name)
        # every documented value is worded (1, COM_LOW_BAT_ACT's deprecated Return, is
        # an enum value of failsafe.h no longer documented)
        assert set(values) <= set(params[name].actions), name
        assert meaning in values[int(params[name].safe)], (name, values)
        assert params[name].is_hidden(params[name].safe)
    for name in ("COM_DLL_EXCEPT", "COM_RCL_EXCEPT"):
        assert _px4_values(name)[0] == "Mission"
        assert params[name].bits == 0b1
    # the mission-path returns: RTL_TYPE 2 and 4, and nothing else, are hidden
    assert {v for v in params["RTL_TYPE"].actions if params["RTL_TYPE"].is_hidden(v)} == {2, 4}


# -- the preflight, on the simulator ------------------------------------------------------
def _fleet(planned, firmware, tmp_path):
    lat, lon, alt = planned.launch
    return quick_fleet(3, firmware, homes=[(lat, lon, alt)] * 3, track_dir=tmp_path / "tracks")


def _urls(fleet, firmware):
    urls = fleet.urls()
    return [a for u in (urls[:1] if firmware == "px4" else urls) for a in ("--connect", u)]


@pytest.mark.parametrize("firmware, named", [
    ("ardupilot", ["BATT_FS_LOW_ACT = 2, RTL: a climb to RTL_ALT and a straight line home",
                   "FS_THR_ENABLE = 1, RTL", "FS_OPTIONS = 16"]),
    ("px4", ["RTL_TYPE = 0, a climb to RTL_RETURN_ALT and a straight line",
             "COM_DLL_EXCEPT = 0", "COM_RCL_EXCEPT = 0"])])
def test_a_vehicle_whose_failsafe_leaves_the_proof_is_refused_before_arming(
        planned, tmp_path, capsys, firmware, named):
    fleet = _fleet(planned, firmware, tmp_path)
    out = tmp_path / "flight"
    try:
        code = main(["fly", str(planned.dir), *_urls(fleet, firmware), "--connect-timeout", "30",
                     "-o", str(out)])
        held = {s: dict(fleet.vehicle(s).params) for s in (1, 2, 3)}
    finally:
        fleet.stop()
    err = capsys.readouterr().err.strip().splitlines()   # the events, then the error
    print(err[-1])
    assert code == 2
    assert err[-1].startswith("gcs fly: error: vehicles 1, 2, 3: ")   # the same, said once
    for text in named:
        assert text in err[-1]
    assert "add --set-failsafes" in err[-1]
    for sysid in (1, 2, 3):
        events = [e["event"] for e in read_track(track_path(tmp_path / "tracks", sysid)).events]
        assert "armed" not in events                    # nothing armed
        booted = flavour(firmware).params                 # nothing written
        assert {k: held[sysid][k] for k in booted} == booted
    report = json.loads((out / "flight.json").read_text())
    assert not report["failsafes"]["1"].get("set")


#: what --set-failsafes leaves the simulated vehicles holding, and what they held
# a link loss that does nothing (FS_GCS_ENABLE 0, NAV_DLL_ACT 0) is hidden but leaves
# a held vehicle hovering: replaced by the return
SET = {"ardupilot": {"BATT_FS_LOW_ACT": (2, 4), "FS_GCS_ENABLE": (0, 4), "FS_THR_ENABLE": (1, 5),
                     "FS_OPTIONS": (16, 19)},
       "px4": {"RTL_TYPE": (0, 4), "NAV_DLL_ACT": (0, 2), "COM_DLL_EXCEPT": (0, 1),
               "COM_RCL_EXCEPT": (0, 1)}}


@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_set_failsafes_writes_reads_back_records_and_restores(planned, tmp_path, firmware):
    from gcs.flight import Flight, FlyOptions

    fleet = _fleet(planned, firmware, tmp_path)
    out = tmp_path / "flight"
    out.mkdir()
    try:
        flight = Flight(planned.dir, fleet.urls()[:1] if firmware == "px4" else fleet.urls(),
                        FlyOptions(output=out, plot=False, set_failsafes=True, live=False,
                                   tlog=False))
        flight.prepare()
        flight.connect()
        flight.preflight.locate()
        flight.preflight.check_failsafes()
        flight.link.close()
        for sysid in (1, 2, 3):
            held = fleet.vehicle(sysid).params
            for name, (before, after) in SET[firmware].items():
                assert held[name] == after, (sysid, name)
            changes = flight.preflight.failsafes[sysid]["set"]
            assert {c["parameter"]: (c["previous"], c["value"]) for c in changes} == \
                SET[firmware]
        events = [e["event"] for e in flight.monitor.events]
        assert any(e.startswith("failsafes set: ") for e in events)
        assert any(e.startswith("known risk: ") and "lands where it is" in e for e in events)
        # what gcs fly writes into flight.json, restored by `gcs failsafes --restore`
        (out / "flight.json").write_text(json.dumps({"failsafes": {
            str(s): f for s, f in flight.preflight.failsafes.items()}}))
        assert main(["failsafes", "--restore", str(out), *_urls(fleet, firmware)]) == 0
        for sysid in (1, 2, 3):
            held = fleet.vehicle(sysid).params
            for name, (before, after) in SET[firmware].items():
                assert held[name] == before, (sysid, name)
    finally:
        fleet.stop()


def test_restore_without_a_flight_report_is_one_line(tmp_path, capsys):
    assert main(["failsafes", "--restore", str(tmp_path), "--connect", "tcp:127.0.0.1:1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "flight.json: no such file" in err[0]


# -- a failsafe in flight, on the simulator -----------------------------------------------
def _seen(planned, xyz) -> np.ndarray:
    """bool per point: some outpost sees it, by dense sampling of the terrain along
    each sight line (`sampled_sight`), not by the planner's kernels."""
    terrain, k = planned.terrain, float(planned.plan.params.get("curvature_coeff", 0.85714))
    cell = abs(terrain.transform.a)
    seen = np.zeros(len(xyz), bool)
    for o in planned.ctx.outposts:
        row0, col0 = terrain.rowcol(o.x, o.y)
        z0 = float(terrain.ground(o.x, o.y)[0]) + o.height_m
        for i, (x, y, z) in enumerate(xyz):
            if math.hypot(x - o.x, y - o.y) > o.range_m:
                continue
            row, col = terrain.rowcol(x, y)
            lowest = sampled_lowest(terrain.height, cell, float(col0), float(row0), z0,
                                    float(col), float(row), k, n=2001)
            seen[i] |= z >= lowest
    return seen


def _to_polyline(points, line) -> np.ndarray:
    """Each point's distance (m) to the polyline ``line`` (3-D)."""
    a, b = line[:-1], line[1:]
    ab = b - a
    out = []
    for p in points:
        t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(
            np.einsum("ij,ij->i", ab, ab), 1e-9), 0.0, 1.0)
        out.append(np.linalg.norm(a + t[:, None] * ab - p, axis=1).min())
    return np.array(out)


def _ardupilot_at_base(planned, tmp_path):
    """Three simulated ArduPilot copters at the plan's base, on its terrain."""
    from gcs.sim import terrain_ground

    lat, lon, alt = planned.launch
    return quick_fleet(3, "ardupilot", homes=[(lat, lon, alt)] * 3,
                       terrain=terrain_ground(planned.terrain), track_dir=tmp_path / "tracks")


def _fly_setting_failsafes(planned, fleet, tmp_path, lost_after, timeout) -> Path:
    """`gcs fly --set-failsafes` of the plan on ``fleet`` (stopped after); its folder."""
    out = tmp_path / "flight"
    try:
        main(["fly", str(planned.dir), *_urls(fleet, "ardupilot"), "--set-failsafes",
              "--lost-after", str(lost_after), "--timeout", str(timeout), "-o", str(out)])
    finally:
        fleet.stop()
    return out


def test_a_low_battery_mid_sortie_flies_smartrtl_the_proven_way_home(planned, tmp_path):
    """ArduPilot with --set-failsafes (BATT_FS_LOW_ACT 4, SmartRTL or Land): its
    battery crosses the low level halfway through its route; it retraces its own
    flown path to its base and lands there. Judged on the simulator's true track:
    every point after the failsafe within SRTL_ACCURACY of the path flown before it,
    hidden from the outpost by dense sampling of each sight line, down at home."""
    fleet = _ardupilot_at_base(planned, tmp_path)
    route = planned.plan.vehicles[0]
    hover_s = fleet.config.battery_min * 60.0
    # the low level, in mAh left, crossed about halfway through route 1
    fleet.vehicle(1).params["BATT_LOW_MAH"] = CAPACITY_MAH * (1.0 - 0.5 * route.mission_time_s
                                                              / hover_s)
    out = _fly_setting_failsafes(planned, fleet, tmp_path, lost_after=3, timeout=120)
    track = read_track(track_path(tmp_path / "tracks", 1))
    fired = next(e["t"] for e in track.events
                 if e["event"] == "battery failsafe: low, SMART_RTL or LAND")
    x, y = planned.terrain.from_lonlat(track.lon, track.lat)
    xyz = np.stack([x, y, track.alt], axis=1)
    before, after = xyz[track.t <= fired], xyz[track.t > fired]
    assert len(after) > 10
    # on the path it flew: its points SRTL_ACCURACY apart, each turned at within the
    # acceptance radius; or braking on the leg it flew when the failsafe fired
    # (within the plan's track tolerance of its route)
    near = 2.0 + ACCEPT_RADIUS_M
    planned_xyz = np.array([(*planned.terrain.from_lonlat(w.lon, w.lat), w.alt_amsl)
                            for w in route.waypoints])
    off = np.minimum(_to_polyline(after, before), _to_polyline(after, planned_xyz))
    assert off.max() <= max(near, float(planned.plan.params["track_tolerance_m"]))
    assert _to_polyline(after[len(after) // 4:], before).max() <= near
    assert not _seen(planned, after[::max(1, len(after) // 150)]).any()
    o = planned.ctx.outposts[0]           # the judge sees: 400 m up beside the post
    assert _seen(planned, [(o.x + 60.0, o.y, float(planned.terrain.ground(o.x, o.y)[0]) + 400)])
    home = np.array(planned.terrain.from_lonlat(track.home[1], track.home[0]))
    assert np.hypot(*(xyz[-1, :2] - home)) < 2.0 and abs(track.alt[-1] - track.home[2]) < 1.0
    assert "landed" in [e["event"] for e in track.events if e["t"] > fired]
    report = json.loads((out / "flight.json").read_text())
    v1 = next(v for v in report["vehicles"] if v["sysid"] == 1)
    assert v1["state"] == "landed"                        # home on its own, not lost
    assert [m["mode"] for m in v1["failsafe_modes"]] == ["SMART_RTL"]
    assert any(e["sysid"] == 1 and e["event"].startswith("failsafe: flying in SMART_RTL")
               for e in report["events"])


def test_the_smartrtl_buffer_simplifies_straight_legs_and_overflows_on_corners():
    """AP_SmartRTL's rules: points SRTL_ACCURACY apart, simplified within half of it
    when the buffer nears full; a path with more corners than room deactivates it."""
    from gcs.sim.smartrtl import SmartPath

    straight = SmartPath(30, 2.0, (0.0, 0.0, 0.0))
    for i in range(1, 1000):                     # 2 km in a line, in 2 m steps
        assert not straight.add((2.0 * i, 0.0, 50.0))
    assert straight.active and len(straight.points) < 30
    assert straight.way_back()[-1] == (0.0, 0.0, 2.0)       # home, 2 m above
    zigzag = SmartPath(30, 2.0, (0.0, 0.0, 0.0))
    full = [zigzag.add((10.0 * i, 40.0 * (i % 2), 50.0)) for i in range(1, 40)]
    assert full.count(True) == 1 and not zigzag.active      # 31 corners: no room


def test_a_smartrtl_buffer_too_small_is_predicted_and_its_fallback_reported(planned, tmp_path):
    """SRTL_POINTS 30 on vehicle 1 (the plan counts its route at about 80): the
    preflight says where the buffer fills, the simulated autopilot fills it no
    sooner ("SmartRTL deactivated: buffer full"), and a low battery after that
    takes BATT_FS_LOW_ACT 4's fallback, LAND where it is: said, and in the report."""
    fleet = _ardupilot_at_base(planned, tmp_path)
    route = planned.plan.vehicles[0]
    fleet.vehicle(1).params["SRTL_POINTS"] = 30.0
    # low after 60 % of its planned flight: its buffer fills at about 43 %, and at 80 %
    # the vehicle, slower than planned, was back over its base when it fired (LAND there
    # was a landing, in 2 of 3 runs)
    fleet.vehicle(1).params["BATT_LOW_MAH"] = CAPACITY_MAH * (
        1.0 - 0.6 * route.mission_time_s / (fleet.config.battery_min * 60.0))
    out = tmp_path / "flight"
    try:
        main(["fly", str(planned.dir), *_urls(fleet, "ardupilot"), "--set-failsafes",
              "--lost-after", "3", "--timeout", "120", "-o", str(out)])
    finally:
        fleet.stop()
    report = json.loads((out / "flight.json").read_text())
    risk = next(r for r in report["failsafes"]["1"]["risks"] if r.startswith("SmartRTL buffer"))
    full_at = int(re.search(r"full at its waypoint (\d+)", risk).group(1))
    assert "SRTL_POINTS = 30" in risk and not any(
        r.startswith("SmartRTL buffer") for r in report["failsafes"]["2"]["risks"])
    track = read_track(track_path(tmp_path / "tracks", 1))
    at = {e["event"]: e["t"] for e in track.events}
    takeoff = at["takeoff"]
    full = at["SmartRTL deactivated: buffer full"]
    # the prediction is conservative: the buffer had room past the waypoint before
    # the one named (the simulator flies the plan's pace within 10 %)
    before = route.waypoints[full_at - 2]
    assert full - takeoff >= 0.9 * (before.t_s - route.takeoff_s)
    assert at["battery failsafe: low, SMART_RTL or LAND"] > full
    v1 = next(v for v in report["vehicles"] if v["sysid"] == 1)
    assert [m["mode"] for m in v1["failsafe_modes"]] == ["LAND"]
    loss = next(x for x in report["losses"] if x["sysid"] == 1)
    assert loss["reason"].startswith("down in the field: a failsafe's LAND")
    said = [e["event"] for e in report["events"] if e["sysid"] == 1]
    assert 'failsafe: the autopilot says "SmartRTL deactivated: buffer full"' in said
    assert 'failsafe: the autopilot says "SmartRTL Unavailable, Trying Land Mode"' in said


def test_the_plan_counts_each_sortie_s_smartrtl_points_no_lower_than_they_fill(planned):
    """plan.json's ``returns``: each sortie's SmartRTL points, counted from its
    polyline, against the buffer; never fewer, at any waypoint, than the
    simulator's buffer holds after flying that polyline in 0.5 m steps."""
    from gcs.sim.smartrtl import SmartPath, simplified
    from planner.returns import returns_said, smartrtl_points, sortie_polyline

    r = planned.plan.metrics["returns"]
    assert r["srtl_points"] == 300 and r["too_long"] == [] and returns_said(planned.plan.metrics) \
        is None
    assert [s["vehicle"] for s in r["sorties"]] == [v.id for v in planned.plan.vehicles]
    for v in planned.plan.vehicles:
        xyz = sortie_polyline(v)
        counted = smartrtl_points(xyz, 2.0)
        path = SmartPath(10_000, 2.0, tuple(xyz[0]))
        for i in range(1, len(xyz)):
            steps = max(1, int(np.linalg.norm(xyz[i] - xyz[i - 1]) / 0.5))
            for t in np.linspace(0, 1, steps + 1)[1:]:
                path.add(tuple(xyz[i - 1] + t * (xyz[i] - xyz[i - 1])))
            assert len(simplified(path.points, 1.0)) <= counted[i], (v.id, i)
    said = returns_said({"returns": dict(r, too_long=[dict(vehicle=2, sortie=1, points=400,
                                                            full_at=70)])})
    assert said.startswith("warning: SmartRTL buffer: vehicle 2 sortie 1 (400 points, full at "
                           "its waypoint 70) need more than SRTL_POINTS 300")


def test_a_px4_battery_failsafe_mid_sortie_returns_along_the_mission(planned, tmp_path):
    """PX4 with --set-failsafes (COM_LOW_BAT_ACT 3, RTL_TYPE 4): its battery reaches
    the critical level halfway through route 1; its Return flies the mission's
    legs, forward to its landing or back to home, and lands at its base. Judged on
    the simulator's true track: within the track tolerance of the planned route,
    seen by no outpost by dense sampling, down at home."""
    from gcs.sim import terrain_ground

    lat, lon, alt = planned.launch
    fleet = quick_fleet(3, "px4", homes=[(lat, lon, alt)] * 3,
                        terrain=terrain_ground(planned.terrain), track_dir=tmp_path / "tracks")
    route = planned.plan.vehicles[0]
    fleet.vehicle(1).params["BAT_CRIT_THR"] = 1.0 - 0.5 * route.mission_time_s / (
        fleet.config.battery_min * 60.0)
    out = tmp_path / "flight"
    try:
        main(["fly", str(planned.dir), *_urls(fleet, "px4"), "--set-failsafes",
              "--lost-after", "3", "--timeout", "120", "-o", str(out)])
    finally:
        fleet.stop()
    track = read_track(track_path(tmp_path / "tracks", 1))
    fired = next(e["t"] for e in track.events
                 if e["event"] == "battery failsafe: critical, AUTO.RTL")
    assert any(e["event"].startswith("return along the mission") for e in track.events)
    x, y = planned.terrain.from_lonlat(track.lon, track.lat)
    xyz = np.stack([x, y, track.alt], axis=1)
    after = xyz[track.t > fired]
    planned_xyz = np.array([(*planned.terrain.from_lonlat(w.lon, w.lat), w.alt_amsl)
                            for w in route.waypoints])
    home = np.array(planned.terrain.from_lonlat(track.home[1], track.home[0]))
    column = np.array([[*home, track.home[2]], [*home, planned_xyz[0, 2]]])
    legs = np.concatenate([column, planned_xyz])
    tolerance = float(planned.plan.params["track_tolerance_m"])
    assert _to_polyline(after, legs).max() <= tolerance + ACCEPT_RADIUS_M
    assert not _seen(planned, after[::max(1, len(after) // 150)]).any()
    assert np.hypot(*(xyz[-1, :2] - home)) < 2.0 and abs(track.alt[-1] - track.home[2]) < 1.0
    report = json.loads((out / "flight.json").read_text())
    v1 = next(v for v in report["vehicles"] if v["sysid"] == 1)
    assert v1["state"] == "landed"
    assert [m["mode"] for m in v1["failsafe_modes"]] == ["AUTO.RTL"]


def test_a_vehicle_held_by_a_re_plan_that_falls_silent_flies_home_on_its_own(planned, tmp_path):
    """The ground station holds every survivor to re-plan after a loss; one of them
    then falls silent, held where it is (issue 59: one was once left hovering 4 km
    out, battery draining). With --set-failsafes its link-loss failsafe (ArduPilot
    FS_GCS_ENABLE 4: SmartRTL or Land; a mission in AUTO flies on, FS_OPTIONS) takes
    it home by its own flown path. Judged on the simulator's true track: the failsafe
    fired in the hold, the way home hidden from the outpost by dense sampling, down
    at home; the flight declared it lost, and took it back landed once heard."""
    import threading
    import time

    fleet = _ardupilot_at_base(planned, tmp_path)
    held = {}

    def kill_one_cut_one_held():
        one, two = fleet.vehicle(1), fleet.vehicle(2)
        while not (one.mode == "AUTO" and two.mode == "AUTO" and not two.landed
                   and len(one.track.snapshots) >= 3):
            time.sleep(0.01)
        fleet.kill(1)
        while two.mode != "GUIDED" and not two.landed:   # the re-plan's hold
            time.sleep(0.005)
        # its acknowledgement on its way first: cut with it, the ground station never
        # knew the hold was taken, and read the silence as the shadow its plan flew
        # into (a loaded run: out of contact as planned, never lost)
        time.sleep(0.3)
        held["t"] = two.t
        fleet.cut_link(2, 25.0)
    threading.Thread(target=kill_one_cut_one_held, daemon=True).start()
    out = _fly_setting_failsafes(planned, fleet, tmp_path, lost_after=2, timeout=150)
    track = read_track(track_path(tmp_path / "tracks", 2))
    failsafe = next(e for e in track.events if e["event"].startswith("link failsafe"))
    fired = failsafe["t"]
    assert held["t"] <= fired and failsafe["event"] == "link failsafe: SMART_RTL or LAND"
    x, y = planned.terrain.from_lonlat(track.lon, track.lat)
    after = np.stack([x, y, track.alt], axis=1)[track.t > fired]
    assert len(after) > 10 and not _seen(planned, after[::max(1, len(after) // 150)]).any()
    home = np.array(planned.terrain.from_lonlat(track.home[1], track.home[0]))
    assert np.hypot(*(after[-1, :2] - home)) < 2.0
    assert "landed" in [e["event"] for e in track.events if e["t"] > fired]
    report = json.loads((out / "flight.json").read_text())
    two = next(v for v in report["vehicles"] if v["sysid"] == 2)
    # heard again down at home, or still on its way there (the simulator keeps real
    # time while the ground station re-plans: a loaded run's long re-plan): taken back
    assert two["state"] == "landed" and [r["as"] for r in two["rejoins"]] in (
        ["landed"], ["flying"])
    assert [x["sysid"] for x in report["losses"]] == [1]
