"""The `Terrain`: a DEM on a square metric grid in the local UTM zone.

Heights are metres AMSL at cell centres, row 0 at the north edge. The terrain
*surface* between centres is the bilinear interpolation of the centres; every
line-of-sight test in the planner uses that surface.

When the working grid had to be resampled from the source DEM (a geographic
DEM, tiles in several CRSs, a chosen resolution) the terrain carries two
surfaces that bracket the source DEM's own bilinear surface everywhere:
``height``, nowhere above it, occludes sight lines (a lower terrain hides
less), and ``height_upper``, nowhere below it, is the ground for clearance and
for the outposts' eyes (a higher eye sees more). On a DEM kept on its own
lattice both are the source heights.

Grid coordinates used by the numba kernels: ``u`` = column, ``v`` = row, both
fractional, with the centre of cell (row r, col c) at (u, v) = (c, r).
"""

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Optional

import numpy as np
from affine import Affine
from pyproj import CRS, Transformer


@dataclass(frozen=True, eq=False)
class Terrain:
    height: np.ndarray  # float64 [row, col], metres AMSL; NaN = void that could not be filled
    transform: Affine  # rasterio convention: (col, row) of the upper-left corner -> (x, y)
    crs: str  # projected CRS of the grid, e.g. "EPSG:32616"
    source: str = ""  # where it came from, for messages
    meta: dict = field(default_factory=dict)  # e.g. {"filled_voids": 12}
    #: float64 [row, col]: upper bound of the source surface (None: ``height`` is exact)
    height_upper: Optional[np.ndarray] = None
    #: the source DEM's own surface, ``.ground(x, y)``, when the grid was resampled
    source_surface: Optional[object] = None

    def __post_init__(self):
        if abs(self.transform.a + self.transform.e) > 1e-9 * abs(self.transform.a):
            raise ValueError("Terrain grid must be square with north up")

    @property
    def cell_size(self) -> float:
        return float(self.transform.a)

    @property
    def shape(self) -> tuple:
        return self.height.shape

    @property
    def upper(self) -> np.ndarray:
        """The ground for clearance and eyes: nowhere below the source surface."""
        return self.height if self.height_upper is None else self.height_upper

    @property
    def valid(self) -> np.ndarray:
        return np.isfinite(self.height) & np.isfinite(self.upper)

    @cached_property
    def solid(self) -> np.ndarray:
        """Cells whose four patches (the 3 x 3 cells around) all have data: the
        surface is known all around their centre. Cells on the outer ring are
        not solid (the surface ends at their centre)."""
        valid = self.valid
        out = np.zeros_like(valid)
        if valid.shape[0] >= 3 and valid.shape[1] >= 3:
            core = np.ones((valid.shape[0] - 2, valid.shape[1] - 2), bool)
            for dr in range(3):
                for dc in range(3):
                    core &= valid[dr:dr + core.shape[0], dc:dc + core.shape[1]]
            out[1:-1, 1:-1] = core
        return out

    # --- grid <-> projected metres -------------------------------------------------
    def xy(self, row, col):
        """Projected (x, y) of cell centres (row, col may be fractional)."""
        x = self.transform.c + (np.asarray(col, float) + 0.5) * self.transform.a
        y = self.transform.f + (np.asarray(row, float) + 0.5) * self.transform.e
        return x, y

    def rowcol(self, x, y):
        """Fractional (row, col) in centre coordinates of projected (x, y)."""
        col = (np.asarray(x, float) - self.transform.c) / self.transform.a - 0.5
        row = (np.asarray(y, float) - self.transform.f) / self.transform.e - 0.5
        return row, col

    # --- projected metres <-> lon/lat ------------------------------------------------
    @cached_property
    def _to_lonlat(self) -> Transformer:
        return Transformer.from_crs(CRS.from_user_input(self.crs), "EPSG:4326", always_xy=True)

    @cached_property
    def _from_lonlat(self) -> Transformer:
        return Transformer.from_crs("EPSG:4326", CRS.from_user_input(self.crs), always_xy=True)

    def to_lonlat(self, x, y):
        return self._to_lonlat.transform(x, y)

    def from_lonlat(self, lon, lat):
        return self._from_lonlat.transform(lon, lat)

    def contains_xy(self, x, y) -> np.ndarray:
        row, col = self.rowcol(x, y)
        n_rows, n_cols = self.shape
        return (row >= 0) & (row <= n_rows - 1) & (col >= 0) & (col <= n_cols - 1)

    def swapped_inside(self, lon: float, lat: float) -> bool:
        """Whether the point (lon, lat) would lie on the grid with its two coordinates
        swapped: a LAT,LON given as LON,LAT, or the other way round."""
        if not (-90 <= lon <= 90 and -180 <= lat <= 180):
            return False
        return bool(self.contains_xy(*self.from_lonlat(lat, lon)))

    def exact_ground(self, x, y) -> np.ndarray:
        """The source DEM's own surface at projected (x, y) (m AMSL; NaN outside)."""
        if self.source_surface is not None:
            return self.source_surface.ground(np.atleast_1d(x), np.atleast_1d(y))
        return self.ground(x, y)

    def ground(self, x, y, upper=False) -> np.ndarray:
        """Bilinear terrain height (m AMSL) at projected (x, y); NaN outside or near
        voids. ``upper``: of the upper surface (clearance, eyes)."""
        row, col = self.rowcol(x, y)
        return bilinear(self.upper if upper else self.height, np.atleast_1d(row),
                        np.atleast_1d(col))

    def ground_at(self, x: float, y: float, upper=False) -> float:
        """`ground` at one point, as a float (`bilinear_at`)."""
        row, col = self.rowcol(x, y)
        return bilinear_at(self.upper if upper else self.height, float(row), float(col))


