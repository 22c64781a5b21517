"""planner.exposure.outposts: the GeoJSON reader, its errors, and the built-in sample set."""

import json
import math
import warnings

import numpy as np
import pytest

from common.errors import InputError
from planner.exposure import Outpost, load_outposts, outposts_to_geojson, sample_outposts
from planner.exposure.outposts import read_outpost_features, sample_outpost_features
from planner.terrain import sample_terrain, synthetic_terrain


@pytest.fixture(scope="module")
def terrain():
    t = synthetic_terrain(64, 64, 30.0, seed=1, family="hills")
    height = t.height.copy()
    height[10:20, 10:20] = np.nan  # a void
    return type(t)(height, t.transform, t.crs)


def lonlat(terrain, row, col):
    lon, lat = terrain.to_lonlat(*terrain.xy(row, col))
    return float(lon), float(lat)


def feature(coords, **props):
    return {"type": "Feature", "properties": props,
            "geometry": {"type": "Point", "coordinates": list(coords)}}


def write(tmp_path, features, name="posts.geojson"):
    path = tmp_path / name
    path.write_text(json.dumps({"type": "FeatureCollection", "features": features}))
    return path


def test_load_outposts_positions_defaults_and_names(tmp_path, terrain):
    a, b = lonlat(terrain, 40, 30), lonlat(terrain, 50.5, 5.25)
    path = write(tmp_path, [feature(a, name="hill", height_m=5, range_m=2500),
                            feature(b, range_m=None)])
    with pytest.warns(UserWarning, match=r"feature 1: no height_m: eye 2 m above ground"):
        posts = load_outposts(path, terrain)
    assert [p.name for p in posts] == ["hill", "O2"]
    assert posts[0].height_m == 5 and posts[0].range_m == 2500
    assert posts[1].height_m == 2.0 and math.isinf(posts[1].range_m)
    x, y = terrain.xy(np.array([40, 50.5]), np.array([30, 5.25]))
    np.testing.assert_allclose([p.x for p in posts], x, atol=1e-6)
    np.testing.assert_allclose([p.y for p in posts], y, atol=1e-6)
    assert (posts[0].lon, posts[0].lat) == a


def test_geojson_round_trip(tmp_path, terrain):
    posts = [Outpost(0, 0, 3.0, 4000.0, *lonlat(terrain, 30, 40), "a"),
             Outpost(0, 0, 2.0, math.inf, *lonlat(terrain, 5, 60), "b")]
    data = outposts_to_geojson(posts)
    assert data["features"][1]["properties"]["range_m"] is None
    back = load_outposts(write(tmp_path, data["features"]), terrain)
    assert [(p.name, p.height_m, p.range_m) for p in back] == [("a", 3.0, 4000.0),
                                                               ("b", 2.0, math.inf)]
    assert [(p.lon, p.lat) for p in back] == [(p.lon, p.lat) for p in posts]
    json.dumps(data)  # plain JSON types only


@pytest.mark.filterwarnings("ignore:.*no height_m:UserWarning")
def test_bad_outposts_name_the_file_and_the_feature(tmp_path, terrain):
    good = lonlat(terrain, 30, 30)
    outside = lonlat(terrain, -20, 30)
    void = lonlat(terrain, 15, 15)
    cases = [
        ([feature(good), feature(good, name="bad one", height_m=-1)],
         "feature 1 (bad one): height_m must be zero or more"),
        ([feature(good, height_m="tall")], "feature 0: height_m must be a finite number"),
        ([feature(good, height_m=True)], "feature 0: height_m must be a finite number"),
        ([feature(good, range_m=-5)], "feature 0: range_m must be positive"),
        ([feature(good, range_m=0)], "feature 0: range_m must be positive"),
        ([feature(good, range_m="far")], "feature 0: range_m must be a finite number"),
        ([{"type": "Feature", "properties": {"name": "line"},
           "geometry": {"type": "LineString", "coordinates": [good, good]}}],
         "feature 0 (line): geometry must be a Point, got LineString"),
        ([{"type": "Feature", "properties": {}, "geometry": None}],
         "geometry must be a Point, got none"),
        ([feature(["a", "b"])], "coordinates must be [lon, lat] numbers"),
        ([feature(outside, name="far")], "feature 0 (far): lon"),
        ([feature(void)], "on a void"),
        ([], "no outposts"),
    ]
    for i, (features, message) in enumerate(cases):
        path = write(tmp_path, features, f"case{i}.geojson")
        with pytest.raises(InputError) as err:
            load_outposts(path, terrain)
        assert str(err.value).startswith(f"{path}: ") and message in str(err.value), err.value
    outside_msg = str(pytest.raises(InputError, load_outposts,
                                    write(tmp_path, [feature(outside)]), terrain).value)
    assert "outside the DEM" in outside_msg


