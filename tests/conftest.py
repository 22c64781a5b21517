"""Shared fixtures: one small saved plan (synthetic hills, one outpost, 3 UAVs from
one launch point), planned once per session for the tests that fly or upload it;
and the numba kernels compiled before the first test (`pytest_sessionstart`)."""

import tempfile
from dataclasses import replace
from types import SimpleNamespace

import pytest
from hills import central_outpost
from saved_plan import copy_plan

from gcs.plan_folder import write_plan_folder
from planner.pipeline import allocate, launch_starts, plan_mission
from planner.plan import TERRAIN_FILE
from planner.scenario import Scenario
from planner.terrain import synthetic_terrain, write_terrain

N = 60


def _small_plan():
    """(scenario, terrain, outposts) of the shared plan."""
    terrain = synthetic_terrain(N, N, cell=30.0, seed=3, family="hills")
    outposts = [central_outpost(terrain)]
    llon, llat = terrain.to_lonlat(*terrain.xy(6, 6))
    # RT, not the default ALNS: its routes end at clearly different times, which the
    # flight tests use (a vehicle shot down once the others have landed). Climbs and
    # descents a little faster than ArduPilot's defaults (as its WPNAV_SPEED_UP / _DN
    # set so): the 145 m column costs less of the tests' short batteries
    scenario = Scenario(sample=True, uavs=3, sensor_range_m=500.0, ceiling_agl_m=150.0,
                        clearance_m=20.0, hide_margin_m=5.0, launch=[(llat, llon)],
                        method="rt", climb_mps=3.0, descent_mps=2.0).validate()
    return scenario, terrain, outposts


#: the files handed out first, in this order: pytest-xdist gives whole files to its test
#: processes in collection order (with --no-loadscope-reorder), each process its next
#: file as it runs out. The simulated flights' files (seconds of wall and CPU in a
#: full run on 2 cores, 2026-12-07) wait on their flights' clocks more than they
#: compute, so they go out beside the files that plan the most: with 4 test
#: processes two or three flights run while one process plans, and the 2 cores stay
#: busy (the flights first, all four at once, left 0.8 of a core idle for 5 minutes)
HANDED_OUT_FIRST = (
    "sitl_tests/test_end_to_end.py",        # flights: 382 s wall, 170 s CPU
    "tests/test_sorties_flown.py",          # flights: 312 s, 102 s
    "tests/test_sample.py",                 # plans: 172 s, 118 s
    "tests/test_failsafes.py",              # flights: 305 s, 71 s
    "tests/test_pipeline.py",               # plans: 165 s, 102 s
    "sitl_tests/test_separation.py",        # flights: 285 s, 54 s
    "tests/test_replan.py",                 # plans: 155 s, 101 s
    "tests/test_link_flight.py",            # flights: 245 s, 39 s
)


def pytest_collection_modifyitems(items):
    """`HANDED_OUT_FIRST`'s files first, the others in their order (a stable sort)."""
    rank = {path: i for i, path in enumerate(HANDED_OUT_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))


def pytest_sessionstart(session):
    """Compile the numba kernels into their cache once, before any test runs and
    before pytest-xdist starts its test processes (which then load them): from a
    fresh checkout, whichever test planned first in each process compiled them, a
    minute of a busy core counted against that test's timeout."""
    if hasattr(session.config, "workerinput"):
        return  # a test process of pytest-xdist: its controller has done it
    scenario, terrain, outposts = _small_plan()
    ctx, outcome = plan_mission(scenario, terrain=terrain, outposts=outposts)
    # the default method's kernels: they compile on the search's first moves, so a
    # second of search compiles them as a full budget would (the rest was 10-20 s of
    # the controller's before any test process started)
    quick = replace(ctx, scenario=replace(scenario, time_budget_s=1.0))
    allocate(quick, 3, launch_starts(ctx), method="alns")
    with tempfile.TemporaryDirectory() as folder:
        write_plan_folder(folder, ctx, outcome)  # the mission files and their proofs


@pytest.fixture(scope="session")
def planned(tmp_path_factory):
    """The plan, saved with its terrain.tif: ``dir``, ``plan``, ``ctx`` (its planning
    context), ``terrain``, ``launch`` (lat, lon, ground m AMSL)."""
    scenario, terrain, outposts = _small_plan()
    ctx, outcome = plan_mission(scenario, terrain=terrain, outposts=outposts)
    d = tmp_path_factory.mktemp("plan")
    outcome.plan.save(d)
    write_terrain(d / TERRAIN_FILE, terrain)
    ctx.save(d)
    launch = outcome.plan.vehicles[0].launch
    return SimpleNamespace(dir=d, plan=outcome.plan, ctx=ctx, terrain=terrain,
                           launch=(launch.lat, launch.lon, launch.alt_amsl))


@pytest.fixture
def plan_dir(planned):
    return planned.dir


@pytest.fixture
def plan_copy(planned, tmp_path):
    """The session plan copied (plan.json, terrain.tif) with its ArduPilot mission files."""
    from missions.export import export_plan_dir

    d = copy_plan(planned, tmp_path / "plan")
    export_plan_dir(d, planned.plan, "ardupilot", formats=("plan", "waypoints"))
    return d
