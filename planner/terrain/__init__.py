"""Stage 1, terrain: DEM files in, a `Terrain` (square metric grid) out.

Modules: grid (the `Terrain` model and its bilinear surface), dem (reading,
mosaicking, keeping or conservatively resampling the source lattice),
dem_kernels (the resampling bound), geotiff (working-grid GeoTIFFs),
synthetic (seeded test terrains).
"""

from .dem import load_dem, sample_terrain, utm_crs
from .geotiff import read_grid, read_terrain, write_grid, write_terrain
from .grid import Terrain, bilinear
from .synthetic import FAMILIES, synthetic_terrain

__all__ = ["FAMILIES", "Terrain", "bilinear", "load_dem", "read_grid", "read_terrain",
           "sample_terrain",
           "synthetic_terrain", "utm_crs", "write_grid", "write_terrain"]
