"""The mission protocol and the start sequence, judged by references we did not write
into gcs/: the simulated vehicles' own mission stores and recorded tracks, and
MAVSDK's autopilot-side MissionRawServer."""

import itertools
import threading
import time

import pytest
from sim_fleet import quick_config

from gcs import commands
from gcs import mission_protocol as mp
from gcs.link import GroundLink
from gcs.mavlink import M
from gcs.sim import FleetConfig, SimFleet, free_base_port, read_track, track_path
from missions.build import MissionOptions, vehicle_mission
from missions.check import unproven
from missions.items import MissionItem
from planner.plan import GeoPoint, VehicleRoute, Waypoint

pytestmark = pytest.mark.timeout(60)

HOME = (-35.363261, 149.165230, 584.0)
ALT = HOME[2] + 25.0
# the protocol meets the autopilots' first second after boot, refusing uploads
BOOTING = dict(warmup_s=1.0, no_space_s=1.0)


# -- helpers ---------------------------------------------------------------------------
def fleet_config(firmware, vehicles, **kw) -> FleetConfig:
    return quick_config(vehicles, firmware, **{**BOOTING, **kw})


def route(vehicle_id: int, legs: int = 6, north_m: float = 0.0) -> VehicleRoute:
    """A small square-ish route starting and ending above HOME, shifted per vehicle."""
    lat0, lon0, ground = HOME
    dlat = 1 / 111_320.0
    dlon = dlat / 0.8148
    pts = [(0.0, 0.0)] + [(north_m + 40.0 * k, 30.0 * (k % 2)) for k in range(1, legs)] \
        + [(0.0, 0.0)]
    wps = [Waypoint(lon0 + e * dlon, lat0 + n * dlat, ALT + (k % 3), 10.0 * k,
                    snapshot=k % 2 == 1) for k, (n, e) in enumerate(pts)]
    wps[0].alt_amsl = wps[-1].alt_amsl = ALT
    return VehicleRoute(vehicle_id, GeoPoint(lon0, lat0, ground), wps, 60.0, 70.0, 400.0)


def mission_for(firmware, vehicle_id, **kw):
    return vehicle_mission(route(vehicle_id, north_m=15.0 * vehicle_id, **kw), firmware,
                           MissionOptions(speed_mps=8.0))


def sendable(mission):
    """The protocol tests fly over no terrain: the structure-only check (the mission
    check's own judge is tests/test_missions.py and tests/test_gate.py)."""
    return unproven(mission, "protocol test: no terrain")


def sim_items(fleet, sysid) -> list:
    """What the simulated vehicle stores, as MissionItem (its own MissionItem type)."""
    out = []
    for seq, it in enumerate(fleet.vehicle(sysid).mission.items):
        out.append(MissionItem(seq, it.frame, it.command, 0, it.autocontinue, it.param1,
                               it.param2, it.param3, it.param4, *_xy(it), it.z))
    return out


def _xy(it):
    if it.frame in (0, 3, 5, 6, 10, 11):
        return it.x * 1e-7, it.y * 1e-7
    return float(it.x), float(it.y)


@pytest.fixture
def opened():
    """Open fleets and links, closed whatever happens."""
    things = []

    def open_(cfg, **kw):
        fleet = SimFleet(cfg).start()
        things.append(fleet)
        link = GroundLink.open(fleet.urls(), expect=cfg.vehicles, timeout_s=10, **kw)
        things.append(link)
        return fleet, link

    yield open_
    for thing in reversed(things):
        (thing.close if isinstance(thing, GroundLink) else thing.stop)()


# -- upload / download against the simulator -------------------------------------------
@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_each_vehicle_gets_its_own_mission(opened, firmware):
    fleet, link = opened(fleet_config(firmware, 3))
    sent = {}
    for sysid, vehicle in link.vehicles.items():
        sent[sysid] = mission_for(firmware, sysid).items
        steps = []
        back = mp.upload_verified(vehicle, sendable(mission_for(firmware, sysid)),
                                  progress=lambda d, t: steps.append((d, t)))
        assert len(back) == len(sent[sysid])
        assert steps[-1] == (2 * len(sent[sysid]),) * 2
    for sysid, items in sent.items():
        held = sim_items(fleet, sysid)                # the vehicle's own store
        assert len(held) == len(items)
        # what the firmware keeps of each item (ArduPilot: 0 is the real home, DO
        # commands in frame 0), the rest the same
        assert mp.compare(items, held, firmware) == []
    # the missions really differ per vehicle (PX4: all through one UDP port)
    assert mp.compare(sim_items(fleet, 1), sim_items(fleet, 2)) != []


