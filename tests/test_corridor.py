"""A vehicle off its proven legs is told as it happens and counted in the outcome.

The reference is plain geometry: positions placed at known distances beside a
route's legs, above its takeoff column and on a re-plan's join leg (by pyproj's
geodesic on the WGS 84 ellipsoid, from the launch point), fed to the monitor as
GLOBAL_POSITION_INT reports."""

import math
from types import SimpleNamespace

import pytest
from pyproj import Geod

from gcs.corridor import POSITION_MARGIN_M, ProvenPath
from gcs.monitor import FLYING, Monitor
from planner.plan import GeoPoint, VehicleRoute, Waypoint

LAT0, LON0, GROUND = -33.9, 151.2, 40.0          # southern and eastern: signs matter


def _geo(east, north, alt):
    """(lat, lon, alt) ``east`` and ``north`` metres of the launch point, along the
    geodesic: distances and bearings from it are exact on the ellipsoid."""
    lon, lat, _ = Geod(ellps="WGS84").fwd(LON0, LAT0, math.degrees(math.atan2(east, north)),
                                         math.hypot(east, north))
    return lat, lon, alt


def _route():
    """Up 60 m over the launch point, 400 m east, 300 m north, back above launch."""
    pts = [(0, 0, 100), (400, 0, 100), (400, 300, 110), (0, 0, 100)]
    way = [Waypoint(_geo(e, n, a)[1], _geo(e, n, a)[0], a, 0.0) for e, n, a in pts]
    return VehicleRoute(1, GeoPoint(LON0, LAT0, GROUND), way, 0.0, 0.0, 0.0)


def test_distance_to_the_legs_and_the_columns():
    path = ProvenPath(_route())
    assert path.distance_m(*_geo(200, 0, 100)) == pytest.approx(0.0, abs=1e-6)
    assert path.distance_m(*_geo(200, 12, 100)) == pytest.approx(12.0, abs=1e-3)
    assert path.distance_m(*_geo(200, 0, 93)) == pytest.approx(7.0, abs=1e-3)
    assert path.distance_m(*_geo(0, 0, 55)) == pytest.approx(0.0, abs=1e-6)   # climbing
    assert path.distance_m(*_geo(-9, 0, 55)) == pytest.approx(9.0, abs=1e-3)
    # the diagonal leg back: a point 20 m beside its middle
    mid, u = (200, 150), (-0.6, 0.8)          # the leg's direction is (-0.8, -0.6)
    assert path.distance_m(*_geo(mid[0] + 20 * u[0], mid[1] + 20 * u[1], 105)) == \
        pytest.approx(20.0, abs=0.05)
    held = ProvenPath(_route(), start=_geo(-150, 80, 90))   # a re-plan's join leg
    assert held.distance_m(*_geo(-75, 40, 95)) == pytest.approx(0.0, abs=1e-3)


class _Link:
    sysid, flavour = 1, "ardupilot"

    def __init__(self):
        self.state = SimpleNamespace(lat=None, lon=None, alt_amsl=None, relative_alt=None,
                                     armed=True, mode="AUTO", mission_seq=1)

    def subscribe(self, cb):
        return lambda: None


def _report(monitor, link, east, north, alt):
    lat, lon, _ = _geo(east, north, alt)
    link.state.lat, link.state.lon, link.state.alt_amsl = lat, lon, alt
    link.state.relative_alt = alt - GROUND
    monitor._on(1, SimpleNamespace(get_type=lambda: "GLOBAL_POSITION_INT",
                                   lat=round(lat * 1e7), lon=round(lon * 1e7),
                                   alt=round(alt * 1e3), relative_alt=round((alt - GROUND) * 1e3),
                                   time_boot_ms=0))


def test_monitor_tells_each_time_a_vehicle_leaves_its_legs_and_comes_back():
    monitor = Monitor(track_tolerance_m=5.0)
    link = _Link()
    monitor.follow(link, 1, _route(), SimpleNamespace(items=[]))
    monitor.vehicles[1].state = FLYING
    limit = 5.0 + POSITION_MARGIN_M
    for north in (0.0, 3.0, limit - 0.5, 0.0):       # within the room: nothing said
        _report(monitor, link, 200, north, 100)
    assert monitor.vehicles[1].off_route == []
    for north in (limit + 1.0, 25.0, 14.0, 2.0):     # out, further, back
        _report(monitor, link, 200, north, 100)
    episode = monitor.vehicles[1].off_route
    assert len(episode) == 1 and episode[0][1] is not None
    assert episode[0][2] == pytest.approx(25.0, abs=0.1)
    said = [e["event"] for e in monitor.events]
    assert any(t.startswith("9 m off its proven route") for t in said)
    assert any(t.startswith("back on its proven route") and "25 m off at most" in t
               for t in said)
    # a re-plan while held 30 m off: its join leg from there is proven, no new episode
    _report(monitor, link, 200, 30.0, 100)
    monitor.new_mission(1, _route(), SimpleNamespace(items=[]))
    _report(monitor, link, 100, 15.0, 100)         # on the way from there to the route
    # closed (its end time may be 0.0: the monitor began this very instant)
    episodes = monitor.vehicles[1].off_route
    assert len(episodes) == 2 and episodes[1][1] is not None


def test_unjudged_without_a_tolerance():
    monitor = Monitor()
    link = _Link()
    monitor.follow(link, 1, _route(), SimpleNamespace(items=[]))
    monitor.vehicles[1].state = FLYING
    _report(monitor, link, 200, 80.0, 100)
    assert monitor.vehicles[1].off_route == []
