"""Sorties flown on the simulator (`--endurance`): the shared small plan (tests/conftest.py)
planned again on a 12-minute battery, 2-3 sorties a vehicle, flown with the
simulator's crew swapping batteries, with losses, a fast-draining pack, an
operator who confirms each swap, and losses during re-plans. Judged from the
simulator's own tracks. (Kept apart from test_sorties.py, which plans and reads
the mission files, so that the two run on different test processes.)"""

import json
import threading
import time
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from flown import problems_beside_pauses, takeoffs_on_fresh_batteries

from gcs.cli import main
from gcs.flight import LOOP_S
from gcs.guard import hold_spans
from gcs.plan_folder import write_plan_folder
from gcs.sim import (
    fleet_for_plan,
    free_base_port,
    radio_for_plan,
    read_track,
    terrain_ground,
    track_path,
)
from planner.pipeline import plan_mission
from planner.scenario import Scenario

pytestmark = pytest.mark.timeout(300)
#: a simulated flight of the twelve plan's sorties: 60-80 s on a quiet 2-core machine,
#: 200-340 s measured beside other flights and CPU hogs (its re-plans slowed most)
FLIGHT_TIMEOUT = pytest.mark.timeout(600)
#: the simulated sortie flights' speed-up
SPEEDUP = 100


@pytest.fixture(scope="module")
def twelve(planned, tmp_path_factory):
    """The shared plan on a 12-minute battery: 2-3 sorties a vehicle."""
    scenario = replace(Scenario.from_params(planned.plan.params), endurance_min=12.0,
                       sample=True).validate()
    ctx, outcome = plan_mission(scenario, terrain=planned.terrain,
                                outposts=planned.ctx.outposts)
    d = tmp_path_factory.mktemp("twelve")
    write_plan_folder(d, ctx, outcome)
    return SimpleNamespace(dir=d, plan=outcome.plan)


@FLIGHT_TIMEOUT
@pytest.mark.parametrize("kill", [None, "2@item8", "2@1450s"])
def test_a_fleet_flies_its_sorties_on_the_simulator(twelve, tmp_path, kill):
    """`gcs fly` of a plan of several sorties: each vehicle lands at its base, the
    next sortie waits for the fresh battery the simulator's crew puts in, then goes
    at its planned time; a loss re-plans the survivors on the battery they report
    left, in sorties again: in its first sortie (item 8), or as it goes up for its
    third when the others have landed on spent batteries (1450 s): they go up again
    once swapped (the re-plan once gave their first, empty sortie nothing to see
    and left them down). Judged by the simulator's own tracks. Without a loss, each
    swap powers the autopilot down for 9 s (a flight controller fed by its pack; the
    simulator closes its TCP port as SITL rebooting does), three times --lost-after:
    silent at its base, not lost; connected to again, it flies its next sortie (at
    4 s, and at 6 s on a machine loaded to 6, its stalls, which the ground station
    leaves out of a silence, kept one of the silences under --lost-after: never
    said). A
    kill that finds vehicle 2 down waiting for its swap (a busy machine once delayed
    it so) is such a silence: lost after --swap-silence, 10 wall s here (1000 s of
    mission time; the default 600 wall s outlasted the test)."""
    out = tmp_path / "flight"
    code = main(["fly", str(twelve.dir), "--sim", "3", "--speedup", str(SPEEDUP), "--lost-after",
                 "3", "--sim-base-port", str(free_base_port(10, 3)), "-o", str(out)]
                + (["--kill", kill, "--swap-silence", "10"] if kill
                   else ["--swap-reboot", "9"]))
    report = json.loads((out / "flight.json").read_text())
    lost = [2] if kill else []
    assert report["outcome"]["lost"] == lost and report["outcome"]["coverage_reached"]
    assert [p for p in problems_beside_pauses(report) if "lost" not in p] == []
    assert report["area"] == twelve.plan.metrics["area"]        # what the targets are of
    assert report["outposts"] == len(twelve.plan.outposts) > 0
    assert code == (0 if report["outcome"]["ok"] else 1)
    assert report["coverage"]["beyond_battery_targets"] == \
        twelve.plan.metrics["battery"]["targets_short"]
    # as planned, unless a re-plan changed the sorties: a loss, or the battery watch
    # bringing home a vehicle the separation guard's holds made late (two vehicles
    # holding each other head-on, turn about, once did)
    replanned = bool(report["replans"])
    for v in twelve.plan.vehicles:
        if v.id in lost:
            continue
        track = read_track(track_path(out / "tracks", v.id))
        ups = takeoffs_on_fresh_batteries(track)
        assert ups == len(v.sorties) if not replanned else ups >= 2
        assert abs(track.alt[-1] - track.home[2]) < 1.0
        if not kill:     # each swap before a sortie powered it down; said, and not lost
            downs = [e["event"] for e in track.events if e["event"] in ("powered down",
                                                                         "boot", "takeoff")]
            last = len(downs) - downs[::-1].index("takeoff")
            assert downs[:last] == ["boot", "takeoff"] + ["powered down", "boot",
                                                          "takeoff"] * (ups - 1), downs
            said = [e["event"].split(" ")[0] for e in report["events"]
                    if e["sysid"] == v.id and "battery swap" in e["event"]
                    and e["event"].startswith(("silent", "heard"))]
            assert said[:2 * (ups - 1)] == ["silent", "heard"] * (ups - 1), said
        if not replanned:   # the pace the battery watch timed, against the track's
            _assert_paces_as_flown(report, v, track, SPEEDUP)
            _assert_landings_as_forecast(report, v.id, track)
    # the failsafes made hidden before anything flies (--sim sets them), what stays a
    # risk said (issue 60)
    said = [e for e in report["events"] if e["event"].startswith("failsafes set: ")]
    assert sorted(e["sysid"] for e in said) == [1, 2, 3]
    assert all("BATT_FS_LOW_ACT 2 -> 4" in e["event"] for e in said)
    risks = [e for e in report["events"] if e["event"].startswith("known risk: ")]
    assert sorted(e["sysid"] for e in risks) == [1, 2, 3]
    assert all("BATT_FS_CRT_ACT = 1: it lands where it is" in e["event"] for e in risks)
    uploads = [e for e in report["events"] if "uploaded and verified" in e["event"]
               and e["event"].startswith("sortie ")]
    assert len(uploads) >= (sum(len(v.sorties) - 1 for v in twelve.plan.vehicles)
                            if not replanned else 2)


