"""Routes in fewer items, and routes longer than a vehicle holds flown in segments.

Judged by what does not come from missions/segments.py: every segment passes the
mission check on its own (hidden, clear), fits the capacity, and the segments
together fly the route's waypoints in order with every snapshot's camera
command; capacities are learned from the simulated vehicles, which hold what
they are configured to (ArduPilot's STATUSTEXT, PX4's silent NO_SPACE); and a
whole flight on the simulator in segments is judged from the simulator's own
track."""

import copy
import json

import numpy as np
import pytest
from flown import problems_beside_guard
from sim_fleet import quick_fleet

from autopilots import NAMES, profile
from common.errors import InputError
from gcs import mission_protocol as mp
from gcs.cli import main
from gcs.link import GroundLink
from gcs.segments import upload_route
from gcs.sim import free_base_port, read_track, track_path
from missions.build import MissionOptions, vehicle_mission
from missions.check import CheckedMission, checked
from missions.items import NAV_LAND, NAV_TAKEOFF, NAV_WAYPOINT
from missions.segments import RouteMissions, fewer_waypoints, leg_prover
from planner.exposure import segments_hidden

pytestmark = pytest.mark.timeout(120)
OPTIONS = MissionOptions(speed_mps=12.0)


def _route_missions(planned, route, firmware, prove=None):
    ctx = planned.ctx
    return RouteMissions(route, firmware, OPTIONS,
                         lambda m: checked(m, ctx.surface, ctx.scenario.clearance_m),
                         fly=fewer_waypoints(route, prove))


def test_fewer_waypoints_keeps_snapshots_and_proven_legs(planned):
    ctx = planned.ctx
    prove = leg_prover(ctx)
    for route in planned.plan.vehicles:
        w = route.waypoints
        # a repeated waypoint is flown once, the snapshot of the two
        doubled = copy.deepcopy(route)
        doubled.waypoints = [w[0]] + [copy.copy(p) for p in w]
        doubled.waypoints[0].snapshot = False
        assert len(fewer_waypoints(doubled)) == len(fewer_waypoints(route))
        keep = fewer_waypoints(route, prove)
        assert keep[0] == 0 or w[0].snapshot is False
        assert all(i in keep for i, p in enumerate(w) if p.snapshot)
        assert keep == sorted(keep) and keep[-1] in (len(w) - 1, len(w) - 2)
        # every leg flown is one the planner's proofs pass (an independent check:
        # hidden with the track tolerance, by the exposure surface itself)
        xyz = np.array([[*ctx.terrain.from_lonlat(w[i].lon, w[i].lat), w[i].alt_amsl]
                        for i in keep], float)
        slack = ctx.travel_params.slack_m
        assert segments_hidden(ctx.surface, xyz[:-1], xyz[1:], slack).all()
        # a mission built from them passes the mission check
        checked(vehicle_mission(route, "ardupilot", OPTIONS, fly=keep), ctx.surface,
                ctx.scenario.clearance_m)


@pytest.mark.parametrize("firmware", NAMES)
def test_segments_fit_and_fly_the_route_in_order(planned, firmware):
    route = max(planned.plan.vehicles, key=lambda r: len(r.waypoints))
    missions = _route_missions(planned, route, firmware)
    whole = len(missions)
    assert missions.first(None) is missions.whole and missions.first(whole) is missions.whole
    capacity = 14
    assert not missions.fits(capacity)
    p = profile(firmware)
    flown, shots, segments = [], [], []
    start, index, final = missions.fly[0], 0, False
    while not final:
        seg = missions.segment(capacity, start, index)
        assert isinstance(seg, CheckedMission) and len(seg) <= capacity
        items = seg.items
        assert (items[0].command == NAV_WAYPOINT) == p.home_item
        assert (NAV_TAKEOFF in [it.command for it in items]) == (index == 0)
        assert (items[-1].command == NAV_LAND) == seg.final
        wps = [w for w in seg.waypoint_of_item if w is not None]
        assert wps[0] == start and wps[-1] == seg.last_waypoint and len(wps) >= 2 or seg.final
        flown += wps if not flown else wps[1:]      # each starts where the last ended
        shots += [it for it in items if it.command == p.camera_command]
        segments.append(seg)
        start, index, final = seg.last_waypoint, index + 1, seg.final
    assert flown == missions.fly
    snapshots = [i for i in missions.fly if route.waypoints[i].snapshot]
    # the waypoint two segments share is flown twice: its camera command comes twice
    assert len(shots) >= len(snapshots)
    if firmware == "px4":                   # capture numbers go on across segments
        numbers = [it.param4 for it in shots]
        assert numbers == sorted(numbers) and numbers[-1] == len(snapshots)
    # a segment starting where the snapshot was taken already: no camera there
    later = next(s for s in segments[1:] if route.waypoints[s.first_waypoint].snapshot) \
        if any(route.waypoints[s.first_waypoint].snapshot for s in segments[1:]) else None
    if later is not None:
        again = missions.segment(capacity, later.first_waypoint, later.segment, taken=True)
        assert len(again) == len(later) - 1
    with pytest.raises(InputError, match="too few"):
        missions.segment(4, missions.fly[0], 0)


