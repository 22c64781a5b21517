"""Hostile outposts (`Outpost`) and their GeoJSON reader."""

import json
import math
import warnings
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from common.errors import InputError
from common.geo import distance_m

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
#: around an outpost outside the area of operations, the DEM is read this far too
CROP_MARGIN_M = 500.0
#: a post this far from the area whose swapped coordinates lie in it was given as
#: lat, lon (near the area, on the diagonal lat = lon, a swap stays near it too)
SWAPPED_FAR_M = 100_000.0
#: what an outpost Feature's properties may hold
KNOWN_PROPERTIES = frozenset({"name", "height_m", "range_m"})
#: styling that map tools add (simplestyle-spec, as geojson.io and our routes.geojson write)
STYLE_PROPERTIES = frozenset({"title", "description", "marker-size", "marker-symbol",
                              "marker-color", "stroke", "stroke-opacity", "stroke-width",
                              "fill", "fill-opacity"})


@dataclass(frozen=True)
class PostFeature:
    """An outpost as its GeoJSON Feature says, before it is placed on a terrain."""

    index: int
    lon: float
    lat: float
    height_m: float
    range_m: float
    name: str  # as given ("" when none)
    source: str

    @property
    def label(self) -> str:
        return f"feature {self.index}" + (f" ({self.name})" if self.name else "")


def load_outposts(path, terrain) -> list:
    """Outposts from a GeoJSON FeatureCollection of Points (lon, lat, WGS 84).

    Feature properties: ``height_m`` eye height above ground (default 2, with a
    warning naming the posts it was taken for),
    ``range_m`` detection range (absent or null: unlimited), ``name`` (optional);
    anything else but map styling is an error. Positions are converted to the
    terrain's CRS; a post must stand on the terrain, not outside it or on a void.
    """
    return place_outposts(read_outpost_features(path), terrain)


