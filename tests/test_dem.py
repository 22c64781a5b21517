"""planner.terrain.dem, planner.terrain.synthetic and planner.terrain.geotiff against analytic surfaces,
rasterio-written files and the matplotlib sample."""

import warnings

import numpy as np
import pytest
import rasterio
from affine import Affine
from hypothesis import given, settings
from hypothesis import strategies as st
from pyproj import Transformer

from common.errors import InputError
from planner.terrain import FAMILIES, read_terrain, synthetic_terrain, write_grid
from planner.terrain.dem import (
    MAX_FILLED_VOID_CELLS,
    VOID_FILL_MARGIN_M,
    load_dem,
    sample_terrain,
    utm_crs,
)

N = 1201  # samples per side of a 3" SRTM tile
D = 1.0 / (N - 1)


def plane(lon, lat):
    """Exactly an integer at every SRTM sample of the N36-N37 W085 tiles."""
    return 100.0 + 3.0 * (lon + 85.0) * 1200 + 2.0 * (38.0 - lat) * 1200


def write_hgt(folder, name, lat0, lon0, func=plane, n=N, voids=()):
    """An SRTM tile: sample (j, i) at lon0 + i/(n-1), lat0 + 1 - j/(n-1)."""
    j, i = np.mgrid[0:n, 0:n]
    h = np.round(func(lon0 + i / (n - 1), lat0 + 1 - j / (n - 1))).astype(">i2")
    for rows, cols in voids:
        h[rows, cols] = -32768
    path = folder / name
    h.tofile(path)
    return path


def heights_at(terrain, lon, lat):
    return terrain.ground(*terrain.from_lonlat(lon, lat))


def assert_bracketed(terrain, lon, lat, truth, band):
    """The terrain's lower and upper surfaces bracket ``truth`` at (lon, lat), at most
    ``band`` metres apart there."""
    x, y = terrain.from_lonlat(lon, lat)
    lower, upper = terrain.ground(x, y), terrain.ground(x, y, upper=True)
    assert np.isfinite(lower).all() and np.isfinite(upper).all()
    assert (lower <= truth + 1e-9).all() and (truth <= upper + 1e-9).all()
    assert (upper - lower).max() <= band


def smooth(lon, lat):
    """A gentle analytic surface in lon/lat, metres."""
    return 400 + 150 * np.sin(40 * (lon + 84.3)) * np.cos(30 * (lat - 36.5))


def write_tif(path, crs, transform, data, nodata=None, dtype="float32"):
    with rasterio.open(path, "w", driver="GTiff", width=data.shape[1], height=data.shape[0],
                       count=1, dtype=dtype, crs=crs, transform=transform,
                       nodata=nodata) as ds:
        ds.write(data.astype(dtype), 1)
    return path


def smooth_tif(path, crs, cell, bounds=(-84.45, 36.35, -84.15, 36.65)):
    """``smooth`` sampled at the pixel centres of a north-up grid in ``crs``."""
    west, south, east, north = rasterio.warp.transform_bounds("EPSG:4326", crs, *bounds)
    cols, rows = int((east - west) / cell), int((north - south) / cell)
    transform = Affine(cell, 0, west, 0, -cell, north)
    c, r = np.meshgrid(np.arange(cols) + 0.5, np.arange(rows) + 0.5)
    x, y = transform @ (c, r)
    lon, lat = Transformer.from_crs(crs, "EPSG:4326", always_xy=True).transform(x, y)
    return write_tif(path, crs, transform, smooth(lon, lat), dtype="float64")


# --- SRTM .hgt -------------------------------------------------------------------------------


