"""What the commands show: result tables, the live flight view and its prompt.

Shared by the commands (`gcs plan` and `gcs demo` show a plan; `gcs fly` and
`gcs demo` fly one), so that no command imports another.
"""

import math
import sys
import threading
import time
from pathlib import Path

from rich.console import Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from autopilots import DEFAULT, PROFILES, firmware_of, profile
from common.units import Z_UNIT_WORDS
from gcs.progress import console
from planner.rates import VERTICAL_RATES
from planner.returns import returns_said


# -- a plan --------------------------------------------------------------------------------
def plan_summary(plan) -> Group:
    """The per-UAV table and the coverage lines `gcs plan` ends with."""
    m = plan.metrics
    table = Table(title=f"{plan.method.upper()} plan, k = {m['k']}")
    for col in ("UAV", "takeoff", "snapshots", "coverage time", "mission time", "waits",
                "path"):
        table.add_column(col, justify="right")
    turnaround = 60.0 * (plan.params.get("turnaround_min") or 0.0)
    for v in plan.vehicles:
        # on the ground before it leaves, held in the air, and between sorties beyond
        # the turnaround
        waits = v.takeoff_s + sum(w.hold_s for w in v.waypoints) + sum(
            b["takeoff_s"] - a["landing_s"] - turnaround for a, b in zip(v.sorties, v.sorties[1:]))
        table.add_row(str(v.id), f"{v.takeoff_s:.0f} s", str(len(v.snapshots)),
                      _minutes(v.coverage_time_s), _minutes(v.mission_time_s),
                      f"{waits:.0f} s", f"{v.path_length_m / 1000:.1f} km")
    ratio = m.get("ratio_to_lower_bound")
    radius = m.get("radius_bound_s")
    beside = (f"; radius bound {_minutes(radius)}" if radius is not None
              and radius < m["lower_bound_s"] - 0.5 else "")
    share = m.get("bound_targets_pct", 100.0)
    over = (f" over the {share:.1f} % of targets one battery reaches as asked"
            if share < 100.0 else "")
    cover = (f"coverage time {_minutes(m['coverage_time_s'])} (lower bound "
             f"{_minutes(m['lower_bound_s'])}{over}, ratio {ratio:.2f}{beside}): at most "
             f"{math.ceil(100 * (ratio - 1) - 1e-9)} % above optimal" if ratio else
             f"coverage time {_minutes(m['coverage_time_s'])}")
    targets = (f"targets {m['targets']}: {m['k_covered']} seen by k+1 = {m['k'] + 1} "
               f"UAVs at k+1 places ({100 * m['k_covered'] / max(m['targets'], 1):.1f} % of "
               f"the targets); planned in {plan.timing_s.get('total', 0):.1f} s")
    impossible = m.get("k_impossible", 0)
    if impossible:
        targets += (f"; {impossible} of them can be photographed from fewer than k+1 = "
                    f"{m['k'] + 1} separate places, so they are seen once from each place "
                    "there is (two UAVs photographing from one place could be lost together)")
    lines = [table, Text(cover), Text(targets), Text(fleet_line(plan)), Text(link_line(plan)),
             Text(rates_line(plan)), Text(battery_line(plan))] + [Text(t) for t in area_lines(plan)]
    too_long = returns_said(m)
    if too_long:
        lines.append(Text(too_long, style="yellow"))
    return Group(*lines)


def fleet_line(plan) -> str:
    """When each vehicle takes off, what the fleet waits, and the proven separation
    with the margin the plan kept beyond it (so that the guard acts only when a
    flight goes wrong)."""
    m = plan.metrics
    takeoffs = ", ".join(f"{v.id} at {v.takeoff_s:.0f} s" for v in
                         sorted(plan.vehicles, key=lambda v: (v.takeoff_s, v.id)) if v.waypoints)
    sep = plan.params.get("separation_m", 0)
    closest = m.get("min_separation_m")
    proven = "never two airborne at once" if closest is None or closest == float("inf") \
        else f"closest approach {closest:.1f} m"
    margin = plan.params.get("separation_margin_m") or 0.0
    kept = f", planned with {margin:g} m more" if sep and margin else ""
    return (f"takeoffs: {takeoffs}; waits {m.get('wait_s', 0):.0f} s in all; {proven} "
            f"(separation {sep:g} m{kept})")


