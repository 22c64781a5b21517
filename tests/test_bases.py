"""`gcs bases` against references it did not produce: the planner's own launch check
and a plan from the best base, brute-force line of sight (dense sampling over an
independent bilinear interpolation, scipy's) for the hiddenness of every base's
column, and the reach bound recomputed from a dense visibility matrix."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from hills import central_outpost
from scipy.ndimage import map_coordinates

from common.errors import InputError
from gcs.cli import main
from planner.bases import suggest_bases
from planner.exposure.los import EARTH_RADIUS_M
from planner.pipeline import allocate, coverage_problem, launch_starts, prepare
from planner.scenario import Scenario
from planner.terrain import synthetic_terrain

N = 60
SEPARATION = 300.0
#: a small area of the built-in terrain (seconds to plan on it)
AREA = "36.57,-84.28,36.61,-84.22"


@pytest.fixture(scope="module")
def hills():
    """Synthetic hills with one outpost on the central hill, its context and bases."""
    terrain = synthetic_terrain(N, N, cell=30.0, seed=3, family="hills")
    outposts = [central_outpost(terrain)]
    scenario = Scenario(sample=True, uavs=2, sensor_range_m=500.0, ceiling_agl_m=150.0,
                        clearance_m=20.0, hide_margin_m=5.0, method="rt").validate()
    ctx = prepare(scenario, terrain=terrain, outposts=outposts)
    bases = suggest_bases(ctx, count=4, separation_m=SEPARATION, spacing_m=90.0)
    return ctx, outposts, bases


# --- brute-force line of sight ------------------------------------------------------------

def _height(terrain, rows, cols):
    """Bilinear terrain height at fractional (row, col): scipy's, not the planner's."""
    return map_coordinates(terrain.height, [np.ravel(rows), np.ravel(cols)], order=1,
                           mode="nearest")


def _clearance_of_sight(terrain, outpost, x, y, z, curvature, samples=1500):
    """Least height (m) of the sight line from the outpost's eye to (x, y, z) above
    the terrain, sampled densely (curvature lowers far terrain as GDAL does): > 0
    means the outpost sees the point (if within range), <= 0 the terrain blocks it."""
    r0, c0 = terrain.rowcol(outpost.x, outpost.y)
    z0 = float(_height(terrain, [r0], [c0])[0]) + outpost.height_m
    r1, c1 = terrain.rowcol(x, y)
    dist = math.hypot(x - outpost.x, y - outpost.y)
    t = np.linspace(0.0, 1.0, samples + 2)[1:-1]
    d = t * dist
    ground = _height(terrain, r0 + t * (r1 - r0), c0 + t * (c1 - c0))
    drop = curvature * d * d / (2 * EARTH_RADIUS_M)
    target = z - curvature * dist * dist / (2 * EARTH_RADIUS_M)
    line = z0 + t * (target - z0)
    return float(np.min(line - (ground - drop)))


def _seen(terrain, outposts, x, y, z, curvature, margin=0.0) -> bool:
    """Some outpost in range sees (x, y, z) with the sight line ``margin`` clear."""
    return any(math.hypot(x - o.x, y - o.y) <= o.range_m
               and _clearance_of_sight(terrain, o, x, y, z, curvature) > margin
               for o in outposts)


# --- the library ------------------------------------------------------------------------

def test_bases_are_ranked_by_their_bound_and_kept_apart(hills):
    ctx, _, bases = hills
    assert 2 <= len(bases) <= 4
    assert [b.rank for b in bases] == list(range(1, len(bases) + 1))
    bounds = [b.bound_s for b in bases]
    assert bounds == sorted(bounds) and all(np.isfinite(bounds)) and bounds[0] > 0
    for i, a in enumerate(bases):
        for b in bases[i + 1:]:
            assert math.hypot(a.x - b.x, a.y - b.y) >= SEPARATION


def test_every_base_passes_the_planners_launch_check(hills):
    ctx, _, bases = hills
    for b in bases:
        trial = replace(ctx, scenario=replace(ctx.scenario, launch=[(b.lat, b.lon)]))
        start = launch_starts(trial)[0]   # raises InputError on a point it refuses
        assert start.xyz[2] == pytest.approx(b.takeoff_m)
        assert start.launch[2] == pytest.approx(b.ground_m)


def test_each_base_column_is_hidden_by_brute_force_line_of_sight(hills):
    ctx, outposts, bases = hills
    s = ctx.scenario
    for b in bases:
        # clear of the terrain: the takeoff top at least the clearance above the ground
        assert b.takeoff_m >= b.ground_m + s.clearance_m - 1e-6
        for z in np.linspace(b.ground_m + 1.0, b.takeoff_m, 8):
            assert not _seen(ctx.terrain, outposts, b.x, b.y, z, s.curvature_coeff), \
                f"base {b.rank}: {z:.1f} m AMSL above it is seen"


def test_a_cell_known_to_be_exposed_is_never_a_base(hills):
    ctx, outposts, bases = hills
    terrain, k = ctx.terrain, ctx.scenario.curvature_coeff
    rows, cols = np.mgrid[0:N, 0:N]
    x, y = terrain.xy(rows.ravel(), cols.ravel())
    ground = _height(terrain, rows.ravel(), cols.ravel())
    # seen 2 m above the ground with a metre to spare: everything above is seen too
    exposed = np.array([_seen(terrain, outposts, a, b, g + 2.0, k, margin=1.0)
                        for a, b, g in zip(x, y, ground)]).reshape(N, N)
    assert exposed.sum() > 100     # the outpost's hill is a real test
    # more bases, packed closer, than the fixture's: the candidates near the hill too
    packed = suggest_bases(ctx, count=12, separation_m=0.0, spacing_m=30.0)
    for b in bases + packed:
        row, col = (int(v) for v in np.rint(terrain.rowcol(b.x, b.y)))
        assert not exposed[row, col], f"base at cell {row},{col} is seen"
    # and an exposed cell is refused by the planner's launch check itself
    row, col = np.argwhere(exposed)[0]
    lon, lat = terrain.to_lonlat(*terrain.xy(row, col))
    trial = replace(ctx, scenario=replace(ctx.scenario, launch=[(float(lat), float(lon))]))
    with pytest.raises(InputError, match="launch point"):
        launch_starts(trial)


def test_bound_matches_a_dense_recomputation_and_a_plan_from_the_best_base(hills):
    ctx, _, bases = hills
    s = ctx.scenario
    vis = ctx.visibility
    dense = np.zeros((len(vis.indptr) - 1, vis.n_targets), bool)
    for e in range(len(vis.indptr) - 1):
        dense[e, vis.indices[vis.indptr[e]:vis.indptr[e + 1]]] = True
    for b in bases:
        start = launch_starts(replace(ctx, scenario=replace(s, launch=[(b.lat, b.lon)])))[0]
        out = coverage_problem(ctx, 1, [start]).launch_out[0]
        arrive = np.min(out[:, None] + ctx.travel, axis=0)  # also via other viewpoints
        first = np.where(dense, arrive[:, None], np.inf).min(axis=0)   # k = 0: one sighting
        assert b.bound_s == pytest.approx(first[dense.any(axis=0)].max(), rel=1e-9)
    best = bases[0]
    outcome = allocate(ctx, s.uavs, launch_starts(
        replace(ctx, scenario=replace(s, launch=[(best.lat, best.lon)]))), strong_bound=False)
    assert outcome.plan.metrics["coverage_time_s"] >= best.bound_s - 1e-6
    # the plan's own bound (the larger of the reach and packing bounds) is at least it
    assert outcome.plan.metrics["radius_bound_s"] >= best.bound_s * (1 - 1e-6)


# --- the command ------------------------------------------------------------------------

def test_gcs_bases_on_the_sample_then_gcs_plan_from_the_best(tmp_path, capsys):
    out = tmp_path / "bases"
    assert main(["bases", "--sample", "--area", AREA, "--uavs", "2", "--count", "3",
                 "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    best = printed.split("best: --launch ")[1].split()[0]
    features = json.loads((out / "bases.geojson").read_text())["features"]
    assert [f["properties"]["rank"] for f in features] == list(range(1, len(features) + 1))
    assert features[0]["properties"]["launch"] == best
    minutes = [f["properties"]["bound_min"] for f in features]
    assert minutes == sorted(minutes)
    for f in features:   # one table row per base, as in the file
        p = f["properties"]
        assert f"{p['rank']:>4}  {p['launch']}" in printed
    assert "<Placemark>" in (out / "bases.kml").read_text()
    assert (out / "bases.png").read_bytes()[:4] == b"\x89PNG"
    assert main(["plan", "--sample", "--area", AREA, "--uavs", "2", "--method", "rt",
                 "--launch", best, "-o", str(tmp_path / "plan")]) == 0
    plan = json.loads((tmp_path / "plan" / "plan.json").read_text())
    assert plan["metrics"]["lower_bound_s"] >= 60 * minutes[0] - 1.0   # rounded to 0.01 min


def test_on_a_battery_a_plan_from_the_best_base_reaches_what_gcs_bases_says(tmp_path,
                                                                            capsys):
    """`gcs bases --endurance` suggests a base inside the area; `gcs plan` from it
    (its --launch as printed, the same options) plans at least the ground the
    table says it reaches, in km² of the plan's own area breakdown."""
    out, options = tmp_path / "bases", ["--sample", "--area", AREA, "--uavs", "2",
                                        "--endurance", "6"]
    assert main(["bases", *options, "--count", "2", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    best = printed.split("best: --launch ")[1].split()[0]
    said = json.loads((out / "bases.geojson").read_text())["features"][0]["properties"]
    assert said["launch"] == best and 0.0 < said["reach_pct"] < 100.0
    s, w, n, e = (float(v) for v in AREA.split(","))
    assert s <= said["lat"] <= n and w <= said["lon"] <= e
    assert main(["plan", *options, "--method", "rt", "--launch", best,
                 "-o", str(tmp_path / "plan")]) == 0
    area = json.loads((tmp_path / "plan" / "plan.json").read_text())["metrics"]["area"]
    assert area["planned"]["km2"] >= said["reach_km2"] - 1e-3


@pytest.mark.parametrize("argv, names", [
    (["--dem", "no-such.tif", "--no-outposts"], "no-such.tif"),
    (["--sample", "--count", "0"], "--count"),
    (["--sample", "--launch", "36.58,-84.25"], "--launch"),
    (["--sample", "--base-spacing", "-5"], "--base-spacing"),
    (["--sample", "--outposts", "missing.geojson"], "missing.geojson"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, argv, names):
    out = tmp_path / "out"
    assert main(["bases", *argv, "-o", str(out)]) == 2
    # progress lines ("... loading terrain") may come first; the error is one line
    err = [line for line in capsys.readouterr().err.strip().splitlines()
           if not line.startswith("... ")]
    assert len(err) == 1 and err[0].startswith("gcs bases: error: ") and names in err[0]
    assert not out.exists()


def test_no_point_passing_is_one_clear_error(hills, monkeypatch):
    import planner.bases

    ctx, _, _ = hills
    monkeypatch.setattr(planner.bases, "checked_start", lambda *args: None)
    with pytest.raises(InputError, match="no ground point passes the launch checks"):
        suggest_bases(ctx, count=2)


def _on_a_battery(endurance_min):
    """The planning context of the tests' hills for 2 UAVs on an ``endurance_min``
    battery, without a launch point (an endurance needs one to validate; the bases
    tried stand in for it)."""
    terrain = synthetic_terrain(N, N, cell=30.0, seed=3, family="hills")
    scenario = Scenario(sample=True, uavs=2, sensor_range_m=500.0, ceiling_agl_m=150.0,
                        clearance_m=20.0, hide_margin_m=5.0, method="rt",
                        endurance_min=endurance_min, launch=[(0.0, 0.0)]).validate()
    return prepare(replace(scenario, launch=[]), terrain=terrain,
                   outposts=[central_outpost(terrain)])


def test_sets_of_bases_reach_what_a_plan_from_them_sees():
    """On a 3-min battery one base reaches about half the ground; a second adds
    more. A plan from a set's bases (the UAVs taking them in turn) sees exactly the
    ground the set is said to reach: the judge is the planner's plan, target for
    target. (With the travel times alone a base was said to reach 1.11 km² and
    plans saw 0.95: their far sorties, as flown, outlasted the battery.)"""
    from planner.bases import suggest_sets

    ctx = _on_a_battery(3.0)
    bases = suggest_bases(ctx, count=4, separation_m=SEPARATION, spacing_m=90.0)
    sets = suggest_sets(ctx, bases)
    assert len(sets) == 2 and sets[1].bases[0] is sets[0].bases[0]
    assert 0.0 < sets[0].reach_pct < sets[1].reach_pct < 100.0
    cell_km2 = ctx.terrain.cell_size ** 2 / 1e6
    alone = [int(b.reach.sum()) for b in bases]
    assert sets[0].reach_km2 == pytest.approx(max(alone) * cell_km2, abs=1e-3)
    # on a battery the ranking is by that reach first (a bound over little ground is
    # small: ranked by it alone, a base reaching none came first), then by the bound;
    # the best base is the first set's
    assert [b.reach_km2 for b in bases] == pytest.approx([n * cell_km2 for n in alone],
                                                         abs=1e-3)
    assert alone == sorted(alone, reverse=True)
    for a, b in zip(bases, bases[1:]):
        assert alone[a.rank - 1] > alone[b.rank - 1] or a.bound_s <= b.bound_s
    assert sets[0].bases == [bases[0]]
    for s in sets:
        launch = [(b.lat, b.lon) for b in s.bases]
        trial = replace(ctx, scenario=replace(ctx.scenario, launch=launch))
        outcome = allocate(trial, 2, launch_starts(trial), strong_bound=False)
        seen = np.logical_or.reduce([b.reach for b in s.bases])
        assert np.array_equal(outcome.counts >= 1, seen)
        assert (outcome.counts >= 1).sum() * cell_km2 == pytest.approx(s.reach_km2, abs=1e-3)
    # the console's tables: one row per base with its reach, one per set, each
    # --launch as gcs plan takes it
    from gcs.cli.bases import bases_table, sets_table

    table = bases_table(bases, 2, 3.0).splitlines()
    assert "on one 3-min battery" in table[0] and "reach km²" in table[1]
    for b, row in zip(bases, table[2:], strict=False):
        rank, launch, _, _, km2, pct, bound = row.split()
        assert (int(rank), launch, float(km2), float(pct), float(bound)) == \
            (b.rank, b.launch_arg, round(b.reach_km2, 2), b.reach_pct, round(b.bound_s / 60, 1))
    assert table[-1] == f"best: --launch {bases[0].launch_arg}"

    rows = sets_table(sets, 3.0).splitlines()[2:]
    for s, row in zip(sets, rows, strict=True):
        n, km2, pct, _, *launch = row.split()
        assert (int(n), float(km2), float(pct)) == (len(s.bases), round(s.reach_km2, 2),
                                                    s.reach_pct)
        assert launch == [b.launch_arg for b in s.bases]


@pytest.mark.parametrize("endurance", [None, 3.0])
def test_bases_stand_in_the_area_of_operations(tmp_path, endurance):
    """With an --area-file polygon over the hills' eastern part, every base stands in
    it (by matplotlib's point-in-polygon on the file's own ring), on a battery too:
    the best bound had a base ranked among them 10 cells west of it."""
    from matplotlib.path import Path as Polygon

    terrain = synthetic_terrain(N, N, cell=30.0, seed=3, family="hills")
    ring = [[float(v) for v in terrain.to_lonlat(*terrain.xy(r, c))]
            for r, c in ((2, 32), (2, 57), (57, 57), (57, 32), (2, 32))]
    area = tmp_path / "east.geojson"
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    scenario = Scenario(sample=True, uavs=2, sensor_range_m=500.0, ceiling_agl_m=150.0,
                        clearance_m=20.0, hide_margin_m=5.0, method="rt",
                        area_file=str(area), endurance_min=endurance,
                        launch=[(0.0, 0.0)]).validate()    # stands in for the bases tried
    ctx = prepare(replace(scenario, launch=[]), terrain=terrain,
                  outposts=[central_outpost(terrain)])
    bases = suggest_bases(ctx, count=4, separation_m=SEPARATION, spacing_m=90.0)
    assert len(bases) >= 2
    polygon = Polygon(ring)
    for b in bases:
        assert b.inside and polygon.contains_point((b.lon, b.lat)), b.launch_arg
        assert endurance is None or b.reach_km2 > 0


def test_on_a_battery_that_reaches_nothing_no_base_is_suggested():
    """A battery too short for any sortie to see a target: one line naming
    --endurance, not bases whose bound over no ground reads 0.0 min."""
    ctx = _on_a_battery(0.5)
    with pytest.raises(InputError, match="no base found reaches a target on one battery") as e:
        suggest_bases(ctx, count=4, separation_m=SEPARATION, spacing_m=90.0)
    assert e.value.source == "--endurance"
