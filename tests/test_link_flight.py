"""Flights through radio shadows (issue 59): the simulator cuts each vehicle's link
while the terrain hides it from the plan's antenna (`gcs.sim` radio,
`planner.link.contact_at`), and the flight tells a silence the plan predicts from
a loss. The plan is tests/conftest.py's: an antenna at its base, 2 m up, and
every vehicle out of its line of sight for 3-7 minutes of flight (its
predicted silences); the references are the simulator's own tracks."""

import json
import threading
import time

import pytest

from common.geo import distance_m
from gcs.contact import EARLY_LATE_S
from gcs.flight import Flight, FlyOptions
from gcs.sim import (
    fleet_for_plan,
    free_base_port,
    radio_for_plan,
    read_track,
    terrain_ground,
    track_path,
)

pytestmark = pytest.mark.timeout(240)

SPEEDUP = 20.0
LOST_AFTER_S = 2.0


def _fleet(planned, tmp_path, radio=True):
    return fleet_for_plan(planned.plan, speedup=SPEEDUP, base_port=free_base_port(10, 3),
                          track_dir=tmp_path / "tracks", terrain=terrain_ground(planned.terrain),
                          radio=radio_for_plan(planned.plan, planned.terrain) if radio else None)


def _fly(planned, tmp_path, fleet, during=None) -> dict:
    flight = Flight(planned.dir, fleet.urls(), FlyOptions(
        output=tmp_path / "f", lost_after_s=LOST_AFTER_S, plot=False, set_failsafes=True))
    if during is not None:
        threading.Thread(target=during, args=(flight,), daemon=True).start()
    try:
        return flight.run()
    finally:
        fleet.stop()


def _shadows(tmp_path, sysid) -> list:
    """[(from, to)] mission s the simulator had the vehicle out of radio contact."""
    events = read_track(track_path(tmp_path / "tracks", sysid)).events
    out, start = [], None
    for e in events:
        if e["event"] == "out of radio contact":
            start = e["t"]
        elif e["event"] == "back in radio contact" and start is not None:
            out.append((start, e["t"]))
            start = None
    return out


def test_the_plan_predicts_shadows_for_the_flight_tests(planned):
    """Every vehicle of the flight tests' plan meets a shadow longer than a loss takes
    to declare at their speed-up: the tests below test something."""
    for v in planned.plan.vehicles:
        assert max(b - a for a, b in v.silences) > 3 * LOST_AFTER_S * SPEEDUP, v.silences


def test_a_flight_through_its_predicted_shadows_loses_nobody(planned, tmp_path):
    report = _fly(planned, tmp_path, _fleet(planned, tmp_path))
    events = [e["event"] for e in report["events"]]
    assert report["losses"] == [] and not report["replans"], events
    assert report["outcome"]["coverage_reached"]
    quiet = 0
    for v in report["vehicles"]:
        flown = _shadows(tmp_path, v["sysid"])
        assert flown, f"vehicle {v['sysid']}: the simulator never cut its link"
        assert v["state"] == "landed"
        # each silence longer than --lost-after was told as planned, and ended
        long = [(a, b) for a, b in flown if (b - a) / SPEEDUP > 2 * LOST_AFTER_S]
        assert len(v["out_of_contact"]) >= len(long) > 0
        assert all(s["to_s"] is not None for s in v["out_of_contact"])
        quiet += len(v["out_of_contact"])
    assert sum("out of contact, as planned" in e for e in events) == quiet


def test_a_vehicle_shot_down_in_a_shadow_is_lost_when_overdue(planned, tmp_path):
    """Killed a few seconds into its longest shadow: declared lost once overdue (after
    its due time, never later than its margin allows), the others re-tasked, nobody
    else lost."""
    fleet = _fleet(planned, tmp_path)
    victim = max(planned.plan.vehicles, key=lambda v: max(b - a for a, b in v.silences)).id
    killed = {}

    def kill_in_the_shadow(flight):
        sim = fleet.vehicle(victim)
        while not sim.link_faults.shadowed:
            time.sleep(0.05)
        time.sleep(0.5)
        killed["at"] = flight.monitor.now()
        fleet.kill(victim)
    report = _fly(planned, tmp_path, fleet, during=kill_in_the_shadow)
    assert [x["sysid"] for x in report["losses"]] == [victim]
    loss = report["losses"][0]
    assert loss["reason"].startswith("overdue") and loss["due_s"] is not None
    told = next(e for e in report["events"] if e.get("out_of_contact") and
                e["sysid"] == victim)
    overdue = next(e for e in report["events"] if e["sysid"] == victim and
                   e["event"] == "lost")
    assert loss["due_s"] <= loss["detected_s"] <= told["due_s"] + (
        overdue["t_s"] - told["t_s"])                 # (the margin, as the event said)
    assert report["replans"] and victim not in report["replans"][0]["survivors"]
    assert all(v["state"] == "landed" for v in report["vehicles"] if v["sysid"] != victim)


def _far_from_shadows(flight, victim, for_s) -> bool:
    """In the air, heard (a vehicle out of a shadow, not heard yet, is still silent for
    the monitor), on its plan's clock well clear of every predicted shadow, and to
    stay so for ``for_s`` wall seconds."""
    v = flight.monitor.vehicles.get(victim)
    heard = v is not None and v.done and v.quiet is None and \
        flight.monitor.links[victim].silent_s() < 0.5
    at = v.contact.fleet_time(flight.monitor.now()) if heard else None
    end = None if at is None else at + for_s * SPEEDUP
    return at is not None and all(end < a - 3 * EARLY_LATE_S or at > b + EARLY_LATE_S
                                  for a, b in v.contact.windows)


