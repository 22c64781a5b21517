"""`gcs.contact`: a silence is the plan's when it starts where a radio shadow is
predicted, and is due back when that shadow ends at the pace the vehicle flies."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from gcs.contact import EARLY_LATE_S, WIDEN, Contact


def _flown(pace, lead_s=0.0):
    """A vehicle whose plan has a shadow from 300 to 420 s, flown at ``pace`` fleet s
    per monitor s, ``lead_s`` ahead of its plan, its waypoints every 60 fleet s."""
    c = Contact([[300.0, 420.0], [900.0, 960.0]], clock_rate=pace)
    for f in range(0, 300, 60):
        c.mark((f - lead_s) / pace, f)
    return c


@given(pace=st.floats(1.0, 100.0), lead=st.floats(-15.0, 15.0))
def test_a_silence_entering_a_predicted_shadow_is_due_back_at_its_end(pace, lead):
    c = _flown(pace, lead)
    heard = (300.0 - lead) / pace                 # last heard where the shadow starts
    q = c.expected(heard, lost_after_s=5.0)
    assert q is not None and q.window == (300.0, 420.0)
    back = (420.0 - lead) / pace                  # where the shadow ends, at that pace
    assert back <= q.due_s <= back + (EARLY_LATE_S + abs(lead)) / pace + 1e-9
    assert q.overdue_s == pytest.approx(q.due_s + 5.0 + WIDEN * (420.0 - 300.0) / pace)


def test_a_silence_where_contact_is_predicted_is_not_the_plans():
    c = _flown(10.0)
    assert c.expected(200.0 / 10.0, lost_after_s=5.0) is None          # 100 s before it
    assert c.expected(500.0 / 10.0, lost_after_s=5.0) is None          # after it


def test_the_pace_is_measured_on_the_plan_not_assumed():
    """A vehicle flying its plan at half the pace its clock runs (held, slowed) is due
    back twice as late."""
    c = Contact([[300.0, 420.0]], clock_rate=20.0)
    for f in range(0, 300, 60):
        c.mark(f / 10.0, f)                       # 10 fleet s per monitor s, not 20
    assert c.pace == pytest.approx(10.0)
    q = c.expected(30.0, lost_after_s=2.0)
    assert q.due_s == pytest.approx(30.0 + 120.0 / 10.0 + EARLY_LATE_S / 10.0)


def test_the_pace_is_read_on_the_vehicles_own_clock_not_when_its_reports_are_read():
    """A ground station reads a sped-up vehicle's reports in bursts (here five
    waypoints' reports within 0.6 s at 100x): on the monitor's clock that is 500
    fleet s per s. By its own clock it flies on schedule, and it is due back when
    the shadow ends at 100; where it was when last heard is read on its own clock
    too, whenever the monitor last read it."""
    c = Contact([[300.0, 420.0]], clock_rate=100.0)
    for f in range(0, 300, 60):
        c.mark(1.0 if f < 150 else 1.6, f, own_s=1000.0 + f)
    assert c.progress == pytest.approx(1.0) and c.pace == pytest.approx(100.0)
    q = c.expected(3.0, lost_after_s=2.0, own_s=1300.0)
    assert q.fleet_s == pytest.approx(300.0) and q.window == (300.0, 420.0)
    assert q.due_s == pytest.approx(3.0 + 120.0 / 100.0 + EARLY_LATE_S / 100.0)


def test_shadows_a_moment_of_contact_apart_are_one_silence():
    """A contact predicted for less than a vehicle may be early or late by is not
    counted on: a silence entering the first shadow is due back after the second."""
    c = Contact([[300.0, 420.0], [420.0 + EARLY_LATE_S - 1.0, 700.0], [800.0, 900.0]],
                clock_rate=10.0)
    assert c.windows == [(300.0, 700.0), (800.0, 900.0)]
    for f in range(0, 300, 60):
        c.mark(f / 10.0, f)
    assert c.expected(30.0, lost_after_s=2.0).window == (300.0, 700.0)


def test_a_new_mission_forgets_the_old_clock():
    c = _flown(10.0)
    c.restart([[50.0, 80.0]])
    assert c.fleet_time(100.0) is None and c.expected(100.0, 5.0) is None
    c.mark(100.0, 40.0)
    assert c.expected(100.0, 5.0).window == (50.0, 80.0)


def _monitored(**state):
    """A `gcs.monitor.Monitor` following one airborne vehicle on a two-waypoint route
    (60 s and 150 s on its clock, a shadow predicted from 70 to 100 s); ``state``:
    its link's state fields. Returns the monitor, the route and the vehicle."""
    from types import SimpleNamespace

    from gcs.monitor import FLYING, Monitor
    from planner.plan import GeoPoint, VehicleRoute, Waypoint

    link = SimpleNamespace(sysid=1, flavour="ardupilot", subscribe=lambda cb: (lambda: None),
                           state=SimpleNamespace(**{**dict(
                               lat=36.6, lon=-84.2, alt_amsl=700.0, relative_alt=60.0,
                               armed=True, mode="AUTO", mission_seq=1), **state}))
    waypoints = [Waypoint(-84.2, 36.6, 700.0, 60.0), Waypoint(-84.19, 36.6, 700.0, 150.0)]
    route = VehicleRoute(1, GeoPoint(-84.2, 36.6, 640.0), waypoints, 150.0, 150.0, 900.0,
                         takeoff_s=60.0, silences=[[70.0, 100.0]])
    monitor = Monitor()
    mission = SimpleNamespace(items=[], waypoint_of_item=[None, 0, 1])
    monitor.follow(link, 1, route, mission)
    v = monitor.vehicles[1]
    v.state, v.airborne = FLYING, True
    return monitor, route, v


