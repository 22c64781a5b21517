"""The fleet clock and the ground station's busy spells: a simulator in the ground
station's process flies at real time while it computes, and the fleet clock,
read off the vehicles' own clocks, stays on their time through it."""

import threading
import time
from types import SimpleNamespace

import pytest

from gcs import busy as busy_mod
from gcs.busy import busy, busy_now, busy_total_s
from gcs.clock import FleetClock
from tests.sim_fleet import quick_fleet


def test_a_busy_spell_is_open_while_any_of_its_threads_works():
    before = busy_total_s()
    both, one_left = threading.Event(), threading.Event()

    def upload(wait):
        with busy():
            both.wait(2)
            wait.wait(2)

    done = threading.Event()
    a = threading.Thread(target=upload, args=(done,))
    b = threading.Thread(target=upload, args=(one_left,))
    a.start(), b.start()
    time.sleep(0.1)
    assert busy_now()
    both.set()
    one_left.set()
    b.join()
    assert busy_now()                   # the other upload still runs
    time.sleep(0.1)
    done.set()
    a.join()
    assert not busy_now()
    assert busy_total_s() - before >= 0.2
    assert busy_mod.last_end() <= time.monotonic()


def test_a_simulator_flies_at_real_time_while_the_ground_station_is_busy():
    """The judge is the simulator's own clock: 50 times the wall clock, except
    through a second of the ground station's work, where it moves one second."""
    fleet = quick_fleet(1, "px4", speedup=50.0)
    try:
        v = fleet.vehicles[0]
        time.sleep(0.3)
        t0 = v.t
        time.sleep(0.5)
        fast = v.t - t0
        with busy():
            time.sleep(0.05)            # the tick under way when it opened
            t1 = v.t
            time.sleep(1.0)
            slow = v.t - t1
        assert fast > 10.0                      # 25 s asked; a busy machine gives less
        assert 0.8 <= slow <= 1.5, slow
        assert v.track.real_time_s == pytest.approx(1.05, abs=0.3)
    finally:
        fleet.stop()


class _Monitor:
    """A monitor's clock and the reports it has by then (monitor time, lon, lat,
    alt, own clock) of vehicles whose whole flights are ``flights``."""

    def __init__(self, flights):
        self.t = 0.0
        self._lock = threading.Lock()
        self._flights = flights

    @property
    def vehicles(self):
        return {i + 1: SimpleNamespace(track=[r for r in rows if r[0] <= self.t])
                for i, rows in enumerate(self._flights)}

    def now(self):
        return self.t


def _flown(paces, period=0.2, own0=100.0):
    """Reports every ``period`` monitor seconds of a vehicle whose own clock runs
    ``pace`` times the wall clock until each listed wall time: [(until, pace)]."""
    rows, wall, own = [], 0.0, own0
    for until, pace in paces:
        while wall < until - 1e-9:
            rows.append((round(wall, 3), 0.0, 0.0, 0.0, round(own, 3)))
            wall += period
            own += period * pace
    return rows


def test_the_fleet_clock_keeps_the_vehicles_time_through_a_spell_at_real_time(monkeypatch):
    """100x, then 4 wall s at 1x (the ground station planning; the clock is not read
    meanwhile), then 100x: the fleet clock moves what the vehicles' own clocks moved
    (reading the rate of the last 3 s times the wall time, it was 53 s ahead after
    the spell, and read a rate of 34 where the vehicles flew at 100)."""
    paces = [(10.0, 100.0), (14.0, 1.0), (20.0, 100.0)]
    tracks = [_flown(paces), _flown(paces, own0=7.0), _flown(paces, period=0.25)]
    m = _Monitor(tracks)
    spell_end = 14.0
    monkeypatch.setattr(busy_mod, "last_end", lambda: time.monotonic() - (m.t - spell_end))
    clock = FleetClock(m)
    for t in (0.0, 2.0, 4.0, 6.0, 8.0, 9.8):
        m.t = t
        if t == 0.0:
            clock.start()
        got = clock.now()
    assert got == pytest.approx(980.0, rel=0.01)
    m.t = 15.0                          # the first reading after the spell
    assert clock.now() == pytest.approx(980.0 + 20.0 + 4.0 + 100.0, rel=0.01)
    assert clock.rate() == pytest.approx(100.0, rel=0.05)   # its reports since the spell
    m.t = 19.6
    assert clock.now() == pytest.approx(1000.0 + 4.0 + 560.0, rel=0.01)


def test_the_fleet_clock_leaves_out_a_vehicle_that_rebooted():
    """A vehicle whose autopilot restarted (a battery swap on a pack-fed controller)
    has a clock that went back: the others keep the fleet's time."""
    steady = _flown([(6.0, 10.0)])
    rebooted = [r if r[0] < 3.0 else (r[0], 0.0, 0.0, 0.0, r[4] - 130.0) for r in steady]
    m = _Monitor([steady, rebooted, list(steady)])
    clock = FleetClock(m)
    m.t = 1.0
    clock.start()
    m.t = 5.8
    assert clock.now() == pytest.approx(48.0, rel=0.02)
