"""Visibility sets against brute-force planner.exposure.los.sees, and candidate viewpoints."""

import math

import numpy as np
import pytest
from affine import Affine
from hypothesis import given, settings
from hypothesis import strategies as st

from common.errors import InputError
from planner.exposure import ExposureParams, Outpost, compute_exposure
from planner.exposure.los import sees
from planner.terrain import Terrain, synthetic_terrain
from planner.visibility import (
    SensorParams,
    candidate_viewpoints,
    compute_visibility,
    fleet_region,
    viewpoints_at,
)
from planner.visibility.kernels import flat_to_targets, transpose_csr

CELL = 30.0


def _terrain(seed, rows=16, cols=18, rough=3.0):
    rng = np.random.default_rng(seed)
    h = 200 + rng.normal(0, rough, (rows, cols)).cumsum(0).cumsum(1) / 4
    return Terrain(h, Affine(CELL, 0, 500_000.0, 0, -CELL, 4_000_000.0), "EPSG:32616")


def _surface(terrain, outposts=(), **params):
    return compute_exposure(terrain, list(outposts), ExposureParams(**params))


def _brute(surface, vp, sensor):
    """Dense [n_vp, n_cells] from planner.exposure.los.sees cell by cell (the reference)."""
    h = surface.terrain.height
    curv = surface.params.curvature_coeff
    out = np.zeros((len(vp), h.size), bool)
    for k, ((r0, c0), z0) in enumerate(zip(vp.indices, vp.xyz[:, 2])):
        for r in range(h.shape[0]):
            for c in range(h.shape[1]):
                z1 = h[r, c] + sensor.target_height_m
                d = CELL * math.hypot(r - r0, c - c0)
                if sensor.max_off_nadir_deg is not None and d > 0:
                    if z0 <= z1 or math.degrees(math.atan2(d, z0 - z1)) > sensor.max_off_nadir_deg:
                        continue
                out[k, r * h.shape[1] + c] = sees(h, CELL, float(c0), float(r0), z0, float(c),
                                                  float(r), z1, sensor.sensor_range_m, curv)
    return out


def _dense(vis, n_cells):
    out = np.zeros((vis.n_viewpoints, n_cells), bool)
    for k in range(vis.n_viewpoints):
        out[k, vis.target_cells[vis.seen_by(k)]] = True
    return out


sensors = st.builds(SensorParams,
                    sensor_range_m=st.floats(60.0, 600.0),
                    max_off_nadir_deg=st.one_of(st.none(), st.floats(20.0, 85.0)))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), sensor=sensors, spacing=st.sampled_from([60.0, 90.0]),
       curvature=st.sampled_from([0.0, 0.85714]))
def test_exact_and_banded_sweep_match_brute_force(seed, sensor, spacing, curvature):
    surface = _surface(_terrain(seed), ceiling_agl_m=60.0, clearance_m=10.0,
                       curvature_coeff=curvature)
    vp = candidate_viewpoints(surface, spacing_m=spacing)
    ref = _brute(surface, vp, sensor)
    n = surface.terrain.height.size
    assert (_dense(compute_visibility(surface, vp, sensor, method="exact"), n) == ref).all()
    # with an unbounded band the sweep defers every undecided cell to the exact test
    wide = compute_visibility(surface, vp, sensor, method="sweep", band_m=np.inf)
    assert (_dense(wide, n) == ref).all()


def test_default_sweep_agrees_with_brute_force_within_one_percent():
    """The documented bound of the default (banded) sweep, on synthetic terrains."""
    for seed, family in enumerate(["mixed", "peaks", "ridges"]):
        t = synthetic_terrain(40, 44, cell=30.0, seed=seed, family=family)
        surface = _surface(t, ceiling_agl_m=80.0, clearance_m=10.0)
        vp = candidate_viewpoints(surface, spacing_m=150.0)
        sensor = SensorParams(sensor_range_m=900.0)
        ref = _brute(surface, vp, sensor)
        got = _dense(compute_visibility(surface, vp, sensor), t.height.size)
        assert (got != ref).sum() <= 0.01 * ref.sum()


