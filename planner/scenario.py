"""A `Scenario`: everything a plan is made from, readable from a TOML file.

Every field has a TOML key (``[section] key``) and a CLI flag (``--key-with-dashes``);
flags override the file, the file overrides the defaults below. Units are in
the names.
"""

import math
import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Optional

from autopilots import DEFAULT, NAMES, PROFILES
from common.errors import InputError
from common.units import Z_UNITS
from planner.coverage.methods import METHODS
from planner.rates import VERTICAL_RATES

#: the firmware names a scenario takes (the profiles')
FIRMWARES = NAMES
#: the default separation between airborne vehicles (m, 3-D). Each of two vehicles
#: may be off its planned point by its track tolerance (5 m: what its legs are
#: proven with) plus its GNSS error (about 3 m at 95 %): 16 m together; the
#: in-flight guard needs room to act on a drift from the schedule, about 1 s of
#: telemetry and command latency at 12 m/s (12 m); and a multicopter spans about
#: a metre: 30 m in all
SEPARATION_M = 30.0
#: below this a separation is not kept but pretended: GNSS error and track
#: tolerance alone take 16 m (0 turns it off, for comparisons)
MIN_SEPARATION_M = 15.0
#: metres a plan keeps beyond the separation, so that the in-flight guard acts only
#: when something is wrong, not on the spread of every flight: measured on the
#: demo flown by the built-in simulator (33x, a loaded 2-core machine), two
#: vehicles' offset from each other against their plans, each on its own schedule
#: from its liftoff, was 19.9 m at the median (47 m at the 95th percentile); the
#: demo's plan, proven at 30.3 m for 30 m, had its vehicles held 8 times
SEPARATION_MARGIN_M = 20.0

#: the part of a battery's endurance a plan never uses (%): PX4 warns at 15 % left
#: (BAT_LOW_THR) and acts at 7 % (BAT_CRIT_THR); a sortie planned to touch down
#: with a quarter left keeps clear of the warning with 10 % more for a headwind on
#: the way home, a landing queue at the base and a battery older than its rating
RESERVE_PCT = 25.0