def read_outpost_features(path) -> list:
    """`PostFeature` per Feature of a GeoJSON file, checked (no terrain needed)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, f"cannot read it ({exc})") from None
    return _parse_features(text, path)


def sample_outpost_features() -> list:
    """The built-in outposts that go with `planner.terrain.sample_terrain`."""
    text = resources.files("planner.data").joinpath(SAMPLE_FILE).read_text(encoding="utf-8")
    return _parse_features(text, f"built-in {SAMPLE_FILE}")


def sample_outposts(terrain) -> list:
    """The built-in outposts on a window of the sample terrain: those standing on it
    (a warning names how many do not; `planner.pipeline` instead widens the crop
    to keep every post that can see into the area)."""
    features = sample_outpost_features()
    inside = [f for f in features if terrain.contains_xy(*terrain.from_lonlat(f.lon, f.lat))]
    if not inside:
        raise InputError(f"built-in {SAMPLE_FILE}", "no built-in outpost lies inside the area")
    if len(inside) < len(features):
        warnings.warn(f"built-in {SAMPLE_FILE}: {len(features) - len(inside)} "
                      "outpost(s) outside the area were left out", stacklevel=2)
    return place_outposts(inside, terrain)


def place_outposts(features, terrain) -> list:
    """Each `PostFeature` as an `Outpost` on ``terrain``; InputError naming a post
    outside the DEM or on a void."""
    return [_placed(f, terrain) for f in features]


def reaching(features, area) -> tuple:
    """([(post, distance m)] of the posts whose detection range reaches the area
    (south, west, north, east), the same of the others). A post outside the area
    still sees into it: only one whose range ends short of it can be left out.
    InputError for a post far from the area whose coordinates swapped lie in it
    (given lat, lon: it would be left out, or the DEM read out to it)."""
    kept, dropped = [], []
    for f in features:
        d = _distance_to_box(f.lon, f.lat, area)
        if d > SWAPPED_FAR_M and -90 <= f.lon <= 90 and _distance_to_box(f.lat, f.lon, area) == 0:
            raise InputError(f.source, f"{f.label}: lon {f.lon:.6f}, lat {f.lat:.6f} is "
                                       f"{d / 1000:.0f} km from the area; as lat,lon it would "
                                       "be inside it: GeoJSON coordinates are lon,lat")
        (kept if d <= f.range_m else dropped).append((f, d))
    return kept, dropped


def crop_around(area, features, margin_m=CROP_MARGIN_M) -> tuple:
    """The smallest (south, west, north, east) holding ``area`` and every post of
    ``features``, ``margin_m`` around the posts: terrain their sight lines cross
    on the way into the area must be in the grid."""
    s, w, n, e = area
    for f in features:
        dlat = margin_m / 111_320.0
        dlon = dlat / max(math.cos(math.radians(f.lat)), 1e-6)
        s, w = min(s, f.lat - dlat), min(w, f.lon - dlon)
        n, e = max(n, f.lat + dlat), max(e, f.lon + dlon)
    return s, w, n, e


def _distance_to_box(lon, lat, area) -> float:
    """Metres from (lon, lat) to the nearest point of the box (0 inside), the
    geodesic to its nearest corner or edge point in degrees (within metres over
    tens of km)."""
    s, w, n, e = area
    qlat, qlon = min(max(lat, s), n), min(max(lon, w), e)
    return distance_m(lat, lon, qlat, qlon)


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


def _parse_features(text: str, source) -> list:
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(source, f"not JSON ({exc})") from None
    if not isinstance(data, dict) or data.get("type") != "FeatureCollection" \
            or not isinstance(data.get("features"), list):
        raise InputError(source, "not a GeoJSON FeatureCollection")
    if not data["features"]:
        raise InputError(source, "no outposts (the FeatureCollection is empty)")
    features = [_feature(i, f, source) for i, f in enumerate(data["features"])]
    # an eye lower than the real one sees less than it does (the unsafe side): the
    # default is said, once per file, naming the posts it was taken for. A missing
    # range_m is unlimited range, the safe side: not said.
    unsized = [f.label for f, raw in zip(features, data["features"])
               if (raw.get("properties") or {}).get("height_m") is None]
    if unsized:
        warnings.warn(f"{source}: {', '.join(unsized)}: no height_m: eye "
                      f"{DEFAULT_HEIGHT_M:g} m above ground assumed", stacklevel=3)
    return features


def _feature(index: int, feature, source) -> PostFeature:
    props = (feature.get("properties") if isinstance(feature, dict) else None) or {}
    name = props.get("name") if isinstance(props, dict) else None
    label = f"feature {index}" + (f" ({name})" if name else "")

    def fail(problem):
        raise InputError(source, f"{label}: {problem}")

    if not isinstance(feature, dict) or feature.get("type") != "Feature":
        fail("not a GeoJSON Feature")
    if not isinstance(props, dict):
        fail("properties must be an object")
    unknown = sorted(set(props) - KNOWN_PROPERTIES - STYLE_PROPERTIES)
    if unknown:
        # a misspelt height_m would leave the eye at the default 2 m, lower than the
        # real one: it sees less than it does, which is the unsafe side
        fail(f"unknown propert{'y' if len(unknown) == 1 else 'ies'} "
             f"{', '.join(map(repr, unknown))}; an outpost has "
             f"{', '.join(sorted(KNOWN_PROPERTIES))} (and map styling such as marker-color)")
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
    return PostFeature(index, lon, lat, height, range_m, str(name) if name else "", str(source))


def _placed(f: PostFeature, terrain) -> Outpost:
    def fail(problem):
        raise InputError(f.source, f"{f.label}: {problem}")

    x, y = terrain.from_lonlat(f.lon, f.lat)
    if not terrain.contains_xy(x, y):
        fail(f"lon {f.lon:.6f}, lat {f.lat:.6f} is outside the DEM" + (
            "; as lat,lon it would be inside: GeoJSON coordinates are lon,lat"
            if terrain.swapped_inside(f.lon, f.lat) else ""))
    ground = float(terrain.exact_ground(x, y)[0])
    if not (np.isfinite(terrain.ground(x, y)[0]) and np.isfinite(ground)):
        fail(f"lon {f.lon:.6f}, lat {f.lat:.6f} is on a void of the DEM (no ground height)")
    return Outpost(x=float(x), y=float(y), height_m=f.height_m, range_m=f.range_m, lon=f.lon,
                   lat=f.lat, name=f.name or f"O{f.index + 1}", ground_m=ground)


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
