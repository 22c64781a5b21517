"""The separation guard on scripted telemetry: it holds the vehicle of lower
priority before a predicted loss of separation, the other too if the pair still
closes, and lets each fly on once clear; judged by where the scripted vehicles
would have been, stepped on a clock of our own."""

import math
import time
from types import SimpleNamespace

import numpy as np
import pytest

from gcs.flight.report import outcome
from gcs.guard import GuardFleet, SeparationGuard, closest_ahead
from gcs.monitor import LANDED, Monitor
from planner.plan import GeoPoint, VehicleRoute, Waypoint
from planner.travel import TravelParams

LAT0, LON0, ALT = 36.5, -84.2, 500.0
M_PER_DEG = 6371008.8 * math.pi / 180


class Scripted:
    """A vehicle whose telemetry follows a straight motion, unless held."""

    def __init__(self, sysid, start_xy, velocity, route_to=None):
        self.sysid, self.flavour = sysid, "ardupilot"
        self.p = np.array([*start_xy, ALT], float)
        self.v = np.array([*velocity, 0.0], float)
        self.held = False
        self.state = SimpleNamespace(lat=None, lon=None, alt_amsl=None, velocity=None,
                                     position_at=None, relative_alt=50.0, armed=True,
                                     last_heartbeat=time.monotonic(), mode="AUTO",
                                     mission_seq=1, battery_pct=90)
        self.route = route_to
        self.report()

    def subscribe(self, cb):
        return lambda: None

    def heartbeat_age(self):
        return 0.0

    silent_s = heartbeat_age

    def advance(self, dt):
        if not self.held:
            self.p = self.p + self.v * dt
        self.report()

    def report(self):
        k = math.cos(math.radians(LAT0))
        s = self.state
        s.lat, s.lon, s.alt_amsl = (LAT0 + self.p[1] / M_PER_DEG,
                                    LON0 + self.p[0] / (M_PER_DEG * k), self.p[2])
        v = np.zeros(3) if self.held else self.v
        s.velocity = (v[1], v[0], v[2])           # north, east, up
        s.position_at = time.monotonic()


def _lonlat(x, y):
    """(lon, lat) of local metres east and north of (LON0, LAT0)."""
    return LON0 + x / (M_PER_DEG * math.cos(math.radians(LAT0))), LAT0 + y / M_PER_DEG


def _route(x, y):
    w = Waypoint(*_lonlat(x, y), ALT, 0.0)
    return VehicleRoute(1, None, [w], 0.0, 0.0, 0.0)


def _guard(vehicles, priority, short=(), waiting=lambda s: None, bases=()):
    monitor = Monitor(lost_after_s=5.0)
    for v in vehicles:
        monitor.follow(v, v.sysid, v.route or _route(*v.p[:2]), None)
    clock = SimpleNamespace(rate=lambda: 1.0)
    guard = SeparationGuard(monitor, 30.0, priority, clock, _Scripted(vehicles, short, waiting),
                            travel=TravelParams(speed_mps=12.0), bases=bases)
    return monitor, guard


class _Scripted(GuardFleet):
    """The scripted vehicles as the guard sees a flight."""

    def __init__(self, vehicles, short, waiting):
        self.vehicles, self._short, self.waiting = vehicles, short, waiting

    def airborne(self):
        return [v.sysid for v in self.vehicles]

    def hold(self, sysid):
        _set(self.vehicles, sysid, True)

    def resume(self, sysid):
        _set(self.vehicles, sysid, False)

    def short(self, sysid):
        return sysid in self._short


def _set(vehicles, sysid, held):
    next(v for v in vehicles if v.sysid == sysid).held = held