@dataclass
class Scenario:
    # [terrain]
    dem: list = field(default_factory=list)  # DEM files (GeoTIFF, .hgt); empty with sample = true
    sample: bool = False  # the built-in terrain and outposts
    area: Optional[tuple] = None  # (south, west, north, east) degrees
    area_file: Optional[str] = None  # polygon (GeoJSON, KML, KMZ): targets only inside it
    area_flight: bool = False  # and flight too: nothing flown outside the polygon
    resolution_m: Optional[float] = None  # default: the DEM's own spacing
    geoid_offset_m: Optional[float] = None  # ellipsoid minus geoid height, for ellipsoidal DEMs
    z_unit: Optional[str] = None  # the DEM's height unit (m, ft, us-ft); None: as its files say
    min_area_pct: Optional[float] = None  # refuse a plan that plans less of the area (%)
    # [outposts]
    outposts: Optional[str] = None  # GeoJSON file
    no_outposts: bool = False  # an explicit choice: plan with no observer posts at all
    # [exposure]
    ceiling_agl_m: float = 120.0
    clearance_m: float = 30.0
    hide_margin_m: float = 10.0
    curvature_coeff: float = 0.85714
    # [sensor]
    sensor_range_m: float = 1500.0
    max_off_nadir_deg: Optional[float] = None
    viewpoint_spacing_m: Optional[float] = None  # default from the sensor range
    # [fleet]
    uavs: int = 4
    launch: list = field(default_factory=list)  # [(lat, lon)]: the bases, UAVs in turn
    speed_mps: float = 12.0
    # vertical rates; None: the firmware's at its defaults (`autopilots.Autopilot.rates`)
    climb_mps: Optional[float] = None
    descent_mps: Optional[float] = None
    takeoff_mps: Optional[float] = None  # the lowest metres of a takeoff (PX4: 10 m)
    land_mps: Optional[float] = None  # the lowest metres of a landing (ArduPilot: 10 m)
    track_tolerance_m: float = 5.0  # legs proven hidden and clear with this much room around
    separation_m: float = SEPARATION_M  # no two airborne vehicles closer, proven (0: not kept)
    separation_margin_m: float = SEPARATION_MARGIN_M  # planned beyond the separation
    accel_mps2: float = 3.0  # horizontal acceleration: the time a waypoint costs (fleet.stop_time)
    firmware: str = DEFAULT
    endurance_min: Optional[float] = None  # flight per battery, takeoff to touchdown (None: no
    #                                        limit, said in every summary)
    reserve_pct: float = RESERVE_PCT  # of the endurance, never planned
    turnaround_min: float = 5.0  # on the ground between sorties: landing, battery swap, checks
    land_at: str = "any"  # a sortie lands at "any" of the fleet's bases (the nearest), or its "own"
    # [link]: the ground station's radio (planner.link)
    antennas: list = field(default_factory=list)  # [(lat, lon, mast m)]; []: at each base
    mast_m: float = 2.0  # the default antennas' masts above the ground at each base
    radio_mhz: float = 915.0  # SiK telemetry radios (RFD900, Holybro); 433 MHz in Europe
    radio_range_m: float = 5000.0  # stock dipoles: a few km in the field
    max_silence_s: Optional[float] = None  # longest predicted silence a route may have (None:
    #                                        any): check-ins in contact (planner.link.checkins)
    # [method]
    method: str = "alns"  # the benchmark's best (benchmarks/bench_coverage.py, bench_plan.py)
    k: int = 0
    visibility: str = "soft"
    alpha: float = 0.55
    beta: float = 0.3
    step_time_cap_s: Optional[float] = None  # th_ra; default chosen by the benchmark
    time_budget_s: Optional[float] = None  # alns search budget; default scales with the plan
    seed: int = 0
    parts: Optional[int] = None  # planned in this many parts (planner.split); None: by size

    def __post_init__(self):
        """Rates not given are the firmware's (a plan says which it assumed)."""
        rates = _firmware_rates(self.firmware)
        for name in VERTICAL_RATES:
            if getattr(self, name) is None and rates is not None:
                setattr(self, name, getattr(rates, name))

    def validate(self, source="scenario", where=None) -> "Scenario":
        """Raise InputError for values no planner stage could use, naming each field as
        the user gave it: ``where(field)`` is (where its value came from, what the user
        calls it), e.g. ("--endurance", "--endurance") for a flag or ("s.toml",
        "[fleet] endurance_min") for a file's key (`make_scenario`); by default
        (``source``, the field's name)."""
        where = where or (lambda f: (source, f))
        for key, ok, problem in self._checks(lambda f: where(f)[1]):
            if not ok:
                src, name = where(key) if key else (source, None)
                raise InputError(src, problem if name in (None, src) else f"{name} {problem}")
        return self

    def _checks(self, n):
        """(field or None, ok, what is wrong, after the field's name ``n(field)``), in
        order: a check runs only when those before it passed (a value of the wrong
        type in a file stops at its own check)."""
        yield None, self.sample or self.dem, "no DEM given (use --dem FILE or --sample)"
        yield None, not (self.sample and self.dem), "give either --dem or --sample, not both"
        yield (None, not (self.outposts and self.no_outposts),
               "give either --outposts or --no-outposts, not both")
        yield (None, self.outposts or self.sample or self.no_outposts,
               "no outposts given: name the observer posts with --outposts FILE.geojson, or "
               "say there are none with --no-outposts")
        yield ("uavs", _whole(self.uavs, 1),
               f"must be a whole number of at least 1, got {self.uavs!r}")
        yield ("k", _whole(self.k, 0) and self.k < self.uavs,
               f"must be a whole number at least 0 and less than {n('uavs')} (k = {self.k!r}, "
               f"uavs = {self.uavs}): each target must be seen by k+1 distinct UAVs")
        for name, values in (("method", METHODS), ("visibility", ("hard", "soft")),
                             ("firmware", FIRMWARES), ("land_at", LAND_AT),
                             ("z_unit", (None, *Z_UNITS))):
            value = getattr(self, name)
            yield (name, isinstance(value, (str, type(None))) and value in values,
                   f"must be one of {', '.join(v for v in values if v)}, got {_got(value)}")
        for name in ("alpha", "beta"):
            value = getattr(self, name)
            yield (name, _number(value) and 0 <= value <= 1,
                   f"must be in [0, 1], got {_got(value)}")
        yield ("time_budget_s", self.time_budget_s is None or _positive(self.time_budget_s),
               f"must be a positive number of seconds, got {_got(self.time_budget_s)}")
        yield ("parts", self.parts is None or _whole(self.parts, 1),
               f"must be a whole number of at least 1, got {self.parts!r}")
        yield ("parts", self.parts is None or self.parts * (self.k + 1) <= self.uavs,
               f"{self.parts} parts need {self.k + 1} UAVs each (k + 1), "
               f"{(self.k + 1) * (self.parts or 1)} in all; uavs = {self.uavs}")
        yield ("area_flight", self.area_file or not self.area_flight,
               f"restricts flight to the {n('area_file')} polygon: give {n('area_file')} too")
        yield ("launch", len(self.launch) <= self.uavs,
               f"give at most one launch point per UAV ({self.uavs}), got "
               f"{len(self.launch)}")
        for name in ("ceiling_agl_m", "sensor_range_m", "speed_mps", "accel_mps2",
                     "radio_mhz", "radio_range_m", *VERTICAL_RATES):
            value = getattr(self, name)
            yield name, _positive(value), f"must be a positive number, got {_got(value)}"
        for name in ("clearance_m", "hide_margin_m", "curvature_coeff", "track_tolerance_m",
                     "separation_m", "separation_margin_m", "turnaround_min", "mast_m"):
            value = getattr(self, name)
            yield (name, _number(value) and value >= 0,
                   f"must not be negative, got {_got(value)}")
        yield ("endurance_min", self.endurance_min is None or _positive(self.endurance_min),
               "must be a positive number of minutes (leave it out: unlimited), got "
               f"{_got(self.endurance_min)}")
        yield ("reserve_pct", _number(self.reserve_pct) and 0 <= self.reserve_pct < 90,
               f"must be from 0 to 90, got {_got(self.reserve_pct)}")
        yield ("max_silence_s", self.max_silence_s is None or _positive(self.max_silence_s),
               "must be a positive number of seconds (leave it out: any silence), got "
               f"{_got(self.max_silence_s)}")
        yield ("max_silence_s", self.max_silence_s is None or self.antennas or self.launch,
               f"needs an antenna to be heard by ({n('antennas')}, or {n('launch')}: one "
               "stands at each base)")
        yield ("resolution_m", self.resolution_m is None or _positive(self.resolution_m),
               "must be a positive number of metres (leave it out: the DEM's own), got "
               f"{_got(self.resolution_m)}")
        yield ("min_area_pct", self.min_area_pct is None or
               (_number(self.min_area_pct) and 0 <= self.min_area_pct <= 100),
               f"must be a percentage from 0 to 100, got {_got(self.min_area_pct)}")
        yield ("geoid_offset_m", self.geoid_offset_m is None or _number(self.geoid_offset_m),
               f"must be a finite number of metres, got {_got(self.geoid_offset_m)}")
        yield ("endurance_min", self.endurance_min is None or self.launch,
               f"needs launch points ({n('launch')}): a sortie starts and ends at a base")
        yield ("separation_m", self.separation_m == 0 or self.separation_m >= MIN_SEPARATION_M,
               f"must be at least {MIN_SEPARATION_M:g} m (or 0: vehicles not kept apart), "
               f"got {_got(self.separation_m)}")

    # --- what each stage takes ---------------------------------------------------------
    def link(self) -> tuple:
        """(antennas, radio) of `planner.link`: the --antenna sites (a mast not given:
        ``mast_m``), or one at each launch point (a vehicle is armed and sent its
        sorties on its pad: its crew's radio is there; with one at the first only,
        a vehicle at a second base behind a ridge was never heard to start);
        ([], radio) without either."""
        from planner.link import Antenna, Radio
        sites = self.antennas or [(*p, None) for p in dict.fromkeys(
            tuple(p) for p in self.launch)]     # every base, whatever UAVs a re-plan has
        antennas = [Antenna(float(a[0]), float(a[1]),
                            self.mast_m if len(a) < 3 or a[2] is None else float(a[2]))
                    for a in sites]
        return antennas, Radio(self.radio_mhz, self.radio_range_m)

    def exposure_params(self):
        from planner.exposure import ExposureParams
        return ExposureParams(ceiling_agl_m=self.ceiling_agl_m, clearance_m=self.clearance_m,
                              hide_margin_m=self.hide_margin_m,
                              curvature_coeff=self.curvature_coeff)

    def sensor_params(self):
        from planner.visibility import SensorParams
        return SensorParams(self.sensor_range_m, self.max_off_nadir_deg)

    @property
    def planned_separation_m(self) -> float:
        """The separation plans are timed for: the separation and its margin (0 when
        vehicles are not kept apart)."""
        return self.separation_m + self.separation_margin_m if self.separation_m > 0 else 0.0

    def travel_params(self):
        from planner.travel import TravelParams
        rates = _firmware_rates(self.firmware)
        return TravelParams(self.speed_mps, self.climb_mps, self.descent_mps,
                            self.track_tolerance_m, self.takeoff_mps, rates.takeoff_band_m,
                            self.land_mps, rates.land_band_m)

    # --- plan.json's "params" --------------------------------------------------------------
    def params(self) -> dict:
        """Every planning parameter, units in the key (plan.json's ``params``)."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in _RENAMED}
        out.update(dem=list(self.dem), sample=bool(self.sample),
                   launch=[list(p) for p in self.launch_points],
                   outposts_file=self.outposts, target_height_m=TARGET_HEIGHT_M)
        return out

    @classmethod
    def from_params(cls, params: dict, source="plan.json") -> "Scenario":
        """The scenario a plan was made from (`params` inverted)."""
        known = {f.name for f in fields(cls)}
        values = {k: v for k, v in params.items() if k in known and k not in _RENAMED}
        values["outposts"] = params.get("outposts_file")
        values["launch"] = [tuple(p) for p in params.get("launch", [])]
        values["antennas"] = [tuple(p) for p in params.get("antennas", [])]
        if values.get("area") is not None:
            values["area"] = tuple(values["area"])
        try:
            return cls(**values)
        except TypeError as exc:
            raise InputError(source, f"bad planning parameters: {exc}") from None

    @property
    def usable_s(self) -> float:
        """Flight time a sortie may take, s: the endurance less the reserve (inf:
        unlimited)."""
        if self.endurance_min is None:
            return math.inf
        return 60.0 * self.endurance_min * (1.0 - self.reserve_pct / 100.0)

    @property
    def launch_points(self) -> list:
        """One (lat, lon) per UAV, or [] when UAVs start at their phase-1 points:
        fewer bases than UAVs take them in turn (UAV i at base i mod n: 3 UAVs from
        bases A and B fly from A, B, A)."""
        n = len(self.launch)
        return [tuple(self.launch[i % n]) for i in range(self.uavs)] if n else []


#: where a sortie may land: at the fleet's base nearest its last viewpoint, or its own
LAND_AT = ("any", "own")
#: fields plan.json keeps under another name (outposts -> outposts_file) or expanded
_RENAMED = ("outposts", "launch")
#: a target is a cell's centre this high above the ground (the sensor model's)
TARGET_HEIGHT_M = 0.5


def _firmware_rates(name):
    """The firmware's `autopilots.Rates`; None for an unknown one (`validate` says
    so)."""
    found = PROFILES.get(str(name).lower())
    return None if found is None else found.rates


def _number(x) -> bool:
    """A finite number (not a bool, not a string from a file)."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _positive(x) -> bool:
    return _number(x) and x > 0