def test_a_waypoint_reached_is_timed_on_the_vehicles_clock_now():
    """A reached report carries no time: it is timed by the vehicle's own clock carried
    on from its last report at its clock's rate, not by that report's (a fifth of a
    wall second older: 20 s of its clock at 100x, which read its progress over a few
    waypoints as twice the plan's)."""
    import time
    from types import SimpleNamespace

    boot_at = time.monotonic() - 0.2
    monitor, _, v = _monitored(boot_s=1000.0, boot_at=boot_at, clock_rate=100.0)
    before = time.monotonic()
    monitor._on(1, SimpleNamespace(get_type=lambda: "MISSION_ITEM_REACHED", seq=1))
    after = time.monotonic()
    _, fleet_s, own_s = v.contact._marks[-1]
    assert fleet_s == 60.0
    assert 1000.0 + 100.0 * (before - boot_at) <= own_s <= 1000.0 + 100.0 * (after - boot_at)


def test_a_vehicle_a_re_plan_holds_until_its_time_is_at_its_start_meanwhile():
    """A re-plan's clock starts as it sends the routes; a vehicle held in the air until
    its takeoff time (60 s here) is at 0 of its new route until then, so a shadow 70 s
    into the new route, entered as it flies on, is the plan's. Marked at its takeoff
    time instead, the monitor read it 60 s ahead of its plan: past that shadow, a
    loss (`Monitor.new_mission`)."""
    from types import SimpleNamespace

    monitor, route, v = _monitored()
    now = monitor.now()
    monitor.new_mission(1, route, SimpleNamespace(items=[]))
    assert v.contact.fleet_time(now + 75.0) == pytest.approx(75.0, abs=0.5)
    assert v.contact.expected(now + 75.0, lost_after_s=5.0).window == (70.0, 100.0)


def test_a_vehicle_down_at_its_base_is_on_no_clock_until_it_lifts_off():
    """A landed vehicle given a new route (a re-plan relaunching it, its next sortie)
    starts that route's clock at its liftoff: its wait at the base is not flight.
    Marked when the route was sent, 300 s in its base column's queue (2 wall s at
    150x) read as half its pace, and a shadow entered on time 120 s past its last
    waypoint reached was taken for a silence where contact is predicted: a loss
    (`Monitor.new_mission`, the demo at 150x)."""
    from dataclasses import replace
    from types import SimpleNamespace

    from gcs.monitor import LANDED
    from planner.plan import Waypoint

    monitor, route, v = _monitored()
    route = replace(route, takeoff_s=0.0, silences=[[300.0, 500.0]],
                    waypoints=[Waypoint(-84.2, 36.6, 700.0, t) for t in (60.0, 120.0, 180.0)])
    v.state = LANDED                    # airborne stays set until it is relaunched
    now = monitor.now()
    monitor.new_mission(1, route, SimpleNamespace(items=[]))
    assert v.contact.fleet_time(now + 100.0) is None
    for fleet_s in (0.0, 60.0, 120.0, 180.0):    # its liftoff 300 s later, its waypoints
        v.contact.mark(now + 300.0 + fleet_s, fleet_s)
    assert v.contact.expected(now + 600.0, lost_after_s=5.0).window == (300.0, 500.0)


def test_a_mark_not_timed_places_the_vehicle_but_is_not_measured_on():
    """A liftoff is seen at the HEARTBEAT that says the vehicle armed, up to a wall
    second late: at 100x one was marked 36 s of its clock late, 3.6 s before its
    first waypoint 39.4 s of its plan further on, and its pace read twice the
    plan's: due back from its shadow 5 s (500 s of flight) early, and declared
    overdue inside it (sitl_tests' simulated fleet with radio)."""
    c = Contact([[225.0, 1086.0]], clock_rate=100.0)
    c.mark(4.495, 83.0, own_s=311.06, timed=False)      # the liftoff, seen late
    c.mark(4.534, 122.4, own_s=314.66)                   # its first waypoint
    assert c.progress == 1.0
    assert c.fleet_time(5.0, own_s=360.0) == pytest.approx(122.4 + 45.34)


