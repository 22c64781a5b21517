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
tests (planner.los.gap_range) and ``segments_hidden``; when it fails, the edge may
still "dip": descend to the higher of the two floors (on the raised terrain),
fly level (checked the same way), climb back.
Different regions are never joined, so their times are infinite.

Paths found on the graph are smoothed by string pulling: a run of vertices
is replaced by one straight 3-D leg whenever that leg passes the same checks.
Leg time is subadditive (a straight leg never has more horizontal or vertical
motion than the run it replaces), so smoothing never makes a path slower. Every
leg stays under the ceiling ``E - hide_margin`` all along (its bilinear surface,
checked exactly like the clearance), not only at its vertices: hidden alone, a
straight leg could pass up to the sight lines where E dips under it.
"""

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from . import exposure, exposure_kernels
from . import travel_kernels as K
from .errors import InputError

#: MISSION_ITEM_INT carries lat/lon in 1e-7 degree (<= 1.1 cm): every planned leg is
#: proven hidden with this much room around it on top of the track tolerance, so the
#: rounded leg is hidden too
ROUNDING_SLACK_M = 0.05

#: (dr, dc) of half the neighbour set; each edge is checked once, used both ways
_HALF_8 = ((0, 1), (1, -1), (1, 0), (1, 1))
_HALF_16 = _HALF_8 + ((1, -2), (1, 2), (2, -1), (2, 1))


@dataclass(frozen=True)
class TravelParams:
    speed_mps: float = 12.0
    climb_mps: float = 3.0
    descent_mps: float = 2.0
    #: how far (horizontally) a vehicle may stray from a planned leg and stay hidden and
    #: clear: cross-track error and corner overshoot (the simulator's copter: up to 4 m)
    track_tolerance_m: float = 5.0

    def __post_init__(self):
        for name in ("speed_mps", "climb_mps", "descent_mps"):
            if not getattr(self, name) > 0:
                raise InputError(name, f"must be positive, got {getattr(self, name)}")
        if not self.track_tolerance_m >= 0:
            raise InputError("track_tolerance_m", f"must not be negative, got "
                                                  f"{self.track_tolerance_m}")

    @property
    def slack_m(self) -> float:
        """Room around every leg that must be hidden too (segments_hidden's slack_m)."""
        return self.track_tolerance_m + ROUNDING_SLACK_M


def leg_time(horizontal_m, dz_m, params=TravelParams()):
    """Time of straight legs: the slower of horizontal and vertical motion."""
    horizontal_m = np.asarray(horizontal_m, float)
    dz_m = np.asarray(dz_m, float)
    vertical = np.where(dz_m > 0, dz_m / params.climb_mps, -dz_m / params.descent_mps)
    return np.maximum(horizontal_m / params.speed_mps, vertical)


def polyline_time(poly, params=TravelParams()) -> float:
    """Flight time along a 3-D polyline (n, 3) under the leg time model."""
    poly = np.asarray(poly, float)
    if len(poly) < 2:
        return 0.0
    d = np.diff(poly, axis=0)
    return float(leg_time(np.hypot(d[:, 0], d[:, 1]), d[:, 2], params).sum())


class TravelGraph:
    """The hidden travel graph over the flyable cells of an exposure surface."""

    def __init__(self, surface, params=TravelParams(), neighbours=16):
        if neighbours not in (8, 16):
            raise InputError("neighbours", f"must be 8 or 16, got {neighbours}")
        self.surface = surface
        self.params = params
        terrain = surface.terrain
        self._h = np.ascontiguousarray(terrain.height, np.float64)
        self._h_clear = raised_terrain(self._h, terrain.cell_size, params.track_tolerance_m)
        self._ceiling = _ceiling_everywhere(surface, self._h)
        rows, cols = np.nonzero(surface.regions > 0)
        self.node_rows = rows.astype(np.int64)
        self.node_cols = cols.astype(np.int64)
        self.node_of_cell = np.full(surface.flyable.shape, -1, np.int64)
        self.node_of_cell[rows, cols] = np.arange(rows.shape[0])
        x, y = terrain.xy(rows, cols)
        self.node_xyz = np.stack([x, y, surface.ceiling[rows, cols]], axis=1)
        self.node_region = surface.regions[rows, cols]
        src, dst, dip = self._edges(np.array(_HALF_8 if neighbours == 8 else _HALF_16,
                                             np.int64))
        za, zb = self.node_xyz[src, 2], self.node_xyz[dst, 2]
        low = np.where(np.isnan(dip), np.minimum(za, zb), dip)
        horiz = np.hypot(*(self.node_xyz[dst, :2] - self.node_xyz[src, :2]).T)
        self._indptr, self._nbr, w, self._dip = K.directed_csr(
            rows.shape[0], src, dst, _edge_time(horiz, za, low, zb, params),
            _edge_time(horiz, zb, low, za, params), dip)
        n = rows.shape[0]
        self.csr = csr_matrix((w, self._nbr.astype(np.int32), self._indptr), shape=(n, n))
        self._csr_reverse = None

    @property
    def n_nodes(self) -> int:
        return int(self.node_rows.shape[0])

    @property
    def n_edges(self) -> int:
        return int(self.csr.nnz)

    # --- legs -----------------------------------------------------------------------
    def legs_ok(self, a, b, strict=True) -> np.ndarray:
        """Which straight legs a[k] -> b[k] (projected x, y, alt) are flyable hidden:
        at least clearance_m and at most ceiling_agl_m above the terrain, and hidden.
        ``strict`` (every planned leg): also under the ceiling E - hide_margin all
        along, and every point within track_tolerance_m of the leg hidden and
        clearance_m above the terrain; else the leg alone, rounded."""
        a = np.atleast_2d(np.asarray(a, float))
        b = np.atleast_2d(np.asarray(b, float))
        terrain = self.surface.terrain
        p = self.surface.params
        ra, ca = terrain.rowcol(a[:, 0], a[:, 1])
        rb, cb = terrain.rowcol(b[:, 0], b[:, 1])
        inside = terrain.contains_xy(a[:, 0], a[:, 1]) & terrain.contains_xy(b[:, 0], b[:, 1])
        h_clear, slack_m = ((self._h_clear, self.params.slack_m) if strict
                            else (self._h, ROUNDING_SLACK_M))
        za, zb = a[:, 2].copy(), b[:, 2].copy()
        lo = K.legs_gaps(h_clear, ca, ra, za, cb, rb, zb)[0]
        hi = K.legs_gaps(self._h, ca, ra, za, cb, rb, zb)[1]
        ok = inside & (lo >= p.clearance_m - 1e-6) & (hi <= p.ceiling_agl_m + 1e-6)
        if strict:
            ok &= K.legs_gaps(self._ceiling, ca, ra, za, cb, rb, zb)[1] <= 1e-6
        idx = np.flatnonzero(ok)
        ok[idx] = _segments_hidden(self.surface, a[idx], b[idx], slack_m)
        return ok

    def _edges(self, half_offsets):
        """Checked undirected edges (src, dst, dip) between nodes of the same region.

        An edge is the straight leg between the two nodes (dip NaN) or, when
        that leg fails, a "dip": descend vertically to ``dip`` = the higher
        of the two floors, fly level, climb to the other node. The vertical
        parts need no check (lower is never less hidden, and they stay above
        the floor); the level part is checked like any leg. A node must pass the
        checks itself (its track-tolerance disc): a dip's vertical part does not
        prove it.
        """
        p = self.surface.params
        src, dst = K.grid_neighbours(self.node_of_cell, self.node_region, half_offsets)
        fine = self.legs_ok(self.node_xyz, self.node_xyz)
        src, dst = src[fine[src] & fine[dst]], dst[fine[src] & fine[dst]]
        z = np.ascontiguousarray(self.node_xyz[:, 2])
        ok = K.grid_legs_within(self._h_clear, self._h, self._ceiling, self.node_rows,
                                self.node_cols, z, src, dst, p.clearance_m, p.ceiling_agl_m)
        idx = np.flatnonzero(ok)
        ok[idx] = _segments_hidden(self.surface, self.node_xyz[src[idx]],
                                   self.node_xyz[dst[idx]], self.params.slack_m)
        floor = self._h_clear[self.node_rows, self.node_cols] + p.clearance_m
        low = np.maximum(floor[src], floor[dst])
        dip = np.full(src.shape[0], np.nan)
        idx = np.flatnonzero(~ok & (low < np.minimum(z[src], z[dst])))
        if idx.size:
            z_low = np.ascontiguousarray(low[idx])
            a = np.column_stack([self.node_xyz[src[idx], :2], z_low])
            b = np.column_stack([self.node_xyz[dst[idx], :2], z_low])
            fine = self.legs_ok(a, b)
            ok[idx[fine]] = True
            dip[idx[fine]] = z_low[fine]
        return src[ok], dst[ok], dip[ok]

    # --- points <-> nodes -------------------------------------------------------------
    def nodes_of(self, xyz, what="point") -> np.ndarray:
        """Node of the cell under each point; InputError if that cell is not flyable."""
        xyz = np.atleast_2d(np.asarray(xyz, float))
        row, col = self.surface.terrain.rowcol(xyz[:, 0], xyz[:, 1])
        r = np.rint(row).astype(np.int64)
        c = np.rint(col).astype(np.int64)
        n_rows, n_cols = self.node_of_cell.shape
        inside = (r >= 0) & (r < n_rows) & (c >= 0) & (c < n_cols)
        nodes = np.full(len(xyz), -1, np.int64)
        nodes[inside] = self.node_of_cell[r[inside], c[inside]]
        if (nodes < 0).any():
            k = int(np.flatnonzero(nodes < 0)[0])
            raise InputError(what, f"({xyz[k, 0]:.0f}, {xyz[k, 1]:.0f}) is not over a flyable"
                             " hidden cell")
        return nodes

    def reachable(self, xyz=None) -> np.ndarray:
        """Bool per node: in a strongly connected part holding a node under ``xyz``
        (e.g. the launch points), or in the largest part when ``xyz`` is None.

        Flyable regions are connected as cells, but a hidden graph edge also needs
        its straight leg hidden, so a region can fall apart into several parts.
        """
        _, labels = connected_components(self.csr, directed=True, connection="strong")
        keep = (np.unique(labels[self.nodes_of(xyz)]) if xyz is not None
                else [np.bincount(labels).argmax()])
        return np.isin(labels, keep)

    # --- times ------------------------------------------------------------------------
    def times_from(self, xyz) -> np.ndarray:
        """[n_points, n_nodes] shortest times (s) from the nodes under the points."""
        return dijkstra(self.csr, directed=True, indices=self.nodes_of(xyz))

    def times_to(self, xyz) -> np.ndarray:
        """[n_points, n_nodes] shortest times (s) from every node to the nodes under the points."""
        return dijkstra(self._reverse(), directed=True, indices=self.nodes_of(xyz))

    def _reverse(self):
        if self._csr_reverse is None:
            self._csr_reverse = self.csr.T.tocsr()
        return self._csr_reverse

    def times_between(self, src_xyz, dst_xyz) -> np.ndarray:
        """[n_src, n_dst] shortest times (s); inf when unreachable (e.g. other regions)."""
        src = self.nodes_of(src_xyz)
        dst = self.nodes_of(dst_xyz)
        if len(src) <= len(dst):
            return self._rows(self.csr, src, dst)
        return self._rows(self._reverse(), dst, src).T

    def _rows(self, graph, sources, columns):
        """dijkstra(graph, sources)[:, columns], in chunks that bound the dense output."""
        out = np.empty((len(sources), len(columns)))
        chunk = max(1, int(2e7 // max(1, self.n_nodes)))
        for a in range(0, len(sources), chunk):
            out[a:a + chunk] = dijkstra(graph, directed=True,
                                        indices=sources[a:a + chunk])[:, columns]
        return out

    def time_matrix(self, xyz, method="auto", radius_factor=3.0) -> np.ndarray:
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
            return self._exact_matrix(nodes)
        if method == "overlay":
            return self._overlay_matrix(nodes, radius_factor)
        raise InputError("method", f"unknown time matrix method {method!r}")

    def _exact_matrix(self, nodes):
        return self._rows(self.csr, nodes, nodes)

    def _overlay_matrix(self, nodes, radius_factor):
        n = len(nodes)
        if n < 2:
            return np.zeros((n, n))
        # the typical spacing: median distance from a point to its nearest other point
        xy = self.node_xyz[nodes, :2]
        nearest, _ = cKDTree(xy).query(xy, k=2)
        spacing = float(np.median(nearest[:, 1]))
        spacing = max(spacing, self.surface.terrain.cell_size)
        limit = radius_factor * spacing / self.params.speed_mps
        slot = np.full(self.n_nodes, -1, np.int64)
        slot[nodes] = np.arange(n)
        local = K.bounded_times(self._indptr, self._nbr, self.csr.data, nodes, slot, n, limit,
                                _n_threads())
        indptr, nbr, w = K.dense_to_csr(local, K.undominated_edges(local))
        times = dijkstra(csr_matrix((w, nbr, indptr), shape=(n, n)), directed=True)
        return self._fill_missed(times, nodes)

    def _fill_missed(self, times, nodes):
        """Exact times where the overlay found no path but the graph has one: a point
        whose only ways in (or out) are longer than the radius is joined to no other.
        Whole columns (reverse Dijkstra) first, then whole rows."""
        _, labels = connected_components(self.csr, directed=True, connection="strong")
        part = labels[nodes]
        missed = ~np.isfinite(times) & (part[:, None] == part[None, :])
        cols = np.flatnonzero(missed.sum(axis=0) > 1)
        if cols.size:
            times[:, cols] = self._rows(self._reverse(), nodes[cols], nodes).T
            missed[:, cols] = False
        rows = np.flatnonzero(missed.any(axis=1))
        if rows.size:
            times[rows] = self._rows(self.csr, nodes[rows], nodes)
        return times

    # --- paths ------------------------------------------------------------------------
    def node_path(self, a_node, b_node) -> np.ndarray:
        """Node ids of a shortest path (empty if unreachable)."""
        return K.node_path(self._indptr, self._nbr, self.csr.data, int(a_node), int(b_node))

    def _expand(self, nodes) -> np.ndarray:
        """Vertices of a node path, with the two corners of every dip edge."""
        out = [self.node_xyz[nodes[:1]]]
        for u, v in zip(nodes[:-1], nodes[1:]):
            row = slice(self._indptr[u], self._indptr[u + 1])
            z = self._dip[row][np.flatnonzero(self._nbr[row] == v)[0]]
            if not np.isnan(z):
                out.append([[*self.node_xyz[u, :2], z], [*self.node_xyz[v, :2], z]])
            out.append(self.node_xyz[[v]])
        return np.vstack(out)

    def path(self, a_xyz, b_xyz) -> np.ndarray:
        """Smoothed hidden 3-D polyline (n, 3) from a to b, or None if unreachable.

        a and b enter the graph at the node of the cell under them; the legs
        a -> node and node -> b must themselves be flyable hidden.
        """
        a_xyz = np.asarray(a_xyz, float)
        b_xyz = np.asarray(b_xyz, float)
        a, b = self.nodes_of(np.stack([a_xyz, b_xyz]))
        nodes = self.node_path(a, b)
        if nodes.size == 0:
            return None
        poly = np.vstack([a_xyz, self._expand(nodes), b_xyz])
        ok = self.legs_ok(poly[[0, -2]], poly[[1, -1]])
        if not ok.all():
            raise InputError("path", "the leg between a point and its cell's node is not hidden")
        return self.smooth(_dedupe(poly))

    def route_polyline(self, xyz):
        """Hidden polyline through the points in order, and each point's vertex index.

        Returns (poly (m, 3), stops (n,)); None if some pair is unreachable.
        The points stay vertices (snapshots are taken there).
        """
        xyz = np.atleast_2d(np.asarray(xyz, float))
        parts = [xyz[:1]]
        stops = [0]
        for p, q in zip(xyz[:-1], xyz[1:]):
            leg = self.path(p, q)
            if leg is None:
                return None
            parts.append(leg[1:])
            stops.append(stops[-1] + len(leg) - 1)
        return np.vstack(parts), np.array(stops, np.int64)

    def smooth(self, poly) -> np.ndarray:
        """String pulling: from each kept vertex, jump to a far vertex that the
        straight leg reaches flyable hidden. The jump is found by galloping
        (1, 2, 4, ... vertices ahead) and bisecting between the last leg that
        passed and the first that failed: O(log n) checks per kept vertex, and
        every kept leg is one that passed."""
        poly = np.asarray(poly, float)
        n = len(poly)
        keep = [0]
        i = 0
        while i < n - 1:
            good, step = i + 1, 1
            bad = None
            if self._leg_ok(poly[i], poly[n - 1]):
                good = n - 1
            else:
                while good + step < n - 1:
                    if not self._leg_ok(poly[i], poly[good + step]):
                        bad = good + step
                        break
                    good += step
                    step *= 2
                bad = n - 1 if bad is None else bad
                while bad - good > 1:
                    mid = (good + bad) // 2
                    if self._leg_ok(poly[i], poly[mid]):
                        good = mid
                    else:
                        bad = mid
            keep.append(good)
            i = good
        return poly[keep]

    def _leg_ok(self, a, b) -> bool:
        return bool(self.legs_ok(a, b)[0])

    def polyline_time(self, poly) -> float:
        return polyline_time(poly, self.params)


def build_travel_graph(surface, params=TravelParams(), neighbours=16) -> TravelGraph:
    return TravelGraph(surface, params, neighbours)


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
    point of its four patches). Patches touching a void take the steepest slope
    found anywhere (voids themselves stay voids)."""
    if tolerance_m <= 0:
        return h
    slope = exposure_kernels.patch_gradient_bound(h, cell)
    finite = np.isfinite(slope)
    slope[~finite] = slope[finite].max(initial=0.0)
    reach = int(np.ceil(tolerance_m / cell))
    spread = maximum_filter(np.pad(slope, 1), size=2 * reach + 3, mode="constant")
    return h + tolerance_m * spread[:h.shape[0], :h.shape[1]]


def _edge_time(horiz, z_from, z_low, z_to, params):
    """Time of a vertical move z_from -> z_low, a level leg, and z_low -> z_to
    (z_low = min(z_from, z_to) makes it one straight leg's time)."""
    direct = np.minimum(z_from, z_to) == z_low
    straight = leg_time(horiz, z_to - z_from, params)
    dip = (leg_time(0.0, z_low - z_from, params) + horiz / params.speed_mps
           + leg_time(0.0, z_to - z_low, params))
    return np.where(direct, straight, dip)


def _segments_hidden(surface, a, b, slack_m) -> np.ndarray:
    """exposure.segments_hidden (proven hidden from every outpost, with every point
    within ``slack_m`` of the leg), for many legs."""
    if len(a) == 0:
        return np.zeros(0, bool)
    return np.asarray(exposure.segments_hidden(surface, a, b, slack_m), bool)


def _dedupe(poly):
    d = np.any(np.diff(poly, axis=0) != 0, axis=1)
    return poly[np.concatenate([[True], d])]


def _n_threads() -> int:
    from numba import get_num_threads
    return max(1, int(get_num_threads()))
