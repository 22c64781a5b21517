"""--area-file (issue 23): a polygon from GeoJSON, KML or KMZ restricts the targets
(and with area_flight the flight) to it; the bounding box --area stays. Judged by
the plan's own targets and waypoints against a point-in-polygon test of our own
here, and bad files by the one-line error."""

import json
import zipfile

import numpy as np
import pytest
from hills import central_outpost
from quick_plan import plan_routes

from common.errors import InputError
from gcs.cli import main
from planner.scenario import Scenario, read_scenario
from planner.terrain import synthetic_terrain
from planner.terrain.area import area_mask, read_area

pytestmark = pytest.mark.timeout(300)

N = 60


@pytest.fixture(scope="module")
def hills():
    terrain = synthetic_terrain(N, N, cell=30.0, seed=3, family="hills")
    outposts = [central_outpost(terrain)]
    launch = terrain.to_lonlat(*terrain.xy(6, 6))
    return terrain, outposts, (launch[1], launch[0])


def _lonlat(terrain, rc):
    lon, lat = terrain.to_lonlat(*terrain.xy(*np.asarray(rc, float).T))
    return np.stack([lon, lat], axis=1)


def _west_polygon(terrain):
    """A quadrilateral over the western 40 % of the grid, with a square hole."""
    # corners between cell centres: no centre lies on an edge
    outer = _lonlat(terrain, [(0.5, 0.5), (0.5, 24.5), (58.5, 24.5), (58.5, 0.5), (0.5, 0.5)])
    hole = _lonlat(terrain, [(29.5, 7.5), (29.5, 15.5), (37.5, 15.5), (37.5, 7.5), (29.5, 7.5)])
    return outer, hole


def _geojson(path, rings):
    path.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": "west"},
         "geometry": {"type": "Polygon", "coordinates": [r.tolist() for r in rings]}},
        {"type": "Feature", "properties": {}, "geometry": {"type": "Point",
                                                           "coordinates": [0, 0]}}]}))
    return path


def _kml(rings) -> str:
    def coords(r):
        return " ".join(f"{a:.9f},{b:.9f},0" for a, b in r)
    inner = "".join(f"<innerBoundaryIs><LinearRing><coordinates>{coords(r)}</coordinates>"
                    "</LinearRing></innerBoundaryIs>" for r in rings[1:])
    return ('<?xml version="1.0" encoding="UTF-8"?><kml xmlns="http://www.opengis.net/kml/2.2">'
            "<Document><Placemark><name>west</name><MultiGeometry><Polygon><outerBoundaryIs>"
            f"<LinearRing><coordinates>{coords(rings[0])}</coordinates></LinearRing>"
            f"</outerBoundaryIs>{inner}</Polygon></MultiGeometry></Placemark></Document></kml>")


def _inside(point, rings) -> bool:
    """Even-odd point in polygon, in lon/lat (the files' own coordinates)."""
    x, y = point
    odd = False
    for ring in rings:
        for (ax, ay), (bx, by) in zip(ring[:-1], ring[1:]):
            if (ay > y) != (by > y) and x < ax + (y - ay) * (bx - ax) / (by - ay):
                odd = not odd
    return odd


def test_geojson_kml_and_kmz_read_the_same(hills, tmp_path):
    terrain = hills[0]
    rings = _west_polygon(terrain)
    gj = read_area(_geojson(tmp_path / "a.geojson", rings))
    (tmp_path / "a.kml").write_text(_kml(rings))
    with zipfile.ZipFile(tmp_path / "a.kmz", "w") as z:
        z.writestr("doc.kml", _kml(rings))
    masks = [area_mask(terrain, read_area(p)) for p in (tmp_path / "a.geojson",
                                                       tmp_path / "a.kml", tmp_path / "a.kmz")]
    assert len(gj) == 1 and len(gj[0]) == 2
    assert all((m == masks[0]).all() for m in masks)
    # against a plain point-in-polygon test of every cell centre, in lon/lat
    rows, cols = np.mgrid[0:N, 0:N]
    centres = _lonlat(terrain, np.stack([rows.ravel(), cols.ravel()], 1))
    expected = np.array([_inside(p, rings) for p in centres]).reshape(N, N)
    assert (masks[0] == expected).all()
    assert masks[0][10, 10] and not masks[0][34, 12] and not masks[0][10, 40]
    multi = {"type": "MultiPolygon", "coordinates": [[r.tolist() for r in rings]]}
    (tmp_path / "m.json").write_text(json.dumps(multi))
    assert (area_mask(terrain, read_area(tmp_path / "m.json")) == expected).all()


