"""numba kernels for the hidden travel graph (see planner/travel.py)."""

import math

import numpy as np
from numba import njit, prange

from planner.exposure.los import gap_range


@njit(cache=True)
def legs_gaps(h, ua, va, za, ub, vb, zb):
    """Lowest and highest height above the ground along each leg (few legs: serial);
    NaN for a leg over a void (unknown ground is neither clear nor under a cap)."""
    n = ua.shape[0]
    lo = np.empty(n)
    hi = np.empty(n)
    for k in range(n):
        lo[k], hi[k] = gap_range(h, ua[k], va[k], za[k], ub[k], vb[k], zb[k], False)
    return lo, hi


@njit(cache=True)
def _heap_push(heap_d, heap_n, size, d, node):
    i = size
    heap_d[i] = d
    heap_n[i] = node
    while i > 0:
        p = (i - 1) >> 1
        if heap_d[p] <= heap_d[i]:
            break
        heap_d[p], heap_d[i] = heap_d[i], heap_d[p]
        heap_n[p], heap_n[i] = heap_n[i], heap_n[p]
        i = p
    return size + 1


@njit(cache=True)
def _grow(heap_d, heap_n):
    """Twice the capacity, same content (a lazy-deletion heap may outgrow its guess)."""
    d = np.empty(2 * heap_d.shape[0])
    n = np.empty(2 * heap_n.shape[0], np.int64)
    d[:heap_d.shape[0]] = heap_d
    n[:heap_n.shape[0]] = heap_n
    return d, n


@njit(cache=True)
def _heap_pop(heap_d, heap_n, size):
    d = heap_d[0]
    node = heap_n[0]
    size -= 1
    heap_d[0] = heap_d[size]
    heap_n[0] = heap_n[size]
    i = 0
    while True:
        a = 2 * i + 1
        if a >= size:
            break
        b = a + 1
        if b < size and heap_d[b] < heap_d[a]:
            a = b
        if heap_d[i] <= heap_d[a]:
            break
        heap_d[a], heap_d[i] = heap_d[i], heap_d[a]
        heap_n[a], heap_n[i] = heap_n[i], heap_n[a]
        i = a
    return d, node, size


@njit(cache=True)
def _bounded_one(indptr, nbr, w, source, slot_of_node, n_slots, limit, dist, touched, heap_d,
                 heap_n, out_row):
    """Dijkstra from ``source`` up to time ``limit``; out_row[slot] = time to each slotted node.
    It stops once every slotted node is settled (a part's viewpoints among the
    whole area's: the rest of the graph is never searched).

    ``dist`` must be all +inf on entry and is restored before returning; the
    heap arrays are returned (they may have grown).
    """
    n_touched = 0
    settled = 0
    dist[source] = 0.0
    touched[n_touched] = source
    n_touched += 1
    size = _heap_push(heap_d, heap_n, 0, 0.0, source)
    while size > 0:
        d, u, size = _heap_pop(heap_d, heap_n, size)
        if d > dist[u]:
            continue
        s = slot_of_node[u]
        if s >= 0:
            out_row[s] = d
            settled += 1  # a node is settled once: equal times are never pushed twice
            if settled == n_slots:
                break
        for p in range(indptr[u], indptr[u + 1]):
            v = nbr[p]
            nd = d + w[p]
            if nd < dist[v] and nd <= limit:
                if dist[v] == np.inf:
                    touched[n_touched] = v
                    n_touched += 1
                dist[v] = nd
                if size == heap_d.shape[0]:
                    heap_d, heap_n = _grow(heap_d, heap_n)
                size = _heap_push(heap_d, heap_n, size, nd, v)
    for k in range(n_touched):
        dist[touched[k]] = np.inf
    return heap_d, heap_n


@njit(cache=True, parallel=True)
def bounded_times(indptr, nbr, w, sources, slot_of_node, n_slots, limit, n_chunks):
    """[n_sources, n_slots] shortest times (inf beyond ``limit``), one Dijkstra per source.

    Sources are split into ``n_chunks`` parallel chunks, each reusing its own
    work arrays (only the nodes a search touched are reset).
    """
    n_nodes = indptr.shape[0] - 1
    n_src = sources.shape[0]
    out = np.full((n_src, n_slots), np.inf)
    for ch in prange(n_chunks):
        dist = np.full(n_nodes, np.inf)
        touched = np.empty(n_nodes, np.int64)
        heap_d = np.empty(1024)
        heap_n = np.empty(1024, np.int64)
        for k in range(ch, n_src, n_chunks):
            heap_d, heap_n = _bounded_one(indptr, nbr, w, sources[k], slot_of_node, n_slots,
                                          limit, dist, touched, heap_d, heap_n, out[k])
    return out


