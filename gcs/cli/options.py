"""The flags commands share, in one place, and what they turn into.

- every `Scenario` field (`gcs plan`, `gcs demo`): flags default to None so that
  a scenario file's value survives unless the flag is given; the help shows the
  real default from `Scenario`;
- MAVLink connections and the mission protocol (`gcs upload`, `download`, `fly`).

Only light modules are imported here: `gcs --help` builds every command's
flags without loading the planner's kernels or pymavlink.
"""

import argparse
import functools
from dataclasses import fields

from autopilots import NAMES as FIRMWARES
from common.errors import InputError
from common.units import Z_UNITS
from planner.coverage.methods import method
from planner.rates import defaults_text
from planner.scenario import LAND_AT, METHODS, Scenario, make_scenario, read_scenario

_DEFAULTS = {f.name: f.default for f in fields(Scenario) if f.default is not f.default_factory}

HELP = {
    "resolution_m": "working grid spacing in metres (default: the DEM's own spacing)",
    "geoid_offset_m": "ellipsoid minus geoid height in metres, required for a DEM whose "
                      "heights are ellipsoidal (AMSL = h - offset)",
    "z_unit": "unit of the DEM's heights, for every --dem file, whatever the files say "
              "(default: each file's band unit or its CRS's vertical axis; metres when "
              "neither says; feet are converted to metres and said)",
    "min_area_pct": "refuse the plan (exit 2, nothing written) when it plans less than "
                    "this percentage of the area of operations (default: a warning below "
                    "10 %%)",
    "ceiling_agl_m": "highest altitude flown, metres above ground",
    "clearance_m": "lowest altitude flown, metres above the terrain surface",
    "hide_margin_m": "metres flown below the exposure surface",
    "curvature_coeff": "earth curvature and refraction coefficient as in GDAL (0 = off)",
    "sensor_range_m": "horizontal range of a snapshot in metres",
    "max_off_nadir_deg": "largest off-nadir angle a snapshot sees, degrees (default: any)",
    "viewpoint_spacing_m": "lattice spacing of candidate viewpoints in metres "
                           "(default: from the sensor range)",
    "uavs": "number of UAVs",
    "mast_m": "height of the antenna at each base above the ground, "
              "metres, when no --antenna is given",
    "radio_mhz": "frequency of the telemetry radio, MHz: its Fresnel zone must clear the "
                 "terrain",
    "radio_range_m": "range of the telemetry radio, metres",
    "max_silence_s": "longest a vehicle may be out of radio contact, seconds: routes check "
                     "in where they would be silent longer, and the plan says by how much "
                     "it could not keep it (default: any silence)",
    "speed_mps": "horizontal cruise speed, m/s",
    "climb_mps": f"climb rate, m/s (default: the firmware's, {defaults_text('climb_mps')})",
    "descent_mps": f"descent rate, m/s (default: the firmware's, "
                   f"{defaults_text('descent_mps')})",
    "takeoff_mps": f"climb rate of a takeoff's lowest metres, m/s (default: the firmware's, "
                   f"{defaults_text('takeoff_mps')})",
    "land_mps": f"descent rate of a landing's lowest metres, m/s (default: the firmware's, "
                f"{defaults_text('land_mps')})",
    "track_tolerance_m": "how far a vehicle may stray from its planned legs, metres: "
                         "every point that close to a leg is proven hidden too",
    "separation_m": "least distance between two airborne vehicles, metres, proven on their "
                    "trajectories and kept by waits (0: vehicles are not kept apart)",
    "separation_margin_m": "metres the plan keeps beyond --separation, so that the "
                           "separation guard acts only when a flight goes wrong, not on "
                           "its usual spread from the plan",
    "accel_mps2": "horizontal acceleration, m/s²: a vehicle slows at each waypoint, which "
                  "the schedule counts",
    "firmware": "the firmware flown: its missions, rates and stops at waypoints",
    "endurance_min": "flight time of one battery, takeoff to touchdown, minutes: routes "
                     "longer than it are flown in sorties from the base (default: unlimited, "
                     "said in every summary)",
    "reserve_pct": "percent of the endurance never planned: clear of the autopilot's "
                   "low-battery warning at 15 %% left, with room for wind",
    "turnaround_min": "minutes on the ground between two sorties: landing, battery swap, "
                      "checks",
    "land_at": "where a sortie lands: any (the fleet's base nearest its last viewpoint, "
               "where --launch names several; the next sortie takes off there) or own (the "
               "base it took off from)",
    "method": "coverage method: " + ", ".join(f"{m.name} ({m.brief})"
                                              for m in map(method, METHODS)),
    "k": "fault tolerance: every target seen by k+1 distinct UAVs",
    "visibility": "fault-tolerant visibility: hard or soft",
    "alpha": "PTV exponent alpha (visibility vs time)",
    "beta": "spread-out exponent beta",
    "step_time_cap_s": "cap th_ra on one insertion's added time, seconds (default: automatic)",
    "time_budget_s": "search budget of --method alns, seconds on the reference machine, "
                     "counted in work units so a plan is the same on any machine "
                     "(default: 0.01 s per snapshot of the start plan, 0.1 s up to 5 s "
                     "plus 5 s per million target cells, at most 20 s)",
    "seed": "random seed (ties and baselines)",
    "parts": "plan the area in N parts, one UAV group each, joined across the seams "
             "(default: one part per 12,000 viewpoints: large areas only)",
}