def test_hgt_reproduces_known_heights_at_known_lonlat(tmp_path):
    path = write_hgt(tmp_path, "N36W085.hgt", 36, -85)
    terrain = load_dem([path], area=(36.3, -84.8, 36.6, -84.5))
    assert terrain.crs == "EPSG:32616"  # lon -84.65 is in UTM zone 16
    rng = np.random.default_rng(1)
    lon, lat = rng.uniform(-84.8, -84.5, 500), rng.uniform(36.3, 36.6, 500)
    # A plane in lon/lat stays (almost exactly) one under the exact warp and bilinear:
    # the two surfaces bracket it within millimetres.
    assert_bracketed(terrain, lon, lat, plane(lon, lat), band=0.01)
    # Pixel-is-point: the tile's first sample is exactly at (lon0, lat0 + 1).
    assert plane(-85.0, 37.0) == np.fromfile(path, ">i2")[0]


@pytest.mark.parametrize("name, n, lat0, lon0, crs", [
    ("N36W085.hgt", 3601, 36, -85, "EPSG:32616"),  # 1 arc-second tile
    ("S34E151.hgt", 1201, -34, 151, "EPSG:32756"),  # southern, eastern hemisphere
])
def test_hgt_sizes_and_hemispheres(tmp_path, name, n, lat0, lon0, crs):
    def func(lon, lat):
        return 50 + 10 * (n - 1) * (lon - lon0) + 7 * (n - 1) * (lat0 + 1 - lat)

    path = write_hgt(tmp_path, name, lat0, lon0, func=func, n=n)
    area = (lat0 + 0.40, lon0 + 0.40, lat0 + 0.42, lon0 + 0.42)
    terrain = load_dem([path], area=area)
    assert terrain.crs == crs
    lon = np.linspace(area[1], area[3], 50)
    lat = np.linspace(area[0], area[2], 50)
    np.testing.assert_allclose(heights_at(terrain, lon, lat), func(lon, lat), atol=1e-3)


def test_hgt_default_resolution_is_the_mean_spacing_in_metres(tmp_path):
    path = write_hgt(tmp_path, "N36W085.hgt", 36, -85)
    terrain = load_dem([path], area=(36.4, -84.6, 36.5, -84.5))
    dx = np.radians(D) * 6378137 * np.cos(np.radians(36.45))
    dy = np.radians(D) * 6367000  # meridian arc length per radian near 36 deg
    assert terrain.cell_size == pytest.approx((dx + dy) / 2, rel=0.01)
    t = terrain.transform
    assert t.a == -t.e and t.b == 0 and t.d == 0  # square, north up


def test_adjacent_hgt_tiles_mosaic_seamlessly(tmp_path):
    south = write_hgt(tmp_path, "N36W085.hgt", 36, -85)
    north = write_hgt(tmp_path, "N37W085.hgt", 37, -85)
    terrain = load_dem([north, south], area=(36.95, -84.6, 37.05, -84.5))
    assert not np.isnan(terrain.height).any()
    lat = np.linspace(36.96, 37.04, 801)  # across the shared row at 37 N
    lon = np.full_like(lat, -84.55)
    np.testing.assert_allclose(heights_at(terrain, lon, lat), plane(lon, lat), atol=1e-3)


def test_area_crop_is_the_areas_utm_bounding_box(tmp_path):
    path = write_hgt(tmp_path, "N36W085.hgt", 36, -85)
    area = (36.2, -84.7, 36.3, -84.6)
    terrain = load_dem([path], area=area)
    s, w, n, e = area
    edge = np.linspace(0, 1, 50)
    lon = np.r_[w + (e - w) * edge, np.full(50, e), e - (e - w) * edge, np.full(50, w)]
    lat = np.r_[np.full(50, s), s + (n - s) * edge, np.full(50, n), n - (n - s) * edge]
    x, y = terrain.from_lonlat(lon, lat)
    rows, cols = terrain.shape
    cell = terrain.cell_size
    # Cell centres cover the area's bounding box in UTM, with at most one cell to spare.
    xc, yc = terrain.xy(np.array([0, rows - 1]), np.array([0, cols - 1]))
    assert x.min() - cell <= xc[0] <= x.min() and x.max() <= xc[1] <= x.max() + cell
    assert y.max() <= yc[0] <= y.max() + cell and y.min() - cell <= yc[1] <= y.min()
    inner_lon, inner_lat = np.meshgrid(np.linspace(w, e, 20), np.linspace(s, n, 20))
    assert np.isfinite(heights_at(terrain, inner_lon.ravel(), inner_lat.ravel())).all()
    assert terrain.height.size < 0.02 * N * N