def link_line(plan) -> str:
    """How much of the flight each vehicle is out of the ground station's radio line of
    sight (`planner.link`), which `gcs fly` then expects rather than calls a loss."""
    link = plan.metrics.get("link")
    if not link:
        return ("radio link: not predicted (no --antenna and no --launch): every silence "
                "in flight will read as a loss after --lost-after")
    sites = "; ".join(f"{lat:.5f},{lon:.5f} mast {mast:g} m" for lat, lon, mast in
                      link["antennas"])
    quiet = [v for v in link["vehicles"] if v["silent_s"] > 0]
    each = ", ".join(f"{v['vehicle']}: {100 * v['share']:.0f} % (longest "
                     f"{v['longest_s']:.0f} s)" for v in quiet) or "none"
    radio = link["radio"]
    return (f"radio link ({sites}; {radio['mhz']:g} MHz, {radio['range_m'] / 1000:g} km): "
            f"out of contact {100 * link['share']:.0f} % of the fleet's airborne time; "
            f"by vehicle {each}" + _max_silence(link.get("max_silence")))


def _max_silence(kept) -> str:
    """What --max-silence kept (`planner.link.checkins`), after the link line."""
    if kept is None:
        return ""
    if kept.get("not_applied"):
        return f"; --max-silence {kept['limit_s']:g} s not applied: {kept['not_applied']}"
    n = sum(kept["check_ins"])
    cost = (f"{n} check-in(s) in contact, {kept['coverage_time_added_s'] / 60:+.1f} min of "
            "coverage time")
    if kept["met"]:
        return f"; --max-silence {kept['limit_s']:g} s kept: {cost}"
    floors = kept.get("floor_s") or [0.0] * len(kept["over_s"])
    over = ", ".join(f"{r + 1}: {o:.0f} s (no route through its viewpoints under "
                     f"{f:.0f} s)" for r, (o, f) in enumerate(zip(kept["over_s"], floors))
                     if o > 0)
    return (f"; --max-silence {kept['limit_s']:g} s NOT kept ({cost}): longest silence over "
            f"it by vehicle {over}; an antenna or relay nearer those routes would shorten "
            "them")


def rates_line(plan) -> str:
    """The vertical rates every time of the plan assumes, and whether they are its
    firmware's own (`autopilots.Autopilot.rates`): a vehicle set slower flies longer."""
    p = plan.params
    firmware = str(firmware_of(p))
    own = PROFILES.get(firmware, profile(DEFAULT)).rates
    rates = {name: p.get(name) or getattr(own, name)      # a plan from before they were said
             for name in VERTICAL_RATES}
    line = (f"rates: climb {rates['climb_mps']:g}, descent {rates['descent_mps']:g}, "
            f"takeoff {rates['takeoff_mps']:g}, landing {rates['land_mps']:g} m/s")
    if all(rates[n] == getattr(own, n) for n in rates):
        return line + f": {firmware}'s defaults (gcs fly says where a vehicle is set slower)"
    return line + f": not all {firmware}'s defaults: set each vehicle's to these"


#: a flight longer than this (min) is past what many multicopter batteries give
LONG_FLIGHT_MIN = 20.0


def battery_line(plan) -> str:
    """What one battery allows, and the sorties flown on it; or that the plan
    assumed an unlimited battery (and, past `LONG_FLIGHT_MIN`, that it should not)."""
    b = plan.metrics.get("battery") or {}
    longest = b.get("longest_flight_s", 0.0) / 60
    if b.get("endurance_min") is None:
        line = (f"battery: unlimited (no --endurance given): the longest flight takes "
                f"{longest:.1f} min")
        if longest > LONG_FLIGHT_MIN:
            line += (", more than many multicopter batteries give (20-40 min): give "
                     "--endurance MIN to fly it in sorties")
        return line
    several = {v.id: len(v.sorties) for v in plan.vehicles if len(v.sorties) > 1}
    flown = ("sorties " + ", ".join(f"vehicle {i}: {n}" for i, n in several.items())
             if several else "one sortie per vehicle")
    line = (f"battery: {b['endurance_min']:g} min less {b['reserve_pct']:g} % reserve = "
            f"{b['usable_s'] / 60:.1f} min a sortie; {flown}, the longest {longest:.1f} min, "
            f"{b['turnaround_min']:g} min on the ground between two")
    elsewhere = sum(f.get("lands_at") not in (None, f.get("base"))
                    for v in plan.vehicles for f in v.sorties)
    if elsewhere:
        line += (f"; {elsewhere} sorties land at another base than they left (the nearest "
                 "to their last viewpoint: the next takes off there)")
    if b.get("beyond_battery"):
        line += f"; {b['beyond_battery']} viewpoints beyond one battery from any base (not flown)"
    if b.get("targets_short"):
        line += f"; {b['targets_short']} targets seen fewer times than asked for the battery"
    return line


def area_lines(plan) -> list:
    """What of the area of operations the plan sees, in km² and %, and why the rest
    is not seen; and a line when the plan has no observers at all."""
    return _area_lines(plan.metrics, len(plan.outposts))


