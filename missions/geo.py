"""Routes for map users: ``routes.geojson`` (GIS tools) and ``routes.kml`` (Google Earth).

Both hold, per vehicle, the hidden route as a 3-D line (altitudes AMSL), its
snapshot points and its launch point, plus the outposts and their detection
ranges (geodesic circles). Coordinates are WGS 84 longitude, latitude.
Colours are the PNG plots' (`common.colours`): in GeoJSON as simplestyle
properties (``stroke``, ``marker-color``, ``fill``), which geojson.io, GitHub and
QGIS's simplestyle support read; in KML as styles.
"""

import json
import math
import xml.etree.ElementTree as ET

import numpy as np
from pyproj import Geod

from common.colours import OUTPOST_COLOUR, VEHICLE_COLOURS, kml_colour, vehicle_colour
from common.fileio import write_text_atomic

CIRCLE_VERTICES = 72
KML_NS = "http://www.opengis.net/kml/2.2"


# --- GeoJSON ------------------------------------------------------------------------------

def routes_geojson(plan) -> dict:
    features = []
    for v in plan.vehicles:
        features += _vehicle_features(v)
    for n, o in _placed(plan.outposts):
        features += _outpost_features(n, o)
    return {"type": "FeatureCollection", "features": features}


def write_geojson(path, plan) -> None:
    write_text_atomic(path, json.dumps(routes_geojson(plan), indent=1, allow_nan=False) + "\n")


def _vehicle_features(v) -> list:
    out = []
    colour = vehicle_colour(v.id)
    if v.waypoints:
        out.append(_feature("LineString", [_lonlatalt(w) for w in v.waypoints], {
            "kind": "route", "vehicle": v.id, "waypoints": len(v.waypoints),
            "snapshots": len(v.snapshots), "coverage_time_s": v.coverage_time_s,
            "mission_time_s": v.mission_time_s, "path_length_m": v.path_length_m,
            "altitude": "metres AMSL", "stroke": colour, "stroke-width": 3}))
    for index, w in enumerate(v.waypoints):
        if w.snapshot:
            out.append(_feature("Point", _lonlatalt(w), {
                "kind": "snapshot", "vehicle": v.id, "waypoint": index, "t_s": w.t_s,
                "alt_amsl_m": w.alt_amsl, "marker-color": colour, "marker-size": "small"}))
    if v.launch is not None:
        out.append(_feature("Point", _lonlatalt(v.launch), {
            "kind": "launch", "vehicle": v.id, "alt_amsl_m": v.launch.alt_amsl,
            "marker-color": "#ffffff", "marker-symbol": "square"}))
    return out


def _outpost_features(n, o) -> list:
    props = {"kind": "outpost", "name": o.get("name") or f"outpost {n + 1}",
             "height_m": o.get("height_m"), "range_m": o.get("range_m")}
    out = [_feature("Point", [o["lon"], o["lat"]], {**props, "marker-color": OUTPOST_COLOUR,
                                                     "marker-symbol": "triangle"})]
    if o.get("range_m") is not None and math.isfinite(float(o["range_m"])):
        ring = range_circle(o["lon"], o["lat"], o["range_m"])
        out.append(_feature("Polygon", [ring], {**props, "kind": "outpost range",
                                                "stroke": OUTPOST_COLOUR, "fill": OUTPOST_COLOUR,
                                                "fill-opacity": 0.08}))
    return out


def _placed(outposts):
    """(index, outpost) of the outposts with a finite position."""
    return [(n, o) for n, o in enumerate(outposts)
            if math.isfinite(float(o["lon"])) and math.isfinite(float(o["lat"]))]


def _feature(kind, coordinates, properties) -> dict:
    return {"type": "Feature", "geometry": {"type": kind, "coordinates": coordinates},
            "properties": {k: _finite(v) for k, v in properties.items()}}


def _lonlatalt(p) -> list:
    return [float(p.lon), float(p.lat), float(p.alt_amsl)]


