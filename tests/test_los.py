"""planner.exposure.los against dense sampling of the bilinear surface (an independent reference)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from sampled_sight import sampled_lowest

from planner.exposure.los import (
    EARTH_RADIUS_M,
    gap_range,
    lowest_visible_altitude,
    next_patch,
    sees,
)
from planner.terrain import bilinear

CELL = 30.0


def _terrain(seed, rows=24, cols=30):
    rng = np.random.default_rng(seed)
    return 200 + rng.normal(0, 3, (rows, cols)).cumsum(0).cumsum(1) / 4


points = st.tuples(st.floats(0, 29), st.floats(0, 23))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), a=points, b=points, k=st.sampled_from([0.0, 0.85714]))
def test_lowest_visible_altitude_matches_dense_sampling(seed, a, b, k):
    h = _terrain(seed)
    (u0, v0), (u1, v1) = a, b
    if np.hypot(u1 - u0, v1 - v0) < 0.5:
        return
    z0 = bilinear(h, [v0], [u0])[0] + 2.0
    exact = lowest_visible_altitude(h, CELL, u0, v0, z0, u1, v1, np.inf, k)
    sampled = sampled_lowest(h, CELL, u0, v0, z0, u1, v1, k, n=40001)
    # never below what sampling proves, and sampling at 40k points gets within centimetres
    assert exact >= sampled - 1e-6
    assert exact - sampled < 0.05
    assert sees(h, CELL, u0, v0, z0, u1, v1, exact + 0.01, np.inf, k)
    ground = bilinear(h, [v1], [u1])[0]
    if exact - 0.01 > ground + 1e-3:
        assert not sees(h, CELL, u0, v0, z0, u1, v1, exact - 0.01, np.inf, k)


def test_range_limit_and_flat_ground():
    h = np.full((10, 10), 100.0)
    assert lowest_visible_altitude(h, CELL, 0.0, 0.0, 102.0, 9.0, 0.0, 200.0, 0.0) == np.inf
    # on flat ground without curvature the lowest visible altitude is the ground itself
    assert abs(lowest_visible_altitude(h, CELL, 0.0, 0.0, 102.0, 9.0, 9.0, np.inf, 0.0) - 100.0) < 1e-9


def test_curvature_lowers_distant_terrain():
    h = np.full((3, 2001), 0.0)
    d = 2000 * CELL
    drop = 0.85714 * d * d / (2 * EARTH_RADIUS_M)
    z = lowest_visible_altitude(h, CELL, 0.0, 1.0, 2.0, 2000.0, 1.0, np.inf, 0.85714)
    # the horizon is the curved ground: the target must be above it, seen from 2 m
    assert z > 0.0
    assert z < drop + 2.0


anywhere = st.tuples(st.floats(-40, 70), st.floats(-40, 60))


@settings(max_examples=200, deadline=None)
@given(a=anywhere, b=anywhere)
def test_a_line_is_walked_patch_by_patch_on_and_off_the_grid(a, b):
    """Each step is the patch (clamped to the grid) holding the step's middle, and
    a line crosses each grid line once: a point off the grid once made the walk
    crawl in steps of 1e-9 (minutes for one exact test)."""
    rows, cols = 24, 30
    (u0, v0), (u1, v1) = a, b
    du, dv = u1 - u0, v1 - v0
    t, steps = 0.0, 0
    while t < 1.0:
        i, j, t_next = next_patch(u0, v0, du, dv, t, rows, cols)
        assert t_next > t
        mid = (t + t_next) / 2
        if t_next - t > 1e-6:
            u, v = u0 + mid * du, v0 + mid * dv
            assert i == min(max(int(np.floor(u)), 0), cols - 2)
            assert j == min(max(int(np.floor(v)), 0), rows - 2)
        t, steps = t_next, steps + 1
        assert steps <= cols + rows + 2


def test_a_changed_source_gets_kernels_compiled_anew(tmp_path):
    """numba re-compiles a cached kernel only when its own file changes; a kernel
    that inlines `next_patch` from this module kept its old code from the cache.
    The cache folder follows every file that uses numba and every package file
    those import (a constant frozen into a kernel), and no other: a docstring of
    the pipeline does not cost a recompile."""
    import os
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    import planner

    copy = tmp_path / "planner"
    shutil.copytree(Path(planner.__file__).parent, copy,
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env.update(PYTHONPATH=str(tmp_path), XDG_CACHE_HOME=str(tmp_path / "cache"))
    code = "import planner, numba; print(numba.config.CACHE_DIR)"

    def folder():
        return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                              text=True, check=True, cwd=tmp_path).stdout.strip()

    before = folder()
    assert before.startswith(str(tmp_path / "cache")) and before == folder()
    pipeline = copy / "pipeline.py"
    pipeline.write_text(pipeline.read_text().replace('"""', '""" A docstring edit.', 1))
    assert folder() == before
    seen = before
    for changed in ("exposure/los.py", "coverage/model/problem.py"):  # a kernel, a constant's
        source = copy / changed
        source.write_text(source.read_text() + "\n# changed\n")
        assert folder() != seen
        seen = folder()
    # a module without numba that a kernel's file imports under another name
    (copy / "exposure" / "aliased.py").write_text("LIMIT = 1\n")
    los = copy / "exposure" / "los.py"
    los.write_text(los.read_text() + "from . import aliased as _aliased  # noqa\n")
    seen = folder()
    (copy / "exposure" / "aliased.py").write_text("LIMIT = 2\n")
    assert folder() != seen


def _walk(u0, v0, u1, v1, rows, cols) -> int:
    """Steps of `next_patch` along the line, each one forward."""
    t, steps = 0.0, 0
    while t < 1.0:
        t_next = next_patch(u0, v0, u1 - u0, v1 - v0, t, rows, cols)[2]
        assert t_next > t
        t, steps = t_next, steps + 1
        assert steps <= cols + rows + 2
    return steps


# a grid coordinate a waypoint rounded for MAVLink lands on: a whole cell give or
# take a few 1e-12 (its latitude and longitude in 1e-7 degrees, projected back)
on_a_grid_line = st.tuples(st.integers(1, 28), st.floats(-1e-11, 1e-11))


@settings(max_examples=200, deadline=None)
@given(u=on_a_grid_line, v=st.floats(1, 22), length=st.integers(-6, 6),
       drift=st.floats(-1e-11, 1e-11), z=st.tuples(st.floats(0, 300), st.floats(0, 300)),
       seed=st.integers(0, 3), swap=st.booleans())
def test_a_line_along_a_grid_line_is_walked_cell_by_cell(u, v, length, drift, z, seed, swap):
    """A leg all but along a grid line (one between two rounded waypoints) moved too
    little in the walk's nudge to leave the cell it was crossing out of: it was
    walked in steps of 1e-9 (300,000 for one leg of a `gcs bases` run, 20 ms each).
    Now it crosses each grid line once, and its lowest and highest height above
    the ground are those of dense sampling of the bilinear ground."""
    rows, cols = 24, 30
    u0 = u[0] + u[1]
    a, b = (u0, v), (u0 + drift, min(max(v + length, 0.5), rows - 1.5))
    if swap:        # along a column or along a row
        a, b = a[::-1], b[::-1]
        rows, cols = cols, rows
    _walk(*a, *b, rows, cols)
    h = np.random.default_rng(seed).random((rows, cols)) * 100.0
    lo, hi = gap_range(h, a[0], a[1], z[0], b[0], b[1], z[1], False)
    t = np.linspace(0.0, 1.0, 4001)
    ground = bilinear(h, a[1] + t * (b[1] - a[1]), a[0] + t * (b[0] - a[0]))
    gap = z[0] + t * (z[1] - z[0]) - ground
    # sampling finds the extremes up to its spacing (an extreme between samples)
    assert gap.min() - 0.2 <= lo <= gap.min() + 1e-6
    assert gap.max() - 1e-6 <= hi <= gap.max() + 0.2