def _run(vehicles, guard, seconds, dt=0.25, deadlocks=None):
    """Step the scripted world and the guard; the least distance seen (and in
    ``deadlocks`` the guard's `deadlocked` after each step where it had one)."""
    least = math.inf
    for _ in range(int(seconds / dt)):
        for v in vehicles:
            v.advance(dt)
        guard.step()
        if guard.deadlocked and deadlocks is not None:
            deadlocks.append(guard.deadlocked)
        time.sleep(0.002)                 # the guard's commands run in threads
        ps = [v.p for v in vehicles]
        least = min([least] + [float(np.linalg.norm(a - b)) for i, a in enumerate(ps)
                               for b in ps[i + 1:]])
    return least


def test_closest_ahead_of_two_straight_motions():
    d, u = closest_ahead(np.array([100.0, 10.0, 0.0]), np.array([-10.0, 0.0, 0.0]), 30.0)
    assert d == pytest.approx(10.0) and u == pytest.approx(10.0)
    d, u = closest_ahead(np.array([100.0, 10.0, 0.0]), np.array([-10.0, 0.0, 0.0]), 5.0)
    assert d == pytest.approx(math.hypot(50.0, 10.0)) and u == pytest.approx(5.0)


def test_crossing_paths_the_lower_priority_waits_then_flies_on():
    """1 flies east, 2 flies north, both reaching the crossing at t = 20 s."""
    one = Scripted(1, (-240.0, 0.0), (12.0, 0.0), _route(400, 0))
    two = Scripted(2, (0.0, -240.0), (0.0, 12.0), _route(0, 400))
    monitor, guard = _guard([one, two], {1: 1, 2: 2})
    deadlocks = []
    least = _run([one, two], guard, 60.0, deadlocks=deadlocks)
    assert deadlocks == []                  # 2 waits on 1, which flies on
    holds = [a for a in guard.actions if a["action"] == "hold"]
    assert [a["sysid"] for a in holds] == [2]                  # right of way: vehicle 1
    assert holds[0]["predicted_m"] < 30.0
    assert least >= 30.0                                       # never closer than it
    assert [a["action"] for a in guard.actions] == ["hold", "resume"]
    assert not two.held and two.p[1] > 100.0                   # and it flew on
    report = guard.report()
    assert report["pairs"][0]["vehicles"] == [1, 2]
    assert report["closest_m"] == pytest.approx(least, abs=13.0)   # sampled every 0.25 s
    assert any("separation guard: hold" in e["event"] for e in monitor.events)


def test_a_vehicle_short_of_battery_has_right_of_way():
    """The crossing above with vehicle 2 short of battery: 1 waits for it."""
    one = Scripted(1, (-240.0, 0.0), (12.0, 0.0), _route(400, 0))
    two = Scripted(2, (0.0, -240.0), (0.0, 12.0), _route(0, 400))
    _, guard = _guard([one, two], {1: 1, 2: 2}, short={2})
    least = _run([one, two], guard, 60.0)
    assert [(a["sysid"], a["action"]) for a in guard.actions] == [(1, "hold"), (1, "resume")]
    assert least >= 30.0 and not one.held and one.p[0] > 100.0


def test_a_vehicle_at_a_predicted_radio_shadow_has_right_of_way():
    """The crossing above with vehicle 2 flying into a radio shadow its plan predicts
    (entered 40 m ahead of where it starts): held there it would hover out of contact
    until its link-loss failsafe flew it home, so 1 waits for it. Without the shadow,
    2 waits (the first crossing test)."""
    route = _route(0, 400)
    route.trajectory = [[0.0, *_lonlat(0, -240), ALT], [60.0, *_lonlat(0, 480), ALT]]
    route.silences = [[40 / 12.0, 30.0]]
    one = Scripted(1, (-240.0, 0.0), (12.0, 0.0), _route(400, 0))
    two = Scripted(2, (0.0, -240.0), (0.0, 12.0), route)
    monitor, guard = _guard([one, two], {1: 1, 2: 2})
    assert monitor.near_shadow(2) and not monitor.near_shadow(1)
    least = _run([one, two], guard, 60.0)
    assert [(a["sysid"], a["action"]) for a in guard.actions] == [(1, "hold"), (1, "resume")]
    assert least >= 30.0 and not one.held and one.p[0] > 100.0


