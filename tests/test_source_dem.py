"""The exposure surface and the planned legs against the *source* DEM the user gave.

The reference is our own of nothing: a sight line from the eye (the source
DEM's ground at the outpost plus its height) to a point, sampled densely, its
terrain read from the source raster itself (rasterio-written file, bilinear
between the file's own pixel centres, in the file's own CRS). Dense sampling
can only miss a horizon, so the reference is at or below the exact lowest seen
altitude; ours must never be more than 0.5 m above it.
"""

import numpy as np
import pytest
import rasterio
from affine import Affine
from pyproj import Transformer

from planner.exposure import ExposureParams, compute_exposure, load_outposts
from planner.exposure.los import DEFAULT_CURVATURE_COEFF, EARTH_RADIUS_M
from planner.pipeline import allocate, launch_starts, prepare
from planner.scenario import Scenario
from planner.terrain import bilinear, load_dem, synthetic_terrain

TOLERANCE_M = 0.5
SAMPLES_PER_M = 1.0 / 2.0  # a terrain sample every 2 m along a sight line, and
NEAR_RATIO = 1.002  # near the eye, where a missed bump is magnified, every 0.2 % of d


class SourceDEM:
    """The source raster's own bilinear surface, read back from the file."""

    def __init__(self, path, working_crs):
        with rasterio.open(path) as ds:
            self.h = ds.read(1, masked=True).astype(float).filled(np.nan)
            self.transform = ds.transform
            self.to_src = Transformer.from_crs(working_crs, ds.crs, always_xy=True)

    def ground(self, x, y):
        u, v = ~self.transform @ self.to_src.transform(np.asarray(x), np.asarray(y))
        return bilinear(self.h, v - 0.5, u - 0.5)


def _lowest_seen(src, eye_xy, eye_z, xy):
    """Dense-sampled lowest altitude seen from the eye above each point (GDAL's
    curvature, as the planner's model): an underestimate of the exact one."""
    out = np.empty(len(xy))
    for k, (x, y) in enumerate(xy):
        d_total = float(np.hypot(x - eye_xy[0], y - eye_xy[1]))
        n = max(int(d_total * SAMPLES_PER_M), 8)
        near = np.exp(np.arange(np.log(1e-3), np.log(d_total), np.log(NEAR_RATIO))) / d_total
        t = np.union1d(np.linspace(1e-3 / d_total, 1.0 - 1e-3 / d_total, n), near)
        d = t * d_total
        ground = src.ground(eye_xy[0] + t * (x - eye_xy[0]), eye_xy[1] + t * (y - eye_xy[1]))
        drop = DEFAULT_CURVATURE_COEFF * d * d / (2 * EARTH_RADIUS_M)
        slope = np.nanmax((ground - drop - eye_z) / d)
        out[k] = eye_z + slope * d_total + DEFAULT_CURVATURE_COEFF * d_total ** 2 / (
            2 * EARTH_RADIUS_M)
    return out


def _write(path, height, transform, crs, nodata=None):
    with rasterio.open(path, "w", driver="GTiff", width=height.shape[1],
                       height=height.shape[0], count=1, dtype="float64", crs=crs,
                       transform=transform, nodata=nodata) as ds:
        ds.write(height, 1)
    return path


def _outposts_file(path, lonlat, height_m=10.0):
    import json

    path.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": f"P{i + 1}", "height_m": height_m},
         "geometry": {"type": "Point", "coordinates": [float(lon), float(lat)]}}
        for i, (lon, lat) in enumerate(lonlat)]}))
    return path


def _hilly(seed, rows, cols, cell):
    """Rough held-out hills: a seeded synthetic family plus cell-scale noise."""
    t = synthetic_terrain(rows, cols, cell=cell, seed=seed, family="mixed")
    rng = np.random.default_rng(seed + 1)
    return t.height + rng.normal(0.0, 3.0, t.height.shape)


