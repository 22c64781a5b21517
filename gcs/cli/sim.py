"""`gcs sim`: simulated ArduPilot or PX4 multicopters on the endpoints real SITL uses."""

import math
import time

from autopilots import ARDUPILOT, NAMES
from common.errors import InputError
from gcs.sim.faults import FaultPlan, parse_cut, parse_kill
from gcs.sim.physics import DEFAULT_HOME, Limits
from planner.rates import defaults_text

HELP = "run simulated vehicles (ArduPilot: TCP 5760+10*i; PX4: UDP 18570+i -> 14550)"


def add_arguments(parser) -> None:
    parser.add_argument("--vehicles", type=int, default=1, metavar="N", help="number of vehicles")
    parser.add_argument("--firmware", choices=NAMES, default=ARDUPILOT,
                        help="which autopilot to behave like")
    parser.add_argument("--home", metavar="LAT,LON[,ALT]",
                        help="launch point of every vehicle; ALT = ground m AMSL (default: "
                             "the terrain's ground there with --terrain, else 0; without "
                             "--home: ArduPilot SITL's " + ",".join(str(v) for v in DEFAULT_HOME)
                             + ")")
    parser.add_argument("--homes", metavar="LAT,LON[,ALT];...",
                        help="one launch point per vehicle, separated by ';' (ALT as --home)")
    parser.add_argument("--speedup", type=float, default=1.0, metavar="X",
                        help="mission time runs X times faster than the wall clock "
                             "(telemetry rates stay real)")
    faults = parser.add_argument_group("faults (times: mission s since boot; durations: wall s)")
    faults.add_argument("--kill", action="append", default=[], metavar="SYSID@Ts|SYSID@itemN",
                        help="shoot vehicle SYSID down at mission time T or on reaching item N")
    faults.add_argument("--cut", action="append", default=[], metavar="SYSID@Ts+Ds",
                        help="cut vehicle SYSID's link at mission time T for D wall seconds")
    faults.add_argument("--drop", type=float, default=0.0, metavar="PCT",
                        help="drop this percentage of packets in both directions")
    faults.add_argument("--refuse-arm", type=int, action="append", default=[], metavar="SYSID",
                        help="vehicle SYSID refuses to arm")
    vehicle = parser.add_argument_group("vehicle")
    defaults = Limits()
    vehicle.add_argument("--speed", type=float, default=defaults.speed_mps, metavar="M/S",
                         help="the airframe's top horizontal speed: a mission asking more "
                              "(DO_CHANGE_SPEED) flies this")
    vehicle.add_argument("--climb", type=float, default=None, metavar="M/S",
                         help=f"climb rate limit (default: the firmware's, "
                              f"{defaults_text('climb_mps')})")
    vehicle.add_argument("--descent", type=float, default=None, metavar="M/S",
                         help=f"descent rate limit (default: the firmware's, "
                              f"{defaults_text('descent_mps')})")
    vehicle.add_argument("--accel", type=float, default=defaults.accel_mps2, metavar="M/S2",
                         help="horizontal acceleration limit")
    vehicle.add_argument("--warmup", type=float, default=None, metavar="S",
                         help="wall seconds of GPS/EKF warm-up before arming is allowed "
                              "(default: the firmware's SITL, sped up: ArduPilot GPS 10 s, "
                              "position 20 s, armable 45 s after the first client connects; "
                              "PX4 1.5, 2 and 5 s after start; divided by --speedup)")
    vehicle.add_argument("--capacity", type=int, default=None, metavar="N",
                         help="mission items a vehicle holds, home included; longer uploads "
                              "are refused with MAV_MISSION_NO_SPACE (default: the "
                              "firmware's: ArduPilot 650, PX4 no limit; 0 = no limit)")
    vehicle.add_argument("--battery", type=float, default=60.0, metavar="MIN",
                         help="minutes of hovering on a full battery (climbs draw more; "
                              "the failsafes act as the firmware's parameters say; a full "
                              "one is put in a minute after landing) (default: 60)")
    vehicle.add_argument("--auto-disarm", type=float, default=10.0, metavar="S",
                         help="disarm after S mission seconds armed and idle on the ground "
                              "(0 = never)")
    vehicle.add_argument("--auto-options", type=int, default=0, metavar="N",
                         help="ArduPilot AUTO_OPTIONS (1 = allow arming in AUTO)")
    vehicle.add_argument("--no-camera", action="store_true",
                         help="no camera configured: no CAMERA_FEEDBACK / CAMERA_IMAGE_CAPTURED")
    io = parser.add_argument_group("endpoints and output")
    io.add_argument("--base-port", type=int, metavar="P",
                    help="first port (default: 5760 ArduPilot TCP, 18570 PX4 UDP)")
    io.add_argument("--gcs-port", type=int, default=14550, metavar="P",
                    help="PX4: UDP port on 127.0.0.1 that telemetry is sent to")
    io.add_argument("--bind", default="127.0.0.1", metavar="HOST",
                    help="address to listen on (0.0.0.0 for other machines)")
    io.add_argument("--track-dir", metavar="DIR",
                    help="write each vehicle's true track to DIR/vehicle_<sysid>.json")
    io.add_argument("--duration", type=float, metavar="S",
                    help="stop after S wall seconds (default: run until Ctrl-C)")
    io.add_argument("--seed", type=int, default=0, help="random seed of packet drops")
    io.add_argument("--terrain", metavar="PLAN_DIR|GEOTIFF",
                    help="fly over this terrain (a plan directory's terrain.tif, or a "
                         "working-grid GeoTIFF): vehicles stand on it at home, land on it "
                         "and crash into it; default: flat ground at each home altitude, as "
                         "in SITL")
    radio = parser.add_argument_group("radio (with --terrain)")
    radio.add_argument("--antenna", action="append", default=[], metavar="LAT,LON[,MAST_M]",
                       help="the ground station's antenna, repeatable: each vehicle's link "
                            "is cut while no antenna has it in radio line of sight on the "
                            "--terrain")
    radio.add_argument("--radio", action="store_true",
                       help="cut each link by a plan directory's antennas (the shadows its "
                            "plan predicts, as gcs fly --sim and gcs demo do by default)")
    io.add_argument("--pty", action="store_true",
                    help="serve each vehicle on a pseudo-terminal (a serial link: connect "
                         "with DEVICE,BAUD) instead of its SITL network endpoint")


