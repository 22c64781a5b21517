"""Hostile outposts (`Outpost`) and their GeoJSON reader."""

import json
import math
import warnings
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from common.errors import InputError

DEFAULT_HEIGHT_M = 2.0


@dataclass(frozen=True)
class Outpost:
    """An observer post: a UAV it sees is shot at.

    ``x, y`` are in the terrain grid's projected CRS; ``height_m`` is the eye
    height above ground; ``range_m`` is the detection range (inf = unlimited);
    ``ground_m`` is the ground under the eye, m AMSL, from the source DEM itself
    (NaN: take it from the working grid's upper surface).
    """

    x: float
    y: float
    height_m: float = DEFAULT_HEIGHT_M
    range_m: float = float("inf")
    lon: float = float("nan")
    lat: float = float("nan")
    name: str = ""
    ground_m: float = float("nan")


# --- GeoJSON -------------------------------------------------------------------------------

SAMPLE_FILE = "sample_outposts.geojson"


def load_outposts(path, terrain) -> list:
    """Outposts from a GeoJSON FeatureCollection of Points (lon, lat, WGS 84).

    Feature properties: ``height_m`` eye height above ground (default 2),
    ``range_m`` detection range (absent or null: unlimited), ``name`` (optional).
    Positions are converted to the terrain's CRS; a post must stand on the
    terrain, not outside it or on a void.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, f"cannot read it ({exc})") from None
    return _parse_outposts(text, terrain, path)


def sample_outposts(terrain) -> list:
    """The built-in outposts that go with `planner.terrain.sample_terrain`.

    On a sample cropped with ``area``, posts outside the crop are left out:
    their lines of sight would cross terrain the crop no longer holds.
    """
    text = resources.files("planner.data").joinpath(SAMPLE_FILE).read_text(encoding="utf-8")
    data = json.loads(text)
    inside = [f for f in data["features"]
              if terrain.contains_xy(*terrain.from_lonlat(*f["geometry"]["coordinates"]))]
    if not inside:
        raise InputError(f"built-in {SAMPLE_FILE}", "no built-in outpost lies inside the area")
    if len(inside) < len(data["features"]):
        warnings.warn(f"built-in {SAMPLE_FILE}: {len(data['features']) - len(inside)} "
                      "outpost(s) outside the area were left out", stacklevel=2)
    return _parse_outposts(json.dumps(dict(data, features=inside)), terrain,
                           f"built-in {SAMPLE_FILE}")


def outposts_to_geojson(outposts) -> dict:
    """The GeoJSON FeatureCollection `load_outposts` reads (range_m null = unlimited)."""
    features = []
    for o in outposts:
        if not (math.isfinite(o.lon) and math.isfinite(o.lat)):
            raise ValueError(f"outpost {o.name or (o.x, o.y)} has no lon/lat")
        props = {"name": o.name, "height_m": o.height_m,
                 "range_m": o.range_m if math.isfinite(o.range_m) else None}
        features.append({"type": "Feature", "properties": props,
                         "geometry": {"type": "Point", "coordinates": [o.lon, o.lat]}})
    return {"type": "FeatureCollection", "features": features}


def _parse_outposts(text: str, terrain, source) -> list:
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(source, f"not JSON ({exc})") from None
    if not isinstance(data, dict) or data.get("type") != "FeatureCollection" \
            or not isinstance(data.get("features"), list):
        raise InputError(source, "not a GeoJSON FeatureCollection")
    if not data["features"]:
        raise InputError(source, "no outposts (the FeatureCollection is empty)")
    return [_outpost(i, f, terrain, source) for i, f in enumerate(data["features"])]


def _outpost(index: int, feature, terrain, source) -> Outpost:
    props = (feature.get("properties") if isinstance(feature, dict) else None) or {}
    name = props.get("name") if isinstance(props, dict) else None
    label = f"feature {index}" + (f" ({name})" if name else "")

    def fail(problem):
        raise InputError(source, f"{label}: {problem}")

    if not isinstance(feature, dict) or feature.get("type") != "Feature":
        fail("not a GeoJSON Feature")
    if not isinstance(props, dict):
        fail("properties must be an object")
    geometry = feature.get("geometry") or {}
    if not isinstance(geometry, dict) or geometry.get("type") != "Point":
        kind = geometry.get("type") if isinstance(geometry, dict) else None
        fail(f"geometry must be a Point, got {kind or 'none'}")
    coords = geometry.get("coordinates")
    if not (isinstance(coords, list) and len(coords) >= 2 and all(_is_number(c) for c in coords)):
        fail("Point coordinates must be [lon, lat] numbers")
    lon, lat = float(coords[0]), float(coords[1])
    if not (-180 <= lon <= 180 and -90 <= lat <= 90):
        fail(f"coordinates {coords[:2]} are not lon, lat degrees")
    height = _number(props, "height_m", DEFAULT_HEIGHT_M, fail, minimum=0.0)
    range_m = _number(props, "range_m", math.inf, fail, minimum=0.0, strict=True)
    x, y = terrain.from_lonlat(lon, lat)
    if not terrain.contains_xy(x, y):
        fail(f"lon {lon:.6f}, lat {lat:.6f} is outside the DEM")
    ground = float(terrain.exact_ground(x, y)[0])
    if not (np.isfinite(terrain.ground(x, y)[0]) and np.isfinite(ground)):
        fail(f"lon {lon:.6f}, lat {lat:.6f} is on a void of the DEM (no ground height)")
    return Outpost(x=float(x), y=float(y), height_m=height, range_m=range_m, lon=lon, lat=lat,
                   name=str(name) if name else f"O{index + 1}", ground_m=ground)


def _number(props, key, default, fail, minimum, strict=False) -> float:
    value = props.get(key)
    if value is None:
        return default
    if not _is_number(value) or not math.isfinite(value):
        fail(f"{key} must be a finite number of metres, got {value!r}")
    if value < minimum or (strict and value == minimum):
        fail(f"{key} must be {'positive' if strict else 'zero or more'}, got {value}")
    return float(value)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)