def test_small_voids_filled_with_warning_large_voids_stay_nan(tmp_path):
    small = (slice(500, 503), slice(600, 604))  # 12 cells
    large = (slice(700, 720), slice(300, 320))  # 400 cells > MAX_FILLED_VOID_CELLS
    assert 12 <= MAX_FILLED_VOID_CELLS < 400
    path = write_hgt(tmp_path, "N36W085.hgt", 36, -85, voids=[small, large])
    with pytest.warns(UserWarning, match=r"filled 1 small void\(s\) \(12 source cells\) by "
                                         r"interpolation at 36\.58\d+,-84\.49\d+ \(12 cells\)"
                                         r".*raised by 20 m; 1 larger"):
        terrain = load_dem([path])
    assert terrain.meta["filled_voids"] == 1 and terrain.meta["unfilled_voids"] == 1
    # Harmonic filling reproduces a plane exactly; the surfaces stand the void margin off it
    lon_s, lat_s = -85 + 601.5 * D, 37 - 501 * D
    assert_bracketed(terrain, np.array([lon_s]), np.array([lat_s]),
                     plane(lon_s, lat_s), band=2 * VOID_FILL_MARGIN_M + 0.01)
    x, y = terrain.from_lonlat(lon_s, lat_s)
    assert terrain.ground(x, y)[0] <= plane(lon_s, lat_s) - VOID_FILL_MARGIN_M + 0.01
    assert terrain.ground(x, y, upper=True)[0] >= plane(lon_s, lat_s) + VOID_FILL_MARGIN_M - 0.01
    place = terrain.meta["filled_at"][0]
    assert place["cells"] == 12
    assert abs(place["lat"] - (37 - 502 * D)) < D and abs(place["lon"] - (-85 + 602 * D)) < D
    # the margin reaches the working cells around the void and no further
    mask = terrain.meta["filled_mask"]
    rows, cols = np.nonzero(mask)
    assert mask.sum() < 200
    far = terrain.xy(rows.max() + 3, cols.max() + 3)
    lon_f, lat_f = terrain.to_lonlat(*far)
    assert_bracketed(terrain, np.array([lon_f]), np.array([lat_f]), plane(lon_f, lat_f),
                     band=0.01)
    lon_l, lat_l = -85 + 310 * D, 37 - 710 * D
    assert np.isnan(heights_at(terrain, lon_l, lat_l)[0])


def test_no_warning_without_voids(tmp_path):
    path = write_hgt(tmp_path, "N36W085.hgt", 36, -85)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        terrain = load_dem([path], area=(36.4, -84.6, 36.5, -84.5))
    assert terrain.meta["filled_voids"] == 0


# --- GeoTIFF in any CRS ------------------------------------------------------------------------


def test_geographic_and_projected_geotiffs_give_the_same_heights(tmp_path):
    geo = smooth_tif(tmp_path / "geo.tif", "EPSG:4326", 1 / 1200)
    merc = smooth_tif(tmp_path / "merc.tif", "EPSG:3857", 80.0)
    a = load_dem([geo], resolution=60)
    b = load_dem([merc], resolution=60)
    assert a.crs == b.crs == "EPSG:32616" and a.cell_size == b.cell_size == 60
    rng = np.random.default_rng(2)
    lon, lat = rng.uniform(-84.42, -84.18, 400), rng.uniform(36.38, 36.62, 400)
    ha, hb = heights_at(a, lon, lat), heights_at(b, lon, lat)
    # Interpolation error of a 150 m sine with ~7 km wavelength on ~100 m cells.
    np.testing.assert_allclose(ha, smooth(lon, lat), atol=1.0)
    np.testing.assert_allclose(hb, smooth(lon, lat), atol=1.0)
    np.testing.assert_allclose(ha, hb, atol=1.5)