def test_no_space_after_boot_is_retried(opened):
    fleet, link = opened(fleet_config("ardupilot", 1, no_space_s=1.5))
    vehicle = link.vehicles[1]
    t0 = time.monotonic()
    mp.upload(vehicle, sendable(mission_for("ardupilot", 1)))
    assert any("Only 0 items" in text for _, text in vehicle.state.statustext)
    assert time.monotonic() - t0 >= 0.5        # it waited, then succeeded


@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_upload_over_a_lossy_link(opened, firmware):
    fleet, link = opened(fleet_config(firmware, 2, seed=3))
    time.sleep(1.2)                             # past ArduPilot's no-upload second
    fleet.set_drop(20.0)
    for sysid, vehicle in link.vehicles.items():
        mission = mission_for(firmware, sysid, legs=3)
        items = mission.items
        mp.upload_verified(vehicle, sendable(mission), timeout_s=0.2, retries=10)
        fleet.set_drop(0.0, sysid)               # read the store without racing the drop
        assert mp.compare(items, sim_items(fleet, sysid), firmware) == []


def test_silent_vehicle_gives_a_timeout_naming_it(opened):
    fleet, link = opened(fleet_config("px4", 2))
    fleet.cut_link(2, 30.0)
    with pytest.raises(mp.MissionError) as err:
        mp.upload(link.vehicles[2], sendable(mission_for("px4", 2)), timeout_s=0.2, retries=2)
    assert err.value.timeout and err.value.sysid == 2
    assert "vehicle 2" in str(err.value) and "no answer to MISSION_COUNT" in str(err.value)


def test_refusals_are_named(opened):
    fleet, link = opened(fleet_config("px4", 1))
    vehicle = link.vehicles[1]
    bad = mission_for("px4", 1)
    speed = next(it for it in bad.items if it.command == M.MAV_CMD_DO_CHANGE_SPEED)
    speed.frame = M.MAV_FRAME_LOCAL_NED         # no position: the check lets it by
    with pytest.raises(mp.MissionError, match="MAV_MISSION_UNSUPPORTED_FRAME") as err:
        mp.upload(vehicle, sendable(bad))
    assert err.value.result == M.MAV_MISSION_UNSUPPORTED_FRAME
    with pytest.raises(mp.MissionError, match="MAV_MISSION_UNSUPPORTED"):
        mp.upload(vehicle, sendable(mission_for("px4", 1)),
                  mission_type=M.MAV_MISSION_TYPE_FENCE)


@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_clear(opened, firmware):
    fleet, link = opened(fleet_config(firmware, 1))
    vehicle = link.vehicles[1]
    mp.upload(vehicle, sendable(mission_for(firmware, 1)))
    mp.clear(vehicle)
    assert len(mp.download(vehicle)) == (1 if firmware == "ardupilot" else 0)


def test_read_back_mismatch_is_an_error(opened, monkeypatch):
    fleet, link = opened(fleet_config("px4", 1))
    mission = sendable(mission_for("px4", 1))
    real_download = mp.download

    def tampered(*a, **kw):
        back = real_download(*a, **kw)
        back[3].z += 5.0
        return back

    monkeypatch.setattr(mp, "download", tampered)
    with pytest.raises(mp.MissionError, match=r"differs.*item 3: z"):
        mp.upload_verified(link.vehicles[1], mission)


