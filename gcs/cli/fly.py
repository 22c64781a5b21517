"""`gcs fly`: upload, start, monitor, re-task survivors on losses, land, report."""

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from autopilots import NAMES, firmware_of
from common.errors import InputError
from gcs.cli.options import (
    add_connect_timeout,
    add_protocol_arguments,
    check_urls,
    parse_assignments,
    protocol_from_args,
)

HELP = "fly a plan: upload, start, monitor, re-task survivors after losses, report"


def add_arguments(parser) -> None:
    parser.add_argument("plan_dir", metavar="PLAN_DIR", help="plan directory written by gcs plan")
    parser.add_argument("--connect", action="append", default=[], metavar="URL",
                        help="MAVLink connection, repeatable (tcp:HOST:PORT, udpin:0.0.0.0:14550, "
                             "udpout:HOST:PORT, /dev/ttyACM0,57600); not needed with --sim")
    parser.add_argument("-o", "--output", default="flight", metavar="DIR",
                        help="directory for flight.json, flight.png and the .tlog files")
    parser.add_argument("--signing-key", metavar="FILE",
                        help="MAVLink 2 signing key: 32-byte file, or a passphrase file "
                             "(SHA-256, as MAVProxy); none = no signing")
    parser.add_argument("--lost-after", type=float, default=5.0, metavar="S",
                        help="a vehicle silent (nothing heard from it) this many wall "
                             "seconds is lost")
    parser.add_argument("--assign", action="append", default=[], metavar="SYSID=VEHICLE",
                        help="fly plan vehicle VEHICLE with system id SYSID (repeatable; "
                             "none: system ids in ascending order take vehicles 1..n)")
    add_connect_timeout(parser)
    parser.add_argument("--ready-timeout", type=float, default=60.0, metavar="S",
                        help="wait this long for pre-arm readiness (EKF/GPS)")
    add_protocol_arguments(parser)
    parser.add_argument("--timeout", type=float, metavar="S",
                        help="stop monitoring after S wall seconds (default: until every "
                             "vehicle has landed or is lost)")
    parser.add_argument("--max-items", type=int, metavar="N",
                        help="upload at most N mission items at a time: longer routes fly in "
                             "segments, the next uploaded in flight (default: as many as each "
                             "vehicle holds, learned when it refuses more)")
    parser.add_argument("--no-tlog", action="store_true", help="do not write .tlog files")
    parser.add_argument("--auto-turnaround", action="store_true",
                        help="between two sorties, send a vehicle on once it reports a fresh "
                             "battery, without the operator's word (SITL; --sim always does); "
                             "otherwise type its system id and Enter once its battery is "
                             "swapped")
    parser.add_argument("--swap-silence", type=float, default=600.0, metavar="S",
                        help="a vehicle down at its base for its battery swap may be silent "
                             "this many wall seconds (the swap powers most autopilots down) "
                             "before it is lost")
    parser.add_argument("--from-where-they-stand", action="store_true",
                        help="a vehicle not at its route's launch point: plan the fleet again "
                             "with its base where it stands (its takeoff and first leg "
                             "proven hidden there), written to the output folder, and fly "
                             "that; otherwise it is refused before anything is armed")
    parser.add_argument("--set-failsafes", action="store_true",
                        help="write each vehicle's failsafe parameters to the values whose "
                             "flight stays hidden (ArduPilot SmartRTL, PX4 a return along the "
                             "mission, a link loss flies the mission on), read them back, and "
                             "keep the previous values in flight.json (`gcs failsafes "
                             "--restore`); without it a vehicle whose failsafe would leave the "
                             "proof is refused before arming (--sim always sets them)")
    view = parser.add_argument_group("watching the flight elsewhere")
    view.add_argument("--forward", action="append", default=[], metavar="URL",
                      help="relay every vehicle's MAVLink to URL, repeatable, as MAVProxy's "
                           "--out (QGroundControl: udpout:127.0.0.1:14550; a router: "
                           "tcp:HOST:PORT); what comes back from there is dropped")
    view.add_argument("--map", nargs="?", const="", metavar="HOST:PORT",
                      help="serve a live map of the flight to a web browser (offline: the "
                           "plan's own terrain, no tiles) on 127.0.0.1:8750, or HOST:PORT")
    view.add_argument("--forward-commands", action="store_true",
                      help="pass what the forwarded side sends on to the vehicles (a second "
                           "station can then command them, and fight the re-tasking)")
    sim = parser.add_argument_group("dry run with the built-in simulated vehicles")
    sim.add_argument("--sim", type=int, metavar="N",
                     help="start N simulated vehicles with homes at the plan's launch points "
                          "and fly against them")
    sim.add_argument("--firmware", choices=NAMES,
                     help="simulated autopilot; none = the plan's firmware")
    sim.add_argument("--speedup", type=float, default=10.0, metavar="X",
                     help="simulated time runs X times faster than the wall clock")
    sim.add_argument("--kill", action="append", default=[], metavar="SYSID@Ts|SYSID@itemN",
                     help="shoot simulated vehicle SYSID down at mission time T s (since its "
                          "boot) or on reaching item N (repeatable)")
    sim.add_argument("--sim-base-port", type=int, metavar="P",
                     help="first simulator port; none = 5760 (ArduPilot TCP), 18570 (PX4 UDP)")
    sim.add_argument("--sim-gcs-port", type=int, default=14550, metavar="P",
                     help="PX4 flavour: UDP port the simulated vehicles send to")
    sim.add_argument("--drain", action="append", default=[], metavar="SYSID@FACTOR",
                     help="a simulated vehicle whose battery empties FACTOR times faster than "
                          "its rating (a cold or worn battery): the battery watch's case")
    sim.add_argument("--swap-reboot", type=float, default=0.0, metavar="S",
                     help="each battery swap powers a simulated vehicle down for S wall "
                          "seconds (its link silent, its TCP port closed), then it boots "
                          "again; 0 = a hot swap")
    sim.add_argument("--sim-radio", action=argparse.BooleanOptionalAction, default=True,
                     help="cut each simulated link while its vehicle is out of the plan's "
                          "antennas' radio line of sight on the plan's terrain, the shadows "
                          "the plan predicts (--no-sim-radio: a link everywhere)")
    sim.add_argument("--sim-capacity", type=int, metavar="N",
                     help="mission items each simulated vehicle holds (default: the "
                          "firmware's: ArduPilot 650, PX4 no limit); longer routes fly in "
                          "segments")