def _finite(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def range_circle(lon, lat, radius_m, n=CIRCLE_VERTICES) -> list:
    """A closed ring [[lon, lat], ...] at geodesic distance ``radius_m`` (WGS 84)."""
    azimuth = np.linspace(0.0, 360.0, n, endpoint=False)
    lons, lats, _ = Geod(ellps="WGS84").fwd(np.full(n, float(lon)), np.full(n, float(lat)),
                                            azimuth, np.full(n, float(radius_m)))
    ring = [[float(a), float(b)] for a, b in zip(lons, lats)]
    return ring + [ring[0]]


# --- KML ----------------------------------------------------------------------------------

def routes_kml(plan) -> str:
    ET.register_namespace("", KML_NS)
    kml = ET.Element(_k("kml"))
    doc = ET.SubElement(kml, _k("Document"))
    _text(doc, "name", f"{plan.method.upper()} hidden coverage plan")
    for n, colour in enumerate(VEHICLE_COLOURS):
        _style(doc, f"vehicle{n}", kml_colour(colour))
    _style(doc, "outpost", kml_colour(OUTPOST_COLOUR), fill=kml_colour(OUTPOST_COLOUR, 0x33))
    for v in plan.vehicles:
        _vehicle_folder(doc, v, f"vehicle{(v.id - 1) % len(VEHICLE_COLOURS)}")
    if plan.outposts:
        folder = ET.SubElement(doc, _k("Folder"))
        _text(folder, "name", "outposts")
        for n, o in _placed(plan.outposts):
            _outpost_placemarks(folder, n, o)
    ET.indent(kml)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(kml, encoding="unicode") + "\n"


def write_kml(path, plan) -> None:
    write_text_atomic(path, routes_kml(plan))


def _vehicle_folder(doc, v, style) -> None:
    folder = ET.SubElement(doc, _k("Folder"))
    _text(folder, "name", f"vehicle {v.id}")
    if v.waypoints:
        mark = _placemark(folder, f"vehicle {v.id} route", style,
                          f"{len(v.snapshots)} snapshots, coverage {v.coverage_time_s:.0f} s, "
                          f"mission {v.mission_time_s:.0f} s, {v.path_length_m:.0f} m; "
                          "altitudes AMSL")
        line = ET.SubElement(mark, _k("LineString"))
        _text(line, "altitudeMode", "absolute")
        _text(line, "coordinates", _coords(v.waypoints))
    for index, w in enumerate(v.waypoints):
        if w.snapshot:
            mark = _placemark(folder, f"snapshot {index}", style,
                              f"t = {w.t_s:.0f} s, {w.alt_amsl:.1f} m AMSL")
            _point(mark, w, "absolute")
    if v.launch is not None:
        mark = _placemark(folder, f"vehicle {v.id} launch", style, "launch and landing point")
        _point(mark, v.launch, "clampToGround")


def _outpost_placemarks(folder, n, o) -> None:
    name = o.get("name") or f"outpost {n + 1}"
    rng = o.get("range_m")
    mark = _placemark(folder, name, "outpost", f"eye {o.get('height_m')} m above ground, "
                      f"range {'unlimited' if rng is None else f'{rng:.0f} m'}")
    pt = ET.SubElement(mark, _k("Point"))
    _text(pt, "coordinates", f"{o['lon']:.8f},{o['lat']:.8f}")
    if rng is not None and math.isfinite(float(rng)):
        mark = _placemark(folder, f"{name} range", "outpost", f"{rng:.0f} m")
        poly = ET.SubElement(mark, _k("Polygon"))
        _text(poly, "tessellate", "1")
        ring = ET.SubElement(ET.SubElement(poly, _k("outerBoundaryIs")), _k("LinearRing"))
        _text(ring, "coordinates", " ".join(f"{a:.8f},{b:.8f}"
                                            for a, b in range_circle(o["lon"], o["lat"], rng)))


def _placemark(parent, name, style, description):
    mark = ET.SubElement(parent, _k("Placemark"))
    _text(mark, "name", name)
    _text(mark, "description", description)
    _text(mark, "styleUrl", f"#{style}")
    return mark


def _point(mark, p, mode) -> None:
    pt = ET.SubElement(mark, _k("Point"))
    _text(pt, "altitudeMode", mode)
    _text(pt, "coordinates", f"{p.lon:.8f},{p.lat:.8f},{p.alt_amsl:.2f}")


def _coords(points) -> str:
    return " ".join(f"{p.lon:.8f},{p.lat:.8f},{p.alt_amsl:.2f}" for p in points)


def _style(doc, ident, colour, fill=None) -> None:
    style = ET.SubElement(doc, _k("Style"), id=ident)
    line = ET.SubElement(style, _k("LineStyle"))
    _text(line, "color", colour)
    _text(line, "width", "3")
    icon = ET.SubElement(style, _k("IconStyle"))
    _text(icon, "color", colour)
    if fill:
        poly = ET.SubElement(style, _k("PolyStyle"))
        _text(poly, "color", fill)


def _text(parent, tag, text) -> None:
    ET.SubElement(parent, _k(tag)).text = text


def _k(tag) -> str:
    return f"{{{KML_NS}}}{tag}"