def test_structure_csr_csc_and_targets_are_consistent():
    surface = _surface(_terrain(7, 30, 30), ceiling_agl_m=80.0, clearance_m=10.0)
    vp = candidate_viewpoints(surface, spacing_m=90.0)
    vis = compute_visibility(surface, vp, SensorParams(sensor_range_m=400.0))
    dense = vis.to_scipy().toarray()
    assert dense.shape == (len(vp), vis.n_targets)
    assert dense.any(axis=0).all()  # every target is seen by some candidate
    for t in range(vis.n_targets):
        assert (np.flatnonzero(dense[:, t]) == vis.seers(t)).all()
    for k in range(len(vp)):
        assert (np.diff(vis.seen_by(k)) > 0).all()
    assert vis.indices.dtype == np.int32 and vis.target_viewpoints.dtype == np.int32
    assert (vis.counts() == dense.sum(axis=1)).all()


@given(st.integers(0, 2**32 - 1), st.integers(1, 5))
@settings(max_examples=30, deadline=None)
def test_parallel_csr_assembly_matches_scipy(seed, n_blocks):
    """Target numbering and the block-parallel transpose against scipy's CSC."""
    from scipy.sparse import csr_matrix
    rng = np.random.default_rng(seed)
    n_rows, n_cells = int(rng.integers(0, 12)), 40
    rows = [np.sort(rng.choice(n_cells, int(rng.integers(0, 9)), replace=False))
            for _ in range(n_rows)]
    indptr = np.concatenate([[0], np.cumsum([len(r) for r in rows])]).astype(np.int64)
    flat = np.concatenate(rows + [np.zeros(0)]).astype(np.int32)
    ids = flat.copy()
    cells = flat_to_targets(ids, n_cells)
    assert (cells == np.unique(flat)).all() and (cells[ids] == flat).all()
    col_ptr, col_rows = transpose_csr(indptr, ids, len(cells), n_blocks)
    ref = csr_matrix((np.ones(len(ids)), ids, indptr), shape=(n_rows, len(cells))).tocsc()
    ref.sort_indices()
    assert (col_ptr == ref.indptr).all() and (col_rows == ref.indices).all()


def test_off_nadir_limit_bounds_the_footprint():
    t = Terrain(np.full((41, 41), 100.0), Affine(CELL, 0, 0, 0, -CELL, 0), "EPSG:32616")
    surface = _surface(t, ceiling_agl_m=110.0, hide_margin_m=10.0, clearance_m=30.0)
    vp = viewpoints_at(surface, [20], [20])  # at 200 m AMSL, 99.5 m above the targets
    vis = compute_visibility(surface, vp, SensorParams(sensor_range_m=5000.0,
                                                       max_off_nadir_deg=45.0))
    r, c = vis.target_rowcol()
    d = CELL * np.hypot(r - 20, c - 20)
    assert d.max() <= 99.5 and vis.n_targets == np.count_nonzero(
        CELL * np.hypot(*np.mgrid[-20:21, -20:21]) <= 99.5)


def test_viewpoints_lattice_regions_and_launch():
    h = np.full((40, 60), 100.0)
    h[:, 28:32] = 400.0  # a high wall splits two valleys
    t = Terrain(h, Affine(CELL, 0, 0, 0, -CELL, 0), "EPSG:32616")
    # an outpost on the wall sees its top, so the wall is not flyable
    surface = _surface(t, [Outpost(x=30 * CELL, y=-20 * CELL, height_m=2.0)],
                       ceiling_agl_m=120.0, clearance_m=30.0)
    ids = np.unique(surface.regions[surface.regions > 0])
    assert len(ids) == 2
    vp = candidate_viewpoints(surface, spacing_m=90.0)
    assert surface.flyable[vp.indices[:, 0], vp.indices[:, 1]].all()
    assert np.allclose(vp.xyz[:, 2], surface.ceiling[vp.indices[:, 0], vp.indices[:, 1]])
    assert set(vp.region) == set(ids)
    one = candidate_viewpoints(surface, spacing_m=90.0, region=ids[0])
    assert (one.region == ids[0]).all()
    x, y = t.xy(5, 5)
    assert fleet_region(surface, [(x, y)]) == (int(surface.regions[5, 5]),)
    assert len(fleet_region(surface)) == 1
    wx, wy = t.xy(20, 30)
    with pytest.raises(InputError):
        fleet_region(surface, [(wx, wy)])
    # the default spacing gives a few thousand at most, never finer than a cell
    assert 1 <= len(candidate_viewpoints(surface)) <= 2400