def test_bad_outpost_files(tmp_path, terrain):
    notjson = tmp_path / "notjson.geojson"
    notjson.write_text("{oops")
    point = tmp_path / "point.geojson"
    point.write_text(json.dumps(feature(lonlat(terrain, 3, 3))))
    for path, message in [(tmp_path / "missing.geojson", "no such file"),
                          (notjson, "not JSON"), (point, "not a GeoJSON FeatureCollection")]:
        with pytest.raises(InputError, match="not JSON|no such file|FeatureCollection") as err:
            load_outposts(path, terrain)
        assert str(err.value).startswith(str(path)) and message in str(err.value)


def test_sample_outposts_stand_on_high_ground_of_the_sample():
    terrain = sample_terrain()
    posts = sample_outposts(terrain)
    assert 3 <= len(posts) <= 5
    ground = terrain.ground(np.array([p.x for p in posts]), np.array([p.y for p in posts]))
    # Plausible lookouts: every post in the top third of the sample's heights.
    assert (ground > np.nanpercentile(terrain.height, 67)).all()
    assert all(6000 <= p.range_m <= 10000 for p in posts)
    assert len({p.name for p in posts}) == len(posts)


# --- the default eye height is said, never silently taken --------------------------------------
def test_posts_without_height_are_named_in_one_warning_per_file(tmp_path):
    """An eye lower than the real one sees less than it does: the 2 m default is
    said, naming each post it was taken for (a missing range_m, unlimited, is not)."""
    path = write(tmp_path, [feature((-84.2, 36.5), name="North"),
                            feature((-84.1, 36.5), name="East", height_m=6),
                            feature((-84.0, 36.5), range_m=3000),
                            feature((-84.0, 36.6), name="Ridge", height_m=0)],
                 "outposts.geojson")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        features = read_outpost_features(path)
    assert [str(w.message) for w in caught] == [
        f"{path}: feature 0 (North), feature 2: no height_m: eye 2 m above ground assumed"]
    assert [f.height_m for f in features] == [2.0, 6.0, 2.0, 0.0]


def test_a_null_height_is_no_height(tmp_path):
    path = write(tmp_path, [feature((-84.2, 36.5), name="Hill post", height_m=None)])
    with pytest.warns(UserWarning) as caught:
        read_outpost_features(path)
    assert [str(w.message) for w in caught] == [
        f"{path}: feature 0 (Hill post): no height_m: eye 2 m above ground assumed"]


def test_no_warning_when_every_post_has_its_height(tmp_path):
    path = write(tmp_path, [feature((-84.2, 36.5), name="North", height_m=2),
                            feature((-84.1, 36.5), height_m=12.5)])  # no range_m: unlimited
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        features = read_outpost_features(path)
    assert [f.range_m for f in features] == [math.inf, math.inf]


def test_the_built_in_outposts_have_their_heights():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        features = sample_outpost_features()
    assert features and all(f.height_m > 0 for f in features)


def test_posts_outside_the_area_are_kept_or_left_out_and_either_is_said():
    """An area of operations with built-in posts outside it: each whose range
    reaches in is kept and said to be (the DEM is then read around it: the user
    sees why the terrain read grew), each whose range ends short is left out and
    said to be; the distances are to the area's nearest point (reference: the
    great-circle distance from each post to that box, by haversine)."""
    from planner.pipeline import outpost_features
    from planner.scenario import Scenario

    area = (36.55, -84.25, 36.62, -84.15)
    scenario = Scenario(sample=True, area=area).validate()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        kept = outpost_features(scenario)
    said = [str(w.message) for w in caught]

    def to_box(f):
        lat, lon = min(max(f.lat, area[0]), area[2]), min(max(f.lon, area[1]), area[3])
        p1, p2, dl = math.radians(f.lat), math.radians(lat), math.radians(lon - f.lon)
        h = math.sin((p2 - p1) / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
        return 2 * 6_371_008.8 * math.asin(math.sqrt(h))

    for f in sample_outpost_features():
        d = to_box(f)
        mine = [s for s in said if f.label in s]
        if d <= f.range_m:
            assert f in kept and len(mine) == (1 if d > 0 else 0), said
            if d > 0:
                assert f"kept: {d / 1000:.1f} km outside the area" in mine[0], mine
        else:
            assert f not in kept and len(mine) == 1 and "left out" in mine[0], said
    assert len(kept) == 3 and len(said) == 4
