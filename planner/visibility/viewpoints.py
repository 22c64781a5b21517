"""Candidate viewpoints: where a UAV may stop to take a snapshot.

Candidates are flyable cells of the fleet's region E_c on a square lattice,
each at the highest hidden altitude ``ceiling = E - hide_margin`` (it sees
the most). The default lattice spacing aims at about ``TARGET_CANDIDATES``
candidates over the region, clamped between one cell (finer is meaningless)
and a third of the sensor range (so every target is seen from several
candidates and the planner has choices).
"""

from dataclasses import dataclass

import numpy as np

from common.errors import InputError

TARGET_CANDIDATES = 3000
DEFAULT_SENSOR_RANGE_M = 1500.0


@dataclass(frozen=True, eq=False)
class Viewpoints:
    indices: np.ndarray  # int64 [n, 2]: (row, col) of the cell under each viewpoint
    xyz: np.ndarray  # float64 [n, 3]: projected x, y and altitude (m AMSL, = ceiling)
    region: np.ndarray  # int32 [n]: flyable region id of each viewpoint

    def __len__(self) -> int:
        return int(self.indices.shape[0])

    def subset(self, keep) -> "Viewpoints":
        return Viewpoints(self.indices[keep], self.xyz[keep], self.region[keep])


def default_spacing(surface, regions, sensor_range_m=DEFAULT_SENSOR_RANGE_M) -> float:
    """Lattice spacing (m) giving about TARGET_CANDIDATES candidates over ``regions``."""
    cell = surface.terrain.cell_size
    area = np.isin(surface.regions, regions).sum() * cell * cell
    spacing = np.sqrt(area / TARGET_CANDIDATES)
    return float(np.clip(spacing, cell, max(cell, sensor_range_m / 3.0)))


def candidate_viewpoints(surface, spacing_m=None, region=None,
                         sensor_range_m=DEFAULT_SENSOR_RANGE_M) -> Viewpoints:
    """Flyable cells of ``region`` (an id, a list of ids, or None = all) on a lattice.

    A region too small or thin to hold a lattice cell still gets one candidate:
    its cell with the highest ceiling above the floor.
    """
    regions = _region_ids(surface, region)
    if spacing_m is None:
        spacing_m = default_spacing(surface, regions, sensor_range_m)
    if not spacing_m > 0:
        raise InputError("spacing", f"viewpoint spacing must be positive, got {spacing_m}")
    cell = surface.terrain.cell_size
    stride = max(1, int(round(spacing_m / cell)))
    n_rows, n_cols = surface.regions.shape
    inside = np.isin(surface.regions, regions)
    lattice = np.zeros_like(inside)
    lattice[stride // 2::stride, stride // 2::stride] = True
    chosen = inside & lattice
    missing = np.setdiff1d(regions, np.unique(surface.regions[chosen]))
    if missing.size:
        chosen[_best_cells(surface, missing)] = True
    rows, cols = np.nonzero(chosen)
    return _make(surface, rows, cols)


def viewpoints_at(surface, rows, cols) -> Viewpoints:
    """Viewpoints above the given flyable cells (e.g. launch cells), at the ceiling."""
    rows = np.asarray(rows, np.int64)
    cols = np.asarray(cols, np.int64)
    if not surface.flyable[rows, cols].all():
        raise InputError("viewpoints", "a viewpoint cell is not flyable")
    return _make(surface, rows, cols)


def fleet_region(surface, launch_xy=None) -> tuple:
    """Region ids the fleet can reach: those holding the launch points, else the largest."""
    if launch_xy is None or len(launch_xy) == 0:
        counts = np.bincount(surface.regions.ravel())
        counts[0] = 0
        if counts.sum() == 0:
            raise InputError("exposure", "no flyable hidden region on this terrain")
        return (int(np.argmax(counts)),)
    return tuple(sorted({int(surface.regions[rc]) for rc in launch_cells(surface, launch_xy)}))


def launch_cells(surface, launch_xy) -> list:
    """(row, col) of the cell under each launch point; InputError if one is not flyable."""
    xy = np.asarray(launch_xy, float).reshape(-1, 2)
    row, col = surface.terrain.rowcol(xy[:, 0], xy[:, 1])
    n_rows, n_cols = surface.regions.shape
    cells = []
    for i, (r, c) in enumerate(zip(np.rint(row).astype(int), np.rint(col).astype(int))):
        if not (0 <= r < n_rows and 0 <= c < n_cols) or surface.regions[r, c] == 0:
            lon, lat = surface.terrain.to_lonlat(xy[i, 0], xy[i, 1])
            raise InputError("launch", f"launch point {i + 1} ({float(lat):.6f},{float(lon):.6f})"
                             " is not in a flyable hidden region (seen by an outpost, or no "
                             "room between clearance and the exposure surface)")
        cells.append((int(r), int(c)))
    return cells


def _region_ids(surface, region) -> np.ndarray:
    present = np.unique(surface.regions)
    present = present[present > 0]
    if region is None:
        ids = present
    else:
        ids = np.unique(np.atleast_1d(np.asarray(region, np.int64)))
        unknown = np.setdiff1d(ids, present)
        if unknown.size:
            raise InputError("region", f"no flyable region with id {int(unknown[0])}")
    if ids.size == 0:
        raise InputError("exposure", "no flyable hidden region on this terrain")
    return ids


def _best_cells(surface, region_ids):
    """For each region, its cell with the most room between floor and ceiling."""
    room = np.where(surface.regions > 0, surface.ceiling - surface.floor, -np.inf).ravel()
    labels = surface.regions.ravel()
    order = np.lexsort((-room, labels))  # by region, best room first
    first = order[np.searchsorted(labels[order], region_ids)]
    return np.unravel_index(first, surface.regions.shape)


def _make(surface, rows, cols) -> Viewpoints:
    x, y = surface.terrain.xy(rows, cols)
    z = surface.ceiling[rows, cols]
    return Viewpoints(indices=np.stack([rows, cols], axis=1).astype(np.int64),
                      xyz=np.stack([x, y, z], axis=1).astype(np.float64),
                      region=surface.regions[rows, cols].astype(np.int32))