def options_from_args(args):
    from gcs.flight import FlyOptions

    if not args.lost_after > 0:
        raise InputError("--lost-after", f"must be positive, got {args.lost_after}")
    if not args.swap_silence >= 0:
        raise InputError("--swap-silence", f"must not be negative, got {args.swap_silence}")
    protocol = protocol_from_args(args)
    if args.max_items is not None and args.max_items < 1:
        raise InputError("--max-items", f"must be at least 1, got {args.max_items}")
    key = None
    if args.signing_key:
        from gcs.signing import load_key
        key = load_key(args.signing_key)
    return FlyOptions(output=Path(args.output), lost_after_s=args.lost_after, signing_key=key,
                      assign=parse_assignments(args.assign, "--assign", "VEHICLE"),
                      connect_timeout_s=args.connect_timeout,
                      ready_timeout_s=args.ready_timeout, timeout_s=args.timeout,
                      protocol_timeout_s=protocol["timeout_s"],
                      protocol_retries=protocol["retries"], max_items=args.max_items,
                      tlog=not args.no_tlog,
                      auto_turnaround=bool(args.auto_turnaround or args.sim),
                      from_where_they_stand=args.from_where_they_stand,
                      set_failsafes=bool(args.set_failsafes or args.sim),
                      swap_silence_s=args.swap_silence)


def sim_fleet(plan, plan_dir, args, output: Path):
    """The built-in fleet for a dry run: one vehicle per plan route, homes at its
    launch, flying over the plan's own terrain."""
    from gcs.sim import FaultPlan, fleet_for_plan, parse_kill, radio_for_plan, terrain_ground
    from planner.plan import TERRAIN_FILE
    from planner.terrain import read_terrain

    n = args.sim
    if n < 1:
        raise InputError("--sim", "need at least one vehicle")
    if args.speedup <= 0:
        raise InputError("--speedup", "must be positive")
    if not args.swap_reboot >= 0:
        raise InputError("--swap-reboot", f"must not be negative, got {args.swap_reboot}")
    if args.sim_capacity is not None and args.sim_capacity < 1:
        raise InputError("--sim-capacity", f"must be at least 1, got {args.sim_capacity}")
    capacity = {} if args.sim_capacity is None else {"mission_capacity": args.sim_capacity}
    if plan.params.get("endurance_min"):    # the battery the plan was made for
        capacity["battery_min"] = float(plan.params["endurance_min"])
    faults = {}
    for text in args.kill:
        sysid, at_s, at_item = parse_kill(text)
        if not 1 <= sysid <= n:
            raise InputError("--kill", f"no simulated vehicle {sysid} (ids are 1..{n})")
        faults[sysid] = FaultPlan(kill_at_s=at_s, kill_at_item=at_item)
    for text in args.drain:
        sysid, factor = _drain(text, n)
        faults[sysid] = replace(faults.get(sysid, FaultPlan()), drain=factor)
    terrain = read_terrain(Path(plan_dir) / TERRAIN_FILE)
    try:
        return fleet_for_plan(plan, n, firmware=firmware_of(plan.params, args.firmware),
            speedup=args.speedup, base_port=args.sim_base_port,
            gcs_port=args.sim_gcs_port, faults=faults, track_dir=output / "tracks", **capacity,
            swap_reboot_s=args.swap_reboot, terrain=terrain_ground(terrain),
            radio=radio_for_plan(plan, terrain) if args.sim_radio else None)
    except ValueError as exc:
        raise InputError("--sim", str(exc)) from None
    except OSError as exc:
        raise InputError("--sim-base-port", f"cannot open a simulator endpoint: {exc}") from None


