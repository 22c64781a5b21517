"""Sorties on real ArduPilot and PX4 SITL (issue 33): each vehicle flies its
battery-sized sorties one after another, lands at its base after each, waits
there for a fresh battery (the crew's swap: on ArduPilot
`fleets.ArduPilotBackend.swap_battery`, sent on the judge's link; PX4 SITL's
simulated battery refills itself once disarmed), and goes again. Judged from
what the autopilot reported of itself on its second link (`judge.Judge`): its
takeoffs, the battery it reported, its track (hidden and clear), its landings,
and the coverage of the snapshots its track confirms."""

from dataclasses import replace

import numpy as np
import pytest
from fleets import Setting, skip_unless_configured
from test_end_to_end import (
    assert_hidden_and_clear,
    assert_landed_at_launch,
    coverable,
    fly_case,
    recorded_coverage,
)

#: 2 vehicles on real SITL's 4 km window with a 10-minute battery: 4-5 sorties each,
#: about 33 min of fleet time (3.3 min of wall time at 10x)
SORTIES = Setting(2, 100.0, (215, 130, 40), 1200.0,
                  (("endurance_min", 10.0), ("turnaround_min", 2.0)))
#: planned for the firmware flown, at its own rates (PX4 takes off at 1.5 m/s below
#: 10 m and climbs at 3.0: planned at ArduPilot's, it warns "slower than planned")
FOR_FIRMWARE = {fw: replace(SORTIES, extra=SORTIES.extra + (("firmware", fw),))
                for fw in ("ardupilot", "px4")}
AIRBORNE_M = 10.0   # above its home: a takeoff counts once the vehicle is this high


def takeoffs(track) -> list:
    """Wall times at which a judged track rose through AIRBORNE_M above its home."""
    t, lat, lon, alt, _, home = track
    up = np.asarray(alt) > home[2] + AIRBORNE_M
    return list(np.asarray(t)[1:][up[1:] & ~up[:-1]])


# PX4 v1.17 SITL landed on 18-20 % against the 25 % reserve while plans assumed a 2.0
# m/s descent (its MPC_Z_V_AUTO_DN is 1.5); planned with the firmware's rates, on 25-26 %
# (2026-11-28), on 24 % (2026-11-29: its sorties took 1.2-1.26 times their planned
# flight time, judged by wall time at its speed-up; open)
@pytest.mark.parametrize("backend,crew", [("ardupilot", "swap"), ("ardupilot", "reboot"),
                                          ("px4", "swap")])
def test_sorties_fly_one_after_another_on_fresh_batteries(planned, backend, crew, tmp_path):
    """``crew`` "reboot": each swap reboots the autopilot (a flight controller fed by
    its pack): silent at its base, its TCP port closed, connected to again."""
    skip_unless_configured(backend)
    p = planned(0, FOR_FIRMWARE[backend])
    result = fly_case(p, backend, tmp_path, crew=crew, auto_turnaround=True)
    report, tracks, judges = result["report"], result["tracks"], result["judges"]
    outcome = report["outcome"]
    assert outcome["lost"] == [] and outcome["in_air"] == [] and outcome["coverage_reached"]
    assert_hidden_and_clear(p, tracks)
    sysids = [v.id for v in p.plan.vehicles]
    assert_landed_at_launch(p.ctx, tracks, sysids, backend)
    for v in p.plan.vehicles:
        assert len(v.sorties) >= 2
        ups = takeoffs(tracks[v.id])
        assert len(ups) == len(v.sorties), (v.id, len(ups), len(v.sorties))
        # each later sortie waited for the swap and took off on the battery it brought
        waits = [e for e in report["events"] if e.get("sysid") == v.id
                 and "waits for a fresh battery" in e["event"]]
        assert len(waits) == len(v.sorties) - 1, waits
        battery = np.array(judges[v.id].battery, float).reshape(-1, 2)
        for up in ups[1:]:
            before = battery[battery[:, 0] <= up]
            assert before[-1, 1] >= 95, (v.id, before[-3:])
        reserve = p.plan.params["reserve_pct"]
        assert battery[:, 1].min() >= reserve, (v.id, battery[:, 1].min(), reserve)
    cov = recorded_coverage(p.ctx, tracks, sysids, k=0)
    short = p.plan.metrics["battery"]["targets_short"]
    assert cov["k_covered"] >= coverable(p.ctx) - short
    if crew == "reboot":    # its TCP port closed at each swap, connected to again
        links = result["flight"].link.connections
        for v in p.plan.vehicles:
            assert links[v.id - 1].reconnects >= len(v.sorties) - 1
            said = [e["event"].split(" ")[0] for e in report["events"]
                    if e["sysid"] == v.id and e["event"].startswith(("silent at", "heard"))]
            assert said == ["silent", "heard"] * (len(said) // 2), said
    print(f"\nsorties [{backend}, {crew}]: wall {result['wall_s']:.0f} s, flight "
          f"{report['duration_s']:.0f} s, takeoffs {[len(takeoffs(tracks[s])) for s in sysids]}, lowest battery "
          f"{[int(np.min(np.array(judges[s].battery)[:, 1])) for s in sysids]} %, coverage "
          f"{cov['k_covered']}/{coverable(p.ctx)} ({short} beyond one battery)")