def test_segments_end_where_the_next_can_be_uploaded(planned):
    """The next segment is uploaded as a vehicle flies its segment's last leg, so a
    segment ends on a leg its plan has in radio contact (a predicted shadow 20 s
    away either side) wherever the capacity leaves such an end: one ending in a
    shadow waited there unheard and was declared lost. Where none is in reach: the
    longest, and `unheard_ends` gives it (the flight says so before takeoff).
    Reference: every end the capacity allows, looked at against the plan's
    silences by hand."""
    from dataclasses import replace

    from missions.segments import SHADOW_MARGIN_S

    capacity, checked_ends, unheard = 14, 0, 0
    for route in planned.plan.vehicles:
        missions = _route_missions(planned, route, "ardupilot")
        deaf = _route_missions(planned, replace(route, silences=[]), "ardupilot")
        w = route.waypoints

        def heard(i, j):        # the leg from route waypoint i to j, out of every shadow
            return all(w[j].t_s < a - SHADOW_MARGIN_S or w[i].t_s > b + SHADOW_MARGIN_S
                       for a, b in route.silences)
        start, index, final, ends = missions.fly[0], 0, False, []
        while not final:
            seg = missions.segment(capacity, start, index)
            final = seg.final
            if not final:
                wps = [i for i in seg.waypoint_of_item if i is not None]
                longest = [i for i in deaf.segment(capacity, start, index).waypoint_of_item
                           if i is not None]
                choices = [k for k in range(2, len(longest) + 1)
                           if heard(longest[k - 2], longest[k - 1])]
                if choices:
                    assert wps == longest[:choices[-1]] and heard(wps[-2], wps[-1])
                    checked_ends += 1
                else:           # none in reach: the longest, and the operator is told
                    assert wps == longest
                    ends.append(wps[-1])
            start, index = seg.last_waypoint, index + 1
        assert missions.unheard_ends(capacity) == ends
        unheard += len(ends)
    assert checked_ends > 0 and unheard > 0


@pytest.mark.parametrize("firmware", NAMES)
def test_a_segment_starts_where_the_vehicle_holds_on_its_leg(planned, firmware):
    """The next segment's first position is the held vehicle's place on the proven
    leg into the waypoint it flies to (nearest point, by brute force over the
    leg), within the capacity and through the mission check; a vehicle standing
    at that waypoint starts there."""
    route = max(planned.plan.vehicles, key=lambda r: len(r.waypoints))
    missions = _route_missions(planned, route, firmware)
    k = len(missions.fly) // 2
    a, b = (route.waypoints[i] for i in missions.fly[k - 1:k + 1])
    ctx = planned.ctx

    def xyz(lat, lon, alt):
        x, y = ctx.terrain.from_lonlat(np.array([lon]), np.array([lat]))
        return np.array([x[0], y[0], alt])

    pa, pb = xyz(a.lat, a.lon, a.alt_amsl), xyz(b.lat, b.lon, b.alt_amsl)
    cross = np.cross(pb - pa, [0.0, 0.0, 1.0])
    held = pa + 0.4 * (pb - pa) + 2.0 * cross / np.linalg.norm(cross) + [0.0, 0.0, -3.0]
    lon, lat = ctx.terrain.to_lonlat(np.array([held[0]]), np.array([held[1]]))
    seg = missions.segment(14, missions.fly[k], 3, here=(lat[0], lon[0], held[2]))
    assert isinstance(seg, CheckedMission) and len(seg) <= 14
    first = profile(firmware).first_item
    positions = [i for i, it in enumerate(seg.items) if i >= first and it.command == NAV_WAYPOINT]
    start = seg.items[positions[0]]
    assert seg.waypoint_of_item[positions[0]] is None
    assert seg.waypoint_of_item[positions[1]] == missions.fly[k]
    leg = pa + np.linspace(0.0, 1.0, 20001)[:, None] * (pb - pa)
    nearest = leg[np.argmin(np.linalg.norm(leg - held, axis=1))]
    assert np.linalg.norm(xyz(start.x, start.y, start.z) - nearest) < 0.05 + \
        np.linalg.norm(pb - pa) / 20000
    at_b = missions.segment(14, missions.fly[k], 3, here=(b.lat, b.lon, b.alt_amsl))
    assert at_b.items == missions.segment(14, missions.fly[k], 3).items


