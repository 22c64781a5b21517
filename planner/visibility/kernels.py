"""numba kernels for the visibility sets (see planner/visibility.py).

Grid coordinates as in planner/exposure/los.py: ``u`` = column, ``v`` = row, cell
centre of (r, c) at (u, v) = (c, r). A viewpoint's candidate targets are the
cells of a precomputed disk of offsets around its nearest cell; each kernel
writes one byte per (viewpoint, offset) and the CSR is assembled afterwards
from those bytes (count pass, then fill pass), so no Python loop touches a
viewpoint or a cell.
"""

import math

import numpy as np
from numba import njit, prange

from planner.exposure.los import curvature_drop, next_patch, piece_max_slope


@njit(cache=True)
def sees_early_exit(h, cell, u0, v0, z0, u1, v1, z1, range_m, curv):
    """``los.sees`` with the same patch walk and arithmetic, stopping at the
    first patch that blocks the target: identical answers, less work."""
    n_rows, n_cols = h.shape
    d = cell * math.sqrt((u1 - u0) ** 2 + (v1 - v0) ** 2)
    if d > range_m:
        return False
    if d == 0.0:
        return True
    target = (z1 - curvature_drop(d, curv) - z0) / d + 1e-12
    t_end = max(0.0, 1.0 - 1e-3 / d)
    ue = u0 + t_end * (u1 - u0)
    ve = v0 + t_end * (v1 - v0)
    # from here on: planner.exposure.los.max_slope(h, cell, u0, v0, z0, ue, ve, 0, curv)
    du = ue - u0
    dv = ve - v0
    length_m = cell * math.sqrt(du * du + dv * dv)
    if length_m <= 0.0:
        return True
    t = 1e-12
    while t < 1.0:
        i, j, t_next = next_patch(u0, v0, du, dv, t, n_rows, n_cols)
        s = piece_max_slope(h, i, j, u0, v0, du, dv, t, t_next, z0, length_m, curv)
        if s > target:
            return False
        t = t_next
    return True


@njit(cache=True, inline="always")
def _off_nadir_ok(d, z0, z1, tan_max):
    """Off-nadir angle atan(d / (z0 - z1)) within the limit (tan_max < 0: no limit)."""
    if tan_max < 0.0:
        return True
    if d == 0.0:
        return z0 >= z1
    return z0 > z1 and d <= (z0 - z1) * tan_max


@njit(cache=True, parallel=True)
def visible_bytes_exact(h, centre_r, centre_c, vz, off_r, off_c, cell, range_m, curv,
                        target_height, tan_max):
    """out[k, o] = 1 when viewpoint k (above its cell centre) sees offset o (exact)."""
    n_rows, n_cols = h.shape
    n_vp = centre_r.shape[0]
    n_off = off_r.shape[0]
    out = np.zeros((n_vp, n_off), np.uint8)
    for k in prange(n_vp):
        u0 = float(centre_c[k])
        v0 = float(centre_r[k])
        for o in range(n_off):
            r = centre_r[k] + off_r[o]
            c = centre_c[k] + off_c[o]
            if r < 0 or r >= n_rows or c < 0 or c >= n_cols:
                continue
            g = h[r, c]
            if not math.isfinite(g):
                continue
            z1 = g + target_height
            d = cell * math.sqrt(float(off_r[o] ** 2 + off_c[o] ** 2))
            if d > range_m or not _off_nadir_ok(d, vz[k], z1, tan_max):
                continue
            if sees_early_exit(h, cell, u0, v0, vz[k], float(c), float(r), z1, range_m, curv):
                out[k, o] = 1
    return out


@njit(cache=True, parallel=True)
def row_counts(seen_bytes):
    n_vp, n_off = seen_bytes.shape
    counts = np.zeros(n_vp, np.int64)
    for k in prange(n_vp):
        s = 0
        for o in range(n_off):
            s += seen_bytes[k, o]
        counts[k] = s
    return counts


@njit(cache=True, parallel=True)
def fill_rows(seen_bytes, centre_r, centre_c, off_r, off_c, n_cols, indptr, flat):
    """CSR fill: row k gets the flat grid indices of the cells viewpoint k sees.

    Offsets run row-major, so each row comes out ascending."""
    n_vp, n_off = seen_bytes.shape
    for k in prange(n_vp):
        p = indptr[k]
        for o in range(n_off):
            if seen_bytes[k, o]:
                flat[p] = (centre_r[k] + off_r[o]) * n_cols + centre_c[k] + off_c[o]
                p += 1


@njit(cache=True)
def _row_blocks(indptr, n_blocks):
    """Row bounds of n_blocks consecutive blocks holding about equal nonzeros."""
    n_rows = indptr.shape[0] - 1
    bounds = np.empty(n_blocks + 1, np.int64)
    bounds[0] = 0
    r = 0
    for b in range(1, n_blocks):
        goal = indptr[n_rows] * b // n_blocks
        while r < n_rows and indptr[r] < goal:
            r += 1
        bounds[b] = r
    bounds[n_blocks] = n_rows
    return bounds


