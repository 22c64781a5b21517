"""The flight's report (flight.json) and its verdict (`outcome`).

Coverage at the end is re-evaluated from the snapshot positions with the
planner's own sensor model; a lost vehicle's snapshots count as lost. The
``outcome`` says whether the flight did its job: the required coverage reached,
no vehicle lost, none left in the air, no battery run empty or failsafe, no two
vehicles closer than the separation, nothing flown off its proof; ``problems``
says what went wrong, one line each, and ``notes`` what happened and did no
harm (the separation guard's holds that kept the separation).
"""

import json
import math
from dataclasses import asdict
from datetime import datetime, timezone

from common.fileio import write_text_atomic
from gcs.busy import busy_total_s
from gcs.monitor import LOST, STRANDED, WAITING
from gcs.retask import snapshot_xyz
from planner.replan import coverable_targets, coverage_summary

from .options import FLIGHT_FILE, FORMAT, PLOT_FILE


def _finite_or_none(x):
    return None if x is None or not math.isfinite(x) else round(float(x), 2)


def report(flight) -> dict:
    """flight.json's document of a `gcs.flight.Flight` (read, never changed)."""
    m = flight.monitor
    vehicles = [_vehicle_report(flight, v) for _, v in sorted(m.vehicles.items())]
    # the last HEARTBEAT to the millisecond as the last thing heard is: unrounded, a
    # HEARTBEAT that was the last thing heard read as heard after it (10.9201 > 10.92)
    losses = [{"sysid": v.sysid, "vehicle": v.vehicle_id, "detected_s": v.lost_at_s,
               "last_heartbeat_s": None if v.last_heartbeat_s is None else
               round(v.last_heartbeat_s, 3), "last_heard_s": v.last_heard_s,
               "reason": v.lost_reason,
               "due_s": next((s["due_s"] for s in v.silences if s["to_s"] is None), None),
               "stalled_s": v.lost_stalled_s}
              for _, v in sorted(m.vehicles.items()) if v.state == LOST]
    covered = coverage(flight.state)
    plan = flight.plan
    guard = flight.guard
    return {
        "format": FORMAT, "plan": str(flight.plan_dir),
        "started_utc": datetime.fromtimestamp(flight.start_unix, timezone.utc).isoformat(),
        "start_unix": flight.start_unix, "duration_s": round(m.now(), 3),
        # of it, what its loop spent computing (re-plans, uploads): not watching
        "busy_s": round(busy_total_s() - flight.busy0_s, 3),
        "lost_after_s": flight.options.lost_after_s, "k": int(plan.metrics.get("k", 0)),
        # what of the area of operations the plan's targets are, and its observers
        "area": plan.metrics.get("area"), "outposts": len(plan.outposts),
        "outcome": outcome(flight, covered),
        "vehicles": vehicles, "losses": losses,
        "replans": [asdict(r) for r in flight.retasks],
        "segments": flight.segments.report(),
        "separation": dict(guard.report() if guard is not None else {},
                           planned_closest_m=_finite_or_none(flight.min_separation_m)),
        "coverage": covered, "events": list(m.events),
        # per vehicle: its failsafes as read, what --set-failsafes changed (the previous
        # values: `gcs failsafes --restore`), the known risks left
        "failsafes": {str(sysid): f for sysid, f in sorted(flight.preflight.failsafes.items())},
    }