def test_tiles_in_different_crs_mosaic(tmp_path):
    west = smooth_tif(tmp_path / "w.tif", "EPSG:4326", 1 / 1200, (-84.45, 36.35, -84.29, 36.65))
    east = smooth_tif(tmp_path / "e.tif", "EPSG:3857", 80.0, (-84.31, 36.35, -84.15, 36.65))
    terrain = load_dem([west, east], resolution=60)
    lon, lat = np.meshgrid(np.linspace(-84.43, -84.17, 30), np.linspace(36.37, 36.63, 30))
    np.testing.assert_allclose(heights_at(terrain, lon.ravel(), lat.ravel()),
                               smooth(lon, lat).ravel(), atol=1.0)


def test_geotiff_nodata_is_void(tmp_path):
    data = np.full((200, 200), 500.0)
    data[50:52, 60:62] = -9999
    data[120:140, 120:140] = -9999
    path = write_tif(tmp_path / "nd.tif", "EPSG:32616", Affine(30, 0, 700000, 0, -30, 4050000),
                     data, nodata=-9999)
    with pytest.warns(UserWarning, match="filled 1 small void"):
        terrain = load_dem([path])
    assert terrain.cell_size == pytest.approx(30)
    filled = terrain.meta["filled_mask"]
    assert filled.any() and not filled.all()
    assert np.nanmax(np.abs(terrain.height[~filled] - 500)) < 1e-9
    np.testing.assert_allclose(terrain.height[filled], 500 - VOID_FILL_MARGIN_M)
    np.testing.assert_allclose(terrain.upper[filled], 500 + VOID_FILL_MARGIN_M)
    assert np.isnan(terrain.ground(700000 + 130 * 30, 4050000 - 130 * 30)[0])


def test_ellipsoidal_heights_need_and_use_the_geoid_offset(tmp_path):
    data = np.full((100, 100), 470.0)
    t = Affine(1 / 1200, 0, -84.3, 0, -1 / 1200, 36.6)
    ell = write_tif(tmp_path / "ell.tif", "EPSG:4979", t, data)
    with pytest.raises(InputError, match="ell.tif: heights are ellipsoidal"):
        load_dem([ell])
    # N = ellipsoid - geoid height (about -31 m here): AMSL = h - N
    terrain = load_dem([ell], geoid_offset=-31.0)
    assert np.nanmean(terrain.height) == pytest.approx(501.0, abs=0.01)
    ortho = write_tif(tmp_path / "ortho.tif", "EPSG:4326+5773", t, data)  # EGM96 heights
    with pytest.warns(UserWarning, match="already AMSL"):
        assert np.nanmean(load_dem([ortho], geoid_offset=-31.0).height) == \
            pytest.approx(470.0, abs=0.01)


# --- vertical units ----------------------------------------------------------------------------
#: metres per unit, from their definitions (not the code's table): the international
#: foot (1959) and the US survey foot (1200/3937 m, EPSG:9003)
FOOT, US_FOOT = 0.3048, 1200 / 3937
#: how a file may say its heights are in feet: (horizontal + vertical CRS, band unit,
#: metres per unit); the CRS codes are EPSG's MSL height (ft) 8050 and NAVD88
#: height (ftUS) 6360. GDAL reports a vertical CRS's unit as the band unit too.
FEET_FILES = {
    "band unit ft": ("EPSG:32616", "ft", FOOT),
    "band unit US survey foot": ("EPSG:32616", "US survey foot", US_FOOT),
    "compound CRS ft": ("EPSG:32616+8050", None, FOOT),
    "compound CRS ftUS": ("EPSG:32616+6360", None, US_FOOT),
    "geographic + ftUS": ("EPSG:4326+6360", None, US_FOOT),
}


