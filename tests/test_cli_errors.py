"""Bad input at the command line: one clear line, exit status 2, nothing half-written."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from gcs.cli import main


def _run(capsys, *argv):
    status = main(list(argv))
    return status, capsys.readouterr().err


def _geotiff(path, height, crs="EPSG:32616", nodata=None):
    profile = dict(driver="GTiff", width=height.shape[1], height=height.shape[0], count=1,
                   dtype="float32", transform=from_origin(500000, 4000000, 30, 30), nodata=nodata)
    if crs:
        profile["crs"] = crs
    with rasterio.open(path, "w", **profile) as ds:
        ds.write(height.astype(np.float32), 1)
    return path


def _outposts(path, lon, lat):
    path.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": "North post"},
         "geometry": {"type": "Point", "coordinates": [lon, lat]}}]}))
    return path


def _assert_clean_failure(status, err, out_dir, *phrases):
    assert status == 2
    lines = err.strip().splitlines()
    assert lines and lines[-1].startswith("gcs plan: error: ")
    for phrase in phrases:
        assert phrase in lines[-1]
    assert not out_dir.exists() or not any(out_dir.iterdir())


def test_missing_dem(tmp_path, capsys):
    out = tmp_path / "out"
    status, err = _run(capsys, "plan", "--dem", str(tmp_path / "nope.tif"), "--no-outposts",
                       "-o", str(out))
    _assert_clean_failure(status, err, out, "nope.tif", "no such file")


def test_dem_without_crs(tmp_path, capsys):
    dem = _geotiff(tmp_path / "nocrs.tif", np.ones((20, 20)), crs=None)
    out = tmp_path / "out"
    status, err = _run(capsys, "plan", "--dem", str(dem), "--no-outposts", "-o", str(out))
    _assert_clean_failure(status, err, out, "nocrs.tif", "no CRS")


def test_all_nodata_dem(tmp_path, capsys):
    dem = _geotiff(tmp_path / "void.tif", np.full((20, 20), -9999.0), nodata=-9999.0)
    out = tmp_path / "out"
    status, err = _run(capsys, "plan", "--dem", str(dem), "--no-outposts", "-o", str(out))
    _assert_clean_failure(status, err, out, "void.tif", "nodata")


def test_outpost_outside_the_dem(tmp_path, capsys):
    posts = _outposts(tmp_path / "posts.geojson", 10.0, 50.0)
    out = tmp_path / "out"
    status, err = _run(capsys, "plan", "--sample", "--outposts", str(posts), "-o", str(out))
    _assert_clean_failure(status, err, out, "posts.geojson", "North post", "outside the DEM")


def test_no_flyable_cell_on_flat_ground(tmp_path, capsys):
    dem = _geotiff(tmp_path / "flat.tif", np.full((40, 40), 100.0))
    posts = _outposts(tmp_path / "posts.geojson", *_lonlat_of_centre(dem))
    out = tmp_path / "out"
    status, err = _run(capsys, "plan", "--dem", str(dem), "--outposts", str(posts),
                       "-o", str(out))
    _assert_clean_failure(status, err, out, "no flyable")


def test_exposed_launch_point(tmp_path, capsys):
    out = tmp_path / "out"
    # the summit of Pine Mountain's neighbour, in full view of the built-in posts
    status, err = _run(capsys, "plan", "--sample", "--area", "36.49,-84.28,36.56,-84.18",
                       "--launch", "36.5235,-84.2553", "-o", str(out))
    _assert_clean_failure(status, err, out, "launch point 1", "not in a flyable hidden region")


def test_k_not_below_the_number_of_uavs(tmp_path, capsys):
    out = tmp_path / "out"
    status, err = _run(capsys, "plan", "--sample", "--uavs", "3", "--k", "3", "-o", str(out))
    _assert_clean_failure(status, err, out, "k = 3", "uavs = 3")


def test_negative_track_tolerance(tmp_path, capsys):
    out = tmp_path / "out"
    status, err = _run(capsys, "plan", "--sample", "--track-tolerance", "-1", "-o", str(out))
    _assert_clean_failure(status, err, out, "track_tolerance_m must not be negative")


def test_a_scheduler_address_nobody_answers_at(tmp_path, capsys):
    import dask
    import distributed  # noqa: F401

    # distributed adds its config defaults when first imported: imported inside
    # dask.config.set, they would be dropped on leaving it (later clusters fail)
    out = tmp_path / "out"
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        status, err = _run(capsys, "plan", "--sample", "--uavs", "2", "--scheduler",
                           "tcp://127.0.0.1:1", "-o", str(out))
    _assert_clean_failure(status, err, out, "--scheduler", "no dask scheduler answers at "
                                                           "tcp://127.0.0.1:1")
    assert "Traceback" not in err


def test_refused_plan_leaves_an_existing_directory_as_it_was(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "plan.json").write_text("old")
    status, err = _run(capsys, "plan", "--sample", "--uavs", "2", "--k", "2", "-o", str(out))
    assert status == 2
    assert [p.name for p in out.iterdir()] == ["plan.json"]
    assert (out / "plan.json").read_text() == "old"


def _lonlat_of_centre(dem):
    from pyproj import Transformer

    lon, lat = Transformer.from_crs("EPSG:32616", "EPSG:4326", always_xy=True).transform(
        500000 + 20 * 30, 4000000 - 20 * 30)
    return lon, lat


@pytest.mark.parametrize("argv", [["--help"], ["plan", "--help"], ["sim", "--help"]])
def test_help_exits_zero(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 0
    assert "usage: gcs" in capsys.readouterr().out


def test_output_that_is_a_file_is_refused_before_any_work(tmp_path, capsys):
    out = tmp_path / "out.tif"
    out.write_bytes(b"mine")
    status, err = _run(capsys, "plan", "--dem", str(tmp_path / "nope.tif"), "--no-outposts",
                       "-o", str(out))
    assert status == 2 and err.strip().splitlines()[-1] == \
        f"gcs plan: error: -o: {out} is a file, not a folder"  # not the DEM: checked first
    assert out.read_bytes() == b"mine"


def test_southern_and_western_coordinates_are_taken_as_typed():
    from gcs.cli import build_parser

    parser = build_parser()
    args = parser.parse_args(["plan", "--sample", "--launch", "-35.3,149.1", "-35.2,-58.4",
                              "--area", "-35.4,-58.5,-35.1,149.2", "-o", "x"])
    assert args.launch == ["-35.3,149.1", "-35.2,-58.4"] and args.area == "-35.4,-58.5,-35.1,149.2"
    assert parser.parse_args(["sim", "--home", "-35.363261,149.165230,584"]).home == \
        "-35.363261,149.165230,584"


def test_warnings_are_one_line_in_the_users_words(tmp_path, capsys):
    """A cropped sample leaves out the outposts whose range ends short of it: one
    warning line each, no Python warning with its source line."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "vehicle-7.plan").write_text("{}")  # a former plan's vehicle: removed
    status, err = _run(capsys, "plan", "--sample", "--area", "36.49,-84.28,36.56,-84.18",
                       "--uavs", "2", "--viewpoint-spacing", "600", "-o", str(out))
    assert status == 0, err
    warnings = [line for line in err.splitlines() if "warning:" in line.lower()]
    assert warnings == [
        "gcs plan: warning: built-in sample_outposts.geojson: feature 1 (Pine Mountain) left "
        "out: 15.2 km from the area, beyond its 10 km range",
        "gcs plan: warning: built-in sample_outposts.geojson: feature 2 (West knob) left out: "
        "11.7 km from the area, beyond its 7 km range"]
    assert "UserWarning" not in err
    assert not (out / "vehicle-7.plan").exists() and (out / "vehicle-2.plan").exists()