def _drain(text: str, n: int) -> tuple:
    """``2@3`` -> (2, 3.0): vehicle 2's battery drains 3 times faster."""
    try:
        sysid, factor = text.split("@")
        sysid, factor = int(sysid), float(factor)
    except ValueError:
        raise InputError("--drain", f"expected SYSID@FACTOR, got {text!r}") from None
    if not 1 <= sysid <= n or not factor > 0:
        raise InputError("--drain", f"{text!r}: need a simulated vehicle 1..{n} and a "
                                    "positive factor")
    return sysid, factor


def start_map(flight, args):
    """The live map of --map (None without), serving before any vehicle is contacted."""
    if args.map is None:
        return None
    from gcs.livemap import LiveMap, parse_address

    try:
        host, port = parse_address(args.map)
    except ValueError as exc:
        raise InputError("--map", str(exc)) from None
    area = None
    area_file = flight.plan.params.get("area_file")
    if area_file and Path(area_file).is_file():
        from planner.terrain.area import read_area
        area = read_area(area_file)
    try:
        live = LiveMap(flight, flight.ctx, host, port, area).start()
    except OSError as exc:
        raise InputError("--map", f"cannot serve on {host}:{port}: {exc.strerror}") from None
    print(f"live map: {live.url}", file=sys.stderr, flush=True)
    return live


def forwarder(args):
    """The `gcs.forward.Forwarder` of --forward URLs (None without); opened now, so a
    URL that cannot be opened is bad input before any vehicle is contacted."""
    if not args.forward:
        return None
    from gcs.forward import Forwarder
    from gcs.link import LinkError

    try:
        return Forwarder(args.forward, args.forward_commands)
    except LinkError as exc:
        raise InputError("--forward", str(exc)) from None


def run(args) -> int:
    from gcs.cli.views import fly_flight, summary
    from gcs.flight import FailsafeRefused, Flight, FlightError
    from gcs.progress import console

    check_urls(args.connect)
    check_urls(args.forward, "--forward")
    if not args.connect and not args.sim:
        raise InputError("--connect", "give at least one --connect URL (or --sim N)")
    if args.forward_commands and not args.forward:
        raise InputError("--forward-commands", "give --forward URL too")
    options = options_from_args(args)
    live = console.is_terminal
    flight = Flight(args.plan_dir, list(args.connect), options,
                    log=(lambda text: None) if live else
                    (lambda text: print(text, file=sys.stderr, flush=True)))
    flight.prepare()                  # the plan read and every mission proven: no link yet
    options.forward = forwarder(args)
    try:
        live_map = start_map(flight, args)
    except InputError:
        if options.forward is not None:
            options.forward.close()
        raise
    fleet = None
    try:
        if args.sim:
            plan = flight.plan
            fleet = sim_fleet(plan, args.plan_dir, args, options.output)
            flight.urls = flight.urls or fleet.urls()
            if options.timeout_s is None:
                longest = max((v.mission_time_s for v in plan.vehicles), default=0.0)
                options.timeout_s = 120.0 + 4.0 * longest / args.speedup
        report = fly_flight(flight, live)
    except FlightError as exc:
        print(f"gcs fly: error: {exc} (see {Path(options.output) / 'flight.json'})",
              file=sys.stderr)
        return 2 if isinstance(exc, FailsafeRefused) else 1
    finally:
        if fleet is not None:
            fleet.stop()
        if options.forward is not None:
            options.forward.close()
            print(options.forward.summary(), file=sys.stderr)
        if live_map is not None:
            live_map.stop()
    summary(report, options.output)
    return 0 if report["outcome"]["ok"] else 1


