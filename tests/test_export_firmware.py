"""One firmware per mission file and per plan folder.

A ``.waypoints`` file gcs writes says which firmware it was built for, whatever its
items (camera commands or not), and `gcs upload` refuses it to a vehicle of the
other one; `gcs export` leaves a folder whose plan.json and mission files agree,
or refuses and writes nothing. Judged by pymavlink's ``MAVWPLoader`` (an
independent reader and writer of the files), the ``.plan`` JSON itself, the bytes
on disk and the simulated vehicles' own mission stores."""

import hashlib
import json
import shutil

import pytest
from saved_plan import copy_plan
from sim_fleet import quick_fleet

from gcs import mission_protocol as mp
from gcs.cli import main
from gcs.mavlink import mavutil  # noqa: F401  (MAVLink 2 and the dialect, before mavwp)
from missions import wpl
from missions.build import MissionOptions, plan_missions, vehicle_mission
from missions.export import export_plan_dir
from missions.items import DO_DIGICAM_CONTROL, IMAGE_START_CAPTURE, MissionItem, first_difference
from planner.plan import PLAN_FILE, Plan

pytestmark = pytest.mark.timeout(120)

MARK = {"ardupilot": 3.0, "px4": 12.0}           # MAV_AUTOPILOT, as a .plan's firmwareType
CAMERA = {"ardupilot": DO_DIGICAM_CONTROL, "px4": IMAGE_START_CAPTURE}


def _loader(path):
    from pymavlink import mavwp

    loader = mavwp.MAVWPLoader()
    loader.load(str(path))
    return loader


def _lines(path) -> list:
    """The file's lines as pymavlink reads them."""
    loader = _loader(path)
    return [MissionItem.from_int(loader.wp(i)) for i in range(loader.count())]


def _snapshot(directory) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(directory.iterdir()) if p.is_file()}


def _one_line_error(capsys, command) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"gcs {command}: error: "), err
    return err[0]


@pytest.fixture
def folder(planned, tmp_path):
    """A plan folder (plan.json, terrain.tif) with its ArduPilot mission files."""
    d = copy_plan(planned, tmp_path / "plan")
    assert Plan.load(d).params["firmware"] == "ardupilot"
    assert main(["export", str(d), "--no-check"]) == 0
    return d


def _firmware_folder(planned, tmp_path, firmware, *extra) -> object:
    """A plan folder exported in place for ``firmware`` with ``extra`` options."""
    d = copy_plan(planned, tmp_path / f"plan-{firmware}")
    assert main(["export", str(d), "--firmware", firmware, "--no-check", *extra]) == 0
    return d


def _fleet(planned, firmware):
    return quick_fleet(1, firmware, homes=[planned.launch])


def _held(fleet) -> list:
    """What the simulated vehicle stores, as `MissionItem`s."""
    return [MissionItem(it.seq, it.frame, it.command, 0, it.autocontinue, it.param1, it.param2,
                        it.param3, it.param4, *((it.lat, it.lon) if it.frame in (0, 3) else
                                                (float(it.x), float(it.y))), it.z)
            for it in fleet.vehicle(1).mission.items]


# -- the mark ---------------------------------------------------------------------------------
@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
@pytest.mark.parametrize("camera", [True, False])
def test_every_waypoints_file_is_marked_and_reads_back_as_built(planned, tmp_path, firmware,
                                                                camera):
    """Line 0 (home, never flown) carries 0, 0, MAV_AUTOPILOT, 0 in params 1-4, with or
    without camera commands; every line is 12 tab-separated values (QGroundControl's
    loader takes nothing else); the mission read for the firmware is exactly the
    one built (the mark is not uploaded), and pymavlink reads the same lines."""
    route = planned.plan.vehicles[0]
    mission = vehicle_mission(route, firmware, MissionOptions(camera=camera))
    assert any(it.command == CAMERA[firmware] for it in mission.items) == camera
    path = tmp_path / "v.waypoints"
    wpl.write_waypoints(path, mission.items, firmware, planned.launch)
    text = path.read_text().splitlines()
    assert text[0] == "QGC WPL 110"
    assert all(len(line.split("\t")) == 12 for line in text[1:])
    lines = _lines(path)
    home = lines[0]
    assert (home.seq, home.command) == (0, 16)
    assert (home.param1, home.param2, home.param3, home.param4) == (0, 0, MARK[firmware], 0)
    assert wpl.marked_firmware(lines) == firmware
    assert first_difference(wpl.file_items(mission.items, firmware, planned.launch),
                            lines) is None
    assert first_difference(mission.items, wpl.read_waypoints(path, firmware)) is None


