"""Bad input at the command line: one clear line, exit status 2, nothing half-written."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
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
    _assert_clean_failure(status, err, out, "--track-tolerance: must not be negative")


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
        "out: 15.1 km from the area, beyond its 10 km range",
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
    (["--ceiling-agl", "-5"], "gcs {}: error: --ceiling-agl: must be a positive number, got -5"),
    (["--clearance", "-1"], "gcs {}: error: --clearance: must not be negative, got -1"),
    (["--area", "1,2,0,3"], "gcs {}: error: --area: '1,2,0,3': need south < north"),
    (["--resolution", "-3"], "gcs {}: error: --resolution: must be a positive number"),
    (["--geoid-offset", "nan"], "gcs {}: error: --geoid-offset: must be a finite"),
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
    assert status == 2 and len(err) == 1, err  # no usage block above it, no traceback
    assert err[0].startswith("gcs exposure: error: ") and message in err[0]
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


# --- in the operator's words (issue 61) ---------------------------------------------------------
def _one_error_line(err, command="plan") -> str:
    """The one error line of ``err`` (stage lines may come before it), checked to be
    the only one and the last."""
    lines = err.strip().splitlines()
    assert [line for line in lines if "error" in line.lower()] == lines[-1:], err
    assert lines[-1].startswith(f"gcs {command}: error: "), err
    return lines[-1]


#: values no planner stage can use, per Scenario field (independent of the code's checks)
BAD_VALUES = {
    "uavs": [0, -2], "k": [-1, 4], "alpha": [1.5, -0.1], "beta": [2.0],
    "time_budget_s": [0, -1.0], "parts": [0], "ceiling_agl_m": [0, -5], "sensor_range_m": [0],
    "speed_mps": [0, -3], "accel_mps2": [0], "climb_mps": [0], "descent_mps": [-1],
    "takeoff_mps": [0], "land_mps": [0], "clearance_m": [-1], "hide_margin_m": [-0.5],
    "curvature_coeff": [-1], "track_tolerance_m": [-1], "separation_m": [-1, 5],
    "turnaround_min": [-1], "endurance_min": [0, -5], "reserve_pct": [95, -1],
    "resolution_m": [0, -3], "method": ["foo"], "visibility": ["medium"],
    "firmware": ["inav"], "land_at": ["there"], "z_unit": ["furlong"],
}
SECTION_OF = {"fleet": ("uavs", "speed_mps", "accel_mps2", "climb_mps", "descent_mps",
                        "takeoff_mps", "land_mps", "track_tolerance_m", "separation_m",
                        "turnaround_min", "endurance_min", "reserve_pct", "firmware", "land_at"),
              "method": ("k", "alpha", "beta", "time_budget_s", "parts", "method", "visibility"),
              "exposure": ("ceiling_agl_m", "clearance_m", "hide_margin_m", "curvature_coeff"),
              "sensor": ("sensor_range_m",), "terrain": ("resolution_m", "z_unit")}
#: the flags as `gcs plan --help` prints them, by field
FLAG_OF = {"uavs": "--uavs", "k": "--k", "alpha": "--alpha", "beta": "--beta",
           "time_budget_s": "--time-budget", "parts": "--parts", "ceiling_agl_m": "--ceiling-agl",
           "sensor_range_m": "--sensor-range", "speed_mps": "--speed", "accel_mps2": "--accel",
           "climb_mps": "--climb", "descent_mps": "--descent", "takeoff_mps": "--takeoff",
           "land_mps": "--land", "clearance_m": "--clearance", "hide_margin_m": "--hide-margin",
           "curvature_coeff": "--curvature-coeff", "track_tolerance_m": "--track-tolerance",
           "separation_m": "--separation", "turnaround_min": "--turnaround",
           "endurance_min": "--endurance", "reserve_pct": "--reserve",
           "resolution_m": "--resolution", "method": "--method", "visibility": "--visibility",
           "firmware": "--firmware", "land_at": "--land-at", "z_unit": "--z-unit"}


def test_the_flag_table_is_the_helps(capsys):
    """FLAG_OF above is what `gcs plan --help` shows for each field's option."""
    with pytest.raises(SystemExit):
        main(["plan", "--help"])
    shown = capsys.readouterr().out
    for flag in FLAG_OF.values():
        assert f"  {flag} " in shown, flag


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(pick=st.sampled_from([(f, v) for f, vs in BAD_VALUES.items() for v in vs]),
       from_file=st.booleans(), file_too=st.booleans())
