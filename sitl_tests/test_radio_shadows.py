"""A flight through the radio shadows its plan predicts, on real SITL behind a relay
that cuts each link by line of sight (issues 59 and 60).

Each vehicle's link to the ground station is cut, both ways, while the terrain
hides it from the plan's antenna: `relay.Relay`, driven by the position the
autopilot reports of itself on its second link. SITL starts with a link-loss
failsafe that would fly a return in view (ArduPilot FS_GCS_ENABLE 1, RTL; PX4
NAV_DLL_ACT 2, Return, without the mission exception), as a vehicle of the
field may have it;
`gcs fly --set-failsafes` must make the silence change nothing. The judges:
the autopilot's own track (hidden, clear, landed, coverage from its
confirmed snapshots) and its own mode, never what the ground station believes.

Real SITL only: the built-in simulator's flights through shadows are
tests/test_link_flight.py's, at 20x. At this folder's 100x, beside two CPU hogs,
the simulated vehicles' clocks ran apart (34x, 54x and 96x in one flight: each
vehicle steps in its own thread), and a vehicle silent in a shadow for 16 wall
s at 54x was declared overdue at the fleet's pace: the monitor cannot know a
silent vehicle's clock, and real vehicles share one.
"""

import time

import pytest
from fleets import REAL_BACKENDS, SPEEDUP, skip_unless_configured
from test_end_to_end import (
    REAL_LOST_AFTER_S,
    assert_hidden_and_clear,
    assert_landed_at_launch,
    assert_one_loss_retasked,
    coverable,
    fly_case,
    recorded_coverage,
)

from autopilots import profile

#: what a vehicle of the field may have: a link loss flies a plain return
UNSAFE_LINK = {"ardupilot": {"FS_GCS_ENABLE": 1}, "px4": {"NAV_DLL_ACT": 2}}
#: s of the autopilot's own time without the ground station's HEARTBEAT before its
#: link-loss failsafe fires (ArduPilot FS_GCS_TIMEOUT, PX4 COM_DL_LOSS_T defaults)
LINK_TIMEOUT_S = {"ardupilot": 5.0, "px4": 10.0}


@pytest.fixture(params=REAL_BACKENDS)
def backend(request):
    skip_unless_configured(request.param)
    return request.param


def test_predicted_shadows_are_flown_through_in_the_mission(planned, backend, tmp_path):
    p = planned(0, backend)
    speedup = SPEEDUP[backend]
    result = fly_case(p, backend, tmp_path, radio=True, params=UNSAFE_LINK.get(backend))
    report, tracks = result["report"], result["tracks"]
    events = [e["event"] for e in report["events"]]
    cuts = result["relay"].cuts
    firmware = profile("px4" if backend == "px4" else "ardupilot")
    # the test tests something: a silence longer than the link failsafe's timeout
    timeout_wall = LINK_TIMEOUT_S[backend] / speedup
    longest = {s: max((b - a for a, b in c), default=0.0) for s, c in cuts.items()}
    print(f"\nradio shadows [{backend}]: longest cut per vehicle (wall s) "
          f"{ {s: round(v, 1) for s, v in longest.items()} }, "
          f"reported out of contact {[len(v['out_of_contact']) for v in report['vehicles']]}")
    assert max(longest.values()) > 2 * timeout_wall + report["lost_after_s"], longest
    # no silence read as a loss, nothing re-planned, every vehicle home
    assert report["losses"] == [] and report["replans"] == [], events
    assert_hidden_and_clear(p, tracks)
    assert_landed_at_launch(p.ctx, tracks, list(tracks), backend)
    cov = recorded_coverage(p.ctx, tracks, list(tracks), k=0)
    assert cov["k_covered"] == coverable(p.ctx)
    for v in report["vehicles"]:
        long = [c for c in cuts[v["sysid"]] if c[1] - c[0] > 2 * report["lost_after_s"]]
        assert len(v["out_of_contact"]) >= len(long), (v["sysid"], long)
    # the autopilot's own word: no change of mode while its link was cut (only the
    # autopilot could have made one), and never a failsafe's mode but the hold the
    # ground station commands (PX4's Hold is both)
    failsafe_modes = {firmware.modes()[name] for name in firmware.failsafe_modes
                      if name != firmware.hold_mode}
    for sysid, judge in result["judges"].items():
        def at(t):
            return round(t - report["start_unix"], 1)
        inside = [(at(t), mode) for t, mode in judge.modes
                  if any(a <= t <= b for a, b in cuts[sysid])]
        assert not inside, f"vehicle {sysid} changed mode in a silence: {inside}"
        entered = [(at(t), mode) for t, mode in judge.modes if mode in failsafe_modes]
        assert not entered, f"vehicle {sysid} flew a failsafe: {entered}"
    for sysid, failsafes in report["failsafes"].items():
        changed = {c["parameter"]: c for c in failsafes.get("set", [])}
        # ArduPilot: FS_GCS_ENABLE 1 -> 4 and FS_OPTIONS' AUTO bits; PX4: NAV_DLL_ACT 2
        # is a return along the mission, and COM_DLL_EXCEPT's mission bit keeps it on
        link = "FS_OPTIONS" if backend == "ardupilot" else "COM_DLL_EXCEPT"
        assert link in changed, (sysid, sorted(changed))
        for name, value in UNSAFE_LINK[backend].items():
            setting = next(r for r in failsafes["read"] if r["parameter"] == name)
            assert setting["value"] == value, setting


