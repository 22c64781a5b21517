"""A fleet from one base keeps apart in flight (issue 37), judged from what the
vehicles really flew: the simulators' recorded true tracks, or what real SITL
reported of itself on its second link, compared on the wall clock they share.
Flown slower than the other end-to-end tests (the guard acts on telemetry a
few times a second: at 100x a vehicle moves 300 m between two reports).

- the plan's fleet, one of them shot down and the survivors re-tasked on the
  re-plan's own schedule: no two airborne vehicles closer than half the
  separation (the guard's room: track error and latency), on both firmwares;
- a vehicle that takes off late, so that it would land in the column another
  one is landing in: the guard holds one of them, the report says so and the
  outcome calls it flown off the proven schedule.
"""

import pytest
from fleets import REAL, skip_unless_configured
from judge import closest_airborne
from test_end_to_end import assert_hidden_and_clear, fly_case

#: slow enough for the guard (wall seconds of telemetry are this many fleet seconds)
SPEEDUP = {"sim": 20.0, "sim-px4": 20.0, "ardupilot": 10.0, "px4": 4.0}
pytestmark = pytest.mark.timeout(400)


@pytest.fixture(params=["sim", "sim-px4", "ardupilot", "px4"])
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


@pytest.mark.parametrize("backend", ["sim"])
def test_a_late_start_makes_the_guard_act(planned, backend, tmp_path):
    """The first vehicle to land starts so late that it would come down the base
    column with the last one: they may not both be in it, so one of them holds."""
    p = planned(0, REAL)
    ends = sorted((v.mission_time_s, v.id) for v in p.plan.vehicles)
    (first_end, late), (last_end, _) = ends[0], ends[-1]
    result = fly_case(p, backend, tmp_path, speedup=SPEEDUP[backend],
                      late=(late, last_end - first_end))
    report = result["report"]
    sep = report["separation"]
    d, pair, _ = closest_airborne(result["tracks"])
    print(f"\n[{backend}, vehicle {late} late by {last_end - first_end:.0f} s] closest "
          f"{d:.1f} m, guard actions {sep['actions']}")
    holds = [a for a in sep["actions"] if a["action"] == "hold"]
    assert holds, "the guard never acted"
    assert all(a["predicted_m"] < _separation(p) for a in holds)
    assert any("separation guard: hold" in e["event"] for e in report["events"])
    assert d >= _separation(p) / 2
    assert not report["outcome"]["ok"]
    assert any("held by the separation guard" in line for line in report["outcome"]["problems"])
    assert report["outcome"]["coverage_reached"] and report["outcome"]["in_air"] == []