def unit_tif(path, crs, heights_m, unit=None, per_unit=1.0, scale=1.0, offset=0.0):
    """``heights_m`` (metres, on a 30 m UTM 16N lattice or a 1" geographic one) written
    in a unit of ``per_unit`` metres, as ``raw * scale + offset``."""
    geographic = crs.startswith("EPSG:4326")
    t = Affine(1 / 3600, 0, -84.4, 0, -1 / 3600, 36.6) if geographic else \
        Affine(30, 0, 750000, 0, -30, 4050000)
    path = write_tif(path, crs, t, (heights_m / per_unit - offset) / scale, dtype="float64")
    if unit or (scale, offset) != (1.0, 0.0):
        with rasterio.open(path, "r+") as ds:
            ds.units = (unit,) if unit else ds.units
            ds.scales, ds.offsets = (scale,), (offset,)
    return path


@settings(max_examples=25, deadline=None)
@given(kind=st.sampled_from(sorted(FEET_FILES)), seed=st.integers(0, 2**16),
       base=st.floats(-400, 8000), relief=st.floats(0, 1500))
def test_a_dem_in_feet_gives_the_heights_of_the_same_dem_in_metres(tmp_path_factory, kind,
                                                                   seed, base, relief):
    tmp = tmp_path_factory.mktemp("feet")
    heights = base + relief * np.random.default_rng(seed).random((40, 50))
    crs, unit, per_unit = FEET_FILES[kind]
    metric = load_dem([unit_tif(tmp / "m.tif", crs.split("+")[0], heights)], resolution=30)
    feet = unit_tif(tmp / "ft.tif", crs, heights, unit, per_unit)
    with pytest.warns(UserWarning) as said:
        terrain = load_dem([feet], resolution=30)
    np.testing.assert_allclose(terrain.height, metric.height, atol=1e-3, equal_nan=True)
    np.testing.assert_allclose(terrain.upper, metric.upper, atol=1e-3, equal_nan=True)
    words = "US survey feet" if per_unit == US_FOOT else "feet"
    assert [str(w.message) for w in said] == [
        f"{feet}: heights taken as {words} ({terrain.meta['z_units'][0]['said_by']}) and "
        f"converted to metres (x {per_unit:.10g})"]
    assert terrain.meta["z_units"][0]["metres_per_unit"] == per_unit


def test_metres_said_or_unsaid_are_taken_silently(tmp_path):
    heights = np.full((20, 20), 812.5)
    files = [unit_tif(tmp_path / "plain.tif", "EPSG:32616", heights),
             unit_tif(tmp_path / "m.tif", "EPSG:32616", heights, "m"),
             unit_tif(tmp_path / "metre.tif", "EPSG:32616", heights, "metre"),
             unit_tif(tmp_path / "egm96.tif", "EPSG:32616+5773", heights)]
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        for path in files:
            assert np.nanmax(np.abs(load_dem([path]).height - 812.5)) < 1e-9, path


def test_the_bands_scale_and_offset_are_applied_before_the_unit(tmp_path):
    heights = 700 + 50 * np.random.default_rng(4).random((20, 20))
    path = unit_tif(tmp_path / "dft.tif", "EPSG:32616", heights, "ft", FOOT, scale=0.1,
                    offset=1000.0)
    with pytest.warns(UserWarning, match="heights taken as feet"):
        np.testing.assert_allclose(load_dem([path]).height, heights, atol=1e-6)


def test_z_unit_overrides_what_the_file_says(tmp_path):
    heights = np.full((20, 20), 640.0)
    mislabelled = unit_tif(tmp_path / "mislabelled.tif", "EPSG:32616", heights, "ft")
    with pytest.warns(UserWarning, match=r"mislabelled.tif: heights taken as metres \(--z-unit "
                                         r"m\), although the file says otherwise \(band unit "
                                         r"'ft'\)"):
        assert np.nanmax(np.abs(load_dem([mislabelled], z_unit="m").height - 640)) < 1e-9
    unsaid = unit_tif(tmp_path / "unsaid.tif", "EPSG:32616", heights, per_unit=US_FOOT)
    with pytest.warns(UserWarning, match=r"unsaid.tif: heights taken as US survey feet "
                                         r"\(--z-unit us-ft\) and converted"):
        terrain = load_dem([unsaid], z_unit="us-ft")
    assert np.nanmax(np.abs(terrain.height - 640)) < 1e-9
    odd = unit_tif(tmp_path / "odd.tif", "EPSG:32616", heights, "furlong", FOOT)
    with pytest.warns(UserWarning, match="although the file says otherwise"):
        assert np.nanmax(np.abs(load_dem([odd], z_unit="ft").height - 640)) < 1e-9
    hgt = write_hgt(tmp_path, "N36W085.hgt", 36, -85)  # SRTM: metres, unless overridden
    area = (36.40, -84.60, 36.41, -84.59)
    with pytest.warns(UserWarning, match="N36W085.hgt: heights taken as feet"):
        np.testing.assert_allclose(load_dem([hgt], area=area, z_unit="ft").height,
                                   load_dem([hgt], area=area).height * FOOT, rtol=1e-6)