def test_head_on_both_are_held_and_the_deadlock_is_told():
    """On one line toward each other: standing still, either is in the other's way,
    so both hold, and stay held: neither can pass the other on its route. The guard
    says so once they have waited on each other for two loops (the flight then
    re-plans them), and forgets it with the holds a re-plan takes over."""
    one = Scripted(1, (-150.0, 0.0), (12.0, 0.0), _route(400, 0))
    two = Scripted(2, (150.0, 0.0), (-12.0, 0.0), _route(-400, 0))
    _, guard = _guard([one, two], {1: 1, 2: 2})
    deadlocks = []
    least = _run([one, two], guard, 20.0, deadlocks=deadlocks)
    assert {a["sysid"] for a in guard.actions if a["action"] == "hold"} == {1, 2}
    assert least >= 30.0 and one.held and two.held
    assert deadlocks and all(d == [1, 2] for d in deadlocks)
    guard.forget()
    assert guard.deadlocked == [] and guard.held == {}


def test_standing_in_the_way_the_other_one_holds():
    """2 (lower priority) is 20 m from 1's route, crossing it: held there it would
    still be in 1's way (20 m from where 1 passes), so 1 holds while 2 flies on
    and clears the way."""
    one = Scripted(1, (-60.0, 0.0), (12.0, 0.0), _route(400, 0))
    two = Scripted(2, (0.0, -20.0), (0.0, 12.0), _route(0, 400))
    _, guard = _guard([one, two], {1: 1, 2: 2})
    least = _run([one, two], guard, 40.0)
    first = guard.actions[0]
    assert (first["action"], first["sysid"]) == ("hold", 1)
    assert least >= 30.0 and not one.held and one.p[0] > 100.0   # and 1 went on after


def _fly_on_after_replan(one, two, wait_s, seconds, dt=0.25):
    """2 hovers where a re-plan held it until ``wait_s``, when the re-plan flies it
    on (the flight's departure); 1 flies. Returns (guard, least distance, where 2
    stood each step before its time)."""
    two.held = True
    clock = {"t": 0.0}
    _, guard = _guard([one, two], {1: 1, 2: 2},
                      waiting=lambda s: max(0.0, wait_s - clock["t"])
                      if s == 2 and clock["t"] < wait_s else None)
    least, stood = math.inf, []
    while clock["t"] < seconds:
        if clock["t"] < wait_s:
            stood.append(two.p.copy())
        else:
            two.held = False
        least = min(least, _run([one, two], guard, dt))
        clock["t"] += dt
    return guard, least, np.array(stood)


def test_a_vehicle_waiting_for_its_replan_time_is_left_to_the_replan():
    """2 waits 60 m off 1's way for its re-plan time, then crosses it. Flying now it
    would meet 1; standing until its time it does not: nobody is held, and above
    all 2 is never flown on early (once, it was: its re-plan's resume then sent it
    back to its route's first item in a straight line, through a hill)."""
    one = Scripted(1, (-240.0, 0.0), (12.0, 0.0), _route(400, 0))
    two = Scripted(2, (0.0, 60.0), (0.0, -12.0), _route(0, -400))
    guard, least, stood = _fly_on_after_replan(one, two, 30.0, 45.0)
    assert guard.actions == []
    assert np.ptp(stood, axis=0).max() == 0.0 and two.p[1] < -100.0   # then it went
    assert least >= 30.0