def test_a_bad_value_is_named_as_the_user_gave_it(tmp_path_factory, capsys, pick, from_file,
                                                  file_too):
    """From the command line the message names the flag (a flag overrides the file's
    value); from a scenario file, the file and its [section] key; never the internal
    field name alone."""
    field, value = pick
    tmp = tmp_path_factory.mktemp("named")
    section = next(s for s, names in SECTION_OF.items() if field in names)
    toml = tmp / "s.toml"
    lines = ["[terrain]", "sample = true"]
    if from_file or file_too:  # the file holds the bad value, or a good one a flag overrides
        good = {"method": '"rt"', "visibility": '"hard"', "firmware": '"px4"',
                "land_at": '"own"', "z_unit": '"m"', "k": 0, "uavs": 4, "parts": 1}
        shown = json.dumps(value) if from_file else good.get(field, 1)
        lines += [f"[{section}]" if section != "terrain" else "", f"{field} = {shown}"]
    toml.write_text("\n".join(lines) + "\n")
    argv = ["plan", str(toml), "-o", str(tmp / "out")]
    if not from_file:
        argv += [FLAG_OF[field], str(value)]
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse's own refusal (a choice it does not offer)
        status = exc.code
    line = _one_error_line(capsys.readouterr().err)
    assert status == 2 and not (tmp / "out").exists()
    if from_file:
        assert line.startswith(f"gcs plan: error: {toml}: [{section}] {field} "), line
    elif field in ("method", "visibility", "firmware", "land_at", "z_unit"):
        assert line.startswith(f"gcs plan: error: argument {FLAG_OF[field]}: invalid choice")
    else:
        assert line.startswith(f"gcs plan: error: {FLAG_OF[field]}: "), line
        assert field not in line.replace(FLAG_OF[field], "") or field in ("k", "uavs"), line


def test_a_value_of_the_wrong_type_in_a_file_is_named_too(tmp_path, capsys):
    toml = tmp_path / "s.toml"
    toml.write_text('[terrain]\nsample = true\n[fleet]\nuavs = "four"\n')
    assert main(["plan", str(toml), "-o", str(tmp_path / "out")]) == 2
    assert _one_error_line(capsys.readouterr().err) == \
        f"gcs plan: error: {toml}: [fleet] uavs must be a whole number of at least 1, got 'four'"


@pytest.mark.parametrize("argv, line", [
    (["plan", "--sample", "--uav", "3"],
     "gcs plan: error: unrecognized arguments: --uav (did you mean --uavs?)"),
    (["plan", "--sample", "--endurace", "20"],
     "gcs plan: error: unrecognized arguments: --endurace (did you mean --endurance?)"),
    (["bases", "--sample", "--ceilng-agl", "90"],
     "gcs bases: error: unrecognized arguments: --ceilng-agl (did you mean --ceiling-agl?)"),
    (["plan", "--sample", "--uavs", "four"], "gcs plan: error: argument --uavs: invalid int "
                                             "value: 'four'"),
    (["plan", "--sample", "--z-unit", "yards"], "gcs plan: error: argument --z-unit: invalid "
                                                "choice: 'yards' (choose from 'm', 'ft', 'us-ft')"),
    (["plan", "--sample"], "gcs plan: error: the following arguments are required: -o/--output"),
    ([], "gcs: error: the following arguments are required: COMMAND (gcs --help lists them)"),
], ids=["misspelt", "misspelt-with-value", "other-command", "not-a-number", "not-a-choice",
        "missing", "no-command"])
