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
#: 10 m and climbs at 3.0: planned at ArduPilot's, it warns "slower than planned"),
#: and at a speed both SITL airframes fly: asked 12 m/s, ArduPilot's cruised about 10
#: and PX4's SIH quad (drag limited) 9-10, their sorties 1.03-1.2 and 1.16-1.22 times
#: their planned time, PX4's landing on 24-25 % against the 25 % reserve (2026-11-29)
FOR_FIRMWARE = {fw: replace(SORTIES, extra=SORTIES.extra + (("firmware", fw),
                                                            ("speed_mps", 8.0)))
                for fw in ("ardupilot", "px4")}
#: a sortie flown, takeoff to landing on the autopilot's own clock, takes at most
#: this many times its planned time (the guard's holds included). At 8 m/s ArduPilot
#: flew 1.02-1.06 times it; PX4 1.07-1.11 while its plans counted a waypoint as
#: ArduPilot's (0.9 s): it slows to a near stop at each, jerk limited, and takes
#: ~12 s more before each landing (2026-11-29); counted as 3.4 s a waypoint
#: (`planner.rates.waypoint_stop_s`), 1.04-1.085. What is left is about the same
#: on every sortie, ~25 s (PX4) and ~11 s (ArduPilot) between its takeoff and its
#: landing, no longer growing with its waypoints
FLOWN_OVER_PLANNED = {"ardupilot": 1.1, "px4": 1.1}
#: the pace the battery watch times a sortie at (flight.json's) is this near to the
#: sortie's time over its planned time on the autopilot's own clock: read 1.0-1.03
#: (ArduPilot) and 1.06-1.11 (PX4; 1.02-1.05 with its waypoint model) of sorties
#: flown 1.02-1.06 and 1.07-1.11 (1.04-1.085) times their plan (2026-11-29; timed to
#: the next waypoint through a 63 s planned hold, the simulator's vehicles were once
#: read 1.34 times slower)
PACE_OFF = 0.1
AIRBORNE_M = 10.0   # above its home: a takeoff counts once the vehicle is this high


def takeoffs(track, down=False) -> list:
    """Wall times at which a judged track rose through AIRBORNE_M above its home
    (``down``: came down through it)."""
    t, lat, lon, alt, _, home = track
    up = np.asarray(alt) > home[2] + AIRBORNE_M
    if down:
        up = ~up
    return list(np.asarray(t)[1:][up[1:] & ~up[:-1]])


def planned_s(route) -> list:
    """Each sortie's planned time from AIRBORNE_M up to AIRBORNE_M down (`flown_s`'s
    span), on the plan's trajectory (piecewise linear: read every 0.1 s)."""
    t, z = np.asarray(route.trajectory, float)[:, [0, 3]].T
    out = []
    for s in route.sorties:
        at = np.arange(s["takeoff_s"], s["landing_s"], 0.1)
        up = at[np.interp(at, t, z) > route.launch.alt_amsl + AIRBORNE_M]
        out.append(float(up[-1] - up[0]))
    return out


def flown_s(track, judge) -> list:
    """Each sortie's time from AIRBORNE_M up to AIRBORNE_M down, on the autopilot's
    own clock (its time since boot: a simulator slower than its speed-up does not
    count; a reboot restarts it, so each end is read at its own side)."""
    wall, own = np.array(judge.clock, float).reshape(-1, 2).T
    ups, downs = takeoffs(track), takeoffs(track, down=True)
    return [float(np.interp(b, wall, own) - np.interp(a, wall, own))
            for a, b in zip(ups, [d for d in downs if d > ups[0]])]


# PX4 v1.17 SITL landed on 18-20 % against the 25 % reserve while plans assumed a 2.0
# m/s descent (its MPC_Z_V_AUTO_DN is 1.5); planned with the firmware's rates, on 24-26 %
# (2026-11-28/29: at 12 m/s, which its SIH quad does not fly); at 8 m/s on 28 %, and on
# 31-33 % with its waypoints counted as PX4 flies them (3.4 s each)
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
    for v in p.plan.vehicles:
        planned, flown = planned_s(v), flown_s(tracks[v.id], judges[v.id])
        pace = next(r["pace"] for r in report["vehicles"] if r["vehicle"] == v.id)
        print(f"vehicle {v.id}: sorties planned {[round(s) for s in planned]} s, flown "
              f"{[round(f) for f in flown]} s by its clock ({AIRBORNE_M:g} m up to "
              f"{AIRBORNE_M:g} m down), paces timed {pace}")
        assert max(np.divide(flown, planned)) <= FLOWN_OVER_PLANNED[backend], \
            (v.id, planned, flown)
        # the battery watch's pace within PACE_OFF of the autopilot's own clock's
        for j, (a, b) in enumerate(zip(planned, flown), start=1):
            assert abs(pace.get(str(j), 1.0) - max(1.0, b / a)) <= PACE_OFF, (v.id, j, pace)


#: two vehicles, one at each of two bases 800 m apart or more (`fleets.launch_points`);
#: planned at k = 1: every target seen by both, so each works near the other's base too
TWO_BASES = replace(FOR_FIRMWARE["ardupilot"], bases=2)


def test_a_sortie_lands_at_the_other_base_and_the_next_leaves_from_there(planned, tmp_path):
    """Real ArduPilot SITL, two bases: a sortie the plan lands at the other base
    touches down there (not taken for a crash), is swapped there, arms there (its
    home now there: ArduPilot sets home at arming) and climbs to its planned height
    above that base, no higher; judged from the autopilot's own second link."""
    skip_unless_configured("ardupilot")
    p = planned(1, TWO_BASES)
    crossing = [(v.id, j) for v in p.plan.vehicles for j, f in enumerate(v.sorties)
                if f["lands_at"] != f["base"]]
    assert crossing, "the plan lands no sortie at the other base"
    result = fly_case(p, "ardupilot", tmp_path, crew="swap", auto_turnaround=True)
    report, tracks = result["report"], result["tracks"]
    outcome = report["outcome"]
    assert outcome["lost"] == [] and outcome["in_air"] == [] and outcome["coverage_reached"]
    bases = {(v.launch.lat, v.launch.lon) for v in p.plan.vehicles}
    assert_hidden_and_clear(p, tracks, bases=sorted(bases))
    for v in p.plan.vehicles:
        _, lat, lon, alt, _, _ = tracks[v.id]
        x, y = p.ctx.terrain.from_lonlat(np.asarray(lon), np.asarray(lat))
        end = v.landing
        ex, ey = p.ctx.terrain.from_lonlat(end.lon, end.lat)
        assert np.hypot(x[-1] - ex, y[-1] - ey) < 5.0, v.id          # down where planned
        assert len(takeoffs(tracks[v.id])) == len(v.sorties), v.id
        top = max(w.alt_amsl for w in v.waypoints)
        assert np.max(alt) <= top + 3.0, (v.id, np.max(alt), top)   # never climbed past it
    print(f"\ntwo bases [ardupilot]: sorties landing at the other base {crossing}, wall "
          f"{result['wall_s']:.0f} s, flight {report['duration_s']:.0f} s")