def _latlon(text: str) -> tuple:
    try:
        lat, lon = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError("--launch", f"expected LAT,LON in degrees, got {text!r}") from None
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        swapped = " (as LON,LAT it would be one)" if -90 <= lon <= 90 and -180 <= lat <= 180 \
            else ""
        raise InputError("--launch", f"{text!r} is not a latitude,longitude pair{swapped}: "
                                     "--launch takes LAT,LON")
    return lat, lon


def parse_antenna(text: str) -> tuple:
    """``LAT,LON[,MAST_M]`` -> (lat, lon, mast m or None)."""
    parts = text.split(",")
    if len(parts) not in (2, 3):
        raise InputError("--antenna", f"expected LAT,LON or LAT,LON,MAST_M, got {text!r}")
    try:
        mast = float(parts[2]) if len(parts) == 3 else None
    except ValueError:
        raise InputError("--antenna", f"the mast of {text!r} is no number of metres") from None
    if mast is not None and not 0 <= mast < 1000:
        raise InputError("--antenna", f"the mast of {text!r} must be 0 to 1000 m")
    try:
        lat, lon = _latlon(",".join(parts[:2]))
    except InputError as e:
        raise InputError("--antenna", e.problem.replace("--launch", "--antenna")) from None
    return lat, lon, mast


def _area(text: str) -> tuple:
    try:
        s, w, n, e = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError("--area", f"expected S,W,N,E in degrees, got {text!r}") from None
    if not (s < n and w < e):
        raise InputError("--area", f"{text!r}: need south < north and west < east")
    return s, w, n, e


#: the flag groups of a scenario, by title
SCENARIO_GROUPS = ("terrain and outposts", "hidden volume", "sensor", "fleet", "radio link",
                   "method")