@pytest.mark.parametrize("crs, unit, problem", [
    ("EPSG:32616", "furlong", "heights in an unknown unit: band unit 'furlong' is not metres, "
                              "feet or US survey feet (give --z-unit m, ft or us-ft"),
    ("EPSG:32616", "degC", "band unit 'degC' is not metres"),
    ("EPSG:32616+8050", "m", "band unit 'm' but vertical CRS 'MSL height (ft)' in foot: which "
                             "unit are the heights in? Give --z-unit"),
    ("EPSG:32616+6358", None, "vertical axis (NAVD88 depth (ftUS)) is a depth"),
])
def test_an_unknown_or_contradicted_unit_is_refused(tmp_path, crs, unit, problem):
    path = unit_tif(tmp_path / "z.tif", crs, np.full((10, 10), 300.0), unit)
    with pytest.raises(InputError) as err:
        load_dem([path])
    assert str(err.value).startswith(f"{path}: ") and problem in str(err.value), str(err.value)
    assert "\n" not in str(err.value)


# --- bad input ---------------------------------------------------------------------------------


def _bad_files(tmp_path):
    t = Affine(1 / 1200, 0, -84.3, 0, -1 / 1200, 36.6)
    text = tmp_path / "notes.tif"
    text.write_text("not a raster")
    nocrs = tmp_path / "nocrs.tif"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        with rasterio.open(nocrs, "w", driver="GTiff", width=10, height=10, count=1,
                           dtype="float32") as ds:
            ds.write(np.ones((1, 10, 10), "float32"))
    nodata = write_tif(tmp_path / "allnodata.tif", "EPSG:4326", t, np.full((10, 10), -9999.0),
                       nodata=-9999)
    short = tmp_path / "N36W085.hgt"
    np.zeros(1000, ">i2").tofile(short)
    badname = tmp_path / "tile.hgt"
    np.zeros(N * N, ">i2").tofile(badname)
    allvoid = tmp_path / "N35W085.hgt"
    np.full(N * N, -32768, ">i2").tofile(allvoid)
    return [
        (tmp_path / "missing.tif", {}, "no such file"),
        (tmp_path, {}, "folder"),
        (text, {}, "not a raster"),
        (nocrs, {}, "no CRS"),
        (nodata, {}, "nodata"),
        (short, {}, "unknown .hgt size"),
        (badname, {}, "south-west corner"),
        (allvoid, {}, "nodata"),
        (write_tif(tmp_path / "ok.tif", "EPSG:4326", t, np.ones((10, 10))),
         {"area": (10, 10, 11, 11)}, "does not overlap"),
    ]


def test_bad_inputs_raise_input_error_naming_the_file(tmp_path):
    for path, kwargs, problem in _bad_files(tmp_path):
        with pytest.raises(InputError) as err:
            load_dem([path], **kwargs)
        assert str(path) in str(err.value) and problem in str(err.value), str(err.value)


def test_bad_area_and_resolution(tmp_path):
    path = write_hgt(tmp_path, "N36W085.hgt", 36, -85)
    with pytest.raises(InputError, match="--area"):
        load_dem([path], area=(36.5, -84, 36.4, -85))
    with pytest.raises(InputError, match="--resolution"):
        load_dem([path], area=(36.4, -84.6, 36.5, -84.5), resolution=-5)


