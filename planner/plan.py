"""The `Plan` data model: routes of hidden 3-D waypoints per vehicle, and plan.json.

A plan directory holds ``plan.json`` (this model, schema ``gcs-plan/2``) beside
``terrain.tif`` (the working-grid DEM, float32, metres AMSL), ``exposure.tif``
and ``coverage.tif``; later stages (missions, gcs) reload the terrain and the
outposts from it to re-check that every leg is hidden.

Times are on the fleet clock: t = 0 when the first takeoff starts. A vehicle's
``trajectory`` is its flight on that clock, from the ground at its launch point to
the ground after landing, as rows [t_s, lon, lat, alt_amsl], linear between rows
(a hold is two rows at one place); the plan proves that no two airborne vehicles
come closer than ``params.separation_m`` on them (``metrics.min_separation_m``).
Schema 2 added the fleet clock (``gcs-plan/1`` times were each vehicle's own).
"""

import json
import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Optional

from common.errors import InputError
from common.fileio import write_text_atomic

SCHEMA = "gcs-plan/2"
PLAN_FILE = "plan.json"
TERRAIN_FILE = "terrain.tif"
EXPOSURE_FILE = "exposure.tif"
COVERAGE_FILE = "coverage.tif"


@dataclass
class GeoPoint:
    lon: float
    lat: float
    alt_amsl: float


@dataclass
class Waypoint:
    lon: float
    lat: float
    alt_amsl: float
    t_s: float  # planned arrival, fleet clock
    snapshot: bool = False
    hold_s: float = 0.0  # waits here this long before flying on (whole seconds)
    sortie: int = 1  # the battery it is flown on (1, 2, ...: `VehicleRoute.sorties`)


@dataclass
class VehicleRoute:
    """One vehicle's hidden polyline, starting and ending at takeoff altitude above launch."""

    id: int
    launch: Optional[GeoPoint]
    waypoints: list
    coverage_time_s: float  # its last snapshot, fleet clock
    mission_time_s: float  # its touchdown, fleet clock
    path_length_m: float
    takeoff_s: float = 0.0  # leaves the ground, fleet clock
    trajectory: list = field(default_factory=list)  # [[t_s, lon, lat, alt_amsl], ...]
    priority: int = 1  # right of way in flight: 1 first (the separation guard holds others)
    # one per battery when the route takes more than one: {"takeoff_s", "landing_s"}
    # (fleet clock), "flight_s" (airborne, holds included), "length_m", "waypoints"
    # ([first, end) of `waypoints`), "base" ([lon, lat, alt_amsl] it takes off from),
    # "lands_at" (the base it lands at: the next sortie's "base"); empty: one flight
    sorties: list = field(default_factory=list)
    land: Optional[GeoPoint] = None  # where it lands, when not at ``launch`` (another base)
    # predicted out of the ground station's radio contact: [[from s, to s]] on the fleet
    # clock (planner.link); empty: in contact throughout, or no antenna to predict from
    silences: list = field(default_factory=list)

    @property
    def landing(self) -> Optional[GeoPoint]:
        """The ground point its flight ends at: ``land``, or its launch point."""
        return self.land or self.launch

    @property
    def snapshots(self) -> list:
        return [w for w in self.waypoints if w.snapshot]

    def sortie_routes(self) -> list:
        """The route as one `VehicleRoute` per sortie (itself when it flies one):
        each takes off from its base and lands at the base it names (``launch``,
        ``land``), its own mission."""
        if len(self.sorties) < 2:
            return [self]
        out = []
        for j, s in enumerate(self.sorties, start=1):
            w = [p for p in self.waypoints if p.sortie == j]
            rows = [r for r in self.trajectory     # their times are kept to the ms
                    if s["takeoff_s"] - 1e-3 <= r[0] <= s["landing_s"] + 1e-3]
            shots = [p.t_s for p in w if p.snapshot]
            base, lands = (_base_point(s.get(k)) for k in ("base", "lands_at"))
            out.append(replace(self, waypoints=w, takeoff_s=s["takeoff_s"],
                               coverage_time_s=max(shots, default=0.0),
                               mission_time_s=s["landing_s"], trajectory=rows,
                               path_length_m=s["length_m"], sorties=[],
                               launch=base or self.launch,
                               land=lands if lands != (base or self.launch) else None))
        return out


