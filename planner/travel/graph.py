# Over 600 lines, knowingly: `TravelGraph` is one object whose arrays (the nodes, the
# proven edges and their dips, the raised terrain) every part of it reads: the proofs
# that build it, attaching points, times and the string-pulled paths. What needs none
# of them lives beside it: the time model (params), the overlay of many points (overlay).
"""Hidden travel times and paths between viewpoints.

The UAV flies inside the hidden volume: at every point of its path it is at
least ``clearance_m`` above the terrain, at most ``ceiling_agl_m`` above it,
and hidden from every outpost (planner.exposure.segments_hidden, a proof).
Every point within ``track_tolerance_m`` of a leg horizontally is hidden and
``clearance_m`` above the terrain too (`raised_terrain`), so a vehicle that
strays that far (cross-track error, overshoot at a corner) is still safe.
A leg's time is the slower of its horizontal motion at ``speed_mps`` and its
vertical motion at ``climb_mps`` up or ``descent_mps`` down, so times are
directed.

Graph: one node per cell of a flyable region (`ExposureSurface.regions`), at
the cell's ceiling ``E - hide_margin`` (the highest hidden altitude there);
edges to the 8 or 16 neighbouring cells of the same region, kept when the
straight 3-D leg between the two nodes passes the exact clearance and ceiling
tests (planner.exposure.los.gap_range) and ``segments_hidden``; when it fails, the edge may
still "dip": descend to the higher of the two floors (on the raised terrain),
fly level (checked the same way), climb back. Rays to neighbouring cells mostly
meet the same ridge, so each proof first tries the horizon a neighbour's proof
found (a few cells of terrain instead of the whole ray; the whole ray when that
fails): a lattice of nodes first, the other nodes from them, edges from their
source node.
Different regions are never joined, so their times are infinite.

Paths found on the graph are smoothed by string pulling: a run of vertices
is replaced by one straight 3-D leg whenever that leg passes the same checks.
Leg time is subadditive (a straight leg never has more horizontal or vertical
motion than the run it replaces), so smoothing never makes a path slower. Every
leg stays under the ceiling ``E - hide_margin`` all along (its bilinear surface,
checked exactly like the clearance), not only at its vertices: hidden alone, a
straight leg could pass up to the sight lines where E dips under it.
"""

import numpy as np
from scipy.ndimage import maximum_filter
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from common.errors import InputError
from planner import exposure
from planner.exposure import kernels as exposure_kernels
from planner.parallel import chunks_of, n_threads, progress_part, run_chunks
from planner.terrain import bilinear

from . import kernels as K
from .overlay import (
    all_pairs,
    bounded_rows,
    bounded_sparse,
    dijkstra_rows,
    hub_times,
    hubs,
    overlay_rows,
    with_edges,
)
from .params import ROUNDING_SLACK_M, TravelParams, polyline_time

#: planned legs keep this much more than clearance_m above the ground, so that the
#: mission check, which proves the rounded waypoints against clearance_m itself,
#: never finds a leg exactly at the floor
CLEARANCE_MARGIN_M = 0.05
#: cells around a point searched for a node it can be joined to (`attach`)
ATTACH_REACH_CELLS = 2
#: nodes, and node pairs, checked per chunk (`planner.parallel.run_chunks`): a few
#: seconds of work each on large areas, so that progress moves and dask tasks pay
NODE_CHUNK = 100_000
EDGE_CHUNK = 100_000
#: nodes on every HINT_LATTICE-th row and column are checked first; their horizons
#: then hint the proofs of the nodes around them (`TravelGraph._check_nodes`)
HINT_LATTICE = 3
#: rounds of doubling the hubs' time limit (`TravelGraph._bridged`) before the last,
#: unlimited one: from twice the radius to 128 times it
BRIDGE_ROUNDS = 6

#: (dr, dc) of half the neighbour set; each edge is checked once, used both ways
_HALF_8 = ((0, 1), (1, -1), (1, 0), (1, 1))
_HALF_16 = _HALF_8 + ((1, -2), (1, 2), (2, -1), (2, 1))
_HALF_16_ARRAY = np.array(_HALF_16, np.int64)


