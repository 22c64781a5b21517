"""The overlay graph of a set of points (viewpoints): their hidden times, sparse.

A plan over a large area cannot keep the [n, n] times between its viewpoints:
`TravelGraph.overlay` keeps an edge from each point to every point within a
radius, with its exact time (a bounded Dijkstra on the graph, `bounded_sparse`),
bridged by a few hubs where a pocket of points would otherwise be cut off
(`hubs`, `hub_times`, `with_edges`). Times between any of its points are then
shortest paths over the overlay alone (`overlay_rows`, `all_pairs`): exact within
the radius, beyond it the time of a real hidden path, an upper bound. Exact rows
of times on the graph itself are `dijkstra_rows`'s chunks.
"""

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from planner.parallel import chunks_of, n_threads, run_chunks

from . import kernels as K

#: hubs per overlay part, each chosen among its nearest points (`_hubs`): more
#: hubs, shorter detours through them
HUBS_PER_PART = 3


HUB_NEIGHBOURS = 16


def dijkstra_rows(graph, columns, sources) -> np.ndarray:
    return dijkstra(graph, directed=True, indices=sources)[:, columns]


def bounded_rows(csr, sources) -> np.ndarray:
    """Exact times from each source up to the overlay's radius (inf beyond)."""
    indptr, nbr, w, slot, n, limit = csr
    return K.bounded_times(indptr, nbr, w, sources, slot, n, limit, n_threads())


def bounded_sparse(csr, sources) -> tuple:
    """`bounded_rows` as sparse rows: (entries per row, columns, times), each
    source's own zero left out."""
    local = bounded_rows(csr, sources)
    local[np.arange(len(sources)), csr[3][sources]] = np.inf
    found = np.isfinite(local)
    rows, cols = np.nonzero(found)
    return found.sum(axis=1), cols.astype(np.int64), local[rows, cols]


def hubs(xy, part, overlay) -> np.ndarray:
    """`HUBS_PER_PART` points per strongly connected part of the overlay that shares
    its part of the graph with another: those nearest (horizontally, among their
    `HUB_NEIGHBOURS` nearest points) a point of another overlay part there, the
    likeliest ways out of a pocket. Empty when the overlay joins what the graph does."""
    indptr, nbr, w = overlay
    n = len(part)
    label = connected_components(csr_matrix((w, nbr, indptr), shape=(n, n)), directed=True,
                                 connection="strong")[1]
    shared, count = np.unique(np.unique(np.stack([part, label]), axis=1)[0],
                              return_counts=True)
    ids = np.flatnonzero(np.isin(part, shared[count > 1]))
    if not ids.size:
        return ids
    dist, near = cKDTree(xy[ids]).query(xy[ids], k=min(HUB_NEIGHBOURS, len(ids)))
    near = ids[near]
    other = (label[near] != label[ids, None]) & (part[near] == part[ids, None])
    dist = np.where(other, dist, np.inf).min(axis=1)
    order = np.lexsort((dist, label[ids]))
    group = label[ids][order]
    start = np.r_[0, np.flatnonzero(np.diff(group)) + 1]
    rank = np.arange(len(group)) - np.repeat(start, np.diff(np.r_[start, len(group)]))
    return ids[order][rank < HUBS_PER_PART]


def hub_times(csr, sources, slot, limit) -> tuple:
    """(source index, point id, time) of every point a bounded search from each
    source reaches within ``limit`` (rows of a few sources at a time, so that
    the dense rows stay small)."""
    n = int(slot.max()) + 1
    found = []
    for chunk in chunks_of(np.arange(len(sources)), max(1, int(2e7 // max(n, 1)))):
        t = K.bounded_times(csr.indptr, csr.indices, csr.data, sources[chunk], slot, n,
                            limit, n_threads())
        r, c = np.nonzero(np.isfinite(t))
        found.append((chunk[r], c, t[r, c]))
    return tuple(np.concatenate([f[i] for f in found]) for i in range(3))


def with_edges(overlay, added) -> tuple:
    """The overlay with the ``added`` (src, dst, time) edges, the shorter kept where
    two join the same pair, none from a point to itself."""
    indptr, nbr, w = overlay
    n = len(indptr) - 1
    src = np.concatenate([np.repeat(np.arange(n), np.diff(indptr))] + [a[0] for a in added])
    dst = np.concatenate([nbr] + [a[1] for a in added]).astype(np.int64)
    w = np.concatenate([w] + [a[2] for a in added])
    keep = src != dst
    src, dst, w = src[keep], dst[keep], w[keep]
    order = np.lexsort((w, dst, src))
    src, dst, w = src[order], dst[order], w[order]
    first = np.ones(len(src), bool)
    first[1:] = (np.diff(src) != 0) | (np.diff(dst) != 0)
    counts = np.bincount(src[first], minlength=n)
    return np.r_[0, np.cumsum(counts)].astype(np.int64), dst[first], w[first]


def overlay_rows(overlay, ids, progress=None) -> np.ndarray:
    """[len(ids), len(ids)] shortest times between those points of `TravelGraph.overlay`
    over the whole overlay (through any of its points); inf where it has no path.
    Needs only the overlay, not the graph."""
    nodes, indptr, nbr, w = overlay
    slot = np.full(len(nodes), -1, np.int64)
    slot[ids] = np.arange(len(ids))
    return shortest_rows(indptr, nbr, w, np.asarray(ids, np.int64), slot, len(ids), progress)


def all_pairs(indptr, nbr, w, progress=None) -> np.ndarray:
    """[n, n] shortest times over a small graph (the overlay)."""
    every = np.arange(len(indptr) - 1)
    return shortest_rows(indptr, nbr, w, every, every, len(every), progress)


def shortest_rows(indptr, nbr, w, sources, slot, n_slots, progress=None) -> np.ndarray:
    """[len(sources), n_slots] shortest times over a small graph (an overlay) to the
    nodes given a slot: a Dijkstra from each source, on every core, in row chunks
    so that progress moves."""
    times = np.empty((len(sources), n_slots))

    def rows(chunk):
        times[chunk] = K.bounded_times(indptr, nbr, w, sources[chunk], slot, n_slots, np.inf,
                                       n_threads())
    run_chunks(rows, chunks_of(np.arange(len(sources)), max(1, -(-len(sources) // 16))),
               progress=progress)
    return times