def _assert_paces_as_flown(report, route, track, speedup) -> None:
    """The pace the battery watch timed each sortie at (flight.json's, a 63 s hold
    the plan gives once read as 1.34 times slower) is within 0.1 of what the
    simulator's own record says: the sortie's time takeoff to landing over its
    planned time (the simulator at the plan's rates: 0.94-1.02), the separation
    guard's holds of it left out (the watch times it afresh after each; on a
    loaded CI machine a sortie of 1.15 times its plan, timed whole, failed
    against a pace of 1.0). Each hold's start and end are known to the ground station within
    its loop (`LOOP_S`, wall seconds: ``speedup`` times that of the vehicle's
    clock), so each widens the bound by that much: a sortie the guard held 5
    times (9 edges in it) read 1.148 against 0.99."""
    ups = [e["t"] for e in track.events if e["event"] == "takeoff"]
    downs = [e["t"] for e in track.events if e["event"] == "landed"]
    pace = next(r["pace"] for r in report["vehicles"] if r["vehicle"] == route.id)
    held = _guard_holds(report, route.id)
    for j, (s, up, down) in enumerate(zip(route.sorties, ups, downs), start=1):
        dt, paused = _steps(track, up, down, held)
        planned = s["landing_s"] - s["takeoff_s"]
        flown = dt[~paused].sum() / planned
        wall = track.wall[(track.t >= up) & (track.t <= down)]
        edges = sum((wall[0] <= t <= wall[-1]) for span in held for t in span)
        bound = 0.1 + edges * LOOP_S * speedup / planned
        assert abs(pace.get(str(j), 1.0) - max(1.0, flown)) <= bound, \
            (route.id, j, pace, flown, edges)