def test_a_command_line_mistake_is_one_line_not_a_usage_block(tmp_path, capsys, argv, line):
    out = ["-o", str(tmp_path / "out")] if argv and argv[-1] != "--sample" else []
    with pytest.raises(SystemExit) as exc:
        main(argv + out)
    assert exc.value.code == 2
    assert capsys.readouterr().err.splitlines() == [line]
    assert not (tmp_path / "out").exists()


def test_a_launch_point_given_as_lon_lat_is_said_to_be_swapped(tmp_path, capsys):
    out = tmp_path / "out"
    status, err = _run(capsys, "plan", "--sample", "--area", "36.49,-84.28,36.56,-84.18",
                       "--uavs", "2", "--launch", "-84.2300,36.5200", "-o", str(out))
    _assert_clean_failure(status, err, out)
    assert _one_error_line(err) == (
        "gcs plan: error: --launch: launch point -84.230000,36.520000 is outside the DEM; as "
        "LON,LAT it would be inside: --launch takes LAT,LON")


def test_a_launch_point_outside_the_dem_either_way_gets_no_swap_hint(tmp_path, capsys):
    out = tmp_path / "out"
    status, err = _run(capsys, "plan", "--sample", "--area", "36.49,-84.28,36.56,-84.18",
                       "--uavs", "2", "--launch", "36.0,-85.0", "-o", str(out))
    _assert_clean_failure(status, err, out)
    assert _one_error_line(err) == ("gcs plan: error: --launch: launch point 36.000000,"
                                    "-85.000000 is outside the DEM")


def test_an_impossible_launch_pair_names_the_order(tmp_path, capsys):
    status, err = _run(capsys, "plan", "--sample", "--launch", "120.5,36.5", "-o",
                       str(tmp_path / "out"))
    assert status == 2 and err.strip().splitlines() == [
        "gcs plan: error: --launch: '120.5,36.5' is not a latitude,longitude pair (as LON,LAT "
        "it would be one): --launch takes LAT,LON"]


@pytest.mark.parametrize("area", [None, "36.49,-84.28,36.56,-84.18"], ids=["whole", "area"])
def test_an_outpost_given_as_lat_lon_is_said_to_be_swapped(tmp_path, capsys, area):
    """Without --area the post falls outside the DEM; with one it would have been
    left out as too far from the area (or the DEM read out to it)."""
    posts = tmp_path / "posts.geojson"
    posts.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": "Knob", "range_m": 5000},
         "geometry": {"type": "Point", "coordinates": [36.5235, -84.2553]}}]}))
    out = tmp_path / "out"
    status, err = _run(capsys, "plan", "--sample", "--outposts", str(posts),
                       *(["--area", area] if area else []), "-o", str(out))
    _assert_clean_failure(status, err, out)
    line = _one_error_line(err)
    assert line.startswith(f"gcs plan: error: {posts}: feature 0 (Knob): lon 36.523500, lat "
                           "-84.255300 is "), line
    assert line.endswith("as lat,lon it would be inside" + (" it" if area else "")
                         + ": GeoJSON coordinates are lon,lat"), line


@pytest.mark.parametrize("lines, line", [
    ('[fleet]\nlaunch = [["a", 1]]', "[fleet] launch must be [[lat, lon], ...] in degrees, got "
                                     "[['a', 1]]"),
    ('area = "north"', "[terrain] area must be [south, west, north, east] in degrees, got "
                       "'north'"),
])
def test_coordinates_that_are_no_numbers_in_a_file_are_one_line(tmp_path, capsys, lines, line):
    toml = tmp_path / "s.toml"
    toml.write_text(f"[terrain]\nsample = true\n{lines}\n")
    assert main(["plan", str(toml), "-o", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [f"gcs plan: error: {toml}: {line}"]