def test_waiting_in_the_way_the_other_one_holds():
    """2 waits on 1's way (1 has right of way): the guard holds 1, never 2, and
    lets 1 fly on once 2, gone at its time, is clear."""
    one = Scripted(1, (-240.0, 0.0), (12.0, 0.0), _route(400, 0))
    two = Scripted(2, (0.0, 0.0), (0.0, 12.0), _route(0, 400))
    guard, least, stood = _fly_on_after_replan(one, two, 30.0, 60.0)
    assert [(a["sysid"], a["action"]) for a in guard.actions] == [(1, "hold"), (1, "resume")]
    assert np.ptp(stood, axis=0).max() == 0.0
    assert least >= 30.0 and not one.held and one.p[0] > 100.0


def test_apart_nobody_is_held():
    one = Scripted(1, (0.0, 0.0), (12.0, 0.0))
    two = Scripted(2, (0.0, 100.0), (12.0, 0.0))
    _, guard = _guard([one, two], {1: 1, 2: 2})
    assert _run([one, two], guard, 20.0) == pytest.approx(100.0)
    assert guard.actions == []


def test_two_held_in_one_base_column_the_lower_lands_first():
    """Both coming home to one base: 2 held 11 m above it, 3 held 21 m above 2 (as a
    sped-up flight left them). Neither may stand where it is for ever: the lower
    one's descent only takes it further from the other, so it lands, then 3."""
    base = GeoPoint(LON0, LAT0, ALT - 40.0)
    top = Waypoint(LON0, LAT0, ALT, 0.0)
    two = Descending(2, ALT - 29.0, base.alt_amsl)
    three = Descending(3, ALT - 8.0, base.alt_amsl)
    monitor, guard = _guard([two, three], {2: 1, 3: 2})
    for v in (two, three):
        monitor.vehicles[v.sysid].route = VehicleRoute(v.sysid, base, [top], 0.0, 0.0, 0.0)
        monitor.vehicles[v.sysid].done.add(0)          # on the final descent
        v.held = True
        guard.held[v.sysid] = (0.0, 5 - v.sysid)
    least = math.inf
    for _ in range(240):
        _run([two, three], guard, 0.25)
        if two.p[2] > base.alt_amsl:            # both in the air
            least = min(least, three.p[2] - two.p[2])
    resumed = [a["sysid"] for a in guard.actions if a["action"] == "resume"]
    assert resumed[:1] == [2] and 3 in resumed
    assert two.p[2] == base.alt_amsl and three.p[2] == base.alt_amsl    # both landed
    assert least >= 21.0 - 0.5                  # never closer than they stood


class Descending(Scripted):
    """A vehicle over the base that, unless held, descends at 2 m/s to the ground."""

    def __init__(self, sysid, alt, ground):
        self.ground = ground
        super().__init__(sysid, (0.0, 0.0), (0.0, 0.0))
        self.p[2], self.v[2] = alt, -2.0
        self.report()

    def advance(self, dt):
        super().advance(dt)
        if self.p[2] <= self.ground:
            self.p[2], self.v[2] = self.ground, 0.0
            self.report()


class InColumn(Descending):
    """Low in its base column, its route going up to the column's top first: unless
    held it climbs there, or descends once told to land where it is."""

    def __init__(self, sysid, alt, ground, top):
        self.top, self.landing = top, False
        super().__init__(sysid, alt, ground)

    def advance(self, dt):
        self.v[2] = -2.0 if self.landing else (2.0 if self.p[2] < self.top else 0.0)
        super().advance(dt)


def _held_in_one_column(one, three, base, top):
    """A guard holding 1 and 3, both routed to the column's top over ``base`` and
    down, 1 past the top already (on its final descent)."""
    monitor, guard = _guard([one, three], {1: 1, 3: 2})
    for v in (one, three):
        monitor.vehicles[v.sysid].route = VehicleRoute(v.sysid, base, [top], 0.0, 0.0, 0.0)
        v.held = True
        guard.held[v.sysid] = (0.0, 4 - v.sysid)
    monitor.vehicles[1].done.add(0)
    return guard