def test_waypoints_passed_unheard_are_not_timed_when_the_next_is_reported():
    """Back from a shadow, a vehicle reports the waypoint it reached; those before it,
    passed unheard, are counted then. Timed then too, a burst of three read its pace
    1.5 times the plan's over the marks after it (sitl_tests at 100x, three
    vehicles declared overdue in shadows they came out of on time)."""
    import time
    from dataclasses import replace
    from types import SimpleNamespace

    from planner.plan import Waypoint

    monitor, route, v = _monitored(clock_rate=100.0)
    times = [60.0 * i for i in range(1, 8)]
    v.route = replace(route, waypoints=[Waypoint(-84.2, 36.6, 700.0, t) for t in times])
    v.mission = SimpleNamespace(items=[], waypoint_of_item=[None, *range(len(times))])
    state = monitor.links[1].state
    for seq, own in [(1, 1000.0), (4, 1180.0), (5, 1240.0), (6, 1300.0), (7, 1360.0)]:
        state.boot_s, state.boot_at = own, time.monotonic()   # on its own clock, on plan
        monitor._on(1, SimpleNamespace(get_type=lambda: "MISSION_ITEM_REACHED", seq=seq))
    assert len(v.done) == 7
    assert v.contact.progress == pytest.approx(1.0, abs=0.01)


def _declared_lost(silence=True, on_pad=False, ground=None, **state):
    """`_monitored`'s vehicle declared lost (for a silence, or not), then heard again
    (a HEARTBEAT, then a position report after it); it flies toward item 2.
    ``ground``: the plan's terrain, (lat, lon) -> m AMSL."""
    import time
    from dataclasses import replace
    from types import SimpleNamespace

    monitor, route, v = _monitored(boot_s=1000.0, boot_at=time.monotonic(), clock_rate=1.0,
                                   **state)
    v.route = replace(route, waypoints=[replace(w, snapshot=True) for w in route.waypoints])
    link = monitor.links[1]
    link.silent_s = lambda: 0.0
    monitor._lose(v, "nothing heard for 6.0 s" if silence else "crashed: ...", silence=silence)
    monitor._on(1, SimpleNamespace(get_type=lambda: "HEARTBEAT", base_mode=0))
    link.state.mission_seq, link.state.boot_at = 2, time.monotonic() + 0.01
    monitor.on_pad = lambda sysid: on_pad
    monitor.ground = ground
    monitor.check_losses()
    return monitor, v


def test_a_vehicle_declared_lost_for_a_silence_and_heard_flying_is_taken_back():
    """Taken back flying, handed to the flight to re-plan, and credited with the
    waypoints it passed unheard (its MISSION_CURRENT is item 2: item 1, waypoint 0,
    was passed)."""
    from gcs.monitor import FLYING

    monitor, v = _declared_lost()
    assert v.state == FLYING and v.lost_at_s is None
    assert monitor.take_rejoined() == [1] and monitor.take_rejoined() == []
    assert [r["as"] for r in v.rejoins] == [FLYING]
    assert v.done == {0} and [s.waypoint for s in v.snapshots] == [0]
    assert any(e.get("rejoined") for e in monitor.events)


def test_a_vehicle_heard_again_on_the_ground_is_taken_back_only_at_its_base():
    """Disarmed on the ground when heard again: landed at its base (it flew its mission
    home unheard), taken back landed; anywhere else, it stays lost."""
    from gcs.monitor import LANDED, LOST

    monitor, v = _declared_lost(on_pad=True, armed=False, relative_alt=0.0)
    assert v.state == LANDED and v.landed_at_s is not None
    assert monitor.take_rejoined() == [1] and [r["as"] for r in v.rejoins] == [LANDED]
    monitor, v = _declared_lost(on_pad=False, armed=False, relative_alt=0.0)
    assert v.state == LOST and monitor.take_rejoined() == []
    assert any("down away from its bases" in e["event"] for e in monitor.events)