def add_scenario_arguments(parser, with_scenario_file=True, groups=SCENARIO_GROUPS) -> None:
    """The flags of every `Scenario` field in ``groups`` (all by default)."""
    if with_scenario_file:
        parser.add_argument("scenario", nargs="?", help="scenario TOML file (flags override it)")
    terrain = parser.add_argument_group("terrain and outposts")
    terrain.add_argument("--dem", nargs="+", metavar="FILE",
                         help="DEM tiles: GeoTIFF (any CRS) or SRTM .hgt; several are mosaicked")
    terrain.add_argument("--sample", action="store_true", default=None,
                         help="use the built-in terrain (USGS Jacksboro DEM) and outposts")
    terrain.add_argument("--area", type=str, metavar="S,W,N,E",
                         help="crop to this area of operations, degrees")
    terrain.add_argument("--area-file", metavar="FILE",
                         help="area of operations as a polygon (GeoJSON Polygon / MultiPolygon, "
                              "KML or KMZ): only terrain inside it is a target")
    terrain.add_argument("--area-flight", action="store_true", default=None,
                         help="with --area-file: fly only inside the polygon too")
    terrain.add_argument("--outposts", metavar="GEOJSON",
                         help="outposts: GeoJSON Points with height_m and optional range_m")
    terrain.add_argument("--no-outposts", action="store_true", default=None,
                         help="plan with no observer posts at all (an explicit choice: without "
                              "it, --outposts is required, except with --sample)")
    for name in ("resolution_m", "geoid_offset_m", "min_area_pct"):
        _add(terrain, name, float)
    terrain.add_argument("--z-unit", dest="z_unit", choices=tuple(Z_UNITS), help=_help("z_unit"))
    fields_of = {
        "hidden volume": ("ceiling_agl_m", "clearance_m", "hide_margin_m", "curvature_coeff"),
        "sensor": ("sensor_range_m", "max_off_nadir_deg", "viewpoint_spacing_m"),
        "fleet": ("uavs", "speed_mps", "climb_mps", "descent_mps", "takeoff_mps", "land_mps",
                  "track_tolerance_m",
                  "separation_m", "separation_margin_m", "accel_mps2", "endurance_min",
                  "reserve_pct",
                  "turnaround_min"),
        "radio link": ("mast_m", "radio_mhz", "radio_range_m", "max_silence_s"),
        "method": ("k", "alpha", "beta", "step_time_cap_s", "time_budget_s", "seed", "parts"),
    }
    for title, names in fields_of.items():
        if title not in groups:
            continue
        group = parser.add_argument_group(title)
        for name in names:
            kind = int if name in ("uavs", "k", "seed", "parts") else float
            _add(group, name, kind)
        if title == "fleet":
            group.add_argument("--launch", nargs="+", metavar="LAT,LON",
                               help="launch point(s), degrees: the bases, up to one per UAV; "
                                    "with fewer, the UAVs take them in turn (default: UAVs "
                                    "start at their first viewpoints)")
            group.add_argument("--firmware", choices=FIRMWARES, help=_help("firmware"))
            group.add_argument("--land-at", dest="land_at", choices=LAND_AT,
                               help=_help("land_at"))
        if title == "radio link":
            group.add_argument("--antenna", dest="antennas", action="append",
                               metavar="LAT,LON[,MAST_M]",
                               help="the ground station's antenna, or a relay's, repeatable: "
                                    "the plan predicts where each vehicle is out of their "
                                    "line of sight (default: one at each --launch base, --mast "
                                    "above the ground)")
        if title == "method":
            group.add_argument("--method", choices=METHODS, help=_help("method"))
            group.add_argument("--visibility", choices=("hard", "soft"), help=_help("visibility"))


_UNITS = {"_mps2": "M/S2", "_mps": "M/S", "_deg": "DEG", "_m": "M", "_s": "S",
          "_min": "MIN", "_pct": "PCT"}


def _flag(name: str) -> dict:
    """``ceiling_agl_m`` -> ``--ceiling-agl`` with metavar ``M``: the unit is the metavar."""
    for suffix, unit in _UNITS.items():
        if name.endswith(suffix):
            return {"flag": "--" + name[: -len(suffix)].replace("_", "-"), "metavar": unit}
    return {"flag": "--" + name.replace("_", "-"), "metavar": "N" if name != "curvature_coeff"
            else "C"}


def _add(group, name: str, kind) -> None:
    spec = _flag(name)
    group.add_argument(spec["flag"], dest=name, type=kind, metavar=spec["metavar"],
                       help=_help(name))


def _help(name: str) -> str:
    default = _DEFAULTS.get(name)
    text = HELP[name]
    return text if default is None else f"{text} (default: {default})"


def scenario_from_args(args) -> "Scenario":
    """Merge defaults, the scenario file (if any) and the flags; a value no stage
    could use is named by the flag the user typed, or the file and its key."""
    file_values = read_scenario(args.scenario) if getattr(args, "scenario", None) else {}
    overrides = {f.name: getattr(args, f.name, None) for f in fields(Scenario)}
    if args.area is not None:
        overrides["area"] = _area(args.area)
    if getattr(args, "launch", None) is not None:
        overrides["launch"] = [_latlon(p) for p in args.launch]
    if getattr(args, "antennas", None) is not None:
        overrides["antennas"] = [parse_antenna(p) for p in args.antennas]
    return make_scenario(file_values, overrides, getattr(args, "scenario", None) or "options",
                         flags={f: flag for f, flag in scenario_flags().items()
                                if hasattr(args, f)})


