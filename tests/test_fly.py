"""`gcs fly` pieces: vehicle assignment, loss detection on the wall clock, and a whole
dry run through the command line against the built-in simulator (its recorded
tracks are the reference). The plan (``plan_dir``) is tests/conftest.py's."""

import json
import time
from types import SimpleNamespace

import pytest

from common.errors import InputError
from gcs.cli import main
from gcs.fly import assign_vehicles
from gcs.monitor import HOLDING, LANDED, LOST, Monitor
from gcs.retask import _in_parallel
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

    assert _in_parallel(switch, [1], m) == {1: None}
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


def test_cli_dry_run_with_a_kill(plan_dir, tmp_path):
    out = tmp_path / "flight"
    started = time.monotonic()
    code = main(["fly", str(plan_dir), "--sim", "3", "--speedup", "100", "--kill", "2@item30",
                 "--lost-after", "2", "--sim-base-port", str(free_base_port(10, 3)), "-o", str(out)])
    wall = time.monotonic() - started
    report = json.loads((out / "flight.json").read_text())
    # a vehicle was lost: the flight did not go as planned, whatever the coverage
    assert code == 1
    assert report["outcome"]["lost"] == [2] and report["outcome"]["coverage_reached"]
    assert report["outcome"]["in_air"] == [] and not report["outcome"]["ok"]
    assert report["format"] == "gcs-flight/1"
    assert [x["sysid"] for x in report["losses"]] == [2]
    assert report["replans"] and report["replans"][0]["survivors"] == [1, 3]
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