def test_held_low_in_a_shared_column_with_only_its_top_left_it_lands_from_there():
    """As a sped-up flight left them (a re-plan brought 3 home as it took off): 1
    held on its final descent 38 m above 3, which is held low in the same column,
    its route climbing to the column's top before landing. Each route passes
    through the other; flown on as routed, each waited on the other until a
    battery ran out. 3 lands from where it stands (`lands_here`), then 1."""
    base = GeoPoint(LON0, LAT0, ALT - 140.0)
    top = Waypoint(LON0, LAT0, ALT, 0.0)
    one = Descending(1, ALT - 16.0, base.alt_amsl)
    three = InColumn(3, ALT - 54.0, base.alt_amsl, ALT)
    guard = _held_in_one_column(one, three, base, top)
    guard.fleet.lands_here = lambda s: s == 3

    def land(sysid):
        three.landing = True
        _set([one, three], sysid, False)
    guard.fleet.land = land
    least = math.inf
    for _ in range(400):
        _run([one, three], guard, 0.25)
        if three.p[2] > base.alt_amsl:                # both in the air
            least = min(least, one.p[2] - three.p[2])
    acts = [(a["sysid"], a["action"]) for a in guard.actions]
    assert acts[0] == (3, "land here") and (1, "resume") in acts, acts
    assert one.p[2] == base.alt_amsl and three.p[2] == base.alt_amsl    # both landed
    assert least >= 38.0 - 0.5                       # never closer than they stood
    # routed as it was, it is left standing: no way out for either
    one.p[2], three.p[2], three.landing = ALT - 16.0, ALT - 54.0, False
    stuck = _held_in_one_column(one, three, base, top)
    _run([one, three], stuck, 30.0)
    assert stuck.actions == [] and one.held and three.held


def test_closest_approach_counts_no_vehicle_touched_down_on_its_pad():
    """One down on the base pad (its landing not yet told: the disarm comes seconds
    later), the next descending the column 12 m above it: no approach in the air."""
    base = GeoPoint(LON0, LAT0, ALT - 40.0)
    top = Waypoint(LON0, LAT0, ALT, 0.0)
    down = Descending(2, base.alt_amsl, base.alt_amsl)
    above = Descending(3, base.alt_amsl + 12.0, base.alt_amsl)
    monitor, guard = _guard([down, above], {2: 1, 3: 2})
    for v in (down, above):
        monitor.vehicles[v.sysid].route = VehicleRoute(v.sysid, base, [top], 0.0, 0.0, 0.0)
    down.state.relative_alt = 0.0
    guard.fleet.on_pad = monitor.on_pad
    assert monitor.on_pad(2) and not monitor.on_pad(3)
    _run([down, above], guard, 1.0)
    assert guard.report()["pairs"] == []


def test_a_vehicle_held_just_above_its_pad_is_flown_on():
    """Held as it descended the last metres of its column (within the height a
    touchdown is told from), alone in the air: it is flown on and lands. Counted as
    down on its pad, it was never looked at again and hovered there until the
    flight's end (a timeout's trip home, on a busy machine)."""
    base = GeoPoint(LON0, LAT0, ALT - 40.0)
    top = Waypoint(LON0, LAT0, ALT, 0.0)
    low = Descending(2, base.alt_amsl + 2.0, base.alt_amsl)
    monitor, guard = _guard([low], {2: 1})
    monitor.vehicles[2].route = VehicleRoute(2, base, [top], 0.0, 0.0, 0.0)
    monitor.vehicles[2].done.add(0)
    low.state.relative_alt = 2.0
    low.held, guard.held[2] = True, (0.0, 3)
    guard.fleet.on_pad = monitor.on_pad
    assert monitor.on_pad(2)
    _run([low], guard, 2.0)
    assert [a["action"] for a in guard.actions] == ["resume"] and not low.held
    assert low.p[2] == base.alt_amsl


