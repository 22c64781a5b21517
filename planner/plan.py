"""The `Plan` data model: routes of hidden 3-D waypoints per vehicle, and plan.json.

A plan directory holds ``plan.json`` (this model, schema ``gcs-plan/1``) beside
``terrain.tif`` (the working-grid DEM, float32, metres AMSL), ``exposure.tif``
and ``coverage.tif``; later stages (missions, gcs) reload the terrain and the
outposts from it to re-check that every leg is hidden.
"""

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Optional

from common.errors import InputError
from common.fileio import write_text_atomic

SCHEMA = "gcs-plan/1"
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
    t_s: float  # planned time since the vehicle left the ground (takeoff climb included)
    snapshot: bool = False


@dataclass
class VehicleRoute:
    """One vehicle's hidden polyline, starting and ending at takeoff altitude above launch."""

    id: int
    launch: Optional[GeoPoint]
    waypoints: list
    coverage_time_s: float
    mission_time_s: float
    path_length_m: float

    @property
    def snapshots(self) -> list:
        return [w for w in self.waypoints if w.snapshot]


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
