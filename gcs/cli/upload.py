"""`gcs upload`: put each vehicle's mission on it and read it back to prove it.

Missions come from a plan directory (built per vehicle for its own firmware) or
from mission files (.plan, .waypoints), one route per file. Every mission is
read and proven hidden and clear against the plan it came from (the plan
directory itself, the plan.json beside a file, or --plan DIR) before any
connection is opened; only checked missions are uploaded (`missions.sources`).
Vehicles are found by HEARTBEAT and take routes in order of system id, unless
`--vehicle SYSID=ROUTE` says otherwise. Every upload is verified item by item.
"""

import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from autopilots import NAMES
from common.errors import InputError
from gcs.cli.options import (
    add_connection_arguments,
    check_urls,
    open_link,
    parse_assignments,
    protocol_from_args,
)

HELP = "upload each vehicle's mission (plan directory or .plan/.waypoints files) and verify it"
FIRMWARE_CHOICES = ("auto",) + NAMES


def add_arguments(parser) -> None:
    parser.add_argument("sources", nargs="+", metavar="PLAN_DIR|FILE",
                        help="a plan directory (plan.json) or mission files "
                             "(.plan, .waypoints), one route per file")
    add_connection_arguments(parser)
    parser.add_argument("--vehicle", "--assign", dest="assign", action="append", default=[],
                        metavar="SYSID=ROUTE",
                        help="give route ROUTE (plan vehicle id, or file number 1..n) to "
                             "system id SYSID, repeatable; the others go by order of system id")
    parser.add_argument("--firmware", choices=FIRMWARE_CHOICES, default="auto",
                        help="mission flavour; auto = each vehicle's own, from its HEARTBEAT "
                             "(a vehicle of another firmware is refused its mission)")
    parser.add_argument("--plan", metavar="DIR",
                        help="plan directory the mission files came from, to prove them "
                             "against (default: the plan.json beside each file)")
    parser.add_argument("--unchecked", action="store_true",
                        help="upload mission files that have no plan to be proven against, "
                             "after a structure check only (warns what was not proven)")


# -- matching ----------------------------------------------------------------------------
def match(sysids, routes, assign: dict) -> list:
    """[(sysid, route)]: the assignments first, the rest in order of system id."""
    by_id = {r.id: r for r in routes}
    unknown = sorted(set(assign.values()) - set(by_id))
    if unknown:
        raise InputError("--vehicle", f"no route {unknown[0]}; routes are "
                                      f"{', '.join(map(str, sorted(by_id)))}")
    missing = sorted(set(assign) - set(sysids))
    if missing:
        raise InputError("--vehicle", f"no vehicle with system id {missing[0]} answered "
                                      f"(found {', '.join(map(str, sysids)) or 'none'})")
    pairs = [(s, by_id[r]) for s, r in assign.items()]
    free_vehicles = [s for s in sorted(sysids) if s not in assign]
    free_routes = [r for r in routes if r.id not in set(assign.values())]
    if len(free_routes) > len(free_vehicles):
        raise InputError("--connect", f"{len(routes)} routes but {len(sysids)} vehicle(s) "
                                      f"found (system ids {', '.join(map(str, sysids))})")
    pairs += list(zip(free_vehicles, free_routes))
    return sorted(pairs, key=lambda p: p[0])


# -- running -----------------------------------------------------------------------------
def load_routes(args) -> list:
    """Every source read and checked (InputError on the first bad one); the warning
    for each unproven one printed."""
    from missions.sources import load_sources

    if args.plan is not None and any(Path(s).is_dir() for s in args.sources):
        raise InputError("--plan", "give --plan with mission files, not with a plan directory")
    routes = load_sources(args.sources, args.plan, args.unchecked,
                          None if args.firmware == "auto" else args.firmware)
    for route in routes:
        if route.unproven_note:
            print(f"gcs upload: warning: {route.unproven_note}", file=sys.stderr, flush=True)
    return routes