def test_an_unmarked_file_is_not_taken_for_marked(planned, tmp_path):
    """Another program's file (pymavlink's writer, home line params all 0), and a
    file whose line 0 is not home, have no mark."""
    mission = vehicle_mission(planned.plan.vehicles[0], "px4", MissionOptions(camera=False))
    ours = tmp_path / "ours.waypoints"
    wpl.write_waypoints(ours, mission.items, "px4", planned.launch)
    loader = _loader(ours)
    loader.wp(0).param3 = 0.0
    theirs = tmp_path / "theirs.waypoints"
    loader.save(str(theirs))
    assert wpl.marked_firmware(wpl.read_waypoints(theirs)) is None
    old = tmp_path / "old.waypoints"
    wpl.write_waypoints(old, mission.items)          # lines as given: takeoff first
    assert wpl.marked_firmware(wpl.read_waypoints(old)) is None


# -- gcs upload: the mark is obeyed -------------------------------------------------------------
@pytest.mark.parametrize("built, vehicle", [("px4", "ardupilot"), ("ardupilot", "px4")])
def test_a_waypoints_file_without_camera_is_refused_to_the_other_firmware(
        planned, tmp_path, capsys, built, vehicle):
    d = _firmware_folder(planned, tmp_path, built, "--no-camera")
    path = d / "vehicle-1.waypoints"
    assert not any(it.command in CAMERA.values() for it in _lines(path))  # no camera mark
    titles = {"ardupilot": "ArduPilot", "px4": "PX4"}
    a = {"ardupilot": "an", "px4": "a"}
    fleet = _fleet(planned, vehicle)
    capsys.readouterr()
    try:
        before = _held(fleet)
        assert main(["upload", str(path), "--connect", fleet.urls()[0]]) == 2
        assert _one_line_error(capsys, "upload") == (
            f"gcs upload: error: {path}: {a[built]} {titles[built]} mission, and vehicle 1 "
            f"runs {titles[vehicle]}: write {a[vehicle]} {titles[vehicle]} one from its plan "
            f"with `gcs export PLAN_DIR --firmware {vehicle}`")
        assert _held(fleet) == before                  # nothing sent
        # --firmware naming the vehicle's: refused before any link opens
        assert main(["upload", str(path), "--firmware", vehicle,
                     "--connect", fleet.urls()[0]]) == 2
        assert f"--firmware is {vehicle}" in _one_line_error(capsys, "upload")
        assert _held(fleet) == before
    finally:
        fleet.stop()


@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_a_marked_file_goes_to_its_own_firmware_as_built(planned, tmp_path, capsys, firmware):
    d = _firmware_folder(planned, tmp_path, firmware, "--no-camera")
    path = d / "vehicle-1.waypoints"
    built = plan_missions(Plan.load(d), firmware,
                          MissionOptions(camera=False,
                                         speed_mps=planned.plan.params.get("speed_mps")))[0]
    fleet = _fleet(planned, firmware)
    try:
        assert main(["upload", str(path), "--connect", fleet.urls()[0]]) == 0
        assert mp.compare(built.items, _held(fleet), firmware) == []
    finally:
        fleet.stop()


def test_an_unmarked_file_without_camera_keeps_todays_behaviour(planned, tmp_path, capsys):
    """A file with no mark (here a PX4 one saved again by pymavlink with the mark
    cleared) says nothing of its firmware: as before, it goes to a vehicle of
    either, line 0 kept as ArduPilot's home. This is what such a file always did."""
    d = _firmware_folder(planned, tmp_path, "px4", "--no-camera")
    path = d / "vehicle-1.waypoints"
    loader = _loader(path)
    loader.wp(0).param3 = 0.0
    loader.save(str(path))
    assert wpl.marked_firmware(wpl.read_waypoints(path)) is None
    fleet = _fleet(planned, "ardupilot")
    try:
        assert main(["upload", str(path), "--connect", fleet.urls()[0]]) == 0
        assert len(_held(fleet)) == len(wpl.read_waypoints(path))
    finally:
        fleet.stop()


# -- gcs export: one truth per folder --------------------------------------------------------
def _folder_firmwares(d) -> set:
    """Every firmware the folder says, read without missions/: plan.json, each .plan's
    firmwareType, each .waypoints file's home line (pymavlink) and camera commands."""
    names = {3: "ardupilot", 12: "px4"}
    said = {json.loads((d / PLAN_FILE).read_text())["params"]["firmware"]}
    for p in d.glob("vehicle-*.plan"):
        said.add(names[json.loads(p.read_text())["mission"]["firmwareType"]])
    for p in d.glob("vehicle-*.waypoints"):
        lines = _lines(p)
        said.add(names[int(lines[0].param3)])
        said |= {fw for fw, command in CAMERA.items()
                 if any(it.command == command for it in lines)}
    return said


@pytest.mark.parametrize("formats, hint", [
    ("geojson", "add plan,waypoints to --format to rewrite them"),
    ("plan,geojson", "add waypoints to --format to rewrite them"),
    ("waypoints", "add plan to --format to rewrite them")])