# --- the matplotlib sample ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def sample():
    return sample_terrain()


def test_sample_is_north_up_pine_mountain_strikes_ne(sample):
    """Pine Mountain (the long ridge leaving the Jacksboro fault line to the NE)
    strikes about N50E like the whole Appalachian fold belt; read upside down it
    would strike N130E. Its strike is the principal axis of the gradient
    structure tensor over the ridge, measured on the loaded (north-up) grid."""
    rows, cols = np.mgrid[0:sample.shape[0], 0:sample.shape[1]]
    lon, lat = sample.to_lonlat(*sample.xy(rows, cols))
    box = (lat > 36.62) & (lat < 36.70) & (lon > -84.20) & (lon < -84.11)
    gy, gx = np.gradient(sample.height)
    gy = -gy  # rows grow southwards
    tensor = [[np.nanmean((gx * gx)[box]), np.nanmean((gx * gy)[box])],
              [np.nanmean((gx * gy)[box]), np.nanmean((gy * gy)[box])]]
    _, vectors = np.linalg.eigh(tensor)
    east, north = vectors[:, 1]  # steepest direction, across the ridge
    strike = (np.degrees(np.arctan2(east, north)) + 90) % 180
    assert 35 < strike < 65


def test_sample_brackets_the_npz_interpolated_at_each_cell_centre(sample):
    """Independent reference: scipy's bilinear interpolation of the npz in lon/lat,
    with the geographic transform worked out from the npz keys. The working grid
    is resampled, so its lower and upper surfaces bracket the reference."""
    from matplotlib import cbook
    from scipy.interpolate import RegularGridInterpolator

    with cbook.get_sample_data("jacksboro_fault_dem.npz") as dem:
        z = dem["elevation"].astype(float)
        west, north, d = float(dem["xmin"]), float(dem["ymin"]), float(dem["dx"])
    assert north > float(36.7)  # the key named ymin holds the northern edge
    lats = north - (np.arange(z.shape[0]) + 0.5) * d  # row 0 north
    lons = west + (np.arange(z.shape[1]) + 0.5) * d
    ref = RegularGridInterpolator((lats[::-1], lons), z[::-1], bounds_error=False)
    rows, cols = np.nonzero(sample.valid)
    lon, lat = sample.to_lonlat(*sample.xy(rows, cols))
    expected = ref(np.c_[lat, lon])
    assert np.isfinite(expected).all()  # the working grid holds no cell outside the npz
    assert (sample.height[rows, cols] <= expected).all()
    assert (sample.upper[rows, cols] >= expected).all()
    band = sample.upper[rows, cols] - sample.height[rows, cols]
    assert np.median(band) < 10.0  # interpolation error on ~80 m cells of steep ridges
    assert sample.crs == "EPSG:32616"
    assert 80 < sample.cell_size < 87  # mean of 74 m (x) and 93 m (y) spacing
    assert 0.9 < sample.valid.mean() < 1.0  # the rotated footprint leaves NaN corners


def test_sample_resolution(sample):
    fine = sample_terrain(resolution=50)
    assert fine.cell_size == 50
    assert fine.height.size > 2.5 * sample.height.size


@settings(max_examples=40, deadline=None)
@given(row=st.floats(0, 390), col=st.floats(0, 370))
def test_grid_lonlat_grid_round_trip_within_a_tenth_of_a_metre(sample, row, col):
    x, y = sample.xy(row, col)
    lon, lat = sample.to_lonlat(x, y)
    x2, y2 = sample.from_lonlat(lon, lat)
    assert np.hypot(x2 - x, y2 - y) < 0.1
    r2, c2 = sample.rowcol(x2, y2)
    assert np.hypot(r2 - row, c2 - col) * sample.cell_size < 0.1


# --- synthetic terrain -------------------------------------------------------------------------


