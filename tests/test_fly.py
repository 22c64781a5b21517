"""`gcs fly` pieces: vehicle assignment, loss detection on the wall clock, and a whole
dry run through the command line against the built-in simulator (its recorded
tracks are the reference). The plan (``plan_dir``) is tests/conftest.py's."""

import json
import time
from types import SimpleNamespace

import pytest

from common.errors import InputError
from gcs.cli import main
from gcs.flight import assign_vehicles
from gcs.monitor import FLYING, HOLDING, LANDED, LOST, Monitor
from gcs.retask import in_parallel
from gcs.sim import free_base_port, read_track, track_path
from planner.plan import Plan

pytestmark = pytest.mark.timeout(120)


def test_assign_in_order_and_by_option(plan_dir):
    plan = Plan.load(plan_dir)
    by_order = assign_vehicles(plan, [7, 3, 5], {})
    assert {s: r.id for s, r in by_order.items()} == {3: 1, 5: 2, 7: 3}
    chosen = assign_vehicles(plan, [1, 2, 3], {3: 1, 1: 3})
    assert {s: r.id for s, r in chosen.items()} == {3: 1, 1: 3}
    with pytest.raises(InputError, match="no vehicle 9"):
        assign_vehicles(plan, [1, 2, 3], {1: 9})
    with pytest.raises(InputError, match="only 2 answered"):
        assign_vehicles(plan, [1, 2], {})


@pytest.mark.parametrize("texts, problem", [(["1=2", "1=3"], "system id 1 given twice"),
                                             (["1:2"], "expected SYSID=VEHICLE")])