def test_a_vehicle_heard_again_is_judged_on_the_ground_by_the_terrain_not_by_home():
    """Height above home is no height above the ground: heard back at home height over
    a valley 80 m below its base, it is flying (a flight test's vehicle, flying its
    mission, was once left lost as 'down away from its bases'). Armed on its pad
    (touching down or lifting off), it is judged once it has done either."""
    from gcs.monitor import FLYING, LANDED, LOST

    monitor, v = _declared_lost(relative_alt=1.0, alt_amsl=700.0, ground=lambda la, lo: 620.0)
    assert v.state == FLYING and monitor.take_rejoined() == [1]
    monitor, v = _declared_lost(on_pad=True, relative_alt=0.0, alt_amsl=640.0,
                                ground=lambda la, lo: 639.5)
    assert v.state == LOST and v.silent_loss and monitor.take_rejoined() == []
    monitor.links[1].state.armed = False
    monitor.check_losses()
    assert v.state == LANDED and monitor.take_rejoined() == [1]


def test_a_vehicle_heard_again_down_at_its_base_after_a_silence_came_home_unheard():
    """Out of contact as planned, its link failsafe took it home unheard (its mode
    change lost with the link) and it disarmed at its base before its last item:
    heard again, it has landed, not crashed, and what it flew unheard is a problem of
    the flight (once judged 'crashed: touched the ground before its last item' in a
    loaded test run). Heard in the air after its silence, then down early: crashed."""
    from types import SimpleNamespace

    from gcs.monitor import LANDED, LOST

    for heard_flying, want in ((False, LANDED), (True, LOST)):
        monitor, _, v = _monitored(relative_alt=0.0, alt_amsl=640.0, mission_seq=3,
                                   battery_pct=None)
        v.mission = SimpleNamespace(final=True, items=[
            SimpleNamespace(seq=i, is_position=True, command=16) for i in range(6)])
        v.quiet = SimpleNamespace(heard_s=5.0, due_s=9.0, overdue_s=12.0, window=(70, 100))
        monitor._back_in_contact(v)
        if heard_flying:   # a position in the air after its silence
            monitor.links[1].state.relative_alt = 60.0
            monitor._on(1, SimpleNamespace(get_type=lambda: "GLOBAL_POSITION_INT", lat=366000000,
                                           lon=-842000000, alt=700000, relative_alt=60000,
                                           time_boot_ms=1000, vx=0, vy=0, vz=0, hdg=0))
            monitor.links[1].state.relative_alt = 0.0
        monitor._on(1, SimpleNamespace(get_type=lambda: "HEARTBEAT", base_mode=0))
        assert v.state == want, monitor.events[-1]
        assert len(v.down_unheard) == (0 if heard_flying else 1)


def test_a_crashed_vehicle_heard_again_is_not_taken_back():
    """Lost for a crash (not a silence): its HEARTBEAT from the ground is said, and it
    stays lost."""
    from gcs.monitor import LOST

    monitor, v = _declared_lost(silence=False)
    assert v.state == LOST and monitor.take_rejoined() == [] and not v.rejoins
    assert any("bring it home by hand" in e["event"] for e in monitor.events)


class _Quiet:
    """A monitor whose vehicle 1 was out of contact as planned from 10 to ``back_s``
    (heard again at ``back_s``, None: not yet), and whose vehicle 2 never was."""

    def __init__(self, back_s):
        from types import SimpleNamespace
        self.t = 12.0
        self.vehicles = {1: SimpleNamespace(state="flying", silences=[
                             {"from_s": 10.0, "to_s": back_s}]),
                         2: SimpleNamespace(state="flying", silences=[])}

    def now(self):
        return self.t

    def check_losses(self):
        return []

    def planned_at(self, sysid):
        return 500.0 if sysid == 1 and self.vehicles[1].silences[0]["to_s"] is None else None


@pytest.mark.parametrize("back_s", [None, 20.0])
def test_a_command_that_fails_in_a_predicted_shadow_restarts_the_re_plan(back_s):
    """A hold sent as the vehicle entered a predicted shadow gets no answer for all its
    tries (9 s); heard again just as they ran out, it is no longer out of contact.
    CI's re-plan then failed the whole flight ('no COMMAND_ACK for MAV_CMD_DO_SET_MODE
    after 6 tries'): now the re-tasking starts again, as for one still out of contact,
    and a vehicle that was heard all along and refused still fails it."""
    from gcs.retask import Retasker, RetaskError, _LostDuring

    monitor = _Quiet(back_s)
    retasker = Retasker.__new__(Retasker)
    retasker.monitor = monitor

    def hold(sysid):
        monitor.t = 21.0                  # the tries' time: heard again meanwhile
        raise TimeoutError("no COMMAND_ACK for MAV_CMD_DO_SET_MODE after 6 tries")

    with pytest.raises(_LostDuring) as quiet:
        retasker._step([1], hold)
    assert quiet.value.what == "out of contact" and quiet.value.sysids == [1]
    with pytest.raises(RetaskError, match="vehicle 2"):
        retasker._step([2], hold)