class Lingering(Scripted):
    """At the top of its base column, held; flown on, it lingers ``linger_s`` (turning
    to its first leg) before it flies off at its velocity."""

    def __init__(self, sysid, velocity, linger_s):
        super().__init__(sysid, (0.0, 0.0), velocity)
        self.linger_s = linger_s

    def advance(self, dt):
        if not self.held and self.linger_s > 0:
            self.linger_s -= dt
            return self.report()
        super().advance(dt)


class Climbing(Scripted):
    """Low in its base column: unless held it climbs at 2 m/s to the top, then flies
    off at its velocity."""

    def __init__(self, sysid, alt, velocity):
        super().__init__(sysid, (0.0, 0.0), velocity)
        self.p[2] = alt
        self.report()

    def advance(self, dt):
        if not self.held and self.p[2] < ALT:
            self.p[2] = min(ALT, self.p[2] + 2.0 * dt)
            return self.report()
        super().advance(dt)


def test_two_held_at_the_top_of_a_column_the_one_above_leaves_first():
    """Issue 62, as on real ArduPilot SITL: 1 at the top of its base column, about to
    turn to its first leg, 2 climbing 16 m below it; the guard held both and
    resumed both 0.1 s later, and 2 came up under 1, which lingered as it turned:
    4-6 m. Now 1, which leaves the column first, flies on; 2 holds until 1 has
    left (its own motion is not counted on), never closer than they stood, and
    neither flies on within two of the guard's loops of its hold."""
    base = GeoPoint(LON0, LAT0, ALT - 140.0)
    one = Lingering(1, (12.0, 0.0), linger_s=3.0)
    two = Climbing(2, ALT - 16.0, (0.0, 12.0))
    one.route = VehicleRoute(1, base, [Waypoint(LON0, LAT0, ALT, 0.0), _route(400, 0)
                                       .waypoints[0]], 0.0, 0.0, 0.0)
    two.route = VehicleRoute(2, base, [Waypoint(LON0, LAT0, ALT, 0.0), _route(0, 400)
                                       .waypoints[0]], 0.0, 0.0, 0.0)
    monitor, guard = _guard([one, two], {1: 1, 2: 2}, bases=[(LAT0, LON0, ALT)])
    monitor.vehicles[1].done.add(0)              # at the top: its first leg next
    for v in (one, two):
        v.held = True
        guard.held[v.sysid] = (monitor.now(), 3 - v.sysid)
    least = _run([one, two], guard, 40.0)
    acts = [(a["sysid"], a["action"]) for a in guard.actions]
    assert acts[0] == (1, "resume") and (2, "resume") in acts, acts
    resumed = next(a["t_s"] for a in guard.actions if a["sysid"] == 2)
    assert least >= 16.0 - 0.5                   # never closer than they stood
    # 2 went once 1 was a separation away across the ground (out of the column)
    assert one.p[0] >= 30.0 and two.p[2] == ALT and two.p[1] > 100.0
    assert resumed > 0.0


def test_a_takeoff_waits_while_a_vehicle_is_predicted_over_its_base():
    """A vehicle on its pad under a base column (2) may take off only when no
    airborne vehicle's predicted flight comes into its climb or route (as a held
    vehicle's resume): 1 flying toward the column over the base is in its way;
    past it and flying away, it is not. (Late from its swap, a vehicle once took off
    under one flying over its base, and they were 3 m apart when the guard, which
    sees only vehicles in the air, first looked.)"""
    base = GeoPoint(LON0, LAT0, ALT - 60.0)
    pad = Scripted(2, (0.0, 0.0), (0.0, 0.0))
    pad.p[2] = ALT - 60.0
    pad.report()
    pad.route = VehicleRoute(2, base, [Waypoint(LON0, LAT0, ALT, 0.0),
                                       _route(0, -500).waypoints[0]], 0.0, 0.0, 0.0)
    verdicts = []
    for x, far in ((-80.0, 600.0), (300.0, 900.0)):
        one = Scripted(1, (x, 0.0), (12.0, 0.0), route_to=_route(far, 0.0))
        monitor, guard = _guard([one, pad], {1: 1, 2: 2}, bases=[(LAT0, LON0, ALT)])
        guard.fleet.airborne = lambda: [1]        # 2 is down on its pad
        verdicts.append(guard.in_way_of_takeoff(2, wait_s=2.0))
    assert verdicts == [1, None]