# -- against MAVSDK's MissionRawServer (an autopilot-side implementation) ----------------
@pytest.mark.parametrize("vehicles", [1, 4])
def test_upload_to_mavsdk_mission_raw_server(vehicles):
    mavsdk = pytest.importorskip("mavsdk")
    from mavsdk.plugins.mission_raw_server import MissionRawServer

    port = free_base_port(1, 1, udp=True)
    link = GroundLink(f"udpin:127.0.0.1:{port}").start()   # bound before MAVSDK sends
    received, servers, done = {}, [], threading.Event()
    try:
        for sysid in range(1, vehicles + 1):
            cfg = mavsdk.Configuration.create_with_component_type(mavsdk.ComponentType.AUTOPILOT)
            cfg.system_id = sysid
            sdk = mavsdk.Mavsdk(cfg)
            assert sdk.add_any_connection(f"udpout://127.0.0.1:{port}") == \
                mavsdk.ConnectionResult.SUCCESS
            server = MissionRawServer(sdk.server_component())

            def on_mission(result, plan, _ud, sysid=sysid):
                received[sysid] = (result, plan.mission_items)
                if len(received) == vehicles:
                    done.set()

            server.subscribe_incoming_mission(on_mission)
            servers.append((sdk, server, cfg))
        link.wait_vehicles(vehicles, timeout_s=10)
        # each MAVSDK has heard the ground station before it is sent a mission, and
        # its transfer gets more time than a vehicle's: four MAVSDK instances in one
        # process on a busy machine once left vehicle 1's MISSION_COUNT unanswered
        # through 6 tries 1.5 s apart
        deadline = time.monotonic() + 20
        while any(sdk.system_count() == 0 for sdk, _, _ in servers) and \
                time.monotonic() < deadline:
            time.sleep(0.1)
        sent = {}
        for sysid, vehicle in link.vehicles.items():
            sent[sysid] = mission_for("px4", sysid).items
            mp.upload(vehicle, sendable(mission_for("px4", sysid)), timeout_s=3.0, retries=10)
        assert done.wait(15), f"MissionRawServer got missions from {sorted(received)}"
        for sysid, items in sent.items():
            result, got = received[sysid]
            assert result.name == "SUCCESS"
            got = [MissionItem.from_int(i) for i in got]   # MAVSDK's items are MISSION_ITEM_INT
            assert mp.compare(items, got) == [], sysid
            assert mp.compare(items, mp.download(link.vehicles[sysid])) == []
    finally:
        link.close()
        for sdk, server, cfg in servers:
            server.destroy()
            sdk.destroy()


# -- starting the mission --------------------------------------------------------------
@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_start_mission_flies_it(opened, firmware, tmp_path):
    fleet, link = opened(fleet_config(firmware, 2, track_dir=tmp_path, speedup=30.0))
    missions = {}
    for sysid, vehicle in link.vehicles.items():
        missions[sysid] = mission_for(firmware, sysid, legs=3)
        mp.upload_verified(vehicle, sendable(missions[sysid]))
    # both at once: one thread per vehicle over the shared link, as a ground station would
    errors = []

    def start(vehicle):
        try:
            commands.start_mission(vehicle, ALT)
        except Exception as exc:               # re-raised below in the test thread
            errors.append(exc)

    threads = [threading.Thread(target=start, args=(v,)) for v in link.vehicles.values()]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    last_nav = {s: max(k for k, it in enumerate(m.items) if it.command == M.MAV_CMD_NAV_LAND)
                for s, m in missions.items()}
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and not all(
            last_nav[s] in v.state.reached for s, v in link.vehicles.items()):
        time.sleep(0.2)
    fleet.stop()
    for sysid, vehicle in link.vehicles.items():
        assert last_nav[sysid] in vehicle.state.reached
        track = read_track(track_path(tmp_path, sysid))     # the vehicle's own record
        events = [e["event"] for e in track.events]
        assert "armed" in events
        assert max(track.alt) >= ALT - 1.0
        items = missions[sysid].items
        wanted = {k for k, w in enumerate(missions[sysid].waypoint_of_item) if w is not None}
        reached = {int(e.split()[1]) for e in events if e.startswith("reached")}
        for k in wanted:       # PX4 reports a waypoint after its DO commands, by the last
            group = [k] + list(itertools.takewhile(
                lambda j: items[j].command >= M.MAV_CMD_NAV_LAST, range(k + 1, len(items))))
            assert reached & set(group), (sysid, k)


def test_mode_changes_over_a_lossy_link(opened, monkeypatch):
    """A lost HEARTBEAT must not fail a mode change the vehicle made: with half the
    packets dropped and one HEARTBEAT period to confirm, most first confirmations
    miss; the command is then sent again until the HEARTBEAT shows the mode."""
    monkeypatch.setattr(commands, "CONFIRM_S", 1.0)
    fleet, link = opened(fleet_config("ardupilot", 1, seed=5))
    vehicle = link.vehicles[1]
    commands.wait_ready(vehicle, 10)
    fleet.set_drop(50.0)
    for mode in ["GUIDED", "LOITER"] * 2:
        commands.set_mode(vehicle, mode, timeout_s=0.2, retries=20)
        assert fleet.vehicle(1).mode == mode