@njit(cache=True, nogil=True)
def node_paths(indptr, nbr, w, node_xy, speed, sources, targets):
    """Nodes of a shortest path for each (source, target) pair, all in one array,
    and where each begins (``offsets``; an empty path: unreachable).

    A* per pair, stopped once its target is settled, guided by the horizontal
    distance to the target at full speed: no leg is faster (`leg_time`), so the
    guide never overestimates and every path found is a shortest one. A route's
    transit from and back to its launch crosses the whole area: plain Dijkstra
    settled most of the graph for each. The work arrays are reused and only the
    nodes a search touched are reset."""
    n_nodes = indptr.shape[0] - 1
    dist = np.full(n_nodes, np.inf)
    pred = np.full(n_nodes, -1, np.int64)
    touched = np.empty(1024, np.int64)
    heap_d = np.empty(1024)
    heap_n = np.empty(1024, np.int64)
    out = np.empty(1024, np.int64)
    offsets = np.zeros(len(sources) + 1, np.int64)
    for k in range(len(sources)):
        source, target = sources[k], targets[k]
        tx, ty = node_xy[target, 0], node_xy[target, 1]
        dist[source] = 0.0
        touched[0] = source
        n_touched = 1
        size = _heap_push(heap_d, heap_n, 0, 0.0, source)
        found = False
        while size > 0:
            f, u, size = _heap_pop(heap_d, heap_n, size)
            if f > dist[u] + _guide(node_xy, u, tx, ty, speed):
                continue  # a stale entry
            if u == target:
                found = True
                break
            for p in range(indptr[u], indptr[u + 1]):
                v = nbr[p]
                nd = dist[u] + w[p]
                if nd < dist[v]:
                    if dist[v] == np.inf:
                        if n_touched == touched.shape[0]:
                            touched = _grown(touched)
                        touched[n_touched] = v
                        n_touched += 1
                    dist[v] = nd
                    pred[v] = u
                    if size == heap_d.shape[0]:
                        heap_d, heap_n = _grow(heap_d, heap_n)
                    size = _heap_push(heap_d, heap_n, size, nd + _guide(node_xy, v, tx, ty,
                                                                        speed), v)
        n = offsets[k]
        if found:
            m = 1
            u = target
            while u != source:
                u = pred[u]
                m += 1
            while n + m > out.shape[0]:
                out = _grown(out)
            u = target
            for i in range(n + m - 1, n - 1, -1):
                out[i] = u
                u = pred[u]
            n += m
        offsets[k + 1] = n
        for i in range(n_touched):
            dist[touched[i]] = np.inf
            pred[touched[i]] = -1
    return out[:offsets[-1]].copy(), offsets


@njit(cache=True, inline="always")
def _guide(node_xy, u, tx, ty, speed):
    return math.hypot(node_xy[u, 0] - tx, node_xy[u, 1] - ty) / speed


@njit(cache=True)
def _grown(a):
    b = np.empty(2 * a.shape[0], a.dtype)
    b[:a.shape[0]] = a
    return b


@njit(cache=True)
def grid_neighbours(node_of_cell, node_region, half_offsets):
    """(src, dst) of node pairs at the given offsets in the same region, each pair once."""
    n_rows, n_cols = node_of_cell.shape
    n_off = half_offsets.shape[0]
    count = 0
    for pass_ in range(2):
        if pass_ == 1:  # node ids as int32: 127 M candidate pairs on a 4096² grid
            src = np.empty(count, np.int32)
            dst = np.empty(count, np.int32)
            count = 0
        for r in range(n_rows):
            for c in range(n_cols):
                a = node_of_cell[r, c]
                if a < 0:
                    continue
                for k in range(n_off):
                    rr = r + half_offsets[k, 0]
                    cc = c + half_offsets[k, 1]
                    if rr < 0 or rr >= n_rows or cc < 0 or cc >= n_cols:
                        continue
                    b = node_of_cell[rr, cc]
                    if b < 0 or node_region[a] != node_region[b]:
                        continue
                    if pass_ == 1:
                        src[count] = a
                        dst[count] = b
                    count += 1
    return src, dst