def _got(x) -> str:
    """A value as a problem quotes it: numbers short (-5, not -5.0), others quoted."""
    return f"{x:g}" if _number(x) else repr(x)


def _whole(x, least) -> bool:
    return isinstance(x, int) and not isinstance(x, bool) and x >= least


# TOML section of each field; a key may also stand at the top level.
SECTIONS = {
    "terrain": ("dem", "sample", "area", "area_file", "area_flight", "resolution_m",
                "geoid_offset_m", "z_unit", "min_area_pct"),
    "outposts": ("outposts", "no_outposts"),
    "exposure": ("ceiling_agl_m", "clearance_m", "hide_margin_m", "curvature_coeff"),
    "sensor": ("sensor_range_m", "max_off_nadir_deg", "viewpoint_spacing_m"),
    "fleet": ("uavs", "launch", "speed_mps", "climb_mps", "descent_mps", "takeoff_mps",
              "land_mps", "track_tolerance_m",
              "separation_m", "separation_margin_m", "accel_mps2", "firmware",
              "endurance_min", "reserve_pct", "turnaround_min", "land_at"),
    "link": ("antennas", "mast_m", "radio_mhz", "radio_range_m", "max_silence_s"),
    "method": ("method", "k", "visibility", "alpha", "beta", "step_time_cap_s", "time_budget_s",
               "seed", "parts"),
}
_ALIASES = {("outposts", "file"): "outposts", ("method", "name"): "method",
            ("terrain", "files"): "dem"}