def _check_against_source(terrain, surface, src, outposts, rng, n_cells=250):
    flyable = np.argwhere(surface.flyable)
    assert len(flyable) > 50
    pick = flyable[rng.choice(len(flyable), min(n_cells, len(flyable)), replace=False)]
    xy = np.stack(terrain.xy(pick[:, 0], pick[:, 1]), axis=1)
    reference = np.full(len(xy), np.inf)
    for o in outposts:
        eye_z = float(src.ground(o.x, o.y)) + o.height_m
        assert o.ground_m == pytest.approx(float(src.ground(o.x, o.y)), abs=1e-6)
        reference = np.minimum(reference, _lowest_seen(src, (o.x, o.y), eye_z, xy))
    ours = surface.lowest_seen[pick[:, 0], pick[:, 1]]
    assert (ours <= reference + TOLERANCE_M).all(), float((ours - reference).max())
    # the ground for clearance is nowhere below the source's ground at the centres
    assert (terrain.upper[pick[:, 0], pick[:, 1]] >= src.ground(*xy.T) - 1e-6).all()
    return ours, reference


def test_utm_geotiff_off_the_snapped_lattice_is_kept_and_safe(tmp_path):
    cell = 30.0
    height = _hilly(11, 150, 160, cell)
    transform = Affine(cell, 0, 700_017.3, 0, -cell, 4_060_011.9)  # not on multiples of 30
    dem = _write(tmp_path / "utm.tif", height, transform, "EPSG:32616")
    terrain = load_dem([dem])
    # kept on its own lattice: the same transform and heights, no resampling
    assert terrain.crs == "EPSG:32616" and terrain.transform == transform
    assert np.array_equal(terrain.height, height) and terrain.height_upper is None
    to_ll = Transformer.from_crs("EPSG:32616", "EPSG:4326", always_xy=True)
    rng = np.random.default_rng(3)
    cells = rng.integers(20, 130, (4, 2))
    posts = _outposts_file(tmp_path / "posts.geojson",
                           [to_ll.transform(*transform @ (c + 0.5, r + 0.5)) for r, c in cells])
    outposts = load_outposts(posts, terrain)
    surface = compute_exposure(terrain, outposts, ExposureParams())
    _check_against_source(terrain, surface, SourceDEM(dem, terrain.crs), outposts, rng)


def test_geographic_dem_is_resampled_safely_and_planned_legs_are_hidden(tmp_path):
    # a 1" geographic grid (about 31 x 25 m here) holding rough hills
    d = 1.0 / 3600
    height = _hilly(23, 130, 150, 28.0)
    transform = Affine(d, 0, -84.30, 0, -d, 36.60)
    dem = _write(tmp_path / "geo.tif", height, transform, "EPSG:4326")
    terrain = load_dem([dem])
    assert terrain.height_upper is not None and terrain.crs == "EPSG:32616"
    src = SourceDEM(dem, terrain.crs)
    rng = np.random.default_rng(5)
    cells = rng.integers(25, 105, (4, 2))
    posts = _outposts_file(tmp_path / "posts.geojson",
                           [transform @ (c + 0.5, r + 0.5) for r, c in cells])
    outposts = load_outposts(posts, terrain)
    surface = compute_exposure(terrain, outposts, ExposureParams())
    ours, reference = _check_against_source(terrain, surface, src, outposts, rng)
    # conservative, not useless: most sampled cells within 10 m of the reference
    assert np.mean(ours >= reference - 10.0) > 0.8

    # a whole plan on it: every point of every leg hidden and clear on the source DEM
    scenario = Scenario(dem=[str(dem)], outposts=str(posts), uavs=2, method="rt",
                        sensor_range_m=600.0, viewpoint_spacing_m=150.0)
    ctx = prepare(scenario)
    outcome = allocate(ctx, 2, launch_starts(ctx))
    checked = 0
    for poly in outcome.polylines:
        for a, b in zip(poly[:-1], poly[1:]):
            n = max(2, int(np.hypot(*(b - a)[:2]) / 5.0))
            pts = a + np.linspace(0, 1, n)[:, None] * (b - a)
            lowest = np.full(n, np.inf)
            for o in ctx.outposts:
                eye_z = float(src.ground(o.x, o.y)) + o.height_m
                lowest = np.minimum(lowest, _lowest_seen(src, (o.x, o.y), eye_z, pts[:, :2]))
            assert (pts[:, 2] < lowest).all()
            assert (pts[:, 2] - src.ground(pts[:, 0], pts[:, 1]) >= 30.0 - 1e-6).all()
            checked += n
    assert checked > 150