# --- option errors come before the heavy imports ------------------------------------------------
#: what `python -m gcs` runs, then the heavy modules it loaded, on stdout (the
#: user's stdout is empty on an option error)
_PROBE = """
import json, runpy, sys
sys.argv[0] = "gcs"
try:
    runpy.run_module("gcs", run_name="__main__", alter_sys=True)
except SystemExit as exc:
    heavy = sorted(m for m in sys.modules if m.split(".")[0] in ("numba", "rasterio", "scipy")
                   or m.split(".")[:2] in (["planner", "pipeline"], ["planner", "terrain"],
                                           ["planner", "exposure"])
                   # the coverage methods' catalogue (--method's choices) is light by design
                   or m.startswith("planner.coverage.")
                   and not m.startswith("planner.coverage.methods"))
    print(json.dumps(heavy))
    raise
"""


def _gcs_in_a_fresh_process(*argv):
    """(exit status, stderr lines, heavy modules imported) of ``python -m gcs ARGV``."""
    done = subprocess.run([sys.executable, "-c", _PROBE, *argv], capture_output=True, text=True,
                          cwd=Path(__file__).resolve().parents[1], timeout=120)
    return done.returncode, done.stderr.strip().splitlines(), json.loads(done.stdout)


@pytest.mark.parametrize("command", ["exposure", "plan"])
@pytest.mark.parametrize("bad, message", [
    (["--ceiling-agl", "-5"], "gcs {}: error: options: ceiling_agl_m must be a positive number"),
    (["--clearance", "-1"], "gcs {}: error: options: clearance_m must not be negative"),
    (["--area", "1,2,0,3"], "gcs {}: error: --area: '1,2,0,3': need south < north"),
    (["--resolution", "-3"], "gcs {}: error: options: resolution_m must be a positive number"),
    (["--geoid-offset", "nan"], "gcs {}: error: options: geoid_offset_m must be a finite"),
], ids=["negative-ceiling", "negative-clearance", "empty-area", "negative-resolution",
        "nan-geoid-offset"])