@functools.cache
def scenario_flags() -> dict:
    """{`Scenario` field: the flag that sets it}, as `add_scenario_arguments` defines
    them (and the help shows them)."""
    parser = argparse.ArgumentParser(add_help=False)
    add_scenario_arguments(parser, with_scenario_file=False)
    return {a.dest: max(a.option_strings, key=len) for a in parser._actions if a.option_strings}


# -- MAVLink connections and the mission protocol ----------------------------------------
def add_connection_arguments(parser) -> None:
    """--connect, --signing-key, --connect-timeout: shared with `gcs download`."""
    parser.add_argument("--connect", action="append", default=[], metavar="URL", required=True,
                        help="MAVLink connection, repeatable: tcp:HOST:PORT (ArduPilot SITL "
                             "5760), udpin:0.0.0.0:14550 (PX4 SITL, telemetry radios), "
                             "udpout:HOST:PORT, /dev/ttyUSB0,57600 (serial DEVICE,BAUD)")
    parser.add_argument("--signing-key", metavar="FILE",
                        help="MAVLink 2 signing key: a 32-byte file, or a text file holding a "
                             "passphrase (SHA-256, as MAVProxy's 'signing setup'); "
                             "none: nothing is signed")
    add_connect_timeout(parser)
    add_protocol_arguments(parser)


#: wall seconds to wait for the vehicles' HEARTBEATs: one value for upload, download and fly
CONNECT_TIMEOUT_S = 30.0


def add_connect_timeout(parser) -> None:
    """--connect-timeout: the same flag and default for every command that connects."""
    parser.add_argument("--connect-timeout", type=float, default=CONNECT_TIMEOUT_S, metavar="S",
                        help="seconds (wall clock) to wait for every vehicle's HEARTBEAT "
                             f"(default: {CONNECT_TIMEOUT_S:g})")


def add_protocol_arguments(parser) -> None:
    """--protocol-timeout, --protocol-retries: shared by upload, download and fly."""
    parser.add_argument("--protocol-timeout", type=float, default=1.5, metavar="S",
                        help="mission protocol: wait this long for each answer before "
                             "resending (MAVLink recommends 1.5 s; shorter on fast links)")
    parser.add_argument("--protocol-retries", type=int, default=5, metavar="N",
                        help="mission protocol (and fly's commands): resend each message up "
                             "to N times before giving up (MAVLink recommends 5; more on "
                             "very lossy links)")


def protocol_from_args(args) -> dict:
    """Keyword arguments (timeout_s, retries) of the gcs.mission_protocol calls."""
    if not args.protocol_timeout > 0:
        raise InputError("--protocol-timeout", f"must be positive, got {args.protocol_timeout}")
    if args.protocol_retries < 0:
        raise InputError("--protocol-retries", f"must be 0 or more, got {args.protocol_retries}")
    return {"timeout_s": args.protocol_timeout, "retries": args.protocol_retries}


def parse_assignments(texts, flag="--vehicle", target="ROUTE") -> dict:
    """{system id: route}: ``SYSID=N`` texts of option ``flag`` (shared with gcs fly)."""
    out = {}
    for text in texts:
        sysid, sep, route = text.partition("=")
        if not sep or not sysid.strip().isdigit() or not route.strip().isdigit():
            raise InputError(flag, f"expected SYSID={target}, got {text!r}")
        if int(sysid) in out:
            raise InputError(flag, f"system id {sysid} given twice")
        out[int(sysid)] = int(route)
    return out


def check_urls(urls, flag="--connect") -> None:
    """Every URL in a form pymavlink takes (before anything is opened); InputError."""
    from gcs.link import LinkError, parse_url

    for url in urls:
        try:
            parse_url(url)
        except LinkError as exc:
            raise InputError(flag, str(exc)) from None


def open_link(args, expect):
    """GroundLink.open from the shared connection options; LinkError -> one line."""
    from gcs.link import GroundLink, LinkError
    from gcs.signing import load_key

    check_urls(args.connect)
    key = load_key(args.signing_key) if args.signing_key else None
    try:
        return GroundLink.open(args.connect, signing_key=key, expect=expect,
                               timeout_s=args.connect_timeout)
    except LinkError as exc:
        raise InputError("--connect", str(exc)) from None
