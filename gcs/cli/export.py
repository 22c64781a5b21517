"""`gcs export`: rewrite the mission files of a saved plan directory."""

import argparse
from pathlib import Path

from autopilots import NAMES as FIRMWARES
from common.errors import InputError
from missions import FORMATS

HELP = "rewrite the mission files (.plan, .waypoints, GeoJSON, KML) of a plan directory"


def add_arguments(parser) -> None:
    parser.add_argument("plan_dir", metavar="PLAN_DIR",
                        help="plan directory written by `gcs plan` (holds plan.json and "
                             "terrain.tif)")
    parser.add_argument("-o", "--output", metavar="DIR", default=argparse.SUPPRESS,
                        help="where to write the files (default: PLAN_DIR itself)")
    parser.add_argument("--firmware", choices=FIRMWARES, default=argparse.SUPPRESS,
                        help="mission flavour (default: the plan's firmware)")
    parser.add_argument("--format", default=",".join(FORMATS), metavar="LIST",
                        help=f"comma-separated formats to write, from {', '.join(FORMATS)}")
    parser.add_argument("--hold", type=float, default=0.0, metavar="S",
                        help="seconds to hover at each snapshot before the camera triggers; "
                             "0 = fly through")
    parser.add_argument("--no-speed", action="store_true", default=argparse.SUPPRESS,
                        help="leave out DO_CHANGE_SPEED (default: fly the plan's speed_mps)")
    parser.add_argument("--no-camera", action="store_true", default=argparse.SUPPRESS,
                        help="leave out the camera triggers at snapshots (default: "
                             "DO_DIGICAM_CONTROL for ArduPilot, IMAGE_START_CAPTURE for PX4)")
    parser.add_argument("--no-fences", action="store_true", default=argparse.SUPPRESS,
                        help="leave the outposts' ranges out of the .plan geofence (default: "
                             "exclusion circles, drawn by QGroundControl)")
    parser.add_argument("--no-check", action="store_true", default=argparse.SUPPRESS,
                        help="skip proving every leg hidden and clear against the plan's "
                             "terrain (default: check, which rebuilds the exposure surface)")


def run(args) -> int:
    from gcs.progress import console
    from missions.build import MissionOptions
    from missions.export import check_folder, export_firmware, export_plan_dir
    from planner.plan import PLAN_FILE, Plan

    plan_dir = Path(args.plan_dir)
    if not (plan_dir / PLAN_FILE).is_file():
        raise InputError(plan_dir, f"not a plan directory (no {PLAN_FILE})")
    plan = Plan.load(plan_dir)
    formats = [f.strip() for f in args.format.split(",") if f.strip()]
    if args.hold < 0:
        raise InputError("--hold", f"must be >= 0 seconds, got {args.hold:g}")
    flag = lambda name: getattr(args, name, False)  # noqa: E731
    options = MissionOptions(camera=not flag("no_camera"), hold_s=args.hold,
                             speed_mps=None if flag("no_speed") else plan.params.get("speed_mps"))
    output = Path(getattr(args, "output", plan_dir))
    firmware = export_firmware(plan, getattr(args, "firmware", None))
    # one truth in the folder written: refused before the (slow) surface is rebuilt;
    # in place, plan.json is given the firmware written (`export_plan_dir`)
    check_folder(output, plan, firmware, formats, plan_dir)
    surface = None if flag("no_check") else _surface(plan_dir, plan)
    written = export_plan_dir(output, plan, firmware, surface, options=options,
                              formats=formats, fences=not flag("no_fences"), plan_dir=plan_dir)
    for path, what in written:
        console.print(f"  {path}  [dim]{what}[/dim]", highlight=False)
    return 0


def _surface(plan_dir, plan):
    from missions.sources import saved_plan_surface
    from planner.plan import TERRAIN_FILE

    if not (plan_dir / TERRAIN_FILE).is_file():
        raise InputError(plan_dir / TERRAIN_FILE, "missing: cannot re-check the legs "
                                                  "(use --no-check to export unchecked)")
    return saved_plan_surface(plan_dir, plan)