def _assert_landings_as_forecast(report, sysid, track) -> None:
    """Each sortie's landing charge is said once, while it flies, and is the charge
    the simulator's own battery has at its touchdown within 8 points: measured,
    5.3 below to 1.0 above over 22 sorties (climbs draw more than the rated draw
    the forecast counts the rest at). Not the charge in the `landed` event: that
    is the vehicle's last report, once a wall second, which at 100 times is up to
    100 s of battery old (14 points above the forecast once). A sortie the
    separation guard held after its forecast is not judged (what a hold costs is
    nobody's forecast). A sortie out of contact in a radio shadow when its draw
    came to be trusted, and heard again only as it landed, says none."""
    said = [e for e in report["events"] if e["sysid"] == sysid and
            ("landing_pct" in e or e["event"] == "landed")]
    sorties, told = [], None
    for e in said:
        if e["event"] == "landed":
            sorties.append((told, e))
            told = None
        else:
            assert told is None, ("said twice in a sortie", told, e)
            told = e
    ups = [e["t"] for e in track.events if e["event"] == "takeoff"]
    downs = [e["t"] for e in track.events if e["event"] == "landed"]
    assert len(sorties) == len(downs), said
    cuts = [e["t"] for e in track.events if e["event"] == "out of radio contact"]
    held = [span for s, span in hold_spans(report["separation"].get("actions", []),
                                           report["duration_s"]) if s == sysid]
    for (told, landed), up, down in zip(sorties, ups, downs):
        if told is None:        # the simulator's record: its link was cut in that sortie
            assert any(up <= t <= down for t in cuts), ("no forecast", landed)
            continue
        if any(a < landed["t_s"] and b > told["t_s"] for a, b in held):
            continue
        charge = 100.0 * (1.0 - track.used[np.searchsorted(track.t, down)])
        assert abs(charge - told["landing_pct"]) <= 8, (told, charge)


def _guard_holds(report, sysid, also=()) -> list:
    """Wall-clock windows the separation guard held vehicle ``sysid`` (and ``also``:
    windows on the flight's clock, such as re-plans)."""
    holds = hold_spans(report["separation"].get("actions", []), report["duration_s"])
    spans = list(also) + [span for s, span in holds if s == sysid]
    return [(report["start_unix"] + a, report["start_unix"] + b) for a, b in spans]


def _steps(track, up, down, pauses):
    """A simulated vehicle's record from ``up`` to ``down`` (its own clock): each
    step's length, and whether it fell in one of the wall-clock windows ``pauses``."""
    inside = (track.t >= up) & (track.t <= down)
    t, wall = track.t[inside], track.wall[inside]
    mid = (wall[1:] + wall[:-1]) / 2
    paused = np.zeros(len(mid), bool)
    for a, b in pauses:
        paused |= (mid >= a) & (mid <= b)
    return np.diff(t), paused


def _battery_used(track, pauses=()) -> list:
    """Share of a full battery each flight of a simulated vehicle used: its own
    record (the simulator's battery: its draw, faster climbing) from takeoff to
    touchdown, less what it drew hovering on the ground station's word (``pauses``:
    wall-clock windows): seconds at the real pace, a minute or more of mission time
    at the test's speed-up."""
    up, out = None, []
    for e in track.events:
        if e["event"] == "takeoff":
            up = e["t"]
        elif e["event"] == "landed" and up is not None:
            _, paused = _steps(track, up, e["t"], pauses)
            used = track.used[(track.t >= up) & (track.t <= e["t"])]
            out.append(float(np.diff(used)[~paused].sum()))
            up = None
    return out


@FLIGHT_TIMEOUT
def test_a_battery_that_drains_fast_is_brought_home_early(twelve, tmp_path):
    """Vehicle 2's battery empties twice as fast as its rating (a simulator fault):
    the battery watch sees it from the draw, brings it home by its hidden path
    before the battery runs down, keeps it down, and the others take its work.
    Judged by the simulator's own record: no flight of any vehicle used more than
    its battery less half the reserve, the time it hovered on the ground station's
    word left out: re-plans, and the separation guard's holds (at 50 times the
    speed each is a minute or more of battery; two vehicles the guard holds
    head-on once cost vehicle 2 64 % of its battery; the guard now gives a vehicle
    short of battery right of way). The draw is trusted after 120 s of flight and 8 %:
    trusted after 240 s, the watch acted with 40 % left and vehicle 2 flew 1.17
    batteries, re-plans left out. With a link everywhere (--no-sim-radio): the
    watch judges a battery it hears, and vehicle 2's first shadow comes 90 s after
    its takeoff, before its draw is trusted; it empties there unheard, and its
    autopilot's own failsafe is what brings it home (tests/test_failsafes.py)."""
    out = tmp_path / "flight"
    code = main(["fly", str(twelve.dir), "--sim", "3", "--speedup", "50", "--drain", "2@2",
                 "--lost-after", "3", "--sim-base-port", str(free_base_port(10, 3)),
                 "--no-sim-radio", "-o", str(out)])
    report = json.loads((out / "flight.json").read_text())
    assert problems_beside_pauses(report) == [] and report["outcome"]["coverage_reached"]
    assert code == (0 if report["outcome"]["ok"] else 1)
    watched = [e for e in report["events"] if "will not last the rest of its sortie" in
               e["event"]]
    fast = [e for e in watched if "times faster than rated" in e["event"]]
    assert [e["sysid"] for e in fast] == [2], watched
    # the draw measured from the battery it reports: twice the rating, within the
    # whole percents it reports and the fleet clock's estimate of the speed-up
    factor = float(fast[0]["event"].split("drawn ")[1].split(" times")[0])
    assert 1.5 <= factor <= 2.5
    reserve = twelve.plan.params["reserve_pct"]
    assert int(fast[0]["event"].split("battery ")[1].split(" %")[0]) > reserve / 2
    replans = [(r["t_s"], r["done_t_s"]) for r in report["replans"]]
    for sysid in (1, 2, 3):
        track = read_track(track_path(out / "tracks", sysid))
        used = _battery_used(track, _guard_holds(report, sysid, replans))
        assert used and max(used) <= 1.0 - reserve / 200.0, (sysid, used)
        assert abs(track.alt[-1] - track.home[2]) < 1.0            # at its base
        ups = takeoffs_on_fresh_batteries(track)
        # 2 kept down after; the others fly what the re-plans gave them (one re-plan
        # left vehicle 3 a single sortie: the coverage reached says they took 2's work)
        assert ups == 1 if sysid == 2 else ups >= 1
    assert report["replans"] and 2 not in report["replans"][-1]["relaunched"]


