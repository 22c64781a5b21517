"""Hidden travel: time model, flat-E optimality, detours, regions, and exact clearance."""

import math

import numpy as np
import pytest
from affine import Affine
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.exposure import (
    ExposureParams,
    Outpost,
    compute_exposure,
    segment_clear,
    segment_hidden,
)
from planner.exposure.los import gap_range
from planner.terrain import Terrain, bilinear, synthetic_terrain
from planner.travel import (
    TravelGraph,
    TravelParams,
    build_travel_graph,
    leg_time,
    overlay_rows,
    polyline_time,
    raised_terrain,
)
from planner.travel import graph as travel_graph
from planner.visibility import candidate_viewpoints

CELL = 30.0


def _flat(rows, cols, z=100.0):
    return Terrain(np.full((rows, cols), z), Affine(CELL, 0, 0, 0, -CELL, 0), "EPSG:32616")


def _linked(graph, vp):
    """The viewpoints on graph nodes that have edges (nodes too close to the grid's
    edge for the track tolerance have none)."""
    return vp.subset(np.diff(graph.csr.indptr)[graph.nodes_of(vp.xyz)] > 0)


def _assert_hidden_polyline(surface, poly):
    for a, b in zip(poly[:-1], poly[1:]):
        assert segment_hidden(surface, a, b)
        assert segment_clear(surface, a, b)


def test_leg_time_is_the_slower_motion():
    p = TravelParams(speed_mps=10.0, climb_mps=2.0, descent_mps=4.0)
    assert leg_time(100.0, 0.0, p) == 10.0
    assert leg_time(100.0, 40.0, p) == 20.0  # climbing 40 m at 2 m/s
    assert leg_time(100.0, -40.0, p) == 10.0  # descending at 4 m/s takes 10 s too
    assert leg_time(0.0, -80.0, p) == 20.0
    poly = np.array([[0, 0, 0], [30, 40, 0], [30, 40, 10]], float)
    assert math.isclose(polyline_time(poly, p), 5.0 + 5.0)


def test_flat_exposure_gives_straight_line_times():
    surface = compute_exposure(_flat(30, 40), [], ExposureParams())
    graph = TravelGraph(surface)
    vp = _linked(graph, candidate_viewpoints(surface, spacing_m=150.0))
    times = graph.time_matrix(vp.xyz, method="exact")
    d = np.hypot(*(vp.xyz[:, None, :2] - vp.xyz[None, :, :2]).transpose(2, 0, 1))
    straight = d / graph.params.speed_mps
    # 16-neighbour moves: within 3 % of the straight line, never shorter
    assert (times >= straight - 1e-9).all()
    assert (times <= 1.03 * straight + 1e-9).all()
    # smoothing pulls the grid path straight: the exact straight-line time
    a, b = vp.xyz[0], vp.xyz[-1]
    poly = graph.path(a, b)
    assert len(poly) == 2
    assert math.isclose(polyline_time(poly), np.hypot(*(b - a)[:2]) / 12.0, rel_tol=1e-9)


def test_path_detours_around_an_exposed_obstacle_and_stays_hidden():
    t = _flat(31, 41)
    # an outpost with a 240 m range on flat ground exposes a disk in the middle
    x, y = t.xy(15, 20)
    surface = compute_exposure(t, [Outpost(x=float(x), y=float(y), height_m=2.0,
                                           range_m=240.0)], ExposureParams())
    assert not surface.flyable[15, 20] and surface.flyable[15, 5]
    graph = TravelGraph(surface)
    a = np.array([*t.xy(15, 5), surface.ceiling[15, 5]])
    b = np.array([*t.xy(15, 35), surface.ceiling[15, 35]])
    poly = graph.path(a, b)
    straight = np.hypot(*(b - a)[:2]) / graph.params.speed_mps
    assert polyline_time(poly) > 1.05 * straight
    _assert_hidden_polyline(surface, poly)
    # the path keeps out of the exposed disk
    assert (np.hypot(poly[:, 0] - x, poly[:, 1] - y) > 240.0).all()
    # smoothing only shortens: the polyline beats the graph time
    assert polyline_time(poly) <= graph.times_between(a[None], b[None])[0, 0] + 1e-9
    assert len(poly) < 10


