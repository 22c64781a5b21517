"""Every failsafe read before arming, on the built-in simulator and on real
ArduPilot and PX4 SITL (issue 60): the firmware's own defaults refuse the
flight, naming the parameters; --set-failsafes writes the hidden-safe values,
and the vehicle itself, asked again, holds them (each a value the profile calls
hidden); the previous values are kept to restore, and restored.

A ground-station link cut by hand mid-mission (the backend's `cut_link`, wherever the
vehicle is), on SITL started with a link failsafe that returns in view: with
--set-failsafes the mission flies on, by the autopilot's own word.

Real SITL runs when the environment names its binaries (`source /opt/sitl.env`:
ARDUPILOT_SITL_BIN, ARDUPILOT_DEFAULTS, PX4_SITL_BIN); otherwise skipped, saying so."""

import math

import pytest
from fleets import REAL_BACKENDS, SPEEDUP, skip_unless_configured, start_backend

from autopilots import profile
from common.geo import LocalFrame, distance_m
from gcs import params
from gcs.flight import FailsafeRefused, Flight, FlyOptions
from gcs.flight.failsafes import restore
from gcs.mavlink import M

pytestmark = pytest.mark.timeout(600)


@pytest.mark.parametrize("backend", ["sim", "ardupilot", "px4"])
def test_failsafes_refused_then_set_read_back_and_restored(planned, tmp_path, backend):
    """The firmware's default failsafes are refused; set, read back, and restored at
    the end. No radio: the vehicles never leave their bases, where an antenna stands."""
    skip_unless_configured(backend)
    case = planned(0, backend)
    be = start_backend(backend, case.plan, tmp_path / "sitl")
    firmware = be.firmware
    parameters = [p for f in profile(firmware).failsafes for p in f.parameters]
    options = FlyOptions(output=tmp_path / "flight", live=False, plot=False, tlog=False,
                         connect_timeout_s=120.0, ready_timeout_s=180.0)
    flight = Flight(case.directory, be.urls(), options)
    try:
        flight.prepare()
        flight.output.mkdir(parents=True, exist_ok=True)
        flight.connect()
        flight.preflight.locate()
        with pytest.raises(FailsafeRefused) as refused:
            flight.preflight.check_failsafes()
        said = str(refused.value)
        assert "add --set-failsafes" in said
        # the firmware's defaults: RC loss RTL and no FS_OPTIONS (ArduPilot), RTL_TYPE 0
        # (PX4), named with their values
        assert ("FS_OPTIONS = 16" if firmware == "ardupilot" else "RTL_TYPE = 0") in said
        options.set_failsafes = True
        flight.preflight.check_failsafes()
        links = flight.monitor.links
        for sysid, link in sorted(links.items()):
            for p in parameters:
                held = params.read(link, p.name)
                assert held is not None, (sysid, p.name)
                gate_off = any(params.read(link, g) is not None and
                               test(params.read(link, g).value) for g, test in p.off)
                assert gate_off or p.is_hidden(held.value), (sysid, p.name, held.value)
            changes = flight.preflight.failsafes[sysid]["set"]
            assert changes and all(params.read(link, c["parameter"]).value == c["value"]
                                   for c in changes)
            assert restore(link, changes) == []
            assert all(params.read(link, c["parameter"]).value == c["previous"]
                       for c in changes)
    finally:
        if flight.link is not None:
            flight.link.close()
        be.stop()



def test_a_low_battery_mid_mission_flies_smartrtl_home_on_ardupilot_sitl(planned, tmp_path):
    """Real ArduPilot SITL with --set-failsafes (BATT_FS_LOW_ACT 4): its simulated
    battery sags below BATT_LOW_VOLT (10.5 V, the copter default) 40 % into vehicle
    1's route (SIM_BATT_VOLTAGE 10 V, set on the judge's link); after BATT_LOW_TIMER
    the firmware's own battery failsafe flies SmartRTL, retracing its path, and
    lands at its base. Judged by the autopilot's own positions on its second link:
    hidden and clear all along, down at its launch point; the monitor says the
    failsafe's mode and the report lists it."""
    _battery_failsafe_flies_home(planned, tmp_path, "ardupilot", "SIM_BATT_VOLTAGE", 10.0,
                                 "SMART_RTL")