def _area_lines(metrics, outposts: int) -> list:
    out = []
    if not outposts:
        out.append("no observers: planned with no outposts, nothing is hidden from anyone "
                   "(the routes keep only the clearance and the ceiling)")
    for z in metrics.get("z_units", []):
        out.append(f"DEM heights of {z['file']} taken as {Z_UNIT_WORDS[z['unit']]} "
                   f"({z['said_by']})" + (", converted to metres" if z["unit"] != "m" else ""))
    voids = metrics.get("filled_voids")
    if voids:
        at = ", ".join(f"{v['lat']:.5f},{v['lon']:.5f} ({v['cells']} cells)" for v in voids["at"])
        out.append(f"DEM voids filled by interpolation at {at}: there the terrain is lowered "
                   f"and the clearance raised by {voids['margin_m']:g} m (voids.tif)")
    a = metrics.get("area")
    if not a:
        return out
    k = metrics.get("k", 0)
    out.append(f"area of operations {a['area_km2']:.2f} km²: {_part(a['planned'])} planned "
               f"(seen by k+1 = {k + 1} UAVs), {_part(a['visible'])} seen from some "
               "reachable hidden viewpoint")
    unplanned = [f"{_part(p)} {why}" for why, p in a.get("unplanned", {}).items()
                 if p["km2"] > 0]
    if unplanned:
        out.append("seen but not planned: " + "; ".join(unplanned))
    unseen = [f"{_part(p)} {why}" for why, p in a["unseen"].items() if p["km2"] > 0]
    if unseen:
        out.append("not seen: " + "; ".join(unseen))
    if a["planned"]["pct"] < LOW_AREA_PCT:
        out.append(f"warning: only {a['planned']['pct']:.1f} % of the area of operations is "
                   f"planned; the largest part of the rest: {_largest(a)} (--min-area PCT refuses "
                   "such a plan)")
    return out


#: a plan that plans less of its area of operations than this (%) says so
LOW_AREA_PCT = 10.0


def planned_pct(plan):
    """The share of the area of operations the plan plans (%), None without an area."""
    a = plan.metrics.get("area")
    return None if not a else a["planned"]["pct"]


def why_unplanned(plan) -> str:
    """The largest share of the plan's area that is not planned, and why."""
    return "the largest part of the rest: " + _largest(plan.metrics["area"])


def _largest(a) -> str:
    """The largest share of the area that is not planned, with its reason."""
    reasons = {**a.get("unplanned", {}), **a["unseen"]}
    why = max(reasons, key=lambda r: reasons[r]["km2"])
    return f"{_part(reasons[why])} {why}"


def _part(p) -> str:
    return f"{p['km2']:.2f} km² ({p['pct']:.1f} %)"


def _minutes(seconds) -> str:
    return f"{seconds / 60:.1f} min"


# -- a flight -------------------------------------------------------------------------------
def fly_plan(plan_dir, urls, options, ctx=None) -> dict:
    """Fly with a live status table on a terminal, event lines on stderr otherwise;
    FlightError when the flight could not go on (the report is written first).
    ``ctx``: the plan's context when it is in memory."""
    from gcs.flight import Flight

    live = console.is_terminal
    flight = Flight(plan_dir, urls, options, ctx=ctx,
                    log=(lambda text: None) if live else
                    (lambda text: print(text, file=sys.stderr, flush=True)))
    return fly_flight(flight, live)


def fly_flight(flight, live: bool) -> dict:
    """Run ``flight``: on a terminal with the status table, and Ctrl-C or --timeout
    answered by the user; otherwise Ctrl-C leaves the vehicles flying and the
    timeout brings them home."""
    _read_battery_swaps(flight)
    if live:
        with Live(status_table([]), console=console, refresh_per_second=4) as view:
            timeout = flight.options.timeout_s
            return flight.run(lambda rows: view.update(status_table(rows)),
                              lambda: ask(view, "interrupted"),
                              lambda: ask(view, f"timed out after {timeout:g} s"))
    return flight.run(progress_lines(lambda text: print(text, file=sys.stderr, flush=True)),
                      on_interrupt=lambda: "leave", on_timeout=lambda: "home")


#: wall seconds between two progress lines of a flight whose output is not a terminal
PROGRESS_S = 15.0


def progress_lines(write, every_s=PROGRESS_S):
    """A flight's ``status`` callback for piped output: the status table as one line
    every ``every_s`` wall seconds, so that a log shows the flight going on between
    its events (it was silent for minutes between takeoff and landing)."""
    last = [-float("inf")]

    def status(rows):
        now = time.monotonic()
        if now - last[0] < every_s or not rows:
            return
        last[0] = now
        write("progress: " + "; ".join(
            f"vehicle {r['sysid']} {r['state']}, item {r['item']}, snapshots {r['snapshots']}"
            + ("" if r["battery"] is None else f", battery {r['battery']} %") for r in rows))
    return status