def read_scenario(path) -> dict:
    """Read a scenario TOML file into ``{field: value}``; relative paths resolve
    against the file's folder. Unknown keys are an error (a typo must not be
    silently ignored)."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(path, "no such scenario file") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(path, f"not valid TOML ({exc})") from None
    known = {f.name for f in fields(Scenario)}
    values = {}
    for key, value in data.items():
        if isinstance(value, dict) and key in SECTIONS:
            for sub, v in value.items():
                name = _ALIASES.get((key, sub), sub)
                if name not in known:
                    raise InputError(path, f"unknown key [{key}] {sub}")
                values[name] = v
        elif key in known:
            values[key] = value
        else:
            raise InputError(path, f"unknown key {key}")
    if isinstance(values.get("dem"), str):
        values["dem"] = [values["dem"]]
    values["dem"] = [str(_resolve(path, p)) for p in values.get("dem", [])]
    for name in ("outposts", "area_file"):
        if values.get(name):
            values[name] = str(_resolve(path, values[name]))
    for name, shape, degrees in (
            ("area", "[south, west, north, east]", lambda a: tuple(float(v) for v in a)),
            ("launch", "[[lat, lon], ...]", lambda a: [tuple(float(c) for c in p) for p in a]),
            ("antennas", "[[lat, lon, mast m], ...]", _antennas)):
        if values.get(name) is not None:
            try:
                values[name] = degrees(values[name])
            except (TypeError, ValueError):
                raise InputError(path, f"{toml_key(name)} must be {shape} in degrees, got "
                                       f"{values[name]!r}") from None
    return values


def _antennas(points) -> list:
    """[[lat, lon], [lat, lon, mast m], ...] -> [(lat, lon, mast m or None)]."""
    out = []
    for p in points:
        values = [float(c) for c in p]
        if len(values) not in (2, 3):
            raise ValueError(p)
        out.append(tuple(values) if len(values) == 3 else (*values, None))
    return out


def _resolve(toml_path: Path, p) -> Path:
    p = Path(p)
    return p if p.is_absolute() else toml_path.parent / p


def make_scenario(file_values: dict, overrides: dict, source="scenario", flags=None) -> Scenario:
    """Defaults, then the file's values, then flags (None = not given). A value no
    stage could use is named as the user gave it: by its flag (``flags``: {field:
    flag}), or as ``source``'s ``[section] key``; a default by its flag."""
    given = {k: v for k, v in overrides.items() if v is not None}
    merged = {**file_values, **given}
    flags = flags or {}

    def where(field):
        if field in file_values and field not in given:
            return source, toml_key(field)
        return (flags[field], flags[field]) if field in flags else (source, field)

    try:
        return Scenario(**merged).validate(source, where)
    except TypeError as exc:
        raise InputError(source, f"bad scenario value: {exc}") from None


def toml_key(field: str) -> str:
    """``[section] key`` of a `Scenario` field in a scenario file."""
    section = next((s for s, names in SECTIONS.items() if field in names), None)
    key = "file" if field == "outposts" else field  # as examples/reference.toml writes it
    return f"[{section}] {key}" if section else key
