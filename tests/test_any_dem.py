"""`gcs plan` on the DEMs users bring: geographic GeoTIFFs with nodata margins,
projected GeoTIFFs, SRTM tiles with voids; every method, k = 0..2, with and
without launch points. It plans, or it refuses with one line in the user's
terms; a plan it writes passes the mission check when re-exported
(`gcs export` rebuilds the surface from the plan folder and proves every leg).
"""

import json
import re

import numpy as np
import pytest
import rasterio
from affine import Affine
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from gcs.cli import main
from planner.scenario import METHODS
from planner.terrain import synthetic_terrain

pytestmark = pytest.mark.slow

#: what the source of a refusal may be: a file the user gave or an option / stage
#: named in the user's terms (README, "Errors")
USER_SOURCES = re.compile(r"^gcs plan: error: (\S+\.(tif|hgt|geojson)|launch|exposure|options|"
                          r"--area|--launch|--resolution|plan): ")
INTERNAL = re.compile(r"Traceback|Error\b|path:|node|kernel|numba|index", re.IGNORECASE)


def _terrain(seed, rows, cols, cell):
    family = ("hills", "ridges", "peaks", "mixed")[seed % 4]
    return synthetic_terrain(rows, cols, cell=cell, seed=seed, family=family).height


def _geotiff(path, height, transform, crs, nodata):
    with rasterio.open(path, "w", driver="GTiff", width=height.shape[1],
                       height=height.shape[0], count=1, dtype="float32", crs=crs,
                       transform=transform, nodata=nodata) as ds:
        ds.write(height.astype(np.float32), 1)


def _geographic_with_margin(tmp, seed):
    """A 1" geographic tile whose data ends at a slanted nodata edge, as a
    reprojected tile's does, with a void inside."""
    height = _terrain(seed, 90, 110, 28.0)
    rows, cols = np.mgrid[0:90, 0:110]
    height[rows + 0.4 * cols < 12 + seed % 7] = -9999.0
    height[40:46, 60:67] = -9999.0  # a void too large to fill
    lon0, lat0 = -84.3 + (seed % 5) * 0.01, 36.6
    path = tmp / "geo.tif"
    _geotiff(path, height, Affine(1 / 3600, 0, lon0, 0, -1 / 3600, lat0), "EPSG:4326", -9999.0)
    return path, (lon0 + 10 / 3600, lat0 - 80 / 3600, lon0 + 100 / 3600, lat0 - 10 / 3600)


def _projected(tmp, seed):
    """A UTM tile (south of the equator: zone 56S) with a nodata margin."""
    height = _terrain(seed, 90, 100, 30.0)
    height[:, : 3 + seed % 5] = np.nan
    path = tmp / "utm.tif"
    x0, y0 = 334_011.0, 6_252_017.0
    _geotiff(path, height, Affine(30, 0, x0, 0, -30, y0), "EPSG:32756", np.nan)
    from pyproj import Transformer
    to_ll = Transformer.from_crs("EPSG:32756", "EPSG:4326", always_xy=True)
    w, n = to_ll.transform(x0 + 300, y0 - 300)
    e, s = to_ll.transform(x0 + 2700, y0 - 2400)
    return path, (w, s, e, n)


def _hgt(tmp, seed):
    """An SRTM 3" tile (S35E149: southern, eastern) with voids, cropped by --area."""
    n = 1201
    j, i = np.mgrid[0:n, 0:n]
    rng = np.random.default_rng(seed)
    h = (600 + 250 * np.sin(i / 23.0 + rng.uniform(0, 6)) * np.cos(j / 31.0)
         + 80 * np.sin(i / 7.0 + j / 11.0)).astype(">i2")
    h[600:603, 600:604] = -32768  # filled (small)
    h[620:640, 590:600] = -32768  # left (large)
    path = tmp / "S35E149.hgt"
    h.tofile(path)
    lat1, lon0 = -34.0, 149.0
    area = (lon0 + 560 / 1200, lat1 - 680 / 1200, lon0 + 650 / 1200, lat1 - 570 / 1200)
    return path, area


KINDS = {"geographic": _geographic_with_margin, "projected": _projected, "hgt": _hgt}


def _outposts(path, lonlat):
    path.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": f"P{k}", "height_m": 8.0},
         "geometry": {"type": "Point", "coordinates": [lon, lat]}}
        for k, (lon, lat) in enumerate(lonlat)]}))
    return path


def _hidden_launch(dem, outposts, area, pick):
    """A launch point on a flyable cell (the library's own exposure surface), or
    None when there is none: most random points of a small hilly tile are seen."""
    from common.errors import InputError
    from planner.exposure import compute_exposure, load_outposts
    from planner.terrain import load_dem

    terrain = load_dem([dem], area=area)
    try:
        surface = compute_exposure(terrain, load_outposts(outposts, terrain))
    except InputError:  # e.g. an outpost on a void: gcs plan must say so itself
        return None
    cells = np.argwhere(surface.regions > 0)
    if not len(cells):
        return None
    r, c = cells[int(pick * (len(cells) - 1))]
    lon, lat = terrain.to_lonlat(*terrain.xy(r, c))
    return float(lat), float(lon)


@settings(max_examples=16, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(sorted(KINDS)), seed=st.integers(0, 1000),
       method=st.sampled_from(METHODS), k=st.integers(0, 2),
       launch=st.sampled_from(["none", "hidden", "centre"]), pick=st.floats(0, 1),
       posts=st.lists(st.tuples(st.floats(0.15, 0.85), st.floats(0.15, 0.85)),
                      min_size=1, max_size=3))
def test_plans_or_refuses_in_the_users_terms(tmp_path_factory, capsys, kind, seed, method, k,
                                             launch, pick, posts):
    tmp = tmp_path_factory.mktemp(kind)
    dem, (w, s, e, n) = KINDS[kind](tmp, seed)
    outposts = _outposts(tmp / "posts.geojson",
                         [(w + fx * (e - w), s + fy * (n - s)) for fx, fy in posts])
    argv = ["plan", "--dem", str(dem), "--outposts", str(outposts), "--uavs", "3",
            "--k", str(k), "--method", method, "--sensor-range", "700",
            "--viewpoint-spacing", "200", "-o", str(tmp / "out")]
    area = (s, w, n, e) if kind == "hgt" else None
    if area:
        argv += ["--area", ",".join(map(str, area))]
    at = {"none": None, "centre": ((s + n) / 2, (w + e) / 2),
          "hidden": _hidden_launch(dem, outposts, area, pick)}[launch]
    if at is not None:
        argv += ["--launch", f"{at[0]:.7f},{at[1]:.7f}"]
    status = main(argv)
    err = capsys.readouterr().err
    event(f"{kind}: {'planned' if status == 0 else err.strip().splitlines()[-1].split(': ')[2]}")
    if status != 0:
        lines = err.strip().splitlines()
        assert status == 2 and USER_SOURCES.match(lines[-1]), err
        assert not INTERNAL.search(lines[-1].split(": ", 2)[-1]), lines[-1]
        assert not (tmp / "out" / "plan.json").exists()
        return
    assert main(["export", str(tmp / "out"), "-o", str(tmp / "again")]) == 0, \
        capsys.readouterr().err
