"""`gcs download`: save the mission a vehicle holds as a .plan or .waypoints file."""

import sys
from pathlib import Path

from common.errors import InputError
from gcs.cli.options import add_connection_arguments, open_link, protocol_from_args

HELP = "download the mission a vehicle holds to a QGroundControl .plan or .waypoints file"
SUFFIXES = (".plan", ".waypoints")


def add_arguments(parser) -> None:
    add_connection_arguments(parser)
    parser.add_argument("--sysid", type=int, metavar="N",
                        help="system id of the vehicle; none: the only vehicle found")
    parser.add_argument("-o", "--output", required=True, metavar="FILE",
                        help="where to write: FILE.plan (QGroundControl) or FILE.waypoints "
                             "(QGC WPL 110), chosen by the suffix")


def run(args) -> int:
    from gcs import mission_protocol as mp

    output = Path(args.output)
    if output.suffix.lower() not in SUFFIXES:
        raise InputError(output, f"unknown mission file type; use {' or '.join(SUFFIXES)}")
    protocol = protocol_from_args(args)
    link = open_link(args, {args.sysid} if args.sysid is not None else None)
    try:
        vehicle = _choose(link.vehicles, args.sysid)
        try:
            items = mp.download(vehicle, **protocol)
        except mp.MissionError as exc:
            print(f"gcs download: error: {exc}", file=sys.stderr)
            return 1
        home = _home(vehicle)
    finally:
        link.close()
    _write(output, vehicle, items, home)
    print(f"{output}: vehicle {vehicle.sysid} ({vehicle.flavour}), {len(items)} items")
    return 0


def _choose(vehicles: dict, sysid):
    if sysid is not None:
        return vehicles[sysid]
    if len(vehicles) > 1:
        raise InputError("--sysid", f"{len(vehicles)} vehicles answered (system ids "
                                    f"{', '.join(map(str, vehicles))}): choose one")
    return next(iter(vehicles.values()))


def _home(vehicle, timeout_s=2.0):
    """(lat, lon, alt AMSL) of home, asked for if not streamed yet; None if unknown."""
    from gcs import commands
    from gcs.mavlink import M

    if vehicle.state.home is None:
        try:
            commands.command_long(vehicle, M.MAV_CMD_REQUEST_MESSAGE,
                                  M.MAVLINK_MSG_ID_HOME_POSITION, retries=1)
            vehicle.recv("HOME_POSITION", timeout_s)
        except commands.CommandError:
            pass                           # no home yet (no GPS fix): the file says so
    return vehicle.state.home


def _write(output: Path, vehicle, items, home) -> None:
    from autopilots import PX4, profile
    from missions import qgc, wpl
    from missions.build import VehicleMission

    autopilot = vehicle.profile or profile(PX4)     # a generic autopilot: no home item
    if output.suffix.lower() == ".waypoints":       # line 0 home, as QGroundControl's
        wpl.write_waypoints(output, items, autopilot.name, home=home)
        return
    mission = VehicleMission(vehicle.sysid, autopilot.name, items, [None] * len(items))
    qgc.write_plan_file(output, mission, home=None if autopilot.home_item else home)
