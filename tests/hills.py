"""The tests' usual watcher: one outpost on the central hill of a synthetic terrain."""

from planner.exposure import Outpost


def central_outpost(terrain) -> Outpost:
    """An observer 2 m above the centre cell, seeing 2.5 km, named "hill"."""
    rows, cols = terrain.shape
    x, y = terrain.xy(rows // 2, cols // 2)
    lon, lat = terrain.to_lonlat(x, y)
    return Outpost(float(x), float(y), 2.0, 2500.0, float(lon), float(lat), "hill")