def test_export_in_place_refuses_to_leave_the_other_firmwares_files(folder, capsys, formats,
                                                                     hint):
    before = _snapshot(folder)
    capsys.readouterr()
    assert main(["export", str(folder), "--format", formats, "--firmware", "px4",
                 "--no-check"]) == 2
    line = _one_line_error(capsys, "export")
    assert line.startswith(f"gcs export: error: {folder}: writing PX4 missions in place would "
                           "leave ArduPilot ones beside them (vehicle-1.")
    assert line.endswith(f"{hint}, or write into another folder with -o DIR")
    assert _snapshot(folder) == before                 # nothing written, plan.json included
    assert _folder_firmwares(folder) == {"ardupilot"}


def test_export_in_place_of_every_mission_format_switches_the_folder(folder, capsys):
    capsys.readouterr()
    assert main(["export", str(folder), "--firmware", "px4", "--format", "plan,waypoints",
                 "--no-camera", "--no-check"]) == 0
    assert f"{folder / PLAN_FILE}  its firmware is now px4" in capsys.readouterr().err
    assert _folder_firmwares(folder) == {"px4"}
    # and back, with the proof (the surface rebuilt from the folder)
    assert main(["export", str(folder), "--firmware", "ardupilot"]) == 0
    assert _folder_firmwares(folder) == {"ardupilot"}


def test_a_folder_left_mixed_is_refused_until_its_missions_are_rewritten(folder, capsys):
    """plan.json saying PX4 over ArduPilot mission files (what the in-place export
    used to leave), and a mission file of a vehicle the plan no longer has."""
    doc = json.loads((folder / PLAN_FILE).read_text())
    doc["params"]["firmware"] = "px4"
    (folder / PLAN_FILE).write_text(json.dumps(doc))
    files = len(list(folder.glob("vehicle-*")))
    shutil.copy(folder / "vehicle-1.plan", folder / "vehicle-9.plan")
    before = _snapshot(folder)
    capsys.readouterr()
    assert main(["export", str(folder), "--format", "geojson", "--no-check"]) == 2
    line = _one_line_error(capsys, "export")
    assert line == (f"gcs export: error: {folder}: writing PX4 missions in place would leave "
                    "ArduPilot ones beside them (vehicle-1.plan, vehicle-1.waypoints, "
                    f"vehicle-2.plan and {files + 1 - 3} more): add plan,waypoints to "
                    "--format to rewrite them and remove vehicle-9.plan, or write into "
                    "another folder with -o DIR")
    assert _snapshot(folder) == before
    assert main(["export", str(folder), "--no-check"]) == 2           # vehicle-9.plan stays
    assert "(vehicle-9.plan): remove them, or write" in _one_line_error(capsys, "export")
    assert _snapshot(folder) == before
    (folder / "vehicle-9.plan").unlink()
    assert main(["export", str(folder), "--no-check"]) == 0
    assert _folder_firmwares(folder) == {"px4"}


def test_export_into_another_plans_folder_of_the_other_firmware_is_refused(folder, planned,
                                                                           tmp_path, capsys):
    other = _firmware_folder(planned, tmp_path, "px4")
    before = _snapshot(other), _snapshot(folder)
    capsys.readouterr()
    assert main(["export", str(folder), "-o", str(other), "--no-check"]) == 2
    assert _one_line_error(capsys, "export") == (
        f"gcs export: error: {other}: holds the plan.json of a PX4 plan: ArduPilot missions "
        "written here would disagree with it; write them into another folder")
    assert (_snapshot(other), _snapshot(folder)) == before
    # a folder of no plan: written, and the plan's own folder untouched
    out = tmp_path / "out"
    assert main(["export", str(folder), "-o", str(out), "--firmware", "px4",
                 "--no-check"]) == 0
    assert _snapshot(folder) == before[1]
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [f"vehicle-{v.id}.{s}" for v in planned.plan.vehicles for s in ("plan", "waypoints")]
        + ["routes.geojson", "routes.kml"])


def test_library_export_refuses_a_mixed_folder_too(folder, capsys):
    """`export_plan_dir` itself (not only the command) keeps the folder whole."""
    from common.errors import InputError

    before = _snapshot(folder)
    with pytest.raises(InputError, match="writing PX4 missions in place would leave ArduPilot"):
        export_plan_dir(folder, Plan.load(folder), "px4", formats=("plan",), plan_dir=folder)
    # not said to be the plan's own folder: its plan.json is another plan's, not rewritten
    with pytest.raises(InputError, match="holds the plan.json of an ArduPilot plan"):
        export_plan_dir(folder, Plan.load(folder), "px4")
    assert _snapshot(folder) == before
    # a folder of no plan holding the other firmware's files
    for p in folder.glob("vehicle-*"):
        shutil.copy(p, folder.parent / p.name)
    with pytest.raises(InputError, match="writing PX4 missions here would leave ArduPilot"):
        export_plan_dir(folder.parent, Plan.load(folder), "px4", formats=("plan",))