@njit(cache=True, parallel=True)
def grid_legs_within(h_clear, h, ceiling, node_rows, node_cols, node_z, src, dst, clearance,
                     agl_cap):
    """Legs between nodes (cell centres) that keep clearance above ``h_clear``, stay
    under the AGL cap above ``h`` and under the ``ceiling`` surface."""
    n = src.shape[0]
    out = np.empty(n, np.bool_)
    for k in prange(n):
        a = src[k]
        b = dst[k]
        ua, va, ub, vb = float(node_cols[a]), float(node_rows[a]), float(node_cols[b]), \
            float(node_rows[b])
        # NaN over a void: every comparison fails
        lo = gap_range(h_clear, ua, va, node_z[a], ub, vb, node_z[b], False)[0]
        out[k] = lo >= clearance and \
            gap_range(h, ua, va, node_z[a], ub, vb, node_z[b], False)[1] <= agl_cap + 1e-6 \
            and gap_range(ceiling, ua, va, node_z[a], ub, vb, node_z[b], False)[1] <= 1e-6
    return out


@njit(cache=True)
def directed_csr(n_nodes, src, dst, dipped, node_xyz, floor, speed, climb, descent):
    """CSR (indptr, indices, data, dipped) of the edges src->dst and dst->src
    (unsorted rows), data their times (`edge_time`; a dip edge flies level at the
    higher of its nodes' ``floor``); ``dipped`` per edge is carried along to both
    directions. Times are made here, edge by edge: as whole arrays they took
    several GB of temporaries on a 4096² area."""
    indptr = np.zeros(n_nodes + 1, np.int64)
    for k in range(src.shape[0]):
        indptr[src[k] + 1] += 1
        indptr[dst[k] + 1] += 1
    for i in range(n_nodes):
        indptr[i + 1] += indptr[i]
    fill = indptr[:-1].copy()
    indices = np.empty(indptr[-1], np.int32)  # as scipy's csr_matrix keeps them
    data = np.empty(indptr[-1])
    dips = np.empty(indptr[-1], np.bool_)
    for k in range(src.shape[0]):
        a = src[k]
        b = dst[k]
        za, zb = node_xyz[a, 2], node_xyz[b, 2]
        low = max(floor[a], floor[b]) if dipped[k] else min(za, zb)
        horiz = math.hypot(node_xyz[b, 0] - node_xyz[a, 0], node_xyz[b, 1] - node_xyz[a, 1])
        indices[fill[a]] = b
        data[fill[a]] = edge_time(horiz, za, low, zb, speed, climb, descent)
        dips[fill[a]] = dipped[k]
        fill[a] += 1
        indices[fill[b]] = a
        data[fill[b]] = edge_time(horiz, zb, low, za, speed, climb, descent)
        dips[fill[b]] = dipped[k]
        fill[b] += 1
    return indptr, indices, data, dips


@njit(cache=True)
def edge_time(horiz, z_from, z_low, z_to, speed, climb, descent):
    """Time of a vertical move z_from -> z_low, a level leg, and z_low -> z_to
    (z_low = min(z_from, z_to) makes it one straight leg's time); each straight
    part takes the slower of its horizontal and vertical motion (`leg_time`)."""
    if min(z_from, z_to) == z_low:
        return max(horiz / speed, _vertical(z_to - z_from, climb, descent))
    return (max(0.0, _vertical(z_low - z_from, climb, descent)) + horiz / speed
            + max(0.0, _vertical(z_to - z_low, climb, descent)))


@njit(cache=True)
def _vertical(dz, climb, descent):
    return dz / climb if dz > 0 else -dz / descent


@njit(cache=True, parallel=True)
def undominated_edges(local):
    """keep[i, j]: the finite local time i -> j is not matched by some i -> k -> j.

    Dropping every dominated edge leaves all shortest times unchanged (with
    positive times, by induction on the edge's time), and makes the overlay
    graph several times sparser.
    """
    n = local.shape[0]
    keep = np.zeros((n, n), np.bool_)
    for i in prange(n):
        near = np.flatnonzero(np.isfinite(local[i]))
        for j in near:
            if j == i:
                continue
            t = local[i, j]
            dominated = False
            for k in near:
                if k != i and k != j and local[i, k] + local[k, j] <= t:
                    dominated = True
                    break
            keep[i, j] = not dominated
    return keep


@njit(cache=True)
def dense_to_csr(values, keep):
    """CSR (indptr, indices, data) of the kept entries of a dense matrix."""
    n = values.shape[0]
    indptr = np.zeros(n + 1, np.int64)
    for i in range(n):
        indptr[i + 1] = indptr[i] + np.count_nonzero(keep[i])
    indices = np.empty(indptr[-1], np.int64)
    data = np.empty(indptr[-1])
    p = 0
    for i in range(n):
        for j in range(n):
            if keep[i, j]:
                indices[p] = j
                data[p] = values[i, j]
                p += 1
    return indptr, indices, data