def test_a_bad_option_value_is_one_line_before_any_heavy_import(tmp_path, command, bad,
                                                                 message):
    status, err, heavy = _gcs_in_a_fresh_process(command, "--sample", *bad,
                                                 "-o", str(tmp_path / "out"))
    assert status == 2 and len(err) == 1 and err[0].startswith(message.format(command)), err
    assert heavy == []
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("bad, message", [
    (["--bogus"], "unrecognized arguments: --bogus"),
    (["--k", "3"], "unrecognized arguments: --k"),  # a plan's option, not exposure's
    (["--ceiling-agl", "abc"], "argument --ceiling-agl: invalid float value: 'abc'"),
], ids=["unknown", "not-exposures", "not-a-number"])
def test_an_unknown_option_or_a_non_number_is_refused_before_any_heavy_import(tmp_path, bad,
                                                                              message):
    status, err, heavy = _gcs_in_a_fresh_process("exposure", "--sample", *bad,
                                                 "-o", str(tmp_path / "e.tif"))
    assert status == 2 and err[-1].startswith("gcs exposure: error: ") and message in err[-1]
    assert [line for line in err if "error" in line.lower()] == err[-1:]  # argparse's usage
    assert err[0].startswith("usage: gcs exposure")                       # above, no traceback
    assert heavy == []
    assert not (tmp_path / "e.tif").exists()


def test_the_probe_sees_heavy_imports(tmp_path):
    """The check above is not vacuous: an empty outposts file is the reader's to find,
    after the planner is imported."""
    posts = tmp_path / "posts.geojson"
    posts.write_text('{"type": "FeatureCollection", "features": []}')
    status, err, heavy = _gcs_in_a_fresh_process("exposure", "--sample", "--outposts",
                                                 str(posts), "-o", str(tmp_path / "e.tif"))
    assert status == 2 and err[-1].startswith(f"gcs exposure: error: {posts}: no outposts")
    assert "planner.pipeline" in heavy and "numba" in heavy