def _in_contact(fleet, flight, victim, for_s) -> None:
    """Wait until ``victim`` flies in contact, far from its predicted shadows for the
    next ``for_s`` wall seconds: what is tested there happens in contact (a shadow
    entered just after a cut ends would hold its return back)."""
    sim = fleet.vehicle(victim)
    while sim.landed or sim.link_faults.shadowed or \
            not _far_from_shadows(flight, victim, for_s):
        time.sleep(0.02)


def test_a_vehicle_shot_down_in_contact_is_lost_after_lost_after(planned, tmp_path):
    fleet = _fleet(planned, tmp_path)
    victim = planned.plan.vehicles[0].id
    killed = {}

    def kill_in_contact(flight):
        _in_contact(fleet, flight, victim, 2 * LOST_AFTER_S)
        killed["at"] = flight.monitor.now()
        fleet.kill(victim)
    report = _fly(planned, tmp_path, fleet, during=kill_in_contact)
    loss = next(x for x in report["losses"] if x["sysid"] == victim)
    assert loss["reason"].startswith("nothing heard for")
    assert loss["detected_s"] - killed["at"] <= LOST_AFTER_S + 2.0 + loss["stalled_s"]
    assert [x["sysid"] for x in report["losses"]] == [victim]
    json.dumps(report)


def test_a_vehicle_declared_lost_that_comes_back_is_rejoined_and_re_planned(planned, tmp_path):
    """Its link cut where contact is predicted, for three times --lost-after: it flies
    on by itself (its mission in AUTO) and is declared lost, and the others are
    re-tasked over its work. Heard again, it is taken back in the air, under the
    monitor and the guard, and the fleet is re-planned with it. Judged by the
    simulator's own record: it flew on through the cut and landed at its base."""
    fleet = _fleet(planned, tmp_path)
    victim = planned.plan.vehicles[0].id
    cut = {}

    def cut_in_contact(flight):
        _in_contact(fleet, flight, victim, 4 * LOST_AFTER_S)
        cut["at"] = flight.monitor.now()
        fleet.cut_link(victim, 3 * LOST_AFTER_S)
    report = _fly(planned, tmp_path, fleet, during=cut_in_contact)
    events = [e for e in report["events"] if e["sysid"] == victim]
    lost = next(e for e in events if e["event"] == "lost")
    assert lost["reason"].startswith("nothing heard for")
    told = "\n".join(f"{e['t_s']:.2f} {e['event']}" for e in events)
    heard = next((e for e in events if e.get("heard_after_loss")), None)
    back = next((e for e in events if e.get("rejoined")), None)
    assert heard is not None and back is not None, told
    # heard once the cut is over (in contact: no shadow on its way), taken back
    # at its first position report after that
    assert cut["at"] < lost["t_s"] < cut["at"] + 3 * LOST_AFTER_S <= heard["t_s"]
    assert heard["t_s"] <= back["t_s"] <= heard["t_s"] + 1.0, told
    # re-tasked without it, then with it
    before = next(r for r in report["replans"] if r["t_s"] >= lost["t_s"])
    assert victim not in before["survivors"] and victim in before["lost"]
    again = next(r for r in report["replans"] if victim in r["rejoined"])
    assert again["t_s"] >= back["t_s"] and victim in again["survivors"] + again["left_out"]
    vehicle = next(v for v in report["vehicles"] if v["sysid"] == victim)
    assert [r["as"] for r in vehicle["rejoins"]] == ["flying"]
    assert report["losses"] == [] and report["outcome"]["lost"] == []
    assert any(f"vehicle {victim} declared lost" in n for n in report["outcome"]["notes"])
    assert report["outcome"]["coverage_reached"]
    assert all(v["state"] == "landed" for v in report["vehicles"])
    # the simulator's record: it never stopped flying, and landed at its base
    track = read_track(track_path(tmp_path / "tracks", victim))
    ends = [e["event"] for e in track.events if e["event"] in ("landed", "crashed")]
    assert track.killed_at is None and ends[-1:] == ["landed"]
    assert distance_m(track.lat[-1], track.lon[-1], *track.home[:2]) < 10.0


def test_gcs_sim_cuts_links_by_a_plans_antennas_only_when_asked(planned):
    """`gcs sim --terrain PLAN_DIR` flies on the plan's terrain with every link up;
    `--radio` cuts each by the plan's antennas, as `gcs fly --sim-radio` does;
    `--radio` without a plan directory to take antennas from is refused."""
    from common.errors import InputError
    from gcs.cli import build_parser
    from gcs.cli import sim as sim_cli

    lat, lon = planned.plan.vehicles[0].launch.lat, planned.plan.vehicles[0].launch.lon

    def config(*extra):
        return sim_cli.config_from_args(build_parser().parse_args(
            ["sim", "--terrain", str(planned.dir), "--home", f"{lat},{lon}", *extra]))

    assert config().radio is None and config().terrain is not None
    assert config("--radio").radio is not None
    with pytest.raises(InputError, match="--radio"):
        sim_cli.config_from_args(build_parser().parse_args(["sim", "--radio"]))