class TravelGraph:
    """The hidden travel graph over the flyable cells of an exposure surface."""

    def __init__(self, surface, params=TravelParams(), neighbours=16, edges=None, client=None,
                 progress=None, hints=True):
        """``edges``: the checked edges of an identical graph (`edges()`, e.g. from a
        plan folder), taken as they are instead of checked again. Otherwise they are
        checked in chunks (`planner.parallel.run_chunks`: on ``client``'s dask
        workers when given), ``progress(fraction)`` told as chunks end. ``hints``
        False: every proof walks whole rays (the reference benchmarks compare with)."""
        if neighbours not in (8, 16):
            raise InputError("neighbours", f"must be 8 or 16, got {neighbours}")
        self.surface = surface
        self.params = params
        self.hints = hints
        terrain = surface.terrain
        self._h = np.ascontiguousarray(terrain.height, np.float64)
        ground = np.ascontiguousarray(terrain.upper, np.float64)
        # clearance is proven over the ground within the track tolerance (strict) or
        # within what rounding for MAVLink moves a point
        self._h_clear = raised_terrain(ground, terrain.cell_size, params.slack_m)
        self._h_round = raised_terrain(ground, terrain.cell_size, ROUNDING_SLACK_M)
        self._ceiling = _ceiling_everywhere(surface, self._h)
        self._attached = {}
        self._strong = None  # `_strong_parts`
        rows, cols = np.nonzero(surface.regions > 0)
        self.node_rows = rows.astype(np.int64)
        self.node_cols = cols.astype(np.int64)
        self.node_of_cell = np.full(surface.flyable.shape, -1, np.int64)
        self.node_of_cell[rows, cols] = np.arange(rows.shape[0])
        x, y = terrain.xy(rows, cols)
        self.node_xyz = np.stack([x, y, surface.ceiling[rows, cols]], axis=1)
        self.node_region = surface.regions[rows, cols]
        if edges is None:
            src, dst, dipped = self._edges(np.array(_HALF_8 if neighbours == 8 else _HALF_16,
                                                    np.int64), client, progress)
        else:
            src, dst, dipped = self._decoded(edges)
        # a dip edge's level is known from its nodes (`_dip_levels`): a flag per entry
        # is all the graph keeps (1 byte per directed edge instead of an 8-byte level)
        self._indptr, self._nbr, w, self._dipped = K.directed_csr(
            rows.shape[0], src, dst, dipped, self.node_xyz, self._floor_at_nodes(),
            params.speed_mps, params.climb_mps, params.descent_mps)
        del src, dst, dipped
        n = rows.shape[0]
        self.csr = csr_matrix((w, self._nbr, self._indptr), shape=(n, n))
        self._nbr = self.csr.indices  # one copy of the neighbour lists (int32)

    def edges(self, compact=False) -> dict:
        """The checked undirected edges (node ids; ``dip``: the level altitude of a
        dip edge, NaN for a straight one), as `TravelGraph(edges=...)` takes them.

        ``compact``: the same edges in a few bytes each, for the plan folder
        (millions of them on large areas): source ids as steps, the neighbour
        as its offset's index, levels only of the dip edges."""
        src, dst, dipped = self._undirected()
        if not compact:
            dip = np.full(len(src), np.nan)
            dip[dipped] = self._dip_levels(src[dipped], dst[dipped])
            return {"src": src, "dst": dst, "dip": dip}
        dr = self.node_rows[dst] - self.node_rows[src]
        dc = self.node_cols[dst] - self.node_cols[src]
        offset = np.argmax((_HALF_16_ARRAY[:, 0] == dr[:, None])
                           & (_HALF_16_ARRAY[:, 1] == dc[:, None]), axis=1)
        which = np.flatnonzero(dipped)
        return {"src_step": np.diff(src, prepend=0).astype(np.int32),
                "offset": offset.astype(np.uint8),
                "dip_step": np.diff(which, prepend=0).astype(np.int32),
                "dip_level": self._dip_levels(src[which], dst[which])}

    def _undirected(self) -> tuple:
        """(src, dst, dipped) of the checked edges, each once, in the order they were
        checked: the entries of each directed row to a later node (an edge is
        checked from its earlier node, `_HALF_16`). Made when asked, not kept
        (1.7 GB on a 4096² area)."""
        src = np.repeat(np.arange(self.n_nodes, dtype=np.int32), np.diff(self._indptr))
        later = self._nbr > src
        return src[later], self._nbr[later], self._dipped[later]

    def _decoded(self, edges) -> tuple:
        """(src, dst, dipped) from `edges()`, compact or not (the levels are not
        read: `_dip_levels` makes them again)."""
        if "src" in edges:
            return (np.asarray(edges["src"]), np.asarray(edges["dst"]),
                    ~np.isnan(np.asarray(edges["dip"], float)))
        src = np.cumsum(edges["src_step"], dtype=np.int64)
        dr, dc = _HALF_16_ARRAY[np.asarray(edges["offset"], np.int64)].T
        dst = self.node_of_cell[self.node_rows[src] + dr, self.node_cols[src] + dc]
        dipped = np.zeros(len(src), bool)
        dipped[np.cumsum(edges["dip_step"], dtype=np.int64)] = True
        return src, dst, dipped

    def _dip_levels(self, src, dst) -> np.ndarray:
        """The level of dip edges src - dst: the higher of their nodes' floors."""
        return np.maximum(self._floor_at_nodes(src), self._floor_at_nodes(dst))

    @property
    def n_nodes(self) -> int:
        return int(self.node_rows.shape[0])

    @property
    def n_edges(self) -> int:
        return int(self.csr.nnz)

    # --- legs -----------------------------------------------------------------------
    def legs_ok(self, a, b, strict=True, horizons=None) -> np.ndarray:
        """Which straight legs a[k] -> b[k] (projected x, y, alt) are flyable hidden:
        at least clearance_m and at most ceiling_agl_m above the terrain, and hidden.
        ``strict`` (every planned leg): also under the ceiling E - hide_margin all
        along, and every point within track_tolerance_m of the leg hidden and
        clearance_m above the terrain; else the leg alone, rounded. ``horizons``:
        as `planner.exposure.segments_hidden` takes them (rows of legs that fail
        before the hidden test are left as they are)."""
        a = np.atleast_2d(np.asarray(a, float))
        b = np.atleast_2d(np.asarray(b, float))
        terrain = self.surface.terrain
        p = self.surface.params
        ra, ca = terrain.rowcol(a[:, 0], a[:, 1])
        rb, cb = terrain.rowcol(b[:, 0], b[:, 1])
        inside = terrain.contains_xy(a[:, 0], a[:, 1]) & terrain.contains_xy(b[:, 0], b[:, 1])
        h_clear, slack_m = ((self._h_clear, self.params.slack_m) if strict
                            else (self._h_round, ROUNDING_SLACK_M))
        za, zb = a[:, 2].copy(), b[:, 2].copy()
        lo = K.legs_gaps(h_clear, ca, ra, za, cb, rb, zb)[0]
        hi = K.legs_gaps(self._h, ca, ra, za, cb, rb, zb)[1]
        with np.errstate(invalid="ignore"):  # NaN: the leg meets a void
            ok = inside & (lo >= p.clearance_m + CLEARANCE_MARGIN_M) & \
                (hi <= p.ceiling_agl_m + 1e-6)
        if strict:
            with np.errstate(invalid="ignore"):
                ok &= K.legs_gaps(self._ceiling, ca, ra, za, cb, rb, zb)[1] <= 1e-6
        idx = np.flatnonzero(ok)
        ok[idx] = _segments_hidden(self.surface, a[idx], b[idx], slack_m, horizons, idx)
        return ok

    def _edges(self, half_offsets, client=None, progress=None):
        """Checked undirected edges (src, dst, dipped) between nodes of the same
        region.

        An edge is the straight leg between the two nodes or, when that leg
        fails, a "dip" (``dipped``): descend vertically to the higher of the two
        floors (`_dip_levels`), fly level, climb to the other node. The vertical
        parts need no check (lower is never less hidden, and they stay above
        the floor); the level part is checked like any leg. A node must pass the
        checks itself (its track-tolerance disc): a dip's vertical part does not
        prove it. Nodes, then node pairs, are checked in chunks.
        """
        src, dst = K.grid_neighbours(self.node_of_cell, self.node_region, half_offsets)
        fine, horizons = self._check_nodes(client, progress)
        keep = fine[src] & fine[dst]
        pairs = np.stack([src[keep], dst[keep]], axis=1)
        del src, dst, keep  # GBs on large areas (127 M candidate pairs on 4096²)
        checked = run_chunks(_checked_edges, chunks_of(pairs, EDGE_CHUNK), (self, horizons),
                             client, progress_part(progress, 0.15, 1.0))
        if not checked:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, bool)
        ok = np.concatenate([c[0] for c in checked])
        dipped = np.concatenate([c[1] for c in checked])
        del checked
        return pairs[ok, 0], pairs[ok, 1], dipped[ok]

    def _check_nodes(self, client=None, progress=None) -> tuple:
        """(fine, horizons) of every node (`_fine_nodes`). The nodes of every
        `HINT_LATTICE`-th row and column go first, walking whole rays; the others
        then start from the horizons of the lattice node nearest them (rays to
        neighbouring cells mostly meet the same ridge). Without ``hints`` every
        node walks whole rays and no horizon is handed on to the edges."""
        fine = np.zeros(self.n_nodes, bool)
        horizons = np.full((self.n_nodes, len(self.surface.outposts)), np.nan)
        on_lattice = (self.node_rows % HINT_LATTICE == 0) & (self.node_cols % HINT_LATTICE == 0)
        hinted_by = self._nearest_lattice_node()
        if not self.hints:
            on_lattice[:], hinted_by[:] = True, -1
        for select, lo, hi in ((on_lattice, 0.0, 0.04), (~on_lattice, 0.04, 0.15)):
            nodes = np.flatnonzero(select)
            hints = np.full((len(nodes), horizons.shape[1]), np.nan)
            has = hinted_by[nodes] >= 0
            hints[has] = horizons[hinted_by[nodes[has]]]
            chunks = list(zip(chunks_of(nodes, NODE_CHUNK), chunks_of(hints, NODE_CHUNK)))
            for (part, _), (ok, found) in zip(chunks, run_chunks(
                    _fine_nodes, chunks, (self,), client, progress_part(progress, lo, hi))):
                fine[part], horizons[part] = ok, found
        return fine, horizons if self.hints else np.full_like(horizons, np.nan)

    def _nearest_lattice_node(self) -> np.ndarray:
        """The node of the `HINT_LATTICE` cell nearest each node's cell (-1: none)."""
        n_rows, n_cols = self.node_of_cell.shape
        r = np.minimum(np.rint(self.node_rows / HINT_LATTICE).astype(np.int64) * HINT_LATTICE,
                       (n_rows - 1) // HINT_LATTICE * HINT_LATTICE)
        c = np.minimum(np.rint(self.node_cols / HINT_LATTICE).astype(np.int64) * HINT_LATTICE,
                       (n_cols - 1) // HINT_LATTICE * HINT_LATTICE)
        return self.node_of_cell[r, c]

    # --- points <-> nodes -------------------------------------------------------------
    def nodes_of(self, xyz, what="point") -> np.ndarray:
        """Node of the cell under each point; InputError if that cell is not flyable."""
        xyz = np.atleast_2d(np.asarray(xyz, float))
        nodes = self._cell_nodes(xyz)
        if (nodes < 0).any():
            k = int(np.flatnonzero(nodes < 0)[0])
            raise InputError(what, f"({xyz[k, 0]:.0f}, {xyz[k, 1]:.0f}) is not over a flyable"
                             " hidden cell")
        return nodes

    def _cell_nodes(self, xyz) -> np.ndarray:
        row, col = self.surface.terrain.rowcol(xyz[:, 0], xyz[:, 1])
        r = np.rint(row).astype(np.int64)
        c = np.rint(col).astype(np.int64)
        n_rows, n_cols = self.node_of_cell.shape
        inside = (r >= 0) & (r < n_rows) & (c >= 0) & (c < n_cols)
        nodes = np.full(len(xyz), -1, np.int64)
        nodes[inside] = self.node_of_cell[r[inside], c[inside]]
        return nodes

    def _floor_at_nodes(self, nodes=slice(None)) -> np.ndarray:
        """Lowest altitude a level leg may fly at each node (on the raised ground)."""
        return (self._h_clear[self.node_rows[nodes], self.node_cols[nodes]]
                + self.surface.params.clearance_m + 2 * CLEARANCE_MARGIN_M)

    def column_top(self, x, y) -> float:
        """The highest altitude above (x, y) where a vehicle is hidden and clear with
        its track tolerance (the top of a takeoff there), or NaN if there is none.
        Hidden only gets likelier lower down and clear higher up, so the altitudes
        that pass form one interval: bisect for its top (once per point)."""
        key = ("top", round(float(x), 6), round(float(y), 6))
        if key not in self._attached:
            self._attached[key] = self._column_top(float(x), float(y))
        return self._attached[key]

    def _column_top(self, x, y) -> float:
        terrain = self.surface.terrain
        row, col = terrain.rowcol(x, y)
        ceiling = float(bilinear(self._ceiling, np.atleast_1d(row), np.atleast_1d(col))[0])
        low = float(terrain.ground(x, y, upper=True)[0]) + self.surface.params.clearance_m
        if not (np.isfinite(ceiling) and np.isfinite(low)) or ceiling < low:
            return float("nan")
        if self._leg_ok([x, y, ceiling], [x, y, ceiling]):
            return ceiling
        lo, hi = low, ceiling
        if not self._leg_ok([x, y, lo], [x, y, lo]):
            return float("nan")
        while hi - lo > 0.05:
            mid = 0.5 * (lo + hi)
            if self._leg_ok([x, y, mid], [x, y, mid]):
                lo = mid
            else:
                hi = mid
        return lo

    def attach(self, xyz):
        """How a point in the hidden volume joins the graph: (node, polyline from the
        point to the node), or None. Nodes of the cells around the point are tried
        nearest first, each by a straight leg or by a dip (down at the point to the
        higher of the two floors, level, up at the node), every leg checked like the
        graph's own. The point itself must pass the checks (its tolerance disc)."""
        key = tuple(np.round(np.asarray(xyz, float), 6))
        if key not in self._attached:
            self._attached[key] = self._attach(np.asarray(xyz, float))
        return self._attached[key]

    def _attach(self, p):
        node = int(self._cell_nodes(p[None])[0])
        if node >= 0 and np.array_equal(self.node_xyz[node], p):
            return node, p[None]  # a node itself (e.g. a viewpoint)
        if not self._leg_ok(p, p):
            return None
        terrain = self.surface.terrain
        row, col = terrain.rowcol(p[0], p[1])
        reach = ATTACH_REACH_CELLS
        r0, c0 = int(np.rint(row)), int(np.rint(col))
        rows, cols = np.mgrid[r0 - reach:r0 + reach + 1, c0 - reach:c0 + reach + 1]
        n_rows, n_cols = self.node_of_cell.shape
        inside = (rows >= 0) & (rows < n_rows) & (cols >= 0) & (cols < n_cols)
        nodes = self.node_of_cell[rows[inside], cols[inside]]
        nodes = nodes[nodes >= 0]
        if not nodes.size:
            return None
        nodes = nodes[np.argsort(np.hypot(*(self.node_xyz[nodes, :2] - p[:2]).T),
                                 kind="stable")]
        straight = self.legs_ok(np.repeat(p[None], len(nodes), axis=0), self.node_xyz[nodes])
        if straight.any():
            node = int(nodes[np.argmax(straight)])
            return node, _dedupe(np.stack([p, self.node_xyz[node]]))
        ground = float(terrain.ground(p[0], p[1], upper=True)[0])
        low = np.maximum(self._floor_at_nodes(nodes),
                         ground + self.surface.params.clearance_m + 2 * CLEARANCE_MARGIN_M)
        for node, z in zip(nodes, low):
            if z >= min(p[2], self.node_xyz[node, 2]):
                continue
            q = self.node_xyz[node]
            if self.legs_ok([p[0], p[1], z], [q[0], q[1], z])[0]:
                return int(node), np.array([p, [p[0], p[1], z], [q[0], q[1], z], q])
        return None

    def _attached_nodes(self, xyz, what="point") -> np.ndarray:
        """`attach` node of each point; InputError naming the first that has none."""
        xyz = np.atleast_2d(np.asarray(xyz, float))
        nodes = np.empty(len(xyz), np.int64)
        for k, p in enumerate(xyz):
            found = self.attach(p)
            if found is None:
                lon, lat = self.surface.terrain.to_lonlat(p[0], p[1])
                raise InputError(what, f"no hidden leg joins {float(lat):.6f},{float(lon):.6f}"
                                 f" at {p[2]:.1f} m to the hidden flyable cells around it")
            nodes[k] = found[0]
        return nodes

    def _attach_times(self, xyz, inbound=False) -> np.ndarray:
        """Time of each point's attach polyline (to its node, or from it)."""
        out = np.empty(len(xyz))
        for k, p in enumerate(np.atleast_2d(xyz)):
            poly = self.attach(p)[1]
            out[k] = self.polyline_time(poly[::-1] if inbound else poly)
        return out

    def reachable(self, xyz=None) -> np.ndarray:
        """Bool per node: in a strongly connected part holding a node under ``xyz``
        (e.g. the launch points), or in the largest part when ``xyz`` is None.

        Flyable regions are connected as cells, but a hidden graph edge also needs
        its straight leg hidden, so a region can fall apart into several parts.
        """
        labels = self._strong_parts()
        keep = (np.unique(labels[self._attached_nodes(xyz)]) if xyz is not None
                else [np.bincount(labels).argmax()])
        return np.isin(labels, keep)

    def _strong_parts(self) -> np.ndarray:
        """Label per node of its strongly connected part, computed once."""
        if self._strong is None:
            self._strong = connected_components(self.csr, directed=True,
                                                connection="strong")[1].astype(np.int32)
        return self._strong

    # --- times ------------------------------------------------------------------------
    def times_from(self, xyz, limit_s=np.inf) -> np.ndarray:
        """[n_points, n_nodes] shortest times (s) from the nodes under the points (inf
        past ``limit_s``: only the nearer nodes are searched)."""
        return dijkstra(self.csr, directed=True, indices=self.nodes_of(xyz), limit=limit_s)

    def times_to(self, xyz) -> np.ndarray:
        """[n_points, n_nodes] shortest times (s) from every node to the nodes under the points."""
        return dijkstra(self._reverse(), directed=True, indices=self.nodes_of(xyz))

    def _reverse(self):
        """The graph with every edge reversed: made when needed, not kept (as large as
        the graph itself, 2.6 GB on a 4096² area; a second or two to make)."""
        return self.csr.T.tocsr()

    def times_between(self, src_xyz, dst_xyz) -> np.ndarray:
        """[n_src, n_dst] shortest times (s) between points joined to the graph by
        `attach`; inf when unreachable (e.g. other regions)."""
        src_xyz = np.atleast_2d(src_xyz)
        dst_xyz = np.atleast_2d(dst_xyz)
        # a fleet shares its launch points: one Dijkstra per distinct node, not per UAV
        src, src_of = np.unique(self._attached_nodes(src_xyz), return_inverse=True)
        dst, dst_of = np.unique(self._attached_nodes(dst_xyz), return_inverse=True)
        if len(src) <= len(dst):
            times = self._rows(self.csr, src, dst)
        else:
            times = self._rows(self._reverse(), dst, src).T
        times = times[src_of.ravel()][:, dst_of.ravel()]
        return (times + self._attach_times(src_xyz)[:, None]
                + self._attach_times(dst_xyz, inbound=True)[None, :])

    def _rows(self, graph, sources, columns, client=None, progress=None):
        """dijkstra(graph, sources)[:, columns], in chunks that bound the dense output,
        on every core (or ``client``'s workers)."""
        if not len(sources):
            return np.empty((0, len(columns)))
        size = max(1, min(int(2e7 // max(1, self.n_nodes)), -(-len(sources) // 16)))
        parts = run_chunks(dijkstra_rows, chunks_of(np.asarray(sources), size), (graph, columns),
                           client, progress, threads=n_threads())
        return np.vstack(parts)

    def time_matrix(self, xyz, method="auto", radius_factor=3.0, client=None,
                    progress=None) -> np.ndarray:
        """[n, n] shortest times between the points (e.g. candidate viewpoints).

        ``exact``: one full Dijkstra per point. ``overlay``: an exact bounded
        Dijkstra from each point up to ``radius_factor`` typical spacings, then
        all-pairs shortest paths over the overlay graph of those local times
        (dominated overlay edges dropped first, which changes no time): exact
        for pairs within the radius, beyond it the time of a real hidden path
        through other points, an upper bound. ``auto`` picks exact while
        n_points x n_nodes stays under 3e7.
        """
        nodes = self.nodes_of(xyz)
        if method == "auto":
            method = "exact" if len(nodes) * self.n_nodes <= 3e7 else "overlay"
        if method == "exact":
            return self._rows(self.csr, nodes, nodes, client, progress)
        if method == "overlay":
            return self._overlay_matrix(nodes, radius_factor, client, progress)
        raise InputError("method", f"unknown time matrix method {method!r}")

    def _overlay_matrix(self, nodes, radius_factor, client=None, progress=None):
        n = len(nodes)
        if n < 2:
            return np.zeros((n, n))
        csr = self._local_search(nodes, radius_factor)
        local = np.vstack(run_chunks(bounded_rows, chunks_of(nodes, -(-n // 8)), (csr,), client,
                                     progress_part(progress, 0.0, 0.6)))
        indptr, nbr, w = K.dense_to_csr(local, K.undominated_edges(local))
        del local
        indptr, nbr, w = self._bridged(nodes, (indptr, nbr, w), csr[5],
                                       progress_part(progress, 0.6, 0.7))
        return all_pairs(indptr, nbr, w, progress_part(progress, 0.7, 1.0))

    def _local_search(self, nodes, radius_factor) -> tuple:
        """What a bounded Dijkstra from each of ``nodes`` takes (`bounded_rows`): the
        graph, the slot of each of the nodes, and the radius in time, so many typical
        spacings (median distance from a point to its nearest other one)."""
        xy = self.node_xyz[nodes, :2]
        nearest, _ = cKDTree(xy).query(xy, k=2)
        spacing = max(float(np.median(nearest[:, 1])), self.surface.terrain.cell_size)
        slot = np.full(self.n_nodes, -1, np.int64)
        slot[nodes] = np.arange(len(nodes))
        return (self._indptr, self._nbr, self.csr.data, slot, len(nodes),
                radius_factor * spacing / self.params.speed_mps)

    def overlay(self, xyz, radius_factor=3.0, client=None, progress=None) -> tuple:
        """The sparse overlay graph of the points (``time_matrix``'s "overlay", kept
        sparse for areas whose [n, n] times do not fit in memory): (nodes under the
        points, then indptr, nbr, w over point ids): an edge to every point within
        the radius, with its exact time."""
        nodes = self.nodes_of(xyz)
        csr = self._local_search(nodes, radius_factor)
        size = max(1, int(3e7 // max(len(nodes), 1)))  # a dense chunk of rows stays small
        rows = run_chunks(bounded_sparse, chunks_of(nodes, size), (csr,), client,
                          progress_part(progress, 0.0, 0.9))
        counts = np.concatenate([r[0] for r in rows] + [np.zeros(0, np.int64)])
        indptr = np.r_[0, np.cumsum(counts)].astype(np.int64)
        nbr = np.concatenate([r[1] for r in rows] + [np.zeros(0, np.int64)])
        w = np.concatenate([r[2] for r in rows] + [np.zeros(0)])
        return (nodes, *self._bridged(nodes, (indptr, nbr, w), csr[5],
                                      progress_part(progress, 0.9, 1.0)))

    def overlay_times(self, overlay, ids, progress=None) -> np.ndarray:
        """[len(ids), len(ids)] times between those points of `overlay`: shortest
        paths over the whole overlay (through any of its points, as in
        ``time_matrix``); the overlay is bridged, so this needs no graph."""
        return overlay_rows(overlay, np.asarray(ids, np.int64), progress)

    def _bridged(self, nodes, overlay, radius_s, progress=None) -> tuple:
        """The overlay (indptr, nbr, w over point ids) with edges added until it
        joins every two points that one strongly connected part of the graph
        holds. A bounded search misses the pairs whose every way leaves its
        radius (a pocket of viewpoints behind a long hidden corridor): per
        overlay part that shares its graph part with another, a few hubs (its
        points nearest another's) get exact edges to and from every point within a time
        limit that doubles each round, until no such part is left. The work
        follows what is missing, not the number of points (a whole-graph search
        per point was the cost of a disconnected overlay). Every edge is the
        exact time of a real hidden path: the overlay's times stay upper bounds,
        exact within the radius."""
        part = self._strong_parts()[nodes]
        xy = self.node_xyz[nodes, :2]
        slot = np.full(self.n_nodes, -1, np.int64)
        slot[nodes] = np.arange(len(nodes))
        reverse, limit = None, 2.0 * radius_s
        for round_ in range(BRIDGE_ROUNDS + 1):
            found = hubs(xy, part, overlay)
            if progress is not None:
                progress(round_ / (BRIDGE_ROUNDS + 1))
            if not found.size:
                break
            reverse = self._reverse() if reverse is None else reverse
            limit = np.inf if round_ == BRIDGE_ROUNDS else limit * 2.0
            out = hub_times(self.csr, nodes[found], slot, limit)
            back = hub_times(reverse, nodes[found], slot, limit)
            overlay = with_edges(overlay, [(found[out[0]], out[1], out[2]),
                                           (back[1], found[back[0]], back[2])])
        return overlay

    # --- paths ------------------------------------------------------------------------
    def node_path(self, a_node, b_node) -> np.ndarray:
        """Node ids of a shortest path (empty if unreachable)."""
        return self.node_paths([(a_node, b_node)])[0]

    def node_paths(self, pairs, progress=None) -> list:
        """`node_path` of each (a_node, b_node), the pairs shared among the cores."""
        pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
        node_xy = np.ascontiguousarray(self.node_xyz[:, :2])

        def run(idx):
            flat, offsets = K.node_paths(self._indptr, self._nbr, self.csr.data, node_xy,
                                         self.params.speed_mps, pairs[idx, 0], pairs[idx, 1])
            return [flat[offsets[i]:offsets[i + 1]] for i in range(len(idx))]
        chunks = chunks_of(np.arange(len(pairs)), max(1, -(-len(pairs) // 16)))
        # on a thread pool: the kernel releases the GIL
        found = run_chunks(run, chunks, progress=progress, threads=n_threads())
        return [path for part in found for path in part]

    def _expand(self, nodes) -> np.ndarray:
        """Vertices of a node path, with the two corners of every dip edge."""
        out = [self.node_xyz[nodes[:1]]]
        for u, v in zip(nodes[:-1], nodes[1:]):
            row = slice(self._indptr[u], self._indptr[u + 1])
            if self._dipped[row][np.flatnonzero(self._nbr[row] == v)[0]]:
                z = self._dip_levels(u, v)
                out.append([[*self.node_xyz[u, :2], z], [*self.node_xyz[v, :2], z]])
            out.append(self.node_xyz[[v]])
        return np.vstack(out)

    def path(self, a_xyz, b_xyz) -> np.ndarray:
        """Smoothed hidden 3-D polyline (n, 3) from a to b, or None if unreachable.
        a and b join the graph by `attach`."""
        found = self.route_polylines([np.stack([a_xyz, b_xyz])])[0]
        return None if found is None else found[0]

    def route_polyline(self, xyz):
        """`route_polylines` of one route."""
        return self.route_polylines([xyz])[0]

    def route_polylines(self, routes, progress=None) -> list:
        """Per route (an (n, 3) array of points to visit in order): the hidden
        polyline through them and each point's vertex index, (poly, stops), or
        None if some pair is unreachable. The points stay vertices (snapshots are
        taken there); the shortest paths between them are found on both cores and
        smoothed all at once (`smooth_all`)."""
        routes = [np.atleast_2d(np.asarray(r, float)) for r in routes]
        pairs = [(p, q) for r in routes for p, q in zip(r[:-1], r[1:])]
        raw = self._raw_paths(pairs, progress_part(progress, 0.0, 0.5))
        smoothed = self.smooth_all([x for x in raw if x is not None],
                                   progress_part(progress, 0.5, 1.0))
        legs = iter(smoothed)
        out, k = [], 0
        for r in routes:
            parts, stops = [r[:1]], [0]
            for _ in range(len(r) - 1):
                leg = raw[k] if raw[k] is None else next(legs)
                k += 1
                if leg is None:
                    parts = None
                    continue
                if parts is not None:
                    parts.append(leg[1:])
                    stops.append(stops[-1] + len(leg) - 1)
            out.append(None if parts is None else (np.vstack(parts), np.array(stops, np.int64)))
        return out

    def _raw_paths(self, pairs, progress=None) -> list:
        """Unsmoothed polylines a -> b (attach legs, node path with its dips), None
        where there is none."""
        ends = [(self.attach(p), self.attach(q)) for p, q in pairs]
        jobs = [(a[0], b[0]) for a, b in ends if a is not None and b is not None]
        found = iter(self.node_paths(jobs, progress))
        out = []
        for (p, q), (a, b) in zip(pairs, ends):
            nodes = next(found) if a is not None and b is not None else np.zeros(0, np.int64)
            if nodes.size == 0:
                out.append(None)
                continue
            out.append(_dedupe(np.vstack([p, a[1], self._expand(nodes), b[1][::-1], q])))
        return out

    def smooth(self, poly) -> np.ndarray:
        """`smooth_all` of one polyline."""
        return self.smooth_all([poly])[0]

    def smooth_all(self, polys, progress=None) -> list:
        """String pulling: from each kept vertex, jump to a far vertex that the
        straight leg reaches flyable hidden. The jump is found by galloping
        (1, 2, 4, ... vertices ahead) and bisecting between the last leg that
        passed and the first that failed: O(log n) checks per kept vertex, and
        every kept leg is one that passed. All polylines advance together, their
        legs checked in one batch per step."""
        polys = [np.asarray(p, float) for p in polys]
        walks = [_string_pull(len(p)) for p in polys]
        kept = [None] * len(polys)
        legs = [self._step(walks, kept, polys, k, None) for k in range(len(polys))]
        while True:
            active = [k for k, leg in enumerate(legs) if leg is not None]
            if progress is not None:
                progress(1.0 - len(active) / max(len(polys), 1))
            if not active:
                return kept
            ok = self.legs_ok(np.array([polys[k][legs[k][0]] for k in active]),
                              np.array([polys[k][legs[k][1]] for k in active]))
            for k, passed in zip(active, ok):
                legs[k] = self._step(walks, kept, polys, k, bool(passed))

    @staticmethod
    def _step(walks, kept, polys, k, passed):
        """Advance walk k by the result of its last leg: its next leg, or None when
        it is done (its kept vertices then in ``kept[k]``)."""
        try:
            return next(walks[k]) if passed is None else walks[k].send(passed)
        except StopIteration as done:
            kept[k] = polys[k][done.value]
            return None

    def _leg_ok(self, a, b) -> bool:
        return bool(self.legs_ok(a, b)[0])

    def polyline_time(self, poly) -> float:
        return polyline_time(poly, self.params)


def build_travel_graph(surface, params=TravelParams(), neighbours=16, client=None,
                       progress=None) -> TravelGraph:
    return TravelGraph(surface, params, neighbours, client=client, progress=progress)


def _ceiling_everywhere(surface, h) -> np.ndarray:
    """E - hide_margin on every cell, flyable or not (NaN on voids only): a leg must
    stay under its bilinear surface, not only at its vertices."""
    cap = h + surface.params.ceiling_agl_m
    return np.minimum(surface.lowest_seen, cap) - surface.params.hide_margin_m


def raised_terrain(h, cell, tolerance_m) -> np.ndarray:
    """Heights whose bilinear surface is, at every point, at least the terrain's
    highest point within ``tolerance_m`` of it horizontally: h + tolerance_m times
    the steepest slope of the patches a point that far away can lie in (each
    vertex takes the largest patch slope bound over a window wide enough for any
    point of its four patches). A vertex whose window holds a patch touching a
    void, or reaches beyond the grid, is a void itself: the ground that close
    is unknown."""
    if tolerance_m <= 0:
        return h
    slope = exposure_kernels.patch_gradient_bound(h, cell)
    void = ~np.isfinite(slope)
    slope[void] = 0.0
    reach = int(np.ceil(tolerance_m / cell))
    # vertex v (padded index v + 1) bounds points of patches v-1..v, and their discs
    # reach patches v-1-reach..v+reach: padded v-reach..v+reach+1
    window = dict(size=2 * reach + 2, origin=-1, mode="constant")
    spread = maximum_filter(np.pad(slope, 1), **window)[:h.shape[0], :h.shape[1]]
    # beyond the grid's edge the ground is unknown too
    near_void = maximum_filter(np.pad(void, 1, constant_values=True),
                               **window)[:h.shape[0], :h.shape[1]]
    return np.where(near_void, np.nan, h + tolerance_m * spread)


def _segments_hidden(surface, a, b, slack_m, horizons=None, rows=None) -> np.ndarray:
    """exposure.segments_hidden (proven hidden from every outpost, with every point
    within ``slack_m`` of the leg), for many legs; ``horizons[rows]`` its hints."""
    if len(a) == 0:
        return np.zeros(0, bool)
    if horizons is None:
        return np.asarray(exposure.segments_hidden(surface, a, b, slack_m), bool)
    mine = np.ascontiguousarray(horizons[rows])
    hidden = np.asarray(exposure.segments_hidden(surface, a, b, slack_m, mine), bool)
    horizons[rows] = mine
    return hidden


def _fine_nodes(graph, chunk) -> tuple:
    """Which nodes pass the checks themselves (their track-tolerance disc), and the
    horizon of each from each outpost (`planner.exposure.segments_hidden`), which
    hints its edges' proofs. ``chunk``: (nodes, hinted horizons of each)."""
    nodes, horizons = chunk
    xyz = graph.node_xyz[nodes]
    horizons = horizons.copy()
    return graph.legs_ok(xyz, xyz, horizons=horizons), horizons


def _checked_edges(graph, node_horizons, pairs):
    """(ok, dipped) of node pairs: the straight leg, else the dip (see `_edges`); the
    source node's horizons hint the legs' proofs."""
    p = graph.surface.params
    src, dst = np.ascontiguousarray(pairs[:, 0]), np.ascontiguousarray(pairs[:, 1])
    z = np.ascontiguousarray(graph.node_xyz[:, 2])
    ok = K.grid_legs_within(graph._h_clear, graph._h, graph._ceiling, graph.node_rows,
                            graph.node_cols, z, src, dst,
                            p.clearance_m + CLEARANCE_MARGIN_M, p.ceiling_agl_m)
    idx = np.flatnonzero(ok)
    hints = node_horizons[src]
    ok[idx] = _segments_hidden(graph.surface, graph.node_xyz[src[idx]],
                               graph.node_xyz[dst[idx]], graph.params.slack_m, hints, idx)
    low = graph._dip_levels(src, dst)
    dipped = np.zeros(src.shape[0], bool)
    idx = np.flatnonzero(~ok & (low < np.minimum(z[src], z[dst])))
    if idx.size:
        z_low = np.ascontiguousarray(low[idx])
        a = np.column_stack([graph.node_xyz[src[idx], :2], z_low])
        b = np.column_stack([graph.node_xyz[dst[idx], :2], z_low])
        fine = graph.legs_ok(a, b, horizons=node_horizons[src[idx]])
        ok[idx[fine]] = True
        dipped[idx[fine]] = True
    return ok, dipped


def _string_pull(n):
    """The vertex indices `TravelGraph.smooth_all` keeps of an n-vertex polyline:
    a generator that yields each leg (i, j) to check and is sent whether it
    passed; its return value is the list of kept indices."""
    keep = [0]
    i = 0
    while i < n - 1:
        good, step = i + 1, 1
        bad = None
        if (yield (i, n - 1)):
            good = n - 1
        else:
            while good + step < n - 1:
                if not (yield (i, good + step)):
                    bad = good + step
                    break
                good += step
                step *= 2
            bad = n - 1 if bad is None else bad
            while bad - good > 1:
                mid = (good + bad) // 2
                if (yield (i, mid)):
                    good = mid
                else:
                    bad = mid
        keep.append(good)
        i = good
    return keep


def _dedupe(poly):
    d = np.any(np.diff(poly, axis=0) != 0, axis=1)
    return poly[np.concatenate([[True], d])]


