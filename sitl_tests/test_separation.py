"""A fleet from one base keeps apart in flight (issue 37), judged from what the
vehicles really flew: the simulators' recorded true tracks, or what real SITL
reported of itself on its second link, compared on the wall clock they share.
Flown slower than the other end-to-end tests (the guard acts on telemetry a
few times a second: at 100x a vehicle moves 300 m between two reports).

- the plan's fleet, one of them shot down and the survivors re-tasked on the
  re-plan's own schedule: no two airborne vehicles closer than half the
  separation (the guard's room: track error and latency), on both firmwares;
- a vehicle that takes off late, by the least delay that brings it within the
  separation of another on the plan's own trajectories: the one that claims their
  base column second waits until it is clear; then the guard holds one of them,
  the report says so and the outcome calls it flown off the proven schedule.

The simulator flies each case in one firmware's flavour, each flavour in at least
one case (PX4's: the loss and the climbing hold; ArduPilot's: the late start):
both flavours of every case took 240 s of the suite's 15 minutes. Real SITL of
both firmwares flies the loss and the climbing hold.
"""

import numpy as np
import pytest
from fleets import REAL, skip_unless_configured
from judge import closest_airborne, shared_column
from test_end_to_end import assert_hidden_and_clear, fly_case

from gcs.monitor import FLYING
from gcs.sim import read_track
from missions.items import NAV_WAYPOINT

#: slow enough for the guard (wall seconds of telemetry are this many fleet seconds)
SPEEDUP = {"sim": 20.0, "sim-px4": 20.0, "ardupilot": 10.0, "px4": 4.0}
pytestmark = pytest.mark.timeout(400)


@pytest.fixture(params=["sim-px4", "ardupilot", "px4"])
def flown(request):
    skip_unless_configured(request.param)
    return request.param


def _separation(planned) -> float:
    return float(planned.plan.params["separation_m"])


def test_a_fleet_from_one_base_keeps_apart_through_a_loss(planned, flown, tmp_path):
    p = planned(0, REAL)
    result = fly_case(p, flown, tmp_path, kills=[(2, 0.5)], speedup=SPEEDUP[flown])
    report = result["report"]
    d, pair, _ = closest_airborne(result["tracks"])
    sep = report["separation"]
    print(f"\n[{flown}] closest airborne approach {d:.1f} m (vehicles {pair}), planned "
          f"{sep['planned_closest_m']} m, guard actions {len(sep['actions'])}, "
          f"{result['wall_s']:.0f} s")
    assert [x["sysid"] for x in report["losses"]] == [2]
    assert report["replans"] and report["replans"][0]["departs"]
    assert d >= _separation(p) / 2
    assert sep["planned_closest_m"] >= _separation(p)
    assert_hidden_and_clear(p, result["tracks"])
    held = {a["sysid"] for a in sep["actions"] if a["action"] == "hold"}
    events = {e["sysid"] for e in report["events"] if "separation guard: hold" in e["event"]}
    assert held == events                      # every hold an event line, and no other


#: metres the simulated ground lies below the base in the column test: SITL's flat
#: ground at its home altitude was 140 m below a canyon base (issue 62)
LONG_COLUMN_M = 140.0
#: mission seconds the first vehicle stays on the ground after its takeoff command
SPOOL_S = 10.0


@pytest.mark.parametrize("backend,delay", [("sim", SPOOL_S), ("ardupilot", 0.0),
                                           ("ardupilot", SPOOL_S), ("px4", 0.0),
                                           ("px4", SPOOL_S)])