def test_capacity_learned_from_what_the_vehicle_says_or_by_probing(planned):
    route = max(planned.plan.vehicles, key=lambda r: len(r.waypoints))
    for firmware, capacity, how in (("ardupilot", 650, "said"), ("ardupilot", 20, "said"),
                                    ("px4", 23, "probed")):
        fleet = quick_fleet(1, firmware, homes=[planned.launch], mission_capacity=capacity)
        try:
            with GroundLink.open(fleet.urls(), expect=1, timeout_s=10) as link:
                vehicle = link.vehicles[1]
                missions = _route_missions(planned, route, firmware)
                learned = []
                uploaded = upload_route(vehicle, missions,
                                        on_capacity=lambda c, h: learned.append((c, h)))
                held = fleet.vehicle(1).mission.items
                if len(missions) <= capacity:
                    assert uploaded is missions.whole and learned == []
                else:
                    assert learned == [(capacity, how)]
                    assert mp.known_capacity(vehicle) == capacity
                    assert not uploaded.final and len(uploaded) <= capacity
                assert len(held) == len(uploaded)
                assert mp.compare(uploaded.items, mp.download(vehicle), firmware) == []
        finally:
            fleet.stop()


def test_upload_of_a_mission_too_long_says_so(planned, tmp_path, capsys):
    """`gcs upload` without fly: the capacity found, and how to raise it."""
    base = free_base_port(10, 3)
    fleet = quick_fleet(3, homes=[planned.launch] * 3, base_port=base, mission_capacity=30,
                        speedup=1.0)
    try:
        code = main(["upload", str(planned.dir),
                     *[f"--connect=tcp:127.0.0.1:{base + 10 * i}" for i in range(3)]])
        err = capsys.readouterr().err
    finally:
        fleet.stop()
    assert code == 1, err
    assert "holds 30 mission items" in err and "BRD_SD_MISSION" in err
    assert "gcs fly" in err


@pytest.mark.parametrize("firmware", ["ardupilot"])   # PX4's: the climbing-leg hold test
def test_a_flight_in_segments_on_the_simulator(planned, tmp_path, firmware):
    """Every route longer than the vehicles hold (24 items): flown in segments
    uploaded in flight, judged by the simulator's own record: every route
    waypoint reached in order, landed at launch, hidden all along, never off the
    proven legs (PX4 climbs straight up where it holds when its next item is
    higher: each segment starts where the vehicle holds). With a link everywhere
    (--no-sim-radio): 24 items are 9-11 waypoints, fewer than the plan's longest
    shadows span (441 s), so some segment ends lie in a shadow whatever the cut;
    the flight says so before takeoff (asserted), and such a vehicle would wait
    there unheard."""
    base = free_base_port(10, 3)
    out = tmp_path / "flight"
    code = main(["fly", str(planned.dir), "--sim", "3", "--speedup", "25", "--sim-capacity",
                 "24", "--lost-after", "3", "--sim-base-port", str(base), "-o", str(out),
                 "--firmware", firmware, "--no-sim-radio"])
    report = json.loads((out / "flight.json").read_text())
    told = [e for e in report["events"] if "unheard_ends" in e]
    assert told and all("end in predicted radio shadows" in e["event"] for e in told)
    # each segment's hold is a tenth of a wall second, 3 s of flight at 25x: the fleet
    # may drift off its separated schedule by a few of them, and then the guard acts
    assert problems_beside_guard(report) == [], report["outcome"]
    assert report["outcome"]["coverage_reached"], report["outcome"]
    assert code == (0 if report["outcome"]["ok"] else 1)
    assert report["separation"]["closest_m"] >= report["separation"]["separation_m"] / 2
    ctx = planned.ctx
    for v in report["vehicles"]:
        assert v["state"] == "landed" and v["mission_capacity"] == 24
        route = planned.plan.vehicles[v["vehicle"] - 1]
        assert v["segments"] >= 1
        track = read_track(track_path(out / "tracks", v["sysid"]))
        assert abs(track.alt[-1] - track.home[2]) < 1.0
        xyz = np.stack([*ctx.terrain.from_lonlat(track.lon, track.lat), track.alt], axis=1)
        moved = np.linalg.norm(np.diff(xyz, axis=0), axis=1) > 1e-6
        assert segments_hidden(ctx.surface, xyz[:-1][moved], xyz[1:][moved]).all()
        snaps = len(track.snapshots)
        assert snaps >= len(route.snapshots)
    ups = report["segments"]
    assert ups and all(u["items"] <= 24 for u in ups)
    assert report["outcome"]["coverage_reached"]
