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
                          r"--[a-z-]+|plan): ")
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


# --- heights in feet -----------------------------------------------------------------------------
#: metres per foot, by definition (not the code's table)
FOOT, US_FOOT = 0.3048, 1200 / 3937
#: (what says the unit: CRS, band unit; metres per unit): EPSG 8050 is MSL height (ft),
#: 6360 NAVD88 height (ftUS)
FEET = {"band unit ft": ("EPSG:32633", "ft", FOOT),
        "compound CRS ft": ("EPSG:32633+8050", None, FOOT),
        "compound CRS ftUS": ("EPSG:32633+6360", None, US_FOOT)}
#: the spot of the issue's DEM (UTM 33N), where the feet DEM's home was 1.6 km too high
HOME = (46.133187, 14.392527)


def _utm33(path, heights_m, crs="EPSG:32633", unit=None, per_unit=1.0):
    from pyproj import Transformer
    x, y = Transformer.from_crs("EPSG:4326", "EPSG:32633", always_xy=True).transform(
        HOME[1], HOME[0])
    n = heights_m.shape[0]
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="float64",
                       crs=crs, transform=Affine(30, 0, round(x) - n * 15, 0, -30,
                                                 round(y) + n * 15)) as ds:
        ds.write(heights_m / per_unit, 1)
        if unit:
            ds.units = (unit,)
    return path


def _plan_home(capsys, dem, out, *extra):
    """(exit status, stdout, stderr, the plan's home altitude, plan.json) of a one-UAV plan
    from HOME."""
    status = main(["plan", "--dem", str(dem), "--no-outposts", "--uavs", "1", "--launch",
                   f"{HOME[0]},{HOME[1]}", "--sensor-range", "500", "--viewpoint-spacing",
                   "250", "-o", str(out), *extra])
    text = capsys.readouterr()
    if status:
        return status, text.out, text.err, None, None
    home = json.loads((out / "vehicle-1.plan").read_text())["mission"]["plannedHomePosition"]
    return status, text.out, text.err, home[2], json.loads((out / "plan.json").read_text())


@pytest.fixture(scope="module")
def metric_home(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("metric")
    heights = _terrain(5, 50, 50, 30.0)
    heights += 745.0 - np.nanmean(heights)
    status = main(["plan", "--dem", str(_utm33(tmp / "m.tif", heights)), "--no-outposts",
                   "--uavs", "1", "--launch", f"{HOME[0]},{HOME[1]}", "--sensor-range", "500",
                   "--viewpoint-spacing", "250", "-o", str(tmp / "out")])
    assert status == 0
    plan = json.loads((tmp / "out" / "vehicle-1.plan").read_text())
    return heights, plan["mission"]["plannedHomePosition"][2]


@pytest.mark.parametrize("kind", sorted(FEET))
def test_a_plan_on_a_dem_in_feet_is_the_plan_on_metres_and_says_so(tmp_path, capsys,
                                                                    metric_home, kind):
    heights, home_m = metric_home
    crs, unit, per_unit = FEET[kind]
    dem = _utm33(tmp_path / "feet.tif", heights, crs, unit, per_unit)
    status, out, err, home, plan = _plan_home(capsys, dem, tmp_path / "out")
    assert status == 0, err
    assert abs(home - home_m) < 1e-3  # was about 1.6 km higher, the feet taken as metres
    words = "US survey feet" if per_unit == US_FOOT else "feet"
    said = [line for line in err.splitlines() if "warning" in line]
    assert len(said) == 1 and said[0].startswith(f"gcs plan: warning: {dem}: heights taken as "
                                                 f"{words} (") \
        and said[0].endswith(f") and converted to metres (x {per_unit:.10g})"), err
    assert f"DEM heights of {dem} taken as {words}" in err  # the summary (on stderr too)
    assert plan["metrics"]["z_units"][0]["unit"] == ("us-ft" if per_unit == US_FOOT else "ft")
    assert plan["params"]["z_unit"] is None


def test_z_unit_overrides_the_files_unit_and_the_plan_keeps_it(tmp_path, capsys, metric_home):
    heights, home_m = metric_home
    unlabelled = _utm33(tmp_path / "unlabelled.tif", heights, per_unit=FOOT)
    status, out, err, home, plan = _plan_home(capsys, unlabelled, tmp_path / "out",
                                              "--z-unit", "ft")
    assert status == 0, err
    assert abs(home - home_m) < 1e-3
    assert plan["params"]["z_unit"] == "ft"
    assert "heights taken as feet (--z-unit ft) and converted to metres" in err


@pytest.mark.parametrize("unit", ["furlong", "degC"])
def test_a_dem_in_an_unknown_unit_is_refused_in_one_line(tmp_path, capsys, unit):
    dem = _utm33(tmp_path / "odd.tif", np.full((20, 20), 300.0), unit=unit)
    status, out, err, _, _ = _plan_home(capsys, dem, tmp_path / "out")
    lines = err.strip().splitlines()  # the stages begun, then one error line
    assert status == 2 and [line for line in lines if "error" in line] == lines[-1:]
    assert lines[-1] == (
        f"gcs plan: error: {dem}: heights in an unknown unit: band unit {unit!r} is not "
        "metres, feet or US survey feet (give --z-unit m, ft or us-ft if they are one of "
        "these)")
    assert not (tmp_path / "out").exists()
