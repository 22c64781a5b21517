"""Scenarios the benchmarks share: a seeded synthetic terrain with one base near a
corner and one outpost at the centre (`benchmarks.bench_silence`,
`benchmarks.radio_models`)."""

from planner.exposure import Outpost
from planner.scenario import Scenario
from planner.terrain import synthetic_terrain


def synthetic_case(family, seed, side=160, method="alns") -> tuple:
    """(scenario, terrain, outposts): ``side`` x ``side`` cells of 30 m of the
    ``family`` terrain, 3 UAVs from a base an eighth of the side in from the
    south-west corner (an antenna on a 2 m mast there), an observer 2 m above the
    centre cell seeing 2.5 km."""
    terrain = synthetic_terrain(side, side, cell=30.0, seed=seed, family=family)
    x, y = terrain.xy(side // 2, side // 2)
    lon, lat = terrain.to_lonlat(x, y)
    outpost = Outpost(float(x), float(y), 2.0, 2500.0, float(lon), float(lat), "hill")
    base_lon, base_lat = terrain.to_lonlat(*terrain.xy(side // 8, side // 8))
    scenario = Scenario(sample=True, uavs=3, sensor_range_m=600.0, ceiling_agl_m=120.0,
                        clearance_m=20.0, hide_margin_m=5.0, viewpoint_spacing_m=300.0,
                        launch=[(base_lat, base_lon)], method=method).validate()
    return scenario, terrain, [outpost]
