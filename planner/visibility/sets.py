"""Sensor model and visibility sets: which terrain cells each viewpoint sees.

A snapshot from viewpoint v sees terrain cell g when g's centre, raised by
``target_height_m`` above the ground, is within ``sensor_range_m`` horizontally,
the line of sight clears the bilinear terrain (planner.exposure.los, with the exposure
surface's curvature coefficient), and, if ``max_off_nadir_deg`` is set, the
angle between the downward vertical and the line of sight is within it.

The coverage target S_c is every valid cell some candidate sees. The sets are
stored both ways: CSR rows per viewpoint (what v sees) and CSC columns per
target (who sees g), target ids 0..n_targets-1 indexing ``target_cells``.
"""

import math
from dataclasses import dataclass

import numba
import numpy as np

from common.errors import InputError

from . import kernels as K

#: viewpoints per kernel call: bounds the byte buffer to about 64 MB
_BUFFER_BYTES = 64 * 2**20


@dataclass(frozen=True)
class SensorParams:
    sensor_range_m: float = 1500.0
    max_off_nadir_deg: float | None = None  # None: no limit
    target_height_m: float = 0.5

    def __post_init__(self):
        if not self.sensor_range_m > 0:
            raise InputError("sensor_range_m", f"must be positive, got {self.sensor_range_m}")
        if self.max_off_nadir_deg is not None and not 0 <= self.max_off_nadir_deg <= 90:
            raise InputError("max_off_nadir_deg",
                             f"must be within 0..90 degrees, got {self.max_off_nadir_deg}")

    @property
    def tan_off_nadir(self) -> float:
        """tan of the limit, or -1 for no limit (the kernels' convention)."""
        if self.max_off_nadir_deg is None or self.max_off_nadir_deg >= 90:
            return -1.0
        return math.tan(math.radians(self.max_off_nadir_deg))


@dataclass(frozen=True, eq=False)
class VisibilityMatrix:
    indptr: np.ndarray  # int64 [n_viewpoints + 1]: CSR row pointers
    indices: np.ndarray  # int32 [nnz]: target ids seen by each viewpoint, ascending
    target_indptr: np.ndarray  # int64 [n_targets + 1]: CSC column pointers
    target_viewpoints: np.ndarray  # int32 [nnz]: viewpoints seeing each target, ascending
    target_cells: np.ndarray  # int64 [n_targets]: flat grid index (row * n_cols + col)
    grid_shape: tuple

    @property
    def n_viewpoints(self) -> int:
        return self.indptr.shape[0] - 1

    @property
    def n_targets(self) -> int:
        return self.target_cells.shape[0]

    @property
    def nnz(self) -> int:
        return self.indices.shape[0]

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.indptr, self.indices, self.target_indptr,
                                      self.target_viewpoints, self.target_cells))

    def seen_by(self, viewpoint: int) -> np.ndarray:
        """Target ids viewpoint ``viewpoint`` sees."""
        return self.indices[self.indptr[viewpoint]:self.indptr[viewpoint + 1]]

    def seers(self, target: int) -> np.ndarray:
        """Viewpoint ids that see target ``target``."""
        return self.target_viewpoints[self.target_indptr[target]:self.target_indptr[target + 1]]

    def counts(self) -> np.ndarray:
        """V(e) for k = 0 with nothing seen yet: targets per viewpoint."""
        return np.diff(self.indptr)

    def to_scipy(self):
        """scipy.sparse.csr_matrix (bool) viewpoints x targets."""
        from scipy.sparse import csr_matrix
        data = np.ones(self.nnz, bool)
        return csr_matrix((data, self.indices, self.indptr),
                          shape=(self.n_viewpoints, self.n_targets))

    def target_rowcol(self):
        return np.unravel_index(self.target_cells, self.grid_shape)

    def restricted(self, cells: np.ndarray) -> "VisibilityMatrix":
        """The same sets with only the targets whose cell is True in ``cells`` (a bool
        grid, e.g. the area of operations' polygon); target ids are renumbered,
        viewpoints kept (one that sees none of them gains nothing)."""
        keep_t = np.asarray(cells, bool).ravel()[self.target_cells]
        new_id = (np.cumsum(keep_t) - 1).astype(np.int32)
        rows = np.repeat(np.arange(self.n_viewpoints), np.diff(self.indptr))
        keep = keep_t[self.indices]
        indptr = np.concatenate([[0], np.cumsum(np.bincount(
            rows[keep], minlength=self.n_viewpoints))]).astype(np.int64)
        t_counts = np.diff(self.target_indptr)
        columns = np.repeat(keep_t, t_counts)
        return VisibilityMatrix(
            indptr=indptr, indices=new_id[self.indices[keep]],
            target_indptr=np.concatenate([[0], np.cumsum(t_counts[keep_t])]).astype(np.int64),
            target_viewpoints=self.target_viewpoints[columns],
            target_cells=self.target_cells[keep_t], grid_shape=self.grid_shape)