#: a home this far (m) above or below the terrain is not standing on it
HOME_GROUND_TOLERANCE_M = 0.1


def _point(text: str, option: str, ground=None) -> tuple:
    """(lat, lon, alt) of ``LAT,LON[,ALT]``: ALT left out is the terrain's ground there
    (``ground(lat, lon)``), or 0 without a terrain; with a terrain a home above or
    below its ground is refused (a copter placed in the air cannot take off)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in (2, 3) or not (-90 <= values[0] <= 90 and -180 <= values[1] <= 180):
        raise InputError(option, f"expected LAT,LON[,ALT] in degrees and metres, got {text!r}")
    if ground is None:
        return tuple(values) if len(values) == 3 else (values[0], values[1], 0.0)
    here = ground(values[0], values[1])
    if here is None or not math.isfinite(here):
        raise InputError(option, f"{values[0]:.6f},{values[1]:.6f} is outside the --terrain "
                                 "(or on a void)")
    if len(values) == 2:
        return values[0], values[1], float(here)
    off = values[2] - here
    if abs(off) > HOME_GROUND_TOLERANCE_M:
        where = "above" if off > 0 else "below"
        raise InputError(option, f"home altitude {values[2]:g} m is {abs(off):.2f} m {where} "
                                 f"the ground there ({here:.2f} m AMSL on the --terrain): leave "
                                 f"ALT out to stand on the ground")
    return values[0], values[1], values[2]


def config_from_args(args):
    """The `gcs.sim.FleetConfig` the flags ask for."""
    from gcs.sim.fleet import FleetConfig

    if args.vehicles < 1:
        raise InputError("--vehicles", "need at least one vehicle")
    if args.speedup <= 0:
        raise InputError("--speedup", "must be positive")
    if not 0 <= args.drop <= 100:
        raise InputError("--drop", "must be a percentage between 0 and 100")
    terrain, radio = _terrain(args.terrain, args)
    homes = None
    if args.homes:
        homes = [_point(p, "--homes", terrain) for p in args.homes.split(";") if p.strip()]
        if len(homes) != args.vehicles:
            raise InputError("--homes", f"{len(homes)} points for {args.vehicles} vehicles")
    if args.home is not None:
        home = _point(args.home, "--home", terrain)
    elif terrain is not None and homes is None:
        raise InputError("--home", "give the launch point on the --terrain (LAT,LON)")
    else:
        home = DEFAULT_HOME
    faults = {}

    def plan(sysid, option):
        if not 1 <= sysid <= args.vehicles:
            raise InputError(option, f"no vehicle with system id {sysid} "
                                     f"(ids are 1..{args.vehicles})")
        return faults.setdefault(sysid, FaultPlan())

    for text in args.kill:
        sysid, at_s, at_item = parse_kill(text)
        p = plan(sysid, "--kill")
        p.kill_at_s, p.kill_at_item = at_s, at_item
    for text in args.cut:
        sysid, start, seconds = parse_cut(text)
        plan(sysid, "--cut").cuts.append((start, seconds))
    for sysid in args.refuse_arm:
        plan(sysid, "--refuse-arm").refuse_arm = True
    if args.capacity is not None and args.capacity < 0:
        raise InputError("--capacity", f"must not be negative, got {args.capacity}")
    if args.battery <= 0:
        raise InputError("--battery", f"must be positive, got {args.battery:g}")
    if args.warmup is not None and args.warmup < 0:
        raise InputError("--warmup", f"must not be negative, got {args.warmup}")
    limits = Limits(args.speed, args.climb, args.descent, args.accel)
    if min(x for x in (limits.speed_mps, limits.climb_mps, limits.descent_mps,
                       limits.accel_mps2) if x is not None) <= 0:
        raise InputError("--speed/--climb/--descent/--accel", "limits must be positive")
    return FleetConfig(
        vehicles=args.vehicles, firmware=args.firmware, home=home,
        homes=homes, speedup=args.speedup, base_port=args.base_port, gcs_port=args.gcs_port,
        bind_host=args.bind, limits=limits, warmup_s=args.warmup,
        **({} if args.capacity is None else {"mission_capacity": args.capacity or None}),
        auto_disarm_s=args.auto_disarm, camera=not args.no_camera, battery_min=args.battery,
        auto_options=args.auto_options, drop_pct=args.drop, faults=faults,
        track_dir=args.track_dir, seed=args.seed, terrain=terrain, radio=radio,
        transport="pty" if args.pty else None)


def _terrain(path, args) -> tuple:
    """(ground, radio) of FleetConfig from --terrain and the radio flags."""
    if path is None:
        if args.antenna or args.radio:
            raise InputError("--antenna" if args.antenna else "--radio",
                             "needs --terrain: the radio's shadows are the terrain's")
        return None, None
    from pathlib import Path

    from gcs.cli.options import parse_antenna
    from gcs.sim import radio_for_plan, terrain_ground
    from planner.link import Antenna, Radio, contact_at
    from planner.plan import PLAN_FILE, TERRAIN_FILE, Plan
    from planner.terrain import read_terrain

    path = Path(path)
    file = path / TERRAIN_FILE if path.is_dir() else path
    if not file.is_file():
        raise InputError(file, "no such file (give a plan directory or a working-grid GeoTIFF)")
    terrain = read_terrain(file)
    radio = None
    if args.antenna:
        antennas = [Antenna(lat, lon, 2.0 if mast is None else mast)
                    for lat, lon, mast in map(parse_antenna, args.antenna)]
        try:
            radio = contact_at(terrain, antennas, Radio())
        except ValueError as exc:
            raise InputError("--antenna", str(exc)) from None
    elif args.radio:
        if not (path.is_dir() and (path / PLAN_FILE).is_file()):
            raise InputError(path, "--radio takes its antennas from a plan directory: give one, "
                                   "or sites of your own with --antenna")
        radio = radio_for_plan(Plan.load(path), terrain)
    return terrain_ground(terrain), radio


def run(args) -> int:
    from gcs.sim.fleet import SimFleet

    config = config_from_args(args)
    fleet = SimFleet(config)
    try:
        fleet.start()
    except OSError as exc:
        raise InputError("--base-port", f"cannot open a simulator endpoint: {exc}") from None
    try:
        _describe(fleet)
        _wait(fleet, args.duration)
    finally:
        fleet.stop()
    return 0


def _describe(fleet) -> None:
    from gcs.sim.flavours import flavour
    from gcs.sim.fleet import vehicle_port

    c = fleet.config
    for i, v in enumerate(fleet.vehicles):
        port = vehicle_port(c.firmware, i, c.base_port)
        if c.transport == "pty":
            where = f"serial {v.link.device}"
        elif flavour(c.firmware).transport == "tcp":
            where = f"TCP {c.bind_host}:{port}"
        else:
            where = f"UDP {c.bind_host}:{port} -> 127.0.0.1:{c.gcs_port}"
        lat, lon, alt = v.cfg.home
        print(f"vehicle {v.sysid} ({c.firmware}): {where}  home {lat:.6f},{lon:.6f},{alt:g} m AMSL")
    print("connect with: " + " ".join(f"--connect {u}" for u in fleet.urls()))
    print(f"speedup x{c.speedup:g}; Ctrl-C stops", flush=True)


def _wait(fleet, duration) -> None:
    end = None if duration is None else time.monotonic() + duration
    reported = set()
    while end is None or time.monotonic() < end:
        for v in fleet.vehicles:
            if v.dead and v.sysid not in reported:
                reported.add(v.sysid)
                print(f"vehicle {v.sysid} killed at mission time {v.track.killed_at:g} s",
                      flush=True)
        if len(reported) == len(fleet.vehicles):
            return
        time.sleep(0.2)
