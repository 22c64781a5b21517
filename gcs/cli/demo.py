"""`gcs demo`: the whole mission on the built-in terrain, start to finish.

Plans with the built-in scenario (gcs/data/demo.toml: the USGS Jacksboro DEM,
its outposts, 4 UAVs from one base, RT with k = 1), writes every output of
`gcs plan`, starts 4 simulated vehicles, flies the plan through its radio shadows
(--no-radio: a link everywhere) with one of them shot down partway, re-tasks the
survivors and ends with the coverage report.
"""

import argparse
from importlib import resources
from pathlib import Path

from autopilots import ARDUPILOT, NAMES
from common.errors import InputError

HELP = "plan, fly and re-task 4 simulated UAVs on the built-in terrain, one of them shot down"

SCENARIO = "demo.toml"


def add_arguments(parser) -> None:
    parser.add_argument("-o", "--output", default="demo-out", metavar="DIR",
                        help="output directory: DIR/plan (gcs plan's files) and DIR/flight "
                             "(flight report, plot, tracks, tlogs); their files are replaced")
    parser.add_argument("--firmware", choices=NAMES, default=ARDUPILOT,
                        help="autopilot the simulated vehicles imitate")
    parser.add_argument("--radio", action=argparse.BooleanOptionalAction, default=True,
                        help="fly through the plan's radio shadows: each simulated link cut "
                             "while its vehicle is out of the antenna's line of sight "
                             "(--no-radio: a link everywhere)")
    parser.add_argument("--speedup", type=float, default=40.0, metavar="X",
                        help="simulated time runs X times faster than the wall clock")
    parser.add_argument("--kill", type=int, default=2, metavar="SYSID",
                        help="the simulated vehicle shot down (0: none)")
    parser.add_argument("--kill-at", type=float, default=0.4, metavar="FRACTION",
                        help="when, as a fraction of that vehicle's mission items")
    parser.add_argument("--base-port", type=int, metavar="P",
                        help="first simulator port (default: the firmware's SITL port)")


def run(args) -> int:
    from common.fileio import check_output_dir

    if not 0 < args.kill_at < 1:
        raise InputError("--kill-at", f"must be between 0 and 1, got {args.kill_at}")
    out = Path(args.output)
    check_output_dir(out)  # files in it are replaced, never the folder wiped
    from gcs.cli.views import plan_summary
    from gcs.plan_folder import write_plan_folder
    from gcs.progress import console, note_first_compile, stage_progress
    from planner.pipeline import plan_mission
    from planner.scenario import make_scenario, read_scenario

    plan_dir, flight_dir = out / "plan", out / "flight"
    scenario_file = resources.files("gcs.data").joinpath(SCENARIO)
    with resources.as_file(scenario_file) as path:
        scenario = make_scenario(read_scenario(path), {"firmware": args.firmware},
                                 source=f"built-in {SCENARIO}")
    console.rule("1. plan: hidden reduced-time routes, k = 1")
    note_first_compile()
    with stage_progress() as progress:
        ctx, outcome = plan_mission(scenario, progress)
        written = write_plan_folder(plan_dir, ctx, outcome)
    console.print(plan_summary(outcome.plan))
    console.rule(f"2. fly: {scenario.uavs} simulated {args.firmware} vehicles, "
                 f"{args.speedup:g}x real time")
    report, flight_files = _fly(ctx, outcome.plan, plan_dir, flight_dir, args)
    console.rule("3. files written")
    for path, what in written + flight_files:
        console.print(f"  {path}  [dim]{what}[/dim]")
    return 0 if demo_succeeded(report, args.kill) else 1


def demo_succeeded(report, victim) -> bool:
    """The demo did its job: the required coverage reached, and no problem but the
    loss it scripted (vehicle ``victim`` shot down; 0: none)."""
    outcome = report["outcome"]
    scripted = {f"vehicle(s) {victim} lost"} if victim else set()
    return outcome["coverage_reached"] and not set(outcome["problems"]) - scripted


def _in_shadow(victim, mission, item) -> str:
    """What the operator will see of a loss at ``item``: inside a predicted radio
    shadow it is found only once the vehicle is overdue."""
    index = next((w for w in mission.waypoint_of_item[item:] if w is not None), None)
    t = None if index is None else victim.waypoints[index].t_s
    for a, b in victim.silences:
        if t is not None and a <= t <= b:
            return (f", inside its predicted radio shadow ({a:.0f}-{b:.0f} s of the plan): "
                    "the loss is found when it is overdue, not at once")
    return ""


def _fly(ctx, plan, plan_dir, flight_dir, args):
    """Fly the plan on simulated vehicles, with the planning context in memory."""
    from gcs.cli.views import fly_plan, summary
    from gcs.flight import FlightError, FlyOptions
    from gcs.progress import console
    from gcs.sim import FaultPlan, fleet_for_plan, radio_for_plan, terrain_ground
    from missions.build import vehicle_mission

    faults = {}
    if args.kill:
        victim = next((v for v in plan.vehicles if v.id == args.kill), None)
        if victim is None:
            raise InputError("--kill", f"the plan has no vehicle {args.kill}")
        # by mission item, not by time: the simulators' clocks start at boot
        mission = vehicle_mission(victim, args.firmware)
        items = mission.items
        item = max(2, int(args.kill_at * len(items)))
        faults[args.kill] = FaultPlan(kill_at_item=item)
        console.print(f"vehicle {args.kill} will be shot down on reaching mission item "
                      f"{item} of {len(items)}"
                      + (_in_shadow(victim, mission, item) if args.radio else ""))
    # --radio: each link cut while the plan's antenna cannot see its vehicle
    fleet = fleet_for_plan(plan, firmware=args.firmware, speedup=args.speedup, faults=faults,
                           track_dir=flight_dir / "tracks", base_port=args.base_port,
                           terrain=terrain_ground(ctx.terrain),
                           radio=radio_for_plan(plan, ctx.terrain) if args.radio else None)
    longest = max(v.mission_time_s for v in plan.vehicles)
    # the simulated copters come with their firmware's failsafes (RTL on RC loss, ...):
    # set to the hidden-safe values as `gcs fly --set-failsafes` does, and said
    options = FlyOptions(output=flight_dir, timeout_s=120.0 + 3.0 * longest / args.speedup,
                         set_failsafes=True)
    console.print("the simulated vehicles' failsafes are set to their hidden-safe values "
                  "(as gcs fly --set-failsafes; flight.json keeps the previous ones)")
    try:
        report = fly_plan(plan_dir, fleet.urls(), options, ctx=ctx)
    except FlightError as exc:
        raise InputError("gcs demo", f"the flight failed: {exc}") from None
    finally:
        fleet.stop()
    summary(report)
    files = [(flight_dir / "flight.json", "flight report: events, losses, re-plans, coverage"),
             (flight_dir / "flight.png", "recorded tracks, the loss, re-planned routes, coverage")]
    files += [(p, "MAVLink telemetry log (mavlogdump.py reads it)")
              for p in sorted(flight_dir.glob("*.tlog"))]
    files += [(p, "true track of the simulated vehicle (gcs-sim-track/3)")
              for p in sorted((flight_dir / "tracks").glob("*.json"))]
    return report, files