@njit(cache=True, parallel=True)
def transpose_csr(indptr, indices, n_cols, n_blocks):
    """CSC of a CSR pattern: per column, the rows in ascending order.

    A counting sort in parallel over n_blocks blocks of rows: each block counts
    its entries per column, a column's entries are laid out block after block
    (so rows ascend), then each block fills its own slots.
    """
    bounds = _row_blocks(indptr, n_blocks)
    start = np.zeros((n_blocks, n_cols), np.int64)
    for b in prange(n_blocks):
        for p in range(indptr[bounds[b]], indptr[bounds[b + 1]]):
            start[b, indices[p]] += 1
    col_ptr = np.zeros(n_cols + 1, np.int64)
    total = 0
    for j in range(n_cols):
        col_ptr[j] = total
        for b in range(n_blocks):
            count = start[b, j]
            start[b, j] = total
            total += count
    col_ptr[n_cols] = total
    rows = np.empty(indices.shape[0], np.int32)
    for b in prange(n_blocks):
        fill = start[b]
        for i in range(bounds[b], bounds[b + 1]):
            for p in range(indptr[i], indptr[i + 1]):
                j = indices[p]
                rows[fill[j]] = i
                fill[j] += 1
    return col_ptr, rows


@njit(cache=True)
def sweep_geometry(m, cell, range_m, curv):
    """Viewpoint-independent plan of the ring sweep over offsets within range + 1 cell.

    In sweep order (ring by ring outwards), for each offset (dr, dc): its
    position in the (2m+1)^2 square, the two ring k-1 cells its ray passes
    between and the interpolation weight of the second, the distance and
    curvature drop, the ray's end (the target minus its last millimetre, as
    planner.exposure.los.sees) and up to three pieces (relative patch, t range) of the
    ray between the ring k-1 crossing and that end.
    """
    side = 2 * m + 1
    n_max = side * side
    order_r = np.empty(n_max, np.int64)
    order_c = np.empty(n_max, np.int64)
    n = 0
    for k in range(0, m + 1):
        for dr in range(-k, k + 1):
            for dc in range(-k, k + 1):
                if max(abs(dr), abs(dc)) != k:
                    continue
                if cell * math.sqrt(float(dr * dr + dc * dc)) > range_m + cell * (1.0 - 1e-9):
                    continue
                order_r[n] = dr
                order_c[n] = dc
                n += 1
    pos = np.empty(n, np.int64)
    par_a = np.full(n, -1, np.int64)
    par_b = np.full(n, -1, np.int64)
    wb = np.zeros(n)
    dist = np.zeros(n)
    drop = np.zeros(n)
    du = np.zeros(n)
    dv = np.zeros(n)
    length = np.zeros(n)
    n_pieces = np.zeros(n, np.int64)
    piece_i = np.zeros((n, 3), np.int64)
    piece_j = np.zeros((n, 3), np.int64)
    piece_ta = np.zeros((n, 3))
    piece_tb = np.zeros((n, 3))
    for q in range(n):
        dr = order_r[q]
        dc = order_c[q]
        k = max(abs(dr), abs(dc))
        pos[q] = (dr + m) * side + dc + m
        if k == 0:
            continue
        d = cell * math.sqrt(float(dr * dr + dc * dc))
        dist[q] = d
        drop[q] = curvature_drop(d, curv)
        t_end = max(0.0, 1.0 - 1e-3 / d)
        du[q] = t_end * dc
        dv[q] = t_end * dr
        length[q] = cell * math.sqrt(du[q] ** 2 + dv[q] ** 2)
        t = 1e-12
        if k >= 2:
            if abs(dc) >= abs(dr):
                y = dr * (k - 1.0) / k
                j = (k - 1) if dc > 0 else -(k - 1)
                i0 = int(math.floor(y))
                wb[q] = y - i0
                par_a[q] = (i0 + m) * side + j + m
                par_b[q] = (i0 + 1 + m) * side + j + m if wb[q] > 0.0 else par_a[q]
            else:
                x = dc * (k - 1.0) / k
                i = (k - 1) if dr > 0 else -(k - 1)
                j0 = int(math.floor(x))
                wb[q] = x - j0
                par_a[q] = (i + m) * side + j0 + m
                par_b[q] = (i + m) * side + j0 + 1 + m if wb[q] > 0.0 else par_a[q]
            t = (k - 1.0) / k / t_end
        # the patch walk of planner.exposure.los.max_slope, relative to the viewpoint cell
        while t < 1.0 and n_pieces[q] < 3:
            um = (t + 1e-9) * du[q]
            vm = (t + 1e-9) * dv[q]
            i = int(math.floor(um))
            j = int(math.floor(vm))
            t_next = 1.0
            if du[q] > 0.0:
                t_next = min(t_next, (i + 1) / du[q])
            elif du[q] < 0.0:
                t_next = min(t_next, i / du[q])
            if dv[q] > 0.0:
                t_next = min(t_next, (j + 1) / dv[q])
            elif dv[q] < 0.0:
                t_next = min(t_next, j / dv[q])
            if t_next <= t:
                t_next = min(1.0, t + 1e-9)
            p = n_pieces[q]
            piece_i[q, p] = i
            piece_j[q, p] = j
            piece_ta[q, p] = t
            piece_tb[q, p] = t_next
            n_pieces[q] = p + 1
            t = t_next
    return (order_r[:n], order_c[:n], pos, par_a, par_b, wb, dist, drop, du, dv, length,
            n_pieces, piece_i, piece_j, piece_ta, piece_tb)