def test_a_vehicle_killed_in_its_shadow_is_lost_once_overdue(planned, backend, tmp_path):
    """The vehicle with the longest shadow, killed a wall second into it: its silence
    is the plan's until it is overdue, then it is lost (not before its due time),
    the others re-tasked, nobody else lost, every survivor home and the coverage
    flown."""
    p = planned(0, backend)
    victim = max(p.plan.vehicles, key=lambda v: max((b - a for a, b in v.silences),
                                                    default=0.0)).id

    def kill_in_its_shadow(be):
        while not be.relay.cut[victim]:
            if be.relay.stopped:
                return
            time.sleep(0.05)
        time.sleep(1.0)
        be.kill(victim)
    result = fly_case(p, backend, tmp_path, radio=True, params=UNSAFE_LINK[backend],
                      at=[(victim, 0.0, kill_in_its_shadow)])
    loss = next(x for x in result["report"]["losses"] if x["sysid"] == victim)
    print(f"\nkilled in a shadow [{backend}]: {loss['reason']}")
    assert loss["reason"].startswith("overdue") and loss["detected_s"] >= loss["due_s"]
    assert_one_loss_retasked(p, result, victim)


def test_a_vehicle_declared_lost_that_comes_back_is_rejoined(planned, backend, tmp_path):
    """Vehicle 1's link cut where its plan predicts contact (a third of the way along
    its route), for three times --lost-after: declared lost ("nothing heard"), the
    others re-tasked; its autopilot flies its mission on in AUTO (the link failsafe
    --set-failsafes chose); heard again, it is taken back in the air and the fleet
    re-planned with it. Judged by the autopilots' own tracks: every vehicle hidden,
    clear and landed at its base, the coverage flown by all three."""
    p = planned(0, backend)
    victim = 1

    def cut_in_contact(be):
        while be.relay.cut[victim]:           # not in a shadow: a radio that fails
            time.sleep(0.05)
        be.cut_link(victim, 3 * REAL_LOST_AFTER_S)
    result = fly_case(p, backend, tmp_path, radio=True, params=UNSAFE_LINK[backend],
                      at=[(victim, 0.3, cut_in_contact)])
    report, tracks = result["report"], result["tracks"]
    events = [e for e in report["events"] if e["sysid"] == victim]
    lost = next(e for e in events if e["event"] == "lost")
    print(f"\nrejoined [{backend}]: lost '{lost['reason']}', then "
          f"{[e['event'][:60] for e in events if e.get('rejoined')]}")
    assert lost["reason"].startswith("nothing heard for")
    assert any(e.get("rejoined") for e in events)
    assert any(victim in r["rejoined"] for r in report["replans"])
    assert report["losses"] == [] and report["outcome"]["coverage_reached"]
    assert_hidden_and_clear(p, tracks)
    assert_landed_at_launch(p.ctx, tracks, list(tracks), backend)
    assert recorded_coverage(p.ctx, tracks, list(tracks), k=0)["k_covered"] == coverable(p.ctx)