@pytest.mark.parametrize("family", FAMILIES)
def test_synthetic_terrain_is_seeded_and_plausible(family):
    a = synthetic_terrain(128, 160, 30.0, seed=5, family=family)
    assert a.shape == (128, 160) and a.cell_size == 30.0
    np.testing.assert_array_equal(a.height, synthetic_terrain(128, 160, 30.0, 5, family).height)
    assert not np.array_equal(a.height, synthetic_terrain(128, 160, 30.0, 6, family).height)
    gy, gx = np.gradient(a.height, 30.0)
    assert np.degrees(np.arctan(np.hypot(gx, gy).max())) < 40
    assert 100 < np.ptp(a.height) <= 400 and a.height.min() >= 299
    lon, lat = a.to_lonlat(*a.xy(64, 80))
    assert a.crs == utm_crs(-84.2, 36.6) == "EPSG:32616"
    assert abs(lon + 84.2) < 0.01 and abs(lat - 36.6) < 0.01


def test_synthetic_terrain_southern_hemisphere():
    t = synthetic_terrain(32, 32, 30.0, family="hills", lat=-33.9, lon=151.2)
    assert t.crs == "EPSG:32756"


# --- GeoTIFF output ----------------------------------------------------------------------------


def test_write_grid_and_read_terrain_round_trip(tmp_path, sample):
    path = tmp_path / "out" / "terrain.tif"
    write_grid(path, sample.height.astype(np.float32), sample)
    back = read_terrain(path)
    assert back.crs == sample.crs and back.transform.almost_equals(sample.transform)
    np.testing.assert_array_equal(np.isnan(back.height), np.isnan(sample.height))
    np.testing.assert_allclose(back.height, sample.height.astype(np.float32), equal_nan=True)
    with rasterio.open(path) as ds:
        assert ds.dtypes[0] == "float32" and ds.compression.name.lower() == "deflate"
    counts = np.arange(sample.height.size, dtype=np.int16).reshape(sample.shape)
    write_grid(tmp_path / "count.tif", counts, sample)
    with rasterio.open(tmp_path / "count.tif") as ds:
        assert ds.dtypes[0] == "int16" and ds.nodata is None
        np.testing.assert_array_equal(ds.read(1), counts)
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["count.tif", "out", "terrain.tif"]


def test_read_terrain_rejects_non_working_grids(tmp_path):
    geo = write_tif(tmp_path / "geo.tif", "EPSG:4326", Affine(0.001, 0, -84, 0, -0.001, 36),
                    np.ones((5, 5)))
    with pytest.raises(InputError, match="geo.tif: not a working-grid terrain"):
        read_terrain(geo)
    with pytest.raises(InputError, match="no such file"):
        read_terrain(tmp_path / "none.tif")


@settings(max_examples=100, deadline=None)
@given(st.integers(2, 9), st.integers(2, 9), st.lists(st.tuples(st.floats(-2.0, 11.0),
                                                               st.floats(-2.0, 11.0)),
                                                     min_size=1, max_size=20),
       st.integers(0, 3))
def test_the_ground_at_one_point_is_the_grids(rows, cols, points, voids):
    """`Terrain.ground_at` (the simulator's and the monitor's, one point as a float)
    gives `Terrain.ground`'s value: inside, on the edges, outside (NaN) and beside
    voids (NaN cells), on both surfaces."""
    from planner.terrain import Terrain

    rng = np.random.default_rng(rows * 10 + cols)
    height = rng.uniform(100.0, 900.0, (rows, cols))
    height.flat[rng.choice(height.size, min(voids, height.size - 1), replace=False)] = np.nan
    terrain = Terrain(height, Affine(30.0, 0.0, 500000.0, 0.0, -30.0, 4000000.0),
                      "EPSG:32616", height_upper=height + 2.0)
    for r, c in points + [(0.0, 0.0), (rows - 1.0, cols - 1.0)]:
        x, y = 500000.0 + 30.0 * (c + 0.5), 4000000.0 - 30.0 * (r + 0.5)
        for upper in (False, True):
            want = terrain.ground(x, y, upper=upper)[0]
            got = terrain.ground_at(x, y, upper=upper)
            assert (np.isnan(want) and np.isnan(got)) or got == want, (r, c, upper)