def test_one_vehicle_at_a_time_in_a_base_column(planned, backend, delay, tmp_path):
    """Three vehicles from one base, the first slow to leave the ground (the
    simulator: 10 s of spool-up after its takeoff command; real SITL: its arming
    refused for 10 s after its start sequence begins), every column 140 m longer
    than planned (the ground below the base), one shot down mid-mission: each
    takeoff waits until the vehicle before has left the column, as the vehicles
    report it, never by the clock of the commands (on real ArduPilot SITL two
    copters stacked in one column met 4.1-5.7 m apart at its top). Judged from
    the simulator's true tracks, or real SITL's own reports on its second link:
    never two in the column at once, and the declared separation kept."""
    skip_unless_configured(backend)
    p = planned(0, REAL)
    sep = _separation(p)
    slow = {"spool": {1: delay}} if backend == "sim" else \
        {"arm_delay": {1: delay}} if delay else {}
    result = fly_case(p, backend, tmp_path, kills=[(2, 0.5)], speedup=SPEEDUP[backend],
                      below_base_m=LONG_COLUMN_M, **slow)
    report, tracks = result["report"], result["tracks"]
    base = p.plan.vehicles[0].launch
    top = max(v.waypoints[0].alt_amsl for v in p.plan.vehicles if v.waypoints) + sep
    span, pair, _ = shared_column(tracks, (base.lat, base.lon), sep, top)
    d, closest, _ = closest_airborne(tracks)
    print(f"\n[{backend}, first vehicle {delay:g} s slow] closest airborne {d:.1f} m "
          f"({closest}); in one column together {span:.1f} s ({pair}); guard actions "
          f"{report['separation']['actions']}")
    assert pair is None, f"vehicles {pair} in the base column together for {span:.1f} s"
    assert d >= sep
    assert [x["sysid"] for x in report["losses"]] == [2]
    assert report["outcome"]["coverage_reached"] and report["outcome"]["in_air"] == []


def late_start(planned, longest_s=600.0, step_s=10.0) -> tuple:
    """(vehicle, seconds): the shortest delay of one vehicle's takeoff (not the
    first's) after which its planned trajectory, shifted, comes within the
    separation of another's: found on the plan's own trajectories."""
    from planner.fleet import Trajectory, route_trajectory, stop_time

    plan, travel = planned.plan, planned.ctx.scenario.travel_params()
    stop = stop_time(plan.params)
    routes = [v for v in plan.vehicles if v.waypoints]
    flights = {v.id: route_trajectory(v, planned.surface.terrain, travel, stop) for v in routes}
    first = min(routes, key=lambda v: v.takeoff_s).id
    for delay in np.arange(step_s, longest_s + step_s, step_s):
        for vid, t in flights.items():
            if vid == first:
                continue
            moved = Trajectory(t.t + delay, t.xyz, t.air, t.vertex)
            if any(moved.closest_approach(o)[0] < _separation(planned)
                   for oid, o in flights.items() if oid != vid):
                return vid, float(delay)
    pytest.fail(f"no takeoff delay up to {longest_s:g} s brings two vehicles of the plan "
                "closer than the separation")