@dataclass
class Plan:
    method: str
    params: dict
    crs: str
    outposts: list  # [{"lon", "lat", "height_m", "range_m"}]; range_m None = unlimited
    vehicles: list  # [VehicleRoute]
    metrics: dict = field(default_factory=dict)
    timing_s: dict = field(default_factory=dict)

    # --- JSON ---------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {"schema": SCHEMA, **_finite(asdict(self))}

    @classmethod
    def from_dict(cls, data: dict, source="plan.json") -> "Plan":
        if not isinstance(data, dict) or data.get("schema") != SCHEMA:
            if isinstance(data, dict) and data.get("schema") == "gcs-plan/1":
                raise InputError(source, "a gcs-plan/1 plan has no fleet clock, so nothing "
                                         "proves its vehicles kept apart: plan it again")
            raise InputError(source, f"not a {SCHEMA} plan (schema is {data.get('schema')!r})"
                             if isinstance(data, dict) else "not a JSON object")
        try:
            vehicles = [
                VehicleRoute(
                    id=int(v["id"]),
                    launch=GeoPoint(**v["launch"]) if v.get("launch") else None,
                    waypoints=[Waypoint(**w) for w in v["waypoints"]],
                    coverage_time_s=float(v["coverage_time_s"]),
                    mission_time_s=float(v["mission_time_s"]),
                    path_length_m=float(v["path_length_m"]),
                    takeoff_s=float(v.get("takeoff_s", 0.0)),
                    trajectory=[list(map(float, row)) for row in v.get("trajectory", [])],
                    priority=int(v.get("priority", v["id"])),
                    sorties=[_sortie(s) for s in v.get("sorties", [])],
                    land=GeoPoint(**v["land"]) if v.get("land") else None,
                    silences=[list(map(float, w)) for w in v.get("silences", [])],
                )
                for v in data["vehicles"]
            ]
            return cls(method=data["method"], params=dict(data["params"]), crs=data["crs"],
                       outposts=list(data["outposts"]), vehicles=vehicles,
                       metrics=dict(data.get("metrics", {})),
                       timing_s=dict(data.get("timing_s", {})))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(source, f"malformed plan: {exc!r}") from None

    def save(self, directory) -> Path:
        path = Path(directory) / PLAN_FILE
        write_text_atomic(path, json.dumps(self.to_dict(), indent=1))
        return path

    @classmethod
    def load(cls, directory) -> "Plan":
        directory = Path(directory)
        path = directory / PLAN_FILE if directory.is_dir() else directory
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise InputError(path, "no such plan file") from None
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise InputError(path, f"not valid JSON ({exc})") from None
        return cls.from_dict(data, source=path)


def _finite(value):
    """JSON has no inf/NaN: write them as null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def _base_point(value) -> Optional[GeoPoint]:
    """A sortie's "base" or "lands_at" ([lon, lat, alt_amsl]) as a `GeoPoint`."""
    return None if value is None else GeoPoint(*map(float, value))


def _sortie(entry: dict) -> dict:
    """A sortie of plan.json: its times and length as floats, its waypoint range as
    ints, its base as [lon, lat, alt_amsl] (None without a launch point)."""
    out = {}
    for key, value in entry.items():
        if key == "waypoints":
            out[key] = [int(x) for x in value]
        elif key in ("base", "lands_at"):
            out[key] = None if value is None else [float(x) for x in value]
        else:
            out[key] = float(value)
    return out
