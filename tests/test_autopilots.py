"""The autopilot profiles: one per firmware, the one place firmware differences live.

Judged against pymavlink's own mode tables (ArduPilot) and PX4's documented
packing, and by what the code base imports."""

import ast
import math
from pathlib import Path
from types import SimpleNamespace

import pytest

from autopilots import NAMES, PROFILES, profile, profile_of_heartbeat
from gcs.mavlink import M, mavutil
from gcs.mission_protocol import compare
from gcs.sim.flavours import FLAVOURS
from missions.build import MissionOptions, vehicle_mission
from missions.items import FRAME_GLOBAL, MissionItem
from planner.plan import GeoPoint, VehicleRoute, Waypoint

ROOT = Path(__file__).resolve().parents[1]


def test_names_and_heartbeats():
    assert NAMES == ("ardupilot", "px4")
    assert profile_of_heartbeat(M.MAV_AUTOPILOT_ARDUPILOTMEGA) is profile("ardupilot")
    assert profile_of_heartbeat(M.MAV_AUTOPILOT_PX4) is profile("px4")
    assert profile_of_heartbeat(M.MAV_AUTOPILOT_GENERIC) is None
    with pytest.raises(KeyError, match="known: ardupilot, px4"):
        profile("inav")


def test_ardupilot_modes_are_pymavlinks():
    ap = profile("ardupilot")
    for number, name in mavutil.mode_mapping_acm.items():
        assert ap.mode_number(name)[0] == number
        assert ap.mode_name(number) == name
    assert ap.set_mode_params("GUIDED") == (4.0, 0.0)


def test_px4_mode_packing():
    px4 = profile("px4")
    custom, main, sub = px4.mode_number("AUTO.MISSION")
    assert (main, sub) == (4, 4) and custom == (4 << 16) | (4 << 24)
    assert px4.set_mode_params("AUTO.LOITER") == (4.0, 3.0)
    assert px4.mode_from_set_mode(4.0, 3.0) == px4.mode_number("AUTO.LOITER")[0]
    assert px4.mode_name(4 << 16) == "AUTO.LOITER"          # bare AUTO while holding
    assert px4.mode_name((9 << 16) | (9 << 24)) == "MODE(9.9)"


def test_the_simulator_mirrors_the_profiles():
    for name, flavour in FLAVOURS.items():
        p = profile(name)
        assert flavour.profile is p and flavour.home_item == p.home_item
        for mode, custom in flavour.modes.items():
            assert p.mode_number(mode)[0] == custom
        for mode in (p.mission_mode, p.land_mode, p.rtl_mode, p.guided_mode,
                     p.mission_end_mode):
            assert mode in flavour.behaviour, (name, mode)
        assert flavour.capacity == p.mission_capacity


def _route():
    lat, lon, ground = -35.36, 149.16, 584.0
    wps = [Waypoint(lon, lat, ground + 30, 0.0), Waypoint(lon + 5e-4, lat, ground + 31, 5.0, True),
           Waypoint(lon, lat, ground + 30, 10.0)]
    return VehicleRoute(1, GeoPoint(lon, lat, ground), wps, 10.0, 20.0, 100.0)


@pytest.mark.parametrize("name", NAMES)
def test_missions_follow_the_profile(name):
    p = profile(name)
    items = vehicle_mission(_route(), name, MissionOptions(speed_mps=5.0)).items
    assert (items[0].command == 16) == p.home_item          # home first, or the takeoff
    assert items[p.first_item].command == 22
    camera = [it for it in items if it.command == p.camera_command]
    assert len(camera) == 1
    assert [camera[0].param1, camera[0].param2, camera[0].param3, camera[0].param4,
            camera[0].x, camera[0].y, camera[0].z] == list(p.camera_params(1))
    yaw = items[p.first_item].param4
    assert (math.isnan(yaw) and math.isnan(p.yaw)) or yaw == p.yaw


