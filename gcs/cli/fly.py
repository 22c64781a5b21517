"""`gcs fly`: upload, start, monitor, re-task survivors on losses, land, report."""

import sys
from pathlib import Path

from rich.live import Live
from rich.table import Table

from autopilots import ARDUPILOT, NAMES
from gcs.cli.upload import add_protocol_arguments, parse_assignments, protocol_from_args
from gcs.progress import console
from planner.errors import InputError

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
                        help="a vehicle silent (no HEARTBEAT) this many wall seconds is lost")
    parser.add_argument("--assign", action="append", default=[], metavar="SYSID=VEHICLE",
                        help="fly plan vehicle VEHICLE with system id SYSID (repeatable; "
                             "none: system ids in ascending order take vehicles 1..n)")
    parser.add_argument("--connect-timeout", type=float, default=30.0, metavar="S",
                        help="wait this long for every vehicle's HEARTBEAT")
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
    sim.add_argument("--sim-capacity", type=int, metavar="N",
                     help="mission items each simulated vehicle holds (default: the "
                          "firmware's: ArduPilot 650, PX4 no limit); longer routes fly in "
                          "segments")


def options_from_args(args):
    from gcs.fly import FlyOptions

    if not args.lost_after > 0:
        raise InputError("--lost-after", f"must be positive, got {args.lost_after}")
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
                      tlog=not args.no_tlog)


def sim_fleet(plan, plan_dir, args, output: Path):
    """The built-in fleet for a dry run: one vehicle per plan route, homes at its
    launch, flying over the plan's own terrain."""
    from gcs.sim import FaultPlan, fleet_for_plan, parse_kill, terrain_ground
    from planner.geotiff import read_terrain
    from planner.plan import TERRAIN_FILE

    n = args.sim
    if n < 1:
        raise InputError("--sim", "need at least one vehicle")
    if args.speedup <= 0:
        raise InputError("--speedup", "must be positive")
    if args.sim_capacity is not None and args.sim_capacity < 1:
        raise InputError("--sim-capacity", f"must be at least 1, got {args.sim_capacity}")
    capacity = {} if args.sim_capacity is None else {"mission_capacity": args.sim_capacity}
    faults = {}
    for text in args.kill:
        sysid, at_s, at_item = parse_kill(text)
        if not 1 <= sysid <= n:
            raise InputError("--kill", f"no simulated vehicle {sysid} (ids are 1..{n})")
        faults[sysid] = FaultPlan(kill_at_s=at_s, kill_at_item=at_item)
    try:
        return fleet_for_plan(plan, n, firmware=args.firmware or plan.params.get(
            "firmware", ARDUPILOT), speedup=args.speedup, base_port=args.sim_base_port,
            gcs_port=args.sim_gcs_port, faults=faults, track_dir=output / "tracks", **capacity,
            terrain=terrain_ground(read_terrain(Path(plan_dir) / TERRAIN_FILE)))
    except ValueError as exc:
        raise InputError("--sim", str(exc)) from None
    except OSError as exc:
        raise InputError("--sim-base-port", f"cannot open a simulator endpoint: {exc}") from None


def status_table(rows) -> Table:
    table = Table(title="vehicles", expand=False)
    for col in ("sysid", "UAV", "mode", "item", "mission", "snapshots", "alt", "heartbeat",
                "battery", "state"):
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


def run(args) -> int:
    from gcs.cli.upload import check_urls
    from gcs.fly import Flight, FlightError

    check_urls(args.connect)
    if not args.connect and not args.sim:
        raise InputError("--connect", "give at least one --connect URL (or --sim N)")
    options = options_from_args(args)
    live = console.is_terminal
    flight = Flight(args.plan_dir, list(args.connect), options,
                    log=(lambda text: None) if live else
                    (lambda text: print(text, file=sys.stderr, flush=True)))
    flight.prepare()                  # the plan read and every mission proven: no link yet
    fleet = None
    if args.sim:
        plan = flight.plan
        fleet = sim_fleet(plan, args.plan_dir, args, options.output)
        flight.urls = flight.urls or fleet.urls()
        if options.timeout_s is None:
            longest = max((v.mission_time_s for v in plan.vehicles), default=0.0)
            options.timeout_s = 120.0 + 4.0 * longest / args.speedup
    try:
        report = fly_flight(flight, live)
    except FlightError as exc:
        print(f"gcs fly: error: {exc} (see {Path(options.output) / 'flight.json'})",
              file=sys.stderr)
        return 1
    finally:
        if fleet is not None:
            fleet.stop()
    summary(report, options.output)
    return 0 if report["outcome"]["ok"] else 1


def fly_plan(plan_dir, urls, options) -> dict:
    """Fly with a live status table on a terminal, event lines on stderr otherwise;
    FlightError when the flight could not go on (the report is written first)."""
    from gcs.fly import Flight

    live = console.is_terminal
    flight = Flight(plan_dir, urls, options,
                    log=(lambda text: None) if live else
                    (lambda text: print(text, file=sys.stderr, flush=True)))
    return fly_flight(flight, live)


def fly_flight(flight, live: bool) -> dict:
    """Run ``flight``: on a terminal with the status table, and Ctrl-C or --timeout
    answered by the user; otherwise Ctrl-C leaves the vehicles flying and the
    timeout brings them home."""
    if live:
        with Live(status_table([]), console=console, refresh_per_second=4) as view:
            timeout = flight.options.timeout_s
            return flight.run(lambda rows: view.update(status_table(rows)),
                              lambda: ask(view, "interrupted"),
                              lambda: ask(view, f"timed out after {timeout:g} s"))
    return flight.run(on_interrupt=lambda: "leave", on_timeout=lambda: "home")


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
    outcome = report.get("outcome", {})
    if outcome.get("ok"):
        console.print("outcome: required coverage reached, no vehicle lost, all landed")
    for problem in outcome.get("problems", []):
        console.print(f"outcome: {problem}", style="red", markup=False, highlight=False)
    if output is not None:
        console.print(f"  {Path(output) / 'flight.json'}  [dim]flight report[/dim]")
        console.print(f"  {Path(output) / 'flight.png'}  [dim]map of the flight[/dim]")
