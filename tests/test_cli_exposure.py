"""`gcs exposure`: the GeoTIFF it writes, read back with rasterio, and its bad-input exits."""

import json

import numpy as np
import pytest
import rasterio

from gcs.cli import main
from planner.exposure import ExposureParams, compute_exposure, load_outposts, sample_outposts
from planner.terrain import load_dem, sample_terrain, synthetic_terrain, write_grid


def read_tif(path):
    with rasterio.open(path) as ds:
        return ds.read(1), ds.profile, ds.transform


@pytest.fixture(scope="module")
def sample_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("sample") / "exposure.tif"
    assert main(["exposure", "--sample", "-o", str(out)]) == 0
    return out


def test_sample_writes_the_exposure_surface_as_float32_geotiff(sample_run, capsys):
    data, profile, transform = read_tif(sample_run)
    terrain = sample_terrain()
    surface = compute_exposure(terrain, sample_outposts(terrain), ExposureParams())
    assert profile["dtype"] == "float32" and profile["crs"].to_epsg() == 32616
    assert transform.almost_equals(terrain.transform) and data.shape == terrain.shape
    np.testing.assert_array_equal(data, surface.exposure.astype(np.float32))
    flyable = np.isfinite(data)
    assert flyable.any() and not flyable.all()
    np.testing.assert_array_equal(flyable, surface.flyable)
    p = ExposureParams()
    h = terrain.height[flyable]
    assert (data[flyable] - p.hide_margin_m >= h + p.clearance_m - 1e-3).all()
    assert (data[flyable] <= h + p.ceiling_agl_m + 1e-3).all()


def test_dem_and_outposts_files_with_options(tmp_path, capsys):
    terrain = synthetic_terrain(96, 96, 30.0, seed=3, family="ridges")
    dem = tmp_path / "dem.tif"
    write_grid(dem, terrain.height.astype(np.float32), terrain)
    lon, lat = terrain.to_lonlat(*terrain.xy(np.array([20, 70]), np.array([30, 60])))
    posts = tmp_path / "posts.geojson"
    posts.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": "a", "height_m": 5, "range_m": 2000},
         "geometry": {"type": "Point", "coordinates": [lon[0], lat[0]]}},
        {"type": "Feature", "properties": {"name": "b"},
         "geometry": {"type": "Point", "coordinates": [lon[1], lat[1]]}}]}))
    out = tmp_path / "sub" / "e.tif"
    argv = ["exposure", "--dem", str(dem), "--outposts", str(posts), "--resolution", "45",
            "--ceiling-agl", "100", "--clearance", "20", "--hide-margin", "5",
            "--curvature-coeff", "0", "-o", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr()
    assert "flyable" in printed.out and "km2" in printed.out and "regions" in printed.out
    # post b has no height_m: the default eye height is said, on one line
    assert [line for line in printed.err.splitlines() if "warning" in line] == [
        f"gcs exposure: warning: {posts}: feature 1 (b): no height_m: eye 2 m above ground "
        "assumed"]
    loaded = load_dem([dem], resolution=45)
    params = ExposureParams(ceiling_agl_m=100, clearance_m=20, hide_margin_m=5,
                            curvature_coeff=0)
    with pytest.warns(UserWarning, match=r"feature 1 \(b\): no height_m"):
        expected = compute_exposure(loaded, load_outposts(posts, loaded), params).exposure
    data, profile, transform = read_tif(out)
    assert transform.almost_equals(loaded.transform) and transform.a == 45
    np.testing.assert_array_equal(data, expected.astype(np.float32))


def _bad_cases(tmp_path):
    terrain = synthetic_terrain(32, 32, 30.0, seed=1)
    dem = tmp_path / "dem.tif"
    write_grid(dem, terrain.height.astype(np.float32), terrain)
    far = tmp_path / "far.geojson"
    far.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": "far"},
         "geometry": {"type": "Point", "coordinates": [10.0, 50.0]}}]}))
    ok = ["--dem", str(dem), "--outposts", str(far)]
    return [
        (["--dem", str(tmp_path / "missing.tif"), "--outposts", str(far)], "no such file"),
        (ok, "far.geojson: feature 0 (far)"),
        (["--dem", str(dem)], "--outposts"),
        (["--sample", "--dem", str(dem)], "not both"),
        ([], "no DEM given"),
        (["--sample", "--clearance", "-1"], "--clearance: must not be negative"),
        (["--sample", "--resolution", "0"], "--resolution: must be a positive number"),
        ([*ok, "--area", "north"], "--area"),
        ([*ok, "--area", "1,2,3,4"], "does not overlap"),
    ]


def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys):
    for i, (args, message) in enumerate(_bad_cases(tmp_path)):
        out = tmp_path / f"out{i}.tif"
        assert main(["exposure", *args, "-o", str(out)]) == 2, args
        err = capsys.readouterr().err.strip().splitlines()[-1]  # after the stage lines
        assert err.startswith("gcs exposure: error: "), err
        assert message in err, err
        assert not out.exists()
    leftovers = [p.name for p in tmp_path.iterdir() if p.suffix == ".tmp" or "out" in p.name]
    assert leftovers == []


def test_bad_input_leaves_an_existing_output_untouched(tmp_path, capsys):
    out = tmp_path / "e.tif"
    out.write_bytes(b"previous")
    assert main(["exposure", "--sample", "--hide-margin", "-2", "-o", str(out)]) == 2
    assert out.read_bytes() == b"previous"
