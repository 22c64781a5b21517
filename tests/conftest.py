"""Shared fixtures: one small saved plan (synthetic hills, one outpost, 3 UAVs from
one launch point), planned once per session for the tests that fly or upload it."""

from types import SimpleNamespace

import pytest

from planner.exposure import Outpost
from planner.pipeline import plan_mission
from planner.plan import TERRAIN_FILE
from planner.scenario import Scenario
from planner.terrain import synthetic_terrain, write_terrain

N = 60


@pytest.fixture(scope="session")
def planned(tmp_path_factory):
    """The plan, saved with its terrain.tif: ``dir``, ``plan``, ``ctx`` (its planning
    context), ``terrain``, ``launch`` (lat, lon, ground m AMSL)."""
    terrain = synthetic_terrain(N, N, cell=30.0, seed=3, family="hills")
    x, y = terrain.xy(N // 2, N // 2)
    lon, lat = terrain.to_lonlat(x, y)
    outposts = [Outpost(float(x), float(y), 2.0, 2500.0, float(lon), float(lat), "hill")]
    llon, llat = terrain.to_lonlat(*terrain.xy(6, 6))
    scenario = Scenario(sample=True, uavs=3, sensor_range_m=500.0, ceiling_agl_m=150.0,
                        clearance_m=20.0, hide_margin_m=5.0, launch=[(llat, llon)]).validate()
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