@pytest.mark.parametrize("backend", ["sim"])
def test_a_late_start_waits_for_its_column_and_the_guard_acts(planned, backend, tmp_path):
    """A vehicle takes off late by the least delay that, on the plan's own
    trajectories, would bring it within the separation of another: the late one
    arms as the next one launches. Whichever claims their base column second waits
    until the other has left it and says so: never two in it at once (from the
    simulator's true tracks). It then flies close behind the other: the guard
    holds one of them, the report says so, and they stay apart."""
    p = planned(0, REAL)
    late, delay = late_start(p)
    result = fly_case(p, backend, tmp_path, speedup=SPEEDUP[backend], late=(late, delay))
    report = result["report"]
    sep = report["separation"]
    d, pair, _ = closest_airborne(result["tracks"])
    base = p.plan.vehicles[0].launch
    in_column, _, _ = closest_airborne(result["tracks"],
                                       near=(base.lat, base.lon, _separation(p)))
    waits = [e["event"] for e in report["events"] if "takeoff waits" in e["event"]]
    print(f"\n[{backend}, vehicle {late} late by {delay:.0f} s] closest {d:.1f} m, "
          f"in the base column {in_column:.1f} m, {waits}, guard actions {sep['actions']}")
    # before the claim was made as each arming is tried, both armed together and
    # climbed the column 10.8-18.9 m apart
    assert waits and in_column >= _separation(p)
    holds = [a for a in sep["actions"] if a["action"] == "hold"]
    # the guard acts where they meet; on a machine busy enough the wait for the
    # column may itself have taken the late one far enough behind (seen once in a
    # suite run beside three other simulated flights): then they never met
    assert holds or d >= _separation(p), "they met and the guard never acted"
    # each hold for a pair predicted closer than the separation, or in one base
    # column at once (a vehicle coming home held while another climbs out of it)
    assert all(a["predicted_m"] < _separation(p) or a.get("column") for a in holds)
    # kept apart, never touching: at 20x a wall second the machine spends elsewhere
    # is 20 s of flight, so how far inside the separation the pair came depends on the
    # machine (15-20 m idle, 9.5-14.6 m beside the suite's other tests): what this
    # simulator test holds is that the guard acts, says so, and no two vehicles meet
    assert d >= 5.0
    if holds:
        # said as it happens, and in the outcome: a note while the separation was kept
        # (the guard's routine work), a problem for each pair that came inside it
        assert any("separation guard: hold" in e["event"] for e in report["events"])
        assert any("the separation guard held" in line for line in report["outcome"]["notes"])
        inside = [line for line in report["outcome"]["problems"]
                  if "closer than the separation" in line]
        assert bool(inside) == (sep["closest_m"] < _separation(p)), (sep["closest_m"], inside)
    # flown on from where it was held, as the simulator itself records: PX4 goes back
    # to the item before (its camera triggering) unless its current item is set since
    # the hold, and on real PX4 climbs first to that item's altitude where it stands
    assert not any("off its proven route" in line for line in report["outcome"]["problems"])
    recorded = [read_track(f) for f in tmp_path.rglob("tracks/vehicle_*.json")]
    assert recorded and not [e for track in recorded for e in track.events
                             if "resumed at the previous position item" in e["event"]]
    assert report["outcome"]["coverage_reached"] and report["outcome"]["in_air"] == []


#: metres below its next waypoint a vehicle is held at (PX4 climbs first beyond 0.8)
BELOW_M = 4.0


def _climbing_mid_leg(sysid):
    """``when`` for `fly_case`'s ``held``: ``sysid`` flies a waypoint leg past its
    route's first waypoint, its next waypoint BELOW_M or more above it."""
    def when(flight):
        m = flight.monitor
        v, state = m.vehicles[sysid], m.links[sysid].state
        if v.state != FLYING or not v.airborne or not v.done or v.mission is None \
                or state.mission_seq is None or state.alt_amsl is None:
            return False
        items = v.mission.items
        seq = state.mission_seq
        return 0 <= seq < len(items) and items[seq].command == NAV_WAYPOINT and \
            items[seq].z >= state.alt_amsl + BELOW_M
    return when


@pytest.mark.parametrize("backend", ["sim-px4", "ardupilot", "px4"])
def test_a_hold_on_a_climbing_leg_flies_on_along_it(planned, backend, tmp_path):
    """The guard holds a vehicle on a leg that climbs to its next waypoint and then
    flies it on. PX4 (MissionBase::checkClimbRequired) would climb straight up
    where it holds, above its proven leg, before flying on level: the ground
    station uploads the rest of its route from where it holds. Judged by the
    vehicles' own tracks: never off the proven legs, hidden and clear. (The
    ArduPilot-flavoured simulator is left out of the suite: real ArduPilot SITL
    judges that firmware, and the suite is at its time.)"""
    skip_unless_configured(backend)
    flown = backend
    p = planned(0, REAL)
    result = fly_case(p, flown, tmp_path, speedup=SPEEDUP[flown],
                      held=(1, 2, _climbing_mid_leg(1)))
    report = result["report"]
    holds = [a for a in report["separation"]["actions"] if a["sysid"] == 1]
    print(f"\n[{flown}] vehicle 1's guard actions {holds}, segments {report['segments']}")
    assert [a["action"] for a in holds[:2]] == ["hold", "resume"]
    problems = [x for x in report["outcome"]["problems"] if "separation guard" not in x]
    assert problems == [] and report["losses"] == [], report["outcome"]
    assert all(v["off_route"] == [] for v in report["vehicles"])
    if flown in ("sim-px4", "px4"):
        assert any(u["sysid"] == 1 and u["why"] == "from here" for u in report["segments"])
    assert_hidden_and_clear(p, result["tracks"])
    assert report["outcome"]["coverage_reached"]