def compute_visibility(surface, viewpoints, sensor=SensorParams(), method="sweep",
                       band_m=0.05) -> VisibilityMatrix:
    """Visibility sets of ``viewpoints`` (above their cells) over ``surface.terrain``.

    ``method="exact"`` runs planner.exposure.los per (viewpoint, cell), stopping at the
    first blocking patch; ``"sweep"`` (default) is a per-viewpoint ring sweep
    that hands to the exact test every cell whose margin against the
    interpolated horizon is under ``band_m`` metres (see
    visibility_kernels._sweep_one; with ``band_m=inf`` it is exact; its
    agreement at the default is measured in benchmarks/bench_visibility.py).
    """
    if method not in ("sweep", "exact"):
        raise InputError("method", f"unknown visibility method {method!r}")
    h = np.ascontiguousarray(surface.terrain.height, dtype=np.float64)
    n_rows, n_cols = h.shape
    rows = np.ascontiguousarray(viewpoints.indices[:, 0], np.int64)
    cols = np.ascontiguousarray(viewpoints.indices[:, 1], np.int64)
    vz = np.ascontiguousarray(viewpoints.xyz[:, 2], np.float64)
    m, off_r, off_c, slot = _disk(sensor.sensor_range_m, surface.terrain.cell_size,
                                  n_rows, n_cols)
    args = (surface.terrain.cell_size, sensor.sensor_range_m,
            float(surface.params.curvature_coeff), sensor.target_height_m,
            sensor.tan_off_nadir)

    def seen_bytes(a, b):
        """[b - a, n_offsets] bytes: viewpoint sees the cell at that offset."""
        if method == "exact":
            return K.visible_bytes_exact(h, rows[a:b], cols[a:b], vz[a:b], off_r, off_c, *args)
        return K.visible_bytes_sweep(h, rows[a:b], cols[a:b], vz[a:b], m, slot,
                                     off_r.shape[0], *args, band_m)

    # chunks of viewpoints bound the byte buffer's memory; each becomes CSR rows
    # of flat cell indices (offsets run row-major, so every row ascends)
    chunk = max(1, _BUFFER_BYTES // max(1, off_r.shape[0]))
    counts, flats = [np.zeros(0, np.int64)], [np.zeros(0, np.int32)]
    for a in range(0, rows.shape[0], chunk):
        b = min(a + chunk, rows.shape[0])
        buf = seen_bytes(a, b)
        counts.append(K.row_counts(buf))
        ptr = np.concatenate([[0], np.cumsum(counts[-1])])
        flats.append(np.empty(ptr[-1], np.int32))  # grids stay far below 2**31 cells
        K.fill_rows(buf, rows[a:b], cols[a:b], off_r, off_c, n_cols, ptr, flats[-1])
        del buf
    indptr = np.concatenate([[0], np.cumsum(np.concatenate(counts))]).astype(np.int64)
    indices = flats[1] if len(flats) == 2 else np.concatenate(flats)
    del flats
    target_cells = K.flat_to_targets(indices, n_rows * n_cols)  # indices: now target ids
    t_ptr, t_vp = K.transpose_csr(indptr, indices, target_cells.shape[0],
                                  min(numba.get_num_threads(), 8))
    return VisibilityMatrix(indptr=indptr, indices=indices, target_indptr=t_ptr,
                            target_viewpoints=t_vp, target_cells=target_cells,
                            grid_shape=(n_rows, n_cols))


def _disk(range_m, cell, n_rows, n_cols):
    """Offsets (dr, dc) within range, and a lookup from the (2m+1)^2 square to them."""
    m = int(min(math.floor(range_m / cell), max(n_rows, n_cols)))
    dr, dc = np.mgrid[-m:m + 1, -m:m + 1]
    inside = (dr * dr + dc * dc) * cell * cell <= range_m * range_m
    off_r = dr[inside].astype(np.int64)
    off_c = dc[inside].astype(np.int64)
    side = 2 * m + 1
    slot = np.full(side * side, -1, np.int64)
    slot[(off_r + m) * side + off_c + m] = np.arange(off_r.shape[0])
    return m, off_r, off_c, slot