def outcome(flight, covered: dict) -> dict:
    """Did the flight do its job? ``ok`` only with the required coverage reached
    (every coverable target seen by min(k + 1, survivors) survivors), no vehicle
    lost and none left in the air; ``problems`` says what went wrong, one line each."""
    m = flight.monitor
    lost = [s for s, v in sorted(m.vehicles.items()) if v.state == LOST]
    stranded = [s for s, v in sorted(m.vehicles.items()) if v.state == STRANDED]
    # one whose start never came (or was called off) stands on the ground
    grounded = [s for s, v in sorted(m.vehicles.items()) if v.state == WAITING]
    flying = [s for s, v in sorted(m.vehicles.items())
              if not v.finished and s not in grounded]
    survivors = covered.get("survivors")
    reached = bool(survivors) and survivors["k_covered"] >= covered["coverable_targets"]
    problems = []
    if flight.error is not None:
        problems.append(f"failed: {flight.error}")
    if lost:
        problems.append(f"vehicle(s) {', '.join(map(str, lost))} lost")
    if not reached:
        problems.append("required coverage not reached: " + (
            f"{survivors['k_covered']} of {covered['coverable_targets']} coverable targets "
            f"seen by {survivors['required_uavs']} surviving vehicle(s)" if survivors
            else covered.get("error", "no coverage computed")))
    if stranded:
        problems.append(f"vehicle(s) {', '.join(map(str, stranded))} stranded: held in "
                        "the air where no hidden leg joins them, left to the operator")
    problems += battery_problems(flight.batteries)
    problems += separation_problems(flight.guard)
    for sysid, v in sorted(m.vehicles.items()):
        if v.off_route:
            worst = max(e[2] for e in v.off_route)
            problems.append(f"vehicle {sysid} flew off its proven route ({len(v.off_route)} "
                            f"time(s), up to {worst:.0f} m from its legs): what it flew "
                            "there was not proven hidden")
        for d in v.down_unheard:
            problems.append(f"vehicle {sysid} came down at its base at {d['t_s']:.1f} s, "
                            f"before its last item, while out of contact (from "
                            f"{d['from_s']:.1f} s): what it flew unheard was not proven hidden")
        if v.uncommanded:
            modes = ", ".join(f"{mode} at {t:.1f} s" for t, mode in v.uncommanded)
            problems.append(f"vehicle {sysid} flew in modes gcs did not command ({modes}): "
                            "what it flew there was not proven hidden")
    if flying:
        why = "timed out" if flight.timed_out else (flight.stopped or "stopped")
        problems.append(f"{why} with vehicle(s) {', '.join(map(str, flying))} in the air")
    if grounded:
        problems.append(f"vehicle(s) {', '.join(map(str, grounded))} never took off")
    return {"ok": not problems, "coverage_reached": reached, "lost": lost,
            "timed_out": flight.timed_out, "in_air": sorted(flying + stranded),
            "stranded": stranded, "problems": problems,
            "notes": guard_notes(flight.guard) + rejoin_notes(m)}


def rejoin_notes(monitor) -> list:
    """A vehicle declared lost and heard again: it flew on, and was taken back.
    Said, not a problem: the silence itself was (re-tasked for, as a loss must be)."""
    return [f"vehicle {sysid} declared lost at {r['lost_at_s']:.0f} s ({r['reason']}), "
            f"heard again at {r['heard_s']:.0f} s: rejoined "
            f"{'in the air' if r['as'] == 'flying' else 'at its base'} and re-planned "
            "with the others"
            for sysid, v in sorted(monitor.vehicles.items()) for r in v.rejoins]


def battery_problems(batteries) -> list:
    """An empty battery in the air, and a battery failsafe the autopilot announced:
    with or without a battery in the plan, the vehicle flew on what it did not have."""
    lines = [f"vehicle {sysid}'s battery reported empty in the air at {t:.0f} s"
             for sysid, t in sorted(batteries.emptied.items())]
    lines += [f"vehicle {sysid}'s battery failsafe at {said[0][0]:.0f} s: "
              + "; ".join(f"'{text}'" for _, text in said)
              for sysid, said in sorted(batteries.failsafes.items())]
    return lines


def separation_problems(guard) -> list:
    """Each pair that flew closer than the declared separation (the closest approach
    the guard measured on their position reports)."""
    if guard is None or not guard.active:
        return []
    return [f"vehicles {a} and {b} flew {d:.1f} m apart at {t:.0f} s, closer than the "
            f"separation ({guard.separation_m:g} m)"
            for (a, b), (d, t) in sorted(guard.closest.items()) if d < guard.separation_m]