def bilinear_at(grid: np.ndarray, row: float, col: float) -> float:
    """`bilinear` at one point, in plain floats (the same operations, the same value):
    a simulated vehicle asks for its ground at every physics step, where numpy's
    per-call overhead on one point was most of the simulator's CPU."""
    n_rows, n_cols = grid.shape
    if not (0.0 <= row <= n_rows - 1 and 0.0 <= col <= n_cols - 1):
        return math.nan
    r0, c0 = min(int(row), max(n_rows - 2, 0)), min(int(col), max(n_cols - 2, 0))
    r1, c1 = min(r0 + 1, n_rows - 1), min(c0 + 1, n_cols - 1)
    fr, fc = min(max(row - r0, 0.0), 1.0), min(max(col - c0, 0.0), 1.0)
    at = grid.item
    top = at(r0, c0) * (1 - fc) + at(r0, c1) * fc
    bottom = at(r1, c0) * (1 - fc) + at(r1, c1) * fc
    return top * (1 - fr) + bottom * fr


def bilinear(grid: np.ndarray, row: np.ndarray, col: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of ``grid`` at fractional centre coordinates."""
    n_rows, n_cols = grid.shape
    row = np.asarray(row, float)
    col = np.asarray(col, float)
    inside = (row >= 0) & (row <= n_rows - 1) & (col >= 0) & (col <= n_cols - 1)
    r0 = np.clip(np.floor(row).astype(int), 0, max(n_rows - 2, 0))
    c0 = np.clip(np.floor(col).astype(int), 0, max(n_cols - 2, 0))
    r1 = np.minimum(r0 + 1, n_rows - 1)
    c1 = np.minimum(c0 + 1, n_cols - 1)
    fr = np.clip(row - r0, 0.0, 1.0)
    fc = np.clip(col - c0, 0.0, 1.0)
    top = grid[r0, c0] * (1 - fc) + grid[r0, c1] * fc
    bottom = grid[r1, c0] * (1 - fc) + grid[r1, c1] * fc
    out = top * (1 - fr) + bottom * fr
    return np.where(inside, out, np.nan)