def test_unreachable_across_regions_is_inf():
    h = np.full((30, 50), 100.0)
    h[:, 23:27] = 500.0  # a high wall; an outpost on it sees its top
    t = Terrain(h, Affine(CELL, 0, 0, 0, -CELL, 0), "EPSG:32616")
    x, y = t.xy(15, 25)
    surface = compute_exposure(t, [Outpost(x=float(x), y=float(y))], ExposureParams())
    graph = TravelGraph(surface)
    vp = _linked(graph, candidate_viewpoints(surface, spacing_m=150.0))
    assert len(set(vp.region)) == 2
    for method in ("exact", "overlay"):
        times = graph.time_matrix(vp.xyz, method=method)
        same = vp.region[:, None] == vp.region[None, :]
        assert np.isinf(times[~same]).all()
        assert np.isfinite(times[same]).all()
    i = int(np.flatnonzero(vp.region == vp.region[0])[0])
    j = int(np.flatnonzero(vp.region != vp.region[0])[0])
    assert graph.path(vp.xyz[i], vp.xyz[j]) is None
    assert graph.route_polyline(vp.xyz[[i, j]]) is None
    assert np.isinf(graph.times_between(vp.xyz[[i]], vp.xyz[[j]])).all()


def test_overlay_matrix_is_exact_nearby_and_an_upper_bound_beyond():
    from planner.terrain import synthetic_terrain

    t = synthetic_terrain(40, 40, cell=CELL, seed=3, family="hills")
    x, y = t.xy(20, 20)
    surface = compute_exposure(t, [Outpost(x=float(x), y=float(y), height_m=10.0)],
                               ExposureParams())
    graph = TravelGraph(surface)
    vp = _linked(graph, candidate_viewpoints(surface, spacing_m=150.0))
    exact = graph.time_matrix(vp.xyz, method="exact")
    overlay = graph.time_matrix(vp.xyz, method="overlay", radius_factor=2.0)
    assert (np.isfinite(exact) == np.isfinite(overlay)).all()
    f = np.isfinite(exact)
    assert (overlay[f] >= exact[f] - 1e-9).all()
    # the overlay's radius: twice the median nearest-neighbour spacing (150 m here)
    near = f & (exact <= 2.0 * 150.0 / graph.params.speed_mps)
    assert np.allclose(overlay[near], exact[near])
    # a radius that joins no two points: bridged through hubs, every pair the graph
    # joins is joined, by a real path (never quicker than the whole graph's)
    lonely = graph.time_matrix(vp.xyz, method="overlay", radius_factor=0.01)
    assert (np.isfinite(lonely) == f).all() and (lonely[f] >= exact[f] - 1e-9).all()
    # route polylines: viewpoints stay vertices, every leg hidden
    order = np.flatnonzero(vp.region == vp.region[0])[:4]
    poly, stops = graph.route_polyline(vp.xyz[order])
    assert np.allclose(poly[stops], vp.xyz[order])
    _assert_hidden_polyline(surface, poly)
    legs = sum(exact[p, q] for p, q in zip(order[:-1], order[1:]))
    assert polyline_time(poly) <= legs + 1e-6


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), a=st.tuples(st.floats(0, 11), st.floats(0, 9)),
       b=st.tuples(st.floats(0, 11), st.floats(0, 9)), za=st.floats(90, 160),
       zb=st.floats(90, 160))