def test_a_critical_battery_mid_mission_returns_along_the_mission_on_px4_sitl(planned,
                                                                               tmp_path):
    """Real PX4 SITL with --set-failsafes (COM_LOW_BAT_ACT 3, RTL_TYPE 4): 40 % into
    vehicle 1's route its simulated pack is let down to 6 % (SIM_BAT_MIN_PCT, on the
    judge's link: below BAT_CRIT_THR 7 %, above BAT_EMERGEN_THR 5 %); the firmware's
    battery failsafe Returns along the mission and lands at a base. Judged by the
    autopilot's own positions: hidden and clear all along, down at its launch."""
    _battery_failsafe_flies_home(planned, tmp_path, "px4", "SIM_BAT_MIN_PCT", 6.0, "AUTO.RTL")


def _battery_failsafe_flies_home(planned, tmp_path, firmware, param, value, mode) -> None:
    """Vehicle 1 of a real SITL fleet flown with --set-failsafes, its simulated battery
    let down 40 % into its route (``param`` = ``value`` on the judge's link): its
    failsafe flies ``mode``, said by the monitor and listed in the report, and lands
    it at its launch point, hidden and clear all along (the autopilot's own track)."""
    from test_end_to_end import assert_hidden_and_clear, assert_landed_at_launch, fly_case

    skip_unless_configured(firmware)
    case = planned(0, firmware)
    result = fly_case(case, firmware, tmp_path,
                      at=[(1, 0.4, lambda be: be.judges[1].set_param(param, value))])
    report, tracks = result["report"], result["tracks"]
    v1 = next(v for v in report["vehicles"] if v["sysid"] == 1)
    print("vehicle 1:", v1["state"], v1["failsafe_modes"],
          [e["event"] for e in report["events"] if e["sysid"] == 1 and "ailsafe" in e["event"]])
    assert [m["mode"] for m in v1["failsafe_modes"]] == [mode]
    assert v1["state"] == "landed"
    assert_hidden_and_clear(case, {1: tracks[1]})
    assert_landed_at_launch(case.ctx, tracks, [1], firmware)


#: wall s of the cut: several of the firmware's link timeouts of its own clock
#: (FS_GCS_TIMEOUT 5 s at 10x: 30 s; COM_DL_LOSS_T 10 s at 4x: 20 s), under the
#: 6 wall s after which the ground station calls a silence it did not expect a loss
CUT_WALL_S = {"ardupilot": 3.0, "px4": 5.0}


@pytest.mark.parametrize("firmware", REAL_BACKENDS)
def test_a_link_cut_mid_mission_flies_the_mission_on_with_set_failsafes(planned, tmp_path,
                                                                        firmware):
    """Real SITL started with a link-loss failsafe that flies a return in view
    (ArduPilot FS_GCS_ENABLE 1, PX4 NAV_DLL_ACT 2, no mission exception), flown
    with --set-failsafes: vehicle 1's link is cut both ways 30 % into its route,
    for longer than its firmware's link timeout. The autopilot's own word, on the
    judge's link: no change of mode in the cut, no failsafe mode ever; it flew on
    in the cut, reached every waypoint after it, landed at its base, hidden and
    clear all along (its own track); nobody lost."""
    from test_end_to_end import assert_hidden_and_clear, assert_landed_at_launch, fly_case
    from test_radio_shadows import LINK_TIMEOUT_S, UNSAFE_LINK

    skip_unless_configured(firmware)
    assert CUT_WALL_S[firmware] * SPEEDUP[firmware] > 1.5 * LINK_TIMEOUT_S[firmware]
    case = planned(0, firmware)
    cuts = []
    result = fly_case(case, firmware, tmp_path, radio=lambda lat, lon, alt: True,
                      params=UNSAFE_LINK[firmware],
                      at=[(1, 0.3, lambda be: cuts.append(_cut(be, 1, CUT_WALL_S[firmware])))])
    report, tracks, judge = result["report"], result["tracks"], result["judges"][1]
    assert len(cuts) == 1, "the link was never cut"
    start, end = cuts[0]
    autopilot = profile(firmware)
    failsafe = {autopilot.modes()[name] for name in autopilot.failsafe_modes
                if name != autopilot.hold_mode}
    print(f"\nlink cut [{firmware}]: {end - start:.1f} wall s from "
          f"{start - report['start_unix']:.1f} s; modes {judge.modes}")
    assert not [m for t, m in judge.modes if start <= t <= end + 1.0], judge.modes
    assert not [m for t, m in judge.modes if m in failsafe], judge.modes
    inside = [(lat, lon) for t, lat, lon, _ in judge.samples if start <= t <= end]
    assert len(inside) > 2 and distance_m(*inside[0], *inside[-1]) > 20.0, inside[:1]
    assert report["losses"] == [] and report["replans"] == []
    v1 = next(v for v in report["vehicles"] if v["sysid"] == 1)
    assert v1["state"] == "landed" and v1["failsafe_modes"] == []
    assert_hidden_and_clear(case, tracks)
    assert_landed_at_launch(case.ctx, tracks, list(tracks), firmware)
    set_1 = next(f["set"] for sysid, f in report["failsafes"].items() if int(sysid) == 1)
    changed = {c["parameter"] for c in set_1}
    assert ("FS_OPTIONS" if firmware == "ardupilot" else "COM_DLL_EXCEPT") in changed