def guard_notes(guard) -> list:
    """The guard's holds, when the separation was kept: events, not problems (a hold
    stops a vehicle on its proven leg, hidden where it stands)."""
    if guard is None:
        return []
    held = sorted({a["sysid"] for a in guard.actions if a["action"] == "hold"})
    if not held:
        return []
    holds = sum(a["action"] == "hold" for a in guard.actions)
    closest = min((d for d, _ in guard.closest.values()), default=None)
    flown = f", the closest two flew {closest:.1f} m apart" if closest is not None else ""
    return [f"the separation guard held vehicle(s) {', '.join(map(str, held))} "
            f"({holds} hold(s)) on their proven legs{flown} "
            f"(separation {guard.separation_m:g} m)"]


def _vehicle_report(flight, v) -> dict:
    m = flight.monitor
    return {
        "sysid": v.sysid, "vehicle": v.vehicle_id, "flavour": v.flavour, "state": v.state,
        "missions": v.generation + 1, "segments": v.segments,
        "mission_capacity": getattr(m.links.get(v.sysid), "mission_capacity", None),
        "lost_at_s": v.lost_at_s,
        "lost_reason": v.lost_reason, "landed_at_s": v.landed_at_s,
        "rejoins": list(v.rejoins),   # declared lost, heard again and taken back
        "snapshots": [asdict(s) for s in v.snapshots],
        "camera": [list(c) for c in v.camera], "track": [list(p) for p in v.track],
        "off_route": [list(e) for e in v.off_route],
        "out_of_contact": list(v.silences)
        + ([{"from_s": round(v.quiet.heard_s, 3), "to_s": None, "due_s": round(v.quiet.due_s, 3),
             "window": list(v.quiet.window)}] if v.quiet is not None else []),
        # the modes a failsafe put it in while flying, and what the firmware flies there
        "failsafe_modes": _failsafe_modes(m.links.get(v.sysid), v.uncommanded),
        "down_unheard": list(v.down_unheard),   # home before its last item, in a silence
        "pace": {str(j): p for j, p in flight.batteries.paces.get(v.sysid, {}).items()},
    }


def _failsafe_modes(link, uncommanded) -> list:
    """[{t_s, mode, flies}] of the uncommanded modes that are a failsafe's."""
    modes = getattr(getattr(link, "profile", None), "failsafe_modes", {})
    return [{"t_s": t, "mode": mode, "flies": modes[mode]} for t, mode in uncommanded
            if mode in modes]


def coverage(state) -> dict:
    """k-coverage from the snapshots taken: by the survivors, and by every vehicle."""
    try:
        ctx = state.context()
    except Exception as exc:
        return {"error": str(exc)}
    m, plan = state.monitor, state.plan
    k = int(plan.metrics.get("k", ctx.scenario.k))
    alive = [v for _, v in sorted(m.vehicles.items()) if v.state != LOST]
    every = [v for _, v in sorted(m.vehicles.items())]
    # the targets only viewpoints beyond one battery see are not the flight's to cover
    short = int((plan.metrics.get("battery") or {}).get("targets_short", 0))
    out = {"coverable_targets": coverable_targets(ctx) - short,
           "beyond_battery_targets": short}
    for name, group in (("survivors", alive), ("all_vehicles", every)):
        out[name] = coverage_summary(ctx, [snapshot_xyz(ctx, v) for v in group], k)
    out["planned"] = {key: plan.metrics.get(key) for key in
                      ("targets", "covered", "k_covered", "coverage_time_s")}
    return out


def write(flight, document: dict) -> None:
    """flight.json, and its picture unless the options say no plot."""
    flight.output.mkdir(parents=True, exist_ok=True)
    write_text_atomic(flight.output / FLIGHT_FILE, json.dumps(document, indent=1))
    if flight.options.plot:
        from gcs.flight_plot import flight_png
        try:
            ctx = flight.state.context()
        except Exception:
            return
        flight_png(flight.output / PLOT_FILE, ctx.terrain, ctx.surface, flight.plan, document)