def run(args) -> int:
    check_urls(args.connect)
    assign = parse_assignments(args.assign)
    protocol = protocol_from_args(args)
    if args.signing_key:
        from gcs.signing import load_key
        load_key(args.signing_key)              # a bad key file: before the files' checks
    routes = load_routes(args)
    expect = set(assign) if len(assign) >= len(routes) else len(routes)
    link = open_link(args, expect)
    try:
        pairs = match(list(link.vehicles), routes, assign)
        for sysid, route in pairs:      # every pair, before anything is sent to any
            route.checked(_firmware(link.vehicles[sysid], args.firmware), sysid)
        results = _upload_all(link, pairs, args.firmware, protocol)
    finally:
        link.close()
    from rich.console import Console

    Console().print(_summary(results))
    failed = [r for r in results if r["error"]]
    for r in failed:
        print(f"gcs upload: error: {r['error']}", file=sys.stderr)
    return 1 if failed else 0


def _upload_all(link, pairs, firmware_choice, protocol) -> list:
    from rich.progress import BarColumn, Progress, TextColumn

    from gcs.progress import console

    bars = Progress(TextColumn("{task.description:<28}"), BarColumn(),
                    TextColumn("{task.completed:>4.0f}/{task.total:.0f}"), console=console,
                    disable=not console.is_terminal)
    vehicles = link.vehicles
    with bars, ThreadPoolExecutor(max_workers=max(1, len(pairs))) as pool:
        jobs = [pool.submit(_upload_one, vehicles[s], route, firmware_choice, bars, protocol)
                for s, route in pairs]
        return [job.result() for job in jobs]


def _firmware(vehicle, choice) -> str:
    """The firmware whose mission ``vehicle`` is given: ``--firmware``, or its own
    (a generic autopilot is given PX4's)."""
    from autopilots import PX4

    own = vehicle.profile.name if vehicle.profile is not None else None
    if choice == "auto":
        return own or PX4
    if own is not None and own != choice:
        raise InputError("--firmware", f"vehicle {vehicle.sysid} runs {vehicle.profile.title}, "
                                       f"not {choice}: leave --firmware out to give each "
                                       "vehicle its own firmware's mission")
    return choice


def _upload_one(vehicle, route, firmware_choice, bars, protocol) -> dict:
    from gcs import mission_protocol as mp

    firmware = _firmware(vehicle, firmware_choice)
    result = {"sysid": vehicle.sysid, "flavour": vehicle.flavour, "route": route.id,
              "firmware": firmware, "items": 0, "error": None, "seconds": 0.0}
    t0 = time.monotonic()
    try:
        mission = route.checked(firmware, vehicle.sysid)   # checked before; cached
        result["items"] = len(mission)
        task = bars.add_task(f"vehicle {vehicle.sysid} <- route {route.id}",
                             total=2 * len(mission))
        try:
            mp.upload_verified(vehicle, mission, **protocol,
                               progress=lambda done, total: bars.update(task, completed=done))
        except mp.MissionError as exc:
            if exc.result != mp.M.MAV_MISSION_NO_SPACE:
                raise
            result["error"] = _too_long(vehicle, len(mission), exc, protocol)
    except (mp.MissionError, InputError) as exc:
        result["error"] = str(exc)
    result["seconds"] = time.monotonic() - t0
    if not bars.console.is_terminal:
        state = "verified" if not result["error"] else "FAILED"
        print(f"vehicle {vehicle.sysid}: route {route.id}, {result['items']} items, {state}",
              file=sys.stderr, flush=True)
    return result


def _too_long(vehicle, items: int, refused, protocol) -> str:
    """A mission longer than the vehicle holds: how many it holds (what it said, or
    found by asking), and how to fly it anyway."""
    from gcs import mission_protocol as mp

    try:
        capacity = mp.learn_capacity(vehicle, items, refused.capacity, **protocol)
        how = "it said so" if refused.capacity else "found by asking"
        holds = f"the vehicle holds {capacity} mission items ({how})"
    except mp.MissionError:
        holds = "the vehicle has no room for it (MAV_MISSION_NO_SPACE)"
    advice = getattr(vehicle.profile, "capacity_advice", "")
    return (f"vehicle {vehicle.sysid}: the mission has {items} items and {holds}: "
            f"`gcs fly` flies it in segments, uploading the next in flight"
            + (f"; or {advice}" if advice else ""))


def _summary(results):
    from rich.table import Table

    table = Table(title="mission upload")
    for column in ("system id", "autopilot", "route", "items", "result", "time"):
        table.add_column(column, justify="right" if column in ("items", "time") else "left")
    for r in results:
        table.add_row(str(r["sysid"]), r["flavour"], str(r["route"]), str(r["items"]),
                      "verified" if not r["error"] else "[red]failed[/red]",
                      f"{r['seconds']:.1f} s")
    return table