def test_without_auto_turnaround_the_operator_confirms_each_swap(planned, twelve, tmp_path):
    """On real vehicles the next sortie waits for the operator's word as well as a
    fresh battery: the flight waits, says so, and goes once it is given."""
    from gcs.flight import Flight, FlyOptions

    fleet = fleet_for_plan(twelve.plan, speedup=100.0, base_port=free_base_port(10, 3),
                           track_dir=tmp_path / "tracks", battery_min=12.0,
                           terrain=terrain_ground(planned.terrain),
                           radio=radio_for_plan(twelve.plan, planned.terrain))
    try:
        flight = Flight(twelve.dir, fleet.urls(), FlyOptions(output=tmp_path / "f",
                                                             lost_after_s=3.0, plot=False,
                                                             set_failsafes=True))
        done = threading.Event()

        def confirm_when_asked():       # once per sortie waiting, as an operator would
            answered = {}           # id -> route, kept: a freed route's id is reused
            while not done.is_set():
                for sysid, route in list(flight.batteries.waiting.items()):
                    if id(route) not in answered:
                        answered[id(route)] = route
                        flight.confirm_swap(sysid)
                time.sleep(0.2)
        threading.Thread(target=confirm_when_asked, daemon=True).start()
        report = flight.run()
    finally:
        done.set()
        fleet.stop()
    events = [e["event"] for e in report["events"]]
    later = sum(len(v.sorties) - 1 for v in twelve.plan.vehicles)
    for sysid in (1, 2, 3):     # each later sortie went only after the operator's word
        mine = [e["event"] for e in report["events"] if e.get("sysid") == sysid]
        ups = [i for i, e in enumerate(mine) if e.startswith("sortie ") and "uploaded" in e]
        words = [i for i, e in enumerate(mine) if e == "battery swap confirmed by the operator"]
        assert len(words) == len(ups) and all(w < u for w, u in zip(words, ups)), mine
        later -= len(ups)
    # the planned sorties, all flown; unless the flight slipped so far off its plan
    # (a busy machine at 100x) that the rest was re-planned into other sorties
    assert later == 0 or "re-planning" in events, (report["outcome"]["problems"], events)
    assert report["outcome"]["coverage_reached"], (report["outcome"]["problems"], events)


