"""The exposure surface and the hiddenness checks against brute-force line of sight.

References: planner.exposure.los (exact closed-form line of sight, itself checked
against dense sampling in test_los.py), dense sampling of the bilinear surface,
and analytic cases (flat ground, a straight ridge, a range limit).
"""

import math

import numpy as np
import pytest
from affine import Affine
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from sampled_sight import sampled_lowest

from planner.exposure import (
    ExposureParams,
    Outpost,
    compute_exposure,
    is_hidden,
    segment_clear,
    segment_hidden,
    segments_hidden,
)
from planner.exposure import kernels as exposure_kernels
from planner.exposure import surface as exposure
from planner.exposure.los import lowest_visible_grid, sees
from planner.terrain import Terrain, bilinear

CELL = 30.0
X0, Y0 = 500_000.0, 4_000_000.0
K = 0.85714


def _terrain(height) -> Terrain:
    return Terrain(np.asarray(height, float), Affine(CELL, 0, X0, 0, -CELL, Y0), "EPSG:32616")


def _rough(seed, rows=28, cols=32, relief=40.0):
    """Smooth hills plus cell-scale roughness: horizons at every distance."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:rows, 0:cols]
    h = 300.0 + sum(relief / (i + 1) * np.sin(rng.uniform(0.1, 0.6) * (i + 1) * u
                                            + rng.uniform(0.1, 0.6) * (i + 1) * v
                                            + rng.uniform(0, 6.3)) for i in range(4))
    return h + rng.normal(0.0, relief / 10, (rows, cols))


def _outpost(terrain, row, col, height=2.0, range_m=math.inf):
    x, y = terrain.xy(row, col)
    return Outpost(x=float(x), y=float(y), height_m=height, range_m=range_m)


def _exact_lowest(terrain, outposts, curvature):
    """Min over outposts of the exact lowest visible altitude at every cell centre."""
    low = np.full(terrain.shape, np.inf)
    for o in outposts:
        row, col = terrain.rowcol(o.x, o.y)
        z0 = terrain.ground(o.x, o.y)[0] + o.height_m
        low = np.minimum(low, lowest_visible_grid(terrain.height, CELL, float(col), float(row),
                                                  z0, o.range_m, curvature))
    return low


def _eye(terrain, o):
    row, col = terrain.rowcol(o.x, o.y)
    return float(col), float(row), terrain.ground(o.x, o.y)[0] + o.height_m


# --- the surface against the exact line of sight ---------------------------------------------

posts = st.lists(st.tuples(st.floats(0, 27), st.floats(0, 31), st.floats(0, 20),
                           st.one_of(st.just(math.inf), st.floats(150, 900))),
                 min_size=1, max_size=3)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), posts=posts, curvature=st.sampled_from([0.0, K]),
       relief=st.sampled_from([5.0, 40.0, 150.0]))
def test_lowest_seen_is_a_tight_lower_bound_of_the_exact_one(seed, posts, curvature, relief):
    terrain = _terrain(_rough(seed, relief=relief))
    outposts = [_outpost(terrain, r, c, hgt, rng) for r, c, hgt, rng in posts]
    params = ExposureParams(curvature_coeff=curvature)
    surface = compute_exposure(terrain, outposts, params)
    exact = _exact_lowest(terrain, outposts, curvature)
    ours = surface.lowest_seen
    # safe side: never above the exact value (the brief allows 0.5 m; we are exact-or-below)
    assert np.all(ours <= exact + 1e-6)
    # and tight up to the ceiling (above it E is capped, and the sweep stops
    # refining): most cells within 2 m. These terrains have cell-scale
    # roughness (white noise up to 15 m per cell), the hard case for tracking
    # horizons from ray to ray: 1,500 random cases measured 98.6 % within 2 m
    # on average, 93.2 % at worst (test_tight_on_average below checks the
    # average); benchmarks/ measures realistic terrains.
    ground = terrain.height
    capped = np.minimum(ours, ground + params.ceiling_agl_m)
    seen = np.isfinite(exact)
    assert np.all(np.isfinite(ours[seen]) | np.isneginf(ours[seen]))
    if seen.any():
        assert _within_2m(ours, exact, ground + params.ceiling_agl_m, seen) >= 0.88
    # the surface derived from it, on the cells off the outer ring (the surface ends
    # at its centres: a rounded point there may leave the grid)
    flyable = capped - params.hide_margin_m >= ground + params.clearance_m
    flyable[[0, -1], :] = flyable[:, [0, -1]] = False
    assert np.array_equal(surface.flyable, flyable)
    assert np.array_equal(surface.exposure[flyable], capped[flyable])
    assert np.isnan(surface.exposure[~flyable]).all()
    assert np.array_equal(surface.regions > 0, flyable)
    np.testing.assert_allclose(surface.ceiling[flyable], capped[flyable] - params.hide_margin_m)
    np.testing.assert_allclose(surface.floor, ground + params.clearance_m)


def _within_2m(ours, exact, cap, seen):
    """Share of seen cells whose capped value is within 2 m of the capped exact one."""
    return np.mean(np.minimum(ours, cap)[seen] >= np.minimum(exact, cap)[seen] - 2.0)


def test_tight_on_average():
    """Over many rough terrains and eyes (as above, seeded), the average share
    of cells within 2 m of the exact value, up to the ceiling."""
    rng = np.random.default_rng(5)
    shares = []
    for case in range(120):
        terrain = _terrain(_rough(case, relief=(5.0, 40.0, 150.0)[case % 3]))
        outposts = [_outpost(terrain, rng.uniform(0, 27), rng.uniform(0, 31),
                             rng.uniform(0, 20), rng.choice([math.inf, 500.0]))
                    for _ in range(rng.integers(1, 4))]
        curvature = (0.0, K)[case % 2]
        surface = compute_exposure(terrain, outposts, ExposureParams(curvature_coeff=curvature))
        exact = _exact_lowest(terrain, outposts, curvature)
        seen = np.isfinite(exact)
        assert np.all(surface.lowest_seen <= exact + 1e-6)
        if seen.any():
            shares.append(_within_2m(surface.lowest_seen, exact, terrain.height + 120.0, seen))
    assert np.mean(shares) >= 0.98


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), rows=st.integers(2, 8), cols=st.integers(2, 40),
       transpose=st.booleans(), eye=st.floats(0, 10), curvature=st.sampled_from([0.0, K]))
# a 0 m eye: sight lines that started 1e-12 of a ray off the eye were 0.06 m off
@example(seed=6218, rows=2, cols=2, transpose=False, eye=0.0, curvature=0.0)
def test_narrow_grids_stay_safe(seed, rows, cols, transpose, eye, curvature):
    """Grids a few cells wide: sectors and wedges with next to no cells across."""
    rng = np.random.default_rng(seed)
    if transpose:
        rows, cols = cols, rows
    terrain = _terrain(300.0 + rng.normal(0.0, 20.0, (rows, cols)))
    post = _outpost(terrain, rng.uniform(0, rows - 1), rng.uniform(0, cols - 1), eye)
    surface = compute_exposure(terrain, [post], ExposureParams(curvature_coeff=curvature))
    assert np.all(surface.lowest_seen <= _exact_lowest(terrain, [post], curvature) + 1e-6)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), posts=posts, curvature=st.sampled_from([0.0, K]))
def test_sweep_does_not_depend_on_threads_or_the_grid_it_starts_from(seed, posts, curvature):
    """Threads take wedges in whatever order they finish; a fresh grid is written
    without being read. Neither may change a single value (voids included)."""
    height = _rough(seed, relief=40.0)
    height[3:5, 20:23] = np.nan
    terrain = _terrain(height)
    outposts = [o for o in (_outpost(terrain, r, c, eye, rng) for r, c, eye, rng in posts)
                if np.isfinite(terrain.ground(o.x, o.y)[0])] or [_outpost(terrain, 20, 5)]
    h = np.ascontiguousarray(terrain.height)
    eyes = exposure._eyes(terrain, outposts)
    results = []
    for slots, start in ((1, np.inf), (2, np.nan), (5, -1e9)):
        acc = np.full(h.shape, start)  # garbage for a fresh sweep: must never show
        for n, eye in enumerate(eyes):
            exposure_kernels.lowest_seen_into(h, CELL, eye, curvature, 120.0, acc, slots,
                                              n == 0 and start != np.inf)
        results.append(acc)
    assert np.array_equal(results[0], results[1]) and np.array_equal(results[0], results[2])


def test_progress_reports_every_outpost():
    terrain = _terrain(_rough(1))
    outposts = [_outpost(terrain, 3 + i, 4 + 2 * i) for i in range(6)]
    calls = []
    compute_exposure(terrain, outposts, progress=lambda done, total: calls.append((done, total)))
    assert calls[-1] == (6, 6)
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)


# --- analytic cases -------------------------------------------------------------------------------

def test_flat_ground_hides_nothing_within_range():
    terrain = _terrain(np.full((40, 50), 250.0))
    post = _outpost(terrain, 20.0, 25.0, height=2.0, range_m=450.0)
    surface = compute_exposure(terrain, [post], ExposureParams(curvature_coeff=0.0))
    row, col = np.mgrid[0:40, 0:50]
    dist = CELL * np.hypot(row - 20.0, col - 25.0)
    inside = dist <= 450.0
    # on a flat earth the outpost sees the ground itself everywhere within range
    np.testing.assert_allclose(surface.lowest_seen[inside & (dist > 0)], 250.0, atol=1e-9)
    assert not surface.flyable[inside].any()
    # beyond range E is the ceiling above ground: flyable everywhere
    assert np.isinf(surface.lowest_seen[~inside]).all()
    inner = ~inside & terrain.solid  # off the outer ring
    np.testing.assert_allclose(surface.exposure[inner], 250.0 + 120.0)
    assert surface.flyable[inner].all()
    assert surface.regions.max() == 1


def test_flat_ground_with_curvature_hides_nothing_short_of_the_horizon():
    """Apparent slope of flat ground at distance d: -(z0 - g) / d - c d, rising
    until the horizon distance sqrt((z0 - g) / c) (12 km for a 10 m eye): closer
    than that the steepest point of every ray is its end, so E = ground."""
    terrain = _terrain(np.full((30, 300), 100.0))
    post = _outpost(terrain, 15.0, 2.0, height=10.0)
    surface = compute_exposure(terrain, [post], ExposureParams(curvature_coeff=K))
    np.testing.assert_allclose(surface.lowest_seen[:, 4:], 100.0, atol=1e-6)
    assert not surface.flyable.any()


def _ridge(rows=41, cols=80, crest_col=30, crest=400.0, base=300.0):
    """A straight north-south ridge: linear flanks up to a crest on column crest_col."""
    col = np.arange(cols, dtype=float)
    profile = np.where(col <= crest_col, base + (crest - base) * col / crest_col,
                       crest - 6.0 * (col - crest_col))
    return np.tile(profile, (rows, 1))


def test_ridge_shadow_follows_the_line_over_the_crest():
    h = _ridge()
    terrain = _terrain(h)
    u0, v0, crest_col = 5.0, 20.0, 30
    post = _outpost(terrain, v0, u0, height=2.0)
    z0 = h[20, 5] + 2.0
    surface = compute_exposure(terrain, [post], ExposureParams(curvature_coeff=0.0))
    row, col = np.mgrid[0:41, 0:80].astype(float)
    behind = col > crest_col
    # the sight line grazing the crest: same fraction of the way along every ray
    line = z0 + (400.0 - z0) * (col - u0) / (crest_col - u0)
    expected = np.where(behind, line, np.nan)
    exact = _exact_lowest(terrain, [post], 0.0)
    np.testing.assert_allclose(exact[behind], expected[behind], atol=1e-6)  # the formula
    ours = surface.lowest_seen
    assert np.all(ours[behind] <= expected[behind] + 1e-6)
    # where the rings run along the crest (|d row| <= |d col|) the crest is on a
    # ring line and the sweep finds it exactly; elsewhere within 2 m (up to the
    # ceiling, above which E is capped and the sweep stops refining)
    along = behind & (np.abs(row - v0) <= np.abs(col - u0))
    cap = h + 120.0
    np.testing.assert_allclose(np.minimum(ours, cap)[along], np.minimum(expected, cap)[along],
                               atol=1e-6)
    assert np.mean(np.minimum(ours, cap)[behind] >= np.minimum(expected, cap)[behind] - 2.0) >= 0.99
    # flyable behind the ridge where the line leaves room for clearance and margin
    room = (np.minimum(expected, h + 120.0) - 10.0 >= h + 30.0) & terrain.solid
    assert np.array_equal(surface.flyable[along], room[along])
    assert surface.flyable[behind].any() and not surface.flyable[~behind].any()


def test_range_limit():
    terrain = _terrain(_rough(7, rows=40, cols=40))
    post = _outpost(terrain, 20.0, 20.0, height=5.0, range_m=300.0)
    surface = compute_exposure(terrain, [post], ExposureParams())
    row, col = np.mgrid[0:40, 0:40]
    dist = CELL * np.hypot(row - 20.0, col - 20.0)
    beyond = dist > 300.0
    assert np.isinf(surface.lowest_seen[beyond]).all()
    assert (surface.lowest_seen[~beyond] < np.inf).all()
    ground = terrain.height
    beyond &= terrain.solid
    np.testing.assert_allclose(surface.exposure[beyond], ground[beyond] + 120.0)
    assert surface.flyable[beyond].all()


# --- points and legs against dense sampling ----------------------------------------------------

@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), curvature=st.sampled_from([0.0, K]))
@example(seed=864, curvature=0.0)  # a crease 10 m from the eye: sampling alone missed 0.9 m
def test_is_hidden_against_dense_sampling(seed, curvature):
    terrain = _terrain(_rough(seed))
    rng = np.random.default_rng(seed)
    posts = [_outpost(terrain, *rng.uniform([0, 0], [27, 31]), height=3.0) for _ in range(2)]
    surface = compute_exposure(terrain, posts, ExposureParams(curvature_coeff=curvature))
    rows, cols = rng.uniform(0, 27, 60), rng.uniform(0, 31, 60)
    x, y = terrain.xy(rows, cols)
    lowest = np.full(60, np.inf)
    for o in posts:
        u0, v0, z0 = _eye(terrain, o)
        lowest = np.minimum(lowest, [sampled_lowest(terrain.height, CELL, u0, v0, z0, c, r, curvature)
                                     for r, c in zip(rows, cols)])
    z = lowest + rng.uniform(-30, 30, 60)
    hidden = is_hidden(surface, np.stack([x, y, z], axis=1))
    clear = np.abs(z - lowest) > 0.25  # sampling misses peaks by centimetres to decimetres
    assert np.array_equal(hidden[clear], (z < lowest)[clear])


def _leg_seen_by_sampling(terrain, posts, a, b, curvature, n=600):
    t = np.linspace(0, 1, n)[:, None]
    p = a + t * (b - a)
    row, col = terrain.rowcol(p[:, 0], p[:, 1])
    for o in posts:
        u0, v0, z0 = _eye(terrain, o)
        for k in range(n):
            if sees(terrain.height, CELL, u0, v0, z0, col[k], row[k], p[k, 2], o.range_m,
                    curvature):
                return True
    return False


def _legs_under_lowest(terrain, exact, rng, n_legs, reach):
    """Legs a -> b between cell centres up to ``reach`` cells apart, each end at or
    up to 8 m under the exact lowest seen altitude (200 m above the ground at most)."""
    r0, c0 = rng.integers(0, 28, n_legs), rng.integers(0, 32, n_legs)
    r1 = np.clip(r0 + rng.integers(-reach, reach + 1, n_legs), 0, 27)
    c1 = np.clip(c0 + rng.integers(-reach, reach + 1, n_legs), 0, 31)
    cap = terrain.height + 200.0
    za = np.minimum(exact[r0, c0], cap[r0, c0]) - rng.uniform(0.0, 8.0, n_legs)
    zb = np.minimum(exact[r1, c1], cap[r1, c1]) - rng.uniform(0.0, 8.0, n_legs)
    return (np.stack([*terrain.xy(r0, c0), za], axis=1),
            np.stack([*terrain.xy(r1, c1), zb], axis=1))


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), curvature=st.sampled_from([0.0, K]),
       range_m=st.sampled_from([math.inf, 500.0]))
def test_segment_hidden_never_passes_a_visible_leg(seed, curvature, range_m):
    terrain = _terrain(_rough(seed, relief=80.0))
    rng = np.random.default_rng(seed)
    posts = [_outpost(terrain, *rng.uniform([0, 0], [27, 31]), height=2.0, range_m=range_m)
             for _ in range(2)]
    surface = compute_exposure(terrain, posts, ExposureParams(curvature_coeff=curvature))
    exact = _exact_lowest(terrain, posts, curvature)
    n_legs = 12
    a, b = _legs_under_lowest(terrain, exact, rng, n_legs, reach=4)
    proven = segments_hidden(surface, a, b)
    for k in range(n_legs):
        assert proven[k] == segment_hidden(surface, a[k], b[k])
        if proven[k]:
            assert not _leg_seen_by_sampling(terrain, posts, a[k], b[k], curvature)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), curvature=st.sampled_from([0.0, K]))
def test_horizon_hints_never_lose_a_proof_nor_prove_a_seen_leg(seed, curvature):
    """Hints (any distance, right, wrong or none) only save work: every leg proven
    without them is proven with them, and no leg proven with them is seen."""
    terrain = _terrain(_rough(seed, relief=80.0))
    rng = np.random.default_rng(seed)
    posts = [_outpost(terrain, *rng.uniform([0, 0], [27, 31]), height=2.0) for _ in range(2)]
    surface = compute_exposure(terrain, posts, ExposureParams(curvature_coeff=curvature))
    exact = _exact_lowest(terrain, posts, curvature)
    n_legs = 40
    a, b = _legs_under_lowest(terrain, exact, rng, n_legs, reach=2)
    found = np.full((n_legs, 2), np.nan)
    plain = segments_hidden(surface, a, b, 5.0, found)
    # the horizons found, jittered by up to 3 cells, and random distances
    hints = np.where(rng.random((n_legs, 2)) < 0.5, found + rng.uniform(-90, 90, (n_legs, 2)),
                     rng.uniform(0, 1500, (n_legs, 2)))
    hinted = segments_hidden(surface, a, b, 5.0, hints)
    assert np.all(hinted[plain])
    for k in np.flatnonzero(hinted & ~plain):
        assert not _leg_seen_by_sampling(terrain, posts, a[k], b[k], curvature)


def test_segment_hidden_proves_legs_with_room_and_rejects_seen_ones():
    h = _ridge()
    terrain = _terrain(h)
    post = _outpost(terrain, 20.0, 5.0, height=2.0)
    surface = compute_exposure(terrain, [post], ExposureParams(curvature_coeff=0.0))
    z0 = h[20, 5] + 2.0

    def line(col):
        return z0 + (400.0 - z0) * (col - 5.0) / 25.0

    x1, y1 = terrain.xy(5.0, 40.0)
    x2, y2 = terrain.xy(35.0, 70.0)
    # a leg 1 m under the crest line all along, diagonal across the shadow
    low = np.array([x1, y1, line(40.0) - 1.0]), np.array([x2, y2, line(70.0) - 1.0])
    assert segment_hidden(surface, *low)
    # the same leg 1 m above the line is seen all along; one end above: seen
    assert not segment_hidden(surface, low[0] + [0, 0, 2.0], low[1] + [0, 0, 2.0])
    assert not segment_hidden(surface, low[0], low[1] + [0, 0, 2.0])
    # a leg from the shadow out over the crest to the outpost's side
    xs, ys = terrain.xy(20.0, 20.0)
    assert not segment_hidden(surface, low[0], np.array([xs, ys, h[20, 20] + 50.0]))
    # off the grid: not provable
    assert not segment_hidden(surface, low[0], np.array([X0 - 100.0, y1, 500.0]))


def test_leg_across_the_range_circle_is_proven_by_the_terrain():
    """A leg in the ridge's shadow crossing an outpost's range circle, with only
    0.4 mm of it inside: hidden by the terrain, whatever the range (halving alone
    never reached a midpoint inside the circle and gave up). The same leg in the
    open, above the sight line, is seen."""
    h = _ridge()
    terrain = _terrain(h)
    eye = np.array([*terrain.xy(20.0, 5.0), h[20, 5] + 2.0])
    z0 = eye[2]
    x, y = terrain.xy(10.0, 50.0)
    radial = np.array([x, y]) - eye[:2]
    reach = float(np.hypot(*radial))
    u = radial / reach
    post = _outpost(terrain, 20.0, 5.0, height=2.0, range_m=reach)
    surface = compute_exposure(terrain, [post], ExposureParams(curvature_coeff=0.0))
    ends = [eye[:2] + u * (reach - 0.0004), eye[:2] + u * (reach + 1.2)]
    slope = (400.0 - z0) / (25.0 * CELL)              # the sight line over the crest
    below = [np.array([*p, z0 + slope * np.hypot(*(p - eye[:2])) - 20.0]) for p in ends]
    assert segment_hidden(surface, *below)
    above = [p + [0.0, 0.0, 200.0] for p in below]
    assert not segment_hidden(surface, *above)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), a=st.tuples(st.floats(0, 31), st.floats(0, 27)),
       b=st.tuples(st.floats(0, 31), st.floats(0, 27)), za=st.floats(-20, 80),
       zb=st.floats(-20, 80))
def test_segment_clear_against_dense_sampling(seed, a, b, za, zb):
    terrain = _terrain(_rough(seed, relief=60.0))
    surface = compute_exposure(terrain, [], ExposureParams())
    h = terrain.height
    ga = bilinear(h, [a[1]], [a[0]])[0]
    gb = bilinear(h, [b[1]], [b[0]])[0]
    pa = np.array([*terrain.xy(a[1], a[0]), ga + za])
    pb = np.array([*terrain.xy(b[1], b[0]), gb + zb])
    t = np.linspace(0, 1, 20001)
    u, v = a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])
    room = (pa[2] + t * (pb[2] - pa[2]) - bilinear(h, v, u)).min()
    clear = segment_clear(surface, pa, pb)
    if clear:
        assert room >= 30.0 - 1e-6
    if room < 30.0 - 0.05:  # sampling may miss a dip by centimetres
        assert not clear
    if room > 30.0 + 0.05:
        assert clear


def test_no_outposts_everything_below_the_ceiling_is_flyable():
    terrain = _terrain(_rough(3))
    surface = compute_exposure(terrain, [], ExposureParams())
    assert np.array_equal(surface.flyable, terrain.solid)  # all but the outer ring
    np.testing.assert_allclose(surface.ceiling[terrain.solid], terrain.height[terrain.solid]
                               + 110.0)
    assert segment_hidden(surface, [*terrain.xy(1, 1), 0.0], [*terrain.xy(20, 20), 0.0])


def test_outpost_off_the_terrain_is_an_error():
    terrain = _terrain(_rough(3))
    with pytest.raises(ValueError, match="off the terrain"):
        compute_exposure(terrain, [Outpost(x=X0 - 500.0, y=Y0)], ExposureParams())