def test_refused_arming_is_explained(opened):
    fleet, link = opened(fleet_config("ardupilot", 1))
    vehicle = link.vehicles[1]
    mp.upload(vehicle, sendable(mission_for("ardupilot", 1)))
    fleet.refuse_arm(1)
    with pytest.raises(commands.CommandError) as err:
        commands.start_mission(vehicle, ALT, ready_timeout_s=3)   # refused until then
    text = str(err.value)
    assert "vehicle 1" in text and "MAV_CMD_COMPONENT_ARM_DISARM refused" in text
    assert "MAV_RESULT_FAILED" in text and "PreArm" in text


def test_arming_waits_for_its_base_column_and_gives_it_back_when_refused(opened):
    """Each arming attempt first claims the column (waited for while another is
    in it), and a refused attempt gives it back: a vehicle held on the ground must
    not keep the next one due out of the column, nor arm beside it."""
    fleet, link = opened(fleet_config("ardupilot", 1, speedup=30.0))
    vehicle = link.vehicles[1]
    mp.upload(vehicle, sendable(mission_for("ardupilot", 1)))
    fleet.refuse_arm(1)
    calls, busy_until = [], time.monotonic() + 1.0

    class Column:
        def claim(self):
            free = time.monotonic() > busy_until      # another vehicle in it for 1 s
            calls.append("claim" if free else "wait")
            return free

        def release(self):
            calls.append("release")
            if calls.count("release") == 2:          # its crew lets it go
                fleet.refuse_arm(1, False)

    commands.start_mission(vehicle, ALT, ready_timeout_s=10, column=Column())
    first = calls.index("claim")
    assert calls[:first] and set(calls[:first]) == {"wait"}
    # every refused attempt gave the column back; the one that armed kept it
    assert calls[first:] == ["claim", "release", "claim", "release", "claim"]


def test_not_ready_is_a_clear_timeout(opened):
    fleet, link = opened(fleet_config("px4", 1, warmup_s=30.0))
    with pytest.raises(commands.CommandError, match="vehicle 1: not ready to arm after 1 s"):
        commands.wait_ready(link.vehicles[1], timeout_s=1.0)


# -- the command line ------------------------------------------------------------------
def main(argv) -> int:
    """`gcs COMMAND ...` for the two commands here, as gcs.cli.main runs them (built
    from their own modules so that other commands' state cannot break this test)."""
    import argparse
    import importlib
    import sys

    from common.errors import InputError

    module = importlib.import_module(f"gcs.cli.{argv[0]}")
    parser = argparse.ArgumentParser(prog=f"gcs {argv[0]}")
    module.add_arguments(parser)
    args = parser.parse_args(argv[1:])
    try:
        return module.run(args)
    except InputError as exc:
        print(f"gcs {argv[0]}: error: {exc}", file=sys.stderr)
        return 2


def _connect(urls) -> list:
    return [arg for url in urls for arg in ("--connect", url)]


@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_cli_upload_and_download(firmware, tmp_path, capsys):
    from missions import qgc, wpl
    from planner.plan import Plan

    plan = Plan("rt", {"speed_mps": 8.0, "firmware": firmware}, "EPSG:32755", [],
                [route(1, legs=3, north_m=15.0), route(2, legs=4, north_m=30.0)])
    plan.save(tmp_path)
    fleet = SimFleet(fleet_config(firmware, 2)).start()
    try:
        urls = _connect(fleet.urls())
        # a plan directory, routes swapped by --vehicle; each built for the vehicle's firmware
        # no terrain.tif to prove the legs against: only with --unchecked, and a warning
        assert main(["upload", str(tmp_path), "--vehicle", "1=2", *urls]) == 2
        assert "terrain.tif: missing" in capsys.readouterr().err
        assert main(["upload", str(tmp_path), "--vehicle", "1=2", "--unchecked", *urls]) == 0
        captured = capsys.readouterr()
        assert "warning" in captured.err and "not proven" in captured.err
        expected = {1: mission_for_route(plan.vehicles[1], firmware),
                    2: mission_for_route(plan.vehicles[0], firmware)}
        for sysid, items in expected.items():
            assert mp.compare(items, sim_items(fleet, sysid), firmware) == []
        out = captured.out
        assert "verified" in out and "failed" not in out
        # download what vehicle 1 holds, in both formats, and read it back with missions/
        for suffix in ("plan", "waypoints"):
            path = tmp_path / f"held.{suffix}"
            assert main(["download", "--sysid", "1", "-o", str(path), *urls]) == 0
            items = qgc.read_plan_file(path) if suffix == "plan" else \
                wpl.read_waypoints(path, firmware)         # line 0 home: kept or dropped
            assert mp.compare(expected[1], items, firmware) == []
            if suffix == "waypoints":                      # home first, for every firmware
                assert wpl.read_waypoints(path)[0].command == 16
        # mission files, one route each, by order of system id
        files = []
        for r in plan.vehicles:
            files.append(tmp_path / f"vehicle-{r.id}.waypoints")
            wpl.write_waypoints(files[-1], mission_for_route(r, firmware))
        assert main(["upload", *map(str, files), "--unchecked", *urls]) == 0
        assert mp.compare(mission_for_route(plan.vehicles[0], firmware),
                          sim_items(fleet, 1), firmware) == []
        # two vehicles and no --sysid: a clear error
        assert main(["download", "-o", str(tmp_path / "x.plan"), *urls]) == 2
        assert "choose one" in capsys.readouterr().err
    finally:
        fleet.stop()