def test_a_vehicle_silent_while_its_next_sortie_uploads_is_lost(planned, twelve, tmp_path,
                                                                 monkeypatch):
    """Shot down on the ground as its next sortie goes up (the upload then finds no
    one): a loss, re-planned like any other, not a failed flight. The sortie stayed
    awaited while it uploaded (once it was taken off the list first, the vehicle
    could not be lost, and the flight stopped on the upload's error)."""
    import gcs.flight.flight
    from gcs.flight import Flight, FlyOptions

    fleet = fleet_for_plan(twelve.plan, speedup=100.0, base_port=free_base_port(10, 3),
                           track_dir=tmp_path / "tracks", battery_min=12.0,
                           terrain=terrain_ground(planned.terrain),
                           radio=radio_for_plan(twelve.plan, planned.terrain))
    real, calls = gcs.flight.flight.upload_route, []

    def upload_route(link, missions, *args, **kwargs):
        calls.append(link.sysid)
        if calls.count(2) == 2 and calls[-1] == 2:   # its first upload after takeoff
            fleet.kill(2)
        return real(link, missions, *args, **kwargs)
    monkeypatch.setattr(gcs.flight.flight, "upload_route", upload_route)
    try:
        report = Flight(twelve.dir, fleet.urls(),
                        FlyOptions(output=tmp_path / "f", lost_after_s=3.0, plot=False,
                                   auto_turnaround=True, set_failsafes=True)).run()
    finally:
        fleet.stop()
    assert calls.count(2) == 2
    assert report["outcome"]["lost"] == [2] and report["outcome"]["coverage_reached"]
    said = [e for e in report["events"] if e["event"].startswith("lost during")]
    assert [e["sysid"] for e in said] == [2] and "next sortie" in said[0]["event"]
    assert report["replans"] and 2 not in report["replans"][-1]["survivors"]


def test_a_re_plan_that_must_hold_a_vehicle_in_the_air_keeps_its_sorties_whole(twelve):
    """Vehicle 3 held in its base column 23 m up as vehicle 2, retired by the battery
    watch, flies home: the fleet clock holds vehicle 3 there for minutes. Shorter
    sorties would not shorten that wait, so the sorties are not cut for it (they
    once were, to one viewpoint each: 32 sorties and 159 min against 9 and 42 with
    vehicle 3 on the ground); the hold past its battery is reported instead."""
    from gcs.retask import geo_to_xyz
    from planner.pipeline import PlanningContext
    from planner.replan import Survivor, replan

    ctx = PlanningContext.load(twelve.dir, twelve.plan)
    full = 60.0 * ctx.scenario.endurance_min
    v1, v2, v3 = twelve.plan.vehicles

    def xyz(p):
        return geo_to_xyz(ctx, p.lon, p.lat, p.alt_amsl)

    plans = []
    for up in (23.0, 0.0):
        plans.append(replan(ctx, [
            Survivor(v1.id, xyz(v1.waypoints[2]), xyz(v1.launch), 0.1 * full),
            Survivor(v2.id, xyz(v2.waypoints[4]), xyz(v2.launch), 0.35 * full, retired=True),
            Survivor(v3.id, xyz(v3.launch) + np.array([0.0, 0.0, up]), xyz(v3.launch))
        ]).plan.metrics)
    held, ground = plans
    assert held["sorties"] <= ground["sorties"] + 2
    assert held["coverage_time_s"] <= 1.3 * ground["coverage_time_s"], (held, ground)
    assert held["wait_s"] > 0 and held["battery"].get("over_battery", 0.0) > 1.0


def test_a_flight_whose_last_survivors_fall_during_a_re_plan_ends(planned, twelve, tmp_path,
                                                                   monkeypatch):
    """Vehicle 2 is shot down; as the re-plan uploads to the others, they fall silent
    too. The attempt cut short left nothing behind (its survivors and their later
    sorties once stood: the flight then waited for ever on sorties of lost
    vehicles): the flight ends, every vehicle lost."""
    import gcs.retask
    from gcs.flight import Flight, FlyOptions
    from gcs.sim import FaultPlan

    fleet = fleet_for_plan(twelve.plan, speedup=100.0, base_port=free_base_port(10, 3),
                           track_dir=tmp_path / "tracks", battery_min=12.0,
                           terrain=terrain_ground(planned.terrain),
                           radio=radio_for_plan(twelve.plan, planned.terrain),
                           faults={2: FaultPlan(kill_at_item=3)})
    real = gcs.retask.upload_route

    def upload_route(link, missions, *args, **kwargs):
        fleet.kill(link.sysid)                         # silent as its re-plan goes up
        return real(link, missions, *args, **kwargs)
    monkeypatch.setattr(gcs.retask, "upload_route", upload_route)
    started = time.monotonic()
    try:
        report = Flight(twelve.dir, fleet.urls(),
                        FlyOptions(output=tmp_path / "f", lost_after_s=3.0, plot=False,
                                   auto_turnaround=True, timeout_s=120.0,
                                   set_failsafes=True)).run()
    finally:
        fleet.stop()
    assert report["outcome"]["lost"] == [1, 2, 3]
    assert time.monotonic() - started < 60.0          # not the 120 s timeout's answer
    assert not any("timed out" in e["event"] for e in report["events"])