def test_a_px4_return_along_a_mission_flown_from_the_air_flies_on_to_its_landing(tmp_path):
    """Real PX4 SITL (RTL_TYPE 4) in the air flies a mission that starts there, as a
    re-task or a later segment does, built by `missions.build` (DO_LAND_START first):
    asked to Return 3 items into 7, it flies on over the mission's next two
    waypoints and lands at home, by its own reported positions. Without the mark
    PX4 1.17 turned back (a one-off run of the same flight, 2026-12-07: never within
    146 m of those waypoints, back to the one before and straight home)."""
    import time

    from gcs import commands, mission_protocol
    from gcs.link import GroundLink
    from missions.build import MissionOptions, route_items
    from missions.check import unproven
    from missions.items import DO_LAND_START
    from planner.plan import GeoPoint, Plan, VehicleRoute, Waypoint

    skip_unless_configured("px4")
    home = (47.397742, 8.545594, 488.0)
    frame = LocalFrame(home[0], home[1])
    corners = [frame.to_geo(e, n) for n, e in
               ((0, 0), (150, 0), (250, 0), (250, 150), (100, 150), (0, 0))]
    waypoints = [Waypoint(lon, lat, home[2] + 30.0, 10.0 * i)
                 for i, (lat, lon) in enumerate(corners)]
    route = VehicleRoute(1, GeoPoint(home[1], home[0], home[2]), waypoints, 60.0, 80.0, 900.0)
    mission = route_items(route, "px4", MissionOptions(speed_mps=8.0), [2, 3, 4, 5],
                          takeoff=False, land=True, segment=1)
    assert mission.items[0].command == DO_LAND_START
    plan = Plan("rt", {}, "EPSG:4326", [], [route])
    be = start_backend("px4", plan, tmp_path / "sitl", 4.0,
                       params={"RTL_TYPE": 4, "NAV_DLL_ACT": 0})
    try:
        with GroundLink.open(be.urls(), expect=1, timeout_s=60) as link:
            v = link.vehicles[1]
            commands.wait_position(v, timeout_s=120)
            mission_protocol.upload(v, unproven(mission, "a square flown from the air"))
            commands.command_long(v, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan,
                                  math.nan, home[2] + 30.0)
            commands.arm(v, timeout_s=60)
            _until(lambda: (v.state.relative_alt or 0) > 27.0, 120, "no climb to 30 m")
            commands.set_mode(v, "AUTO.MISSION")
            _until(lambda: v.state.mission_seq == 3, 120, "never flying to item 3")
            commands.command_long(v, M.MAV_CMD_NAV_RETURN_TO_LAUNCH)
            asked = time.time()
            _until(lambda: v.state.landed and (v.state.relative_alt or 9) < 1.0, 180,
                   "never landed")
        samples = [s for s in be.judges[1].samples if s[0] >= asked]
    finally:
        be.stop()
    for lat, lon in corners[3:5]:
        closest = min(distance_m(lat, lon, a, b) for _, a, b, _ in samples)
        assert closest < 5.0, (lat, lon, closest)
    _, lat, lon, _ = samples[-1]
    assert distance_m(lat, lon, home[0], home[1]) < 3.0


def _cut(backend, sysid: int, seconds: float) -> tuple:
    """Cut ``sysid``'s link now for ``seconds`` wall s (the backend's `cut_link`: on
    real SITL, the relay's); (from, to) wall times."""
    import time

    start = time.time()
    backend.cut_link(sysid, seconds)
    return start, start + seconds


def _until(holds, seconds, said) -> None:
    import time

    deadline = time.monotonic() + seconds
    while not holds():
        assert time.monotonic() < deadline, said
        time.sleep(0.1)