def test_gap_range_matches_dense_sampling(seed, a, b, za, zb):
    rng = np.random.default_rng(seed)
    h = 100 + rng.normal(0, 8, (10, 12))
    lo, hi = gap_range(h, a[0], a[1], za, b[0], b[1], zb)
    s = np.linspace(0, 1, 20001)
    u = a[0] + s * (b[0] - a[0])
    v = a[1] + s * (b[1] - a[1])
    gap = za + s * (zb - za) - bilinear(h, v, u)
    # sampling can only miss extremes: it bounds the exact range from inside
    assert lo <= gap.min() + 1e-9 and hi >= gap.max() - 1e-9
    assert gap.min() - lo < 0.01 and hi - gap.max() < 0.01


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), rough=st.floats(1, 40), tol=st.floats(0.5, 70),
       cell=st.sampled_from([10.0, 30.0, 90.0]))
def test_raised_terrain_bounds_the_ground_within_the_tolerance(seed, rough, tol, cell):
    """Brute force: at random points p, the raised surface is at least the terrain
    at many points within ``tol`` of p (on rings and inside the disc)."""
    rng = np.random.default_rng(seed)
    h = 100 + rng.normal(0, rough, (9, 11))
    up = raised_terrain(h, cell, tol)
    p = rng.uniform([0, 0], [8, 10], (200, 2))               # (row, col)
    ang = rng.uniform(0, 2 * np.pi, (200, 64))
    rad = tol / cell * np.sqrt(rng.uniform(0, 1, (200, 64)))
    rad[:, :16] = tol / cell                                 # on the edge of the disc too
    q = p[:, None, :] + rad[..., None] * np.stack([np.sin(ang), np.cos(ang)], -1)
    inside = (q[..., 0] >= 0) & (q[..., 0] <= 8) & (q[..., 1] >= 0) & (q[..., 1] <= 10)
    ground = np.where(inside, bilinear(h, q[..., 0], q[..., 1]), -np.inf)
    raised = bilinear(up, p[:, 0], p[:, 1])
    known = np.isfinite(raised)
    assert (raised[known] >= ground.max(axis=1)[known] - 1e-9).all()
    # the ground beyond the grid's edge is unknown: no bound where a disc reaches it
    assert not known[~inside.all(axis=1)].any()
    reach = np.ceil(tol / cell) + 1  # patches a vertex's bound covers beyond its own
    deep = (np.minimum(p[:, 0], 8 - p[:, 0]) > reach + 1) & \
        (np.minimum(p[:, 1], 10 - p[:, 1]) > reach + 1)
    assert known[deep].all()
    assert (up[np.isfinite(up)] >= h[np.isfinite(up)]).all()
    assert (raised_terrain(h, cell, 0.0) == h).all()


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 10_000), family=st.sampled_from(["hills", "ridges", "peaks"]),
       n_posts=st.integers(0, 3))
def test_node_paths_are_shortest_as_dijkstra_finds_them(seed, family, n_posts):
    """The guided searches of `node_paths` (route polylines) against scipy's
    Dijkstra on the same graph: same reachability, same time, real edges."""
    from scipy.sparse.csgraph import dijkstra

    from planner.terrain import synthetic_terrain

    t = synthetic_terrain(36, 44, cell=CELL, seed=seed, family=family)
    rng = np.random.default_rng(seed)
    posts = [Outpost(x=float(x), y=float(y), height_m=10.0)
             for x, y in (t.xy(*rng.integers(0, 36, 2)) for _ in range(n_posts))]
    graph = TravelGraph(compute_exposure(t, posts, ExposureParams()))
    if graph.n_nodes < 2:
        return
    pairs = rng.integers(0, graph.n_nodes, (25, 2))
    paths = graph.node_paths(pairs)
    exact = dijkstra(graph.csr, indices=np.unique(pairs[:, 0]))
    row = {s: i for i, s in enumerate(np.unique(pairs[:, 0]))}
    for (a, b), path in zip(pairs, paths):
        best = exact[row[a], b]
        assert (len(path) > 0) == np.isfinite(best)
        if len(path):
            assert path[0] == a and path[-1] == b
            legs = np.array([graph.csr[u, v] for u, v in zip(path[:-1], path[1:])])
            assert (legs > 0).all()  # every step an edge of the graph
            assert math.isclose(legs.sum(), best, rel_tol=1e-9, abs_tol=1e-9)