def test_cli_bad_assignments(plan_dir, tmp_path, capsys, texts, problem):
    args = [a for t in texts for a in ("--assign", t)]
    out = tmp_path / "flight"
    assert main(["fly", str(plan_dir), "--connect", "tcp:127.0.0.1:1", *args,
                 "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--assign" in err and problem in err
    assert not out.exists()


class _FakeLink:
    def __init__(self, sysid):
        self.sysid, self.flavour = sysid, "ardupilot"
        self.state = SimpleNamespace(relative_alt=50.0, last_heartbeat=time.monotonic(),
                                     mode="AUTO", mission_seq=1, battery_pct=90, armed=True)
        self.callbacks = []

    def subscribe(self, cb):
        self.callbacks.append(cb)
        return lambda: None

    def heartbeat_age(self):
        return time.monotonic() - self.state.last_heartbeat

    silent_s = heartbeat_age

    def beat(self, armed=True):
        self.state.last_heartbeat = time.monotonic()
        self.state.armed = armed
        self._send(SimpleNamespace(base_mode=128 if armed else 0, get_type=lambda: "HEARTBEAT"))

    def report(self, relative_alt):
        """A GLOBAL_POSITION_INT at ``relative_alt`` m above home."""
        self.state.relative_alt = relative_alt
        self._send(SimpleNamespace(relative_alt=relative_alt * 1e3, lat=0, lon=0, alt=0,
                                   get_type=lambda: "GLOBAL_POSITION_INT"))

    def _send(self, msg):
        for cb in self.callbacks:
            cb(msg)


def test_loss_after_silence_not_before(plan_dir):
    plan = Plan.load(plan_dir)
    m = Monitor(lost_after_s=0.5)
    links = [_FakeLink(1), _FakeLink(2)]
    for link, route in zip(links, plan.vehicles):
        m.follow(link, route.id, route, SimpleNamespace(items=[], waypoint_of_item=[]))
    end = time.monotonic() + 1.2
    while time.monotonic() < end:
        links[0].beat()
        if time.monotonic() < end - 0.9:       # vehicle 2: a 0.3 s gap, then silence
            links[1].beat()
        assert m.check_losses() in ([], [2])
        time.sleep(0.05)
    assert m.vehicles[2].state == LOST and m.vehicles[1].state != LOST
    # a short gap is no loss: vehicle 1 went 0.3 s without a heartbeat, still here
    time.sleep(0.3)
    links[0].beat()
    assert m.check_losses() == [] and m.vehicles[1].state != LOST
    # disarmed near the ground after flying: landed, not lost
    links[0].state.relative_alt = 0.5
    links[0].beat(armed=False)
    assert m.vehicles[1].state == LANDED
    # and stays landed: a re-task that held it as it touched down does not revive it
    m.set_state(1, HOLDING)
    assert m.vehicles[1].state == LANDED


def test_a_silent_vehicle_down_between_two_sorties_is_lost_not_waited_for(plan_dir):
    """Landed, it is done, unless it has a sortie still to fly (`Monitor.awaited`):
    then silence there is a loss (the flight once waited for its battery swap for
    ever); a vehicle down for good may fall silent."""
    plan = Plan.load(plan_dir)
    m = Monitor(lost_after_s=0.2)
    links = [_FakeLink(1), _FakeLink(2)]
    for link, route in zip(links, plan.vehicles):
        m.follow(link, route.id, route, SimpleNamespace(items=[], waypoint_of_item=[]))
        link.state.relative_alt = 0.5
        link.beat(armed=False)
    for link in links:                     # flew, then landed
        link.report(50.0)
        link.beat()
        link.report(0.5)
        link.beat(armed=False)
    assert m.vehicles[1].state == m.vehicles[2].state == LANDED
    m.awaited = lambda: {2}                 # vehicle 2 has a sortie to fly
    time.sleep(0.4)                         # both silent
    assert m.check_losses() == [2]
    assert m.vehicles[1].state == LANDED and m.vehicles[2].state == LOST


def test_a_loss_found_while_waiting_on_another_vehicle_is_not_forgotten(plan_dir):
    """Vehicle 2 falls silent while the flight waits on vehicle 1 (a segment switch):
    the loss found there is taken by the flight loop once, for one re-task."""
    plan = Plan.load(plan_dir)
    m = Monitor(lost_after_s=0.2)
    links = [_FakeLink(1), _FakeLink(2)]
    for link, route in zip(links, plan.vehicles):
        m.follow(link, route.id, route, SimpleNamespace(items=[], waypoint_of_item=[]))

    def switch(sysid):          # vehicle 1 answers for 0.5 s; vehicle 2 is silent
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            links[sysid - 1].beat()
            time.sleep(0.02)

    assert in_parallel(switch, [1], m) == {1: None}
    assert m.vehicles[2].state == LOST
    assert m.check_losses() == []            # found already, while waiting ...
    assert m.take_losses() == [2]            # ... and still to be re-tasked for
    assert m.take_losses() == []


def test_a_loss_is_found_on_time_while_the_flight_computes(plan_dir):
    """The flight's loop is busy (a re-plan takes seconds on a loaded machine) and
    calls nothing: the loss watch still finds the silent vehicle within its period
    of ``lost_after_s``, at that time, and keeps it for the loop."""
    plan = Plan.load(plan_dir)
    m = Monitor(lost_after_s=0.3)
    links = [_FakeLink(1), _FakeLink(2)]
    for link, route in zip(links, plan.vehicles):
        m.follow(link, route.id, route, SimpleNamespace(items=[], waypoint_of_item=[]))
    m.watch_losses(period_s=0.05)
    try:
        links[1].beat()
        silent_from = m.now()
        end = time.monotonic() + 1.5     # "computing": only vehicle 1 is heard
        while time.monotonic() < end and m.vehicles[2].state != LOST:
            links[0].beat()
            time.sleep(0.02)
        assert m.vehicles[2].state == LOST and m.vehicles[1].state != LOST
        assert m.vehicles[2].lost_at_s - silent_from <= 0.3 + 0.5
        assert m.take_losses() == [2]
    finally:
        m.close()


def test_landing_after_flying_only_below_home(plan_dir):
    """A route over ground lower than the launch point: every heartbeat may come
    while the vehicle is below home height (at 150x the climb above it lasts a
    fraction of a second). It still flew, so its touchdown is a landing (the demo
    once waited for vehicle 1 until it gave up)."""
    plan = Plan.load(plan_dir)
    m = Monitor(lost_after_s=5.0)
    link = _FakeLink(1)
    m.follow(link, plan.vehicles[0].id, plan.vehicles[0],
              SimpleNamespace(items=[], waypoint_of_item=[]))
    link.state.relative_alt = 0.0
    link.beat()                          # armed on the ground
    assert not m.vehicles[1].airborne
    link.report(25.0)                    # the climb, between two heartbeats
    for agl in (-40.0, -120.0, -60.0):
        link.report(agl)
        link.beat()
    assert m.vehicles[1].airborne
    link.report(-0.1)                    # back at home height, then disarmed
    link.beat(armed=False)
    assert m.vehicles[1].state == LANDED


def test_the_status_shows_no_item_of_the_mission_before(plan_dir):
    """A relaunched vehicle's MISSION_CURRENT of its old, longer mission, still on its
    way, is not shown against the new mission (the live map once said "item 70/49")."""
    plan = Plan.load(plan_dir)
    m = Monitor(lost_after_s=5.0)
    link = _FakeLink(1)
    m.follow(link, plan.vehicles[0].id, plan.vehicles[0],
             SimpleNamespace(items=[None] * 49, waypoint_of_item=[]))
    link.state.mission_seq = 70
    assert m.status_rows()[0]["item"] == "-/49"
    link.state.mission_seq = 12
    assert m.status_rows()[0]["item"] == "12/49"


def test_cli_dry_run_with_a_kill(plan_dir, tmp_path):
    out = tmp_path / "flight"
    started = time.monotonic()
    code = main(["fly", str(plan_dir), "--sim", "3", "--speedup", "100", "--kill", "2@item30",
                 "--lost-after", "2", "--sim-base-port", str(free_base_port(10, 3)),
                 "-o", str(out)])
    wall = time.monotonic() - started
    report = json.loads((out / "flight.json").read_text())
    # a vehicle was lost: the flight did not go as planned, whatever the coverage
    assert code == 1
    assert report["outcome"]["lost"] == [2] and report["outcome"]["coverage_reached"]
    assert report["outcome"]["in_air"] == [] and not report["outcome"]["ok"]
    assert report["format"] == "gcs-flight/1"
    assert [x["sysid"] for x in report["losses"]] == [2]
    # each survivor re-tasked, or left to fly its plan where the ground station did
    # not hear it at that moment (on a loaded machine at 100x: `gcs.flight.left_out`)
    first = report["replans"][0]
    assert sorted(first["survivors"] + first["left_out"]) == [1, 3] and first["survivors"]
    assert (out / "flight.png").stat().st_size > 10000
    assert all((out / f"vehicle_{s}.tlog").stat().st_size > 1000 for s in (1, 2, 3))
    cov = report["coverage"]["survivors"]
    assert cov["k_covered"] == report["coverage"]["coverable_targets"]
    for sysid in (1, 3):       # the simulator's own record: landed where it took off
        track = read_track(track_path(out / "tracks", sysid))
        assert any(e["event"] == "landed" for e in track.events)
        assert abs(track.alt[-1] - track.home[2]) < 1.0
    assert read_track(track_path(out / "tracks", 2)).killed_at is not None
    assert wall < 60


def test_an_item_reached_means_every_waypoint_before_it_was(plan_dir):
    """PX4 reports a waypoint followed by its camera command with the camera's
    number, and only the latest of several items reached between two reports:
    every waypoint up to the item reported counts as reached, snapshots with it."""
    plan = Plan.load(plan_dir)
    route = plan.vehicles[0]
    m = Monitor(lost_after_s=5.0)
    link = _FakeLink(1)
    # takeoff, speed, then waypoints 0..5 each followed by a camera command
    of_item = [None, None]
    for i in range(6):
        of_item += [i, None]
    m.follow(link, route.id, route, SimpleNamespace(items=[], waypoint_of_item=of_item))

    def reached(seq):
        link._send(SimpleNamespace(seq=seq, get_type=lambda: "MISSION_ITEM_REACHED"))

    reached(3)                           # the camera after waypoint 0
    assert m.vehicles[1].done == {0}
    reached(9)                           # 5 and 7 never reported: waypoints 1-3 reached
    assert m.vehicles[1].done == {0, 1, 2, 3}
    snapshots = [i for i in range(4) if route.waypoints[i].snapshot]
    assert [s.waypoint for s in m.vehicles[1].snapshots] == snapshots
    reached(9)                           # repeated reports change nothing
    assert len(m.vehicles[1].snapshots) == len(snapshots)


def test_a_failed_start_brings_the_vehicles_in_the_air_home(planned, tmp_path):
    """The last vehicle due out refuses to arm until its start gives up: the flight
    fails, and the vehicles already up are not left on their missions with
    nobody watching: they are brought home by hidden paths and watched down.
    Judged by the simulator's own tracks: each landed where it took off, long
    before its mission would have ended, and the one refused never armed."""
    from gcs.flight import Flight, FlightError, FlyOptions
    from gcs.sim import fleet_for_plan, radio_for_plan, terrain_ground

    plan = planned.plan
    last = max(plan.vehicles, key=lambda v: v.takeoff_s).id
    # over the plan's relief: its routes go below the base, where a flat ground at the
    # base's height would be touched (at the time the start gives up, once the
    # others have left the base column one at a time, they fly there)
    fleet = fleet_for_plan(plan, speedup=20.0, base_port=free_base_port(10, 3),
                           track_dir=tmp_path / "tracks",
                           terrain=terrain_ground(planned.terrain),
                           radio=radio_for_plan(plan, planned.terrain))
    fleet.refuse_arm(last)
    try:
        with pytest.raises(FlightError, match="start failed"):
            Flight(planned.dir, fleet.urls(), FlyOptions(
                output=tmp_path / "f", lost_after_s=3.0, plot=False, ready_timeout_s=4.0,
                set_failsafes=True)).run()
    finally:
        fleet.stop()
    report = json.loads((tmp_path / "f" / "flight.json").read_text())
    assert report["outcome"]["in_air"] == [] and not report["outcome"]["ok"]
    assert any(e["event"].startswith("the flight failed: the vehicles in the air are "
                                      "brought home") for e in report["events"])
    assert report["replans"] and report["replans"][-1]["survivors"]
    for v in plan.vehicles:
        track = read_track(track_path(tmp_path / "tracks", v.id))
        events = [e["event"] for e in track.events]
        if v.id == last:
            assert "armed" not in events
            continue
        assert "landed" in events and abs(track.alt[-1] - track.home[2]) < 1.0
        if v.id in report["replans"][0]["left_out"]:
            # in a radio shadow as it failed: it flew its plan until heard, and was
            # then brought home with the others (`gcs.flight.left_out`)
            assert any(v.id in r["survivors"] for r in report["replans"][1:])
            continue
        # down before its mission would have ended, on its own clock from its takeoff
        took_off = next(e["t"] for e in track.events if e["event"] == "takeoff")
        assert track.t[-1] < took_off + v.mission_time_s - v.takeoff_s


LAT0, LON0, M_PER_DEG = 36.6, -84.2, 111_320.0


def _watched(holds=(), waiting=None):
    """A vehicle as the battery watch (`Batteries.left_s`) sees it, on a straight route
    north at 10 m/s, a waypoint every 1000 m and 100 s apart (``holds``: {waypoint:
    s}, the later ones that much later), standing at the first on its own clock
    1000 s; ``waiting``: a re-plan's wait (s). Returns the watch, the vehicle and
    its reported state."""
    from gcs.flight.batteries import Batteries
    from planner.plan import VehicleRoute, Waypoint
    from planner.travel import TravelParams

    holds, t, waypoints = dict(holds), 0.0, []
    for k in range(5):
        waypoints.append(Waypoint(LON0, LAT0 + k * 1000.0 / M_PER_DEG, 700.0, t,
                                  snapshot=k < 3, hold_s=holds.get(k, 0.0)))
        t += holds.get(k, 0.0) + 100.0
    route = VehicleRoute(1, None, waypoints, coverage_time_s=waypoints[2].t_s,
                         mission_time_s=waypoints[-1].t_s + 60.0, path_length_m=4000.0)
    state = SimpleNamespace(lat=LAT0, lon=LON0, alt_amsl=700.0, battery_pct=50,
                            mission_seq=None)
    vehicle = SimpleNamespace(route=route, done={0}, track=[(0, LON0, LAT0, 700.0, 1000.0)],
                              state=FLYING, mission=None)
    travel = TravelParams(speed_mps=10.0, climb_mps=3.0, descent_mps=2.0)
    flight = SimpleNamespace(monitor=SimpleNamespace(vehicles={1: vehicle}, links={
        1: SimpleNamespace(state=state)}, now=lambda: 100.0), ctx=SimpleNamespace(
            scenario=SimpleNamespace(travel_params=lambda: travel)))
    return Batteries(flight, lambda s: waiting), vehicle, state


def _stand(vehicle, state, north_m, own_s, t_s=0.0) -> None:
    """The vehicle reports itself ``north_m`` along its route at its own clock ``own_s``."""
    state.lat = LAT0 + north_m / M_PER_DEG
    vehicle.track.append((t_s, LON0, state.lat, 700.0, own_s))


def test_the_battery_watch_counts_the_rest_from_where_it_is_at_its_pace():
    """`Batteries.left_s`: the rest of a sortie from where the vehicle is (to its next
    waypoint at the plan's speed, then the route as planned), stretched by how
    much slower than planned it has made its way along the route on its own
    clock, never shrunk; on its way home once it has nothing left to photograph
    (the watch then only says what it will land on); nothing past the end. And a
    re-plan counts the battery of one that slow as that much shorter
    (`Retasker._flown_s`). Reference: the route's own times, by hand."""
    from gcs.flight.batteries import WATCH_AFTER_S
    from gcs.flight.state import homebound
    from gcs.retask import Retasker

    fake, vehicle, state = _watched()
    assert fake.left_s(1) == pytest.approx(460.0 - 0.0, abs=1.0)   # first look
    # 2 * WATCH_AFTER_S later on its own clock, where the plan is WATCH_AFTER_S after
    # the start: it makes half the planned pace
    along = WATCH_AFTER_S * 10.0
    _stand(vehicle, state, along, 1000.0 + 2 * WATCH_AFTER_S)
    vehicle.done = {k for k in range(5) if 1000.0 * k <= along}
    left = fake.left_s(1)
    assert fake._pace[1] == pytest.approx(2.0, rel=0.01)
    assert fake.paces == {1: {1: pytest.approx(2.0, rel=0.01)}}   # flight.json's, by sortie
    assert left == pytest.approx(2.0 * (460.0 - WATCH_AFTER_S), rel=0.01)
    assert not homebound(fake.state.monitor, 1)
    vehicle.done = {0, 1, 2}           # its last snapshot taken: on its way home, 1800 m
    assert homebound(fake.state.monitor, 1)  # from waypoint 3 (planned at 300 s), at half pace
    assert fake.left_s(1) == pytest.approx(2.0 * (460.0 - (300.0 - 180.0)), rel=0.01)
    vehicle.done = {0, 1, 2, 3, 4}
    assert fake.left_s(1) is None
    # held by a re-plan until its time: its pace is timed afresh from where it flies
    # on (one so held read 6.8 times slower)
    vehicle.done, fake.waiting_s = {0, 1, 2}, lambda s: 30.0
    assert fake.left_s(1) == pytest.approx(460.0 - (300.0 - 180.0), rel=0.01)
    assert 1 not in fake._pace and fake._route_seen[1][1] == 1000.0 + 2 * WATCH_AFTER_S
    # held by the separation guard 50 s, 1800 m along: timed afresh from where it flies
    # on, at the planned pace (with the holds' spans taken out of its time instead, a
    # simulated vehicle held at 100 x was said to need 221 % of a battery to get home)
    fake.waiting_s, vehicle.state, vehicle.done = (lambda s: None), HOLDING, {0, 1}
    _stand(vehicle, state, 1800.0, 1000.0 + 2 * WATCH_AFTER_S + 50.0)
    assert fake.left_s(1) == pytest.approx(460.0 - 180.0, rel=0.01)
    assert 1 not in fake._pace
    # flown on, its resume reaching it 20 s later (a loop of a loaded ground station at
    # 100 x): still standing, then as planned; timed from where it moved on, pace 1.0
    # (timed from the resume's sending: 1.17)
    vehicle.state = FLYING
    _stand(vehicle, state, 1800.0, 1000.0 + 2 * WATCH_AFTER_S + 70.0)
    assert fake.left_s(1) == pytest.approx(460.0 - 180.0, rel=0.01)
    vehicle.done = {0, 1, 2}
    _stand(vehicle, state, 1800.0 + 10.0 * WATCH_AFTER_S, 1000.0 + 3 * WATCH_AFTER_S + 70.0)
    assert fake.left_s(1) == pytest.approx(460.0 - 180.0 - WATCH_AFTER_S, rel=0.01)
    assert fake._pace[1] == pytest.approx(1.0, rel=0.01)
    # the re-plan: half its battery left, at half the pace: a quarter of the flight
    ctx = SimpleNamespace(scenario=SimpleNamespace(endurance_min=12.0))
    monitor = SimpleNamespace(links={1: SimpleNamespace(state=state)})
    for pace, flown in ((None, 360.0), ({1: 2.0}, 540.0)):
        retasker = SimpleNamespace(ctx=ctx, monitor=monitor, pace=pace or {})
        assert Retasker._flown_s(retasker, 1) == pytest.approx(flown)


def test_a_vehicle_heard_again_after_a_silence_is_where_its_mission_is():
    """Its reached reports lost in a silence (a radio shadow), a vehicle is flying to
    the waypoint its mission's current item (MISSION_CURRENT, streamed) is, not to
    the one after the last reached report: 2500 m along, flying to waypoint 3 (3000
    m, planned at 300 s), 210 s of its sortie are left. From its last reached report
    (waypoint 0) it was read as flying back to waypoint 1, 510 s left, and brought
    home early (a 12-minute-battery flight at 100x with radio). Reference: the
    route's own times, by hand."""
    fake, vehicle, state = _watched()
    vehicle.mission = SimpleNamespace(waypoint_of_item=[None, 0, 1, None, 2, 3, 4])
    _stand(vehicle, state, 2500.0, 1250.0)
    assert fake.left_s(1) == pytest.approx(460.0 - (100.0 - 150.0), abs=1.0)   # no news
    state.mission_seq = 5                       # flying to item 5: waypoint 3
    assert fake.left_s(1) == pytest.approx(460.0 - (300.0 - 50.0), abs=1.0)
    state.mission_seq = 2                       # behind what it reached: that stands
    vehicle.done = {0, 1, 2}
    assert fake.left_s(1) == pytest.approx(460.0 - (300.0 - 50.0), abs=1.0)


@pytest.mark.parametrize("reached", ["on arrival", "after the hold"])
def test_a_vehicle_standing_out_its_planned_hold_is_on_time(reached):
    """A hold the plan gives a waypoint (a separation wait: 63 s on a sortie of the
    shared plan) is spent as planned: `Batteries.left_s` counts the time the vehicle
    has stood there, on its own clock, up to the hold, and its pace stays the
    plan's. ArduPilot says it reached the waypoint on arrival, PX4 (and the
    simulator) after the hold. Read as flying to the next waypoint, a vehicle of the
    shared plan flying as planned was timed 1.34 times slower, and the battery
    watch brought it home early. Reference: the route's own times, by hand."""
    fake, vehicle, state = _watched(holds={2: 60.0})     # waypoint 2: 200 s to 260 s
    assert vehicle.route.mission_time_s == 520.0
    assert fake.left_s(1) == pytest.approx(520.0, abs=1.0)   # first look
    vehicle.done = {0, 1, 2} if reached == "on arrival" else {0, 1}
    for stood in (0.0, 50.0, 60.0):     # arrived on time, at 1200 s on its own clock
        _stand(vehicle, state, 2000.0, 1200.0 + stood)
        assert fake.left_s(1) == pytest.approx(520.0 - 200.0 - stood, abs=1.0)
        assert fake._pace[1] == pytest.approx(1.0, abs=0.01)
    vehicle.done = {0, 1, 2}            # left on time: 100 m on to waypoint 3 at 1270 s
    _stand(vehicle, state, 2100.0, 1270.0)
    assert fake.left_s(1) == pytest.approx(520.0 - 270.0, abs=1.0)
    assert fake._pace[1] == pytest.approx(1.0, abs=0.01)


@pytest.mark.parametrize("firmware", ["ardupilot", "px4"])
def test_a_vehicle_slower_than_the_plan_is_told_before_it_flies(planned, tmp_path, firmware):
    """The simulated autopilots answer their mission rate limits as each firmware
    names them (ArduPilot WPNAV_SPEED_DN in cm/s, PX4 MPC_Z_V_AUTO_DN in m/s) and
    fly by them. At a descent of 1 m/s the plan's faster descent is said, one line
    per vehicle, naming the parameter and both rates; vehicles at the plan's rates
    hear nothing, but that PX4 stops at each waypoint of a plan made for ArduPilot
    (what it costs there: `planner.rates.waypoint_stop_s`). No radio: the vehicles
    never leave their bases, where an antenna stands."""
    from gcs.flight import Flight, FlyOptions
    from gcs.sim import fleet_for_plan
    from gcs.sim.physics import Limits
    from planner.rates import waypoint_stop_s

    params = planned.plan.params
    planned_rate = params["descent_mps"]
    said = {}
    for descent in (1.0, planned_rate):
        limits = Limits(climb_mps=params["climb_mps"], descent_mps=descent,
                        takeoff_mps=params["takeoff_mps"], land_mps=params["land_mps"])
        fleet = fleet_for_plan(planned.plan, speedup=20.0, base_port=free_base_port(10, 3),
                               firmware=firmware, limits=limits)
        flight = Flight(planned.dir, fleet.urls(), FlyOptions(output=tmp_path / str(descent),
                                                              plot=False, set_failsafes=True))
        try:
            flight.prepare()
            flight.connect()
            flight.check_rates()
        finally:
            flight.link.close()
            fleet.stop()
        said[descent] = [e for e in flight.monitor.events if "slower than planned" in e["event"]]
    name = {"ardupilot": "WPNAV_SPEED_DN = 100 (1 m/s", "px4": "MPC_Z_V_AUTO_DN = 1 (1 m/s"}
    assert planned_rate > 1.0
    assert sorted(e["sysid"] for e in said[1.0]) == sorted(flight.monitor.vehicles)
    assert all(name[firmware] in e["event"] and f"descent_mps {planned_rate:g}" in e["event"]
               for e in said[1.0])
    stops = [e for e in said[planned_rate] if "(px4 stops at each)" in e["event"]]
    assert params.get("firmware", "ardupilot") == "ardupilot"
    assert said[planned_rate] == stops and len(stops) == (len(said[1.0]) if firmware == "px4"
                                                          else 0)
    px4_stop = waypoint_stop_s(params["speed_mps"], params["accel_mps2"], 4.0)
    assert all(f"each waypoint {px4_stop:.1f} s (px4 stops at each)" in e["event"]
               for e in stops)


def test_the_plan_summary_says_the_rates_it_assumed(planned):
    """`gcs plan` says the vertical rates every time of the plan assumes, and
    whether they are its firmware's defaults (the shared plan climbs and descends
    faster than ArduPilot's: the operator must set them)."""
    from dataclasses import replace

    from gcs.cli.views import rates_line
    from planner.rates import FIRMWARE_RATES

    line = rates_line(planned.plan)
    assert line.startswith("rates: climb 3, descent 2, takeoff 2.5, landing 0.5 m/s") and \
        "not all ardupilot's defaults" in line
    for firmware, rates in FIRMWARE_RATES.items():
        params = dict(planned.plan.params, firmware=firmware, **{
            n: getattr(rates, n) for n in ("climb_mps", "descent_mps", "takeoff_mps", "land_mps")})
        line = rates_line(replace(planned.plan, params=params))
        assert f"climb {rates.climb_mps:g}, descent {rates.descent_mps:g}" in line and \
            line.endswith(f"{firmware}'s defaults (gcs fly says where a vehicle is set slower)")


def test_takeoffs_are_timed_on_the_liftoff_the_vehicle_reports():
    """`Departures`: the fleet clock reads the first vehicle's planned takeoff time
    when it is seen leaving the ground, not when its takeoff was commanded (arming
    and spool-up come between: on real ArduPilot SITL a liftoff came 7 s of flight
    after the one before instead of 15); one seen leaving 12 s after its planned
    time puts the takeoffs after it 12 s later, and says so."""
    from gcs.flight.departures import Departure, Departures

    now = {"t": 0.0}
    vehicles = {s: SimpleNamespace(state=FLYING, lifted_at_s=None,
                                   route=SimpleNamespace(takeoff_s=15.0 * (s - 1)))
                for s in (1, 2, 3)}
    events = []
    monitor = SimpleNamespace(vehicles=vehicles, now=lambda: now["t"],
                              event=lambda s, text, **kw: events.append((s, text)))

    class Clock:                                    # the fleet clock at 10x
        t = None
        started = property(lambda self: self.t is not None)

        def rate(self):
            return 10.0

        def start(self, at):
            self.t, self.wall = at, now["t"]

        def now(self):
            return None if self.t is None else self.t + 10.0 * (now["t"] - self.wall)
    state = SimpleNamespace(monitor=monitor, clock=Clock())
    d = Departures(state)
    d._launched = {1: (0.0, 0.0, 0.0)}              # commanded at 0, due at 0
    d.pending = {2: Departure(15.0, "launch", None), 3: Departure(30.0, "launch", None)}
    now["t"] = 1.0                                  # 10 s of flight later: not up yet
    d._anchor_clock()
    assert not state.clock.started
    vehicles[1].lifted_at_s, now["t"] = 1.2, 1.5    # up 12 s after the command
    d._anchor_clock()
    assert state.clock.now() == pytest.approx(3.0)  # up 0.3 s ago, at 10x
    assert d.latency_s == pytest.approx(12.0)
    assert [p.due for p in d.pending.values()] == [15.0, 30.0]     # the first sets t = 0
    del d.pending[2]
    d._launched = {2: (now["t"], 15.0, 15.0)}
    vehicles[2].lifted_at_s, now["t"] = 3.9, 4.0    # up at fleet 27 s, due at 15 s
    d._anchor_clock()
    assert d.pending[3].due == pytest.approx(42.0)
    assert any("12 s after its planned takeoff" in text for _, text in events)
    # 24 s from its command: launches are still begun as early as the quickest took
    # (begun earlier by a slow one, the next quick one lifts off before its time)
    assert d.latency_s == pytest.approx(12.0)
    # a next sortie scheduled from now on is as late as they are
    d.launch(1, 600.0, None)
    assert (d.pending[1].due, d.pending[1].planned) == (pytest.approx(612.0), 600.0)


def test_takeoffs_keep_the_plans_order_however_late_the_vehicles_are_ready():
    """A vehicle back from its battery swap, its next sortie past due, does not take
    off before a takeoff the plan has earlier: another's next sortie, that vehicle
    still in the air or down for its swap, or a pending takeoff (three vehicles late
    from their swaps once went in the order they were ready, and the guard held two
    for each other until their batteries ran out). A lost vehicle is not waited for."""
    from gcs.flight.departures import Departures

    part = lambda t: SimpleNamespace(takeoff_s=t, launch=None)    # noqa: E731
    vehicles = {s: SimpleNamespace(state=LANDED, lifted_at_s=None) for s in (1, 2, 3)}
    events = []
    monitor = SimpleNamespace(vehicles=vehicles, now=lambda: 0.0,
                              event=lambda s, text, **kw: events.append((s, text)))
    clock = SimpleNamespace(now=lambda: 5000.0, rate=lambda: 1.0, started=True)
    later = {1: [(0.0, part(784.0))], 2: [], 3: [(0.0, part(1005.0))]}
    state = SimpleNamespace(monitor=monitor, clock=clock, later=later,
                            separation_m=30.0, plan=SimpleNamespace(vehicles=[]))
    d = Departures(state)
    sent = []
    d._send = lambda sysid, dep: sent.append(sysid)
    d.launch(2, 1210.0, part(1210.0))          # 2 ready first: 1 and 3 go before it
    d.due()
    assert sent == [] and events[-1] == (2, "takeoff waits: vehicle 1 takes off before "
                                            "it in the plan")
    later[1].clear()
    d.launch(1, 784.0, part(784.0))
    d.due()
    assert sent == [1]
    d._launched[1] = (0.0, 784.0, 784.0)       # sent, not seen up yet: 3 still waits
    later[3].clear()
    d.launch(3, 1005.0, part(1005.0))
    d.due()
    assert sent == [1] and 2 in d.pending and 3 in d.pending
    vehicles[1].state = FLYING
    del d._launched[1]
    vehicles[3].state = LOST
    d.due()
    assert sent == [1, 2]
    # one whose swap the operator leaves unconfirmed past its time is not waited for
    vehicles[3].state, later[1] = LANDED, [(0.0, part(4000.0))]
    d.launch(3, 4500.0, part(4500.0))
    d.due()
    assert sent == [1, 2]
    d.awaits_operator = lambda sysid: sysid == 1
    d.due()
    assert sent == [1, 2, 3]


@pytest.mark.parametrize("text,failsafe", [
    ("Battery 1 is low 10.50V used 2200 mAh", True),          # ArduPilot AP_BattMonitor
    ("Battery 1 is critical 9.90V used 2600 mAh", True),
    ("Battery 1 is low 20%", True),                           # the built-in simulator
    ("Low battery level! Return advised", True),              # PX4 commander
    ("Critical battery level! Land now!", True),
    ("Emergency battery level! Land immediately", True),
    ("PreArm: Battery 1 below minimum arming voltage", False),
    ("battery swap confirmed by the operator", False),
])
def test_battery_failsafe_announcements_are_told_apart(text, failsafe):
    from gcs.flight.batteries import BATTERY_FAILSAFE_TEXT

    assert bool(BATTERY_FAILSAFE_TEXT.search(text)) == failsafe