def _as_ardupilot_reads_back(item):
    """What ArduPilot 4.7 SITL sent back for the items of our missions (observed):
    DO commands in frame 0 with x, y, z zero (DO_DIGICAM_CONTROL keeps x, y),
    NAV_LAND's param4 as 1, params a command does not store as 0, altitudes cut to
    whole centimetres."""
    wire = item.to_int()
    if not item.is_position:
        wire["frame"] = FRAME_GLOBAL
        if item.command != 203:
            wire["x"] = wire["y"] = 0
        wire["z"] = 0.0
    else:
        wire["z"] = math.floor(wire["z"] * 100) / 100
    if item.command == 21:
        wire["param4"] = 1.0
    if item.command in (16, 21, 22):
        wire["param2"] = wire["param3"] = 0.0
    if item.command == 16:
        wire["param1"] = float(int(wire["param1"]))
    return MissionItem.from_int(SimpleNamespace(**wire))


def test_read_back_compares_the_fields_each_firmware_keeps():
    items = vehicle_mission(_route(), "ardupilot", MissionOptions(speed_mps=5.0, hold_s=2.5)
                            ).items
    back = [_as_ardupilot_reads_back(it) for it in items]
    back[0].x += 0.001                                        # the real home
    assert compare(items, back, "ardupilot") == []
    assert compare(items, back, "px4") != []                  # PX4 keeps every frame
    assert any("frame 2 != 0" in p for p in compare(items, back, None))
    speed = next(it for it in back if it.command == 178)
    speed.param2 += 1.0                                       # a kept field still counts
    problems = compare(items, back, "ardupilot")
    assert len(problems) == 1 and "param2" in problems[0]
    speed.param2 -= 1.0
    land = back[-1]
    land.z += 0.02                                            # 2 cm are kept
    assert "z " in compare(items, back, "ardupilot")[0]


def test_ardupilot_read_back_is_what_its_storage_keeps():
    ap = profile("ardupilot")
    wire = {"seq": 3, "frame": 2, "command": 203, "current": 0, "autocontinue": 1,
            "param1": 0.0, "param2": 0.0, "param3": 0.0, "param4": 0.0, "x": 1, "y": 0,
            "z": 7.0, "mission_type": 0}
    back = ap.read_back(wire)
    assert (back["frame"], back["x"], back["z"]) == (0, 1, 0.0)
    wp = dict(wire, command=16, frame=0, param1=2.7, param2=3.0, param4=float("nan"),
              x=365519720, y=-842666433, z=575.9439086914062)
    back = ap.read_back(wp)
    assert (back["param1"], back["param2"], back["param4"]) == (2.0, 0.0, 0.0)
    assert back["z"] == 575.94 and back["x"] == wp["x"]
    assert ap.read_back(dict(wp, seq=0)) is None                 # home
    assert ap.read_back(dict(wp, command=21, param4=-3.0))["param4"] == -1.0
    assert profile("px4").read_back(wp) == wp


def test_capacity_is_learned_from_what_the_vehicle_says():
    assert profile("ardupilot").capacity_said("Only 650 items are supported") == 650
    assert profile("ardupilot").capacity_said("Flight plan received") is None
    assert profile("px4").capacity_said("Only 650 items are supported") is None
    assert "BRD_SD_MISSION" in profile("ardupilot").capacity_advice


def _imports(path: Path) -> set:
    tree = ast.parse(path.read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.add(node.module.split(".")[0])
    return out


def test_layering():
    """autopilots and common import nothing of ours; planner imports only common and
    autopilots (the firmware facts it plans with: rates, names, the default);
    missions never gcs; and gcs/, missions/ and planner/ test no firmware by name
    (the profiles do)."""
    ours = {"gcs", "missions", "planner", "autopilots", "common"}
    for package in ("autopilots", "common"):
        for path in (ROOT / package).rglob("*.py"):
            assert not _imports(path) & (ours - {package}), path
    for package, never in (("planner", {"gcs", "missions"}), ("missions", {"gcs"})):
        for path in (ROOT / package).rglob("*.py"):
            assert not _imports(path) & never, path
    for package in ("gcs", "missions", "planner"):
        for path in (ROOT / package).rglob("*.py"):
            if path.name == "flavours.py":
                continue                     # the simulator's mirror names its profiles
            text = path.read_text()
            for needle in ('== "ardupilot"', '== "px4"', "== ARDUPILOT", "== PX4",
                           "flavour.name =="):
                assert needle not in text, f"{path}: {needle}"
    assert set(PROFILES) == set(NAMES)
    assert all(p.rates.climb_mps > 0 for p in PROFILES.values())    # every one has its rates