def _landed_flight(monitor, guard):
    """A flight as its report judges it: every vehicle landed, the coverage reached,
    no battery trouble; the guard and monitor of a scripted run."""
    for sysid in monitor.vehicles:
        monitor.set_state(sysid, LANDED)
    batteries = SimpleNamespace(emptied={}, failsafes={})
    return SimpleNamespace(monitor=monitor, guard=guard, batteries=batteries, error=None,
                           timed_out=False, stopped=None)


REACHED = {"coverable_targets": 10, "survivors": {"k_covered": 10, "required_uavs": 2}}


def test_holds_that_kept_the_separation_are_notes_and_the_flight_succeeds():
    """The crossing above: vehicle 2 held and flown on, the pair never closer than
    the separation (by the scripted positions): the outcome is ok (gcs fly exits
    0), the hold is a note. It was a problem: 'held by the separation guard: flown
    off the proven schedule', exit 1, for every routine hold."""
    one = Scripted(1, (-240.0, 0.0), (12.0, 0.0), _route(400, 0))
    two = Scripted(2, (0.0, -240.0), (0.0, 12.0), _route(0, 400))
    monitor, guard = _guard([one, two], {1: 1, 2: 2})
    least = _run([one, two], guard, 60.0)
    assert least >= 30.0 and [a["action"] for a in guard.actions] == ["hold", "resume"]
    verdict = outcome(_landed_flight(monitor, guard), REACHED)
    assert verdict["ok"] and verdict["problems"] == []
    assert len(verdict["notes"]) == 1 and "held vehicle(s) 2 (1 hold(s))" in verdict["notes"][0]


def test_a_pair_flown_closer_than_the_separation_is_a_problem():
    """The crossing above judged against a separation 20 m beyond what the pair
    kept (by the scripted positions): the pair is a problem, at the distance the
    scripted vehicles came to."""
    one = Scripted(1, (-240.0, 0.0), (12.0, 0.0), _route(400, 0))
    two = Scripted(2, (0.0, -240.0), (0.0, 12.0), _route(0, 400))
    monitor, guard = _guard([one, two], {1: 1, 2: 2})
    least = _run([one, two], guard, 60.0)
    guard.separation_m = least + 20.0          # declared more than they kept
    verdict = outcome(_landed_flight(monitor, guard), REACHED)
    assert not verdict["ok"]
    [problem] = verdict["problems"]
    assert problem.startswith("vehicles 1 and 2 flew ") and "closer than the separation" in problem
    flown = float(problem.split(" flew ")[1].split(" m apart")[0])
    assert flown == pytest.approx(least, abs=13.0)              # sampled every 0.25 s


def test_the_flight_replans_vehicles_held_for_each_other_once_then_says_so():
    """`Flight._unlock` on what the guard says each loop: a re-plan the first time
    a set is deadlocked; the same set again after it is told once, not re-planned
    every loop; another set is re-planned in its turn."""
    from gcs.flight import Flight

    monitor = Monitor(lost_after_s=5.0)
    replans = []
    flight = SimpleNamespace(monitor=monitor, _unlocked={}, retask=lambda: replans.append(1))
    for held in ([], [1, 2], [1, 2], [1, 2], [2, 3], []):
        Flight._unlock(flight, held)
    assert len(replans) == 2
    said = [(e["event"].split(": ")[1], e["held"]) for e in monitor.events]
    assert said == [("vehicles held for each other, none may go first", [1, 2]),
                    ("vehicles held for each other again after a re-plan", [1, 2]),
                    ("vehicles held for each other, none may go first", [2, 3])]
