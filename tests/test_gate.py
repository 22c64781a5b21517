"""Only checked missions reach a vehicle, on every upload path; files are read and
checked before any link opens; every link form works, serial included.

Judged by the simulated vehicle's own mission store and by whether it ever saw a
ground station at all (its TCP server's accepted clients), never by what gcs says.
"""

import json
import shutil
import time
from contextlib import contextmanager
from types import SimpleNamespace

import pytest
from sim_fleet import quick_fleet

from autopilots import profile
from common.errors import InputError
from gcs import mission_protocol as mp
from gcs.cli import main
from gcs.link import GroundLink
from gcs.monitor import FLYING, STRANDED, Monitor
from gcs.retask import Retask, Retasker, RetaskError
from missions import qgc, wpl
from missions.build import MissionOptions, vehicle_mission
from missions.check import CheckedMission, checked
from missions.export import export_plan_dir
from missions.items import MissionItem
from planner.plan import PLAN_FILE, Plan

pytestmark = pytest.mark.timeout(90)


@pytest.fixture
def vehicle(planned):
    """One simulated ArduPilot copter at the plan's launch point."""
    fleet = quick_fleet(1, homes=[planned.launch])
    yield fleet
    fleet.stop()


def held(fleet) -> list:
    """What the simulated vehicle stores (ArduPilot: item 0 is its home)."""
    return [it for it in fleet.vehicle(1).mission.items]


def stored(fleet) -> list:
    """The vehicle's store as `MissionItem`s (its own item type converted)."""
    return [MissionItem(it.seq, it.frame, it.command, 0, it.autocontinue, it.param1, it.param2,
                        it.param3, it.param4, *((it.lat, it.lon) if it.frame in (0, 3) else
                                                (float(it.x), float(it.y))), it.z)
            for it in fleet.vehicle(1).mission.items]


def never_contacted(fleet) -> bool:
    return fleet.vehicle(1).link.accepted == 0 and len(held(fleet)) == 1


def _edit_plan(path, edit):
    doc = json.loads(path.read_text())
    edit(doc["mission"]["items"])
    path.write_text(json.dumps(doc))


def _first_waypoint(items):
    return next(it for it in items if it["command"] == 16)


def relative_frame(items):
    wp = _first_waypoint(items)
    wp["frame"] = 3                                    # MAV_FRAME_GLOBAL_RELATIVE_ALT
    wp["AltitudeMode"] = 1