def _read_battery_swaps(flight) -> None:
    """Between sorties the operator confirms each battery swap by typing the
    vehicle's system id and Enter (not needed with --auto-turnaround)."""
    if flight.options.auto_turnaround or not any(v.sorties for v in flight.plan.vehicles):
        return

    def read():
        for line in sys.stdin:
            for word in line.split():
                if word.isdigit():
                    flight.confirm_swap(int(word))
    threading.Thread(target=read, daemon=True, name="battery-swaps").start()


ANSWERS = {"h": "home", "home": "home", "l": "leave", "leave": "leave"}


def ask(view, why: str) -> str:
    """Ctrl-C or the timeout during a flight: bring every vehicle home along hidden
    paths, or leave them flying on their missions. Asks again until the answer is
    one it knows; end of input (or a second Ctrl-C) leaves them."""
    view.stop()
    # "\[" keeps rich from reading [h] and [l] as markup tags and swallowing them
    prompt = (f"[bold]{why}[/bold]: bring every vehicle home along hidden paths? "
              "\\[h]ome / \\[l]eave them on their missions: ")
    while True:
        try:
            answer = console.input(prompt)
        except (EOFError, KeyboardInterrupt):
            return "leave"
        choice = ANSWERS.get(answer.strip().lower())
        if choice is not None:
            break
        console.print(f"please answer h (home) or l (leave), not {answer.strip()!r}",
                      markup=False, highlight=False)
    if choice == "home":
        view.start()
    return choice


ALT_COLUMN = "alt above home"


def status_table(rows) -> Table:
    table = Table(title="vehicles", expand=False)
    # "alt" is GLOBAL_POSITION_INT.relative_alt: above home (QGroundControl's "Alt (Rel)"),
    # negative over valleys lower than the launch point
    for col in ("sysid", "UAV", "mode", "item", "mission", "snapshots", ALT_COLUMN,
                "heartbeat", "battery", "state"):
        table.add_column(col, justify="right")
    for r in rows:
        style = {"lost": "red", "landed": "green", "holding": "yellow"}.get(r["state"], "")
        table.add_row(str(r["sysid"]), str(r["vehicle"]), r["mode"], r["item"],
                      str(r["mission"]), r["snapshots"],
                      "-" if r["alt"] is None else f"{r['alt']:.0f} m",
                      f"{r['heartbeat_s']:.1f} s", "-" if r["battery"] is None else
                      f"{r['battery']} %", f"[{style}]{r['state']}[/{style}]" if style
                      else r["state"], style=None)
    return table


def summary(report, output=None) -> None:
    """Losses, re-plans and coverage reached; the files written when ``output`` is given."""
    for loss in report["losses"]:
        console.print(f"vehicle {loss['sysid']} lost at {loss['detected_s']:.1f} s "
                      f"({loss['reason']})")
    for r in report["replans"]:
        console.print(f"re-plan at {r['t_s']:.1f} s for {r['survivors']}: planned in "
                      f"{r['planning_s']:.1f} s, uploaded in {r['upload_s']:.1f} s; "
                      f"coverage time {r['planned'].get('coverage_time_s', 0) / 60:.1f} min")
    cov = report["coverage"].get("survivors")
    if cov:
        console.print(f"k = {cov['k']}: {cov['k_covered']} of {cov['targets']} targets seen by "
                      f"{cov['required_uavs']} surviving vehicle(s) "
                      f"({100 * cov['fraction_k_covered']:.1f} %) in {report['duration_s']:.0f} s")
    # the targets are the plan's: say what of the area they are, and whether
    # anything was hidden from anyone at all
    for line in _area_lines({"area": report.get("area"), "k": report.get("k", 0)},
                            report.get("outposts", 1)):
        console.print(f"plan: {line}")
    outcome = report.get("outcome", {})
    if outcome.get("ok"):
        console.print("outcome: required coverage reached, no vehicle lost, all landed")
    for problem in outcome.get("problems", []):
        console.print(f"outcome: {problem}", style="red", markup=False, highlight=False)
    for note in outcome.get("notes", []):
        console.print(f"note: {note}", markup=False, highlight=False)
    if output is not None:
        console.print(f"  {Path(output) / 'flight.json'}  [dim]flight report[/dim]")
        console.print(f"  {Path(output) / 'flight.png'}  [dim]map of the flight[/dim]")