def test_targets_and_optionally_flight_stay_in_the_polygon(hills, tmp_path):
    terrain, outposts, launch = hills
    rings = _west_polygon(terrain)
    path = _geojson(tmp_path / "west.geojson", rings)
    common = dict(sample=True, uavs=2, sensor_range_m=500.0, ceiling_agl_m=150.0,
                  clearance_m=20.0, hide_margin_m=5.0, launch=[launch],
                  method="rt+ls")   # the polygon is the point here, not the search
    whole, _ = plan_routes(Scenario(**common).validate(), terrain, outposts)
    ctx, outcome = plan_routes(Scenario(**common, area_file=str(path)).validate(), terrain,
                               outposts)
    inside = area_mask(terrain, read_area(path))
    r, c = ctx.visibility.target_rowcol()
    assert ctx.visibility.n_targets > 0 and inside[r, c].all()
    wr, wc = whole.visibility.target_rowcol()
    assert ctx.visibility.n_targets == int(inside[wr, wc].sum()) < whole.visibility.n_targets
    assert outcome.plan.metrics["k_covered"] == outcome.plan.metrics["targets"] == \
        ctx.visibility.n_targets
    assert outcome.plan.params["area_file"] == str(path)
    # a plain check of the sparse sets: viewpoint rows and target columns agree
    for v in range(0, ctx.visibility.n_viewpoints, 37):
        for t in ctx.visibility.seen_by(v):
            assert v in ctx.visibility.seers(t)
    # area_flight: every waypoint inside the polygon too
    ctx2, flown = plan_routes(Scenario(**common, area_file=str(path), area_flight=True)
                              .validate(), terrain, outposts)
    points = [(w.lon, w.lat) for v in flown.plan.vehicles for w in v.waypoints]
    assert points and all(_inside(p, rings) for p in points)
    assert np.isnan(ctx2.surface.exposure[~inside]).all()
    # the overview draws the polygon and says what it is
    from gcs.plots import overview_figure
    fig = overview_figure(ctx2.terrain, ctx2.surface, flown.plan)
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert "area of operations (targets and flight inside)" in labels


def test_scenario_key_and_flag(tmp_path, hills):
    rings = _west_polygon(hills[0])
    _geojson(tmp_path / "west.geojson", rings)
    (tmp_path / "s.toml").write_text('[terrain]\nsample = true\narea_file = "west.geojson"\n'
                                     "area_flight = true\n")
    values = read_scenario(tmp_path / "s.toml")
    assert values["area_file"] == str(tmp_path / "west.geojson") and values["area_flight"]
    with pytest.raises(InputError, match="give area_file too"):
        Scenario(sample=True, area_flight=True).validate()


@pytest.mark.parametrize("name, content, problem", [
    ("nope.geojson", None, "no such file"),
    ("points.geojson", '{"type": "FeatureCollection", "features": [{"type": "Feature", '
                       '"geometry": {"type": "Point", "coordinates": [0, 0]}}]}',
     "no polygon in the file"),
    ("bad.kml", "<kml><Polygon>", "not KML"),
    ("bad.kmz", "not a zip", "not a KMZ"),
    ("far.geojson", '{"type": "Polygon", "coordinates": [[[10, 50], [10.1, 50], [10.1, 50.1], '
                    '[10, 50]]]}', "the polygon covers no cell of the terrain"),
    ("area.shp", "", "not an area file"),
])
def test_bad_area_files_one_line_exit_2(tmp_path, capsys, name, content, problem):
    path = tmp_path / name
    if content is not None:
        path.write_text(content)
    out = tmp_path / "out"
    code = main(["plan", "--sample", "--area", "36.49,-84.28,36.53,-84.22",
                 "--area-file", str(path), "--uavs", "2", "--viewpoint-spacing", "600",
                 "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert err[-1] == f"gcs plan: error: {path}: " + err[-1].split(f"{path}: ", 1)[1]
    assert problem in err[-1]
    assert not out.exists() or not any(out.iterdir())