def raised(items):
    wp = [it for it in items if it["command"] == 16][len(items) // 4]
    wp["params"][6] += 200.0                           # 200 m up, into view
    wp["Altitude"] = wp["params"][6]


def do_jump(items):
    items.insert(3, {"type": "SimpleItem", "command": 177, "frame": 2, "autoContinue": True,
                     "doJumpId": 99, "params": [1, 3, 0, 0, 0, 0, 0]})


def faster(items):
    speed = next(it for it in items if it["command"] == 178)   # DO_CHANGE_SPEED
    speed["params"][1] *= 2.0                   # same legs, twice as fast: off the schedule


@pytest.mark.parametrize("edit, problem", [(relative_frame, "frame 3"),
                                           (raised, "is not hidden from the outposts"),
                                           (do_jump, "DO_JUMP"),
                                           (faster, "DO_CHANGE_SPEED to 24 m/s, not the "
                                                    "plan's 12 m/s")])
def test_edited_plan_file_never_reaches_the_vehicle(plan_copy, vehicle, capsys, edit, problem):
    path = plan_copy / "vehicle-1.plan"
    _edit_plan(path, edit)
    started = time.monotonic()
    assert main(["upload", str(path), "--connect", vehicle.urls()[0]]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"gcs upload: error: {path}: ") and problem in err, err
    assert len(err.splitlines()) == 1
    assert never_contacted(vehicle)                  # refused before any link opened
    assert time.monotonic() - started < 10


def test_raised_waypoint_in_a_waypoints_file(plan_copy, vehicle, capsys):
    path = plan_copy / "vehicle-2.waypoints"
    items = wpl.read_waypoints(path)
    items[len(items) // 2].z += 200.0
    wpl.write_waypoints(path, items)
    assert main(["upload", str(path), "--connect", vehicle.urls()[0]]) == 2
    assert "is not hidden from the outposts" in capsys.readouterr().err
    assert never_contacted(vehicle)


def test_checked_file_is_uploaded_as_it_is(plan_copy, vehicle, capsys):
    path = plan_copy / "vehicle-1.plan"
    assert main(["upload", str(path), "--connect", vehicle.urls()[0]]) == 0
    assert mp.compare(qgc.read_plan_file(path, "ardupilot"), stored(vehicle), "ardupilot") == []


def test_file_without_a_plan_needs_unchecked(plan_copy, vehicle, tmp_path, capsys):
    alone = tmp_path / "alone"
    alone.mkdir()
    path = shutil.copy(plan_copy / "vehicle-1.waypoints", alone / "edited.waypoints")
    url = vehicle.urls()[0]
    assert main(["upload", str(path), "--connect", url]) == 2
    err = capsys.readouterr().err
    assert "nothing to check it against" in err and "--plan" in err
    assert never_contacted(vehicle)
    # the plan it came from, named with --plan: checked, uploaded
    assert main(["upload", str(path), "--plan", str(plan_copy), "--connect", url]) == 0
    assert len(held(vehicle)) == len(wpl.read_waypoints(path))
    # --unchecked: a one-line warning naming what was not proven, then the upload
    assert main(["upload", str(path), "--unchecked", "--connect", url]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert len(warnings) == 1
    assert "legs not proven hidden from outposts nor clear of the terrain" in warnings[0]


def test_truncated_file_fails_before_connecting(plan_copy, vehicle, capsys):
    path = plan_copy / "vehicle-1.plan"
    text = path.read_text()
    path.write_text(text[: len(text) // 2])
    assert main(["upload", str(path), "--connect", vehicle.urls()[0]]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"gcs upload: error: {path}: ") and "line" in err
    assert never_contacted(vehicle)


@pytest.mark.parametrize("command", ["upload", "fly"])
def test_url_without_a_scheme_is_refused_at_once(plan_copy, capsys, command):
    started = time.monotonic()
    assert main([command, str(plan_copy), "--connect", "127.0.0.1:5760"]) == 2
    err = capsys.readouterr().err.strip()
    assert time.monotonic() - started < 5
    assert f"gcs {command}: error: --connect: 127.0.0.1:5760" in err
    assert "tcp:127.0.0.1:5760" in err and "udpin:" in err and "DEVICE,BAUD" in err


def test_upload_over_a_serial_line(planned, plan_copy, capsys):
    """A simulated vehicle on one end of a pseudo-terminal, `gcs upload` with the
    DEVICE,BAUD URL on the other."""
    fleet = quick_fleet(1, "px4", homes=[planned.launch], transport="pty", speedup=1.0,
                        no_space_s=1.0)
    try:
        url = fleet.urls()[0]
        assert url.startswith("/dev/") and url.endswith(",57600")
        # the plan folder made PX4's: its mission files and plan.json (a PX4 .plan
        # beside ArduPilot .waypoints and plan.json is refused)
        export_plan_dir(plan_copy, Plan.load(plan_copy), "px4", formats=("plan", "waypoints"),
                        plan_dir=plan_copy)
        path = plan_copy / "vehicle-1.plan"            # the file is PX4's, as the vehicle
        assert main(["upload", str(path), "--connect", url]) == 0
        assert mp.compare(qgc.read_plan_file(path, "px4"), stored(fleet), "px4") == []
    finally:
        fleet.stop()


def test_fly_refuses_an_edited_plan_before_connecting(plan_copy, vehicle, tmp_path, capsys):
    doc = json.loads((plan_copy / PLAN_FILE).read_text())
    wps = doc["vehicles"][1]["waypoints"]
    wps[len(wps) // 2]["alt_amsl"] += 200.0
    (plan_copy / PLAN_FILE).write_text(json.dumps(doc))
    out = tmp_path / "flight"
    assert main(["fly", str(plan_copy), "--connect", vehicle.urls()[0], "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "vehicle 2" in err and "is not hidden from the outposts" in err
    assert len(err.splitlines()) == 1
    assert never_contacted(vehicle) and not out.exists()


@contextmanager
def _followed(planned, vehicle):
    """The simulated vehicle flying vehicle 1's checked mission, followed by a
    `Monitor`: (monitor, its link, the mission, what the vehicle stores)."""
    route = planned.plan.vehicles[0]
    options = MissionOptions(speed_mps=planned.plan.params["speed_mps"])
    first = checked(vehicle_mission(route, "ardupilot", options), planned.ctx.surface,
                    planned.plan.params["clearance_m"])
    with GroundLink.open(vehicle.urls(), expect=1, timeout_s=10) as link:
        v = link.vehicles[1]
        mp.upload_verified(v, first)
        monitor = Monitor(5.0)
        monitor.follow(v, route.id, route, first)
        monitor.set_state(1, FLYING)          # flying its mission, as far as gcs knows
        try:
            yield monitor, v, first, held(vehicle)
        finally:
            monitor.close()


def test_re_tasking_uploads_only_checked_missions(planned, vehicle, monkeypatch):
    """A re-plan whose route was raised into view is refused by the check: the vehicle
    keeps the mission it had. And nothing but a CheckedMission is sent at all."""
    with _followed(planned, vehicle) as (monitor, v, first, before):
        with pytest.raises(TypeError, match="only a checked mission"):
            mp.upload_verified(v, first.items)
        with pytest.raises(TypeError, match="made only by"):
            CheckedMission(first.items, "x", None, None)
        bad = Plan.from_dict(planned.plan.to_dict()).vehicles[0]
        bad.waypoints[len(bad.waypoints) // 2].alt_amsl += 200.0
        monkeypatch.setattr("gcs.retask.replan", lambda *a, **k: SimpleNamespace(
            plan=SimpleNamespace(metrics={}, vehicles=[bad])))
        with pytest.raises(RetaskError, match="is not hidden from the outposts"):
            Retasker(planned.ctx, monitor).\
                _attempt(Retask(t_s=0.0, lost=[]), [1])
        assert held(vehicle) == before


def test_a_survivor_no_hidden_leg_joins_is_stranded_not_the_flight(planned, vehicle,
                                                                    monkeypatch):
    """A held vehicle whose position no hidden leg joins to the hidden volume cannot
    start a route: it stays held, stranded (the operator's), nothing is uploaded to
    it, and the re-tasking goes on with the others (here: none) instead of failing."""
    with _followed(planned, vehicle) as (monitor, _, _, before):
        def unjoined(ctx, survivor):
            raise InputError(f"vehicle {survivor.vehicle_id}", "its position is not joined "
                                                                "to the hidden volume")

        monkeypatch.setattr("gcs.retask.survivor_start", unjoined)
        monkeypatch.setattr("gcs.retask.replan", lambda *a, **k: pytest.fail("re-planned"))
        record = Retasker(planned.ctx, monitor).retask()
        assert record.stranded == [1] and record.survivors == []
        assert monitor.vehicles[1].state == STRANDED and monitor.vehicles[1].finished
        assert vehicle.vehicle(1).mode == profile("ardupilot").hold_mode  # held there
        assert held(vehicle) == before                       # nothing uploaded
        assert any(e["event"].startswith("stranded") for e in monitor.events)