def mission_for_route(r, firmware):
    return vehicle_mission(r, firmware, MissionOptions(speed_mps=8.0)).items


@pytest.mark.parametrize("failsafe_mode", [None, "SMART_RTL"])
def test_a_vehicle_that_disarmed_itself_before_the_takeoff_is_armed_again(opened, monkeypatch,
                                                                        failsafe_mode):
    """ArduPilot disarms itself idle on the ground (DISARM_DELAY, 10 s of its time: a
    fraction of a wall second at a high --speedup, as CI once met). A takeoff that
    comes after that is refused; the start arms again and retries, once. Brought
    down in a failsafe's mode (real ArduPilot SITL: a GCS failsafe in the GUIDED
    takeoff climb, no mission to continue yet, flew SmartRTL back to the pad, where
    it disarmed; the start armed again in SMART_RTL, "Arm: SMARTRTL mode not
    armable", until its ready timeout), the start fails at once and says why: the
    flight has judged the vehicle down, and one sent up again flew unwatched."""
    fleet, link = opened(fleet_config("ardupilot", 1, speedup=20.0))
    vehicle = link.vehicles[1]
    mp.upload_verified(vehicle, sendable(mission_for("ardupilot", 1)))
    arm, armed = commands._StartRun.arm, []

    def arm_then_idle(run, _=None):
        arm(run, _)
        armed.append(run.armed_at)
        if len(armed) == 1 and failsafe_mode:
            fleet.vehicle(1).mode = failsafe_mode
        deadline = time.monotonic() + 10
        while len(armed) == 1 and not commands._disarmed_since(vehicle, run.armed_at):
            assert time.monotonic() < deadline, "the vehicle did not disarm itself"
            time.sleep(0.05)

    monkeypatch.setattr(commands._StartRun, "arm", arm_then_idle)
    if failsafe_mode:
        with pytest.raises(commands.CommandError, match="a failsafe brought it back down in "
                                                        "SMART_RTL during its takeoff climb"):
            commands.start_mission(vehicle, ALT)
        assert len(armed) == 1 and not fleet.vehicle(1).armed
        return
    commands.start_mission(vehicle, ALT)
    assert len(armed) == 2
    assert fleet.vehicle(1).armed and (vehicle.state.relative_alt or 0.0) > 1.0


def test_an_item_sent_twice_is_said_out_of_order_and_the_upload_goes_on(opened, monkeypatch):
    """ArduPilot answers an item it is not asking for now with MISSION_ACK
    INVALID_SEQUENCE and keeps the transfer open (MissionItemProtocol::
    handle_mission_item): on a busy machine a re-sent item crosses its next request.
    Every item sent twice, each second one so answered: the upload still completes
    (it was a refusal, and a failed flight on a loaded machine with real SITL)."""
    fleet, link = opened(fleet_config("ardupilot", 1))
    time.sleep(1.2)                             # past ArduPilot's no-upload second
    vehicle = link.vehicles[1]
    send = mp._send_item

    def twice(link_, item, mission_type):
        send(link_, item, mission_type)
        send(link_, item, mission_type)

    monkeypatch.setattr(mp, "_send_item", twice)
    mission = mission_for("ardupilot", 1, legs=3)
    items = mission.items
    mp.upload(vehicle, sendable(mission))
    assert mp.compare(items, sim_items(fleet, 1), "ardupilot") == []