@njit(cache=True)
def _sweep_one(h, cell, r0, c0, z0, range_m, curv, target_height, tan_max, band_m, geo,
               slot, out_row, horizon):
    """Ring sweep from the viewpoint above cell (r0, c0), writing out_row[slot[pos]].

    horizon[pos] is the steepest apparent slope along the ray to that cell,
    excluding its last millimetre (as planner.exposure.los.sees). The part of the ray
    up to the ring k - 1 crossing is taken as the linear interpolation of the
    horizons of the two cells it passes between (XDraw's approximation); the
    rest, up to the target, is exact (planner.exposure.los patch by patch). A target
    blocked by that exact last piece is hidden for certain; otherwise, when
    its margin against the interpolated part is within ``band_m`` metres, the
    cell is decided by the exact test (sees_early_exit) instead.
    """
    (off_r, off_c, pos, par_a, par_b, wb, dist, drop, du, dv, length, n_pieces,
     piece_i, piece_j, piece_ta, piece_tb) = geo
    n_rows, n_cols = h.shape
    u0 = float(c0)
    v0 = float(r0)
    for q in range(off_r.shape[0]):
        r = r0 + off_r[q]
        c = c0 + off_c[q]
        if r < 0 or r >= n_rows or c < 0 or c >= n_cols:
            continue
        p = pos[q]
        o = slot[p]
        g = h[r, c]
        d = dist[q]
        if d == 0.0:
            horizon[p] = -np.inf
            if o >= 0 and math.isfinite(g) and _off_nadir_ok(0.0, z0, g + target_height,
                                                               tan_max):
                out_row[o] = 1
            continue
        local = -np.inf
        for k in range(n_pieces[q]):
            i = min(max(c0 + piece_i[q, k], 0), n_cols - 2)
            j = min(max(r0 + piece_j[q, k], 0), n_rows - 2)
            s = piece_max_slope(h, i, j, u0, v0, du[q], dv[q], piece_ta[q, k],
                                 piece_tb[q, k], z0, length[q], curv)
            if s > local:
                local = s
        approx = -np.inf
        if par_a[q] >= 0:
            approx = (1.0 - wb[q]) * horizon[par_a[q]] + wb[q] * horizon[par_b[q]]
        horizon[p] = max(approx, local)
        if o < 0 or not math.isfinite(g):
            continue
        z1 = g + target_height
        if not _off_nadir_ok(d, z0, z1, tan_max):
            continue
        target = (z1 - drop[q] - z0) / d + 1e-12
        if (local - target) * d > 1e-9:
            continue  # blocked by the exactly computed last piece
        if (local < target and math.isfinite(approx)
                and abs(target - approx) * d > band_m):
            if target >= approx:
                out_row[o] = 1
        elif sees_early_exit(h, cell, u0, v0, z0, float(c), float(r), z1, range_m, curv):
            out_row[o] = 1


@njit(cache=True, parallel=True)
def visible_bytes_sweep(h, centre_r, centre_c, vz, m, slot, n_off, cell, range_m, curv,
                        target_height, tan_max, band_m):
    """out[k, o] = 1 when viewpoint k (above its cell centre) sees offset o; ring sweep."""
    n_vp = centre_r.shape[0]
    out = np.zeros((n_vp, n_off), np.uint8)
    geo = sweep_geometry(m, cell, range_m, curv)
    side = 2 * m + 1
    for k in prange(n_vp):
        horizon = np.empty(side * side)
        _sweep_one(h, cell, centre_r[k], centre_c[k], vz[k], range_m, curv, target_height,
                   tan_max, band_m, geo, slot, out[k], horizon)
    return out


@njit(cache=True, parallel=True)
def flat_to_targets(flat, n_cells):
    """Target cells (ascending flat indices of every cell seen); ``flat`` is
    overwritten in place by each entry's target id (saves a copy of the largest array)."""
    seen = np.zeros(n_cells, np.uint8)
    for p in prange(flat.shape[0]):
        seen[flat[p]] = 1  # threads may write the same 1 twice: harmless
    target_of = np.empty(n_cells, np.int32)
    n = 0
    for f in range(n_cells):
        target_of[f] = n
        n += seen[f]
    cells = np.empty(n, np.int64)
    for f in prange(n_cells):
        if seen[f]:
            cells[target_of[f]] = f
    for p in prange(flat.shape[0]):
        flat[p] = target_of[flat[p]]
    return cells
