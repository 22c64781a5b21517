"""The area of operations as a polygon: GeoJSON, KML or KMZ, as users draw it.

    polygons = read_area(path)                 # [[ring, ring, ...], ...], rings of (lon, lat)
    inside = area_mask(terrain, polygons)      # bool [rows, cols]: cell centre inside
    targets, flight = areas(terrain, box, path, area_flight)   # what a plan may use

Accepted: a GeoJSON Polygon or MultiPolygon, bare, as a Feature or in a
FeatureCollection (every polygon feature counts; other geometries are
ignored); a KML file's ``<Polygon>`` elements (in Placemarks or a
MultiGeometry; outer and inner boundaries); a KMZ (the zipped KML Google Earth
writes). Coordinates are WGS 84 longitude, latitude (GeoJSON and KML both say
so). Holes are honoured: a point is inside when it is inside an odd number of
rings of its polygon (even-odd rule).

A scenario's area of operations is a (south, west, north, east) box, a polygon
file, or both (`areas`): targets lie inside both, and flight inside the box, and
inside the polygon too where the scenario says so.
"""

import json
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np

from common.errors import InputError

SUFFIXES = (".geojson", ".json", ".kml", ".kmz")


def read_area(path) -> list:
    """Polygons of ``path``: [polygon], each a list of rings, each an (n, 2) array of
    lon, lat. InputError naming the file for anything else."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise InputError(path, "not an area file: expected GeoJSON (.geojson, .json), "
                               ".kml or .kmz")
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except OSError as exc:
        raise InputError(path, f"cannot read: {exc.strerror}") from None
    if suffix == ".kmz":
        polygons = _kml_polygons(_kmz_text(path, data), path)
    elif suffix == ".kml":
        polygons = _kml_polygons(data, path)
    else:
        polygons = _geojson_polygons(data, path)
    if not polygons:
        raise InputError(path, "no polygon in the file (a Polygon or MultiPolygon is needed)")
    for polygon in polygons:
        for ring in polygon:
            bad = ~(np.abs(ring[:, 0]) <= 180) | ~(np.abs(ring[:, 1]) <= 90)
            if bad.any():
                lon, lat = ring[np.flatnonzero(bad)[0]]
                raise InputError(path, f"coordinate {lon!r}, {lat!r} is not a longitude, "
                                       "latitude in degrees")
    return polygons


def _geojson_polygons(data: bytes, path) -> list:
    try:
        doc = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(path, f"not GeoJSON: invalid JSON ({exc})") from None
    out = []

    def geometry(g, where):
        if not isinstance(g, dict):
            return
        kind = g.get("type")
        try:
            if kind == "Polygon":
                out.append(_rings(g["coordinates"], path, where))
            elif kind == "MultiPolygon":
                out.extend(_rings(p, path, where) for p in g["coordinates"])
            elif kind == "GeometryCollection":
                for sub in g.get("geometries", []):
                    geometry(sub, where)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(path, f"{where}: malformed {kind} ({exc})") from None

    if not isinstance(doc, dict):
        raise InputError(path, "not GeoJSON: expected an object")
    kind = doc.get("type")
    if kind == "FeatureCollection":
        for n, f in enumerate(doc.get("features") or []):
            geometry((f or {}).get("geometry"), f"feature {n}")
    elif kind == "Feature":
        geometry(doc.get("geometry"), "feature")
    elif kind in ("Polygon", "MultiPolygon", "GeometryCollection"):
        geometry(doc, "geometry")
    else:
        raise InputError(path, f"not GeoJSON: type {kind!r}")
    return out


def _rings(coordinates, path, where) -> list:
    rings = []
    for ring in coordinates:
        a = np.asarray([[float(c[0]), float(c[1])] for c in ring], float)
        if len(a) < 3:
            raise InputError(path, f"{where}: a ring has {len(a)} points, a polygon needs 3")
        rings.append(a)
    if not rings:
        raise InputError(path, f"{where}: a polygon without rings")
    return rings


def _kmz_text(path, data: bytes) -> bytes:
    import io

    try:
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            names = [n for n in z.namelist() if n.lower().endswith(".kml")]
            if not names:
                raise InputError(path, "no .kml inside the KMZ")
            main = "doc.kml" if "doc.kml" in names else names[0]
            return z.read(main)
    except zipfile.BadZipFile:
        raise InputError(path, "not a KMZ (not a zip file)") from None


def _kml_polygons(data: bytes, path) -> list:
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise InputError(path, f"not KML: {exc}") from None
    out = []
    for n, poly in enumerate(e for e in root.iter() if _local(e.tag) == "Polygon"):
        rings = []
        for boundary in poly:
            if _local(boundary.tag) not in ("outerBoundaryIs", "innerBoundaryIs"):
                continue
            for coords in (e for e in boundary.iter() if _local(e.tag) == "coordinates"):
                rings.append(_kml_ring(coords.text or "", path, n))
        if rings:
            out.append(rings)
    return out


def _kml_ring(text: str, path, n) -> np.ndarray:
    points = []
    for token in text.split():
        parts = token.split(",")
        try:
            points.append([float(parts[0]), float(parts[1])])
        except (IndexError, ValueError):
            raise InputError(path, f"polygon {n + 1}: bad coordinate {token!r}") from None
    if len(points) < 3:
        raise InputError(path, f"polygon {n + 1}: a ring has {len(points)} points, "
                               "a polygon needs 3")
    return np.asarray(points, float)


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def area_mask(terrain, polygons) -> np.ndarray:
    """bool [rows, cols]: the cell's centre lies inside one of ``polygons`` (even-odd
    rule per polygon, rings projected onto the terrain's grid). Vectorised over
    cells; the loop is over polygon edges."""
    rows, cols = terrain.shape
    cx = terrain.transform.c + (np.arange(cols) + 0.5) * terrain.transform.a
    cy = terrain.transform.f + (np.arange(rows) + 0.5) * terrain.transform.e
    inside = np.zeros((rows, cols), bool)
    for polygon in polygons:
        odd = np.zeros((rows, cols), bool)
        for ring in polygon:
            x, y = terrain.from_lonlat(ring[:, 0], ring[:, 1])
            x, y = np.asarray(x, float), np.asarray(y, float)
            x2, y2 = np.roll(x, -1), np.roll(y, -1)
            for ax_, ay, bx, by in zip(x, y, x2, y2):
                if ay == by:
                    continue
                # rows the edge spans (cy descends: row 0 is the north edge)
                band = np.flatnonzero((cy < max(ay, by)) & (cy >= min(ay, by)))
                if not len(band):
                    continue
                r0, r1 = band[0], band[-1] + 1
                at = ax_ + (cy[r0:r1, None] - ay) * (bx - ax_) / (by - ay)
                odd[r0:r1] ^= cx[None, :] < at
        inside |= odd
    return inside


__all__ = ["SUFFIXES", "area_mask", "read_area"]


def box_ring(area) -> list:
    """The (south, west, north, east) box as an `area_mask` polygon (lon, lat ring)."""
    s, w, n, e = area
    return [np.array([[w, s], [e, s], [e, n], [w, n]], float)]


def area_of(terrain, area_file, polygons=None):
    """bool [rows, cols] of the cells inside ``area_file``'s polygon (``polygons``:
    read from it already); None without one."""
    if not area_file:
        return None
    inside = area_mask(terrain, polygons if polygons is not None else read_area(area_file))
    if not inside.any():
        raise InputError(area_file, "the polygon covers no cell of the terrain (outside the "
                                    "DEM or the --area crop?)")
    return inside


def areas(terrain, box=None, area_file=None, area_flight=False, polygons=None) -> tuple:
    """(where targets are, where the fleet may fly): bool [rows, cols] masks, None
    where nothing restricts it. Targets lie inside the (south, west, north, east)
    ``box`` (the DEM may be read wider, around outposts outside it) and the
    ``area_file`` polygon; flight stays inside the box, and inside the polygon
    with ``area_flight``."""
    inside_box = area_mask(terrain, [box_ring(box)]) if box is not None else None
    shape = area_of(terrain, area_file, polygons)
    return _both(inside_box, shape), _both(inside_box, shape if area_flight else None)


def _both(a, b):
    """The intersection of two optional masks (None: no restriction)."""
    return b if a is None else a if b is None else a & b