def _overlay_points():
    """A travel graph on ridges and every 37th node of its largest part, as points."""
    terrain = synthetic_terrain(90, 90, cell=30.0, seed=8, family="ridges")
    x, y = terrain.xy(45, 45)
    surface = compute_exposure(terrain, [Outpost(float(x), float(y), 5.0, 2000.0)])
    graph = build_travel_graph(surface, TravelParams())
    nodes = np.flatnonzero(graph.reachable())[::37]
    return graph, nodes, graph.node_xyz[nodes]


def test_parts_times_over_the_whole_overlay_are_its_matrix():
    """The sparse overlay of all points and the times among any subset over it (what
    an area planned in parts uses) are the dense overlay matrix, sliced."""
    graph, nodes, xyz = _overlay_points()
    whole = graph.time_matrix(xyz, method="overlay")
    overlay = graph.overlay(xyz)
    some = np.sort(np.random.default_rng(1).choice(len(nodes), len(nodes) // 3, replace=False))
    np.testing.assert_allclose(graph.overlay_times(overlay, some), whole[np.ix_(some, some)],
                               rtol=1e-12)


def _clusters(graph, nodes, size):
    """Two clusters of ``size`` nodes of one strongly connected part, around two of
    its nodes far apart: the points of a hidden pocket behind a long corridor."""
    xy = graph.node_xyz[nodes, :2]
    a = nodes[np.argmin(xy.sum(axis=1))]
    b = nodes[np.argmax(xy.sum(axis=1))]
    near = [nodes[np.argsort(np.linalg.norm(xy - graph.node_xyz[c, :2], axis=1))[:size]]
            for c in (a, b)]
    return np.concatenate(near)


@pytest.mark.parametrize("case", ["pockets", "corridor"])
def test_bridged_overlay_joins_what_the_graph_joins(case, monkeypatch):
    """Terrains made to leave the overlay in pieces: many pockets (every 37th node of
    ridges, a radius under their spacing) and a corridor (two clusters at the two
    ends of a part, nothing between them). Against whole-graph Dijkstra: the
    overlay joins every pair one strongly connected part holds, never quicker than
    the graph, exactly within its radius; the bridging searches from a few hubs per
    piece, not from every point (the whole-graph fill of each point it replaced)."""
    graph, nodes, xyz = _overlay_points()
    every = np.flatnonzero(graph.reachable())
    if case == "corridor":
        nodes = _clusters(graph, every[graph._strong_parts()[every] ==
                                       graph._strong_parts()[nodes[0]]], 15)
        xyz = graph.node_xyz[nodes]
    radius = 0.5 if case == "pockets" else 3.0
    searched = []
    hub_times = travel_graph.hub_times
    monkeypatch.setattr(travel_graph, "hub_times", lambda csr, sources, slot, limit: (
        searched.append(len(sources)) or hub_times(csr, sources, slot, limit)))
    overlay = graph.overlay(xyz, radius_factor=radius)
    times = overlay_rows(overlay, np.arange(len(nodes)))
    exact = graph.time_matrix(xyz, method="exact")
    part = graph._strong_parts()[nodes]
    same = part[:, None] == part[None, :]
    assert np.isfinite(times[same]).all()
    f = np.isfinite(times)
    assert (times[f] >= exact[f] - 1e-9).all()
    r = graph._local_search(nodes, radius)[5]
    near = f & (exact <= r)
    np.testing.assert_allclose(times[near], exact[near], rtol=1e-12)
    assert searched
    if case == "corridor":           # 2 pieces x 3 hubs, forward and back, a few rounds
        assert max(searched) <= 6 and (~near & same).sum() > 0
        far = ~near & same & (exact > 0)
        assert np.median(times[far] / exact[far]) < 1.1
    np.testing.assert_array_equal(graph.overlay_times(overlay, np.arange(len(nodes))), times)
